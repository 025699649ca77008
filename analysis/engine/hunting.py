"""Which controllers make a machine hunt: one parameter setting classified by the truth and by the DF.

The truth is the systematic search of the exact loop (:func:`dfwb.engine.cycles.find_cycles`): a setting
*hunts* when the search reaches a stable cycle (or, dithered, when runs hunt not locked to the dither:
:mod:`dfwb.engine.dither`); otherwise the loop *diverges* when runs leave every bound,
has *only unstable* cycles when the search found some but none attracts, and has *no cycle* in the range
covered when every run came to rest; it is *not settled* when the work budget ran out or a run failed. The
DF's verdict comes from its predictions (Loeb's stability): a stable one, only unstable ones, or none; where
the linear loop is unstable and the DF predicts no stable cycle, large motions grow as the linear loop's do
(*diverges*). One DF map of the plant serves every controller (:func:`dfwb.engine.limit_cycles.balance`),
so a map over controller parameters computes it once.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.errors import DfwbError
from dfwb.base.values import conforms, positive
from dfwb.engine.scales import linear_poles, search_ranges

CLASSES = ("stable", "hunts", "unstable", "diverges", "none", "incomplete", "uncomputed")
LABELS = {"stable": "hunts (a stable cycle)", "hunts": "hunts, not locked to the dither (within 8 of its periods)",
          "unstable": "only unstable cycles",
          "diverges": "diverges (from some starts)", "none": "no cycle in the range searched",
          "incomplete": "not settled (the work budget ran out, or runs failed)",
          "uncomputed": "no DF (the compensated plant is no plant, or its DF is not mapped: the dither's)"}
HUNTS = ("stable", "hunts")  # the classes that hunt: a stable cycle, or (dithered) hunting not locked to the dither
UNCOMPUTED = {"class": "uncomputed", "predictions": []}  # a compensated loop's DF verdict
MAP_AMPLITUDES = 5  # start amplitudes per cell (1 per decade over the default span)
GRID = (24, 64)  # the shared DF map: forces x frequencies


_CYCLE = {"omega": positive, "period": positive, "amplitude_x": positive, "F": positive, "stable": bool,
          "multipliers": [(float, None)], "events": [str]}
CELL = {"x": float, "y": float, "linear": {"stable": (bool, None), "max_real_pole": (float, None)},
        "truth": {"class": frozenset(CLASSES), "cycles": [_CYCLE],
                  "coverage": {"starts": int, "outcomes": {str: int}, "complete": bool}},
        "df": {"class": frozenset(CLASSES), "predictions": [{"F": positive, "omega": positive,
                                                             "amplitude_x": positive, "stable": bool}]}}
COST = {"step": positive, "horizon": positive, "standing_error": (float, None), "settling_time": (float, None),
        "overshoot": (float, None), "peak_force": (float, None), "rms_force": (float, None), "note": str,
        "residual_oscillation": (float, None)}
COMPENSATED_CELL = dict(CELL, cost=COST)  # a compensated loop's cell: its cost (the DF uncomputed)


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
    elif outcomes.get("hunting"):  # a dithered loop's runs that hunt, not locked (dfwb.engine.dither)
        kind = "hunts"
    elif not search.coverage.settled:
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


def classify(problem, engine=None, dfmap=None, amplitudes=None, truth=True, df=True, df_params=None):
    """One setting classified: a JSON-able dict with ``truth``, ``df`` and ``linear`` (see the module docstring).

    ``problem``: the loop at the setting; ``engine``: its DF engine; ``dfmap``: a shared :class:`DFMap` (else
    one is computed on the derived ranges); ``amplitudes``: the truth search's starts (default: MAP_AMPLITUDES
    over the loop's span); ``df_params``: the plant parameters of the DF (default: the problem's; a compensated
    loop's equivalent plant, :meth:`~dfwb.engine.compensators.Compensation.equivalent`).
    """
    from dfwb.engine import truth as exact
    from dfwb.engine.limit_cycles import balance, search

    poles = linear_poles(problem)
    stable = bool(poles) and all(p.real < 0.0 for p in poles)
    cell = {"linear": {"stable": stable, "max_real_pole": max((p.real for p in poles), default=-math.inf)}}
    if truth:
        found = exact.search(problem, amplitudes=amplitudes or problem.scales.amplitudes(MAP_AMPLITUDES),
                             boundaries="unless-stable")
        cell["truth"] = truth_cell(found)
    if df:
        params = problem.params if df_params is None else df_params
        if dfmap is None:
            F, omega = search_ranges(problem)
            predictions = search(problem.spec.name, problem.G, params, F, omega, engine=engine).cycles
        else:
            predictions = balance(engine, problem.G, params, dfmap.F_grid, dfmap.omega_grid, dfmap.N_grid)
            predictions = predictions.cycles
        cell["df"] = df_cell(predictions, stable)
    return cell


def truth_cell(found):
    """A cell's ``truth``: the class of a :class:`~dfwb.engine.cycles.CycleSearch`, its cycles, its coverage."""
    kind, cycles = truth_class(found)
    return {"class": kind, "cycles": [_cycle(c) for c in cycles],
            "coverage": {"starts": found.coverage.starts, "outcomes": found.coverage.outcomes,
                         "complete": found.coverage.complete}}


