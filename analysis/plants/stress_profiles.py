"""The stress profiles of the built-in plants (:attr:`dfwb.plants.registry.Plant.stress`).

Each profile carries what ``dfwb stress`` knows about one plant and nothing
else (see :class:`~dfwb.plants.stress_kit.StressProfile`): its cases, from the
edges of every parameter's range to seeded random ones; the invariants of its
physics at every communication point (an observer); its end-of-run energy and
momentum balances; its random held inputs, 1e5-period cases and invalid
parameters. The suite that runs them is :mod:`dfwb.verify.stress`.
"""

import math

from dfwb.fmus.backlash import TABLE as BACKLASH_TABLE
from dfwb.fmus.drivetrain import TABLE as DRIVETRAIN_TABLE
from dfwb.fmus.friction import TABLE as FRICTION_TABLE
from dfwb.fmus.static_backlash import TABLE as STATIC_BACKLASH_TABLE
from dfwb.fmus.stribeck import TABLE as STRIBECK_TABLE
from dfwb.plants.stress_kit import (
    EPS,
    TWO_PI,
    Case,
    StressObserver,
    StressProfile,
    adder,
    energy_balance,
    held_sine,
    loguniform,
    pattern,
    random_stepping,
    uniform,
)

__all__ = ["FRICTION", "STRIBECK", "BACKLASH", "DRIVETRAIN", "STATIC_BACKLASH", "EPS_VALUES"]

EPS_VALUES = (0.0, 1e-9, 0.5, 1.0 - 1e-9, 1.0)  # restitution coefficients every backlash case family covers
# An integrated plant's balances hold to its tolerance rtol, not to rounding: their allowance is this many rtol of
# the scale (each slide's velocity is accurate to rtol of its peak, its steps' errors adding up)
INTEGRATED_SLACK = 100.0


