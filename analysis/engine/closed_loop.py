"""The judge: a plant FMU in a loop with the controller FMU, co-simulated by fmpy.

The loop is force = -G(s) position: the controller is ``LinearSystem.fmu``
loaded with -G, its input the plant output, its output the plant input
``f``. The master is the fixed-step Jacobi scheme that libcosim uses too: at
every communication point read all outputs, then set all inputs, then step
every FMU; both FMUs are exact for inputs held over a step, so the only
co-simulation error is the hold (a delay of about a step). The measured
cycle is the first harmonic of the plant input force and of the plant output
over whole periods of the settled oscillation.

The hold's error is first order in the step h and not small: at 512 steps
per period it is of the size of the describing function's own error (the
friction PID loop: w 7% high). :func:`step_study` measures the cycle at
halving steps, checks the observed order and extrapolates (Richardson);
:func:`judge_errors` compares a measurement with the exact cycle
(:class:`dfwb.engine.periodic.TrueCycle`).

The co-simulated orbit is not exactly periodic: the plant's events react to
an input that changes only on the grid (a stuck friction mass breaks away
at a communication point), so they snap to it and the orbit jitters by
about a step from cycle to cycle (quasi-periodic at the step's scale), and
the measured cycle moves by about as much with tiny changes of the step.
The settledness test allows for that (:func:`measure`), :func:`settle` runs
in blocks until the oscillation settles instead of for a fixed time, and
that part of the error bounds what Richardson can do (:func:`step_study`).
"""

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from dfwb.base.defaults import JUDGE_SAMPLES
from dfwb.base.errors import InputError
from dfwb.fmi.location import fmu_path
from dfwb.fmi.session import FMUSession
from dfwb.fmi.simulation import FMUError
from dfwb.fmus.linear_system import MAX_ORDER  # the controller FMU's orders
from dfwb.plants import plant as find_plant

CONTROLLER = "LinearSystem"
BLOCK = 10  # periods per measurement block
MIN_PERIODS = 30  # a settling run's first look: a transient block and two measured ones
MAX_PERIODS = 400  # a settling run gives up after this many (predicted) periods
DIVERGED = 1e3  # the force's swing grown this much since the first block: the oscillation grows without bound
QUANTITIES = ("omega", "F", "amplitude_x")
ORDER_BAND = (0.5, 1.5)  # observed orders for which the first-order Richardson value helps (step_study)
STUDY_SAMPLES = (128, 256, 512, 1024, 2048)


