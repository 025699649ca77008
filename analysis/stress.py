"""Numerical stress suite for the exact plant solvers (``dfwb stress``).

Each *case* drives one solver (:class:`~dfwb.fmus.FrictionMass`,
:class:`~dfwb.fmus.TwoMassBacklash`, :class:`~dfwb.fmus.StaticBacklash`)
directly, through a list of communication points (and, optionally, an input
``f`` held over each step, as an FMI master feeds it), and checks invariants
of the physics and of the numerics, not merely that the run ended:

``finite``
    no NaN or infinity in ``output()`` nor in ``integrals()``, at every point.
``gap`` / ``play``
    the backlash gap stays in [0, h] (the static backlash: ``|x - y/k| <= h/2``)
    up to ``1e-9 h + 1e-12 |x|``; in contact the gap is exactly 0 or h, both
    masses share one velocity and the force presses them together; an engaged
    static backlash has ``y = k (x -+ h/2)`` and moves in the engaged direction.
``stick`` / ``slide`` / ``stays_stuck``
    friction (``Dv = 0``): mode 0 means ``v == 0`` exactly, ``|u(t)| <= Fs``
    and ``Ff = u``; sliding means ``mode * v >= 0`` and ``Ff = Fc mode + B v``;
    a mass at rest whose force never exceeds Fs never moves (x, v exactly
    kept). With ``Dv > 0``: ``|v| <= Dv`` in the band.
``momentum``
    ``M1 v1 + M2 v2`` (static backlash ``M v``; friction without Coulomb
    friction ``M v + B x``) equals its initial value plus ``int u dt`` in
    closed form (``u = f + F cos(w t + phi)``, f held per step).
``energy``
    at eps = 1 with f = F = 0 the kinetic energy is constant at every point;
    on short runs the kinetic energy changes by the work of u
    (Gauss-Legendre between the recorded events): equal for eps = 1, the
    static backlash and the friction-free mass, never more for eps < 1 and
    friction (dissipation >= 0).
``impulse``
    friction, short runs: ``M (v - v0) = int (u - Ff) dt`` (Gauss-Legendre).
``fourier``
    short runs: the running integrals ``I_k(t) = int_0^t y exp(-i k w s) ds``
    against Gauss-Legendre quadrature of the sampled output.
``events``
    ``events / max(periods, 1)`` below a bound (1e4; physically a case here
    needs at most a few hundred).
``deterministic``
    a second run is bitwise identical (all outputs, integrals, event counts).
``step_independence``
    a run stepped differently (Gauss-Legendre nodes, or one long step) ends
    bitwise identical at the last point: the README promises results that do
    not depend on the communication step.
``phase_independence``
    with F = 0 the phase phi of the (absent) excitation must not matter:
    runs with phi + 1.5 and phi - 1.5 end bitwise identical (short cases).
``time``
    one run of a case must finish within its budget (20 s; 60 s for the
    1e5-period cases of the full set).
``exception``
    a valid case raised (any exception, PlantError included).
``refused``
    invalid parameters, inputs and steps must raise :class:`PlantError`
    whose message starts with the parameter's name (``"M = ... is out of
    range"``).

Tolerances are derived from rounding. Let ``e`` be the machine epsilon, N
the events so far and S the scale of the checked quantity (the largest
momentum seen, the initial momentum, ``2 |F| / w`` and ``int |f| dt``). Every
piece restarts from a state rounded to a few ulp of S, and every piece
evaluates its own phase ``w t + phi`` whose rounding (an ulp of ``w t``)
moves ``int u`` by up to ``|F| t e``; errors add at most once per event, so
``tol = 1e-10 S + 4 e (N + 1) (S + (|F| + max |f|) t)``. The first term is
the "1e-10 of the scale" allowance (it covers 4.5e5 events' worth of S-ulps);
the second dominates only for long horizons, where phase rounding is real.
The quadrature checks add Gauss-Legendre's error, below 1e-14 relative on
the subintervals used (at most period/16 and between events, 16 nodes).

Cases (``quick``: 377, of which 120 invalid inputs; ~25 s on this
two-core machine): every restitution eps in
{0, 1e-9, 0.5, 1 - 1e-9, 1}; h from 1e-9 to 10 m, F from 1e-6 to 1e6 N,
w from 1e-4 to 1e4 rad/s, masses from 1e-6 to 1e6 kg (the other parameters
chosen so the case stays in the regime it probes: for the backlash the
ratio of the free amplitude F/(M2 w^2) to h); Fs = Fc and B = 0 for friction,
Fs exactly at the force's peak, a constant force equal to +-Fs; steps from
1e-9 s to 1e3 s (also 1e-9 s steps at t = 10 and t = 1e6); held inputs
(a sampled sine, step patterns that stop, reverse and press again, and
random runs of values with exact zeros, repeats and +-Fs, as a controller
feeds them); seeded random parameters (``random.Random(seed)``,
reproducible); invalid parameters. The full set (``quick=False``, 1083
cases, ~10 min on one core, ~5 min as 4 parts on two cores) adds more
random cases, every eps on every axis and 1e5-period horizons;
``part``/``parts`` split it for CI.
"""

import cmath
import math
import random
import sys
import time
from array import array
from dataclasses import dataclass

import numpy as np

from dfwb.fmus import FrictionMass, PlantError, StaticBacklash, TwoMassBacklash

EPS = sys.float_info.epsilon
TWO_PI = 2.0 * math.pi
BUDGET = 20.0  # seconds for one run of a case
LONG_BUDGET = 60.0  # seconds for one run of a 1e5-period case
EVENTS_PER_PERIOD = 1e4
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
GL_MAX_INTERVALS = 20_000  # above this the quadrature checks are skipped (noted)
EPS_VALUES = (0.0, 1e-9, 0.5, 1.0 - 1e-9, 1.0)
SOLVERS = {"friction": FrictionMass, "backlash": TwoMassBacklash, "static": StaticBacklash}