# -- friction: a mass with Coulomb, viscous and static friction -------------------------
def _friction_cases(name, rng, quick):
    cases = []

    add = adder(name, cases)

    base = dict(M=1.0, B=0.0, Fc=5.0, Fs=5.0, F=10.0, omega=1.0)
    add(base, note="baseline Fs=Fc, B=0")
    add(dict(base, B=0.5, Fs=7.0), note="default friction Fs>Fc, B>0")
    for F in (1e-6, 1e-3, 1e3, 1e6):  # the force's scale, stick-slip kept (Fs = Fc = F/2)
        add(dict(base, F=F, Fc=F / 2, Fs=F / 2), note=f"F={F:g}, Fs=Fc=F/2")
    add(dict(base, F=1e-6), note="F=1e-6 << Fs: stuck forever")
    add(dict(base, F=1e6), note="F=1e6 >> Fs")
    for w in (1e-4, 1e-2, 1e2, 1e4):
        add(dict(base, omega=w), note=f"w={w:g}")
    for M in (1e-6, 1e6):
        add(dict(base, M=M), note=f"M={M:g}")
    add(dict(base, M=1e-6, F=1e6, Fc=5e5, Fs=5e5, omega=1e4), note="M=1e-6, F=1e6, w=1e4")
    add(dict(base, M=1e6, F=1e-6, Fc=5e-7, Fs=5e-7, omega=1e-4), per_period=8, note="M=1e6, F=1e-6, w=1e-4")
    # the force touching Fs exactly, and just above or below it
    add(dict(base, F=5.0), note="F = Fs: tangent, never exceeds")
    add(dict(base, F=5.0 * (1 + 1e-12)), note="F = Fs (1 + 1e-12)")
    add(dict(base, F=5.0 * (1 - 1e-12)), note="F = Fs (1 - 1e-12)")
    add(dict(base, Fs=7.0, F=5.0, f=2.0), note="f + F = Fs exactly (peak touches Fs)")
    # a constant force of exactly +-Fs (F = 0): must stay stuck whatever phi
    for f in (7.0, -7.0):
        add(dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, f=f, omega=1.0), n_periods=2,
            note=f"constant f = {f:+g} = +-Fs, F = 0")
    add(dict(base, f=3.0, phi=0.7), note="offset f=3, phi=0.7")
    add(dict(base, F=-10.0, phi=-2.0), note="negative F")
    add(dict(base, v0=3.0, x0=1e6), note="x0=1e6, v0=3")
    add(dict(M=1.0, B=0.0, Fc=0.0, Fs=0.0, F=10.0, omega=1.0, v0=-2.0), note="free mass (Fc=Fs=B=0)")
    add(dict(M=2.0, B=0.3, Fc=0.0, Fs=0.0, F=10.0, omega=3.0), note="linear mass-damper")
    add(dict(base, Dv=1e-3), note="Karnopp Dv=1e-3")
    add(dict(base, Dv=1e-9, Fs=7.0, B=0.5), note="Karnopp Dv=1e-9")
    # communication steps at both ends of the range
    add(dict(base, F=1e6, Fc=1e5, Fs=1e5, omega=1e4), times=uniform(1e-6, 1000), note="dt=1e-9 from t=0")
    t_late = (10.0,) + tuple(10.0 + 1e-9 * k for k in range(1, 1001))
    add(base, times=(t_late, "t=10 in one step, then 1000 steps of 1e-9 s"), note="dt=1e-9 at t=10")
    add(dict(base, omega=1e-4), times=uniform(1.2e6, 1200), note="dt=1e3 s, w=1e-4")
    t_far = (1e6,) + tuple(1e6 + 1e-9 * k for k in range(1, 1001))
    add(dict(base, omega=1e-3), times=(t_far, "t=1e6 in one step, then 1000 steps of 1e-9 s (~8.6 ulp of t each)"),
        note="dt=1e-9 at t=1e6, w=1e-3")
    add(dict(base, harmonics=0), note="harmonics=0")
    add(base, times=uniform(1e4, 10), note="dt=1e3 s, w=1 (160 periods per step)")
    # held input, as an FMI master feeds a sine
    c = add(dict(M=1.0, B=0.0, Fc=5.0, Fs=5.0, F=0.0, omega=1.0), note="held sine input 10 sin, 32/period")
    held_sine(c, 10.0, 32)
    c = add(dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, omega=1.0), times=uniform(1e-3, 1000),
            note="held input, dt=1e-6, alternating sign")
    c.inputs = tuple(8.0 if (j // 100) % 2 == 0 else -8.0 for j in range(1000))
    c.input_form = "8.0 if (j // 100) % 2 == 0 else -8.0"

    friction = dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, omega=1.0)
    cases.append(pattern(name, friction, [(8.0, 10), (-8.0, 20), (8.0, 10)], 0.1,
                         "held steps +-8: v returns to 0 exactly at a step"))
    cases.append(pattern(name, friction, [(8.0, 10), (0.0, 10), (7.0, 10), (-7.0, 10)], 0.1,
                         "held steps to 0 and to +-Fs exactly"))
    for i in range(30 if quick else 150):
        cases.append(_random_friction(name, rng, i))
    if not quick:
        for F in (1e-6, 1e6):
            for w in (1e-4, 1e4):
                for M in (1e-6, 1e6):
                    add(dict(base, F=F, Fc=F / 2, Fs=F / 2, omega=w, M=M), note=f"corner F={F:g} w={w:g} M={M:g}")
    return cases


def _random_friction(name, rng, i):
    params = _random_mass_with_friction(rng, (1e-6, 1e6), (1e-6, 1e6), (1e-4, 1e4), 1.5, 0.5)
    times, stepping = random_stepping(rng, TWO_PI / params["omega"], rng.randint(2, 10))
    return Case(name, params, times, stepping, note=f"random #{i}")


def _random_mass_with_friction(rng, masses, forces, omegas, most_fc, equal):
    """Random parameters of a mass with friction: M, F and w log-uniform in their ranges, Fc up to most_fc F, Fs
    = Fc with probability ``equal`` (else up to 1.5 Fc), B at most M w (half the time 0), a random phase, and
    (each 3 times in 10) an offset f and a start velocity."""
    M, F, w = loguniform(rng, *masses), loguniform(rng, *forces), loguniform(rng, *omegas)
    Fc = F * rng.uniform(0.0, most_fc)
    Fs = Fc if rng.random() < equal else Fc * (1 + rng.uniform(0, 0.5))
    B = 0.0 if rng.random() < 0.5 else M * w * rng.uniform(0, 1)  # decay rate B/M <= w
    params = dict(M=M, B=B, Fc=Fc, Fs=Fs, F=F, omega=w, phi=rng.uniform(-math.pi, math.pi))
    if rng.random() < 0.3:
        params["f"] = F * rng.uniform(-0.5, 0.5)
    if rng.random() < 0.3:
        params["v0"] = F / (M * w) * rng.uniform(-1, 1)
    return params


class FrictionObserver(StressObserver):
    """Stick, slide and (without Coulomb friction) momentum at every point."""

    TABLE = FRICTION_TABLE

    def setup(self):
        p = dict(self.TABLE.defaults, **self.case.params)
        self.M, self.B = p["M"], p["B"]
        self.Fc, self.Fs, self.Dv = p["Fc"], p["Fs"], p.get("Dv", 0.0)
        self.x0, self.v0 = p["x0"], p["v0"]
        # |u| never exceeds Fs and the mass starts at rest: it must never move
        self.stays_stuck = self.v0 == 0.0 and abs(self.F) + self.f_max <= self.Fs
        self.linear = self.Fc == 0.0 and self.Fs == 0.0

    def sample(self, plant, t, f, values):
        x, v, ff, mode = values
        fail = self.failures.add
        u = self.u(t, f)
        r = self.u_rounding(t, f, self.Fs)
        vscale = abs(self.v0) + (2.0 * abs(self.F) / self.w + (self.f_max + self.Fs) * t) / self.M
        tiny = 64.0 * EPS * (plant.events + 1) * vscale
        if mode not in (-1, 0, 1):
            fail("mode", t=t, mode=mode)
        if self.stays_stuck and not (x == self.x0 and v == 0.0):
            fail("stays_stuck", t=t, x=x, v=v, mode=mode, u=u, Fs=self.Fs,
                 why="max |u| = |f| + |F| <= Fs from rest, yet the mass moved")
        if mode == 0:
            if self.Dv == 0.0:
                if v != 0.0:
                    fail("stick", t=t, v=v, why="mode 0 with v != 0")
                self.margins.see("stick", max(abs(u) - self.Fs, 0.0), r, self.case)
                if not abs(u) <= self.Fs + r:
                    fail("stick", t=t, u=u, Fs=self.Fs, excess=abs(u) - self.Fs, tol=r, why="stuck with |u| > Fs")
                if not abs(ff - u) <= r:
                    fail("stick", t=t, Ff=ff, u=u, why="stuck with Ff != u")
            else:
                if not abs(v) <= self.Dv * (1 + 1e-12) + tiny:
                    fail("stick", t=t, v=v, Dv=self.Dv, why="band mode with |v| > Dv")
                bound = max(self.Fs, self.Fc + self.B * self.Dv)
                if not abs(ff) <= bound + r:
                    fail("stick", t=t, Ff=ff, bound=bound, why="band mode with |Ff| > max(Fs, Fc + B Dv)")
        else:
            if not mode * v >= self.Dv - tiny:
                fail("slide", t=t, v=v, mode=mode, Dv=self.Dv, tol=tiny, why="sliding against the mode's direction")
            expected, level = self.slide_friction(mode, v)
            tol_ff = r + 16.0 * EPS * (level + abs(self.B * v))
            err = abs(ff - expected)
            self.margins.see("slide", err, tol_ff, self.case)
            if not err <= tol_ff:
                fail("slide", t=t, Ff=ff, expected=expected, error=err, tol=tol_ff, why=self.SLIDE_LAW)
        if self.linear:
            p0 = self.M * self.v0
            self.momentum(plant, t, self.M * v + self.B * (x - self.x0), p0,
                          self.M * abs(v) + self.B * abs(x - self.x0))


    SLIDE_LAW = "Ff != Fc sgn(v) + B v"

    def slide_friction(self, mode, v):
        """The sliding friction force in direction ``mode`` at velocity v, and the size of its constant part."""
        return mode * self.Fc + self.B * v, abs(self.Fc)


def _friction_held(rng, scale, w, F):
    Fc = scale * rng.uniform(0.2, 1.0)
    params = dict(M=loguniform(rng, 1e-3, 1e3), B=0.0, Fc=Fc, Fs=Fc * rng.choice((1.0, 1.4)), F=F, omega=w)
    return params, (params["Fs"], -params["Fs"])


def _friction_bounds(p, F, f_max, dy_max):
    p = dict(FRICTION_TABLE.defaults, **p)
    return dy_max, (f_max + abs(F) + p["Fc"] + p["B"] * dy_max) / p["M"]


def _friction_balances(case, out, n, sums, table=FRICTION_TABLE, slack=0.0):
    """The energy and impulse balances of a mass with friction (``slack``: a further tolerance relative to the
    scales, an integrated plant's)."""
    p = dict(table.defaults, **case.params)
    M, B = p["M"], p["B"]
    v0 = p["v0"]
    ke0, ke = 0.5 * M * v0 ** 2, 0.5 * M * out[1] ** 2
    scale = max(ke0, ke) + sums["abs_work"]
    linear_free = p["Fc"] == 0.0 and p["Fs"] == 0.0 and B == 0.0
    energy = energy_balance(ke - ke0, sums["work"], (1e-10 + slack) * scale + 8.0 * EPS * n * scale,
                            equal=linear_free)
    dp = M * (out[1] - v0)
    scale = sums["abs_impulse"] + M * (abs(v0) + abs(out[1]))
    tol = (1e-10 + slack) * scale + 8.0 * EPS * n * scale
    err = abs(dp - sums["impulse"])
    impulse = ("impulse", err, tol, dict(momentum_change=dp, integral_u_minus_Ff=sums["impulse"], error=err, tol=tol,
                                         why="M (v - v0) != int (u - Ff) dt"))
    return [energy, impulse]


FRICTION = StressProfile(
    cases=_friction_cases, observer=FrictionObserver, output=0, velocity=1, rate=1, force=2,
    bounds=_friction_bounds, balances=_friction_balances, random_held=_friction_held,
    long=(
        (dict(M=1.0, B=0.0, Fc=5.0, Fs=5.0, F=10.0, omega=1.0), "1e5 periods stick-slip Fs=Fc"),
        (dict(M=1.0, B=0.0, Fc=0.0, Fs=0.0, F=10.0, omega=1e3), "1e5 periods free mass w=1e3"),
        (dict(M=1.0, B=0.5, Fc=5.0, Fs=7.0, F=6.0, omega=1.0), "1e5 periods stuck (F < Fs)"),
    ),
    invalid=(("M", 0.0), ("M", -1.0), ("M", math.nan), ("M", math.inf), ("B", -0.1), ("B", math.nan), ("Fc", -1.0),
             ("Fc", math.nan), ("Fs", 4.0), ("Fs", math.nan), ("Dv", -1e-3), ("Dv", math.nan), ("x0", math.nan),
             ("v0", math.inf), ("M", None), ("M", "1")),
)


# -- stribeck: the friction mass with Stribeck friction, its slides integrated ----------------
def _stribeck_cases(name, rng, quick):
    cases = []
    add = adder(name, cases)

    base = dict(M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, F=10.0, omega=1.0)
    add(base, note="defaults (vs = 0.1, delta = 2)")
    add(dict(base, Fs=5.0), note="Fs = Fc: no Stribeck fall (the friction mass)")
    add(dict(base, B=0.0), note="B = 0")
    for F in (1e-6, 1e-3, 1e3, 1e6):  # the force's scale, the fall kept at the motion's velocity scale F/(M w)
        add(dict(base, F=F, Fc=F / 2, Fs=0.7 * F, vs=0.01 * F, B=0.0), note=f"F={F:g}, Fc=F/2, Fs=0.7F, vs=F/100")
    for w in (1e-4, 1e-2, 1e2, 1e4):
        add(dict(base, omega=w, vs=0.01 * 10.0 / w, B=0.0), note=f"w={w:g}, vs=F/(100 w)")
    for M in (1e-6, 1e6):
        add(dict(base, M=M, vs=0.01 * 10.0 / M, B=0.0), note=f"M={M:g}, vs=F/(100 M)")
    for vs in (1e-4, 1e3):
        add(dict(base, vs=vs), note=f"vs={vs:g}: the fall far below / beyond the motion's speed")
    for delta in (0.5, 1.0, 10.0):
        add(dict(base, delta=delta), note=f"delta={delta:g}")
    for rtol in (1e-12, 1e-3):
        add(dict(base, rtol=rtol), note=f"rtol={rtol:g}")
    add(dict(base, F=7.0), note="F = Fs: tangent, never exceeds")
    add(dict(base, F=7.0 * (1 + 1e-12)), note="F = Fs (1 + 1e-12)")
    add(dict(base, F=7.0 * (1 - 1e-12)), note="F = Fs (1 - 1e-12)")
    add(dict(base, F=5.0, f=2.0), note="f + F = Fs exactly (peak touches Fs)")
    for f in (7.0, -7.0):
        add(dict(base, F=0.0, f=f), n_periods=2, note=f"constant f = {f:+g} = +-Fs, F = 0")
    add(dict(base, f=3.0, phi=0.7), note="offset f=3, phi=0.7")
    add(dict(base, v0=3.0, x0=1e6), note="x0=1e6, v0=3")
    add(dict(base, Fc=0.0, Fs=0.0, B=0.0, v0=-2.0), note="free mass (Fc=Fs=B=0)")
    t_late = (10.0,) + tuple(10.0 + 1e-9 * k for k in range(1, 1001))
    add(base, times=(t_late, "t=10 in one step, then 1000 steps of 1e-9 s"), note="dt=1e-9 at t=10")
    add(base, times=uniform(1e3, 1), note="one step of 1e3 s (160 periods)")
    add(dict(base, harmonics=0), note="harmonics=0")
    c = add(dict(base, F=0.0), note="held sine input 10 sin, 32/period")
    held_sine(c, 10.0, 32)
    cases.append(pattern(name, dict(base, F=0.0), [(8.0, 10), (-8.0, 20), (8.0, 10)], 0.1,
                         "held steps +-8: v returns to 0 within a step"))
    cases.append(pattern(name, dict(base, F=0.0), [(8.0, 10), (0.0, 10), (7.0, 10), (-7.0, 10)], 0.1,
                         "held steps to 0 and to +-Fs exactly"))
    for i in range(10 if quick else 40):
        cases.append(_random_stribeck(name, rng, i))
    return cases


def _random_stribeck(name, rng, i):
    params = _random_mass_with_friction(rng, (1e-3, 1e3), (1e-3, 1e3), (1e-2, 1e2), 1.2, 0.3)
    M, F, w = params["M"], params["F"], params["omega"]
    params.update(vs=F / (M * w) * loguniform(rng, 1e-3, 10.0),  # the fall's speed against the motion's
                  delta=rng.choice((1.0, 2.0, 3.5)), rtol=rng.choice((1e-6, 1e-9)))
    times, stepping = random_stepping(rng, TWO_PI / w, rng.randint(2, 6))
    return Case(name, params, times, stepping, note=f"random #{i}")


class StribeckObserver(FrictionObserver):
    """The friction mass's stick (exact) and slide checks, the slide's friction the Stribeck law's."""

    TABLE = STRIBECK_TABLE
    SLIDE_LAW = "Ff != (Fc + (Fs - Fc) exp(-(|v|/vs)^delta)) sgn(v) + B v"

    def setup(self):
        super().setup()
        p = dict(self.TABLE.defaults, **self.case.params)
        self.vs, self.delta = p["vs"], p["delta"]
        self.slack = INTEGRATED_SLACK * p["rtol"]

    def slide_friction(self, mode, v):
        """The Stribeck law, written apart from the plant's (exp underflows to 0 beyond |v| = 1e6 vs)."""
        w = abs(v) / self.vs
        share = 0.0 if w > 1e6 else math.exp(-(w ** self.delta))
        return mode * (self.Fc + (self.Fs - self.Fc) * share) + self.B * v, self.Fs


def _stribeck_bounds(p, F, f_max, dy_max):
    p = dict(STRIBECK_TABLE.defaults, **p)
    return dy_max, (f_max + abs(F) + p["Fs"] + p["B"] * dy_max) / p["M"]


def _stribeck_balances(case, out, n, sums):
    """The friction mass's energy balance, with the slides' tolerance (their velocity is accurate to rtol).

    No impulse balance: its integrand u - Ff(v) falls from Fs to Fc over |v| ~ vs, nearly a step at
    delta = 10, which the suite's quadrature between events does not resolve (it once erred by 4e-3 where
    the solver's steps resolve the fall); the observer checks the law at every point instead.
    """
    p = dict(STRIBECK_TABLE.defaults, **case.params)
    check, err, tol, detail = _friction_balances(case, out, n, sums, STRIBECK_TABLE, INTEGRATED_SLACK * p["rtol"])[0]
    # and the work of u against the slides' velocity rounding (their error control's floor: 64 eps of the
    # forces' sum over M per unit time, what a force within rounding of Fs moves): tiny motions have no scale
    size, stop = abs(p.get("F", 0.0)) + sums["f_max"] + p["Fs"] + p["Fc"], case.times[-1]
    tol += 64.0 * EPS * size * size / p["M"] * stop * stop
    return [(check, err, tol, dict(detail, tol=tol))]


STRIBECK = StressProfile(
    cases=_stribeck_cases, observer=StribeckObserver, output=0, velocity=1, rate=1,
    bounds=_stribeck_bounds, balances=_stribeck_balances, random_held=_friction_held,
    long=((dict(M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, F=6.0, omega=1.0), "1e5 periods stuck (F < Fs)"),),
    invalid=(("M", 0.0), ("M", math.nan), ("B", -0.1), ("Fc", -1.0), ("Fs", 4.0), ("vs", 0.0), ("vs", -1.0),
             ("vs", math.nan), ("delta", 0.4), ("delta", 11.0), ("delta", math.nan), ("rtol", 1e-13),
             ("rtol", 1e-2), ("rtol", math.nan), ("x0", math.nan), ("v0", math.inf), ("M", None), ("vs", "1")),
)


# -- two-mass backlash: two masses, a clearance h and impacts of restitution eps --------
def _backlash_params(M1, M2, F, w, ratio):
    """h from the ratio of the free amplitude F/(M2 w^2) to the clearance."""
    return dict(M1=M1, M2=M2, h=F / (M2 * w * w * ratio), F=F, omega=w)


def _backlash_cases(name, rng, quick):
    cases = []

    add = adder(name, cases)

    base = dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0)
    for eps in EPS_VALUES:
        add(dict(base, eps=eps), note=f"paper case eps={eps!r}")
    axis_eps = EPS_VALUES if not quick else (0.0, 0.5, 1.0)
    axes = [
        ("h=1e-9", _backlash_params(1.0, 1.0, 2e-6, 20.0, 5.0)),  # h = 1e-9
        ("h=10", _backlash_params(1.0, 1.0, 2e4, 20.0, 5.0)),  # h = 10
        ("F=1e-6", dict(M1=1.0, M2=1.0, h=0.1, F=1e-6, omega=math.sqrt(2e-6))),  # X/h = 5
        ("F=1e6", dict(M1=1.0, M2=1.0, h=0.1, F=1e6, omega=math.sqrt(2e6))),
        ("w=1e-4", dict(M1=1.0, M2=1.0, h=10.0, F=1e-6, omega=1e-4)),  # X/h = 10
        ("w=1e4", dict(M1=1.0, M2=1.0, h=1e-3, F=5e5, omega=1e4)),  # X/h = 5
        ("M1=1e-6", dict(base, M1=1e-6)),
        ("M1=1e6", dict(base, M1=1e6)),
        ("M2=1e-6", _backlash_params(1.0, 1e-6, 2e-4, 20.0, 5.0)),
        ("M2=1e6", _backlash_params(1.0, 1e6, 1e6, math.sqrt(2.0), 5.0)),
        ("M1=1e-6 M2=1e6", _backlash_params(1e-6, 1e6, 1e6, math.sqrt(2.0), 5.0)),
        ("M1=1e6 M2=1e-6", _backlash_params(1e6, 1e-6, 2e-4, 20.0, 5.0)),
    ]
    for label, params in axes:
        for eps in axis_eps:
            add(dict(params, eps=eps), note=f"{label} eps={eps!r}")
    # initial conditions at the boundaries, far from the origin, moving
    add(dict(base, eps=0.5, gap0=0.0), note="gap0=0, pressed at start")
    add(dict(base, eps=0.5, gap0=0.1, phi=math.pi), note="gap0=h, pulled at start")
    add(dict(base, eps=0.5, gap0=0.0, phi=math.pi, v1_0=1.0, v2_0=1.0), note="gap0=0, pulled apart, moving")
    add(dict(base, eps=1.0, x1_0=1e9, v1_0=-3.0, v2_0=2.0), note="x1_0=1e9, moving")
    # free elastic flight: kinetic energy constant at every point
    add(dict(M1=2.0, M2=0.5, h=0.1, eps=1.0, F=0.0, omega=1.0, v1_0=0.3, v2_0=-1.1), n_periods=20,
        note="free elastic flight")
    add(dict(M1=1e-6, M2=1e6, h=1e-9, eps=1.0, F=0.0, omega=1e4, v1_0=1e-3, v2_0=0.0),
        note="free elastic flight, mass ratio 1e12, h=1e-9")
    # constant pressing force: a Zeno accumulation ending in contact (or, eps ~ 1, bouncing)
    for eps in EPS_VALUES:
        add(dict(base, F=0.0, f=-10.0, eps=eps), n_periods=2, note=f"constant press f=-10 eps={eps!r}")
    # steps at the ends of the range
    add(dict(base, eps=0.5), times=uniform(1e-6, 1000), note="dt=1e-9 from t=0")
    add(dict(base, eps=0.5, F=1e6, omega=1e4, h=1e-3), times=uniform(1e-6, 1000), note="dt=1e-9, F=1e6, w=1e4")
    add(dict(M1=1.0, M2=1.0, h=10.0, F=1e-6, omega=1e-4, eps=0.5), times=uniform(6.3e5, 630), note="dt=1e3 s, w=1e-4")
    add(dict(base, eps=0.0, omega=1.0, F=1.0), times=uniform(1e4, 10), note="dt=1e3 s, w=1")
    t_far = (1e6,) + tuple(1e6 + 1e-9 * k for k in range(1, 1001))
    add(dict(M1=1.0, M2=1.0, h=10.0, F=1e-6, omega=1e-4, eps=0.5),
        times=(t_far, "t=1e6 in one step, then 1000 steps of 1e-9 s"), note="dt=1e-9 at t=1e6, w=1e-4")
    add(dict(base, eps=0.5, harmonics=1), note="harmonics=1")
    # a held input
    c = add(dict(base, F=0.0, eps=0.5), note="held sine input 50 sin, 32/period")
    held_sine(c, 50.0, 32)

    # held inputs that stop, reverse and press again (F = 0, so phi must not matter)
    press = dict(M1=1.0, M2=1.0, h=0.1, eps=0.5, F=0.0, omega=1.0, gap0=0.0)
    for phi in (0.0, -1.5):
        cases.append(pattern(name, dict(press, phi=phi), [(-10.0, 10), (0.0, 10), (-10.0, 10)], 0.1,
                             f"held -10, 0, -10 from contact, phi={phi!r}"))
    cases.append(pattern(name, dict(press, gap0=0.05, eps=0.0), [(10.0, 10), (-10.0, 20), (10.0, 10)], 0.1,
                         "held +-10, eps=0: the pair's velocity returns to 0 at a step"))
    cases.append(pattern(name, dict(press, gap0=0.1), [(10.0, 10), (0.0, 10), (10.0, 10)], 0.1,
                         "held +10, 0, +10 from contact at gap h (default phi)"))
    c = Case(name, dict(press, F=1.0), *uniform(1.0, 10), note="F=1 pulls apart at gap0=0; held f=-10 presses from t=0")
    c.inputs, c.input_form = (-10.0,) * 10, "-10.0 for 10 steps"
    cases.append(c)
    for i in range(40 if quick else 200):
        cases.append(_random_backlash(name, rng, i))
    return cases


