"""Hunting maps: two parameters over a grid, each cell classified by the truth and by the DF, side by side.

Each cell is one setting of the two parameters (of the controller or of the plant), classified by
:func:`dfwb.engine.hunting.classify`: the exact loop's systematic search (hunts with a stable cycle, only
unstable cycles, diverges, no cycle in the range searched) and the describing function's verdict. Over
controller parameters one DF map of the plant serves every cell, computed once here and shipped to the
workers.

Cells run in worker processes or on Dask (:class:`dfwb.studies.executor.Executor`), are cached like DF
points (:mod:`dfwb.studies.cache`, keyed by everything a cell depends on) and, with an output folder, are
appended to ``cells.csv`` as they finish (checksummed rows, :mod:`dfwb.base.runlog`): a killed map resumes
with what it had. A row is resumed only under the key of the same map and code, and a cell read back (from
the folder or the cache) only with a classified cell's shape; a map under a Python function G is never
resumed (its key cannot name the function). A cell that fails (a parameter value the plant refuses) is
reported as such, never the map. The linear loop's stability boundary (the plant with its nonlinearity
removed) is computed on a fine grid, and the bifurcation curves are continued in the two parameters from
the folds found on the way (:func:`dfwb.engine.hunting.fold_curves`).
"""

import contextlib
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dfwb.base.defaults import DF_MAP_SIZE
from dfwb.base.errors import DfwbError, InputError
from dfwb.base.files import folder_lock, read_bytes, write_atomic
from dfwb.base.runlog import RunLog
from dfwb.engine.family import LoopFamily
from dfwb.engine.hunting import (
    MAP_AMPLITUDES,
    UNCOMPUTED,
    DFMap,
    classify,
    df_map_for,
    fold_curves,
    hunting,
    linear_map,
    valid_cell,
)
from dfwb.foreign.hunting import no_fmu_options
from dfwb.foreign.plant import fmu_plant, is_fmu_path
from dfwb.studies.cache import code_revision, digest, finite, fmu_revision, open_cache, solver_revision
from dfwb.studies.continuation import _text, check_parameter, check_somewhere
from dfwb.studies.executor import Executor, cached_engine
from dfwb.studies.responses import HuntingMapResponse

MAX_CELLS = 10_000  # a 100 x 100 map: tens of minutes on two cores
MAX_SIDE = 1_000
AXIS_LIMIT = 1e150  # the largest end of a map's axis (beyond, its figure's axis has no ticks to draw)
COLUMNS = ["x", "y", "truth", "truth_omega", "truth_amplitude", "df", "df_omega", "df_amplitude", "linear", "cell",
           "key"]  # key: the digest of everything the cell depends on but (x, y): a row of another map is not resumed
LINEAR_GRID = 80  # the linear loop's stability is drawn from this many points per side
CHUNK = 4  # cells per task


@dataclass(frozen=True)
class MapChunk:
    """Cells of one map for one worker: the plant, its FMU, G (text, coefficients or a function), the fixed
    values, the axes' names, the cells' (x, y), the shared DF map (or None) and the start amplitudes."""

    plant: str
    fmu: str
    G: object
    values: tuple
    axes: tuple
    cells: tuple
    dfmap: object
    amplitudes: int
    compensate: tuple = ()


def compute_cells(chunk, fmu_data=None):
    """(code revision, the classified cells) of a chunk; a cell that cannot be computed says why."""
    engine = cached_engine(chunk.plant, chunk.fmu, (), fmu_data)
    G = chunk.G if not isinstance(chunk.G, tuple) else (list(chunk.G[0]), list(chunk.G[1]))
    family = LoopFamily(chunk.plant, G, dict(chunk.values), free=chunk.axes, compensate=chunk.compensate)
    dfmap = None
    if chunk.dfmap is not None:
        F, omega, re, im = (np.array(part) for part in chunk.dfmap)
        dfmap = DFMap(F, omega, re + 1j * im)
    fmu_dir = Path(chunk.fmu).parent if fmu_data is None else None
    cells = []
    for x, y in chunk.cells:
        values = dict(zip(chunk.axes, (x, y)))
        try:
            problem = family.problem(values, fmu_dir)
            amplitudes = problem.scales.amplitudes(chunk.amplitudes)
            # a compensated loop: its DF where the compensated plant is a plant (computed per cell), and its cost
            equivalent = family.df_params(values) if family.compensation else None
            df_engine = family.df_engine(engine)
            if not getattr(df_engine, "mapped", True):  # a DF whose map costs minutes a cell (the dither's)
                equivalent = None
            cell = classify(problem, df_engine, dfmap, amplitudes,
                            df=not family.compensation or equivalent is not None, df_params=equivalent)
            if family.compensation:
                from dfwb.engine.cost import step_cost

                cell.update(cost=step_cost(problem).as_dict())
                if equivalent is None:
                    cell.update(df=dict(UNCOMPUTED))
        except DfwbError as error:
            cell = {"error": " ".join(str(error).split())}
        cells.append(dict(cell, x=x, y=y))
    return code_revision(), cells