# -- cases ------------------------------------------------------------------------------
@dataclass
class Case:
    """A valid case: a plant, its parameters and how it is stepped."""

    plant: str  # "friction", "backlash", "static"
    params: dict
    times: tuple  # communication points t_1 < ... < t_n (t_0 = 0)
    stepping: str  # how the times were made, for the description
    inputs: tuple = None  # f held over (t_{j-1}, t_j], set just before advancing to t_j
    note: str = ""
    long: bool = False
    budget: float = BUDGET
    quadrature: bool = True  # the Gauss-Legendre checks (short runs)
    input_form: str = ""  # how the held inputs were made, for the description

    def describe(self):
        params = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        text = f"{self.plant}[{self.note}] {SOLVERS[self.plant].__name__}({params}); {self.stepping}"
        if self.inputs is not None:
            text += f"; held input f_j = {self.input_form}, set before advancing to t_(j+1), j = 0..{len(self.inputs) - 1}"
        return text

    @property
    def omega(self):
        return self.params.get("omega", 1.0)

    @property
    def period(self):
        return TWO_PI / self.omega


@dataclass
class InvalidCase:
    """Bad input that must be refused with a PlantError naming ``name``."""

    plant: str
    params: dict
    name: str
    action: str = "init"  # "init", "set_input" (value), "advance" (value)
    value: float = None

    def describe(self):
        params = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        text = f"invalid {SOLVERS[self.plant].__name__}({params})"
        if self.action != "init":
            text += f".{self.action}({self.value!r})"
        return text + f" must be refused naming {self.name!r}"


def uniform(stop, steps):
    """Communication points k stop / steps, k = 1..steps."""
    return tuple(stop * k / steps for k in range(1, steps + 1)), f"{steps} steps of {stop / steps:.6g} s to t = {stop!r} (t_k = {stop!r}*k/{steps})"


def _periods(params, n, per_period=32):
    w = params.get("omega", 1.0)
    return uniform(n * TWO_PI / w, int(n * per_period))


def _held_sine(case, amplitude, steps_per_cycle):
    """Feed case f_j = amplitude sin(2 pi j / steps_per_cycle), held over step j."""
    case.inputs = tuple(amplitude * math.sin(TWO_PI * j / steps_per_cycle) for j in range(len(case.times)))
    case.input_form = f"{amplitude!r}*sin(2*pi*j/{steps_per_cycle})"


def _pattern(plant, params, segments, dt, note):
    """A held input made of segments (value, steps), each step dt long (F = 0 unless given)."""
    inputs = tuple(value for value, steps in segments for _ in range(steps))
    times, stepping = uniform(dt * len(inputs), len(inputs))
    form = " then ".join(f"{value!r} for {steps} steps" for value, steps in segments)
    return Case(plant, dict(params), times, stepping, inputs, note, input_form=form)


def _adder(plant, cases):
    """add(params, ...) -> Case: a case of ``plant`` on a uniform grid (or given ``times``), appended to ``cases``."""

    def add(params, n_periods=10, per_period=32, note="", times=None, inputs=None, **kw):
        p = dict(params)
        if times is None:
            times, stepping = _periods(p, n_periods, per_period)
        else:
            times, stepping = times
        case = Case(plant, p, times, stepping, inputs, note, **kw)
        cases.append(case)
        return case

    return add