def _random_backlash(name, rng, i):
    eps = rng.choice(EPS_VALUES)
    max_ratio = 20.0 if eps > 0.9 else 100.0
    while True:
        M1, M2 = loguniform(rng, 1e-6, 1e6), loguniform(rng, 1e-6, 1e6)
        F, w = loguniform(rng, 1e-6, 1e6), loguniform(rng, 1e-4, 1e4)
        ratio = loguniform(rng, 0.05, max_ratio)
        params = _backlash_params(M1, M2, F, w, ratio)
        if 1e-9 <= params["h"] <= 10.0:
            break
    params.update(eps=eps, phi=rng.uniform(-math.pi, math.pi), gap0=params["h"] * rng.random())
    if rng.random() < 0.3:
        params["f"] = F * rng.uniform(-0.3, 0.3)
    if rng.random() < 0.3:
        vs = F / (M2 * w)
        params["v1_0"], params["v2_0"] = vs * rng.uniform(-1, 1), vs * rng.uniform(-1, 1)
    times, stepping = random_stepping(rng, TWO_PI / w, rng.randint(2, 10))
    return Case(name, params, times, stepping, note=f"random #{i} X/h={ratio:.3g}")


class BacklashObserver(StressObserver):
    """The gap, contact, momentum and (free elastic flight) kinetic energy at every point."""

    TABLE = BACKLASH_TABLE

    def setup(self):
        p = dict(self.TABLE.defaults, **self.case.params)
        self.M1, self.M2, self.h = p["M1"], p["M2"], p["h"]
        self.eps = p["eps"]
        self.p0 = self.M1 * p["v1_0"] + self.M2 * p["v2_0"]
        self.ke0 = 0.5 * self.M1 * p["v1_0"] ** 2 + 0.5 * self.M2 * p["v2_0"] ** 2
        self.free_elastic = (self.eps == 1.0 and self.F == 0.0 and self.f_max == 0.0)

    def pressing(self, plant, t, f, v):
        """(what presses the masses together in contact, its rounding): u."""
        return self.u(t, f), self.u_rounding(t, f, 0.0)

    def sample(self, plant, t, f, values):
        x1, v1, x2, v2, g = values
        fail = self.failures.add
        tol_g = 1e-9 * self.h + 1e-12 * abs(x1)
        if not -tol_g <= g <= self.h + tol_g:
            fail("gap", t=t, gap=g, h=self.h, tol=tol_g, why="gap outside [0, h]")
        contact = plant.contact
        if contact not in (0, 1, 2):
            fail("gap", t=t, contact=contact, why="unknown contact state")
        elif contact:
            u = self.u(t, f)
            sigma = -1 if contact == 1 else 1
            edge = 0.0 if contact == 1 else self.h
            if g != edge or v1 != v2:
                fail("gap", t=t, contact=contact, gap=g, v1=v1, v2=v2,
                     why="contact with a gap off the edge or two velocities")
            N, r = self.pressing(plant, t, f, v1)
            if not sigma * N >= -r:
                fail("gap", t=t, contact=contact, u=u, N=N, tol=r, why="contact while u pulls the masses apart")
        self.momentum(plant, t, self.M1 * v1 + self.M2 * v2, self.p0, self.M1 * abs(v1) + self.M2 * abs(v2))
        if self.free_elastic:
            ke = 0.5 * self.M1 * v1 * v1 + 0.5 * self.M2 * v2 * v2
            tol = 8.0 * EPS * (plant.events + 1) * self.ke0 + 1e-300
            err = abs(ke - self.ke0)
            self.margins.see("energy", err, tol, self.case)
            if not err <= tol:
                fail("energy", t=t, kinetic=ke, initial=self.ke0, error=err, tol=tol, impacts=plant.impacts,
                     why="eps = 1, f = F = 0: kinetic energy must stay constant")


