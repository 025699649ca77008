"""``dfwb run SCENE.toml``: compute what a scene needs, and nothing else, then write its results.

Work is skipped at every level:

- each DF point is looked up first in the output folder (an interrupted run
  resumes), then in the content-addressed cache (:mod:`dfwb.studies.cache`); only the
  rest is computed, on local processes or a Dask cluster (:mod:`dfwb.studies.executor`);
- the engine integrates only X_0 and X_1 unless harmonics are asked for, steps
  one forcing period at a time (exact with the FMU's own excitation) and stops
  at the periodic steady state;
- time traces, limit cycles and figures exist only when the scene names them;
  traces and the judge's co-simulations are cached as well;
- a scene run before over the same points with the same code and FMUs (the same
  fingerprint) is copied whole: its outputs, figures included, are one cache
  entry, so such a re-run reads one file and imports no engine, numpy or plot.

Every computed point is appended to ``results.csv`` at once (flushed and
synced) and stored in the cache, so an interruption loses only the points in
flight. The final ``results.csv``, ``results.json``, ``traces/*.csv``, the
figures and ``summary.md`` are each written atomically.
"""

import base64
import contextlib
import csv
import dataclasses
import functools
import io
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from dfwb.base.defaults import HARMONICS
from dfwb.base.errors import InputError, RunError
from dfwb.base.files import ensure_folder, file_digest, folder_lock, inside, read_bytes, write_atomic
from dfwb.base.runlog import RunLog
from dfwb.base.text import parameters
from dfwb.engine.describing import COLUMNS, DFEngine, DFResult, from_row, to_row
from dfwb.fmi.location import fmu_path
from dfwb.studies.cache import (
    MAX_ENTRY,
    Cache,
    code_revision,
    digest,
    drawing_revision,
    finite,
    fmu_revision,
    open_cache,
    solver_revision,
)
from dfwb.studies.executor import Chunk, Executor, chunked
from dfwb.studies.progress import Display
from dfwb.studies.scene import PAPER_FIGURES, Point, Scene, load_scene, section_plant
from dfwb.studies.sweep import MAX_POINTS

MANIFEST = "manifest.json"
MAX_MANIFEST = 64 << 20  # bytes
RUN_COLUMNS = ["series", "key"] + COLUMNS
MAX_LOG_ROWS = 2 * MAX_POINTS  # the log of one scene: its points once, plus the rewrite's limit-cycle map rows
SUMMARY_ROWS = 40  # rows of each series shown in summary.md (all are in results.csv)
MAX_RECORD = MAX_ENTRY // 2  # bytes of outputs a run's cache record holds (base64 makes them a third larger)


@dataclass
class Outcome:
    """What a run did: counts, time, where the results are, and the paper's report sections."""

    out_dir: Path
    points: int = 0
    computed: int = 0
    cache_hits: int = 0
    resumed: int = 0
    rejected: int = 0
    figures_cached: int = 0  # figures copied from the cache instead of drawn
    up_to_date: bool = False  # the folder already held this scene's results: nothing was done
    copied: bool = False  # every output copied from the cache, as an earlier run of this same scene wrote it
    seconds: float = 0.0
    phases: dict = field(default_factory=dict)  # where the time went: seconds per phase of the run
    figures: list = field(default_factory=list)
    sections: list = field(default_factory=list)  # (title, png path, markdown) of paper figures
    failed: list = field(default_factory=list)  # why each point of a user's FMU that failed did (left out)


def phase_times(phases):
    """'points 1.2 s, figures 0.3 s, ...': where a run's time went, phases that took no time left out."""
    return ", ".join(f"{name} {seconds:.2f} s" for name, seconds in phases.items() if seconds >= 0.005) or "-"


class _Points:
    """The scene's DF points by key: resumed from the folder, found in the cache, or computed."""

    def __init__(self, run, settings):
        self.run, self.settings = run, settings  # settings: sorted (name, value) for DFEngine
        self.harmonics = dict(settings)["harmonics"]
        self._named = {}

    def named(self, plant, F, omega, params):
        """(digest, key) of a point, computed once per run."""
        point = (plant, F, omega, tuple(sorted(params.items())))
        if point not in self._named:
            key = self.key(plant, F, omega, params)
            self._named[point] = (digest(key), key)
        return self._named[point]

    def key(self, plant, F, omega, params, harmonics=None):
        """The point's cache key: :func:`dfwb.studies.points.df_key`, the one a sweep uses too."""
        from dfwb.studies.points import df_key

        return df_key(self.run.specs[plant], F, omega, params, fmu=self.run.revisions[plant], code=self.run.code,
                      rtol=self.run.scene.engine.rtol, **dict(self.settings, harmonics=harmonics or self.harmonics))

    def lookup(self, key):
        """A cached value, also from an entry with more harmonics (N is the same to the last bit)."""
        value = self.run.cache.get(key)
        if value is None and key["settings"]["harmonics"] < HARMONICS:
            value = self.run.cache.get(dict(key, settings=dict(key["settings"], harmonics=HARMONICS)))
            if value is not None:
                value = dict(value, harmonics=value["harmonics"][: key["settings"]["harmonics"] + 1])
        return value