def _axis(family, axis, label, plant):
    """(name, [values]) of an axis given as (name, start, stop, n)."""
    try:
        name, start, stop, count = axis
    except (TypeError, ValueError):
        raise InputError(f"{label} = {axis!r:.60}: give (NAME, START, STOP, N)") from None
    name, (lo, hi) = check_parameter(family, name, start, stop, plant)
    if max(abs(lo), abs(hi)) > AXIS_LIMIT:  # (a continuation follows such a range: its branch bounds its axis)
        raise InputError(f"{label} {name} = {float(start):g}:{float(stop):g}: each end within +-{AXIS_LIMIT:g} (the "
                         "map's cells span the range, and its figure draws it as an axis)")
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 2 <= count <= MAX_SIDE:
        raise InputError(f"{label} {name}: N = {count!r} cells: an integer from 2 to {MAX_SIDE}")
    values = np.linspace(float(start), float(stop), int(count))
    return name, [float(v) for v in values]


def _row(cell, key):
    row = {"x": repr(cell["x"]), "y": repr(cell["y"]), "cell": json.dumps(finite(cell), sort_keys=True), "key": key}
    if "error" in cell:
        return dict(row, truth="error", df="error", linear="")
    for source in ("truth", "df"):
        row[source] = cell[source]["class"]
        best = hunting(cell, source)
        row[f"{source}_omega"] = "" if best is None else repr(best["omega"])
        row[f"{source}_amplitude"] = "" if best is None else repr(best["amplitude_x"])
    stable = cell["linear"]["stable"]
    row["linear"] = "unknown" if stable is None else "stable" if stable else "unstable"
    return row


