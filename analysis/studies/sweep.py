"""Sweeps of describing functions over F x omega x plant parameters, in parallel, resumable.

Every finished point is appended to ``results.csv`` at once (flushed and
synced, with a checksum: :mod:`dfwb.base.runlog`), so an interrupted sweep loses
at most the points in flight; the next run with the same definition skips
what the CSV verifiably holds. One sweep at a time writes into a folder (a
second is refused), and a sweep has at most ``MAX_POINTS`` points, counted
before any is built. ``results.json`` (the complete list of records) is
rewritten atomically as the sweep goes and at its end. The definition
is kept in ``sweep.json``: resuming a different sweep into the same folder is
refused rather than mixed.

A point has one shape everywhere, its record (:meth:`dfwb.engine.describing.DFResult.as_dict`):
``results.json`` is the list of records, ``results.csv`` holds one flattened
record per row (:func:`dfwb.engine.describing.to_row`, units in the column
names) and :func:`run_sweep` returns the records (a :class:`Sweep`: a list
that also says what the run did, and draws its -1/N curves).

A point not in the folder is looked up in the content-addressed cache
(:mod:`dfwb.studies.cache`) before it is computed, and a computed one is put
there, under the key a scene's runner gives the same point
(:func:`dfwb.studies.points.df_key`): a scene over a sweep's points computes
none of them, and a sweep over a scene's points (one that records harmonics:
a sweep records X_0 .. X_10) neither. A cache that fails costs a warning; a
corrupt entry is rejected and its point computed again. A point a user's FMU
failed is cached no more than it is logged.
"""

import contextlib
import functools
import itertools
import json
import math
import numbers
import os
import time
from collections.abc import Mapping
from pathlib import Path

from dfwb.base.defaults import HARMONICS, SAMPLES_PER_PERIOD
from dfwb.base.errors import RunError, fmu_only
from dfwb.base.files import folder_lock, read_bytes, write_atomic
from dfwb.base.runlog import RunLog
from dfwb.engine.describing import COLUMNS, DRIVES, check_point, from_row, to_row
from dfwb.fmi.location import fmu_folder, fmu_path
from dfwb.fmus.piecewise import PlantError
from dfwb.plants import plant as find_plant
from dfwb.studies.cache import code_revision, fmu_revision, open_cache
from dfwb.studies.executor import Chunk, Executor, chunked
from dfwb.studies.points import MAX_PERIODS, df_key
from dfwb.studies.progress import Display

MAX_POINTS = 200_000  # DF points of one sweep or scene: hours of computing, a few hundred MB of results


def grid_size(*lengths):
    """The number of points of a grid, counted exactly (Python integers never overflow)."""
    return math.prod(int(n) for n in lengths)


def check_size(size, what="the sweep"):
    if size > MAX_POINTS:
        raise PlantError(f"{what} has {size} points: at most {MAX_POINTS} (split it)")


def _values(what, values):
    """A list (tuple, range, array) of values, not text and not a lazy iterator that may never end."""
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or not hasattr(values, "__getitem__"):
        raise PlantError(f"{what} = {values!r:.80} is not a list of numbers")
    return values


def _mapping(what, value):
    if value is not None and not isinstance(value, Mapping):
        raise PlantError(f"{what} = {value!r:.80} is not a mapping of parameter names to values (or None)")
    return dict(value or {})


def grid(Fs, omegas, params=None, grid_params=None):
    """The sweep's points, F the outer loop: [(F, omega, {name: value})]; refused beyond MAX_POINTS."""
    Fs, omegas, params = _values("F", Fs), _values("omega", omegas), _mapping("params", params)
    grid_params = _mapping("grid_params", grid_params)
    for name, values in grid_params.items():
        _values(f"grid_params[{name!r}]", values)
    names = sorted(grid_params)
    check_size(grid_size(len(Fs), len(omegas), *(len(grid_params[n]) for n in names)))
    combos = [dict(zip(names, values)) for values in itertools.product(*(grid_params[n] for n in names))]
    return [(F, omega, dict(params, **combo)) for F in Fs for combo in combos for omega in omegas]