class SceneRun:
    """One run of one scene; see :func:`run_scene`."""

    def __init__(self, scene, out_dir, executor, cache, fmu_dir, progress):
        self.scene, self.out, self.executor, self.cache = scene, Path(out_dir), executor, cache
        self.fmu_dir, self.progress = fmu_dir, progress
        self.code = code_revision()
        plants = {item.plant for group in (scene.series, scene.trace, scene.limit_cycle) for item in group}
        self.specs = {plant: scene.plant(plant) for plant in sorted(plants)}
        self.fmus = {plant: fmu_path(spec, fmu_dir) for plant, spec in self.specs.items()
                     if not getattr(spec, "foreign", False)}
        self.revisions = {plant: fmu_revision(path) for plant, path in self.fmus.items()}
        self.revisions.update({plant: spec.info.digest for plant, spec in self.specs.items() if plant not in self.fmus})
        self.values = {}  # digest -> as_dict() of every DF point known in this run
        self.outcome = Outcome(self.out)
        self.map_rows = []  # CSV rows of the limit cycles' DF maps
        self.log = RunLog(self.out / "results.csv", RUN_COLUMNS, max_rows=MAX_LOG_ROWS)
        self.written = []  # output files of this run (the manifest lists them)
        self._lock = contextlib.ExitStack()  # the folder's lock, from begin() to finish()
        self._rejected = cache.rejected  # a cache shared by several runs counts for all of them

    # -- DF points ----------------------------------------------------------------------
    def settings(self, harmonics):
        e = self.scene.engine
        return (("drive", e.drive), ("harmonics", harmonics), ("max_periods", e.max_periods),
                ("samples_per_period", e.samples_per_period))

    def compute_points(self, points, table, display, label):
        """Make ``self.values`` hold every (plant, F, omega, params) of ``points``; append new ones to the CSV."""
        keys = {}
        for plant, F, omega, params in points:
            name, key = table.named(plant, F, omega, params)
            keys.setdefault(name, (key, plant, F, omega, params))
        resumed = self.resumable
        pending, hits, old = [], 0, 0
        for name, (key, plant, F, omega, params) in keys.items():
            if name in self.values:
                continue
            if name in resumed:
                self.values[name] = resumed[name]
                old += 1
                continue
            value = table.lookup(key)
            if value is not None:
                self.values[name] = value
                hits += 1
            else:
                pending.append((name, key, plant, F, omega, params))
        self.outcome.cache_hits += hits
        self.outcome.resumed += old
        task = display.add(label, len(keys), len(keys) - len(pending), hits)
        foreign = [p for p in pending if p[2] not in self.fmus]
        pending = [p for p in pending if p[2] in self.fmus]
        by_chunk = {}
        chunks = []
        for plant in sorted({p[2] for p in pending}):
            mine = [p for p in pending if p[2] == plant]
            for part in chunked(mine, self.executor.jobs):
                chunk = Chunk(plant, str(self.fmus[plant]), table.settings, tuple((p[3], p[4], p[5]) for p in part))
                by_chunk[id(chunk)] = part
                chunks.append(chunk)
        with self.log:
            for chunk, results in self.executor.run(chunks):
                part = by_chunk[id(chunk)]
                for (name, key, plant, F, omega, params), value in zip(part, results):
                    if not all(math.isfinite(value[component]) for component in ("N_re", "N_im")):
                        raise RunError(f"{plant} at F = {F!r}, omega = {omega!r}, params = {params}: the engine "
                                           f"gave N = {value['N_re']} + {value['N_im']}j, not a finite number")
                self.log.append([dict(to_row(value), series="", key=p[0]) for p, value in zip(part, results)])
                for p, value in zip(part, results):  # the log first: a cache that fails never costs a point
                    self.cache.put(p[1], value)
                    self.values[p[0]] = value
                self.outcome.computed += len(results)
                display.advance(task, len(results))
            self._compute_foreign(foreign, table, display, task)
        return {name: entry[0] for name, entry in keys.items()}

    def fmu_engine(self, plant, harmonics):
        """The engine of a user's FMU (its worker processes are the process's, shared)."""
        from dfwb.foreign.engine import engine_for

        e = self.scene.engine
        return engine_for(self.specs[plant], harmonics=harmonics, max_periods=e.max_periods, rtol=e.rtol)

    def _compute_foreign(self, pending, table, display, task):
        """The points of users' FMUs, a batch on its engine's workers at a time (inside the log's ``with``).

        A point the FMU fails (a crash, a hang, NaN) is reported in ``outcome.failed`` and left out of the
        results, the log and the cache: the next run tries it again."""
        for plant in sorted({p[2] for p in pending}):
            mine = [p for p in pending if p[2] == plant]
            engine = self.fmu_engine(plant, table.harmonics)
            for part in chunked(mine, engine.jobs):
                values = [r.as_dict() for r in engine.batch([(p[3], p[4], p[5]) for p in part])]
                kept = [(p, v) for p, v in zip(part, values) if not v["note"].startswith("failed:")]
                self.outcome.failed += [v["note"][len("failed: "):] for v in values if v["note"].startswith("failed:")]
                self.log.append([dict(to_row(v), series="", key=p[0]) for p, v in kept])
                for p, value in kept:
                    self.cache.put(p[1], value)
                    self.values[p[0]] = value
                self.outcome.computed += len(kept)
                display.advance(task, len(part))

    @functools.cached_property
    def resumable(self):
        """{key: value} of the points an interrupted run left in results.csv, each row verified by its
        checksum (read once per run); a file that is not such a log is set aside (:mod:`dfwb.base.runlog`)."""
        values = {}
        for r in self.log.read():
            try:
                values[r["key"]] = from_row(r)
            except (KeyError, TypeError, ValueError):
                continue  # a row we wrote but cannot read back: computed again
        return values

    def series_rows(self, table):
        """({series name: [record]} in the scene's order, params as the scene gives them; their CSV rows)."""
        data = {s.name: [] for s in self.scene.series}
        csv_rows = []
        for p in self.scene.points():
            params = self.specs[p.plant].checked(p.params)
            name = table.named(p.plant, p.F, p.omega, params)[0]
            if name not in self.values:  # a point a user's FMU failed (outcome.failed says why)
                continue
            value = dict(self.values[name], params=params)
            csv_rows.append(dict(to_row(value), series=p.series, key=name))
            data[p.series].append(value)
        return data, csv_rows

    # -- traces ---------------------------------------------------------------------------
    def traces(self, display):
        """{name: {output: [values]}} of the scene's traces: from the cache, else simulated (and cached)."""
        out, missing = {}, []
        for trace in self.scene.trace:  # the cache first: the display counts what is left to simulate
            spec = self.specs[trace.plant]
            params = spec.checked(trace.params)
            own = getattr(spec, "foreign", False)
            key = {"kind": "trace", "model": "foreign" if own else spec.fmu_name, "fmu": self.revisions[trace.plant],
                   "code": self.code, "params": spec.complete(params), "F": trace.F,
                   "omega": trace.omega, "start": trace.start, "stop": trace.stop, "step": trace.step,
                   "outputs": trace.outputs}
            stored = self.cache.get(key)
            out[trace.name] = _trace_columns(stored, trace.outputs)
            self.cache.rejected += stored is not None and out[trace.name] is None
            if out[trace.name] is None:
                missing.append((trace, params, key))
            else:
                self.outcome.cache_hits += 1
        found = len(self.scene.trace) - len(missing)
        task = display.add("traces", len(self.scene.trace), found, found)
        simulated = {}  # digest -> value of the traces simulated here: a second trace of the same key reuses it
        for trace, params, key in missing:
            name = digest(key)
            value = simulated.get(name)
            if value is None:
                import numpy as np  # only for a trace to compute

                if trace.plant in self.fmus:
                    from dfwb.fmi.simulation import simulate  # fmpy: likewise

                    result = simulate(self.fmus[trace.plant], trace.stop, trace.step,
                                      dict(params, F=trace.F, omega=trace.omega), trace.outputs)
                else:  # a user's FMU, on its worker (a failure: the run's, said in one line)
                    result = {k: np.array(v) for k, v in self.fmu_engine(trace.plant, 1).trace(
                        trace.F, trace.omega, params, trace.stop, trace.step, trace.outputs).items()}
                keep = np.asarray(result["time"]) >= trace.start - 1e-9 * trace.step
                value = {name: result[name][keep].astype(float).tolist() for name in ["time"] + trace.outputs}
                self.cache.put(key, value)
                simulated[name] = value
            else:
                self.outcome.cache_hits += 1
            out[trace.name] = value
            display.advance(task, 1)
        return out

    # -- limit cycles ---------------------------------------------------------------------
    def limit_cycles(self, display):
        """{name: LimitCycleResponse} of the scene's [[limit_cycle]]s: their DF maps computed as the scene's points
        (in parallel, cached), the rest by :func:`dfwb.studies.limit_cycles.analyse` with the run's cache."""
        if not self.scene.limit_cycle:
            return {}
        import numpy as np

        from dfwb.engine.scales import search_ranges
        from dfwb.studies.limit_cycles import analyse

        results = {}
        table = _Points(self, self.settings(HARMONICS))
        for lc in self.scene.limit_cycle:
            if lc.compensate:  # judged by its exact loop alone: no DF map to compute (analyse refuses what needs one)
                results[lc.name] = analyse(lc.plant, lc.controller(), lc.params, F_range=lc.F_range,
                                           omega_range=lc.omega_range, n_F=lc.n_F, n_omega=lc.n_omega,
                                           exact=lc.exact, verify=lc.verify, samples_per_period=lc.samples_per_period,
                                           fmu_dir=self.fmu_dir, cache=self.cache, progress=_staged(display, lc.name),
                                           compensate=lc.compensate)
                continue
            if lc.plant not in self.fmus:  # a user's FMU: its map on its engine's workers, not cached yet
                results[lc.name] = analyse(self.specs[lc.plant], lc.controller(), lc.params, F_range=lc.F_range,
                                           omega_range=lc.omega_range, n_F=lc.n_F, n_omega=lc.n_omega,
                                           exact=lc.exact, engine=self.fmu_engine(lc.plant, HARMONICS),
                                           progress=_staged(display, lc.name))
                continue
            family = lc.family()
            problem = family.problem(fmu_dir=self.fmu_dir)
            F_range, omega_range = search_ranges(problem, lc.F_range, lc.omega_range)
            params = family.params()
            n_F, n_omega = lc.map_size()
            grid = [(lc.plant, F, w, params) for F in np.geomspace(*F_range, n_F)
                    for w in np.geomspace(*omega_range, n_omega)]
            keys = self.compute_points(grid, table, display, f"{lc.name}: DF map")
            self.map_rows += [dict(to_row(self.values[name]), series=lc.name, key=name) for name in keys]
            engine = _CachedEngine(self, table, lc.plant)
            progress = _staged(display, lc.name, skip="DF map")  # the map's points are shown above
            hits = self.cache.hits
            results[lc.name] = analyse(lc.plant, lc.controller(), lc.params, F_range=F_range,
                                       omega_range=omega_range, n_F=n_F, n_omega=n_omega, exact=lc.exact,
                                       verify=lc.verify, samples_per_period=lc.samples_per_period,
                                       fmu_dir=self.fmu_dir, engine=engine, cache=self.cache, progress=progress)
            self.outcome.computed += engine.computed
            self.outcome.cache_hits += engine.hits + (self.cache.hits - hits - engine.hits)
        return results

    # -- everything -------------------------------------------------------------------------
    def fingerprint(self, table, points):
        """A digest of everything the outputs depend on: the scene, every point's key, the code."""
        keys = [table.named(plant, F, omega, params)[0] for plant, F, omega, params in points]
        return digest({"scene": dataclasses.asdict(self.scene), "points": keys, "fmus": self.revisions,
                       "code": self.code, "drawing": drawing_revision()})

    def up_to_date(self, fingerprint):
        """The stored outcome if the folder holds exactly this run's outputs (each file's SHA-256), else None.

        Every name in the manifest must be a file inside the folder: one that is not marks it as damaged."""
        try:
            manifest = json.loads(read_bytes(self.out / MANIFEST, MAX_MANIFEST, "manifest"))
            if manifest["fingerprint"] != fingerprint:
                return None
            stored = manifest["outcome"]
            if any(file_digest(inside(self.out, name)) != sha for name, sha in manifest["files"].items()):
                return None
            return Outcome(self.out, points=stored["points"], up_to_date=True,
                           figures=[inside(self.out, name) for name in stored["figures"]],
                           sections=[(title, inside(self.out, png), text) for title, png, text in stored["sections"]])
        except (OSError, ValueError, KeyError, TypeError, AttributeError):  # UnsafePath is a ValueError
            return None

    def write(self, name, content):
        """Write an output file atomically and remember it for the manifest."""
        path = self.out / name
        write_atomic(path, content)
        self.written.append(path)
        return path

    def write_manifest(self, fingerprint):
        o = self.outcome
        files = {path.relative_to(self.out).as_posix(): file_digest(path) for path in sorted(set(self.written))}
        document = {"fingerprint": fingerprint, "files": files,
                    "outcome": {"points": o.points, "figures": [p.name for p in o.figures],
                                "sections": [(title, png.name, text) for title, png, text in o.sections]}}
        write_atomic(self.out / MANIFEST, json.dumps(document, indent=1))

    def run(self, drawing=None):
        """Run the scene; return its :class:`Outcome` (:meth:`begin`, then :meth:`finish`)."""
        self.begin(drawing)
        return self.finish()

    def begin(self, drawing=None):
        """Compute what the scene needs and write its results; its figures are drawn here, or handed to
        ``drawing`` (a :class:`~dfwb.studies.drawing.Drawing`), which :meth:`finish` waits for. The folder
        stays locked until then (:meth:`close`)."""
        started = self.started = self._mark = time.perf_counter()
        scene = self.scene
        self._done = None
        table = _Points(self, self.settings(HARMONICS if scene.needs_harmonics else 1))
        points = [(p.plant, p.F, p.omega, self.specs[p.plant].checked(p.params)) for p in scene.points()]
        fingerprint = self.fingerprint(table, points)
        done = self.up_to_date(fingerprint)
        if done is not None:
            done.seconds = time.perf_counter() - started
            self._done = done
            return self
        if self.out.exists() and not self.out.is_dir():
            raise RunError(f"--out {self.out} is a file, not a folder")
        self._lock.enter_context(folder_lock(self.out))  # one run at a time writes here
        try:
            (self.out / MANIFEST).unlink(missing_ok=True)  # from here on the folder is being changed
            if self.copy(fingerprint):
                self.write_manifest(fingerprint)
                self._done = self.outcome
                return self
            if drawing is not None and scene.figure:
                drawing.prepare()  # its processes get ready while this scene computes
            self.lap("start")  # the scene, the cache, the FMUs' revisions, the fingerprint
            with self.cache.writing(), Display(self.progress, scene.title) as display:
                self.compute_points(points, table, display, "DF points")
                self.lap("points")
                traces = self.traces(display)
                self.lap("traces")
                cycles = self.limit_cycles(display)
                self.lap("limit cycles")
                studies = {}  # a scene without them loads neither (nor numpy)
                if scene.continuation:
                    studies.update(self.continuations(display))
                    self.lap("continuations")
                if scene.map:
                    studies.update(self.maps(display))
                    self.lap("maps")
            data, csv_rows = self.series_rows(table)
            self.outcome.points = len(self.values)
            self.write_results(data, csv_rows, traces, cycles, studies)
            self.lap("results")
            self._drawn = self.draw(data, traces, dict(cycles, **studies), drawing)
            self.lap("figures")  # drawn here, or handed to the drawing processes
            self._rest = (fingerprint, data, cycles, studies)
            self._ended = time.perf_counter()
        except BaseException:
            self.close()
            raise
        return self

    def finish(self):
        """Wait for the figures, write the summary, the manifest and the run's cache record; unlock."""
        try:
            if self._done is not None:
                return self._done
            fingerprint, data, cycles, studies = self._rest
            self._mark = time.perf_counter()  # the time since begin() went to other work (other scenes')
            elsewhere = self._mark - self._ended
            for pngs, sections in self._drawn:
                sections = sections.result() if hasattr(sections, "result") else sections
                self.outcome.sections += [(title, self.out / Path(png).name, text) for title, png, text in sections]
                self.outcome.figures += [self.out / png for png in pngs]
            self.lap("figures")  # drawing, or waiting for the drawing processes
            self.outcome.rejected = self.cache.rejected - self._rejected + self.log.rejected
            self.outcome.seconds = time.perf_counter() - self.started - elsewhere
            body = self.summary_body(data, cycles, studies)
            self.write_summary(body)
            if not self.outcome.failed:  # with points missing, the next run is not up to date: it tries them again
                self.write_manifest(fingerprint)
                self.store(fingerprint, body)
            return self.outcome
        finally:
            self.close()

    def close(self):
        """Unlock the folder (a run that failed, or was begun and is given up)."""
        self._lock.close()

    def lap(self, name):
        """Add the time since the last lap to the phase ``name``."""
        now = time.perf_counter()
        self.outcome.phases[name] = self.outcome.phases.get(name, 0.0) + now - self._mark
        self._mark = now

    # -- a whole run from the cache -----------------------------------------------------------------
    def output_names(self):
        """The files of a run of this scene but its summary, as paths relative to the folder; None for a scene
        that is never copied whole: one with hunting maps (they keep their own folders and resume from them)
        or with the limit cycles of a user's FMU (their points are not cached: one that failed is tried again)."""
        if self.scene.map or any(lc.plant not in self.fmus for lc in self.scene.limit_cycle):
            return None
        names = ["results.csv", "results.json"] + [f"traces/{t.name}.csv" for t in self.scene.trace]
        return names + [name for figure in self.scene.figure for name in figure.files()]

    def store(self, fingerprint, body):
        """Put this run's outputs in the cache as one record, for a run of the same fingerprint elsewhere."""
        names = self.output_names()
        if names is None or not isinstance(self.cache, Cache):
            return
        try:  # what this run wrote: a file replaced by a link meanwhile is not followed
            files = {name: read_bytes(self.out / name, MAX_RECORD, "run's output", follow=False) for name in names}
        except OSError:
            return  # the points are cached one by one all the same
        if sum(map(len, files.values())) > MAX_RECORD:
            return
        o = self.outcome
        self.cache.put({"kind": "run", "run": fingerprint},
                       {"files": {name: base64.b64encode(data).decode() for name, data in files.items()},
                        "summary": body, "points": o.points, "figures": [p.name for p in o.figures],
                        "sections": [[title, png.name, text] for title, png, text in o.sections]})

    def copy(self, fingerprint):
        """Write the outputs of an earlier run of this fingerprint from the cache; False if there is none.

        A record that does not name exactly this scene's outputs, or is not shaped as :meth:`store` writes
        it, is damaged: counted as rejected, and the scene is run."""
        names = self.output_names()
        if names is None:
            return False
        stored = self.cache.get({"kind": "run", "run": fingerprint})
        if stored is None:
            return False
        try:
            pngs = [name for name in names if name.endswith(".png")]
            if not (isinstance(stored["files"], dict) and sorted(stored["files"]) == sorted(names)
                    and isinstance(stored["figures"], list) and all(png in pngs for png in stored["figures"])
                    and isinstance(stored["summary"], list) and all(isinstance(line, str) for line in stored["summary"])
                    and isinstance(stored["sections"], list)
                    and all(isinstance(section, list) and len(section) == 3 and section[1] in pngs
                            and isinstance(section[0], str) and isinstance(section[2], str)
                            for section in stored["sections"])
                    and type(stored["points"]) is int and stored["points"] >= 0):
                raise ValueError("not this scene's record")
            files = {name: base64.b64decode(stored["files"][name], validate=True) for name in names}
        except (KeyError, TypeError, ValueError, AttributeError):  # binascii.Error is a ValueError
            self.cache.rejected += 1
            self.outcome.rejected = self.cache.rejected - self._rejected
            return False
        for name, data in files.items():
            ensure_folder((self.out / name).parent)
            self.write(name, data)
        o = self.outcome
        o.copied, o.points, o.cache_hits, o.figures_cached = True, stored["points"], stored["points"], len(pngs)
        o.figures = [self.out / name for name in stored["figures"]]
        o.sections = [(title, self.out / png, text) for title, png, text in stored["sections"]]
        o.seconds = time.perf_counter() - self.started
        self.write_summary(stored["summary"])
        return True

    # -- continuations and maps ----------------------------------------------------------------------
    def continuations(self, display):
        """{name: ContinuationResponse} of the scene's [[continuation]]s, cached whole."""
        from dfwb.studies.continuation import follow

        results = {}
        for c in self.scene.continuation:
            spec, own = self._study_plant(c)
            G = c.controller()
            key = {"kind": "continuation", "code": self.code, "solvers": solver_revision(),
                   "fmu": fmu_revision(fmu_path(spec, self.fmu_dir)) if not own else dict(own, sha256=spec.info.digest),
                   "plant": c.plant, "G": G,  # an expression, or (num, den)
                   "params": c.params, "parameter": c.parameter, "start": c.start, "stop": c.stop,
                   "sources": c.sources, "max_points": c.max_points, "samples": c.samples if own else None,
                   "compensate": c.compensate}
            task = display.add(f"{c.name}: continuation", 1, 0, 0)
            response = _cached_continuation(self.cache.get(key))
            if response is None:
                response = follow(spec, G, c.parameter, c.start, c.stop, c.params, sources=tuple(c.sources),
                                  max_points=c.max_points, fmu_dir=self.fmu_dir, compensate=c.compensate,
                                  **(dict(own, samples=c.samples) if own else {}))
                self.cache.put(key, finite(response.as_dict()))
            else:
                self.outcome.cache_hits += 1
            display.advance(task, 1)
            results[c.name] = response
        return results

    def maps(self, display):
        """{name: HuntingMapResponse} of the scene's [[map]]s, each in its folder ``map_<name>`` (resumed)."""
        from dfwb.studies.hunting import run_map

        results = {}
        for m in self.scene.map:
            progress = _staged(display, m.name)
            folder = self.out / f"map_{m.name}"
            spec, own = self._study_plant(m)
            results[m.name] = run_map(spec, m.controller(), *m.axes(), m.params, out_dir=folder, own_folder=True,
                                      jobs=self.executor.jobs, dask=self.executor.dask, cache=self.cache,
                                      fmu_dir=self.fmu_dir, amplitudes=m.amplitudes, curves=m.curves,
                                      progress=progress, compensate=m.compensate, **own)
            self.written += [path for path in folder.iterdir()  # (its lock file is no output)
                             if path.is_file() and not path.name.startswith(".")]
        return results

    def _study_plant(self, section):
        """(the plant of a [[continuation]] or [[map]], the keywords of a user's FMU's DF map and driver)."""
        spec = section_plant(section)
        if not getattr(spec, "foreign", False):
            return spec, {}
        return spec, {"F_range": tuple(section.F_range), "omega_range": tuple(section.omega_range),
                      "n_F": section.map_size()[0], "n_omega": section.map_size()[1], "rtol": self.scene.engine.rtol}

    def write_results(self, data, csv_rows, traces, cycles, studies=None):
        self.write("results.csv", self.log.text(csv_rows + self.map_rows))
        if traces:
            ensure_folder(self.out / "traces")
        for name, columns in traces.items():
            buffer = io.StringIO()
            writer = csv.writer(buffer, lineterminator="\n")
            writer.writerow(list(columns))
            writer.writerows(zip(*(map(repr, values) for values in columns.values())))
            self.write(f"traces/{name}.csv", buffer.getvalue())
        document = {"title": self.scene.title, "series": data,
                    "traces": {name: f"traces/{name}.csv" for name in traces},
                    "limit_cycles": {name: finite(r.as_dict()) for name, r in cycles.items()},
                    "continuations": {name: finite(r.as_dict()) for name, r in (studies or {}).items()
                                      if name in {c.name for c in self.scene.continuation}},
                    "maps": {name: {"folder": f"map_{name}", "cells": "cells.json", "summary": r.summary()}
                             for name, r in (studies or {}).items() if name in {m.name for m in self.scene.map}}}
        self.write("results.json", json.dumps(document))

    def draw(self, data, traces, cycles, drawing=None):
        """[(PNG names, sections)] of the scene's figures, drawn here, or handed to ``drawing`` (then the
        sections are a Future): each figure written as PNG and SVG."""
        drawn = []
        for figure in self.scene.figure:
            pngs = figure.pngs()
            job = (self.out, self.scene, figure, pngs, data, traces, cycles)
            drawn.append((pngs, draw_figure(*job) if drawing is None else drawing.submit(draw_figure, *job)))
            self.written += [self.out / name for name in figure.files()]
        return drawn

    def counts(self):
        """The summary's line saying where the results came from and how long the run took."""
        o = self.outcome
        cache = f"Cache: {self.cache.root or 'off'}."
        if o.copied:
            return (f"{o.points} DF points; every output copied from the cache, as an earlier run of this same "
                    f"scene (the same points, code and FMUs) wrote it; {o.seconds:.2f} s. {cache}")
        # every DF point is computed, resumed or a cache hit; cache_hits also counts traces and judge runs
        df_hits = o.points - o.computed - o.resumed
        others = o.cache_hits - df_hits
        return (f"{o.points} DF points: {o.computed} computed on {self.executor.name}, {df_hits} from the "
                f"cache, {o.resumed} resumed from this folder"
                + (f"; {others} time trace(s) and closed-loop run(s) from the cache" if others else "")
                + (f", {o.rejected} cache entries rejected (corrupt or another version) and recomputed"
                   if o.rejected else "")
                + f"; {o.seconds:.2f} s ({phase_times(o.phases)}). {cache}")

    def write_summary(self, body):
        """summary.md: the scene's title and description, :meth:`counts`, then ``body`` (its lines)."""
        scene = self.scene
        lines = [f"# {scene.title}", ""] + ([scene.description.strip(), ""] if scene.description.strip() else [])
        self.write("summary.md", "\n".join(lines + [self.counts(), ""] + body) + "\n")

    def summary_body(self, data, cycles, studies=None):
        """The lines of summary.md after its counts: the outputs, the figures, each series' points (a
        sample), the limit cycles and the studies."""
        o, scene = self.outcome, self.scene
        lines = ["Results: `results.csv` (one row per point) and `results.json`"
                 + (", time traces in `traces/`." if scene.trace else "."), ""]
        for title, png, text in o.sections:
            lines += [f"## {title}", "", f"![{title}]({png.name})", "", text, ""]
        shown = {png.name for _, png, _ in o.sections}
        lines += [f"![{path.stem}]({path.name})" for path in o.figures if path.name not in shown]
        for name, rows in data.items():
            lines += ["", f"## Series {name}", "", "| F [N] | params | w [rad/s] | N | -1/N | periodic | note |",
                      "|---|---|---|---|---|---|---|"]
            step = max(1, math.ceil(len(rows) / SUMMARY_ROWS))
            for r in rows[::step]:
                N = complex(r["N_re"], r["N_im"])
                inverse = ("-" if r["minus_inv_N_re"] is None
                           else f"{complex(r['minus_inv_N_re'], r['minus_inv_N_im']):.6g}")
                lines.append(f"| {r['F']:g} | {parameters(r['params'])} | {r['omega']:.6g} | "
                             f"{N:.6g} | {inverse} | {r['periodic']} | {r['note']} |")
            if step > 1:
                lines.append(f"\nEvery {step}th of {len(rows)} points; all are in `results.csv`.")
        for name, r in cycles.items():
            lines += ["", f"## Limit cycles: {name}", "", r.markdown()]
        for name, r in (studies or {}).items():
            what = "Continuation" if name in {c.name for c in self.scene.continuation} else "Hunting map"
            lines += ["", f"## {what}: {name}", "", "```", r.summary(), "```"]
        return lines


