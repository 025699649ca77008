"""A limit-cycle analysis, the one way dfwb does it (the API, the command line and scenes all call :func:`analyse`).

For a plant under a controller G(s):

1. the describing function's predictions, solving G(jw) N(F, w) = -1 on a DF
   map over ranges derived from the plant and G when none are given
   (:mod:`dfwb.engine.scales`: from the force that moves the plant to what the
   linear loop allows), refined by Newton (:mod:`dfwb.engine.limit_cycles`);
2. with ``verify``, the co-simulation judge of each prediction
   (:func:`dfwb.engine.closed_loop.verify`);
3. with ``exact``, the true cycles of the exact closed loop, found by the
   systematic search with its coverage (:func:`dfwb.engine.cycles.find_cycles`),
   each prediction linked to its true cycle.

A cache (:class:`dfwb.studies.cache.Cache`) keeps the judge's runs and the
exact search under keys of everything they depend on; a DF ``engine`` may be
given (a scene's reads its points from the run and the cache).
"""

import math

from dfwb.base.errors import InputError
from dfwb.engine.family import LoopFamily
from dfwb.engine.scales import search_ranges
from dfwb.engine.transfer import num_den
from dfwb.foreign.engine import engine_for
from dfwb.studies.cache import code_revision, finite, fmu_revision, solver_revision
from dfwb.studies.responses import LimitCycleResponse


def analyse(plant, G, values=None, *, F_range=None, omega_range=None, n_F=16, n_omega=48, exact=False, verify=False,
            samples_per_period=512, amplitudes=None, fmu_dir=None, engine=None, cache=None, progress=None):
    """The limit cycles of ``plant`` under ``G``: :class:`~dfwb.studies.responses.LimitCycleResponse`.

    ``values``: G's parameters and the plant's; ``progress``: ``progress(stage, done, total)`` or None;
    the rest as :func:`dfwb.limit_cycles`.
    """
    from dfwb.engine.limit_cycles import search

    family = LoopFamily(plant, G, values)
    spec, controller, params = family.spec, family.G(), family.params()
    if not (2 <= n_F <= 1000 and 2 <= n_omega <= 1000):
        raise InputError(f"a DF map of {n_F} x {n_omega} points: each side must have 2 to 1000")
    foreign = getattr(spec, "foreign", False)
    problem = family.problem(fmu_dir=fmu_dir) if spec.loop is not None else None
    if exact and problem is None and not foreign:
        raise InputError(f"plant {spec.name!r} has no exact closed loop: exact is available for "
                         "friction, backlash and static-backlash, and for your own model-exchange FMU")
    if verify and foreign:
        raise InputError("verify runs dfwb's own closed-loop FMUs: not yet for your own FMU")
    F, omega = search_ranges(problem, F_range, omega_range)
    if amplitudes is not None:
        amplitudes = _amplitudes(amplitudes)
    engine = engine or engine_for(spec, fmu_dir=fmu_dir)
    found = search(spec.name, controller, params, F, omega, n_F, n_omega, engine=engine,
                   progress=None if progress is None else (lambda done, total: progress("DF map", done, total)))
    predictions = found.cycles
    verification, runs = [], []
    if verify:
        for i, prediction in enumerate(predictions):
            outcome, run = _judge(spec, controller, params, prediction, samples_per_period, fmu_dir, cache)
            verification.append(outcome)
            runs.append((prediction, run))
            if progress:
                progress("judge", i + 1, len(predictions))
    search_result = None
    if exact and foreign:
        search_result = _exact_fmu(engine, controller, params, predictions, amplitudes, F, omega)
    elif exact:
        search_result = _exact(problem, predictions, amplitudes, cache, progress)
    return LimitCycleResponse(plant=spec.name, params=params, G=controller, predictions=predictions,
                              F_grid=found.F_grid, omega_grid=found.omega_grid, N_grid=found.N_grid,
                              cycles=search_result.cycles if search_result else [],
                              links=search_result.links if search_result else [],
                              coverage=search_result.coverage if search_result else None,
                              verification=verification, runs=runs, F_range=list(F), omega_range=list(omega),
                              values=family.merged(), unit=spec.unit)


def _amplitudes(amplitudes):
    """Start amplitudes: 1 to 100 positive finite numbers."""
    try:
        values = [float(a) for a in amplitudes]
    except (TypeError, ValueError):
        raise InputError(f"amplitudes = {amplitudes!r:.60}: expected a list of positive numbers") from None
    if not 1 <= len(values) <= 100 or not all(math.isfinite(a) and a > 0.0 for a in values):
        raise InputError(f"amplitudes = {amplitudes!r:.60}: expected 1 to 100 positive, finite numbers")
    return sorted(values)


def _judge(spec, G, params, prediction, samples_per_period, fmu_dir, cache):
    """(outcome, run) of the co-simulation judge of one prediction (its run's last 10 periods), cached."""
    import numpy as np

    from dfwb.engine.closed_loop import CONTROLLER, LoopRun, verify
    from dfwb.fmi.location import fmu_path

    fmus = [fmu_revision(fmu_path(spec, fmu_dir)), fmu_revision(fmu_path(CONTROLLER, fmu_dir))]
    key = {"kind": "verify", "fmu": fmus,
           "code": code_revision(), "plant": spec.name, "params": params, "G": num_den(G),
           "cycle": [prediction.F, prediction.omega, prediction.amplitude_x], "samples_per_period": samples_per_period}
    value = cache.get(key) if cache is not None else None
    if value is None:
        outcome, run = verify(spec.name, G, prediction, params, samples_per_period, fmu_dir=fmu_dir)
        tail = run.time >= run.time[-1] - 10 * prediction.period  # what the figure shows
        value = {"outcome": outcome, "run": {"time": run.time[tail].tolist(), "step": run.step,
                                             "position": run.position[tail].tolist(),
                                             "force": run.force[tail].tolist()}}
        if cache is not None:
            cache.put(key, finite(value))
    run = value["run"]
    return value["outcome"], LoopRun(np.array(run["time"]), np.array(run["position"]), np.array(run["force"]),
                                     run["step"])