def key(F, omega, params):
    return (repr(float(F)), repr(float(omega)), json.dumps(params, sort_keys=True))


def _key_of(record):
    return key(record["F"], record["omega"], record["params"])


class Sweep(list):
    """The records of a sweep's points, in the order of the points (a list), and what the run did.

    Attributes
    ----------
    plant : str
        The plant's name.
    out_dir : Path
        The sweep's folder.
    computed, cached, resumed : int
        Points computed by this call, found in the cache, and kept from the folder's ``results.csv``.
    rejected : int
        Cache entries and rows of ``results.csv`` that were damaged (or of another version): computed again.
    """

    def __init__(self, records=(), plant="", out_dir=".", computed=0, cached=0, resumed=0, rejected=0):
        super().__init__(records)
        self.plant, self.out_dir = plant, Path(out_dir)
        self.computed, self.cached, self.resumed, self.rejected = computed, cached, resumed, rejected

    def drawable(self):
        """The records that have a finite -1/N (not N = 0, nor a point a user's FMU failed)."""
        return [r for r in self if r["minus_inv_N_re"] is not None
                and math.isfinite(r["minus_inv_N_re"]) and math.isfinite(r["minus_inv_N_im"])]

    def plot(self, ax=None, marks=None):
        """The -1/N curves in the Nyquist plane: one per force and parameter set, omega along each.

        Drawn as a scene's ``kind = "nyquist"`` figure draws its series
        (:func:`dfwb.plotting.plots.nyquist_panel`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw; a new figure's axes when None.
        marks : list of float, optional
            Frequencies [rad/s] marked by a dot and their value on each curve; default (None): the sweep's
            lowest and highest, where each curve begins and ends; ``()``: none.

        Returns
        -------
        list of matplotlib.lines.Line2D
            One line per curve (none if no point has a finite -1/N).

        Examples
        --------
        >>> import tempfile, dfwb
        >>> with tempfile.TemporaryDirectory() as out:
        ...     records = dfwb.sweep("friction", dfwb.grid([10.0, 20.0], [0.5, 1.0, 2.0]), out, jobs=1,
        ...                           cache=False)
        >>> lines = records.plot()
        >>> len(lines), lines[0].get_label(), lines[0].axes.get_xlabel()
        (2, 'friction: F = 10 N', 'Re{-1/N} [N/m]')
        """
        from dfwb.plotting.plots import curves_of, nyquist_panel

        rows = self.drawable()
        if marks is None:
            omegas = [r["omega"] for r in rows]
            marks = sorted({min(omegas), max(omegas)}) if omegas else ()
        title = f"-1/N of {self.plant}" + (" (dots: omega in rad/s)" if marks else "")
        return nyquist_panel(ax, curves_of({self.plant: rows}, [self.plant]), title, marks)

    def figure(self, path, marks=None):
        """The -1/N curves (:meth:`plot`) written to ``path`` (a PNG) and beside it as SVG; returns the PNG's path.

        RunError if no point has a finite -1/N: there is nothing to draw."""
        if not self.drawable():
            raise RunError(f"no point of the sweep in {self.out_dir} has a finite -1/N (N = 0, or the point "
                           "failed, at every one): there are no curves to draw")
        from dfwb.plotting.plots import drawn

        return drawn(path, lambda ax: self.plot(ax, marks), figsize=(6.5, 5))