def run_map(plant, G, x, y, values=None, *, out_dir=None, jobs=None, dask=None, cache=False, fmu_dir=None,
            amplitudes=None, curves=True, resume=True, progress=None, own_folder=False, F_range=None,
            omega_range=None, n_F=DF_MAP_SIZE[0], n_omega=DF_MAP_SIZE[1], rtol=None, timeout=None, compensate=None):
    """The hunting map of ``plant`` under ``G`` over the axes ``x`` and ``y`` (each (NAME, START, STOP, N)).

    Returns a :class:`~dfwb.studies.responses.HuntingMapResponse`; see :func:`dfwb.hunting_map`.
    ``own_folder``: ``out_dir`` belongs to the caller (a scene's), so a different map there starts over
    instead of being refused. A user's FMU (an FMUPlant or an .fmu path) has its cells classified here
    (:func:`dfwb.foreign.hunting.cells`, the FMU's own workers), with ``F_range`` and
    ``omega_range`` (required) and ``n_F`` x ``n_omega`` for its DF map, ``rtol`` and ``timeout``; it has no
    linear loop nor bifurcation curves dfwb could draw. ``compensate``: compensators in the loop, whose
    parameters may be axes; each cell then has the truth and the loop's cost (:mod:`dfwb.engine.cost`), and the
    DF where the compensated plant is a plant (the feedforward of the velocity on the friction mass, per cell).
    """
    from dfwb.fmi.location import fmu_path

    if is_fmu_path(plant):
        plant = fmu_plant(plant)
    fixed = dict(values or {})
    names = [a[0] if isinstance(a, (tuple, list)) and a and isinstance(a[0], str) else None for a in (x, y)]
    for name in names:
        if name in fixed:
            raise InputError(f"{name} is an axis of the map: give its range, not a value for it")
    if names[0] is not None and names[0] == names[1]:
        raise InputError(f"x and y are both {names[0]}: a map needs two different parameters")
    family = LoopFamily(plant, G, fixed, free=tuple(n for n in names if isinstance(n, str)), compensate=compensate)
    compensate = family.compensation.kinds
    both = all(name in family.plant_names for name in names)  # their ranges may depend on each other (Fc <= Fs)
    (x_name, xs), (y_name, ys) = _axis(family, x, "x", not both), _axis(family, y, "y", not both)
    check_somewhere(family, [{x_name: a, y_name: b} for a in (xs[0], xs[-1]) for b in (ys[0], ys[-1])],
                    "every corner of the map")
    if len(xs) * len(ys) > MAX_CELLS:
        raise InputError(f"a map of {len(xs)} x {len(ys)} = {len(xs) * len(ys)} cells: at most {MAX_CELLS} "
                         "(fewer cells, or several maps)")
    count = MAP_AMPLITUDES if amplitudes is None else amplitudes
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= 100:
        raise InputError(f"amplitudes = {count!r}: the number of start amplitudes per cell, 1 to 100")
    spec = family.spec
    foreign = getattr(spec, "foreign", False)
    started = time.perf_counter()
    shared = None
    if foreign:
        classify_at, own = _foreign_cells(family, (x_name, y_name), F_range, omega_range, (n_F, n_omega), rtol,
                                          timeout)
        fmu, revision, engine, curves = spec.name, spec.info.digest, None, False
    else:
        no_fmu_options(F_range, omega_range, (n_F, n_omega), rtol, timeout)
        fmu = str(fmu_path(spec, fmu_dir))
        engine, revision, own = cached_engine(spec.name, fmu, ()), fmu_revision(fmu), None
    if not foreign and not compensate and x_name not in family.plant_names and y_name not in family.plant_names:
        # one DF map serves every cell
        try:
            corners = [family.problem({x_name: a, y_name: b}, fmu_dir) for a in (xs[0], xs[-1])
                       for b in (ys[0], ys[-1])]
        except DfwbError:  # G refuses a corner: each cell computes its own DF (and says what it refuses)
            corners = None
        if corners is not None:
            grid = df_map_for(corners, engine)
            shared = (grid.F_grid.tolist(), grid.omega_grid.tolist(), grid.N_grid.real.tolist(),
                      grid.N_grid.imag.tolist())
    if isinstance(G, str):
        G_key = chunk_G = G
    elif family.built:  # a Python function cannot go to another process, nor name a cache entry or a resumed
        G_key, chunk_G, jobs, dask, cache, resume = None, G, 1, None, False, False  # row: computed here, afresh
    else:
        from dfwb.engine.transfer import num_den

        G_key = num_den(family.G())
        chunk_G = tuple(map(tuple, G_key))
    merged = family.merged()
    common = {"plant": spec.name, "G": G_key, "values": merged, "amplitudes": count, "compensate": list(compensate),
              "dfmap": None if shared is None else digest([shared[0], shared[1]])}
    if own is not None:  # a user's FMU: what its cells depend on besides
        common["fmu"] = own
    definition = dict(common, x=[x_name, xs], y=[y_name, ys])
    base = dict(common, kind="map-cell", code=code_revision(), solvers=solver_revision(), fmu=revision,
                axes=[x_name, y_name])
    key = None if G_key is None else digest(base)
    store = open_cache(cache)
    cells = {}
    wanted = [(a, b) for b in ys for a in xs]
    points = set(wanted)
    with _folder(out_dir, definition, len(wanted), resume, own_folder) as (log, rows):
        for row in rows:
            cell = _read_cell(row["cell"]) if key is not None and row["key"] == key else None
            if cell is not None and (cell["x"], cell["y"]) in points:
                cells[(cell["x"], cell["y"])] = cell
        resumed = len(cells)
        hits = 0
        for point in wanted:
            if point in cells:
                continue
            value = store.get(dict(base, x=point[0], y=point[1]))
            if valid_cell(value) and (value["x"], value["y"]) == point:
                cells[point] = value
                hits += 1
                if log is not None:
                    log.append([_row(value, key)])
        pending = [point for point in wanted if point not in cells]
        chunks = [MapChunk(spec.name, fmu, chunk_G, tuple(sorted(merged.items())), (x_name, y_name),
                           tuple(pending[i:i + CHUNK]), shared, count, compensate)
                  for i in range(0, len(pending), CHUNK)]
        done = len(wanted) - len(pending)
        if progress:
            progress("cells", done, len(wanted))
        with contextlib.ExitStack() as stack:
            if foreign:  # here: the FMU's own worker processes share each cell's runs
                batches = ([_foreign_cell(classify_at, (x_name, y_name), point)] for point in pending)
            else:
                executor = stack.enter_context(Executor(jobs, dask))
                batches = (results for _chunk, results in executor.run(chunks, compute_cells))
            for results in batches:
                for cell in results:
                    point = (cell["x"], cell["y"])
                    cells[point] = cell
                    if "error" not in cell:
                        store.put(dict(base, x=point[0], y=point[1]), finite(cell))
                if log is not None:
                    log.append([_row(cell, key) for cell in results])
                done += len(results)
                if progress:
                    progress("cells", done, len(wanted))
    grid = [[cells[(a, b)] for a in xs] for b in ys]
    linear = {"x": [], "y": [], "growth": []} if foreign else \
        linear_map(family, x_name, (xs[0], xs[-1]), y_name, (ys[0], ys[-1]), LINEAR_GRID, fmu_dir)
    found_curves = []
    if curves and not compensate:  # (the curves' continuation has no compensated loop yet)
        found_curves = fold_curves(family, x_name, xs, y_name, ys, grid, fmu_dir, engine,
                                   progress=None if progress is None else (lambda d, t: progress("curves", d, t)))
    response = HuntingMapResponse(plant=spec.name, G=_text(G, family), x=x_name, xs=xs, y=y_name, ys=ys,
                                  values={k: v for k, v in merged.items() if k not in (x_name, y_name)},
                                  cells=grid, linear=linear, curves=found_curves, unit=spec.unit,
                                  counts={"cells": len(wanted), "computed": len(pending), "cached": hits,
                                          "resumed": resumed},
                                  seconds=time.perf_counter() - started, out_dir=out_dir)
    if out_dir is not None:
        response.write(Path(out_dir))
    return response