def _friction_cases(rng, quick):
    cases = []

    add = _adder("friction", cases)

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
        add(dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, f=f, omega=1.0), n_periods=2, note=f"constant f = {f:+g} = +-Fs, F = 0")
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
    _held_sine(c, 10.0, 32)
    c = add(dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, omega=1.0), times=uniform(1e-3, 1000), note="held input, dt=1e-6, alternating sign")
    c.inputs = tuple(8.0 if (j // 100) % 2 == 0 else -8.0 for j in range(1000))
    c.input_form = "8.0 if (j // 100) % 2 == 0 else -8.0"

    friction = dict(M=1.0, B=0.0, Fc=5.0, Fs=7.0, F=0.0, omega=1.0)
    cases.append(_pattern("friction", friction, [(8.0, 10), (-8.0, 20), (8.0, 10)], 0.1,
                          "held steps +-8: v returns to 0 exactly at a step"))
    cases.append(_pattern("friction", friction, [(8.0, 10), (0.0, 10), (7.0, 10), (-7.0, 10)], 0.1,
                          "held steps to 0 and to +-Fs exactly"))
    for i in range(30 if quick else 150):
        cases.append(_random_friction(rng, i))
    if not quick:
        for F in (1e-6, 1e6):
            for w in (1e-4, 1e4):
                for M in (1e-6, 1e6):
                    add(dict(base, F=F, Fc=F / 2, Fs=F / 2, omega=w, M=M), note=f"corner F={F:g} w={w:g} M={M:g}")
    return cases


def _loguniform(rng, lo, hi):
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def _random_stepping(rng, period, n_periods):
    stop = n_periods * period
    lo, hi = max(1e-9, stop / 2000), min(1e3, stop)
    if lo >= hi:
        return uniform(stop, max(1, math.ceil(stop / hi)))
    dt = _loguniform(rng, lo, hi)
    return uniform(stop, max(1, round(stop / dt)))


def _random_friction(rng, i):
    M, F, w = _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-4, 1e4)
    Fc = F * rng.uniform(0.0, 1.5)
    Fs = Fc if rng.random() < 0.5 else Fc * (1 + rng.uniform(0, 0.5))
    B = 0.0 if rng.random() < 0.5 else M * w * rng.uniform(0, 1)  # decay rate B/M <= w
    params = dict(M=M, B=B, Fc=Fc, Fs=Fs, F=F, omega=w, phi=rng.uniform(-math.pi, math.pi))
    if rng.random() < 0.3:
        params["f"] = F * rng.uniform(-0.5, 0.5)
    if rng.random() < 0.3:
        params["v0"] = F / (M * w) * rng.uniform(-1, 1)
    times, stepping = _random_stepping(rng, TWO_PI / w, rng.randint(2, 10))
    return Case("friction", params, times, stepping, note=f"random #{i}")


def _backlash_params(M1, M2, F, w, ratio):
    """h from the ratio of the free amplitude F/(M2 w^2) to the clearance."""
    return dict(M1=M1, M2=M2, h=F / (M2 * w * w * ratio), F=F, omega=w)


def _backlash_cases(rng, quick):
    cases = []

    add = _adder("backlash", cases)

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
    add(dict(M1=2.0, M2=0.5, h=0.1, eps=1.0, F=0.0, omega=1.0, v1_0=0.3, v2_0=-1.1), n_periods=20, note="free elastic flight")
    add(dict(M1=1e-6, M2=1e6, h=1e-9, eps=1.0, F=0.0, omega=1e4, v1_0=1e-3, v2_0=0.0), note="free elastic flight, mass ratio 1e12, h=1e-9")
    # constant pressing force: a Zeno accumulation ending in contact (or, eps ~ 1, bouncing)
    for eps in EPS_VALUES:
        add(dict(base, F=0.0, f=-10.0, eps=eps), n_periods=2, note=f"constant press f=-10 eps={eps!r}")
    # steps at the ends of the range
    add(dict(base, eps=0.5), times=uniform(1e-6, 1000), note="dt=1e-9 from t=0")
    add(dict(base, eps=0.5, F=1e6, omega=1e4, h=1e-3), times=uniform(1e-6, 1000), note="dt=1e-9, F=1e6, w=1e4")
    add(dict(M1=1.0, M2=1.0, h=10.0, F=1e-6, omega=1e-4, eps=0.5), times=uniform(6.3e5, 630), note="dt=1e3 s, w=1e-4")
    add(dict(base, eps=0.0, omega=1.0, F=1.0), times=uniform(1e4, 10), note="dt=1e3 s, w=1")
    t_far = (1e6,) + tuple(1e6 + 1e-9 * k for k in range(1, 1001))
    add(dict(M1=1.0, M2=1.0, h=10.0, F=1e-6, omega=1e-4, eps=0.5), times=(t_far, "t=1e6 in one step, then 1000 steps of 1e-9 s"),
        note="dt=1e-9 at t=1e6, w=1e-4")
    add(dict(base, eps=0.5, harmonics=1), note="harmonics=1")
    # a held input
    c = add(dict(base, F=0.0, eps=0.5), note="held sine input 50 sin, 32/period")
    _held_sine(c, 50.0, 32)

    # held inputs that stop, reverse and press again (F = 0, so phi must not matter)
    press = dict(M1=1.0, M2=1.0, h=0.1, eps=0.5, F=0.0, omega=1.0, gap0=0.0)
    for phi in (0.0, -1.5):
        cases.append(_pattern("backlash", dict(press, phi=phi), [(-10.0, 10), (0.0, 10), (-10.0, 10)], 0.1,
                              f"held -10, 0, -10 from contact, phi={phi!r}"))
    cases.append(_pattern("backlash", dict(press, gap0=0.05, eps=0.0), [(10.0, 10), (-10.0, 20), (10.0, 10)], 0.1,
                          "held +-10, eps=0: the pair's velocity returns to 0 at a step"))
    cases.append(_pattern("backlash", dict(press, gap0=0.1), [(10.0, 10), (0.0, 10), (10.0, 10)], 0.1,
                          "held +10, 0, +10 from contact at gap h (default phi)"))
    c = Case("backlash", dict(press, F=1.0), *uniform(1.0, 10), note="F=1 pulls apart at gap0=0; held f=-10 presses from t=0")
    c.inputs, c.input_form = (-10.0,) * 10, "-10.0 for 10 steps"
    cases.append(c)
    for i in range(40 if quick else 200):
        cases.append(_random_backlash(rng, i))
    return cases


def _random_backlash(rng, i):
    eps = rng.choice(EPS_VALUES)
    max_ratio = 20.0 if eps > 0.9 else 100.0
    while True:
        M1, M2 = _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-6, 1e6)
        F, w = _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-4, 1e4)
        ratio = _loguniform(rng, 0.05, max_ratio)
        params = _backlash_params(M1, M2, F, w, ratio)
        if 1e-9 <= params["h"] <= 10.0:
            break
    params.update(eps=eps, phi=rng.uniform(-math.pi, math.pi), gap0=params["h"] * rng.random())
    if rng.random() < 0.3:
        params["f"] = F * rng.uniform(-0.3, 0.3)
    if rng.random() < 0.3:
        vs = F / (M2 * w)
        params["v1_0"], params["v2_0"] = vs * rng.uniform(-1, 1), vs * rng.uniform(-1, 1)
    times, stepping = _random_stepping(rng, TWO_PI / w, rng.randint(2, 10))
    return Case("backlash", params, times, stepping, note=f"random #{i} X/h={ratio:.3g}")


def _static_cases(rng, quick):
    cases = []

    add = _adder("static", cases)

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
    _held_sine(c, 50.0, 32)
    cases.append(_pattern("static", dict(M=2.0, k=1.0, h=0.1, F=0.0, omega=1.0), [(10.0, 1), (-10.0, 1), (10.0, 1)], 1.0,
                          "held +10, -10, +10 (1 s each): v = 0 exactly at the reversal"))
    for i in range(25 if quick else 150):
        cases.append(_random_static(rng, i))
    return cases


