"""Independent scipy reference for the plants in feedback with a linear controller (the closed loops).

Why this module exists
----------------------
:mod:`dfwb.fmus.loops` integrates a plant in negative feedback with a linear
controller G(s) exactly, piece by piece, with its own Taylor-series event
search. Such a solver needs a judge that shares none of its machinery. This
module is that judge: the same physics written the way a careful control
engineer would write it with scipy alone, ``scipy.integrate.solve_ivp``
(DOP853, rtol = 1e-12 and a tight absolute tolerance by default) between
events, every mode switch a *terminal* event located by solve_ivp's own root
finding on its dense output, the switching logic applied by hand at each
event and the integration restarted from there. The tests compare the event
sequences, the event times and the final states of the two.

A run can also stop at an event its caller chooses (``until``) and sample
the state from solve_ivp's dense output (``t_eval``): enough to build a
Poincare map of the loop and to integrate over a period without dfwb, as
``tests/test_cycle_truth.py`` does to check dfwb's limit-cycle search.

It imports only numpy, scipy, the controller's matrices
(:meth:`dfwb.fmus.linear_system.LinearSystem.matrices`, which also checks b
and a) and the error classes; nothing of :mod:`dfwb.fmus.hybrid` or
:mod:`dfwb.fmus.loops`.

The loop (docs/models.md, section 4)
------------------------------------
``f = -G(s) y``, ``G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an)``,
y the plant's output, f the force on the plant. The controller state z is the
controllable canonical form (``z1' = z2, ..., zn' = -an z1 - ... - a1 zn + y``)
and ``f = -(C z + D y)``. The loop's state is the plant's coordinates followed
by z:

* ``"friction"``: (x, v, z), y = x. CVS friction (no Karnopp band): sliding
  ``M v' = f - Fc sgn(v) - B v`` until v reaches 0 (event ``"band"``); at
  v = 0 the mass sticks (v = 0 held, x constant) while ``|f| <= Fs`` and breaks
  away in the direction of f when ``|f|`` reaches Fs (``"break+"``/``"break-"``).
* ``"backlash"``: (x1, v1, gap, w = v2 - v1, z), y = x1, the force on M2. Free
  flight (``v1' = 0``, ``w' = f / M2``) until the gap reaches 0 (``"gap 0"``) or
  h (``"gap h"``): Newton's impact (paper eq. 8-10, momentum kept, the relative
  velocity reversed and scaled by eps). At the wall the masses are merged
  (contact, ``(M1 + M2) v1' = f``) when f presses them together and the next
  bounce would rise no more than ``ZENO * h`` (``0.5 w^2 M2 <= ZENO h |f|``:
  the accumulation of impacts is over); contact ends when f stops pressing
  (``"release"``).
* ``"static-backlash"``: (x, v, y, z), the mass M driven by f and a geometric
  backlash of slope k and total play h giving y. In the play y is held; at an
  edge (``"engage+"``/``"engage-"``) y follows ``k (x -+ h/2)`` until v
  reverses (``"reverse"``).

A piece starts on the boundary it has just left, where solve_ivp sees a zero
of that boundary's event function. Where the departure is at zero speed (a
gap after a release or a plastic impact, x at an edge of the play after v
reversed) the function is armed ``DEPARTURE_SLACK * h`` beyond the boundary,
so rounding cannot fire it (a genuine return is found that much late: about
1e-16 m / its speed). An event found at the very start of a piece anyway (the
step overshot a quick return to v = 0 or a bounce) makes the piece integrate
again with a 16 times smaller first step, at most ``RETRIES`` times; a bounce
starts with its first step at an eighth of its estimated duration.
Every loop is bounded: a run by ``max_events`` events (:class:`RunError`
beyond), the retries by ``RETRIES``.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

from dfwb.base.errors import RunError
from dfwb.fmus.backlash import TABLE as BACKLASH
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import TABLE as FRICTION
from dfwb.fmus.linear_system import LinearSystem
from dfwb.fmus.static_backlash import TABLE as STATIC_BACKLASH

__all__ = ["closed_loop_reference", "PLANTS", "DEFAULTS", "ZENO"]

PLANTS = ("friction", "backlash", "static-backlash")
# the plants' parameters and their defaults (their tables, fmus/table.py)
DEFAULTS = {"friction": FRICTION.defaults, "backlash": BACKLASH.defaults, "static-backlash": STATIC_BACKLASH.defaults}
COORDINATES = {"friction": ("x", "v"), "backlash": ("x1", "v1", "gap", "w"), "static-backlash": ("x", "v", "y")}
ZENO = 1e-12  # contact once the next bounce would rise no more than ZENO * h
MAX_EVENTS = 100_000
RETRIES = 12  # smaller first steps tried when an event is found at the start of a piece
DEPARTURE_SLACK = 1e-15  # a gap leaving a wall at zero speed may dip this much (times h) by rounding


def _check(name, value, ok, allowed):
    """PlantError naming the value unless it is a finite real number and ``ok(value)``."""
    if not (isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool)
            and math.isfinite(value) and ok(value)):
        raise PlantError(f"{name} = {value!r} is out of range: {allowed}")
    return float(value)


def _event(fun, direction):
    """A terminal solve_ivp event ``fun(t, X)`` crossing zero in ``direction``."""
    fun.terminal = True
    fun.direction = direction
    return fun


class _Loop:
    """A plant's modes and switching logic around one controller; :meth:`run` walks the events."""

    def __init__(self, b, a, X0, p, method, rtol, atol, max_step, max_events):
        Ac, Bc, C, D = LinearSystem(b, a).matrices()  # checks the order, the lengths and the values
        self.Ac, self.Bc = np.array(Ac, dtype=float), np.array(Bc, dtype=float)
        self.C, self.D = np.array(C, dtype=float), float(D)
        self.Bc_now = self.Bc
        self.n = len(Ac)
        self.m = len(X0) - self.n
        self.p = p
        self.method, self.rtol, self.max_step, self.max_events = method, rtol, max_step, max_events
        scale = max(float(np.max(np.abs(X0[:self.m]))), self.length(), 1e-3)
        self.atol = 1e-3 * rtol * scale if atol is None else atol
        self.X = np.array(X0, dtype=float)
        self.t = 0.0
        self.log = []
        self.counts = {}
        self.nfev = 0
        self.first_step = None  # a cap on the next piece's first step (a bounce's duration)
        self.stopped = False  # whether ``until`` stopped the run at an event
        self.samples = None  # the states at run's t_eval (None without)
        self.correction = 0.0  # a backlash inverse's: the controller sees y + correction

    # -- the controller ---------------------------------------------------------------
    def force(self, X):
        """f = -(C z + D y), y corrected by a backlash inverse."""
        return -(self.C @ X[self.m:] + self.D * (X[self.OUTPUT] + self.correction))

    def force_rate(self, X, dX):
        """df/dt from the state and its derivative (between events, where the correction is constant)."""
        return -(self.C @ dX[self.m:] + self.D * dX[self.OUTPUT])

    def controller(self, X):
        """z' = Ac z + Bc y (Bc without its integrator's part while a deadband holds it; y corrected)."""
        return self.Ac @ X[self.m:] + self.Bc_now * (X[self.OUTPUT] + self.correction)

    def length(self):
        return 0.0

    # -- the walk -------------------------------------------------------------------------
    def _solve(self, rhs, t_end, events, first_step, dense):
        kwargs = {} if first_step is None else {"first_step": min(first_step, t_end - self.t)}
        sol = solve_ivp(rhs, (self.t, t_end), self.X, method=self.method, rtol=self.rtol, atol=self.atol,
                        events=events, max_step=self.max_step, dense_output=dense, **kwargs)
        self.nfev += sol.nfev
        if sol.status == -1:
            raise RunError(f"solve_ivp failed at t = {sol.t[-1]!r} s in mode {self.mode_name()}: {sol.message}")
        return sol

    def run(self, t_end, t_eval=None, until=None):
        """Walk the events to ``t_end`` (or to the event ``until`` stops at); the state at ``t_eval`` if given."""
        dense = t_eval is not None
        if dense:
            self.samples = np.full((len(t_eval), len(self.X)), np.nan)
            taken = 0  # t_eval[:taken] are sampled
        while self.t < t_end:
            rhs, events, kinds = self.system()
            first = self.first_step
            self.first_step = None
            for retry in range(RETRIES + 1):
                sol = self._solve(rhs, t_end, events, first, dense)
                if sol.status != 1:
                    break
                which = min((float(te[0]), i) for i, te in enumerate(sol.t_events) if te.size)
                if which[0] > self.t or retry == RETRIES:
                    break
                # found at the piece's start: the departure itself, or a return within the first step
                first = (t_end - self.t if first is None else first) / 16.0
            if dense:  # the piece covers (its start, its end], the first one also t = 0
                end = int(np.searchsorted(t_eval, sol.t[-1], side="right"))
                if end > taken:
                    self.samples[taken:end] = sol.sol(t_eval[taken:end]).T
                    taken = end
            if sol.status != 1:
                self.t, self.X = t_end, sol.y[:, -1].copy()
                break
            t_ev, index = which
            if len(self.log) >= self.max_events:
                raise RunError(f"more than {self.max_events} events before t = {t_ev!r} s (last: "
                               f"{kinds[index]}): the motion chatters")
            self.t, self.X = t_ev, sol.y_events[index][0].copy()
            self.log.append((t_ev, kinds[index]))
            before = self.mode_name()
            self.fire(kinds[index])
            if until is not None and until(kinds[index], before):
                self.stopped = True
                break
        if dense:  # no piece integrated (t_end = 0): the times at the start take the initial state
            end = int(np.searchsorted(t_eval, self.t, side="right"))
            self.samples[taken:end] = self.X
        return self


