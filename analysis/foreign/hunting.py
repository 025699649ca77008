"""Loops with a user's FMU: their true cycles searched, and a setting classified as dfwb's own loops' are.

The truth is :mod:`dfwb.foreign.loop`'s (model exchange: integrated and shot,
Floquet multipliers; co-simulation: co-simulated, refined and extrapolated,
stable cycles only), run from first forces +-F0 at the DF's predictions'
forces and across the F range. A setting's cell (:func:`cells`, and
:func:`classifier` for :func:`dfwb.engine.margin.margins`) has the shape
:func:`dfwb.engine.hunting.classify` gives: the truth's class and cycles, and
the DF's, from a map of the FMU's DF at the setting's plant parameters (one
map for every gain, or every setting of G). An FMU has no linear part dfwb
knows, so the DF's verdict here is never "diverges".
"""

import math

import numpy as np

from dfwb.base.defaults import DF_MAP_SIZE
from dfwb.base.errors import OWN_PLANTS, InputError, fmu_only
from dfwb.engine import cycles as search
from dfwb.engine.hunting import DFMap, df_cell, truth_cell
from dfwb.engine.limit_cycles import balance, df_map
from dfwb.engine.margin import GAIN
from dfwb.engine.periodic import TrueCycle, trace_arrays
from dfwb.engine.transfer import num_den
from dfwb.foreign.loop import MAX_RETURNS, SETTLE

__all__ = ["study", "no_fmu_options", "true_search", "predictor", "cells", "classifier"]



def no_fmu_options(F_range, omega_range, size, rtol, timeout, own=OWN_PLANTS, **more):
    """:func:`study`'s options given to dfwb's own plant: refused in one line naming them (``more``: other
    such options, each ``(value, default)``; ``own``: why the plant needs none)."""
    given = dict(F_range=(F_range, None), omega_range=(omega_range, None), n_F=(size[0], DF_MAP_SIZE[0]),
                 n_omega=(size[1], DF_MAP_SIZE[1]), rtol=(rtol, None), timeout=(timeout, None), **more)
    fmu_only(given, own)


def study(spec, F_range, omega_range, size, rtol, timeout):
    """(engine, F range, omega range) of a margin, map or continuation of a user's FMU: its DF map's ranges
    (required: dfwb cannot derive them from an FMU) and sides checked, refused in one line."""
    from dfwb.engine.scales import search_ranges
    from dfwb.foreign.engine import engine_for

    if F_range is None or omega_range is None:
        raise InputError("give F_range and omega_range: dfwb cannot derive them from a user's FMU")
    F, omega = search_ranges(None, F_range, omega_range)
    if not all(isinstance(n, int) and not isinstance(n, bool) and 2 <= n <= 1000 for n in size):
        raise InputError(f"n_F, n_omega = {size[0]!r}, {size[1]!r}: the DF map's sides, integers from 2 to 1000")
    return engine_for(spec, rtol=rtol, timeout=timeout), F, omega


