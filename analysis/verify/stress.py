"""Numerical stress suite for the plant solvers (``dfwb stress``).

Each *case* drives one registered plant's solver (the ``solver_class`` of
its FMU facade: :class:`~dfwb.fmus.FrictionMass`,
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
the subintervals used (at most period/16 and between events, 16 nodes). An
integrated plant (``stribeck``) is accurate to its tolerance, not to
rounding: its profile adds 100 rtol of the scale to its balances, and the
Fourier check adds the plant's own bound on its integrals' error.

Cases (``quick``: 649, of which 211 invalid inputs; ~80 s on one core of
this two-core machine): every restitution eps in
{0, 1e-9, 0.5, 1 - 1e-9, 1}; h from 1e-9 to 10 m, F from 1e-6 to 1e6 N,
w from 1e-4 to 1e4 rad/s, masses from 1e-6 to 1e6 kg (the other parameters
chosen so the case stays in the regime it probes: for the backlash the
ratio of the free amplitude F/(M2 w^2) to h); Fs = Fc and B = 0 for friction,
Fs exactly at the force's peak, a constant force equal to +-Fs; steps from
1e-9 s to 1e3 s (also 1e-9 s steps at t = 10 and t = 1e6); held inputs
(a sampled sine, step patterns that stop, reverse and press again, and
random runs of values with exact zeros, repeats and +-Fs, as a controller
feeds them); seeded random parameters (``random.Random(seed)``,
reproducible); invalid parameters. The full set (``quick=False``, 1548
cases) adds more
random cases, every eps on every axis and 1e5-period horizons;
``part``/``parts`` split it for CI.

What the suite knows of a plant is the plant's stress profile
(:attr:`dfwb.plants.registry.Plant.stress`, a
:class:`~dfwb.plants.stress_kit.StressProfile`; the built-in ones are in
:mod:`dfwb.plants.stress_profiles`): its cases, its per-point observer (the
plant-specific checks above), its energy and impulse balances and its
invalid parameters. Every registered plant with a profile is stressed, in
registration order; this module holds the machinery they share.
"""

import cmath
import math
import random
import sys
import time
from array import array

import numpy as np

from dfwb.base.errors import InputError
from dfwb.fmus import PlantError
from dfwb.plants import PLANTS
from dfwb.plants.stress_kit import (  # noqa: F401  (re-exported: the suite's vocabulary)
    BUDGET,
    EPS,
    LONG_BUDGET,
    TWO_PI,
    Case,
    InvalidCase,
    StressObserver,
    StressProfile,
    harmonic_impulse,
    loguniform,
    profile,
    uniform,
)

EVENTS_PER_PERIOD = 1e4
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(16)
GL_MAX_INTERVALS = 20_000  # above this the quadrature checks are skipped (noted)


def stressed():
    """The registered plants that have a stress profile, in registration order."""
    return [entry for entry in PLANTS.values() if entry.stress is not None]


# -- cases ------------------------------------------------------------------------------
def _random_held(rng, i):
    """A held input as a master feeds a controller's output: runs of values that
    include exact zeros, exact repeats, sign flips and the plant's special values (friction: exactly +-Fs)."""
    entry = rng.choice(tuple(entry for entry in stressed() if entry.stress.random_held is not None))
    scale = loguniform(rng, 1e-3, 1e3)
    w = loguniform(rng, 1e-2, 1e2)
    F = 0.0 if rng.random() < 0.5 else scale * rng.uniform(0.2, 2.0)
    params, special = entry.stress.random_held(rng, scale, w, F)
    special = tuple(special)
    params["phi"] = rng.choice((0.0, rng.uniform(-math.pi, math.pi)))
    values = []
    n = rng.randint(8, 60)
    while len(values) < n:
        value = rng.choice((0.0, scale, -scale, scale * rng.uniform(-2, 2)) + special)
        values += [value] * rng.randint(1, 5)
    dt = TWO_PI / w / rng.choice((4, 16, 64))
    case = Case(entry.name, params, *uniform(dt * len(values), len(values)), inputs=tuple(values),
                note=f"random held input #{i}", input_form=repr(tuple(values)))
    return case


