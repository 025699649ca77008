"""What a plant gives the stress suite (``dfwb stress``): its cases, its invariants, its balances.

The suite itself (:mod:`dfwb.verify.stress`) runs cases, checks determinism,
step and phase independence, finiteness, the event rate, the Fourier
integrals and the energy bookkeeping for every plant alike. What it must know
about one plant is that plant's :class:`StressProfile`, set as
:attr:`dfwb.plants.registry.Plant.stress`: which outputs are the output and
the driven velocity, the plant's own cases, a per-point observer of its
physics (a :class:`StressObserver`) and its end-of-run energy and momentum
balances. The profiles of the built-in plants are in
:mod:`dfwb.plants.stress_profiles`.

This module is the vocabulary they share: :class:`Case` and
:class:`InvalidCase`, the helpers that build communication grids and held
inputs, and the observer base with the momentum check.

Examples
--------
>>> from dfwb.plants.stress_kit import uniform
>>> uniform(1.0, 4)[0]
(0.25, 0.5, 0.75, 1.0)
"""

import cmath
import math
import sys
from dataclasses import dataclass
from typing import Callable, Optional

from dfwb.fmus.piecewise import PlantError
from dfwb.plants.registry import plant as _plant

__all__ = ["StressProfile", "StressObserver", "Case", "InvalidCase", "profile", "uniform", "periods", "held_sine",
           "pattern", "adder", "loguniform", "random_stepping", "harmonic_impulse", "energy_balance",
           "EPS", "TWO_PI", "BUDGET", "LONG_BUDGET"]

EPS = sys.float_info.epsilon
TWO_PI = 2.0 * math.pi
BUDGET = 20.0  # seconds for one run of a case
LONG_BUDGET = 60.0  # seconds for one run of a 1e5-period case


@dataclass(frozen=True)
class StressProfile:
    """The stress suite's knowledge of one plant.

    The solver is the plant's :attr:`model`'s ``solver_class``, constructed
    as ``solver(**case.params)`` (the excitation ``F``, ``omega``, ``phi``,
    ``f`` and ``harmonics`` included).

    Attributes
    ----------
    cases : callable
        ``cases(name, rng, quick) -> [Case]``: the plant's valid cases (its
        own seeded random ones drawn from ``rng``, a ``random.Random``).
    observer : type
        A :class:`StressObserver` subclass: the plant's invariants, checked at
        every communication point.
    output : int
        Index in ``solver.output()`` of the signal whose running Fourier
        integrals ``solver.integrals()`` are (checked by quadrature).
    velocity : int
        Index of the velocity of the mass the force drives (power ``u v``).
    rate : int
        Index of the output's rate, or of the velocity that bounds it.
    bounds : callable
        ``bounds(params, F, f_max, rate_max) -> (max |y'|, max |y''|)`` of the
        output over a run, for the Fourier check's tolerance.
    balances : callable
        ``balances(case, output, n, sums) -> [(check, error, tol, detail)]``:
        the end-of-run energy (and momentum) balances of a short run, from the
        last ``output`` of the run, ``n`` (events + held inputs + 1) and
        ``sums`` (a dict: ``work``, ``abs_work`` and, with :attr:`force`,
        ``impulse``, ``abs_impulse``, by Gauss-Legendre quadrature;
        ``f_max``). :func:`energy_balance` makes the energy entry.
    random_held : callable or None
        ``random_held(rng, scale, w, F) -> (params, special inputs)``: the
        parameters of a random held-input case (``scale``: the input's scale)
        and the input values to include exactly (e.g. +-Fs).
    force : int or None
        Index of the plant's own force on the driven mass, against the input
        (friction's Ff): the quadrature integrates ``u - force`` for the
        impulse balance.
    long : tuple
        ``((params, note), ...)``: 1e5-period cases (the full set only).
    invalid : tuple
        ``((parameter, value), ...)``: the solver must refuse each with a
        PlantError naming the parameter (beyond the excitation's, which every
        plant is checked on).
    """

    cases: Callable
    observer: type
    output: int
    velocity: int
    rate: int
    bounds: Callable
    balances: Callable
    random_held: Optional[Callable] = None
    force: Optional[int] = None
    long: tuple = ()
    invalid: tuple = ()


def profile(name):
    """(the plant's solver class, its StressProfile); PlantError if it has none."""
    entry = _plant(name)
    if entry.stress is None:
        raise PlantError(f"plant {entry.name!r} has no stress profile")
    return entry.model.solver_class, entry.stress


# -- cases ------------------------------------------------------------------------------
@dataclass
class Case:
    """A valid case: a plant, its parameters and how it is stepped."""

    plant: str  # a registered plant's name
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
        text = f"{self.plant}[{self.note}] {profile(self.plant)[0].__name__}({params}); {self.stepping}"
        if self.inputs is not None:
            text += (f"; held input f_j = {self.input_form}, set before advancing to t_(j+1), "
                     f"j = 0..{len(self.inputs) - 1}")
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
        text = f"invalid {profile(self.plant)[0].__name__}({params})"
        if self.action != "init":
            text += f".{self.action}({self.value!r})"
        return text + f" must be refused naming {self.name!r}"