def _random_static(rng, i):
    while True:
        M, k = _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-6, 1e6)
        F, w = _loguniform(rng, 1e-6, 1e6), _loguniform(rng, 1e-4, 1e4)
        ratio = _loguniform(rng, 0.1, 50)
        h = F / (M * w * w * ratio)
        if 1e-9 <= h <= 10.0:
            break
    params = dict(M=M, k=k, h=h, F=F, omega=w, phi=rng.uniform(-math.pi, math.pi))
    if rng.random() < 0.3:
        params["v0"] = F / (M * w) * rng.uniform(-0.3, 0.3)
    times, stepping = _random_stepping(rng, TWO_PI / w, rng.randint(2, 10))
    return Case("static", params, times, stepping, note=f"random #{i} X/h={ratio:.3g}")


def _random_held(rng, i):
    """A held input as a master feeds a controller's output: runs of values that
    include exact zeros, exact repeats, sign flips and (friction) exactly +-Fs."""
    plant = rng.choice(("friction", "backlash", "static"))
    scale = _loguniform(rng, 1e-3, 1e3)
    w = _loguniform(rng, 1e-2, 1e2)
    F = 0.0 if rng.random() < 0.5 else scale * rng.uniform(0.2, 2.0)
    if plant == "friction":
        Fc = scale * rng.uniform(0.2, 1.0)
        params = dict(M=_loguniform(rng, 1e-3, 1e3), B=0.0, Fc=Fc, Fs=Fc * rng.choice((1.0, 1.4)), F=F, omega=w)
        special = (params["Fs"], -params["Fs"])
    elif plant == "backlash":
        M2 = _loguniform(rng, 1e-3, 1e3)
        params = dict(M1=_loguniform(rng, 1e-3, 1e3), M2=M2, h=min(max(scale / (M2 * w * w) * rng.uniform(0.2, 5.0), 1e-9), 10.0),
                      eps=rng.choice(EPS_VALUES), F=F, omega=w)
        params["gap0"] = rng.choice((0.0, params["h"], 0.5 * params["h"]))
        special = ()
    else:
        M = _loguniform(rng, 1e-3, 1e3)
        params = dict(M=M, k=1.0, h=min(max(scale / (M * w * w) * rng.uniform(0.2, 5.0), 1e-9), 10.0), F=F, omega=w)
        special = ()
    params["phi"] = rng.choice((0.0, rng.uniform(-math.pi, math.pi)))
    values = []
    n = rng.randint(8, 60)
    while len(values) < n:
        value = rng.choice((0.0, scale, -scale, scale * rng.uniform(-2, 2)) + special)
        values += [value] * rng.randint(1, 5)
    dt = TWO_PI / w / rng.choice((4, 16, 64))
    case = Case(plant, params, *uniform(dt * len(values), len(values)), inputs=tuple(values),
                note=f"random held input #{i}", input_form=repr(tuple(values)))
    return case


def _long_cases():
    """1e5 periods, read every 10 periods: the full set only."""
    n, every = 100_000, 10

    def long(plant, params, note):
        period = TWO_PI / params["omega"]
        times, stepping = uniform(n * period, n // every)
        return Case(plant, params, times, stepping, note=note, long=True, budget=LONG_BUDGET, quadrature=False)

    return [
        long("friction", dict(M=1.0, B=0.0, Fc=5.0, Fs=5.0, F=10.0, omega=1.0), "1e5 periods stick-slip Fs=Fc"),
        long("friction", dict(M=1.0, B=0.0, Fc=0.0, Fs=0.0, F=10.0, omega=1e3), "1e5 periods free mass w=1e3"),
        long("friction", dict(M=1.0, B=0.5, Fc=5.0, Fs=7.0, F=6.0, omega=1.0), "1e5 periods stuck (F < Fs)"),
        long("backlash", dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0, eps=0.0), "1e5 periods eps=0"),
        long("backlash", dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0, eps=1e-9), "1e5 periods eps=1e-9"),
        long("backlash", dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0, eps=0.5), "1e5 periods eps=0.5"),
        long("backlash", dict(M1=1.0, M2=1.0, h=0.1, F=50.0, omega=20.0, eps=1.0), "1e5 periods eps=1"),
        long("backlash", dict(M1=2.0, M2=0.5, h=0.1, F=0.0, omega=20.0, eps=1.0, v1_0=0.3, v2_0=-1.1),
             "1e5 periods free elastic flight"),
        long("static", dict(M=2.0, k=1.0, h=0.1, F=50.0, omega=20.0), "1e5 periods"),
    ]


def _invalid_cases():
    nan, inf = math.nan, math.inf
    cases = []
    common = [("F", nan), ("F", inf), ("omega", 0.0), ("omega", -1.0), ("omega", nan), ("omega", inf),
              ("phi", nan), ("phi", -inf), ("phi", 1e300), ("f", nan), ("f", inf), ("harmonics", 11),
              ("harmonics", -1), ("harmonics", 2.5), ("harmonics", nan), ("harmonics", inf), ("omega", None),
              ("F", "1")]
    specific = {
        "friction": [("M", 0.0), ("M", -1.0), ("M", nan), ("M", inf), ("B", -0.1), ("B", nan), ("Fc", -1.0),
                     ("Fc", nan), ("Fs", 4.0), ("Fs", nan), ("Dv", -1e-3), ("Dv", nan), ("x0", nan),
                     ("v0", inf), ("M", None), ("M", "1")],
        "backlash": [("M1", 0.0), ("M1", nan), ("M2", -1.0), ("M2", inf), ("h", 0.0), ("h", -0.1), ("h", nan),
                     ("h", 1e-300), ("h", inf), ("eps", -1e-12), ("eps", 1.0 + 1e-12), ("eps", nan), ("gap0", -1e-12),
                     ("gap0", 0.1 * (1 + 1e-12)), ("gap0", nan), ("x1_0", nan), ("v1_0", inf), ("v2_0", -inf),
                     ("h", None)],
        "static": [("M", 0.0), ("M", nan), ("k", 0.0), ("k", -1.0), ("k", inf), ("h", 0.0), ("h", nan),
                   ("x0", inf), ("v0", nan), ("k", None)],
    }
    for plant in ("friction", "backlash", "static"):
        for name, value in common + specific[plant]:
            cases.append(InvalidCase(plant, {name: value}, name))
        for value in (nan, inf, -inf):
            cases.append(InvalidCase(plant, {}, "f", "set_input", value))
        for value in (nan, -1.0, inf, 1e300):  # 1e300: a phase that no longer resolves a period
            cases.append(InvalidCase(plant, {}, "t_end", "advance", value))
    return cases