def run_sweep(plant, points, out_dir, jobs=None, drive="internal", samples_per_period=SAMPLES_PER_PERIOD,
              fmu_dir=None, progress=True, resume=True, rtol=None, timeout=None, cache=True):
    """Compute every point not yet in ``out_dir`` nor in the cache; return the records of all points in grid order.

    Parameters
    ----------
    plant : str
    points : list of (F, omega, params)
        Usually from :func:`grid`.
    out_dir : path
        Gets ``results.csv``, ``results.json`` and ``sweep.json``.
    jobs : int, optional
        Worker processes (default: all cores); 1 computes in this process.
    cache : bool or path
        True: ``$XDG_CACHE_HOME/dfwb`` (else ``~/.cache/dfwb``); a path; False: no cache. The points are
        shared with scenes (:func:`dfwb.studies.runner.run_scene`), a user's FMU's too. ``resume=False``
        starts the folder afresh but still takes the cached points (``cache=False`` computes them all).

    Returns
    -------
    Sweep
        One record per point (:meth:`dfwb.engine.describing.DFResult.as_dict`), a list; its ``computed``,
        ``cached``, ``resumed`` say where the points came from, :meth:`Sweep.plot` draws them.
    """
    spec = find_plant(plant)
    plant = spec.name
    foreign = getattr(spec, "foreign", False)
    check_size(len(_values("points", points)))
    checked = []
    for point in points:  # everything is checked before anything runs or is written
        if not (isinstance(point, (tuple, list)) and len(point) == 3):
            raise PlantError(f"point {point!r:.80} is not (F, omega, params)")
        F, omega = check_point(point[0], point[1])
        checked.append((F, omega, spec.checked(_mapping("params", point[2]))))
    points = checked
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral) or jobs < 1):
        raise PlantError(f"jobs = {jobs!r:.80} is not a number of workers: an integer >= 1, or None for all cores")
    if not isinstance(out_dir, (str, os.PathLike)):
        raise PlantError(f"out_dir = {out_dir!r:.80} is not a folder: give a path")
    fmu_dir = fmu_folder(fmu_dir)
    if drive not in DRIVES:
        raise PlantError(f"drive {drive!r:.80} is not allowed (allowed: {', '.join(DRIVES)})")
    if isinstance(samples_per_period, bool) or not isinstance(samples_per_period, numbers.Integral) \
            or samples_per_period < 4:
        raise PlantError(f"samples_per_period = {samples_per_period!r:.80} is out of range: an integer >= 4")
    samples_per_period = int(samples_per_period)
    out_dir = Path(out_dir)
    store = open_cache(cache)
    engine = None
    if foreign:  # checked before anything is written: the options, and the FMU's engine
        from dfwb.foreign.engine import engine_for

        engine = engine_for(spec, drive=drive, samples_per_period=samples_per_period, rtol=rtol, timeout=timeout)
        engine.jobs = jobs or engine.jobs
    else:
        fmu_only({"rtol": (rtol, None), "timeout": (timeout, None)}, "dfwb's own plants are computed exactly")
    definition = {"plant": plant, "drive": drive,
                  "samples_per_period": samples_per_period if drive == "input" else None,
                  "points": [[F, omega, params] for F, omega, params in points]}
    if foreign:  # the FMU's content, not its path, and how it is run
        definition.update(drive=spec.kind, fmu={"sha256": spec.info.digest, "input": spec.input,
                                                "output": spec.output, "rtol": engine.rtol})
    # the engine's settings, as a scene's with harmonics has them: the cache's keys are the same
    settings = (("drive", drive), ("harmonics", HARMONICS), ("max_periods", MAX_PERIODS),
                ("samples_per_period", samples_per_period))
    with folder_lock(out_dir):
        stored = out_dir / "sweep.json"
        log = RunLog(out_dir / "results.csv", COLUMNS, max_rows=len(points))
        if resume and stored.exists() and _definition(stored) != definition:
            raise PlantError(f"{out_dir} holds a different sweep (see {stored}); use another folder or --no-resume")
        if not resume:
            log.path.unlink(missing_ok=True)
        write_atomic(stored, json.dumps(definition, indent=1))

        wanted = {key(*p) for p in points}
        done = {}
        for r in log.read():
            try:
                record = from_row(r)
                k = _key_of(record)
            except (KeyError, TypeError, ValueError):
                continue
            if k in wanted:
                done[k] = record
        resumed = len(done)
        fmu = None if foreign else str(fmu_path(spec, fmu_dir))
        # cache_key(F, omega, params): the key a scene's runner gives the point, too
        if foreign:
            cache_key = functools.partial(df_key, spec, fmu=spec.info.digest, code=code_revision(),
                                          harmonics=engine.harmonics, max_periods=engine.max_periods, rtol=engine.rtol)
        else:
            cache_key = functools.partial(df_key, spec, fmu=fmu_revision(fmu), code=code_revision(), **dict(settings))
        pending, cached = [], []
        for p in points:
            k = key(*p)
            if k in done:
                continue
            record = _cached(store, cache_key(*p), spec.name, p[2])
            if record is None:
                pending.append(p)
            else:
                done[k] = record
                cached.append(record)
        jobs = max(1, min(jobs or os.cpu_count() or 1, len(pending) or 1))
        computed = 0
        with log, store.writing(), Display(progress, f"DF sweep of {plant} into {out_dir}") as display:
            task = display.add("DF points", len(points), len(points) - len(pending), len(cached))
            log.append([to_row(r) for r in cached])
            last_json = time.monotonic()
            with _computing(spec, engine, pending, jobs, settings, fmu) as batches:
                for results in batches:
                    log.append([to_row(r) for r in results if not r["note"].startswith("failed:")])
                    for r in results:  # a failed point is reported in results.json, and computed again on resume
                        done[_key_of(r)] = r
                        if _cacheable(r):  # the log first: a cache that fails never costs a point
                            store.put(cache_key(r["F"], r["omega"], r["params"]), r)
                    computed += len(results)
                    display.advance(task, len(results))
                    if time.monotonic() - last_json > 5.0:
                        _write_json(out_dir, points, done)
                        last_json = time.monotonic()
        return Sweep(_write_json(out_dir, points, done), plant, out_dir, computed=computed, cached=len(cached),
                     resumed=resumed, rejected=store.rejected + log.rejected)