class _Friction(_Loop):
    """Mass with CVS friction: modes "stick" (v = 0 held), +1 / -1 (sliding with sgn v).

    With a Coulomb feedforward ``F_hat sgn(signal)`` the mass feels f plus it: the signal is its velocity
    (nothing while it sticks) or the controller's force f, whose sign changes at an event ``"coulomb"``.
    """

    OUTPUT = 0

    def __init__(self, *args):
        super().__init__(*args)
        self.F_hat, self.signal = self.p.get("coulomb") or (0.0, None)
        self.a, self.w_d = self.p.get("dither") or (0.0, 1.0)
        self.d = self.p.get("deadband")
        self.integrator = self.integrator_mode() if self.p.get("reset") or self.d else None
        self.held = False  # within the deadband, the integrator holds
        if self.d:
            self.hold(abs(self.X[self.OUTPUT]) < self.d)
        f = self.force(self.X)
        self.sign = 1 if f > 0.0 else -1 if f < 0.0 else 0  # the controller's force's sign (signal "control")
        self.counts = {"sticks": 0}
        if self.X[1] != 0.0:
            self.mode = 1 if self.X[1] > 0.0 else -1
        else:
            self.rest()  # a stick phase from t = 0 counts as one

    def mode_name(self):
        return {0: "stick", 1: "slide+", -1: "slide-"}[self.mode]

    def length(self):
        return self.p["Fs"] / max(1.0, abs(self.D))  # the play of x while the force stays below Fs

    def integrator_mode(self):
        """(w, e): the controller's integrator, its coordinate w . z (w^T Ac = 0, w . Bc = 1) and its direction
        e (Ac e = 0, w . e = 1), from the null spaces of Ac^T and Ac (numerically, apart from dfwb's closed form)."""
        from scipy.linalg import null_space

        left, right = null_space(self.Ac.T), null_space(self.Ac)
        if left.shape[1] != 1 or right.shape[1] != 1:
            raise PlantError("integrator management (reset, deadband) needs a controller with one integrator (a "
                             "simple pole at 0)")
        w = left[:, 0] / (left[:, 0] @ self.Bc)
        e = right[:, 0] / (w @ right[:, 0])
        return w, e

    def hold(self, held):
        """Hold the integrator (its part of Bc, e (w . Bc) = e, removed) or let it integrate."""
        self.held = held
        self.Bc_now = self.Bc - self.integrator[1] if held else self.Bc

    def feedforward(self, s):
        """The compensator's force in mode s (constant between events)."""
        return self.F_hat * (s if self.signal == "velocity" else self.sign if self.signal == "control" else 0)

    def dither(self, t):
        """The dither's force a sin(w_d t) at t."""
        return self.a * math.sin(self.w_d * t)

    def rhs_for(self, s):
        M, B, Fc = self.p["M"], self.p["B"], self.p["Fc"]
        k = self.feedforward(s)

        def rhs(t, X):
            dX = np.empty_like(X)
            if s == 0:
                dX[0] = dX[1] = 0.0
            else:
                dX[0] = X[1]
                dX[1] = (self.force(X) + k + self.dither(t) - s * Fc - B * X[1]) / M
            dX[2:] = self.controller(X)
            return dX
        return rhs

    def rest(self):
        """v = 0: stick while |f| <= Fs, else slide in the direction of f (|f| = Fs: slide where f heads beyond)."""
        self.X[1] = 0.0
        if not self.breaks_away():
            self.mode = 0
            self.counts["sticks"] += 1

    def breaks_away(self):
        """At rest: slide (True) where the force on the mass, f and the feedforward, is beyond Fs."""
        f, Fs = self.force(self.X) + self.feedforward(0) + self.dither(self.t), self.p["Fs"]
        if abs(f) == Fs:  # on the level: it breaks away where the force heads beyond it, else sticks
            rate = (self.force_rate(self.X, self.rhs_for(0)(self.t, self.X))
                    + self.a * self.w_d * math.cos(self.w_d * self.t))
            if f * rate <= 0.0:
                return False
        if abs(f) >= Fs:
            self.mode = 1 if f > 0.0 else -1
            return True
        return False

    def system(self):
        s = self.mode
        k = self.feedforward(s)
        if s == 0:
            Fs = self.p["Fs"]
            events = [_event(lambda t, X: self.force(X) + k + self.dither(t) - Fs, 1),
                      _event(lambda t, X: self.force(X) + k + self.dither(t) + Fs, -1)]
            kinds = ["break+", "break-"]
        else:
            events, kinds = [_event(lambda t, X: X[1], -s)], ["band"]
        if self.signal == "control":  # the controller's force crossing 0 switches the feedforward
            events.append(_event(lambda t, X: self.force(X), -self.sign))
            kinds.append("coulomb")
        if self.d:  # y reaching the band's edges: from within outwards, from outside inwards
            d, y = self.d, self.OUTPUT
            inside = self.held
            outside_up = not inside and self.X[y] > 0.0
            if inside or outside_up:
                events.append(_event(lambda t, X: X[y] - d, 1 if inside else -1))
                kinds.append("deadband")
            if inside or not outside_up:
                events.append(_event(lambda t, X: X[y] + d, -1 if inside else 1))
                kinds.append("deadband")
        return self.rhs_for(s), events, kinds

    def fire(self, kind):
        if kind == "deadband":
            self.hold(not self.held)
        elif kind == "coulomb":
            rate = self.force_rate(self.X, self.rhs_for(self.mode)(self.t, self.X))
            self.sign = -self.sign if self.sign else (1 if rate > 0.0 else -1)
            if self.mode == 0:
                self.breaks_away()  # the force on the stuck mass jumped by 2 F_hat
        elif kind == "band":
            if self.p.get("reset"):  # the mass comes to rest: its integrator cleared, then stick or not
                w, e = self.integrator
                z = self.X[self.m:]
                self.X[self.m:] = z - (w @ z) * e
                f = self.force(self.X)  # it jumped: the feedforward of its sign follows it
                self.sign = 1 if f > 0.0 else -1 if f < 0.0 else self.sign
            self.rest()
        else:
            self.X[1] = 0.0
            self.mode = 1 if kind == "break+" else -1