def _exact(problem, predictions, amplitudes, cache, progress):
    """The exact search around the predictions (:func:`dfwb.engine.cycles.find_cycles`), cached."""

    from dfwb.engine import cycles as search
    from dfwb.engine.periodic import TrueCycle

    key = {"kind": "exact", "code": code_revision(), "solvers": solver_revision(), "plant": problem.spec.name,
           "params": problem.params, "G": num_den(problem.G), "amplitudes": amplitudes,
           "predictions": [[c.F, c.omega, c.amplitude_x] for c in predictions]}
    value = cache.get(key) if cache is not None else None
    if value is None:
        def report(done, total, label):
            if progress is not None and done is not None:
                progress("exact loop", done, total)

        found = search.find_cycles(problem, predictions, amplitudes, progress=report)
        value = {"cycles": [dict(c.as_dict(), trace={"t": c.trace["t"].tolist(), "y": c.trace["y"].tolist(),
                                                     "f": c.trace["f"].tolist(),
                                                     "events": [[t, str(k)] for t, k in c.trace["events"]]})
                            for c in found.cycles], "links": found.links, "coverage": found.coverage.as_dict()}
        if cache is not None:
            cache.put(key, finite(value))
        return found
    cycles = []
    for entry in value["cycles"]:
        cycles.append(TrueCycle(**dict(entry, trace=_trace(entry["trace"]))))
    return search.CycleSearch(cycles, value["links"], search.Coverage(**value["coverage"]), [])


def _trace(trace):
    """A true cycle's trace from its JSON form: arrays of t, y and f, and (time, kind) events."""
    import numpy as np

    return {"t": np.array(trace["t"]), "y": np.array(trace["y"]), "f": np.array(trace["f"]),
            "events": [tuple(e) for e in trace["events"]]}


def _exact_fmu(engine, G, params, predictions, amplitudes, F_range, omega_range):
    """The true cycles of a user's FMU under G (:mod:`dfwb.foreign.loop`), with coverage.

    Starts: the first force +-F0 for F0 the predictions' forces and three across the F range (or the
    ``amplitudes`` given, read as forces); the time scale: the predictions' median frequency, else the
    middle of the omega range.
    """
    from dfwb.engine import cycles as search
    from dfwb.engine.periodic import TrueCycle

    forces = sorted(set(amplitudes or [p.F for p in predictions] +
                        [math.exp(math.log(F_range[0]) + i * (math.log(F_range[1]) - math.log(F_range[0])) / 2)
                         for i in range(3)]))
    starts = [sign * F for F in forces for sign in (1.0, -1.0)]
    omegas = sorted(p.omega for p in predictions)
    omega_ref = omegas[len(omegas) // 2] if omegas else math.sqrt(omega_range[0] * omega_range[1])
    num, den = num_den(G)
    found, outcomes = engine.true_cycles(num, den, params, starts, omega_ref)
    cycles = [TrueCycle(**dict(entry, trace=_trace(entry["trace"]))) for entry in found]
    links = []
    for prediction in predictions:  # the nearest true cycle in frequency and amplitude, within a factor 1.5
        near = [(abs(math.log(c.omega / prediction.omega)) + abs(math.log(c.amplitude_x / prediction.amplitude_x)), j)
                for j, c in enumerate(cycles) if c.amplitude_x > 0 and prediction.amplitude_x > 0]
        near = [(d, j) for d, j in near if d < 2 * math.log(1.5)]
        links.append(min(near)[1] if near else None)
    for j, cycle in enumerate(cycles):
        cycle.prediction = next((i for i, link in enumerate(links) if link == j), None)
    counts = {}
    for outcome in outcomes:
        key = outcome.split(":")[0]
        counts[key] = counts.get(key, 0) + 1
    from dfwb.foreign.loop import MAX_RETURNS, SETTLE

    text = (f"first forces +-{forces[0]:.3g} to {forces[-1]:.3g} N ({len(forces)} values) from the plant's "
            f"start values, each run {SETTLE} periods of {2 * math.pi / omega_ref:.4g} s before its swing is read")
    if engine.plant.kind == "co-simulation":
        text += ("; the loop co-simulated (the output held over each step, the controller exact) and refined "
                 "from 32 steps per period, extrapolated: stable cycles only (unstable ones are out of reach of "
                 "a stepped FMU)")
    coverage = search.Coverage(amplitudes=[forces[0], forces[-1]], count=len(forces), parts=["force"],
                               starts=len(starts), predictions=len(predictions), outcomes=counts,
                               horizon=20 * 2 * math.pi / omega_ref, max_returns=MAX_RETURNS,
                               complete=not any(o.startswith("failed") for o in outcomes), starts_text=text)
    return search.CycleSearch(cycles, links, coverage, [])