def df_cell(predictions, linear_stable):
    """A cell's ``df``: the DF's class and its predictions."""
    return {"class": df_class(predictions, linear_stable),
            "predictions": [{"F": p.F, "omega": p.omega, "amplitude_x": p.amplitude_x, "stable": p.stable}
                            for p in predictions]}


def _cycle(c):
    return {"omega": c.omega, "period": c.period, "amplitude_x": c.amplitude_x, "F": c.F, "stable": c.stable,
            "multipliers": c.multipliers, "events": c.signature}


def valid_cell(cell):
    """Whether ``cell`` (read back from a file or a cache) has the shape :func:`classify` gives, at a point
    (x, y): a crafted or damaged cell is recomputed, never drawn or counted."""
    return (conforms(cell, CELL) or conforms(cell, COMPENSATED_CELL)
            or conforms(cell, {"error": str, "x": float, "y": float}))


def hunting(cell, source="truth"):
    """The stable cycle a cell's verdict names (the largest), or None: the one a map shows."""
    cycles = cell[source]["cycles" if source == "truth" else "predictions"]
    stable = [c for c in cycles if c["stable"]]
    return max(stable, key=lambda c: c["amplitude_x"]) if stable else None


TRACKED = ("fold", "nonsmooth-fold", "period-doubling", "torus")  # what changes hunting: followed across a map
BACK = 0.02  # a bifurcation is found again from this part of the range before it, on the side it was reached
TRACK_POINTS = 30  # continuation points per column, at most
MAX_CURVES = 4  # bifurcation curves per source on one map
MAX_SEEDS = 8  # attempts to seed one per source
SEED_POINTS = 40  # continuation points across one cell, at most


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
    from dfwb.engine.scales import largest_real_parts

    xs, ys = np.linspace(*x_range, n), np.linspace(*y_range, n)
    polynomials = []
    for b in ys:
        for a in xs:
            try:
                polynomials.append(family.characteristic({x_name: float(a), y_name: float(b)}))
            except DfwbError:  # a value the plant or G refuses: no verdict there
                polynomials.append([math.inf])
    growth = [float(g) if math.isfinite(g) else None for g in largest_real_parts(polynomials)]
    return {"x": xs.tolist(), "y": ys.tolist(), "growth": [growth[j * n:(j + 1) * n] for j in range(n)]}