def controller_values(G, sign=-1.0):
    """LinearSystem.fmu parameters (order, b0.., a1..) of ``sign * G`` (den normalised)."""
    num = np.trim_zeros(np.atleast_1d(np.asarray(G.num[0][0], dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(G.den[0][0], dtype=float)), "f")
    order = len(den) - 1
    if not 1 <= order <= MAX_ORDER:
        raise InputError(f"G(s) of order {order}: the controller FMU takes orders 1..{MAX_ORDER}")
    num = np.concatenate([np.zeros(order + 1 - len(num)), num]) * sign / den[0]
    den = den / den[0]
    values = {"order": order}
    values.update({f"b{i}": float(num[i]) for i in range(order + 1)})
    values.update({f"a{i}": float(den[i]) for i in range(1, order + 1)})
    return values


@dataclass
class LoopRun:
    """Samples of one closed-loop run at every communication point."""

    time: np.ndarray
    position: np.ndarray  # plant output
    force: np.ndarray  # plant input f, held over [t_k, t_k + step]
    step: float


@dataclass
class Oscillation:
    """What the judge measured.

    ``change`` is the largest relative change of omega, F and amplitude_x
    between the last two blocks of ``periods`` periods, ``tolerance`` what
    :func:`measure` allowed it, ``reason`` why nothing was measured or
    nothing settled ("" when settled).
    """

    settled: bool
    omega: float
    F: float  # first-harmonic amplitude of the force
    amplitude_x: float  # first-harmonic amplitude of the plant output
    periods: int  # whole periods measured at the end
    change: float = math.nan
    tolerance: float = math.nan
    reason: str = ""


class _Master:
    """The fixed-step Jacobi master, advanced in pieces (so that a run can go on until it settles)."""

    def __init__(self, plant, G, params, step, initial, fmu_dir, sessions):
        spec = find_plant(plant)
        values = spec.check(dict(params or {}, **(initial or {})))
        self.plant, self.controller = sessions or (
            FMUSession(fmu_path(spec, fmu_dir)), FMUSession(fmu_path(CONTROLLER, fmu_dir)))
        self.plant.start(dict(values, F=0.0))
        self.controller.start(controller_values(G))
        self.output, self.step = spec.output, step
        self.position, self.force = [], []  # arrays of samples, one per advance
        self.steps = 0

    def _read(self):
        return self.plant.reals([self.output])[0], self.controller.reals(["y"])[0]  # every output first,

    def advance(self, n):
        """n more steps; the samples at their ends are recorded (at t = 0 too on the first call)."""
        first = not self.position
        position, force = np.empty(n + first), np.empty(n + first)
        if first:
            position[0], force[0] = self._read()
        x, f = (position[0], force[0]) if first else (self.position[-1][-1], self.force[-1][-1])
        for k in range(first, n + first):
            self.plant.step(self.step, {"f": f})  # then set the inputs and step both
            self.controller.step(self.step, {"u": x})
            x, f = position[k], force[k] = self._read()
        self.position.append(position)
        self.force.append(force)
        self.steps += n

    def run(self):
        position, force = np.concatenate(self.position), np.concatenate(self.force)
        return LoopRun(np.arange(len(position)) * self.step, position, force, self.step)


def run_loop(plant, G, params=None, step=1e-3, stop_time=10.0, initial=None, fmu_dir=None,
             sessions=None):
    """Co-simulate plant + controller from ``initial`` plant parameters (e.g. x0, v0)."""
    master = _Master(plant, G, params, step, initial, fmu_dir, sessions)
    master.advance(int(round(stop_time / step)))
    return master.run()


def measure(run, periods=10, rtol=1e-3):
    """The settled oscillation at the end of a run: frequency and first harmonics.

    The period comes from the upward crossings of the force through its mean
    over the second half of the run; the first harmonics are taken over the
    last ``periods`` whole periods: the held force integrated exactly, the
    position by the trapezoidal rule.

    ``settled`` when that block and the ``periods`` periods before it agree
    in omega, F and amplitude_x, and the last block's cycles agree with each
    other in period and swing, to ``rtol + omega * step``. The second term is
    the step's own resolution (a step is omega * step radians of the cycle):
    the plant's events snap to the communication grid, so the co-simulated
    orbit jitters by about a step from cycle to cycle and never settles
    closer than that; a test on ``rtol`` alone calls fast-contracting stable
    cycles "not settled" at coarse steps. The jitter of block averages stays
    well inside it (at most 0.25 omega * step in the shipped loops).
    """
    t, f, x, h = run.time, run.force, run.position, run.step
    if periods < 1:
        raise InputError(f"periods = {periods!r}: measure at least one whole period")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(x))):
        return Oscillation(False, 0.0, 0.0, 0.0, 0, reason="the run diverged (values not finite)")
    half = len(t) // 2
    mean = f[half:].mean()
    above = f - mean > 0
    ups = np.flatnonzero(~above[:-1] & above[1:])
    if np.ptp(f[half:]) <= 1e-12 * (1.0 + np.abs(f[half:]).max()):
        return Oscillation(False, 0.0, 0.0, 0.0, 0, reason="no oscillation: the force is constant")
    if len(ups) < periods + 1 or ups[-periods - 1] < half:
        return Oscillation(False, 0.0, 0.0, 0.0, 0, reason=f"fewer than {periods} periods in the run's second half")
    crossings = t[ups] + (mean - f[ups]) / (f[ups + 1] - f[ups]) * h
    last = _block(t, f, x, h, ups, crossings, len(ups) - 1 - periods, len(ups) - 1)
    omega = last["omega"]
    tolerance = rtol + omega * h
    if len(ups) < 2 * periods + 1:
        return Oscillation(False, omega, last["F"], last["amplitude_x"], periods, math.nan, tolerance,
                           f"fewer than {2 * periods} periods to compare")
    before = _block(t, f, x, h, ups, crossings, len(ups) - 1 - 2 * periods, len(ups) - 1 - periods)
    change = max(abs(last[q] - before[q]) / max(abs(last[q]), 1e-300) for q in QUANTITIES)
    settled = bool(change <= tolerance and last["spread"] <= tolerance)
    reason = "" if settled else (
        f"the last two blocks of {periods} periods differ by {change:.2g} (relative) > {tolerance:.2g}"
        if change > tolerance else
        f"the cycles of the last block differ by {last['spread']:.2g} (relative) > {tolerance:.2g}")
    return Oscillation(settled, omega, last["F"], last["amplitude_x"], periods, float(change), tolerance, reason)