def draw_figure(out, scene, figure, pngs, data, traces, cycles):
    """Draw one figure of ``scene`` into the files ``pngs`` (and SVGs) in ``out``; return its
    [(title, png, markdown)] sections (a module function: drawing processes run it too)."""
    from dfwb.plotting import plots
    from dfwb.studies.paper import Paper

    if figure.kind == "paper":
        paper = Paper(out, data, traces)
        try:
            getattr(paper, figure.paper)()
        except (ArithmeticError, IndexError, KeyError, ValueError) as error:
            raise RunError(f"figure {figure.name}: the paper's {figure.paper} cannot be drawn from this "
                           f"scene's points ({type(error).__name__}: {error}); it expects those of "
                           f"scenes/{PAPER_FIGURES[figure.paper].file}.toml") from None
        return paper.sections
    if figure.kind in ("limit_cycle", "continuation", "map"):
        for name, png in zip(figure.series, pngs):
            cycles[name].figure(out / png)
        return []
    plots.scene_figure(out, figure, data, traces, scene)
    return []


def _trace_columns(value, outputs):
    """A cached trace's columns in the scene's order (time, then ``outputs``), or None if the entry is not
    such a trace (the JSON of the cache sorts keys; a foreign entry is simulated again)."""
    names = ["time"] + list(outputs)
    if not isinstance(value, dict) or sorted(value) != sorted(names):
        return None
    columns = {name: value[name] for name in names}
    sizes = {len(column) if isinstance(column, list) else -1 for column in columns.values()}
    if len(sizes) != 1 or -1 in sizes or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                 for column in columns.values() for x in column):
        return None
    return columns


