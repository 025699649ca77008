"""Independent scipy reference for the describing functions of docs/models.md.

Why this module exists
----------------------
The workbench computes describing functions (DFs) with its own exact,
event-driven solvers inside FMUs. This module is a second, independent
implementation written the way a user would write it with nothing but scipy:
``scipy.integrate.solve_ivp`` between events, events located by solve_ivp's
own root finding, and the integration restarted after every event. It serves

* the tests, as a high-accuracy reference (DOP853, rtol = 1e-12) to check the
  project's DFs to about 1e-8;
* the benchmark, as "what a user would write instead", at a chosen method and
  tolerance.

It deliberately imports nothing from ``dfwb.fmus`` or the project's solvers.

Conventions (docs/models.md): input ``f(t) = F cos(w t)``, start at rest,
``X_k = (2/T) int_T x(t) exp(-j k w t) dt`` over whole periods of the periodic
steady state (``X_0 = (1/T) int_T x dt``), ``N = X_1 / F``.

The Fourier integrals are extra ODE states integrated by the solver itself,
so the harmonics carry the integrator's tolerance rather than that of a
quadrature on sampled output. Every period is integrated in a local time
``tau = t - n T`` in [0, T] (the input is T-periodic, so this is exact) with
the Fourier states restarted at zero: this keeps the phases accurate after
hundreds of periods and gives the coefficients of each period separately.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from dfwb.base.errors import InputError, RunError
from dfwb.fmus.backlash import TABLE as BACKLASH
from dfwb.fmus.friction import TABLE as FRICTION
from dfwb.fmus.static_backlash import TABLE as STATIC_BACKLASH

NH = 11  # harmonics k = 0..10
_fr, _bl, _sb = FRICTION.default, BACKLASH.default, STATIC_BACKLASH.default  # the plants' defaults
PLANTS = ("friction", "backlash")  # the plants describing_function_reference simulates
_K = np.arange(NH, dtype=float)
_MAX_EVENTS = 200000  # per period; a guard against an event loop that makes no progress


def _atol_vector(atol, rtol, scales):
    """Absolute tolerance per state.

    Default (``atol=None``): ``1e-2 * rtol`` times a natural scale of each state
    (position, velocity, Fourier integral over one period), so the error test
    is relative in practice and still meaningful where a state crosses zero.
    A scalar or array given by the caller is used as it is (a user's choice).
    """
    if atol is None:
        return 1e-2 * rtol * np.asarray(scales, dtype=float)
    return atol


def _coefficients(I, T):
    """Complex X_k, k = 0..10, from the period's integrals (int x exp(-j k w t), stored re, im interleaved)."""
    X = I.view(np.complex128) * (2.0 / T)
    X[0] = X[0] / 2.0
    return X


def _solve(rhs, tau0, tau1, y0, method, rtol, atol, events, first_step=None, t_eval=None):
    """One solve_ivp call from an event (or period start) to the next event or period end."""
    kwargs = {}
    if first_step is not None:
        kwargs["first_step"] = min(first_step, tau1 - tau0)
    sol = solve_ivp(rhs, (tau0, tau1), y0, method=method, rtol=rtol, atol=atol,
                    events=events, t_eval=t_eval, **kwargs)
    if sol.status == -1:
        raise RunError(f"solve_ivp failed at tau = {sol.t[-1]!r}: {sol.message}")
    return sol


def _grid(samples, tau0, tau1):
    """Output sample times in [tau0, tau1), then tau1 itself (so sol.y[:, -1] is the end state)."""
    if samples is None:
        return None
    return np.append(samples[(samples >= tau0) & (samples < tau1)], tau1)


# --------------------------------------------------------------------------------------------
# Mass with CVS friction
# --------------------------------------------------------------------------------------------

class _FrictionRun:
    """Period-by-period simulation of the friction mass (exact stick, no Karnopp band).

    Modes: 0 = stick (v = 0, x constant), +1 / -1 = sliding with sgn(v) = mode.
    Sliding is integrated by solve_ivp with the terminal event v = 0 crossed
    towards zero (direction -mode); at that event the force decides: |u| > Fs
    reverses, else the mass sticks. Break-away from stick is at the first time
    |F cos(w tau)| reaches Fs, solved analytically with arccos (exact, and no
    ODE is needed while x is constant); the Fourier integrals over a stick
    interval are integrated analytically too.
    """

    def __init__(self, F, omega, M, B, Fc, Fs, method, rtol, atol, dense_per_period):
        if not (M > 0 and B >= 0 and Fc >= 0 and Fs >= Fc and omega > 0 and F >= 0):
            raise InputError("need M > 0, B >= 0, 0 <= Fc <= Fs, omega > 0, F >= 0")
        self.F, self.w, self.M = float(F), float(omega), float(M)
        self.B, self.Fc, self.Fs = float(B), float(Fc), float(Fs)
        self.T = 2.0 * math.pi / self.w
        self.method, self.rtol = method, rtol
        xs = max(self.F, 1e-300) / (self.w * math.hypot(self.M * self.w, self.B))  # linear amplitude
        self.atol = _atol_vector(atol, rtol, [xs, xs * self.w] + [xs * self.T] * (2 * NH))
        self.kw = _K * self.w
        self.mikw = -1j * self.kw
        self.samples = None if not dense_per_period else np.arange(dense_per_period) * (self.T / dense_per_period)
        self.x, self.v, self.mode = 0.0, 0.0, 0
        self.nfev = 0
        self.events = 0
        # arccos phase of the break-away boundary: |cos(theta)| > Fs/F on (-c, c) and (pi-c, pi+c)
        self.c = math.acos(self.Fs / self.F) if self.F > self.Fs else None
        self._ev = {s: self._event(s) for s in (1, -1)}

    def _event(self, s):
        def v_zero(t, y):
            return y[1]
        v_zero.terminal = True
        v_zero.direction = -s
        return v_zero

    def _rhs(self, s):
        F, w, M, B, Fcs, mikw = self.F, self.w, self.M, self.B, self.Fc * s, self.mikw

        def rhs(t, y):
            v = y[1]
            e = np.exp(mikw * t)
            e *= y[0]
            d = np.empty(2 + 2 * NH)
            d[0] = v
            d[1] = (F * math.cos(w * t) - Fcs - B * v) / M
            d[2:] = e.view(np.float64)
            return d
        return rhs

    def u(self, tau):
        return self.F * math.cos(self.w * tau)

    def breakaway(self, tau):
        """First tau' >= tau with |u| >= Fs and |u| > Fs just after (inf if F <= Fs)."""
        if self.c is None:
            return math.inf
        if abs(self.u(tau)) > self.Fs:
            return tau
        c, th = self.c, math.fmod(self.w * tau, 2.0 * math.pi)
        target = math.pi - c if th < math.pi else 2.0 * math.pi - c
        return tau + max(target - th, 0.0) / self.w

    def _stick_integrals(self, a, b):
        """int_a^b x exp(-j k w t) dt at constant x (analytic), re/im interleaved."""
        I = np.empty(NH, dtype=np.complex128)
        I[0] = b - a
        m = self.mikw[1:]
        I[1:] = (np.exp(m * b) - np.exp(m * a)) / m
        I *= self.x
        return I.view(np.float64)

    def _at_rest_decide(self, tau):
        """v = 0 at tau: stick while |u| <= Fs, else slide in the direction of u."""
        self.v = 0.0
        u = self.u(tau)
        self.mode = int(math.copysign(1, u)) if abs(u) > self.Fs else 0

    def period(self):
        """Advance one period; returns (X_k of this period, max |v|, sampled (tau, x) or None)."""
        T = self.T
        I = np.zeros(2 * NH)
        tau = 0.0
        vmax = abs(self.v)
        ts, xs = [], []
        count = 0
        while tau < T:
            count += 1
            if count > _MAX_EVENTS:
                raise RunError("friction: too many events in one period")
            if self.mode == 0:
                tb = min(self.breakaway(tau), T)
                I += self._stick_integrals(tau, tb)
                if self.samples is not None:
                    grid = _grid(self.samples, tau, tb)[:-1]
                    ts.append(grid)
                    xs.append(np.full(grid.size, self.x))
                tau = tb
                if tb < T:
                    self.mode = int(math.copysign(1, self.u(tb)))
                continue
            s = self.mode
            if self.v * s <= 0.0 and self.v != 0.0:
                # a v = 0 crossing fell on the period boundary: decide it here
                self._at_rest_decide(tau)
                continue
            sol = _solve(self._rhs(s), tau, T, np.concatenate(((self.x, self.v), I)),
                         self.method, self.rtol, self.atol, self._ev[s],
                         t_eval=_grid(self.samples, tau, T))
            self.nfev += sol.nfev
            vmax = max(vmax, float(np.max(np.abs(sol.y[1]))) if sol.y.size else 0.0)
            if self.samples is not None:
                sel = sol.t < (sol.t_events[0][0] if sol.status == 1 else T)
                ts.append(sol.t[sel])
                xs.append(sol.y[0][sel])
            if sol.status == 1:
                tau = float(sol.t_events[0][0])
                y = sol.y_events[0][0]
                self.x, I = float(y[0]), y[2:].copy()
                self.events += 1
                self._at_rest_decide(tau)
            else:
                y = sol.y[:, -1]
                self.x, self.v, I = float(y[0]), float(y[1]), y[2:].copy()
                tau = T
        samples = None
        if self.samples is not None:
            samples = (np.concatenate(ts) if ts else np.empty(0), np.concatenate(xs) if xs else np.empty(0))
        return _coefficients(I, T), vmax, samples

    def section(self):
        return np.array([self.v]), (self.mode,)


# --------------------------------------------------------------------------------------------
# Two-mass backlash with impacts
# --------------------------------------------------------------------------------------------

class _BacklashRun:
    """Period-by-period simulation of the two masses with clearance h and impacts.

    Modes: "free" (M1 x1'' = 0, M2 x2'' = u, terminal events g = 0 and g = h
    crossed while closing), 0 / h (in contact at that wall, (M1 + M2) x'' = u,
    terminal event u = 0 crossed the way that pulls the masses apart).
    Impacts follow Newton's law with momentum conserved. The Zeno accumulation
    (eps < 1, force pressing the masses together) is cut when the next bounce
    would rise less than ``zeno * h``: the masses are then merged keeping the
    centre of mass and the total momentum, which is what the exact infinite
    sequence of impacts converges to (position error below ``zeno * h``).
    After an impact the first step is capped at an eighth of the bounce time
    so that the next impact at the same wall, which starts from g = 0 exactly,
    cannot be stepped over.
    """

    def __init__(self, F, omega, M1, M2, h, eps, method, rtol, atol, dense_per_period, zeno):
        if not (M1 > 0 and M2 > 0 and h > 0 and 0 <= eps <= 1 and omega > 0 and F >= 0):
            raise InputError("need M1, M2, h > 0, 0 <= eps <= 1, omega > 0, F >= 0")
        self.F, self.w, self.M1, self.M2, self.h, self.eps = map(float, (F, omega, M1, M2, h, eps))
        self.Mt = self.M1 + self.M2
        self.T = 2.0 * math.pi / self.w
        self.method, self.rtol, self.zeno = method, rtol, zeno
        xs = max(self.F / (self.Mt * self.w ** 2), self.h)
        self.atol = _atol_vector(atol, rtol, [xs, xs * self.w, xs, xs * self.w] + [xs * self.T] * (2 * NH))
        self.mikw = -1j * _K * self.w
        self.samples = None if not dense_per_period else np.arange(dense_per_period) * (self.T / dense_per_period)
        self.y = np.array([0.0, 0.0, self.h / 2.0, 0.0])  # x1, v1, x2, v2
        self.mode = "free"
        self.first_step = None
        self.nfev = 0
        self.events = 0
        self.impacts = 0
        self._free_events = [self._gap_event(0.0, -1), self._gap_event(self.h, 1)]
        self._contact_events = {0.0: [self._release_event(1)], self.h: [self._release_event(-1)]}
        self._free_rhs = self._make_rhs(None)
        self._contact_rhs = self._make_rhs(self.Mt)

    def _gap_event(self, wall, direction):
        def gap(t, y):
            return y[2] - y[0] - wall
        gap.terminal = True
        gap.direction = direction
        return gap

    def _release_event(self, direction):
        F, w = self.F, self.w

        def force(t, y):
            return F * math.cos(w * t)
        force.terminal = True
        force.direction = direction
        return force

    def _make_rhs(self, contact_mass):
        F, w, mikw = self.F, self.w, self.mikw
        m1_inv = 0.0 if contact_mass is None else 1.0 / contact_mass  # M1 x1'' = 0 in free flight
        m2_inv = 1.0 / (self.M2 if contact_mass is None else contact_mass)

        def rhs(t, y):
            u = F * math.cos(w * t)
            e = np.exp(mikw * t)
            e *= y[0]
            d = np.empty(4 + 2 * NH)
            d[0] = y[1]
            d[1] = u * m1_inv
            d[2] = y[3]
            d[3] = u * m2_inv
            d[4:] = e.view(np.float64)
            return d
        return rhs

    def u(self, tau):
        return self.F * math.cos(self.w * tau)

    def _snap(self, wall):
        """Put the gap exactly at the wall, keeping the centre of mass."""
        x1, v1, x2, v2 = self.y
        xc = (self.M1 * x1 + self.M2 * x2) / self.Mt
        x1 = xc - self.M2 * wall / self.Mt
        self.y[0], self.y[2] = x1, x1 + wall

    def _pressing(self, wall, u):
        return u < 0.0 if wall == 0.0 else u > 0.0

    def _impact(self, tau, wall):
        """Newton's impact at ``wall`` (gap closing), then free flight or contact (Zeno cut)."""
        M1, M2, e, Mt = self.M1, self.M2, self.eps, self.Mt
        x1, v1, x2, v2 = self.y
        self.y[1] = (v1 * (M1 - e * M2) + v2 * M2 * (1.0 + e)) / Mt
        self.y[3] = (v1 * M1 * (1.0 + e) + v2 * (M2 - e * M1)) / Mt
        self._snap(wall)
        self.impacts += 1
        self._after_touch(tau, wall)

    def _after_touch(self, tau, wall):
        """At g = wall with the gap opening (or still): merge if the next bounce is negligible."""
        u = self.u(tau)
        wrel = abs(self.y[3] - self.y[1])
        self.first_step = None
        if self._pressing(wall, u):
            if wrel * wrel * self.M2 < 2.0 * abs(u) * self.zeno * self.h:
                vc = (self.M1 * self.y[1] + self.M2 * self.y[3]) / self.Mt
                self.y[1] = self.y[3] = vc
                self.mode = wall
                return
            self.first_step = 0.125 * 2.0 * wrel * self.M2 / abs(u)
        self.mode = "free"

    def _boundary_event(self):
        """Handle an event that fell exactly on the period boundary, missed by the previous solve.

        solve_ivp only sees sign changes inside a step, so an impact or a release due at
        t = n T is invisible from both sides; it is applied here, at tau = 0, and only here
        (inside a period every event is handled where it is found).
        """
        if self.mode == "free":
            g = self.y[2] - self.y[0]
            gdot = self.y[3] - self.y[1]
            if g <= 0.0 and gdot < 0.0:
                self._impact(0.0, 0.0)
                return True
            if g >= self.h and gdot > 0.0:
                self._impact(0.0, self.h)
                return True
        elif not self._pressing(self.mode, self.u(0.0)) and self.u(0.0) != 0.0:
            self._snap(self.mode)
            self.y[3] = self.y[1]
            self.mode = "free"
            return True
        return False

    def period(self):
        """Advance one period; returns (X_k of this period, max |v|, sampled (tau, x1) or None)."""
        T = self.T
        I = np.zeros(2 * NH)
        tau = 0.0
        vmax = float(np.max(np.abs(self.y[[1, 3]])))
        ts, xs = [], []
        count = 0
        while tau < T:
            count += 1
            if count > _MAX_EVENTS:
                raise RunError("backlash: too many events in one period (Zeno not resolved?)")
            if tau == 0.0 and self._boundary_event():
                continue
            if self.mode == "free":
                rhs, events = self._free_rhs, self._free_events
            else:
                rhs, events = self._contact_rhs, self._contact_events[self.mode]
            sol = _solve(rhs, tau, T, np.concatenate((self.y, I)), self.method, self.rtol, self.atol,
                         events, first_step=self.first_step if self.mode == "free" else None,
                         t_eval=_grid(self.samples, tau, T))
            self.first_step = None
            self.nfev += sol.nfev
            if sol.y.size:
                vmax = max(vmax, float(np.max(np.abs(sol.y[[1, 3]]))))
            if sol.status == 1:
                which = 0 if sol.t_events[0].size else 1
                tev = float(sol.t_events[which][0])
                y = sol.y_events[which][0]
            else:
                tev, y = T, None
            if self.samples is not None:
                sel = sol.t < tev
                ts.append(sol.t[sel])
                xs.append(sol.y[0][sel])
            if y is None:
                y = sol.y[:, -1]
            self.y, I = y[:4].copy(), y[4:].copy()
            tau = tev
            if sol.status != 1:
                break
            self.events += 1
            if self.mode == "free":
                self._impact(tau, 0.0 if which == 0 else self.h)
            else:  # release: the force now pulls the masses apart
                self._snap(self.mode)
                self.y[3] = self.y[1]
                self.mode = "free"
        samples = None
        if self.samples is not None:
            samples = (np.concatenate(ts) if ts else np.empty(0), np.concatenate(xs) if xs else np.empty(0))
        return _coefficients(I, T), vmax, samples

    def section(self):
        x1, v1, x2, v2 = self.y
        return np.array([v1, v2 - v1, x2 - x1]), (self.mode,)


# --------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------

def _run(sim, periods):
    """Fixed number of periods; per-period coefficients, sections, optional samples."""
    T = sim.T
    X, sections, modes, ts, xs = [], [], [], [], []
    for n in range(periods):
        Xn, _, samples = sim.period()
        X.append(Xn)
        sec, mode = sim.section()
        sections.append(sec)
        modes.append(mode[0])
        if samples is not None:
            ts.append(samples[0] + n * T)
            xs.append(samples[1])
    out = dict(X=np.array(X), section=np.array(sections), mode=modes, T=T,
               nfev=sim.nfev, events=sim.events)
    if ts:
        out["t"], out["x"] = np.concatenate(ts), np.concatenate(xs)
    return out


def friction_response(F, omega, periods, M=_fr.M, B=_fr.B, Fc=_fr.Fc, Fs=_fr.Fs, method="DOP853", rtol=1e-12,
                      atol=None, dense_per_period=0):
    """Simulate the friction mass from rest for ``periods`` periods of ``F cos(omega t)``.

    Exact CVS friction (stick at v = 0 while |u| <= Fs), solve_ivp between
    events; see :class:`_FrictionRun` for why it is split this way.

    Parameters
    ----------
    F, omega : float
        Force amplitude (N) and angular frequency (rad/s).
    periods : int
        Whole periods to simulate from x = v = 0 at t = 0.
    M, B, Fc, Fs : float
        Mass, viscous, Coulomb and static friction (docs/models.md defaults).
    method, rtol, atol :
        Passed to solve_ivp; ``atol=None`` scales it per state (see ``_atol_vector``).
    dense_per_period : int
        If > 0, also return x sampled at that many equally spaced times per period.

    Returns
    -------
    dict
        ``X``: (periods, 11) complex X_k of each period; ``section``: (periods, 1)
        velocity at the end of each period; ``mode``: end-of-period mode
        (0 stick, +-1 sliding); ``T``; ``nfev``; ``events`` (v = 0 events);
        ``t``, ``x`` if sampled.
    """
    sim = _FrictionRun(F, omega, M, B, Fc, Fs, method, rtol, atol, dense_per_period)
    return _run(sim, periods)


def backlash_response(F, omega, periods, M1=_bl.M1, M2=_bl.M2, h=_bl.h, eps=_bl.eps, method="DOP853", rtol=1e-12,
                      atol=None, dense_per_period=0, zeno=1e-12):
    """Simulate the two-mass backlash from x1 = 0, x2 = h/2 at rest for ``periods`` periods.

    Free flight between impacts, Newton restitution with momentum conserved,
    Zeno accumulation cut into contact when the next bounce would be below
    ``zeno * h``; see :class:`_BacklashRun`.

    Returns
    -------
    dict
        ``X``: (periods, 11) complex X_k of x1 per period; ``section``: (periods, 3)
        (v1, v2 - v1, g) at the end of each period; ``mode``: "free", 0.0 or h
        (contact at that wall); ``T``; ``nfev``; ``events``; ``t``, ``x`` (x1) if sampled.
    """
    sim = _BacklashRun(F, omega, M1, M2, h, eps, method, rtol, atol, dense_per_period, zeno)
    out = _run(sim, periods)
    out["impacts"] = sim.impacts
    return out


def describing_function_reference(plant, F, omega, max_periods=400, average_periods=20, periodic_tol=None,
                                  **params):
    """Reference DF N = X_1 / F of ``plant`` ("friction" or "backlash") at (F, omega).

    Simulates from rest period by period until the state at whole periods
    repeats (friction: v and mode; backlash: v1, v2 - v1, g and contact mode),
    relative to ``periodic_tol`` (default max(1e-10, 10 rtol): below the
    integrator's own error the section cannot settle further). The repeat of
    the section means the last period is the periodic orbit, so its
    coefficients are the DF. If nothing repeats within ``max_periods``, the
    last ``average_periods`` periods are averaged and ``periodic`` is False.

    Parameters
    ----------
    plant : {"friction", "backlash"}
    F, omega : float
    **params
        Plant parameters and solver options (method, rtol, atol, ...).

    Returns
    -------
    dict
        ``N`` (complex), ``harmonics`` (|X_k|, k = 0..10), ``periodic``,
        ``periods`` (periods simulated), ``X`` (complex X_k), ``nfev``.
    """
    rtol = params.get("rtol", 1e-12)
    tol = max(1e-10, 10.0 * rtol) if periodic_tol is None else periodic_tol
    if plant == "friction":
        p = dict(FRICTION.defaults, **params)
        sim = _FrictionRun(F, omega, p["M"], p["B"], p["Fc"], p["Fs"], p.get("method", "DOP853"), rtol,
                           p.get("atol"), 0)
        unknown = set(params) - {"M", "B", "Fc", "Fs", "method", "rtol", "atol"}

        def scale_of(vmax):
            return np.array([vmax])
    elif plant == "backlash":
        p = dict(BACKLASH.defaults, **params)
        sim = _BacklashRun(F, omega, p["M1"], p["M2"], p["h"], p["eps"], p.get("method", "DOP853"), rtol,
                           p.get("atol"), 0, p.get("zeno", 1e-12))
        unknown = set(params) - {"M1", "M2", "h", "eps", "method", "rtol", "atol", "zeno"}

        def scale_of(vmax):
            return np.array([vmax, vmax, sim.h])
    else:
        raise InputError(f"unknown plant {plant!r} (allowed: {', '.join(PLANTS)})")
    if unknown:
        raise InputError(f"unknown parameters for {plant}: {', '.join(sorted(unknown))}")
    if F == 0.0:
        return dict(N=0j, harmonics=[0.0] * NH, periodic=True, periods=0, X=np.zeros(NH, complex), nfev=0)

    history = []
    prev = None
    for n in range(1, max_periods + 1):
        Xn, vmax, _ = sim.period()
        history.append(Xn)
        sec, mode = sim.section()
        if prev is not None:
            psec, pmode = prev
            scale = np.maximum(scale_of(vmax), 1e-300)
            if mode == pmode and np.all(np.abs(sec - psec) <= tol * scale):
                return dict(N=complex(Xn[1] / F), harmonics=[float(a) for a in np.abs(Xn)], periodic=True,
                            periods=n, X=Xn, nfev=sim.nfev)
        prev = (sec, mode)
    Xa = np.mean(history[-average_periods:], axis=0)
    return dict(N=complex(Xa[1] / F), harmonics=[float(a) for a in np.abs(Xa)], periodic=False,
                periods=max_periods, X=Xa, nfev=sim.nfev)


def static_backlash_scipy(F, omega, method, rtol, M=_sb.M, k=_sb.k, h=_sb.h, samples=2048):
    """N of the static backlash plant the way a user would write it (the benchmark's rival).

    The mass ODE by ``solve_ivp`` (``method``, ``rtol``) over two periods from
    rest, the play operator applied on a dense grid of ``samples`` points per
    period, and the first harmonic of the second period by the trapezoid rule.
    The independent reference is the closed form
    (:func:`dfwb.plants.closed_forms.static_backlash_plant_df`).
    """
    T = 2 * math.pi / omega
    sol = solve_ivp(lambda t, y: [y[1], F * math.cos(omega * t) / M], (0.0, 2 * T), [0.0, 0.0], method=method,
                    rtol=rtol, atol=rtol * F / (M * omega ** 2), dense_output=True)
    t = np.linspace(0.0, 2 * T, 2 * samples + 1)
    x = sol.sol(t)[0]
    y, out = 0.0, np.empty_like(x)
    for i, xi in enumerate(x):
        y = min(max(y, k * (xi - h / 2)), k * (xi + h / 2))
        out[i] = y
    second = slice(samples, None)
    X1 = 2.0 / T * np.trapezoid(out[second] * np.exp(-1j * omega * t[second]), t[second])
    return X1 / F
