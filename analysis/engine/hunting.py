"""Which controllers make a machine hunt: one parameter setting classified by the truth and by the DF.

The truth is the systematic search of the exact loop (:func:`dfwb.engine.cycles.find_cycles`): a setting
*hunts* when the search reaches a stable cycle; otherwise the loop *diverges* when runs leave every bound,
has *only unstable* cycles when the search found some but none attracts, and has *no cycle* in the range
covered when every run came to rest. The DF's verdict comes from its predictions (Loeb's stability): a
stable one, only unstable ones, or none; where the linear loop is unstable and the DF predicts no stable
cycle, large motions grow as the linear loop's do (*diverges*). One DF map of the plant serves every
controller (:func:`dfwb.engine.limit_cycles.balance`), so a map over controller parameters computes it once.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.errors import DfwbError
from dfwb.engine.scales import linear_poles, search_ranges

CLASSES = ("stable", "unstable", "diverges", "none", "incomplete")
LABELS = {"stable": "hunts (a stable cycle)", "unstable": "only unstable cycles", "diverges": "diverges",
          "none": "no cycle in the range searched", "incomplete": "not settled (the work budget ran out)"}
MAP_AMPLITUDES = 5  # start amplitudes per cell (1 per decade over the default span)
GRID = (24, 64)  # the shared DF map: forces x frequencies


@dataclass
class DFMap:
    """A plant's DF on a grid, shared by the controllers of a map (``F_grid`` [N], ``omega_grid`` [rad/s])."""

    F_grid: np.ndarray
    omega_grid: np.ndarray
    N_grid: np.ndarray


def df_map_for(problems, engine, size=GRID):
    """One DF map covering the derived ranges of several loops of the same plant (a map's corners)."""
    from dfwb.engine.limit_cycles import df_map

    ranges = [search_ranges(problem) for problem in problems]
    F = (min(r[0][0] for r in ranges), max(r[0][1] for r in ranges))
    omega = (min(r[1][0] for r in ranges), max(r[1][1] for r in ranges))
    F_grid, omega_grid = np.geomspace(*F, size[0]), np.geomspace(*omega, size[1])
    return DFMap(F_grid, omega_grid, df_map(engine, problems[0].params, F_grid, omega_grid))


def truth_class(search):
    """(class, cycles) of a :class:`~dfwb.engine.cycles.CycleSearch` (the classes of the module docstring)."""
    outcomes = search.coverage.outcomes
    if search.stable():
        kind = "stable"
    elif not search.coverage.complete:
        kind = "incomplete"
    elif outcomes.get("diverged"):
        kind = "diverges"
    elif search.cycles:
        kind = "unstable"
    else:
        kind = "none"
    return kind, search.cycles


def df_class(predictions, linear_stable):
    """The DF's class: a stable prediction, only unstable ones, divergence (an unstable linear loop), none."""
    if any(p.stable for p in predictions):
        return "stable"
    if not linear_stable:
        return "diverges"
    return "unstable" if predictions else "none"


def classify(problem, engine=None, dfmap=None, amplitudes=None, truth=True, df=True):
    """One setting classified: a JSON-able dict with ``truth``, ``df`` and ``linear`` (see the module docstring).

    ``problem``: the loop at the setting; ``engine``: its DF engine; ``dfmap``: a shared :class:`DFMap` (else
    one is computed on the derived ranges); ``amplitudes``: the truth search's starts (default: MAP_AMPLITUDES
    over the loop's span).
    """
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.limit_cycles import balance, search

    poles = linear_poles(problem)
    stable = bool(poles) and all(p.real < 0.0 for p in poles)
    cell = {"linear": {"stable": stable, "max_real_pole": max((p.real for p in poles), default=-math.inf)}}
    if truth:
        found = find_cycles(problem, amplitudes=amplitudes or problem.scales.amplitudes(MAP_AMPLITUDES),
                            boundaries="unless-stable")
        kind, cycles = truth_class(found)
        cell["truth"] = {"class": kind, "cycles": [_cycle(c) for c in cycles],
                         "coverage": {"starts": found.coverage.starts, "outcomes": found.coverage.outcomes,
                                      "complete": found.coverage.complete}}
    if df:
        if dfmap is None:
            F, omega = search_ranges(problem)
            predictions = search(problem.spec.name, problem.G, problem.params, F, omega, engine=engine).cycles
        else:
            predictions = balance(engine, problem.G, problem.params, dfmap.F_grid, dfmap.omega_grid, dfmap.N_grid)
            predictions = predictions.cycles
        cell["df"] = {"class": df_class(predictions, stable),
                      "predictions": [{"F": p.F, "omega": p.omega, "amplitude_x": p.amplitude_x, "stable": p.stable}
                                      for p in predictions]}
    return cell


def _cycle(c):
    return {"omega": c.omega, "period": c.period, "amplitude_x": c.amplitude_x, "F": c.F, "stable": c.stable,
            "multipliers": c.multipliers, "events": c.signature}


def hunting(cell, source="truth"):
    """The stable cycle a cell's verdict names (the largest), or None: the one a map shows."""
    cycles = cell[source]["cycles" if source == "truth" else "predictions"]
    stable = [c for c in cycles if c["stable"]]
    return max(stable, key=lambda c: c["amplitude_x"]) if stable else None