def fold_curves(family, x_name, xs, y_name, ys, grid, fmu_dir=None, engine=None, progress=None):
    """The bifurcations that change hunting (TRACKED), continued in (x, y) across a map.

    Each is seeded where a column's verdict (hunts or not, truth or DF) changes between two cells: the
    hunting cell's cycle (or prediction) is continued in y across the two, and the bifurcation between
    them located; then it is located again column by column, outwards from there, from where it was
    (:func:`_relocate`). A change of verdict that a curve already passes through seeds nothing; at most
    MAX_CURVES curves and MAX_SEEDS attempts per source: the work is bounded.
    """
    curves = []
    sources = ("truth", "df") if engine is not None else ("truth",)
    columns = sorted(range(len(xs)), key=lambda i: abs(i - (len(xs) - 1) / 2))  # from the middle outwards
    done, total = 0, max(1, 2 * MAX_CURVES * len(xs))
    for source in sources:
        tried = 0
        for i in columns:
            for j in range(len(ys) - 1):
                kinds = [_verdict(grid[j][i], source), _verdict(grid[j + 1][i], source)]
                if None in kinds or kinds[0] == kinds[1] or _covered(curves, source, xs[i], ys[j], ys[j + 1]):
                    continue
                if tried >= MAX_SEEDS or sum(c.source == source for c in curves) >= MAX_CURVES:
                    break
                tried += 1
                hunting = j if kinds[0] else j + 1
                column = family.at({x_name: xs[i]})
                seed, F_range = _seed(column, y_name, (ys[j], ys[j + 1]), ys[hunting], source, fmu_dir, engine)
                if seed is None:
                    continue
                bounds = (min(ys), max(ys))
                curve = Curve(seed.kind, source, [(xs[i], seed.parameter)])
                for direction in (1, -1):
                    here = seed
                    for k in range(i + direction, len(xs) if direction > 0 else -1, direction):
                        column = family.at({x_name: xs[k]})
                        found = _relocate(column, y_name, bounds, here, fmu_dir, engine, F_range)
                        if found is None:  # moved too far for a step from where it was: seed it in this column
                            found = _reseed(column, y_name, ys, [row[k] for row in grid], here, source, fmu_dir,
                                            engine)
                        done += 1
                        if progress:
                            progress(min(done, total), total)
                        if found is None:
                            break
                        here = found
                        curve.points.append((xs[k], here.parameter))
                curve.points.sort()
                curves.append(curve)
    return curves


def _reseed(column, name, ys, cells, previous, source, fmu_dir, engine):
    """The bifurcation of ``previous``'s kind seeded in a column at its change of verdict nearest to where
    ``previous`` was, or None."""
    changes = [j for j in range(len(ys) - 1) if None not in (_verdict(cells[j], source), _verdict(cells[j + 1], source))
               and _verdict(cells[j], source) != _verdict(cells[j + 1], source)]
    if not changes:
        return None
    j = min(changes, key=lambda j: abs(0.5 * (ys[j] + ys[j + 1]) - previous.parameter))
    hunting = j if _verdict(cells[j], source) else j + 1
    seed, _F = _seed(column, name, (ys[j], ys[j + 1]), ys[hunting], source, fmu_dir, engine)
    return seed if seed is not None and seed.kind == previous.kind else None


def _verdict(cell, source):
    """Whether a cell hunts by ``source`` (None: no verdict there)."""
    if source not in cell or cell[source]["class"] in ("incomplete", "error"):
        return None
    return cell[source]["class"] in HUNTS


def _covered(curves, source, x, y_lo, y_hi):
    """Whether a curve of ``source`` passes column x between y_lo and y_hi."""
    return any(c.source == source and any(px == x and min(y_lo, y_hi) <= py <= max(y_lo, y_hi) for px, py in c.points)
               for c in curves)


def _seed(column, name, bracket, hunting, source, fmu_dir, engine):
    """(the TRACKED bifurcation between the two values of ``bracket``, the DF's force range), or (None, None):
    the hunting cell's stable cycle or prediction at ``hunting`` continued across the bracket."""
    from dfwb.engine.continuation import continue_cycles, continue_predictions
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.limit_cycles import search

    lo, hi = sorted(bracket)
    try:
        problem = column.problem({name: hunting}, fmu_dir)
    except DfwbError:
        return None, None
    F_range = None
    if source == "truth":
        found = find_cycles(problem, amplitudes=problem.scales.amplitudes(MAP_AMPLITUDES), boundaries=False)
        starts = [(hunting, c) for c in found.stable()]
        found = continue_cycles(column, name, (lo, hi), starts, fmu_dir, SEED_POINTS)[1] if starts else []
    else:
        F, omega = search_ranges(problem)
        F_range = (F[0], F[1] * 10.0)
        starts = [(hunting, p) for p in search(problem.spec.name, problem.G, problem.params, F, omega,
                                               engine=engine).cycles if p.stable]
        found = continue_predictions(column, name, (lo, hi), starts, engine, F_range, SEED_POINTS)[1] if starts else []
    seeds = [b for b in found if b.kind in TRACKED and b.state is not None and lo <= b.parameter <= hi]
    return (min(seeds, key=lambda b: abs(b.parameter - hunting)) if seeds else None), F_range


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
            try:
                fixed = problem.converge(problem.on_section(list(y0[:-1])), seed.returns, on_section=True)
            except DfwbError:  # its work budget ran out: not found again here
                fixed = None
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