def uniform(stop, steps):
    """Communication points k stop / steps, k = 1..steps."""
    times = tuple(stop * k / steps for k in range(1, steps + 1))
    return times, f"{steps} steps of {stop / steps:.6g} s to t = {stop!r} (t_k = {stop!r}*k/{steps})"


def periods(params, n, per_period=32):
    """n periods of the excitation, per_period points each."""
    w = params.get("omega", 1.0)
    return uniform(n * TWO_PI / w, int(n * per_period))


def held_sine(case, amplitude, steps_per_cycle):
    """Feed case f_j = amplitude sin(2 pi j / steps_per_cycle), held over step j."""
    case.inputs = tuple(amplitude * math.sin(TWO_PI * j / steps_per_cycle) for j in range(len(case.times)))
    case.input_form = f"{amplitude!r}*sin(2*pi*j/{steps_per_cycle})"


def pattern(plant, params, segments, dt, note):
    """A held input made of segments (value, steps), each step dt long (F = 0 unless given)."""
    inputs = tuple(value for value, steps in segments for _ in range(steps))
    times, stepping = uniform(dt * len(inputs), len(inputs))
    form = " then ".join(f"{value!r} for {steps} steps" for value, steps in segments)
    return Case(plant, dict(params), times, stepping, inputs, note, input_form=form)


def adder(plant, cases):
    """add(params, ...) -> Case: a case of ``plant`` on a uniform grid (or given ``times``), appended to ``cases``."""

    def add(params, n_periods=10, per_period=32, note="", times=None, inputs=None, **kw):
        p = dict(params)
        if times is None:
            times, stepping = periods(p, n_periods, per_period)
        else:
            times, stepping = times
        case = Case(plant, p, times, stepping, inputs, note, **kw)
        cases.append(case)
        return case

    return add


def loguniform(rng, lo, hi):
    """A number log-uniform in [lo, hi]."""
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def random_stepping(rng, period, n_periods):
    """n_periods periods in uniform steps of a log-uniform size (1e-9 s to 1e3 s, at most 2000 steps)."""
    stop = n_periods * period
    lo, hi = max(1e-9, stop / 2000), min(1e3, stop)
    if lo >= hi:
        return uniform(stop, max(1, math.ceil(stop / hi)))
    dt = loguniform(rng, lo, hi)
    return uniform(stop, max(1, round(stop / dt)))


# -- closed forms and balances ----------------------------------------------------------
def harmonic_impulse(F, w, phi, t):
    """int_0^t F cos(w s + phi) ds = 2 F/w cos(w t/2 + phi) sin(w t/2), no cancellation."""
    half = 0.5 * w * t
    return 2.0 * F / w * math.cos(half + phi) * math.sin(half)


def energy_balance(dke, work, tol, equal):
    """The "energy" balance: kinetic energy change against the work of u (equal, or never more)."""
    err = abs(dke - work) if equal else max(dke - work, 0.0)
    why = "kinetic energy change != work of u" if equal else "kinetic energy gained more than the work of u"
    return "energy", err, tol, dict(kinetic_change=dke, work=work, error=err, tol=tol, why=why)


# -- the per-point observer -------------------------------------------------------------
class StressObserver:
    """Per-point invariants of a case's first run; a plant's profile subclasses it.

    The suite calls the observer after every communication point. It checks
    that the outputs and integrals are finite, then calls :meth:`sample`.
    ``failures.add(check, **detail)`` records a failure and
    ``margins.see(check, error, tol, case)`` the margin of a checked quantity.
    """

    slack = 0.0  # a further tolerance of the balances relative to their scale (an integrated plant's: its rtol)

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
        self.setup()

    def setup(self):
        """Read the plant's parameters (called once, at construction)."""

    def sample(self, plant, t, f, values):
        """Check the plant's invariants at time t (input f, finite outputs ``values``)."""

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
        """The force on the driven mass, f + F cos(w t + phi)."""
        return f + self.F * math.cos(self.w * t + self.phi)

    def u_rounding(self, t, f, level):
        """Rounding allowance of u (and of a force of size ``level`` compared with it)."""
        return 16.0 * EPS * (abs(f) + abs(self.F) * (1.0 + abs(self.w * t + self.phi)) + abs(level))

    def momentum(self, plant, t, p, p0, scale_now):
        """The "momentum" check: p - p0 = int u dt (closed form), to rounding."""
        self.p_max = max(self.p_max, scale_now)
        J = self.impulse_f + harmonic_impulse(self.F, self.w, self.phi, t)
        S = abs(p0) + self.p_max + self.abs_f + 2.0 * abs(self.F) / self.w
        n = plant.events + 1 + (len(self.case.inputs) if self.case.inputs is not None else 0)
        tol = (1e-10 + self.slack) * S + 4.0 * EPS * n * (S + (abs(self.F) + self.f_max) * t)
        err = abs((p - p0) - J)
        self.margins.see("momentum", err, tol, self.case)
        if not err <= tol:
            self.failures.add("momentum", t=t, momentum_change=p - p0, impulse=J, error=err, tol=tol,
                              scale=S, events=plant.events)