class _Backlash(_Loop):
    """Two masses with clearance h: modes "free" and ("contact", -1) at gap 0 / ("contact", +1) at gap h."""

    OUTPUT = 0

    def __init__(self, *args):
        super().__init__(*args)
        self.counts = {"impacts": 0}
        self.departing = None  # the wall just left at zero speed (its event armed a rounding below it)
        gap, h = self.X[2], self.p["h"]
        self.mode = "free"
        if gap <= 0.0 or gap >= h:
            self.touch(-1 if gap <= 0.0 else 1)
            self.at_wall(-1 if gap <= 0.0 else 1)

    def touch(self, sigma):
        """A backlash inverse's correction after a touch of the wall ``sigma``: the controller sees x1 +
        h_hat/2 sigma (x2 - h/2 with h_hat = h, M2 on that wall)."""
        self.correction = 0.5 * self.p.get("inverse", 0.0) * sigma

    def mode_name(self):
        return self.mode if self.mode == "free" else f"contact{'-+'[self.mode[1] > 0]}"

    def length(self):
        return self.p["h"]

    def rhs_for(self, mode):
        M1, M2 = self.p["M1"], self.p["M2"]

        def rhs(t, X):
            dX = np.empty_like(X)
            f = self.force(X)
            dX[0] = X[1]
            if mode == "free":
                dX[1], dX[2], dX[3] = 0.0, X[3], f / M2
            else:
                dX[1], dX[2], dX[3] = f / (M1 + M2), 0.0, 0.0
            dX[4:] = self.controller(X)
            return dX
        return rhs

    def pressing(self, sigma):
        """f pushes M2 into the wall ``sigma`` (f = 0: the way f is heading)."""
        f = self.force(self.X)
        if f == 0.0:
            f = self.force_rate(self.X, self.rhs_for(("contact", sigma))(self.t, self.X))
        return sigma * f > 0.0

    def at_wall(self, sigma):
        """At the wall ``sigma`` after any impact: contact if pressed with a negligible bounce, else free."""
        M1, M2, h = self.p["M1"], self.p["M2"], self.p["h"]
        X = self.X
        X[2] = 0.0 if sigma < 0 else h
        w = X[3]
        if self.pressing(sigma) and 0.5 * w * w * M2 <= ZENO * h * abs(self.force(X)):
            v2 = X[1] + w
            X[1] = (M1 * X[1] + M2 * v2) / (M1 + M2)  # the centre of mass's velocity
            X[3] = 0.0
            self.mode = ("contact", sigma)
            return
        self.mode = "free"
        if w == 0.0:
            self.departing = sigma
        elif self.pressing(sigma):  # a bounce: start within it
            self.first_step = 0.25 * abs(w) * M2 / abs(self.force(X))

    def system(self):
        h = self.p["h"]
        if self.mode == "free":
            low = h * DEPARTURE_SLACK if self.departing == -1 else 0.0
            high = h * DEPARTURE_SLACK if self.departing == 1 else 0.0
            self.departing = None
            events = [_event(lambda t, X: X[2] + low, -1), _event(lambda t, X: X[2] - h - high, 1)]
            return self.rhs_for("free"), events, ["gap 0", "gap h"]
        sigma = self.mode[1]
        return self.rhs_for(self.mode), [_event(lambda t, X: sigma * self.force(X), -1)], ["release"]

    def fire(self, kind):
        if kind == "release":
            sigma = self.mode[1]
            self.X[2] = 0.0 if sigma < 0 else self.p["h"]
            self.X[3] = 0.0
            self.mode = "free"
            self.departing = sigma
            return
        sigma = -1 if kind == "gap 0" else 1
        M1, M2, eps = self.p["M1"], self.p["M2"], self.p["eps"]
        v1, w = self.X[1], self.X[3]
        if sigma * w > 0.0:  # closing: Newton's law of impact (paper eq. 8-10)
            v2 = v1 + w
            v1n = (v1 * (M1 - eps * M2) + v2 * M2 * (1.0 + eps)) / (M1 + M2)
            v2n = (v1 * M1 * (1.0 + eps) + v2 * (M2 - eps * M1)) / (M1 + M2)
            self.X[1], self.X[3] = v1n, v2n - v1n
            self.counts["impacts"] += 1
        self.touch(sigma)
        self.at_wall(sigma)


