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

import numpy as np

from dfwb.base.defaults import DF_MAP_SIZE, JUDGE_SAMPLES
from dfwb.base.errors import InputError
from dfwb.base.values import leaves, real, short
from dfwb.engine.compensators import check_judged
from dfwb.engine.family import LoopFamily
from dfwb.engine.scales import search_ranges
from dfwb.engine.transfer import num_den
from dfwb.foreign.engine import engine_for
from dfwb.foreign.hunting import true_search
from dfwb.studies.cache import code_revision, finite, fmu_revision, solver_revision
from dfwb.studies.responses import LimitCycleResponse


def analyse(plant, G, values=None, *, F_range=None, omega_range=None, n_F=None, n_omega=None,
            exact=False, verify=False,
            samples_per_period=JUDGE_SAMPLES, amplitudes=None, fmu_dir=None, engine=None, cache=None, progress=None,
            compensate=None):
    """The limit cycles of ``plant`` under ``G``: :class:`~dfwb.studies.responses.LimitCycleResponse`.

    ``values``: G's parameters, the plant's and the compensators'; ``progress``: ``progress(stage, done,
    total)`` or None; the rest as :func:`dfwb.limit_cycles`. A compensated loop (``compensate``) is judged
    by its truth (``exact`` required), with its cost; its DF is computed where the compensated plant is a plant
    (:meth:`~dfwb.engine.compensators.Compensation.equivalent`: the velocity's feedforward on the friction mass).
    """
    from dfwb.engine.cost import step_cost
    from dfwb.engine.limit_cycles import search

    family = LoopFamily(plant, G, values, compensate=compensate)
    compensated = bool(family.compensation)
    check_judged(family.compensation, exact, verify)
    spec, controller, params = family.spec, family.G(), family.params()
    engine = engine or engine_for(spec, fmu_dir=fmu_dir)
    df_engine = family.df_engine(engine)
    size = getattr(df_engine, "map_size", DF_MAP_SIZE)  # the dither's DF, whose points cost, maps fewer
    n_F, n_omega = size[0] if n_F is None else n_F, size[1] if n_omega is None else n_omega
    if not (2 <= n_F <= 1000 and 2 <= n_omega <= 1000):
        raise InputError(f"a DF map of {short(n_F, 30)} x {short(n_omega, 30)} points: each side must have 2 to 1000")
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
    if exact and problem is not None and problem.dither is not None:  # refused before its DF map, if at all
        from dfwb.engine.dither import check_dither

        check_dither(problem, amplitudes)
    # the plant's DF, or a compensated loop's equivalent plant's; None: it has none (the plant's would predict the
    # uncompensated loop's cycles)
    df_params = family.df_params()
    if df_params is None:
        grids, predictions = (np.zeros(0), np.array(omega, dtype=float), np.zeros((0, 2), complex)), []
    else:
        found = search(spec.name, controller, df_params, F, omega, n_F, n_omega, engine=df_engine,
                       progress=None if progress is None else (lambda done, total: progress("DF map", done, total)))
        grids, predictions = (found.F_grid, found.omega_grid, found.N_grid), found.cycles
    verification, runs = [], []
    if verify:
        for i, prediction in enumerate(predictions):
            outcome, run = _judge(spec, controller, params, prediction, samples_per_period, fmu_dir, cache)
            verification.append(outcome)
            runs.append((prediction, run))
            if progress:
                progress("judge", i + 1, len(predictions))
    search_result = cost = None
    if exact and foreign:
        search_result = true_search(engine, controller, params, predictions, amplitudes, F, omega)
    elif exact:
        search_result = _exact(problem, predictions, amplitudes, cache, progress)
        cost = step_cost(problem)
    return LimitCycleResponse(plant=spec.name, params=params, G=controller, predictions=predictions,
                              F_grid=grids[0], omega_grid=grids[1], N_grid=grids[2],
                              compensation=family.compensation.describe(family.merged()), cost=cost,
                              equivalent=df_params if compensated else None,
                              df_described=family.compensation.df_text(spec) if compensated else None,
                              cycles=search_result.cycles if search_result else [],
                              responses=getattr(search_result, "responses", None),
                              hunting=[{"start": f.start, "detail": f.detail} for f in search_result.fates
                                       if f.outcome == "hunting"] if search_result else [],
                              links=search_result.links if search_result else [],
                              coverage=search_result.coverage if search_result else None,
                              verification=verification, runs=runs,
                              F_range=[float(grids[0][0]), float(grids[0][-1])] if len(grids[0]) else list(F),
                              omega_range=[float(grids[1][0]), float(grids[1][-1])] if len(grids[1]) else list(omega),
                              values=family.merged(), unit=spec.unit)


def _amplitudes(amplitudes):
    """Start amplitudes: 1 to 100 positive finite numbers."""
    try:
        values = ([None] if isinstance(amplitudes, (str, bytes, bytearray, memoryview))
                  else [real(a) for a in amplitudes] if leaves(amplitudes, 100) <= 100 else [])
    except TypeError:  # not a list
        values = [None]
    if None in values:
        raise InputError(f"amplitudes = {short(amplitudes, 60)}: expected a list of positive numbers")
    if not 1 <= len(values) <= 100 or not all(math.isfinite(a) and a > 0.0 for a in values):
        raise InputError(f"amplitudes = {short(amplitudes, 60)}: expected 1 to 100 positive, finite numbers")
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
    from dfwb.engine import truth

    key = {"kind": "exact", "code": code_revision(), "solvers": solver_revision(), "plant": problem.spec.name,
           "params": problem.params, "G": num_den(problem.G), "amplitudes": amplitudes,
           "compensation": repr(problem.compensation),
           "predictions": [[c.F, c.omega, c.amplitude_x] for c in predictions]}
    value = cache.get(key) if cache is not None else None
    if value is None:
        def report(done, total, label):
            if progress is not None and done is not None:
                progress("exact loop", done, total)

        found = truth.search(problem, predictions, amplitudes, progress=report)
        value = {"cycles": [_stored(c) for c in found.cycles], "links": found.links,
                 "coverage": found.coverage.as_dict(),
                 "fates": [[f.start, f.outcome, f.detail] for f in found.fates if f.outcome == "hunting"]}
        if problem.dither is not None:  # the dither's own responses (dfwb.engine.dither)
            value["responses"] = [_stored(c) for c in found.responses]
        if cache is not None:
            cache.put(key, finite(value))
        return found
    cycles = [_restored(entry) for entry in value["cycles"]]
    fates = [search.Fate(start, outcome, detail=detail) for start, outcome, detail in value.get("fates", [])]
    found = search.CycleSearch(cycles, value["links"], search.Coverage(**value["coverage"]), fates)
    if "responses" in value:
        found.responses = [_restored(entry) for entry in value["responses"]]
    return found


def _restored(entry):
    """A true cycle from the cache's JSON types (:func:`_stored`)."""
    from dfwb.engine.periodic import TrueCycle, trace_arrays

    return TrueCycle(**dict(entry, trace=trace_arrays(entry["trace"])))


def _stored(cycle):
    """A true cycle as JSON types, its trace included (what the cache keeps)."""
    trace = cycle.trace
    return dict(cycle.as_dict(), trace={"t": trace["t"].tolist(), "y": trace["y"].tolist(), "f": trace["f"].tolist(),
                                        "events": [[t, str(k)] for t, k in trace["events"]]})