def _backlash_held(rng, scale, w, F):
    M2 = loguniform(rng, 1e-3, 1e3)
    params = dict(M1=loguniform(rng, 1e-3, 1e3), M2=M2,
                  h=min(max(scale / (M2 * w * w) * rng.uniform(0.2, 5.0), 1e-9), 10.0),
                  eps=rng.choice(EPS_VALUES), F=F, omega=w)
    params["gap0"] = rng.choice((0.0, params["h"], 0.5 * params["h"]))
    return params, ()


def _backlash_bounds(p, F, f_max, dy_max):
    p = dict(BACKLASH_TABLE.defaults, **p)
    return dy_max, (f_max + abs(F)) / (p["M1"] + p["M2"])


def _backlash_balances(case, out, n, sums, table=BACKLASH_TABLE):
    p = dict(table.defaults, **case.params)
    F = p.get("F", 0.0)
    M1, M2 = p["M1"], p["M2"]
    ke0 = 0.5 * M1 * p["v1_0"] ** 2 + 0.5 * M2 * p["v2_0"] ** 2
    ke = 0.5 * M1 * out[1] ** 2 + 0.5 * M2 * out[3] ** 2
    eps = p["eps"]
    umax = abs(F) + sums["f_max"]
    zeno_cut = n * 1e-12 * p["h"] * umax  # the contact rule drops < tol_h |u| per entry
    scale = max(ke0, ke) + sums["abs_work"]
    tol = 1e-10 * scale + 8.0 * EPS * n * scale + zeno_cut
    return [energy_balance(ke - ke0, sums["work"], tol, equal=eps == 1.0)]