class _StaticBacklash(_Loop):
    """Mass and geometric backlash: modes "free" (y held) and ("engaged", +1 / -1) (y = k (x -+ h/2))."""

    OUTPUT = 2

    def __init__(self, *args):
        super().__init__(*args)
        self.counts = {"engagements": 0}
        self.departing = None  # the edge just left (its event armed a rounding beyond it)
        k, h = self.p["k"], self.p["h"]
        play = self.X[0] - self.X[2] / k
        self.mode = "free"
        for s in (1, -1):
            if s * play >= 0.5 * h * (1.0 - 1e-12):
                self.engage(s, count=False)
                break

    def mode_name(self):
        return self.mode if self.mode == "free" else f"engaged{'-+'[self.mode[1] > 0]}"

    def length(self):
        return self.p["h"]

    def rhs_for(self, mode):
        M, k = self.p["M"], self.p["k"]

        def rhs(t, X):
            dX = np.empty_like(X)
            dX[0] = X[1]
            dX[1] = self.force(X) / M
            dX[2] = 0.0 if mode == "free" else k * X[1]
            dX[3:] = self.controller(X)
            return dX
        return rhs

    def snap(self, s):
        """Put y exactly on the edge s of the play."""
        self.X[2] = self.p["k"] * (self.X[0] - s * 0.5 * self.p["h"])

    def engage(self, s, count=True):
        """At the edge s: a backlash inverse's correction takes the side s, then engaged if x moves on (v = 0: if
        f pushes on), else free."""
        self.correction = 0.5 * self.p["k"] * self.p.get("inverse", 0.0) * s
        self.snap(s)
        v = self.X[1]
        if s * v > 0.0 or (v == 0.0 and s * self.force(self.X) > 0.0):
            self.mode = ("engaged", s)
            self.counts["engagements"] += count
        else:
            self.mode = "free"
            self.departing = s

    def system(self):
        k, half = self.p["k"], 0.5 * self.p["h"]
        if self.mode == "free":
            up = half + self.p["h"] * DEPARTURE_SLACK if self.departing == 1 else half
            down = half + self.p["h"] * DEPARTURE_SLACK if self.departing == -1 else half
            self.departing = None
            events = [_event(lambda t, X: X[0] - X[2] / k - up, 1),
                      _event(lambda t, X: X[0] - X[2] / k + down, -1)]
            return self.rhs_for("free"), events, ["engage+", "engage-"]
        s = self.mode[1]
        return self.rhs_for(self.mode), [_event(lambda t, X: X[1], -s)], ["reverse"]

    def fire(self, kind):
        if kind == "reverse":
            self.snap(self.mode[1])
            self.X[1] = 0.0
            self.departing = self.mode[1]
            self.mode = "free"
            return
        self.engage(1 if kind == "engage+" else -1)