def all_cases(quick=True, seed=20240505):
    """The valid and invalid cases, in a fixed order (seeded random cases)."""
    rng = random.Random(seed)
    cases = _friction_cases(rng, quick) + _backlash_cases(rng, quick) + _static_cases(rng, quick)
    cases += [_random_held(rng, i) for i in range(40 if quick else 300)]
    if not quick:
        cases += _long_cases()
    return cases + _invalid_cases()


# -- closed forms -----------------------------------------------------------------------
def harmonic_impulse(F, w, phi, t):
    """int_0^t F cos(w s + phi) ds = 2 F/w cos(w t/2 + phi) sin(w t/2), no cancellation."""
    half = 0.5 * w * t
    return 2.0 * F / w * math.cos(half + phi) * math.sin(half)


class _Failures:
    """The failures of one case: the first occurrence of each check, with a count."""

    def __init__(self, case):
        self.case = case
        self.by_check = {}

    def add(self, check, **detail):
        entry = self.by_check.get(check)
        if entry is None:
            self.by_check[check] = {"case": self.case.describe(), "check": check, "detail": detail,
                                    "plant": self.case.plant, "params": _jsonable(self.case.params),
                                    "occurrences": 1}
        else:
            entry["occurrences"] += 1

    def entries(self):
        return list(self.by_check.values())


def _jsonable(params):
    return {k: (v if isinstance(v, (int, float)) and math.isfinite(v) else repr(v)) for k, v in params.items()}


class _Margins:
    """Worst err / tol per check over the suite: how tight the tolerances are."""

    def __init__(self):
        self.worst = {}

    def see(self, check, err, tol, case):
        ratio = err / tol if tol > 0 else (0.0 if err == 0 else math.inf)
        if ratio > self.worst.get(check, (-1.0, ""))[0]:
            self.worst[check] = (ratio, case.describe())


# -- one run: drive the solver through the communication points -------------------------
def _make(case):
    return SOLVERS[case.plant](**case.params)


def _signature(plant, extra=()):
    """All the numbers a read gives, as one flat list (for bitwise comparison)."""
    values = list(plant.output()) + list(extra)
    for z in plant.integrals():
        values += (z.real, z.imag)
    values += (float(plant.events), float(getattr(plant, "impacts", 0)))
    return values


def _run(case, observer=None, trace=None, log_events=False):
    """Step the solver through case.times (inputs set at each step's start)."""
    plant = _make(case)
    if log_events:
        plant.event_log = []
    inputs = case.inputs
    f = case.params.get("f", 0.0)
    for j, t in enumerate(case.times):
        if inputs is not None:
            f = inputs[j]
            plant.set_input(f)
        plant.advance(t)
        if observer is not None:
            observer(plant, t, f)
        if trace is not None:
            trace.extend(_signature(plant))
    return plant