def _cached(store, cache_key, plant, params):
    """The record of a point from the cache (with this sweep's plant name and parameters as given), or None.

    An entry that is no DF record (it cannot be written as a row of results.csv) counts as rejected."""
    value = store.get(cache_key)
    if value is None:
        return None
    try:
        record = dict(value, plant=plant, params=params)
        from_row(to_row(record))
    except (KeyError, TypeError, ValueError, AttributeError):
        store.rejected += 1
        return None
    return record


def _cacheable(record):
    """Whether a computed record goes into the cache: not a failed point, and every number finite."""
    numbers_ = [record["N_re"], record["N_im"], *record["harmonics"]]
    if record["N_error"] is not None:
        numbers_.append(record["N_error"])
    return not record["note"].startswith("failed:") and all(math.isfinite(x) for x in numbers_)


@contextlib.contextmanager
def _computing(spec, engine, pending, jobs, settings, fmu):
    """An iterator of lists of records of the pending points: dfwb's own plants on the executor's
    processes (``fmu``: the FMU file), a user's FMU on its engine's worker processes (``jobs`` points at once)."""
    if engine is not None:  # its workers are the process's, kept for the next call: nothing to close
        yield ([r.as_dict() for r in engine.batch(pending[start:start + engine.jobs])]
               for start in range(0, len(pending), engine.jobs))
        return
    with Executor(jobs) as executor:
        yield (results for _chunk, results in
               executor.run(Chunk(spec.name, fmu, settings, c) for c in chunked(pending, jobs)))


def _definition(path):
    """The definition stored in sweep.json, or None when it is not one (damaged, or not JSON)."""
    try:
        return json.loads(read_bytes(path, 256 << 20, "sweep definition"))
    except (OSError, ValueError):
        return None


def _write_json(out_dir, points, done):
    records = [done[key(*p)] for p in points if key(*p) in done]
    write_atomic(Path(out_dir) / "results.json", json.dumps(records, indent=1))
    return records