_CLASSES = {"friction": _Friction, "backlash": _Backlash, "static-backlash": _StaticBacklash}


def _parameters(plant, params):
    """The plant's parameters with the defaults filled in, checked (PlantError naming a bad one)."""
    p = dict(DEFAULTS[plant])
    for name, value in (params or {}).items():
        if name not in p and name != "z0":
            raise PlantError(f"{name!r} is not a parameter of the {plant} loop: it has {sorted(p)} and z0")
        p[name] = value
    positive = (lambda v: v > 0.0, "must be > 0")
    finite = (lambda v: True, "must be a finite number")
    rules = {
        "friction": {"M": positive, "B": (lambda v: v >= 0.0, "must be >= 0"),
                     "Fc": (lambda v: v >= 0.0, "must be >= 0"), "Fs": (lambda v: v >= p["Fc"], "must be >= Fc"),
                     "Dv": (lambda v: v == 0.0, "must be 0 (exact stick, the CVS model)"),
                     "x0": finite, "v0": finite},
        "backlash": {"M1": positive, "M2": positive, "h": positive,
                     "eps": (lambda v: 0.0 <= v <= 1.0, "must be in [0, 1]"),
                     "x1_0": finite, "v1_0": finite, "v2_0": finite},
        "static-backlash": {"M": positive, "k": positive, "h": positive, "x0": finite, "v0": finite},
    }[plant]
    for name, (ok, allowed) in rules.items():
        p[name] = _check(name, p[name], ok, allowed)
    if plant == "backlash":
        h = p["h"]
        p["gap0"] = 0.5 * h if p["gap0"] is None else p["gap0"]
        p["gap0"] = _check("gap0", p["gap0"], lambda v: 0.0 <= v <= h, f"must be in [0, h] = [0, {h!r}]")
    return p