class _Observer:
    """Per-point invariants of run A."""

    def __init__(self, case, failures, margins):
        self.case, self.failures, self.margins = case, failures, margins
        p = case.params
        self.F, self.w, self.phi = p.get("F", 0.0), case.omega, p.get("phi", 0.0)
        self.impulse_f = 0.0  # int of the held/constant f so far
        self.abs_f = 0.0  # int |f|
        self.f_max = abs(p.get("f", 0.0)) if case.inputs is None else max(abs(v) for v in case.inputs)
        self.t_prev = 0.0
        self.p_max = 0.0
        self.y_max = 0.0
        self.sample = getattr(self, "_" + case.plant)
        self.setup = getattr(self, "_setup_" + case.plant)
        self.setup()

    def __call__(self, plant, t, f):
        dt = t - self.t_prev
        self.impulse_f += f * dt
        self.abs_f += abs(f) * dt
        self.t_prev = t
        values = plant.output()
        integrals = plant.integrals()
        if not all(math.isfinite(v) for v in values) or not all(
                math.isfinite(z.real) and math.isfinite(z.imag) for z in integrals):
            self.failures.add("finite", t=t, output=[repr(v) for v in values],
                              integrals=[repr(z) for z in integrals if not cmath.isfinite(z)][:3])
            return
        self.sample(plant, t, f, values)

    def u(self, t, f):
        return f + self.F * math.cos(self.w * t + self.phi)

    def u_rounding(self, t, f, level):
        return 16.0 * EPS * (abs(f) + abs(self.F) * (1.0 + abs(self.w * t + self.phi)) + abs(level))

    def momentum(self, plant, t, p, p0, scale_now):
        self.p_max = max(self.p_max, scale_now)
        J = self.impulse_f + harmonic_impulse(self.F, self.w, self.phi, t)
        S = abs(p0) + self.p_max + self.abs_f + 2.0 * abs(self.F) / self.w
        n = plant.events + 1 + (len(self.case.inputs) if self.case.inputs is not None else 0)
        tol = 1e-10 * S + 4.0 * EPS * n * (S + (abs(self.F) + self.f_max) * t)
        err = abs((p - p0) - J)
        self.margins.see("momentum", err, tol, self.case)
        if not err <= tol:
            self.failures.add("momentum", t=t, momentum_change=p - p0, impulse=J, error=err, tol=tol,
                              scale=S, events=plant.events)

    # friction ------------------------------------------------------------------------
    def _setup_friction(self):
        p = self.case.params
        self.M, self.B = p.get("M", 1.0), p.get("B", 0.5)
        self.Fc, self.Fs, self.Dv = p.get("Fc", 5.0), p.get("Fs", 7.0), p.get("Dv", 0.0)
        self.x0, self.v0 = p.get("x0", 0.0), p.get("v0", 0.0)
        # |u| never exceeds Fs and the mass starts at rest: it must never move
        self.stays_stuck = self.v0 == 0.0 and abs(self.F) + self.f_max <= self.Fs
        self.linear = self.Fc == 0.0 and self.Fs == 0.0

    def _friction(self, plant, t, f, values):
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
            expected = mode * self.Fc + self.B * v
            tol_ff = r + 16.0 * EPS * (abs(self.Fc) + abs(self.B * v))
            err = abs(ff - expected)
            self.margins.see("slide", err, tol_ff, self.case)
            if not err <= tol_ff:
                fail("slide", t=t, Ff=ff, expected=expected, error=err, tol=tol_ff, why="Ff != Fc sgn(v) + B v")
        if self.linear:
            p0 = self.M * self.v0
            self.momentum(plant, t, self.M * v + self.B * (x - self.x0), p0,
                          self.M * abs(v) + self.B * abs(x - self.x0))

    # two-mass backlash --------------------------------------------------------------------
    def _setup_backlash(self):
        p = self.case.params
        self.M1, self.M2, self.h = p.get("M1", 1.0), p.get("M2", 1.0), p.get("h", 0.1)
        self.eps = p.get("eps", 0.5)
        self.p0 = self.M1 * p.get("v1_0", 0.0) + self.M2 * p.get("v2_0", 0.0)
        self.ke0 = 0.5 * self.M1 * p.get("v1_0", 0.0) ** 2 + 0.5 * self.M2 * p.get("v2_0", 0.0) ** 2
        self.free_elastic = (self.eps == 1.0 and self.F == 0.0 and self.f_max == 0.0)

    def _backlash(self, plant, t, f, values):
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
                fail("gap", t=t, contact=contact, gap=g, v1=v1, v2=v2, why="contact with a gap off the edge or two velocities")
            r = self.u_rounding(t, f, 0.0)
            if not sigma * u >= -r:
                fail("gap", t=t, contact=contact, u=u, tol=r, why="contact while u pulls the masses apart")
        self.momentum(plant, t, self.M1 * v1 + self.M2 * v2, self.p0, self.M1 * abs(v1) + self.M2 * abs(v2))
        if self.free_elastic:
            ke = 0.5 * self.M1 * v1 * v1 + 0.5 * self.M2 * v2 * v2
            tol = 8.0 * EPS * (plant.events + 1) * self.ke0 + 1e-300
            err = abs(ke - self.ke0)
            self.margins.see("energy", err, tol, self.case)
            if not err <= tol:
                fail("energy", t=t, kinetic=ke, initial=self.ke0, error=err, tol=tol, impacts=plant.impacts,
                     why="eps = 1, f = F = 0: kinetic energy must stay constant")

    # static backlash -----------------------------------------------------------------------
    def _setup_static(self):
        p = self.case.params
        self.M, self.k, self.h = p.get("M", 2.0), p.get("k", 1.0), p.get("h", 0.1)
        self.v0 = p.get("v0", 0.0)

    def _static(self, plant, t, f, values):
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