TRACKED = ("fold", "nonsmooth-fold", "period-doubling", "torus")  # what changes hunting: followed across a map
BACK = 0.02  # a bifurcation is found again from this part of the range before it, on the side it was reached
TRACK_POINTS = 30  # continuation points per column, at most


@dataclass
class Curve:
    """A bifurcation continued in two parameters: its ``kind``, ``source`` and points (x, y)."""

    kind: str
    source: str
    points: list = field(default_factory=list)

    def as_dict(self):
        return {"kind": self.kind, "source": self.source, "points": [list(p) for p in self.points]}


def linear_map(family, x_name, x_range, y_name, y_range, n, fmu_dir=None):
    """The linear loop on an n x n grid: {"x", "y", "growth": rows of the largest real part of its poles
    [1/s] (< 0: stable; None where G or the plant refuses the values)}; its zero contour is the boundary."""
    xs, ys = np.linspace(*x_range, n), np.linspace(*y_range, n)
    rows = []
    for b in ys:
        row = []
        for a in xs:
            try:
                growth = family.linear_growth({x_name: float(a), y_name: float(b)})
                row.append(growth if math.isfinite(growth) else None)
            except DfwbError:  # a value the plant or G refuses: no verdict there
                row.append(None)
        rows.append(row)
    return {"x": xs.tolist(), "y": ys.tolist(), "growth": rows}


def fold_curves(family, x_name, xs, y_name, ys, grid=None, fmu_dir=None, engine=None, progress=None):
    """The bifurcations that change hunting (TRACKED), continued in (x, y) across a map: found by a
    continuation in y at the middle column, then located again column by column from where they were."""
    from dfwb.engine.continuation import continue_cycles, continue_predictions
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.limit_cycles import search

    bounds = (min(ys), max(ys))
    middle = xs[len(xs) // 2]
    column = family.at({x_name: middle})
    starts, predictions, F_range = [], [], None
    for value in (ys[0], ys[-1]):
        try:
            problem = column.problem({y_name: value}, fmu_dir)
        except DfwbError:
            continue
        found = find_cycles(problem, amplitudes=problem.scales.amplitudes(MAP_AMPLITUDES), boundaries=False)
        starts += [(value, c) for c in found.cycles]
        if engine is not None:
            F, omega = search_ranges(problem)
            F_range = F if F_range is None else (min(F[0], F_range[0]), max(F[1], F_range[1]))
            predictions += [(value, p) for p in search(problem.spec.name, problem.G, problem.params, F, omega,
                                                       engine=engine).cycles]
    seeds = continue_cycles(column, y_name, bounds, starts, fmu_dir)[1] if starts else []
    if predictions:
        F_range = (F_range[0], F_range[1] * 10.0)
        seeds += continue_predictions(column, y_name, bounds, predictions, engine, F_range)[1]
    seeds = [seed for seed in seeds if seed.kind in TRACKED and seed.state is not None]
    curves = []
    total = max(1, len(seeds) * (len(xs) - 1))
    done = 0
    for seed in seeds:
        curve = Curve(seed.kind, seed.source, [(middle, seed.parameter)])
        for direction in (1, -1):
            here = seed
            order = [x for x in xs if (x - middle) * direction > 0]
            for x in sorted(order, key=lambda v: abs(v - middle)):
                here = _relocate(family.at({x_name: x}), y_name, bounds, here, fmu_dir, engine, F_range)
                done += 1
                if progress:
                    progress(done, total)
                if here is None:
                    break
                curve.points.append((x, here.parameter))
        curve.points.sort()
        curves.append(curve)
    return curves


def _relocate(column, name, bounds, seed, fmu_dir, engine, F_range):
    """The bifurcation ``seed`` found again in the family ``column``: continued in ``name`` from a little before
    it (on the side it was reached from) until one of its kind is located; None where there is none."""
    from dfwb.engine import continuation as c

    span = bounds[1] - bounds[0]
    for back in (BACK, 2 * BACK, 8 * BACK):
        value = seed.parameter - seed.side * back * span
        if not bounds[0] <= value <= bounds[1]:
            continue
        y0 = np.array(seed.state[:-1] + [value], dtype=float)
        if seed.source == "truth":
            try:
                problem = column.problem({name: value}, fmu_dir)
            except DfwbError:
                continue
            fixed = problem.converge(problem.on_section(list(y0[:-1])), seed.returns, on_section=True)
            if fixed is None:
                continue
            swing = problem._swing(fixed[0], fixed[1])
            swing = [v for i, v in enumerate(swing) if i != problem.pivot]
            system = c.CycleSystem(column, name, span, seed.returns, swing, fixed[1], fmu_dir, problem.budget)
            y0 = np.array(problem.reduced(fixed[0]) + [value])
        else:
            system = c.PredictionSystem(column, name, span, engine, F_range)
            fixed_value = np.zeros(3)
            fixed_value[-1] = 1.0
            corrected = c._correct(system, y0, fixed_value, y0)
            if corrected is None:
                continue
            y0 = corrected[0]
        nodes, _reason = c.follow(system, y0, seed.side, bounds, TRACK_POINTS)
        for _i, bifurcation, _points in c.bifurcations(system, nodes, span):
            if bifurcation.kind == seed.kind:
                bifurcation.returns = seed.returns
                return bifurcation
        return None
    return None