def _staged(display, name, skip=None):
    """``progress(stage, done, total)`` of a study: a bar per stage (but ``skip``) on the run's display."""
    tasks = {}

    def progress(stage, done, total):
        if stage == skip:
            return
        if stage not in tasks:
            tasks[stage] = [display.add(f"{name}: {stage}", total, done, 0), done]  # done: resumed
        display.advance(tasks[stage][0], done - tasks[stage][1])
        tasks[stage][1] = done

    return progress


def _cached_continuation(value):
    """The continuation a cache entry holds, or None (none, or not a continuation's record: recomputed)."""
    from dfwb.studies.responses import ContinuationResponse

    try:
        return None if value is None else ContinuationResponse.from_dict(value)
    except ValueError:
        return None


class _CachedEngine:
    """The DFEngine interface over the run's known points, the cache, then a local engine."""

    def __init__(self, run, table, plant):
        self.run, self.table, self.plant = run, table, run.specs[plant]
        self._engine = None
        self.computed = self.hits = 0

    def point(self, F, omega, params=None):
        params = self.plant.checked(params or {})
        name, key = self.table.named(self.plant.name, F, omega, params)
        value = self.run.values.get(name)
        if value is None:
            value = self.table.lookup(key)
            self.hits += value is not None
        if value is None:
            if self._engine is None:
                self._engine = DFEngine(self.plant.name, fmu=self.run.fmus[self.plant.name],
                                        **dict(self.table.settings))
            value = self._engine.point(F, omega, params).as_dict()
            self.run.cache.put(key, value)
            self.computed += 1
        self.run.values[name] = value
        return DFResult.from_dict(dict(value, params=params))