def _foreign_cells(family, axes, F_range, omega_range, size, rtol, timeout):
    """(classify_at, what the cells depend on) of a map of a user's FMU (over G's parameters one DF map of
    the FMU serves every cell; over its own, each cell computes its own)."""
    from dfwb.foreign.hunting import cells, study

    spec = family.spec
    engine, F, omega = study(spec, F_range, omega_range, size, rtol, timeout)
    own = {"sha256": spec.info.digest, "input": spec.input, "output": spec.output, "kind": spec.kind,
           "rtol": engine.rtol, "F_range": list(F), "omega_range": list(omega), "map": list(size)}
    return cells(engine, family, F, omega, size), own


def _foreign_cell(classify_at, axes, point):
    """The classified cell at ``point`` (x, y), or why it could not be (one failed cell, not the map)."""
    try:
        cell = classify_at(dict(zip(axes, point)))
    except DfwbError as error:
        cell = {"error": " ".join(str(error).split())}
    return dict(cell, x=point[0], y=point[1])


def _read_cell(text):
    """The cell a row's JSON holds if it has a classified cell's shape (:func:`valid_cell`), else None."""
    try:
        cell = json.loads(text)
    except (ValueError, RecursionError):
        return None
    return cell if valid_cell(cell) else None


class _folder:
    """The output folder of a map, locked while it runs: map.json (the definition) and the cells' log.

    A folder holding another map is refused unless ``resume`` is False or the folder is the caller's own
    (then its log starts over)."""

    def __init__(self, out_dir, definition, cells, resume, own):
        self.out_dir, self.definition, self.cells, self.resume, self.own = out_dir, definition, cells, resume, own
        self._lock = self._log = None

    def __enter__(self):
        """(the log to append to, the verified rows it held); (None, []) without a folder."""
        if self.out_dir is None:
            return None, []
        out = Path(self.out_dir)
        self._lock = folder_lock(out)
        self._lock.__enter__()
        stored = out / "map.json"
        log = RunLog(out / "cells.csv", COLUMNS, max_rows=self.cells)
        text = json.dumps(finite(self.definition), sort_keys=True)
        other = stored.exists() and _stored(stored) != json.loads(text)
        if self.resume and other and not self.own:
            self._lock.__exit__(None, None, None)
            raise InputError(f"{out} holds a different map (see {stored}): use another folder, or do not resume")
        if not self.resume or other:
            log.path.unlink(missing_ok=True)
        write_atomic(stored, text)
        rows = log.read()  # before it is opened to append to
        self._log = log
        log.__enter__()
        return log, rows

    def __exit__(self, *exc):
        if self._log is not None:
            self._log.__exit__(*exc)
        if self._lock is not None:
            self._lock.__exit__(*exc)


def _stored(path):
    try:
        return json.loads(read_bytes(path, 64 << 20, "map definition"))
    except (OSError, ValueError):
        return None