# -- the quadrature run: sample at Gauss-Legendre nodes between events ------------------
def _quadrature(case, event_times, plant_a, failures, margins):
    """Run C: step through Gauss-Legendre nodes; check energy, impulse, Fourier, step independence."""
    p = case.params
    F, w, phi = p.get("F", 0.0), case.omega, p.get("phi", 0.0)
    period = case.period
    width = period / 16.0
    # intervals: communication steps split at events and at most period/16 long
    events = sorted(t for t in event_times)
    intervals = []  # (a, b, j) with j the communication step
    e = 0
    a = 0.0
    for j, t_end in enumerate(case.times):
        cuts = []
        while e < len(events) and events[e] <= t_end:
            if events[e] > a:
                cuts.append(events[e])
            e += 1
        edges = [a] + cuts + [t_end]
        for lo, hi in zip(edges[:-1], edges[1:]):
            if hi <= lo:
                continue
            m = max(1, math.ceil((hi - lo) / width))
            if len(intervals) + m > GL_MAX_INTERVALS:
                return "skipped: more than %d quadrature intervals" % GL_MAX_INTERVALS
            for i in range(m):
                intervals.append((lo + (hi - lo) * i / m, lo + (hi - lo) * (i + 1) / m if i + 1 < m else hi, j))
        a = t_end
    plant = _make(case)
    H = plant.harmonics
    work = impulse = abs_work = abs_impulse = 0.0
    fourier = [0j] * (H + 1)
    abs_y = y_max = dy_max = 0.0
    y_index = {"friction": 0, "backlash": 0, "static": 2}[case.plant]
    v_index = {"friction": 1, "backlash": 3, "static": 1}[case.plant]
    f = p.get("f", 0.0)
    j_now = -1
    for a, b, j in intervals:
        if j != j_now:
            if j > 0:
                plant.advance(case.times[j - 1])
            if case.inputs is not None:
                f = case.inputs[j]
                plant.set_input(f)
            j_now = j
        half, mid = 0.5 * (b - a), 0.5 * (a + b)
        for node, weight in zip(GL_NODES, GL_WEIGHTS):
            t = min(max(mid + half * float(node), a, plant.t), b)
            plant.advance(t)
            out = plant.output()
            y, v = out[y_index], out[v_index]
            u = f + F * math.cos(w * t + phi)
            wt = half * float(weight)
            work += wt * u * v
            abs_work += wt * abs(u * v)
            if case.plant == "friction":
                impulse += wt * (u - out[2])
                abs_impulse += wt * (abs(u) + abs(out[2]))
            z = cmath.exp(-1j * w * t)
            zk = 1.0
            for k in range(H + 1):
                fourier[k] += wt * y * zk
                zk *= z
            abs_y += wt * abs(y)
            y_max = max(y_max, abs(y))
            dy_max = max(dy_max, abs(out[1]))
    plant.advance(case.times[-1])
    f_max = abs(p.get("f", 0.0)) if case.inputs is None else max(abs(x) for x in case.inputs)
    if case.plant == "friction":
        ddy_max = (f_max + abs(F) + p.get("Fc", 5.0) + p.get("B", 0.5) * dy_max) / p.get("M", 1.0)
    elif case.plant == "backlash":
        ddy_max = (f_max + abs(F)) / (p.get("M1", 1.0) + p.get("M2", 1.0))
    else:
        dy_max *= p.get("k", 1.0)
        ddy_max = p.get("k", 1.0) * (f_max + abs(F)) / p.get("M", 2.0)
    # step independence: the same end state whatever the communication points
    sig_a, sig_c = _signature(plant_a), _signature(plant)
    if array("d", sig_a).tobytes() != array("d", sig_c).tobytes():
        diff = [(i, a_, c_) for i, (a_, c_) in enumerate(zip(sig_a, sig_c)) if array("d", [a_]).tobytes() != array("d", [c_]).tobytes()]
        failures.add("step_independence", t=case.times[-1], differing=len(diff),
                     first=[{"index": i, "run": a_, "gauss_nodes_run": c_} for i, a_, c_ in diff[:4]],
                     why="stepping through Gauss-Legendre nodes instead of the communication points changed the end state")
    stop = case.times[-1]
    n = plant_a.events + 1 + (len(case.inputs) if case.inputs is not None else 0)
    out_a = plant_a.output()
    # energy and impulse
    if case.plant == "backlash":
        M1, M2 = p.get("M1", 1.0), p.get("M2", 1.0)
        ke0 = 0.5 * M1 * p.get("v1_0", 0.0) ** 2 + 0.5 * M2 * p.get("v2_0", 0.0) ** 2
        ke = 0.5 * M1 * out_a[1] ** 2 + 0.5 * M2 * out_a[3] ** 2
        eps = p.get("eps", 0.5)
        umax = abs(F) + (abs(f) if case.inputs is None else max(abs(x) for x in case.inputs))
        zeno_cut = n * 1e-12 * p.get("h", 0.1) * umax  # the contact rule drops < tol_h |u| per entry
        scale = max(ke0, ke) + abs_work
        tol = 1e-10 * scale + 8.0 * EPS * n * scale + zeno_cut
        _energy(case, failures, margins, ke - ke0, work, tol, equal=eps == 1.0)
    elif case.plant == "static":
        M = p.get("M", 2.0)
        ke0, ke = 0.5 * M * p.get("v0", 0.0) ** 2, 0.5 * M * out_a[1] ** 2
        scale = max(ke0, ke) + abs_work
        _energy(case, failures, margins, ke - ke0, work, 1e-10 * scale + 8.0 * EPS * n * scale, equal=True)
    else:
        M, B = p.get("M", 1.0), p.get("B", 0.5)
        v0 = p.get("v0", 0.0)
        ke0, ke = 0.5 * M * v0 ** 2, 0.5 * M * out_a[1] ** 2
        scale = max(ke0, ke) + abs_work
        linear_free = p.get("Fc", 5.0) == 0.0 and p.get("Fs", 7.0) == 0.0 and B == 0.0
        _energy(case, failures, margins, ke - ke0, work, 1e-10 * scale + 8.0 * EPS * n * scale, equal=linear_free)
        dp = M * (out_a[1] - v0)
        scale = abs_impulse + M * (abs(v0) + abs(out_a[1]))
        tol = 1e-10 * scale + 8.0 * EPS * n * scale
        err = abs(dp - impulse)
        margins.see("impulse", err, tol, case)
        if not err <= tol:
            failures.add("impulse", t=stop, momentum_change=dp, integral_u_minus_Ff=impulse, error=err, tol=tol,
                         why="M (v - v0) != int (u - Ff) dt")
    # Fourier integrals: each piece's closed form is exact to a few ulp of the
    # output's scale Y = max|y| + max|y'|/w + max|y''|/w^2 divided by k w (the
    # integration by parts divides by k w twice), however short the piece, so
    # n pieces carry n ulp of Y/w; the phases k w t carry k ulp of w t each.
    integrals = plant_a.integrals()
    Y = y_max + dy_max / w + ddy_max / (w * w)
    tol = 1e-9 * (abs_y + Y / w) + 16.0 * EPS * n * (Y / w + abs_y * max(H, 1) * w * stop)
    worst = max(range(H + 1), key=lambda k: abs(integrals[k] - fourier[k]))
    err = abs(integrals[worst] - fourier[worst])
    margins.see("fourier", err, tol, case)
    if not err <= tol:
        failures.add("fourier", t=stop, k=worst, solver=repr(integrals[worst]), quadrature=repr(fourier[worst]),
                     error=err, tol=tol, why="running Fourier integral != quadrature of the output")
    return None


def _energy(case, failures, margins, dke, work, tol, equal):
    err = abs(dke - work) if equal else max(dke - work, 0.0)
    margins.see("energy", err, tol, case)
    if not err <= tol:
        failures.add("energy", t=case.times[-1], kinetic_change=dke, work=work, error=err, tol=tol,
                     why="kinetic energy change != work of u" if equal else "kinetic energy gained more than the work of u")