_PAPER = dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0)
BACKLASH = StressProfile(
    cases=_backlash_cases, observer=BacklashObserver, output=0, velocity=3, rate=1,
    bounds=_backlash_bounds, balances=_backlash_balances, random_held=_backlash_held,
    long=(
        (dict(_PAPER, eps=0.0), "1e5 periods eps=0"),
        (dict(_PAPER, eps=1e-9), "1e5 periods eps=1e-9"),
        (dict(_PAPER, eps=0.5), "1e5 periods eps=0.5"),
        (dict(_PAPER, eps=1.0), "1e5 periods eps=1"),
        (dict(M1=2.0, M2=0.5, h=0.1, F=0.0, omega=20.0, eps=1.0, v1_0=0.3, v2_0=-1.1),
         "1e5 periods free elastic flight"),
    ),
    invalid=(("M1", 0.0), ("M1", math.nan), ("M2", -1.0), ("M2", math.inf), ("h", 0.0), ("h", -0.1), ("h", math.nan),
             ("h", 1e-300), ("h", math.inf), ("eps", -1e-12), ("eps", 1.0 + 1e-12), ("eps", math.nan),
             ("gap0", -1e-12), ("gap0", 0.1 * (1 + 1e-12)), ("gap0", math.nan), ("x1_0", math.nan),
             ("v1_0", math.inf), ("v2_0", -math.inf), ("h", None)),
)