def true_search(engine, G, params, predictions, amplitudes, F_range, omega_range):
    """The true cycles of a user's FMU under G (:mod:`dfwb.foreign.loop`), with coverage.

    Starts: the first force +-F0 for F0 the predictions' forces and three across the F range (or the
    ``amplitudes`` given, read as forces); the time scale: the predictions' median frequency, else the
    middle of the omega range. A model-exchange FMU's loop is also shot from each unstable prediction's
    harmonic balance (the runs only ever settle on stable cycles).
    """
    forces = sorted(set(amplitudes or [p.F for p in predictions] +
                        [math.exp(math.log(F_range[0]) + i * (math.log(F_range[1]) - math.log(F_range[0])) / 2)
                         for i in range(3)]))
    starts = [sign * F for F in forces for sign in (1.0, -1.0)]
    omegas = sorted(p.omega for p in predictions)
    omega_ref = omegas[len(omegas) // 2] if omegas else math.sqrt(omega_range[0] * omega_range[1])
    num, den = num_den(G)
    cosimulation = engine.plant.kind == "co-simulation"
    seeds = [] if cosimulation else [(p.F, p.omega) for p in predictions if not p.stable]
    found, outcomes = engine.true_cycles(num, den, params, starts, omega_ref, seeds)
    cycles = [TrueCycle(**dict(entry, trace=trace_arrays(entry["trace"]))) for entry in found]
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
    text = (f"first forces +-{forces[0]:.3g} to {forces[-1]:.3g} N ({len(forces)} values) from the plant's "
            f"start values, each run {SETTLE} periods of {2 * math.pi / omega_ref:.4g} s before its swing is read")
    if cosimulation:
        text += ("; the loop co-simulated (the output held over each step, the controller exact) and refined "
                 "from 32 steps per period, extrapolated: stable cycles only (unstable ones are out of reach of "
                 "a stepped FMU)")
    elif seeds:
        text += (f"; Newton from the harmonic balance at the DF's {len(seeds)} unstable prediction(s), where an "
                 "unstable cycle may be")
    coverage = search.Coverage(amplitudes=[forces[0], forces[-1]], count=len(forces), parts=["force"],
                               starts=len(starts), predictions=len(predictions), outcomes=counts,
                               horizon=20 * 2 * math.pi / omega_ref, max_returns=MAX_RETURNS,
                               complete=not any(o.startswith("failed") or o == "not settled" for o in outcomes),
                               starts_text=text,
                               stable_only=cosimulation)
    return search.CycleSearch(cycles, links, coverage, [])


def predictor(engine, F_range, omega_range, size=DF_MAP_SIZE):
    """``predict(G, params, precise=True)``: the DF's predictions (``Cycle``s) of a user's FMU (``engine``'s)
    with its parameters ``params`` under G, located on the FMU's DF map over ``F_range`` x ``omega_range``
    (``size`` points, on the engine's looser twin) and refined on the precise DF (``precise=False``: on the
    looser twin, as starts and seeds need no more). The map is computed once for each setting of the FMU's
    own parameters: over G's parameters alone, one map serves every value."""
    maps = {}

    def predict(G, params, precise=True):
        key = tuple(sorted(params.items()))
        if key not in maps:
            if len(maps) >= 4:  # a map over the FMU's parameters: each setting its own (a few kept)
                maps.clear()
            F_grid, omega_grid = np.geomspace(*F_range, size[0]), np.geomspace(*omega_range, size[1])
            maps[key] = DFMap(F_grid, omega_grid, df_map(engine.coarse(), params, F_grid, omega_grid))
        dfmap = maps[key]
        return balance(engine if precise else engine.coarse(), G, params, dfmap.F_grid, dfmap.omega_grid,
                       dfmap.N_grid).cycles

    return predict


def cells(engine, family, F_range, omega_range, size=DF_MAP_SIZE):
    """``classify_at(values, truth=True, df=True)``: the cell of ``family`` (a LoopFamily of a user's FMU) at
    ``values`` of its free parameters, shaped as :func:`dfwb.engine.hunting.classify` gives it (its linear
    verdict unknown: None), from the :func:`predictor`'s DF map."""
    predict = predictor(engine, F_range, omega_range, size)

    def classify_at(values, truth=True, df=True):
        # the truth alone (a margin's bisection) takes the predictions only for its starts and seeds: located
        # on the looser twin, they need no refining on the precise DF
        G, params = family.G(values), family.params(values)
        predictions = predict(G, params, precise=df)
        cell = {"linear": {"stable": None, "max_real_pole": None}}
        if truth:
            cell["truth"] = truth_cell(true_search(engine, G, params, predictions, None, F_range, omega_range))
        if df:
            cell["df"] = df_cell(predictions, True)
        return cell

    return classify_at


def classifier(engine, F_range, omega_range, size=DF_MAP_SIZE):
    """A ``classifier(scaled, ks)`` for :func:`~dfwb.engine.margin.margins` with a user's FMU (see :func:`cells`):
    the gain factor k is the scaled family's one value."""
    def make(scaled, ks):
        classify_at = cells(engine, scaled, F_range, omega_range, size)
        return lambda k, truth=True, df=True: classify_at({GAIN: k}, truth, df)

    return make