# -- one case ---------------------------------------------------------------------------
def run_case(case, margins=None):
    """Run one case; returns (list of failures, seconds of run A, notes)."""
    margins = margins if margins is not None else _Margins()
    if isinstance(case, InvalidCase):
        return _run_invalid(case), 0.0, []
    failures = _Failures(case)
    notes = []
    observer = _Observer(case, failures, margins)
    trace_a = []
    start = time.perf_counter()
    try:
        plant_a = _run(case, observer, trace_a, log_events=case.quadrature)
    except Exception as error:  # noqa: BLE001 - any exception of a valid case is a finding
        failures.add("exception", error=f"{type(error).__name__}: {error}", after=time.perf_counter() - start)
        return failures.entries(), time.perf_counter() - start, notes
    seconds = time.perf_counter() - start
    if seconds > case.budget:
        failures.add("time", seconds=seconds, budget=case.budget, events=plant_a.events)
    periods = case.times[-1] / case.period
    rate = plant_a.events / max(periods, 1.0)
    if not rate <= EVENTS_PER_PERIOD:
        failures.add("events", events=plant_a.events, periods=periods, per_period=rate, bound=EVENTS_PER_PERIOD)
    # determinism: a second identical run, bitwise
    try:
        trace_b = []
        _run(case, None, trace_b)
        if array("d", trace_a).tobytes() != array("d", trace_b).tobytes():
            first = next(i for i, (a, b) in enumerate(zip(trace_a, trace_b))
                         if array("d", [a]).tobytes() != array("d", [b]).tobytes())
            failures.add("deterministic", index=first, run_a=trace_a[first], run_b=trace_b[first])
    except Exception as error:  # noqa: BLE001
        failures.add("deterministic", error=f"{type(error).__name__}: {error}")
    # quadrature run (short) or one long step (long): also step independence
    try:
        if case.quadrature:
            note = _quadrature(case, [t for t, _ in plant_a.event_log], plant_a, failures, margins)
            if note:
                notes.append(note)
        elif case.inputs is None:
            plant_c = _make(case)
            plant_c.advance(case.times[-1])
            if array("d", _signature(plant_a)).tobytes() != array("d", _signature(plant_c)).tobytes():
                failures.add("step_independence", t=case.times[-1], run=_signature(plant_a)[:6],
                             one_step=_signature(plant_c)[:6], why="one long step changed the end state")
    except Exception as error:  # noqa: BLE001
        failures.add("exception", stage="quadrature / step-independence run", error=f"{type(error).__name__}: {error}")
    # F = 0: the phase of the absent excitation must not matter (short cases)
    if case.params.get("F", 0.0) == 0.0 and not case.long:
        for shift in (1.5, -1.5):
            variant = Case(case.plant, dict(case.params, phi=case.params.get("phi", 0.0) + shift), case.times,
                           case.stepping, case.inputs, case.note, quadrature=False)
            try:
                plant_v = _run(variant)
                if array("d", _signature(plant_a)).tobytes() != array("d", _signature(plant_v)).tobytes():
                    failures.add("phase_independence", phi=variant.params["phi"], t=case.times[-1],
                                 output_phi=list(plant_a.output()), output_shifted=list(plant_v.output()),
                                 why="F = 0, yet changing phi changed the result")
            except Exception as error:  # noqa: BLE001
                failures.add("phase_independence", phi=variant.params["phi"], error=f"{type(error).__name__}: {error}")
    return failures.entries(), seconds, notes


def _run_invalid(case):
    entry = {"case": case.describe(), "check": "refused", "plant": case.plant, "params": _jsonable(case.params)}
    try:
        plant = SOLVERS[case.plant](**case.params)
        if case.action == "set_input":
            plant.set_input(case.value)
        elif case.action == "advance":
            plant.advance(1.0)
            plant.advance(case.value)
    except PlantError as error:
        if str(error).startswith(f"{case.name} = "):
            return []
        entry["detail"] = {"raised": f"PlantError: {error}", "why": f"the message does not start with '{case.name} = '"}
        return [entry]
    except Exception as error:  # noqa: BLE001
        entry["detail"] = {"raised": f"{type(error).__name__}: {error}", "why": "not a PlantError"}
        return [entry]
    entry["detail"] = {"raised": None, "why": "accepted"}
    return [entry]


# -- the suite --------------------------------------------------------------------------
def run_stress(quick=True, progress=False, part=0, parts=1, seed=20240505):
    """Run the stress suite and return its result.

    ``quick``: about 100 cases, about a minute; otherwise the full set,
    of which only the cases ``index % parts == part`` run (CI pieces).
    Returns {"cases", "failed" (cases with a failure), "failures" (list of
    {"case", "check", "detail", ...}), "seconds", "checks" (failures per
    check), "worst_margins" (largest err/tol per check), "slowest", "notes"}.
    """
    if not (isinstance(parts, int) and parts >= 1 and isinstance(part, int) and 0 <= part < parts):
        raise ValueError(f"part = {part!r}, parts = {parts!r}: expected 0 <= part < parts")
    cases = [c for i, c in enumerate(all_cases(quick, seed)) if i % parts == part]
    margins = _Margins()
    failures, timings, notes = [], [], []
    failed = 0
    start = time.perf_counter()
    for i, case in enumerate(cases):
        found, seconds, case_notes = run_case(case, margins)
        if found:
            failed += 1
            failures += found
        timings.append((seconds, case.describe()))
        notes += [f"{case.describe()}: {n}" for n in case_notes]
        if progress:
            status = "FAIL " + ",".join(f["check"] for f in found) if found else "ok"
            print(f"[{i + 1}/{len(cases)}] {seconds:7.3f}s {status}  {case.describe()[:150]}", file=sys.stderr, flush=True)
    checks = {}
    for f in failures:
        checks[f["check"]] = checks.get(f["check"], 0) + 1
    timings.sort(reverse=True)
    return {
        "quick": quick, "part": part, "parts": parts, "seed": seed,
        "cases": len(cases), "failed": failed, "failures": failures,
        "seconds": time.perf_counter() - start, "checks": checks,
        "worst_margins": {k: {"ratio": r, "case": c} for k, (r, c) in sorted(margins.worst.items())},
        "slowest": [{"seconds": s, "case": c} for s, c in timings[:5]],
        "notes": notes,
    }


if __name__ == "__main__":  # pragma: no cover - a convenience; the CLI is `dfwb stress`
    import json

    print(json.dumps(run_stress(quick="--full" not in sys.argv, progress=True), indent=1, default=repr))