# -- drivetrain: a gear with play (the two-mass backlash) driving a load with stick-slip friction -------
def _drivetrain_cases(name, rng, quick):
    """The two-mass backlash's cases with the load's friction scaled to the force and to the load's share of
    the mass (Fc = F M1 / (M1 + M2) / 10, Fs = 1.4 Fc, B = 0: it sticks and slips without drowning the play;
    a friction far above that on a light load rattles it, an elastic impact and a stop every microsecond, beyond
    the event bound), and the friction's own: none (the backlash), a rigid coupling (h = 0: the friction mass
    of M1 + M2), a load that never moves, Fs at the force's peak."""
    cases = []
    for case in _backlash_cases(name, rng, quick):
        p = dict(DRIVETRAIN_TABLE.defaults, **case.params)
        scale = abs(p.get("F", 0.0)) + abs(p.get("f", 0.0)) + (max(abs(v) for v in case.inputs) if case.inputs
                                                                else 0.0)
        Fc = 0.1 * scale * p["M1"] / (p["M1"] + p["M2"])
        case.params = dict(case.params, B=0.0, Fc=Fc, Fs=1.4 * Fc)
        cases.append(case)
    add = adder(name, cases)
    base = dict(M1=1.0, M2=1.0, h=0.1, eps=0.5, B=0.5, Fc=5.0, Fs=7.0, F=50.0, omega=20.0)
    add(base, note="defaults, the paper's play")
    add(dict(base, B=0.0, Fc=0.0, Fs=0.0), note="no load friction: the two-mass backlash")
    add(dict(base, h=0.0), note="h = 0: rigid, the friction mass of M1 + M2")
    add(dict(base, h=0.0, v1_0=1.0, v2_0=-1.0), note="h = 0, the masses start apart in speed")
    add(dict(base, F=10.0, omega=1.0, Fs=1e6, Fc=1e6), note="a load that never moves: M2 rattles in the play")
    add(dict(base, F=7.0, omega=0.1, h=1e-3), note="slow drive, the force's peak at Fs")
    add(dict(base, eps=1.0, Fs=5.0), note="eps = 1, Fs = Fc")
    add(dict(base, F=0.0, f=-10.0), n_periods=2, note="constant press f = -10")
    return cases