def _block(t, f, x, h, ups, crossings, i0, i1):
    """omega, F, amplitude_x over the whole periods from crossing i0 to i1, and the cycles' relative spread."""
    t0, t1 = crossings[i0], crossings[i1]
    omega = 2 * math.pi * (i1 - i0) / (t1 - t0)
    cycles = np.diff(crossings[i0:i1 + 1])
    swings = [np.ptp(f[a:b + 1]) for a, b in zip(ups[i0:i1], ups[i0 + 1:i1 + 1])]
    spread = max(np.ptp(cycles) / cycles.mean(), np.ptp(swings) / np.mean(swings))
    return {"omega": omega, "F": abs(_held_harmonic(t, f, h, t0, t1, omega)),
            "amplitude_x": abs(_sampled_harmonic(t, x, t0, t1, omega)), "spread": float(spread)}


def _held_harmonic(t, f, h, t0, t1, omega):
    """(2 / (t1 - t0)) int_t0^t1 f exp(-j w t) dt for f held over each step: exact."""
    k = np.arange(int(t0 // h), int(math.ceil(t1 / h)))
    a, b = np.clip(t[k], t0, t1), np.clip(t[k] + h, t0, t1)
    integral = np.sum(f[k] * (np.exp(-1j * omega * b) - np.exp(-1j * omega * a)) / (-1j * omega))
    return 2.0 / (t1 - t0) * integral


def _sampled_harmonic(t, x, t0, t1, omega):
    """The same for a sampled signal, trapezoidal between samples (linear at the window's ends)."""
    inside = (t > t0) & (t < t1)
    grid = np.concatenate([[t0], t[inside], [t1]])
    values = np.interp(grid, t, x)
    return 2.0 / (t1 - t0) * np.trapezoid(values * np.exp(-1j * omega * grid), grid)


def settle(plant, G, params=None, step=1e-3, period=1.0, initial=None, fmu_dir=None, sessions=None,
           periods=BLOCK, min_periods=MIN_PERIODS, max_periods=MAX_PERIODS, rtol=1e-3):
    """Co-simulate until the oscillation settles (:func:`measure`), in blocks of ``periods`` periods.

    ``period`` is the expected period (a prediction's); it only sizes the
    blocks. The run is measured after ``min_periods`` and after every block
    from then on, and stops when settled, at ``max_periods``, when the
    oscillation grows without bound (its force swing a thousandfold that of
    the first block) or dies out, or when an FMU refuses a step; the last
    three are reported, not raised, as not settled with the reason.

    Returns
    -------
    (Oscillation, LoopRun)
    """
    if not (step > 0 and period > 0 and math.isfinite(period / step)):
        raise InputError(f"step = {step!r}, period = {period!r}: both must be positive and finite")
    if not 1 <= periods <= min_periods <= max_periods:
        raise InputError(f"periods = {periods!r}, min_periods = {min_periods!r}, max_periods = {max_periods!r}: "
                         "expected 1 <= periods <= min_periods <= max_periods")
    per_period = period / step
    block = max(1, int(round(periods * per_period)))
    master = _Master(plant, G, params, step, initial, fmu_dir, sessions)
    target = min_periods
    while True:  # bounded: every pass adds a block, up to max_periods
        try:
            master.advance(int(round(target * per_period)) - master.steps)
        except FMUError as error:
            return Oscillation(False, 0.0, 0.0, 0.0, 0, reason=f"an FMU refused a step: {error}"), master.run()
        run = master.run()
        found = measure(run, periods, rtol)
        fate = _fate(run.force, block)
        if found.settled or fate or target >= max_periods:
            break
        target = min(target + periods, max_periods)
    if fate and not found.settled:
        found = Oscillation(False, 0.0, 0.0, 0.0, 0, reason=fate)
    return found, run


def _fate(force, block):
    """Why a run cannot settle any more, or "": its force swing grown DIVERGED-fold (or not finite), or gone."""
    if not np.all(np.isfinite(force)):
        return "the oscillation grows without bound (values not finite)"
    first, last = np.ptp(force[:block + 1]), np.ptp(force[-block - 1:])
    if first == 0.0:  # started at rest: nothing to compare with
        return "" if last > 0.0 else "the loop stays at rest"
    if last > DIVERGED * first:
        return (f"the oscillation grows without bound (its swing {last / first:.3g} times the first block's): "
                "beyond an unstable cycle, or a step too coarse for the co-simulation to be stable")
    if last <= 1e-9 * first:
        return "the oscillation died out: the loop came to rest"
    return ""


def verify(plant, G, cycle, params=None, samples_per_period=JUDGE_SAMPLES, periods=MIN_PERIODS, perturbation=0.5,
           fmu_dir=None, max_periods=MAX_PERIODS, rtol=1e-3):
    """Co-simulate from near a predicted cycle and from a perturbed start; compare.

    The plant starts at rest at the predicted output amplitude (and at
    ``1 + perturbation`` times it); the loop runs at least ``periods``
    predicted periods and then on until the oscillation settles or
    ``max_periods`` (:func:`settle`, :func:`measure`).

    Returns
    -------
    (dict, LoopRun): ``F``, ``omega``, ``amplitude_x``, ``settled``,
    ``rel_error_F``, ``rel_error_omega``, ``rel_error_amplitude_x`` of the
    near start against ``cycle``, ``step``, ``periods`` (how long it ran,
    in predicted periods), ``change``, ``tolerance`` and ``reason`` (see
    :class:`Oscillation`), and ``perturbed`` (the same for the perturbed
    start); the near start's run.
    """
    step = cycle.period / samples_per_period
    spec = find_plant(plant)
    sessions = (FMUSession(fmu_path(spec, fmu_dir)), FMUSession(fmu_path(CONTROLLER, fmu_dir)))
    runs, trajectories = [], []
    for scale in (1.0, 1.0 + perturbation):
        start = {spec.loop_start: scale * cycle.amplitude_x}
        found, run = settle(plant, G, params, step, cycle.period, start, fmu_dir, sessions,
                            min_periods=periods, max_periods=max(periods, max_periods), rtol=rtol)
        trajectories.append(run)
        runs.append({
            "F": found.F, "omega": found.omega, "amplitude_x": found.amplitude_x, "settled": found.settled,
            "rel_error_F": abs(found.F - cycle.F) / cycle.F,
            "rel_error_omega": abs(found.omega - cycle.omega) / cycle.omega,
            "rel_error_amplitude_x": abs(found.amplitude_x - cycle.amplitude_x) / cycle.amplitude_x,
            "start": start, "step": step, "periods": round(run.time[-1] / cycle.period, 3),
            "change": found.change if math.isfinite(found.change) else None,
            "tolerance": found.tolerance if math.isfinite(found.tolerance) else None, "reason": found.reason})
    near, perturbed = runs
    near["perturbed"] = perturbed
    return near, trajectories[0]


@dataclass
class StepRun:
    """The judge at one step of a study: what :func:`settle` measured from the predicted amplitude."""

    samples: int  # steps per expected period
    step: float
    omega: float
    F: float
    amplitude_x: float
    settled: bool
    periods: float  # how long it ran, in expected periods
    reason: str = ""


@dataclass
class Extrapolation:
    """Richardson's value of the judge at step 0, per quantity (None where it does not help).

    ``orders`` are the observed orders and ``uncertainty`` the relative
    change of the extrapolation between the last two pairs of steps (a
    generous error estimate: it contains the pair before's first-order
    residue), both from the three steps ``samples``; ``notes`` say why a
    quantity was not extrapolated.
    """

    omega: object
    F: object
    amplitude_x: object
    samples: tuple
    orders: dict
    uncertainty: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)


@dataclass
class StepStudy:
    """The judge at shrinking steps (:func:`step_study`)."""

    runs: list  # StepRun, coarse to fine
    orders: list  # per three successive settled steps: {"samples": (n1, n2, n3), "omega": p, "F": p, ...}
    richardson: object  # Extrapolation, or None (then ``reason`` says why)
    reason: str = ""

    def as_dict(self):
        return asdict(self)


def step_study(plant, G, cycle, params=None, samples=STUDY_SAMPLES, fmu_dir=None, max_periods=MAX_PERIODS,
               rtol=1e-3):
    """The judge at each of ``samples`` steps per expected period, its observed order and Richardson's value.

    Each run starts at rest at ``cycle.amplitude_x`` (``cycle``: anything
    with ``.period`` and ``.amplitude_x``, e.g. a DF prediction) and goes on
    until it settles (:func:`settle`). The hold makes the error first order
    in the step, so from three successive settled steps h1 > h2 > h3 in a
    constant ratio r the observed order is p = log((q1 - q2) / (q2 - q3)) / log r,
    and the first-order Richardson value q3 + (q3 - q2) / (r - 1) (2 q(h/2) - q(h)
    for halving steps) removes the h term.

    The first-order formula is used, not one with the observed order: where
    p drifts from 1 it does so because of the h^2 term, and extrapolating
    with p then overshoots (measured on the three shipped loops: the
    first-order value was the closer one at every step). A quantity is
    extrapolated only where that helps: three successive settled steps (an
    unsettled or diverged run means nothing), differences of one sign (a
    non-monotone sequence is dominated by the step's jitter or a change of
    the orbit, not by the hold's h term), and p within ORDER_BAND (for a
    pure order-p error the first-order value beats the raw one only for
    0 < p < log2(3)).

    Part of the error is not smooth in h and no extrapolation removes it:
    where the plant's events snap to the grid (friction breakaways), the
    measured cycle moves by up to about h/T (relative) with tiny changes of
    the step. The friction PID loop from 512..2048 steps: observed orders
    0.74..0.96 and the extrapolation 0.04..0.3% off the exact cycle over
    periods 1e-4 apart (the 2048 step itself: 2..3%); the two-mass backlash:
    orders 0.97..1.03, 7e-5 off. ``uncertainty`` covered the error in every case.
    """
    samples = _check_samples(samples)
    if not (getattr(cycle, "period", 0) > 0 and getattr(cycle, "amplitude_x", 0) > 0
            and math.isfinite(cycle.period) and math.isfinite(cycle.amplitude_x)):
        raise InputError("cycle: expected an object with a positive, finite .period and .amplitude_x")
    spec = find_plant(plant)
    sessions = (FMUSession(fmu_path(spec, fmu_dir)), FMUSession(fmu_path(CONTROLLER, fmu_dir)))
    runs = []
    for n in samples:
        step = cycle.period / n
        found, run = settle(plant, G, params, step, cycle.period, {spec.loop_start: cycle.amplitude_x}, fmu_dir,
                            sessions, max_periods=max_periods, rtol=rtol)
        runs.append(StepRun(n, step, found.omega, found.F, found.amplitude_x, found.settled,
                            round(run.time[-1] / cycle.period, 3), found.reason))
    return _extrapolate(runs)


def _check_samples(samples):
    try:
        samples = [int(n) for n in samples]
    except (TypeError, ValueError):
        raise InputError(f"samples = {samples!r}: expected a sequence of integers (steps per period)") from None
    if len(samples) < 2 or any(n < 8 for n in samples) or any(b <= a for a, b in zip(samples, samples[1:])):
        raise InputError(f"samples = {samples!r}: expected at least two, increasing, each at least 8")
    ratios = [b / a for a, b in zip(samples, samples[1:])]
    if max(ratios) - min(ratios) > 1e-9 * ratios[0]:
        raise InputError(f"samples = {samples!r}: the step must shrink by one constant ratio (e.g. doubling)")
    return samples


def _extrapolate(runs):
    """StepStudy of the runs: observed orders of every settled triple, Richardson on the finest one."""
    r = runs[1].samples / runs[0].samples
    triples = [runs[i:i + 3] for i in range(len(runs) - 2) if all(run.settled for run in runs[i:i + 3])]
    orders = [dict({"samples": tuple(run.samples for run in t)},
                   **{q: _order(*(getattr(run, q) for run in t), r) for q in QUANTITIES}) for t in triples]
    if not triples:
        return StepStudy(runs, orders, None, "no three successive steps settled: nothing to extrapolate from")
    coarse, middle, fine = triples[-1]
    values, uncertainty, notes = {}, {}, {}
    for q in QUANTITIES:
        q1, q2, q3 = getattr(coarse, q), getattr(middle, q), getattr(fine, q)
        p = orders[-1][q]
        values[q] = None
        if p is None:
            notes[q] = "not monotone: the differences change sign (jitter or a change of the orbit)"
        elif not ORDER_BAND[0] <= p <= ORDER_BAND[1]:
            notes[q] = f"observed order {p:.3g} outside {ORDER_BAND}: not the hold's first-order regime"
        else:
            values[q] = float(q3 + (q3 - q2) / (r - 1))
            uncertainty[q] = float(abs(values[q] - (q2 + (q2 - q1) / (r - 1))) / abs(values[q]))
    extrapolation = Extrapolation(values["omega"], values["F"], values["amplitude_x"], (coarse.samples,
                                  middle.samples, fine.samples), orders[-1], uncertainty, notes)
    return StepStudy(runs, orders, extrapolation, "; ".join(f"{q}: {note}" for q, note in notes.items()))


def _order(q1, q2, q3, r):
    """log((q1 - q2) / (q2 - q3)) / log r, or None when the differences are not of one sign (or vanish)."""
    d1, d2 = q1 - q2, q2 - q3
    if not d1 * d2 > 0:
        return None
    return math.log(d1 / d2) / math.log(r)


def judge_errors(measured, true_cycle):
    """Signed relative errors {omega, F, amplitude_x} of a judge's measurement against an exact cycle.

    ``measured``: anything with those attributes or keys (an
    :class:`Oscillation`, a :class:`StepRun`, an :class:`Extrapolation`,
    :func:`verify`'s dict); ``true_cycle``: anything with ``.omega``, ``.F``
    and ``.amplitude_x`` (a :class:`dfwb.engine.periodic.TrueCycle`).
    Positive: the judge is high. None where ``measured`` has no value (a
    quantity not extrapolated).
    """
    errors = {}
    for q in QUANTITIES:
        value = measured.get(q) if isinstance(measured, dict) else getattr(measured, q, None)
        exact = _number(getattr(true_cycle, q, None))
        if exact is None or exact == 0:
            raise InputError(f"true_cycle.{q} = {getattr(true_cycle, q, None)!r}: expected a finite, non-zero number")
        if value is not None and _number(value) is None:
            raise InputError(f"measured {q} = {value!r}: expected a finite number or None")
        errors[q] = None if value is None else float(value) / exact - 1.0
    return errors


def _number(value):
    """float(value) if it is a finite real number (not a bool), else None."""
    if isinstance(value, bool):
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None