def _initial_state(plant, p, n, state):
    """The loop's state at t = 0: ``state`` checked, or the plant's initial values and z0 (zeros)."""
    names = COORDINATES[plant]
    if state is None:
        q = {"friction": lambda: [p["x0"], p["v0"]],
             "backlash": lambda: [p["x1_0"], p["v1_0"], p["gap0"], p["v2_0"] - p["v1_0"]],
             "static-backlash": lambda: [p["x0"], p["v0"], p["k"] * p["x0"]]}[plant]()
        z0 = [0.0] * n if p.get("z0") is None else list(p["z0"])
        if len(z0) != n:
            raise PlantError(f"length of z0 = {len(z0)} is out of range: the controller's order is {n}")
        state = q + z0
    state = list(state)
    if len(state) != len(names) + n:
        raise PlantError(f"length of state = {len(state)} is out of range: the {plant} loop has "
                         f"{len(names)} plant coordinates {names} and {n} controller states")
    labels = list(names) + [f"z{i}" for i in range(1, n + 1)]
    X = [_check(label, value, lambda v: True, "must be a finite number") for label, value in zip(labels, state)]
    if plant == "backlash":
        h = p["h"]
        _check("gap", X[2], lambda v: 0.0 <= v <= h, f"the gap must be in [0, h] = [0, {h!r}]")
    if plant == "static-backlash":
        play = X[0] - X[2] / p["k"]
        _check("x - y/k", play, lambda v: abs(v) <= 0.5 * p["h"] * (1.0 + 1e-9),
               f"the play must be within +-h/2 = {0.5 * p['h']!r}")
    return X


def _times(t_eval, t_end):
    """``t_eval`` as a float array, checked: sorted finite times in [0, t_end] (PlantError naming a bad one)."""
    if isinstance(t_eval, (str, bytes)) or not hasattr(t_eval, "__len__") or np.ndim(t_eval) != 1:
        raise PlantError(f"t_eval = {t_eval!r} is out of range: a sorted sequence of times in [0, t_end]"
                         .replace("\n", " "))
    allowed = f"must be a finite time in [0, t_end] = [0, {t_end!r}] (s)"
    times = [_check(f"t_eval[{i}]", v, lambda v: 0.0 <= v <= t_end, allowed) for i, v in enumerate(t_eval)]
    for i in range(1, len(times)):
        if times[i] < times[i - 1]:
            raise PlantError(f"t_eval[{i}] = {times[i]!r} is out of range: t_eval must be sorted, and "
                             f"t_eval[{i - 1}] = {times[i - 1]!r} is later")
    return np.array(times, dtype=float)