class DrivetrainObserver(BacklashObserver):
    """The play's gap and contact (the two-mass backlash's), the load's stick, and momentum without friction."""

    TABLE = DRIVETRAIN_TABLE

    def setup(self):
        super().setup()
        p = dict(self.TABLE.defaults, **self.case.params)
        self.B, self.Fc, self.rigid = p["B"], p["Fc"], p["h"] == 0.0
        self.frictionless = p["B"] == 0.0 and p["Fc"] == 0.0 and p["Fs"] == 0.0
        self.free_elastic = self.free_elastic and self.frictionless

    def pressing(self, plant, t, f, v):
        """sigma N >= -rounding: in contact the motor side presses on the load, the force on M2 being
        (M1 u + M2 (Fc s + B v)) / (M1 + M2) sliding together, u stuck together; a rigid coupling never parts."""
        if self.rigid:
            return 0.0, 0.0
        u, s = self.u(t, f), plant.slip
        if s == 0:
            return u, self.u_rounding(t, f, 0.0)
        N = self.M1 * u + self.M2 * (self.Fc * s + self.B * v)
        return N, self.M1 * self.u_rounding(t, f, 0.0) + 16.0 * EPS * self.M2 * (self.Fc + self.B * abs(v))

    def sample(self, plant, t, f, values):
        super().sample(plant, t, f, values)
        x1, v1, x2, v2, g = values
        slip = plant.slip
        if slip not in (-1, 0, 1):
            self.failures.add("stick", t=t, slip=slip, why="unknown slip state")
        elif slip == 0 and v1 != 0.0:
            self.failures.add("stick", t=t, v1=v1, why="the load stuck (slip 0) with v1 != 0")
        elif slip and not slip * v1 >= -64.0 * EPS * (plant.events + 1) * (abs(v1) + abs(v2)):
            self.failures.add("slide", t=t, v1=v1, slip=slip, why="the load sliding against its direction")

    def momentum(self, plant, t, p, p0, scale_now):
        """Only without the load's friction (which takes momentum); the scale is M1 |v1| + M2 (|v1| + |w|):
        the drivetrain carries v2 as v1 + w, accurate to ulps of |v1| + |w| (relative 1e-4 of a v2 of 2e-15
        beside a v1 of 1e-3), where the two-mass backlash's centre of mass keeps M2 v2 to its own ulps."""
        if self.frictionless:
            _x1, v1, _x2, v2, _g = plant.output()
            super().momentum(plant, t, p, p0, self.M1 * abs(v1) + self.M2 * (abs(v1) + abs(v2 - v1)))


def _drivetrain_bounds(p, F, f_max, dy_max):
    """The two-mass backlash's, and the load alone decelerated by its friction (a light load: x1'' of 1e11)."""
    p = dict(DRIVETRAIN_TABLE.defaults, **p)
    return dy_max, (f_max + abs(F)) / (p["M1"] + p["M2"]) + (p["Fs"] + p["B"] * dy_max) / p["M1"]


def _drivetrain_balances(case, out, n, sums):
    """The two-mass backlash's energy balance: never more than the work of u (equal only at eps = 1 without
    the load's friction)."""
    p = dict(DRIVETRAIN_TABLE.defaults, **case.params)
    (check, err, tol, detail), = _backlash_balances(case, out, n, sums, DRIVETRAIN_TABLE)
    if p["eps"] == 1.0 and not (p["B"] == 0.0 and p["Fc"] == 0.0 and p["Fs"] == 0.0):
        check, err, tol, detail = energy_balance(detail["kinetic_change"], detail["work"], tol, equal=False)
    return [(check, err, tol, detail)]


DRIVETRAIN = StressProfile(
    cases=_drivetrain_cases, observer=DrivetrainObserver, output=0, velocity=3, rate=1,
    bounds=_drivetrain_bounds, balances=_drivetrain_balances, random_held=_backlash_held,
    long=((dict(_PAPER, eps=0.5), "1e5 periods eps=0.5, the load's default friction"),
          (dict(_PAPER, h=0.0, F=20.0, omega=1.0), "1e5 periods rigid (h = 0), the load sticking and slipping")),
    invalid=(("M1", 0.0), ("M1", math.nan), ("M2", -1.0), ("M2", math.inf), ("h", -0.1), ("h", math.nan),
             ("h", 1e-300), ("h", math.inf), ("eps", -1e-12), ("eps", 1.0 + 1e-12), ("eps", math.nan),
             ("gap0", -1e-12), ("gap0", 0.1 * (1 + 1e-12)), ("gap0", math.nan), ("x1_0", math.nan),
             ("v1_0", math.inf), ("v2_0", -math.inf), ("B", -0.1), ("B", math.nan), ("Fc", -1.0), ("Fs", 4.0),
             ("Fs", math.nan), ("h", None)),
)