def _long_cases():
    """1e5 periods, read every 10 periods: the full set only."""
    n, every = 100_000, 10

    def long(plant, params, note):
        period = TWO_PI / params["omega"]
        times, stepping = uniform(n * period, n // every)
        return Case(plant, dict(params), times, stepping, note=note, long=True, budget=LONG_BUDGET, quadrature=False)

    return [long(entry.name, params, note) for entry in stressed() for params, note in entry.stress.long]


def _invalid_cases():
    """Every plant: bad excitation parameters (common to all), its own bad parameters, bad inputs and steps."""
    nan, inf = math.nan, math.inf
    cases = []
    common = [("F", nan), ("F", inf), ("omega", 0.0), ("omega", -1.0), ("omega", nan), ("omega", inf),
              ("phi", nan), ("phi", -inf), ("phi", 1e300), ("f", nan), ("f", inf), ("harmonics", 11),
              ("harmonics", -1), ("harmonics", 2.5), ("harmonics", nan), ("harmonics", inf), ("omega", None),
              ("F", "1")]
    for entry in stressed():
        for name, value in common + list(entry.stress.invalid):
            cases.append(InvalidCase(entry.name, {name: value}, name))
        for value in (nan, inf, -inf):
            cases.append(InvalidCase(entry.name, {}, "f", "set_input", value))
        for value in (nan, -1.0, inf, 1e300):  # 1e300: a phase that no longer resolves a period
            cases.append(InvalidCase(entry.name, {}, "t_end", "advance", value))
    return cases


def all_cases(quick=True, seed=20240505):
    """The valid and invalid cases, in a fixed order (seeded random cases)."""
    rng = random.Random(seed)
    cases = []
    for entry in stressed():
        cases += entry.stress.cases(entry.name, rng, quick)
    cases += [_random_held(rng, i) for i in range(64 if quick else 300)]  # over every stressed plant
    if not quick:
        cases += _long_cases()
    return cases + _invalid_cases()


# -- reporting ----------------------------------------------------------------------------
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
    return profile(case.plant)[0](**case.params)


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
    stress = profile(case.plant)[1]
    plant = _make(case)
    H = plant.harmonics
    work = impulse = abs_work = abs_impulse = 0.0
    fourier = [0j] * (H + 1)
    abs_y = y_max = dy_max = 0.0
    y_index, v_index, rate, force = stress.output, stress.velocity, stress.rate, stress.force
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
            if force is not None:
                impulse += wt * (u - out[force])
                abs_impulse += wt * (abs(u) + abs(out[force]))
            z = cmath.exp(-1j * w * t)
            zk = 1.0
            for k in range(H + 1):
                fourier[k] += wt * y * zk
                zk *= z
            abs_y += wt * abs(y)
            y_max = max(y_max, abs(y))
            dy_max = max(dy_max, abs(out[rate]))
    plant.advance(case.times[-1])
    f_max = abs(p.get("f", 0.0)) if case.inputs is None else max(abs(x) for x in case.inputs)
    dy_max, ddy_max = stress.bounds(p, F, f_max, dy_max)
    # step independence: the same end state whatever the communication points
    sig_a, sig_c = _signature(plant_a), _signature(plant)
    if array("d", sig_a).tobytes() != array("d", sig_c).tobytes():
        diff = [(i, a_, c_) for i, (a_, c_) in enumerate(zip(sig_a, sig_c))
                if array("d", [a_]).tobytes() != array("d", [c_]).tobytes()]
        failures.add("step_independence", t=case.times[-1], differing=len(diff),
                     first=[{"index": i, "run": a_, "gauss_nodes_run": c_} for i, a_, c_ in diff[:4]],
                     why="stepping through Gauss-Legendre nodes instead of the communication points "
                         "changed the end state")
    stop = case.times[-1]
    n = plant_a.events + 1 + (len(case.inputs) if case.inputs is not None else 0)
    out_a = plant_a.output()
    # the plant's energy (and impulse) balances
    sums = {"work": work, "abs_work": abs_work, "impulse": impulse, "abs_impulse": abs_impulse, "f_max": f_max}
    for check, err, tol, detail in stress.balances(case, out_a, n, sums):
        margins.see(check, err, tol, case)
        if not err <= tol:
            failures.add(check, t=stop, **detail)
    # Fourier integrals: each piece's closed form is exact to a few ulp of the
    # output's scale Y = max|y| + max|y'|/w + max|y''|/w^2 divided by k w (the
    # integration by parts divides by k w twice), however short the piece, so
    # n pieces carry n ulp of Y/w; the phases k w t carry k ulp of w t each.
    integrals = plant_a.integrals()
    Y = y_max + dy_max / w + ddy_max / (w * w)
    tol = 1e-9 * (abs_y + Y / w) + 16.0 * EPS * n * (Y / w + abs_y * max(H, 1) * w * stop)
    if hasattr(plant_a, "integrals_error"):  # an integrated plant: plus its own bound on int |y error| dt
        tol += plant_a.integrals_error()
    worst = max(range(H + 1), key=lambda k: abs(integrals[k] - fourier[k]))
    err = abs(integrals[worst] - fourier[worst])
    margins.see("fourier", err, tol, case)
    if not err <= tol:
        failures.add("fourier", t=stop, k=worst, solver=repr(integrals[worst]), quadrature=repr(fourier[worst]),
                     error=err, tol=tol, why="running Fourier integral != quadrature of the output")
    return None


# -- one case ---------------------------------------------------------------------------
def run_case(case, margins=None):
    """Run one case; returns (list of failures, seconds of run A, notes)."""
    margins = margins if margins is not None else _Margins()
    if isinstance(case, InvalidCase):
        return _run_invalid(case), 0.0, []
    failures = _Failures(case)
    notes = []
    observer = profile(case.plant)[1].observer(case, failures, margins)
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
        plant = _make(case)
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
        raise InputError(f"part = {part!r}, parts = {parts!r}: expected 0 <= part < parts")
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
            print(f"[{i + 1}/{len(cases)}] {seconds:7.3f}s {status}  {case.describe()[:150]}", file=sys.stderr,
                  flush=True)
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
