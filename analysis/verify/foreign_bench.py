"""The cost and error of a DF point of a user's FMU, beside the built-in exact engine (a part of ``dfwb bench``).

Two kinds of foreign plant, each point timed (median of repeats after one warm-up run, the worker process
started) and checked against an independent value:

- **model exchange**: the small C FMUs of :mod:`dfwb.build_fmus.c_models` (a mass-spring-damper, a
  saturation, a relay with hysteresis), compiled here, at the driver's rtol 1e-8 (and, in the full set, its
  default 1e-10), against their closed forms;
- **co-simulation**: dfwb's own native plant FMUs run as black boxes (input ``f``, the built-in excitation
  left at F = 0; held input, refined and extrapolated, rtol 1e-6), at the plants' benchmark points, against
  the exact engine on the same FMU, whose time is measured beside.

Each row carries the true error and the reported ``N_error`` (both relative to |N|): the estimate is
honest where the first is below the second.
"""

import statistics
import tempfile
import time

from dfwb.build_fmus import c_models
from dfwb.engine.describing import DFEngine
from dfwb.fmi.location import fmu_path
from dfwb.foreign.engine import FMUEngine
from dfwb.foreign.plant import fmu_plant
from dfwb.plants import PLANTS

ME_POINTS = (("MassSpringDamper", 1.0, 1.0, lambda F, w: c_models.msd_df(w)),
             ("MassSpringDamper", 2.0, 2.0, lambda F, w: c_models.msd_df(w)),
             ("Saturation", 3.0, 1.0, lambda F, w: c_models.saturation_df(F)),
             ("Relay", 3.0, 2.0, lambda F, w: c_models.relay_df(F)))
ME_RTOLS = {True: (1e-8,), False: (1e-8, 1e-10)}  # quick, full
CS_RTOL = 1e-6
FIELDS = ["kind", "plant", "F", "omega", "params", "rtol", "error", "N_error", "seconds", "exact_seconds"]


def timed(run, repeats):
    """(median seconds, last result) of ``repeats`` runs after one untimed warm-up run (fewer once they
    have taken 2 s: a slow point's median needs no more)."""
    result = run()
    seconds = []
    while len(seconds) < repeats and sum(seconds) <= 2.0:
        started = time.perf_counter()
        result = run()
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds), result


def foreign_rows(quick=True, repeats=3, fmu_dir=None, report=print):
    """The measured rows (dicts of :data:`FIELDS`) of both kinds; a kind that cannot run here is one
    row with ``error`` None and ``why`` saying why (no C compiler, say)."""
    return model_exchange_rows(quick, repeats, report) + co_simulation_rows(quick, repeats, fmu_dir, report)


def model_exchange_rows(quick, repeats, report=print):
    rows = []
    with tempfile.TemporaryDirectory(prefix="dfwb_bench_foreign_") as folder:
        try:
            built = {name: c_models.build(name, folder) for name in dict.fromkeys(p[0] for p in ME_POINTS)}
        except c_models.CoreBuildError as error:
            return [{"kind": "model-exchange", "plant": "c_models", "error": None, "why": str(error)}]
        for rtol in ME_RTOLS[quick]:
            for name, F, omega, closed_form in ME_POINTS:
                engine = FMUEngine(fmu_plant(built[name]), rtol=rtol)
                seconds, result = timed(lambda: engine.point(F, omega, {}), repeats)
                truth = closed_form(F, omega)
                rows.append({"kind": "model-exchange", "plant": name, "F": F, "omega": omega, "params": {},
                             "rtol": rtol, "error": abs(result.N - truth) / abs(truth),
                             "N_error": result.N_error / abs(truth), "seconds": seconds, "exact_seconds": None})
                report(f"foreign model exchange {name} F={F:g} omega={omega:g} rtol={rtol:g}: {seconds * 1e3:.0f} ms")
    return rows


def co_simulation_rows(quick, repeats, fmu_dir=None, report=print):
    rows = []
    for name, entry in PLANTS.items():
        if not (entry.bench and entry.model.native_solver):  # a plant with benchmark points and a native FMU
            continue
        path = fmu_path(entry, fmu_dir, kind="native")
        generic = FMUEngine(fmu_plant(path, input="f", output=entry.output), rtol=CS_RTOL)
        exact = DFEngine(name, fmu=path)
        for F, omega, params in entry.bench["quick" if quick else "full"]:
            seconds, result = timed(lambda: generic.point(F, omega, dict(params)), repeats)
            exact_seconds, truth = timed(lambda: exact.point(F, omega, dict(params)), max(repeats, 5))
            rows.append({"kind": "co-simulation", "plant": name, "F": F, "omega": omega, "params": dict(params),
                         "rtol": CS_RTOL, "error": abs(result.N - truth.N) / abs(truth.N),
                         "N_error": result.N_error / abs(truth.N), "seconds": seconds,
                         "exact_seconds": exact_seconds})
            report(f"foreign co-simulation {name} F={F:g} omega={omega:g}: {seconds * 1e3:.0f} ms")
    return rows


def foreign_markdown(rows):
    """The section of ``bench.md`` on a user's FMU, from :func:`foreign_rows`."""
    text = ["## A user's FMU through the generic driver", "",
            "A DF point of a foreign FMU (`dfwb.fmu_plant`): small C model-exchange FMUs "
            "(`dfwb.build_fmus.c_models`) against their closed forms, and dfwb's native plant FMUs run as "
            "black-box co-simulation FMUs (held input, refined and extrapolated) against the exact engine on "
            "the same FMU. Errors relative to |N|; `N_error` is the driver's own estimate (honest where it is "
            "above the true error); times are medians after a warm-up.", ""]
    for why in [r["why"] for r in rows if r.get("why")]:
        text += [f"Not measured: {why}", ""]
    rows = [r for r in rows if not r.get("why")]
    honest = sum(r["error"] <= r["N_error"] for r in rows)
    text += [f"The true error is below `N_error` at {honest} of {len(rows)} points.", "",
             "| kind | plant | F | w | params | rtol | true error | N_error | ms per point | exact engine, ms "
             "| ratio |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        exact = r["exact_seconds"]
        text.append(f"| {r['kind']} | {r['plant']} | {r['F']:g} | {r['omega']:g} | {_params(r['params'])} | "
                    f"{r['rtol']:g} | {r['error']:.1e} | {r['N_error']:.1e} | {r['seconds'] * 1e3:.0f} | "
                    + (f"{exact * 1e3:.2f} | {r['seconds'] / exact:.0f} |" if exact else "| |"))
    return text


def _params(params):
    return ", ".join(f"{k} = {v:g}" for k, v in params.items())