# -- static backlash: a mass followed by a dead band h of slope k -----------------------
def _static_cases(name, rng, quick):
    cases = []

    add = adder(name, cases)

    def amp(M, F, w, ratio, k=1.0):  # h from X / h, X = F / (M w^2)
        return dict(M=M, k=k, h=F / (M * w * w * ratio), F=F, omega=w)

    base = dict(M=2.0, k=1.0, h=0.1, F=50.0, omega=20.0)
    add(base, note="baseline")
    add(amp(2.0, 2e-6 * 2, 20.0, 4.0), note="h=1e-9")
    add(amp(2.0, 2e4 * 2, 20.0, 2.0), note="h=10")
    add(dict(base, F=1e-6, omega=math.sqrt(1e-6 / (2 * 0.1 * 1.5))), note="F=1e-6")
    add(dict(base, F=1e6, omega=math.sqrt(1e6 / (2 * 0.1 * 1.5))), note="F=1e6")
    add(dict(base, h=10.0, F=2e-7, omega=1e-4), note="w=1e-4")
    add(dict(base, h=1e-3, F=3e5, omega=1e4), note="w=1e4")
    add(amp(1e-6, 1e-3, 20.0, 2.0), note="M=1e-6")
    add(amp(1e6, 1e6, 10.0, 2.0), note="M=1e6")
    add(dict(base, k=1e-6), note="k=1e-6")
    add(dict(base, k=1e6), note="k=1e6")
    add(dict(base, F=1.0), note="X < h/2: never engages")
    add(dict(base, x0=1e6, v0=0.5), note="x0=1e6, drifting")
    add(dict(base, x0=1e6, h=1e-9, F=50.0 * 1e-8), note="x0=1e6 with h=1e-9 (ulp(x0) ~ h/8)")
    add(dict(base, f=10.0), note="constant offset f=10: drifts")
    add(base, times=uniform(1e-6, 1000), note="dt=1e-9 from t=0")
    add(dict(base, h=10.0, F=2e-7, omega=1e-4), times=uniform(6.3e5, 630), note="dt=1e3 s, w=1e-4")
    c = add(dict(base, F=0.0), note="held sine input 50 sin, 32/period")
    held_sine(c, 50.0, 32)
    cases.append(pattern(name, dict(M=2.0, k=1.0, h=0.1, F=0.0, omega=1.0), [(10.0, 1), (-10.0, 1), (10.0, 1)], 1.0,
                         "held +10, -10, +10 (1 s each): v = 0 exactly at the reversal"))
    for i in range(25 if quick else 150):
        cases.append(_random_static(name, rng, i))
    return cases


def _random_static(name, rng, i):
    while True:
        M, k = loguniform(rng, 1e-6, 1e6), loguniform(rng, 1e-6, 1e6)
        F, w = loguniform(rng, 1e-6, 1e6), loguniform(rng, 1e-4, 1e4)
        ratio = loguniform(rng, 0.1, 50)
        h = F / (M * w * w * ratio)
        if 1e-9 <= h <= 10.0:
            break
    params = dict(M=M, k=k, h=h, F=F, omega=w, phi=rng.uniform(-math.pi, math.pi))
    if rng.random() < 0.3:
        params["v0"] = F / (M * w) * rng.uniform(-0.3, 0.3)
    times, stepping = random_stepping(rng, TWO_PI / w, rng.randint(2, 10))
    return Case(name, params, times, stepping, note=f"random #{i} X/h={ratio:.3g}")


class StaticBacklashObserver(StressObserver):
    """The play operator, the engaged direction and momentum at every point."""

    def setup(self):
        p = dict(STATIC_BACKLASH_TABLE.defaults, **self.case.params)
        self.M, self.k, self.h = p["M"], p["k"], p["h"]
        self.v0 = p["v0"]

    def sample(self, plant, t, f, values):
        x, v, y = values
        fail = self.failures.add
        tol = 1e-9 * self.h + 1e-12 * abs(x)
        offset = x - y / self.k
        if not abs(offset) <= 0.5 * self.h + tol:
            fail("play", t=t, x=x, y=y, offset=offset, half_h=0.5 * self.h, tol=tol, why="|x - y/k| > h/2")
        s = plant.engaged
        if s:
            if not abs(offset - s * 0.5 * self.h) <= tol:
                fail("play", t=t, engaged=s, offset=offset, tol=tol, why="engaged but y != k (x - s h/2)")
            vscale = abs(self.v0) + (2.0 * abs(self.F) / self.w + self.f_max * t) / self.M
            if not s * v >= -64.0 * EPS * (plant.events + 1) * vscale:
                fail("play", t=t, engaged=s, v=v, why="engaged while moving away from the edge")
        self.momentum(plant, t, self.M * v, self.M * self.v0, self.M * abs(v))


def _static_held(rng, scale, w, F):
    M = loguniform(rng, 1e-3, 1e3)
    return dict(M=M, k=1.0, h=min(max(scale / (M * w * w) * rng.uniform(0.2, 5.0), 1e-9), 10.0), F=F, omega=w), ()


def _static_bounds(p, F, f_max, dy_max):
    p = dict(STATIC_BACKLASH_TABLE.defaults, **p)
    return dy_max * p["k"], p["k"] * (f_max + abs(F)) / p["M"]


def _static_balances(case, out, n, sums):
    p = dict(STATIC_BACKLASH_TABLE.defaults, **case.params)
    M = p["M"]
    ke0, ke = 0.5 * M * p["v0"] ** 2, 0.5 * M * out[1] ** 2
    scale = max(ke0, ke) + sums["abs_work"]
    return [energy_balance(ke - ke0, sums["work"], 1e-10 * scale + 8.0 * EPS * n * scale, equal=True)]


STATIC_BACKLASH = StressProfile(
    cases=_static_cases, observer=StaticBacklashObserver, output=2, velocity=1, rate=1,
    bounds=_static_bounds, balances=_static_balances, random_held=_static_held,
    long=((dict(M=2.0, k=1.0, h=0.1, F=50.0, omega=20.0), "1e5 periods"),),
    invalid=(("M", 0.0), ("M", math.nan), ("k", 0.0), ("k", -1.0), ("k", math.inf), ("h", 0.0), ("h", math.nan),
             ("x0", math.inf), ("v0", math.nan), ("k", None)),
)