def run_scene(scene, out_dir=None, jobs=None, dask=None, cache=True, fmu_dir=None, progress=True):
    """Run a scene (a path or a :class:`~dfwb.studies.scene.Scene`); return an :class:`Outcome`.

    Parameters
    ----------
    scene : path or Scene
    out_dir : path, optional
        Default ``out/scenes/<file stem>``.
    jobs : int, optional
        Local worker processes, or Dask workers with ``dask="local"`` (default: all cores).
    dask : str, optional
        ``"local"`` or the address of a dask.distributed scheduler.
    cache : bool or path
        True: ``$XDG_CACHE_HOME/dfwb`` (else ``~/.cache/dfwb``); a path; False: no cache.
    """
    return begin_scene(scene, out_dir, jobs, dask, cache, fmu_dir, progress).finish()


def begin_scene(scene, out_dir=None, jobs=None, dask=None, cache=True, fmu_dir=None, progress=True, drawing=None,
                executor=None):
    """:func:`run_scene` up to its figures, which ``drawing`` draws meanwhile: the :class:`SceneRun`, whose
    ``finish()`` gives the Outcome (and ``close()`` gives the run up). ``executor``: one shared by several
    runs (its pool started once; the caller closes it), else one of ``jobs`` and ``dask`` for this run."""
    if not isinstance(scene, Scene):
        path = Path(scene)
        scene = load_scene(path)
        out_dir = out_dir or Path("out/scenes") / path.stem
    if out_dir is None:
        raise InputError("out_dir is required when the scene is not a file")
    with contextlib.nullcontext(executor) if executor is not None else Executor(jobs, dask) as executor:
        return SceneRun(scene, out_dir, executor, open_cache(cache), fmu_dir, progress).begin(drawing)


__all__ = ["run_scene", "Outcome", "Point"]