def closed_loop_reference(plant, b, a, t_end, params=None, state=None, method="DOP853", rtol=1e-12, atol=None,
                          max_step=np.inf, max_events=MAX_EVENTS, t_eval=None, until=None, coulomb=None,
                          reset=False, deadband=None, dither=None, inverse=None):
    """Simulate a plant in feedback with ``-G(s)`` from t = 0 to ``t_end`` with solve_ivp and exact events.

    Parameters
    ----------
    plant : str
        ``"friction"``, ``"backlash"`` or ``"static-backlash"``.
    b, a : sequence of float
        ``G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an)``: ``b`` has
        n + 1 coefficients, ``a`` has n (1 <= n <= 8), all finite.
    t_end : float
        The end time (s), finite and >= 0.
    params : dict, optional
        The plant's parameters (see ``DEFAULTS[plant]``; missing ones take the
        defaults), plus ``"z0"``, the controller's initial state (zeros).
        friction: M, B, Fc, Fs, Dv (must be 0), x0, v0; backlash: M1, M2, h,
        eps, x1_0, v1_0, v2_0, gap0 (h/2); static-backlash: M, k, h, x0, v0
        (y starts at k x0).
    state : sequence of float, optional
        The whole loop state at t = 0, the plant's coordinates then z, as
        ``dfwb.fmus.loops`` orders it (friction: x, v; backlash: x1, v1, gap,
        w = v2 - v1; static-backlash: x, v, y); it overrides the initial values
        in ``params``.
    method : str
        solve_ivp's method.
    rtol : float
        Relative tolerance.
    atol : float or array, optional
        Absolute tolerance; default ``1e-3 * rtol`` times the plant's length
        scale (the largest of the initial coordinates, h, and 1e-3).
    max_step : float
        solve_ivp's largest step (no limit by default).
    max_events : int
        The most events allowed before t_end.
    t_eval : sequence of float, optional
        Sorted times in [0, t_end] (s) at which to sample the loop state (the
        result's ``samples``). Each is read from solve_ivp's dense output of
        the piece (the integration between two events) that contains it; a
        time exactly at an event is read from the piece that ends there, so
        it is the state just *before* the event's switching logic acts (an
        impact's velocities before the impact). Dense output is asked for
        only when ``t_eval`` is given (it costs a few more right-hand side
        evaluations per step, counted in ``nfev``; the steps, events and
        states are unchanged).
    until : callable, optional
        ``until(kind, mode_before) -> bool``, called after every event with
        the event's kind (as in ``events``) and the name of the mode the loop
        was in just before it (as the result's ``mode`` spells it: "stick",
        "slide+", "slide-"; "free", "contact-", "contact+"; "free",
        "engaged-", "engaged+"). When it returns True the run stops right
        there: ``state`` and ``mode`` are those the event left, ``t`` is the
        event's time, and the samples of later times are NaN.
    coulomb : (float, str), optional
        friction only: a Coulomb feedforward ``F_hat sgn(signal)`` added to the
        force, ``(F_hat, "velocity")`` (the mass's velocity: nothing while it
        sticks) or ``(F_hat, "control")`` (the controller's force; its sign
        changes at events "coulomb").
    reset : bool
        friction only: clear the controller's integrator whenever the mass
        comes to rest (at every event "band"), before it sticks or breaks away.
    deadband : float, optional
        friction only: the controller's integrator holds while |y| < deadband
        (events "deadband" at its edges).
    dither : (float, float), optional
        friction only: ``(a, w_d)``, the force ``a sin(w_d t)`` added to the
        force on the mass (t from the run's start). The steps are then at
        most a 32nd of its period (``max_step``): solve_ivp sees an event
        only where its function changes sign between two steps, and a stuck
        mass's equations alone would let it step over the dither's peaks.
    inverse : float, optional
        backlash and static-backlash: a backlash inverse's estimated play
        h_hat. The controller then sees ``y + k h_hat/2 s`` for y (k = 1 for
        the backlash), s the side of the play's last touch (0 before any):
        set where the mass reaches an edge of the play (static-backlash) or
        M2 a wall (backlash), and at t = 0 on one, before the event's own
        logic (which sees the force it makes).

    Returns
    -------
    dict
        ``state`` (the loop state at t_end, a list), ``events`` (a list of
        ``(t, kind)``, kind a string as ``dfwb.fmus.contract.EventKind``
        spells it: "band", "break+", "break-", "gap 0", "gap h", "release",
        "engage+", "engage-", "reverse"), ``mode`` (the final mode's name),
        ``counts`` (sticks, impacts or engagements), ``nfev`` (right-hand side
        evaluations), ``t`` (= t_end, or the time of the event ``until``
        stopped at). Counted as dfwb.fmus.loops counts them: stick phases
        including one from t = 0, impacts, engagements by an event (not one
        at t = 0). With ``t_eval``, also ``samples``: a numpy array of shape
        (len(t_eval), state size), the loop state (ordered as ``state``) at
        each of the times (NaN after an ``until`` stop).

    Raises
    ------
    PlantError
        A plant name, coefficient, parameter, state, t_end, t_eval (unsorted,
        outside [0, t_end], not finite) or until (not callable) out of range
        (the message names it).
    RunError
        More than ``max_events`` events, or solve_ivp failing.

    Examples
    --------
    >>> r = closed_loop_reference("friction", [30.0, 60.0], [0.0], 2.0, {"x0": 0.3})
    >>> [kind for _t, kind in r["events"]][:3]
    ['band', 'break+', 'band']

    Stop the first time the mass comes to rest from sliding forwards, and
    sample the state on the way (the first sample is the start, x0 = 0.3 at
    rest with z = 0):

    >>> seen = []
    >>> def stop(kind, mode_before):
    ...     seen.append((kind, mode_before))
    ...     return kind == "band" and mode_before == "slide+"
    >>> r = closed_loop_reference("friction", [30.0, 60.0], [0.0], 20.0, {"x0": 0.3}, t_eval=[0.0, 0.5, 19.0],
    ...                           until=stop)
    >>> seen
    [('band', 'slide-'), ('break+', 'stick'), ('band', 'slide+')]
    >>> r["mode"], r["t"] == r["events"][-1][0] < 20.0, r["state"][1]
    ('stick', True, 0.0)
    >>> r["samples"][0].tolist(), bool(r["samples"][1, 1] < 0.0), bool(np.isnan(r["samples"][2]).all())
    ([0.3, 0.0, 0.0], True, True)
    """
    if plant not in _CLASSES:
        raise PlantError(f"plant = {plant!r} is out of range: one of {PLANTS}")
    n = len(list(a))
    LinearSystem(b, a)  # checks the controller before anything else
    _check("t_end", t_end, lambda v: v >= 0.0, "must be a finite number >= 0 (s)")
    if not (isinstance(max_events, int) and max_events >= 0):
        raise PlantError(f"max_events = {max_events!r} is out of range: a whole number >= 0")
    if t_eval is not None:
        t_eval = _times(t_eval, float(t_end))
    if until is not None and not callable(until):
        raise PlantError(f"until = {until!r} is out of range: a callable until(kind, mode_before) or None")
    p = _parameters(plant, params)
    if coulomb is not None:
        if plant != "friction" or not (isinstance(coulomb, tuple) and len(coulomb) == 2
                                       and coulomb[1] in ("velocity", "control")):
            raise PlantError(f"coulomb = {coulomb!r} is out of range: (F_hat, 'velocity' or 'control'), friction only")
        p["coulomb"] = (_check("F_hat", coulomb[0], lambda v: v >= 0.0, "must be >= 0"), coulomb[1])
    if reset is not False:
        if plant != "friction" or reset is not True:
            raise PlantError(f"reset = {reset!r} is out of range: True or False, friction only")
        p["reset"] = True
    if deadband is not None:
        if plant != "friction":
            raise PlantError(f"deadband = {deadband!r}: friction only")
        p["deadband"] = _check("deadband", deadband, lambda v: v >= 0.0, "must be >= 0")
    if dither is not None:
        if plant != "friction" or not (isinstance(dither, tuple) and len(dither) == 2):
            raise PlantError(f"dither = {dither!r} is out of range: (a, w_d), friction only")
        p["dither"] = (_check("a", dither[0], lambda v: v >= 0.0, "must be >= 0"),
                       _check("w_d", dither[1], lambda v: v > 0.0, "must be > 0"))
        max_step = min(max_step, 2.0 * math.pi / p["dither"][1] / 32.0)
    if inverse is not None:
        if plant == "friction":
            raise PlantError(f"inverse = {inverse!r}: a plant with a play only (backlash, static-backlash)")
        p["inverse"] = _check("inverse", inverse, lambda v: v >= 0.0, "must be >= 0")
    X0 = _initial_state(plant, p, n, state)
    loop = _CLASSES[plant](b, a, X0, p, method, rtol, atol, max_step, max_events)
    loop.run(float(t_end), t_eval, until)
    result = {"state": [float(v) for v in loop.X], "events": list(loop.log), "mode": loop.mode_name(),
              "counts": dict(loop.counts), "nfev": loop.nfev, "t": loop.t if loop.stopped else float(t_end)}
    if t_eval is not None:
        result["samples"] = loop.samples
    return result
