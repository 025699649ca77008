"""Benchmark: the speed targets of the hunting tools, measured: a hunting map, a continuation, find_cycles per loop.

The loop throughout: the friction mass (default parameters) under PI control,
``G = "Kp + Ki/s"``; its linear loop is stable for 0 < Ki < 0.5 Kp. Reported,
never asserted (the exit code is 0 whether the targets are met or not):

(a) **the hunting map** ``dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 1, 50, N), ("Ki", 0.1, 25, N),
    jobs=2, cache=False, curves=True, out_dir=<a temporary folder>)``, N = 30 (``--quick``: 10): the truth
    and the DF in every cell, the linear boundary and the bifurcation curves. Target: the whole call in at
    most 60 s (for N = 30). Reported: the call's wall time (dfwb already imported and warmed up by a 2 x 2
    map: the workers' start-up is inside), the time per cell (wall time / cells), and the phases of the call,
    timed by wrapping, for the call only, the functions ``run_map`` calls (``df_map_for``, ``linear_map``,
    ``fold_curves`` of :mod:`dfwb.engine.hunting`, ``HuntingMapResponse.write``): setup / the shared DF map /
    the cells (worker pool) / the linear map / the curves / writing the folder. The workers' CPU time comes
    from ``getrusage(RUSAGE_CHILDREN)``; a worker's start-up is estimated apart (a fresh interpreter importing
    dfwb's map modules, median of 3). The per-cell compute time distribution (median, 90th percentile,
    max) comes from a sample of the map's cells (an evenly spaced ``--sample`` x ``--sample`` subgrid)
    classified again in this process, one at a time, exactly as a worker does it
    (``LoopFamily.problem``, the loop's scales, ``dfwb.engine.hunting.classify`` with the shared DF map); their
    classes are checked against the map's.
(b) **a continuation** of the true cycles: ``dfwb.continuation("friction", "Kp + Ki/s", "Ki", 0.5, 30, Kp=Kp,
    sources="truth", max_points=1000)`` for Kp in {5, 10, 20, 40}; each branch stops at its own ends (the
    range, infinity at the linear boundary Ki = 0.5 Kp), so one continuation gives 50 to 100 points and the
    four together more than 200. Target: 200 points in at most 5 s, read as a rate over the set, its searches
    included: 200 x (the set's wall time / its points) <= 5 s, i.e. at most 25 ms per point. Reported per
    continuation: wall time, points, time per point and the split (timed by wrapping): the searches for
    starts (``find_cycles`` at both ends of the range) / following (``dfwb.engine.continuation.follow``,
    the arclength steps) / bifurcations (``dfwb.engine.continuation.bifurcations``, detected and located to
    1e-7 of the range).
(c) **find_cycles** (the systematic search, default starts and horizon, no DF predictions) of the 16 loops Kp
    in {5, 10, 20, 40} x Ki in {0.5, 1, 2, 4}: ``find_cycles(LoopProblem("friction", f"{Kp} + {Ki}/s"))``
    timed each (the problem's construction included), with the cycles found and the coverage line. No target.

(b) and (c) are repeated ``--repeats`` times, interleaved across their cases (every case sees the same machine
load), medians reported; the map is run ``--map-repeats`` times (default once: it is the long part). The
machine has 2 shared, noisy cores: single runs can be off by tens of percent (three full runs here gave the map
in 37.8 to 54.2 s).

Usage: ``.venv/bin/python benchmarks/hunting.py [--quick] [--repeats 3] [--map-repeats 1] [--size 30]
[--sample 6] [--jobs 2] [--out out/bench_hunting]``. Writes ``hunting.md`` and ``hunting.json`` into ``--out``.
``--quick``: a 10 x 10 map, a 4 x 4 sample, one repeat (about 30 s); the full run takes one to two minutes.
"""

import argparse
import contextlib
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

import dfwb
from dfwb.engine import continuation as engine_continuation
from dfwb.engine import cycles as engine_cycles
from dfwb.engine.periodic import LoopProblem
from dfwb.studies import hunting as studies_hunting
from dfwb.studies import responses

PLANT = "friction"
G = "Kp + Ki/s"
MAP_X = ("Kp", 1.0, 50.0)
MAP_Y = ("Ki", 0.1, 25.0)
MAP_TARGET = 60.0  # s, the whole 30 x 30 map
TARGET_SIDE = 30  # the map the target is set for
POINTS_TARGET = (200, 5.0)  # 200 continuation points in at most 5 s
CONTINUATION = ("Ki", 0.5, 30.0)
CONTINUATION_KP = (5.0, 10.0, 20.0, 40.0)
MAX_POINTS = 1000
PAIRS = [(Kp, Ki) for Kp in (5, 10, 20, 40) for Ki in (0.5, 1, 2, 4)]
QUANTITIES = ("map wall time", "time per cell", "per-cell compute time", "continuation wall time",
              "time per point", "find_cycles")  # every measured quantity, named in the report


# -- timing by wrapping (this process, for one call only; the library's files are not touched) -----------------------
@contextlib.contextmanager
def wrapped(targets):
    """Wrap ``getattr(owner, name)`` for each (owner, name, label) of ``targets`` while the block runs: yields
    {label: [(start, end)]} of every outermost call (a call inside another of the same label is not counted)."""
    marks, depth, saved = {}, Counter(), []

    def wrapper_of(original, label):
        def wrapper(*args, **kwargs):
            depth[label] += 1
            started = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                depth[label] -= 1
                if depth[label] == 0:
                    marks.setdefault(label, []).append((started, time.perf_counter()))
        return wrapper

    try:
        for owner, name, label in targets:
            original = getattr(owner, name)
            saved.append((owner, name, original))
            setattr(owner, name, wrapper_of(original, label))
        yield marks
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


def spent(marks, label):
    """Seconds spent in the calls of ``label``."""
    return sum(end - start for start, end in marks.get(label, ()))


def children_cpu():
    """CPU seconds (user + system) of this process's finished children (the map's workers), or None."""
    try:
        import resource

        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    except (ImportError, OSError):
        return None
    return usage.ru_utime + usage.ru_stime


def distribution(values):
    """median, 90th percentile, max, mean and count of a list of seconds."""
    values = sorted(values)
    p90 = statistics.quantiles(values, n=10, method="inclusive")[-1] if len(values) > 1 else values[0]
    return {"count": len(values), "median": statistics.median(values), "p90": p90, "max": values[-1],
            "mean": statistics.fmean(values), "min": values[0]}


# -- (a) the hunting map -----------------------------------------------------------------------------------------------
def run_map(size, jobs):
    """One map into a temporary folder: its wall time, phases, workers' CPU, counts, classes and curves."""
    # wrapped where the map looks them up
    targets = [(studies_hunting, "df_map_for", "df map"), (studies_hunting, "linear_map", "linear"),
               (studies_hunting, "fold_curves", "curves"), (responses.HuntingMapResponse, "write", "write")]
    with tempfile.TemporaryDirectory(prefix="dfwb_bench_map_") as out, wrapped(targets) as marks:
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
        cpu = children_cpu()
        started = time.perf_counter()
        response = dfwb.hunting_map(PLANT, G, MAP_X + (size,), MAP_Y + (size,), out_dir=out, jobs=jobs, cache=False,
                                    curves=True)
        ended = time.perf_counter()
        cpu = None if cpu is None else children_cpu() - cpu
        written = sorted(p.name for p in Path(out).iterdir())
    seconds = ended - started
    df_map, linear = marks["df map"][0], marks["linear"][0]
    phases = {"setup": df_map[0] - started, "df map": df_map[1] - df_map[0], "cells": linear[0] - df_map[1],
              "linear map": linear[1] - linear[0], "curves": spent(marks, "curves"), "write": spent(marks, "write")}
    phases["other"] = seconds - sum(phases.values())
    cells = size * size
    return {"seconds": seconds, "load_average": load, "library_seconds": response.seconds, "phases": phases,
            "workers_cpu_seconds": cpu,
            "seconds_per_cell": seconds / cells, "cells_seconds_per_cell": phases["cells"] / cells,
            "counts": response.counts, "written": written, "response": response,
            "truth": dict(Counter(response.classes("truth").ravel().tolist())),
            "df": dict(Counter(response.classes("df").ravel().tolist())),
            "curves": [{"kind": c.kind, "source": c.source, "points": len(c.points)} for c in response.curves],
            "summary": response.summary()}


def sample_cells(response, side):
    """The per-cell compute time: an evenly spaced side x side subgrid of the map's cells, classified again here
    one at a time as a worker does (``dfwb.studies.hunting.compute_cells``): [{x, y, seconds, classes}]."""
    from dfwb.engine.family import LoopFamily
    from dfwb.engine.hunting import MAP_AMPLITUDES, classify, df_map_for
    from dfwb.fmi.location import fmu_path
    from dfwb.studies.executor import cached_engine

    xs, ys = response.xs, response.ys
    family = LoopFamily(PLANT, G, {}, free=(response.x, response.y))
    engine = cached_engine(family.spec.name, str(fmu_path(family.spec, None)), ())
    corners = [family.problem({response.x: a, response.y: b}) for a in (xs[0], xs[-1]) for b in (ys[0], ys[-1])]
    started = time.perf_counter()
    dfmap = df_map_for(corners, engine)
    dfmap_seconds = time.perf_counter() - started
    rows = sorted(set(np.linspace(0, len(ys) - 1, min(side, len(ys))).round().astype(int).tolist()))
    columns = sorted(set(np.linspace(0, len(xs) - 1, min(side, len(xs))).round().astype(int).tolist()))
    sample = []
    for j in rows:
        for i in columns:
            x, y = xs[i], ys[j]
            started = time.perf_counter()
            problem = family.problem({response.x: x, response.y: y})
            amplitudes = problem.scales.amplitudes(MAP_AMPLITUDES)
            built = time.perf_counter()
            cell = classify(problem, engine, dfmap, amplitudes)
            ended = time.perf_counter()
            classes = (cell["truth"]["class"], cell["df"]["class"])
            in_map = response.cells[j][i]
            sample.append({"x": x, "y": y, "seconds": ended - started, "classify_seconds": ended - built,
                           "truth": classes[0], "df": classes[1], "runs": cell["truth"]["coverage"]["starts"],
                           "same_as_map": classes == (in_map.get("truth", {}).get("class"),
                                                      in_map.get("df", {}).get("class"))})
    return sample, dfmap_seconds


# -- (b) continuation --------------------------------------------------------------------------------------------------
def run_continuation(Kp):
    """One continuation of the true cycles in Ki at Kp: wall time, points, the split."""
    targets = [(engine_cycles, "find_cycles", "searches"), (engine_continuation, "follow", "following"),
               (engine_continuation, "bifurcations", "bifurcations")]
    name, start, stop = CONTINUATION
    with wrapped(targets) as marks:
        started = time.perf_counter()
        response = dfwb.continuation(PLANT, G, name, start, stop, sources="truth", max_points=MAX_POINTS, Kp=Kp)
        seconds = time.perf_counter() - started
    split = {label: spent(marks, label) for label in ("searches", "following", "bifurcations")}
    split["other"] = seconds - sum(split.values())
    points = sum(len(branch.points) for branch in response.branches)
    return {"seconds": seconds, "points": points, "branches": [len(b.points) for b in response.branches],
            "ends": [[[value, reason] for value, reason in b.ends] for b in response.branches],
            "bifurcations": [[b.kind, b.parameter] for b in response.bifurcations], "split": split}


# -- (c) find_cycles ---------------------------------------------------------------------------------------------------
def run_find_cycles(Kp, Ki):
    started = time.perf_counter()
    found = engine_cycles.find_cycles(LoopProblem(PLANT, f"{Kp} + {Ki}/s"))
    seconds = time.perf_counter() - started
    return {"seconds": seconds, "cycles": [{"omega": c.omega, "amplitude_x": c.amplitude_x, "stable": c.stable}
                                           for c in found.cycles],
            "runs": found.coverage.starts, "outcomes": found.coverage.outcomes,
            "coverage": found.coverage.summary()}


def worker_start(runs=3):
    """Median seconds for a fresh interpreter (this environment) to import what a map's worker imports."""
    code = "import dfwb, dfwb.studies.hunting, dfwb.engine.hunting, dfwb.engine.cycles, dfwb.engine.limit_cycles"
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def machine_info():
    return {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
            "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None}


def main(argv=None):
    options = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options.add_argument("--quick", action="store_true", help="a 10 x 10 map, a 4 x 4 sample, one repeat")
    options.add_argument("--repeats", type=int, help="rounds of (b) and (c) (default 3; --quick: 1)")
    options.add_argument("--map-repeats", type=int, default=1, help="maps run (default 1)")
    options.add_argument("--size", type=int, help="the map's side (default 30; --quick: 10)")
    options.add_argument("--sample", type=int, help="the sampled subgrid's side (default 6; --quick: 4)")
    options.add_argument("--jobs", type=int, default=2, help="the map's worker processes (default 2)")
    options.add_argument("--out", type=Path, default=Path("out/bench_hunting"))
    args = options.parse_args(argv)
    size = args.size or (10 if args.quick else TARGET_SIDE)
    side = args.sample or (4 if args.quick else 6)
    repeats = args.repeats or (1 if args.quick else 3)
    for label, value, low in (("--size", size, 2), ("--sample", side, 1), ("--repeats", repeats, 1),
                              ("--map-repeats", args.map_repeats, 1), ("--jobs", args.jobs, 1)):
        if value < low:
            options.error(f"{label} {value}: at least {low}")
    machine = machine_info()
    print(f"machine: {machine['cpus']} cores, load average {machine['load_average']}", flush=True)

    # warm-up, untimed: imports, the FMU in this process, matplotlib (the map's figure), the native core
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="dfwb_bench_warm_") as out:
        dfwb.hunting_map(PLANT, G, MAP_X + (2,), MAP_Y + (2,), out_dir=out, jobs=1, curves=False)
    engine_cycles.find_cycles(LoopProblem(PLANT, "10 + 2/s"))
    print(f"warm-up (a 2 x 2 map in this process, one find_cycles): {time.perf_counter() - started:.1f} s", flush=True)

    # (a) the map
    maps = []
    for k in range(args.map_repeats):
        run = run_map(size, args.jobs)
        maps.append(run)
        print(f"[map {k + 1}/{args.map_repeats}] {size} x {size}, jobs={args.jobs}: {run['seconds']:.1f} s "
              f"({run['seconds_per_cell']:.3f} s per cell); " + ", ".join(f"{p} {s:.1f} s"
                                                                          for p, s in run["phases"].items()),
              flush=True)
    start_up = worker_start()
    print(f"a worker's start-up (a fresh interpreter importing dfwb's map modules): {start_up:.2f} s", flush=True)
    response = maps[-1].pop("response")
    for run in maps:
        run.pop("response", None)
    print(maps[-1]["summary"], flush=True)
    sample, dfmap_seconds = sample_cells(response, side)
    cell_times = distribution([s["seconds"] for s in sample])
    print(f"per-cell compute time, {len(sample)} cells in this process: median {cell_times['median']:.3f} s, "
          f"90th percentile {cell_times['p90']:.3f} s, max {cell_times['max']:.3f} s", flush=True)

    # (b) and (c), interleaved rounds
    continuations = {Kp: [] for Kp in CONTINUATION_KP}
    searches = {pair: [] for pair in PAIRS}
    for r in range(repeats):
        for Kp in CONTINUATION_KP:
            run = run_continuation(Kp)
            continuations[Kp].append(run)
            print(f"[{r + 1}/{repeats}] continuation, Kp = {Kp:g}: {run['seconds']:.2f} s, {run['points']} points",
                  flush=True)
        for pair in PAIRS:
            searches[pair].append(run_find_cycles(*pair))
        print(f"[{r + 1}/{repeats}] find_cycles, 16 loops: {sum(s[-1]['seconds'] for s in searches.values()):.2f} s",
              flush=True)

    result = summarize(args, size, side, repeats, machine, maps, sample, cell_times, dfmap_seconds, continuations,
                       searches)
    result["map"]["worker_start_seconds"] = start_up
    result["machine"]["load_average_end"] = os.getloadavg() if hasattr(os, "getloadavg") else None
    text = markdown(result)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "hunting.md").write_text(text)
    (args.out / "hunting.json").write_text(json.dumps(result, indent=1, default=float) + "\n")
    print(text)
    return 0


def summarize(args, size, side, repeats, machine, maps, sample, cell_times, dfmap_seconds, continuations, searches):
    cells = size * size
    median_map = statistics.median(run["seconds"] for run in maps)
    phases = {p: statistics.median(run["phases"][p] for run in maps) for p in maps[0]["phases"]}
    last = maps[-1]
    cpu = [run["workers_cpu_seconds"] for run in maps if run["workers_cpu_seconds"] is not None]
    projected_cells = cell_times["mean"] * cells / args.jobs
    the_map = {
        "size": [size, size], "cells": cells, "jobs": args.jobs, "runs": maps, "repeats": len(maps),
        "x": list(MAP_X) + [size], "y": list(MAP_Y) + [size],
        "seconds": median_map, "seconds_per_cell": median_map / cells, "phases": phases,
        "cells_seconds_per_cell": phases["cells"] / cells,
        "workers_cpu_seconds": statistics.median(cpu) if cpu else None,
        "workers_cpu_seconds_per_cell": statistics.median(cpu) / cells if cpu else None,
        "workers_busy": statistics.median(cpu) / (args.jobs * phases["cells"]) if cpu else None,
        "truth": last["truth"], "df": last["df"], "curves": last["curves"], "summary": last["summary"],
        "target_seconds": MAP_TARGET, "target_side": TARGET_SIDE,
        "target_met": median_map <= MAP_TARGET if size == TARGET_SIDE else None,
        "sample": {"side": side, "cells": sample, "seconds": cell_times,
                   "classify_seconds": distribution([s["classify_seconds"] for s in sample]),
                   "by_truth_class": {kind: distribution([s["seconds"] for s in sample if s["truth"] == kind])
                                      for kind in sorted({s["truth"] for s in sample})},
                   "df_map_seconds": dfmap_seconds, "same_as_map": sum(s["same_as_map"] for s in sample),
                   "projected_cells_seconds": projected_cells}}
    rows = []
    for Kp, runs in continuations.items():
        median = statistics.median(run["seconds"] for run in runs)
        points = runs[-1]["points"]
        rows.append({"Kp": Kp, "runs": runs, "seconds": median, "points": points,
                     "seconds_per_point": median / points if points else None,
                     "split": {k: statistics.median(run["split"][k] for run in runs) for k in runs[0]["split"]},
                     "branches": runs[-1]["branches"], "ends": runs[-1]["ends"],
                     "bifurcations": runs[-1]["bifurcations"]})
    total_seconds = sum(row["seconds"] for row in rows)
    total_points = sum(row["points"] for row in rows)
    following = sum(row["split"]["following"] + row["split"]["bifurcations"] for row in rows)
    per_point = total_seconds / total_points
    continuation = {"parameter": list(CONTINUATION), "Kp": list(CONTINUATION_KP), "max_points": MAX_POINTS,
                    "continuations": rows, "seconds": total_seconds, "points": total_points,
                    "seconds_per_point": per_point, "seconds_for_200_points": POINTS_TARGET[0] * per_point,
                    "following_seconds_per_point": following / total_points,
                    "target_points": POINTS_TARGET[0], "target_seconds": POINTS_TARGET[1],
                    "target_met": POINTS_TARGET[0] * per_point <= POINTS_TARGET[1]}
    pairs = []
    for (Kp, Ki), runs in searches.items():
        pairs.append({"Kp": Kp, "Ki": Ki, "seconds": statistics.median(run["seconds"] for run in runs),
                      "all_seconds": [run["seconds"] for run in runs], "cycles": runs[-1]["cycles"],
                      "runs": runs[-1]["runs"], "outcomes": runs[-1]["outcomes"], "coverage": runs[-1]["coverage"]})
    times = [p["seconds"] for p in pairs]
    search = {"pairs": pairs, "seconds": distribution(times), "total_seconds": sum(times)}
    return {"quick": args.quick, "repeats": repeats, "machine": machine, "quantities": list(QUANTITIES),
            "plant": PLANT, "G": G, "map": the_map, "continuation": continuation, "find_cycles": search}


def verdict(met):
    return "not applicable" if met is None else ("**met**" if met else "**NOT met**")


def markdown(r):
    m, c, f, machine = r["map"], r["continuation"], r["find_cycles"], r["machine"]
    s = m["sample"]
    size = m["size"][0]
    lines = [f"# Hunting tools: the speed targets, measured ({'quick' if r['quick'] else 'full'} run)", "",
             f"The friction mass (default parameters) under PI control, G = `{r['G']}` (linear loop stable for "
             "0 < Ki < 0.5 Kp). Wall times; (b) and (c) are medians of "
             f"{r['repeats']} interleaved round(s), the map {m['repeats']} run(s). The machine has "
             f"{machine['cpus']} shared, noisy cores: single runs can be off by tens of percent.", "",
             "| target | measured | verdict |", "|---|---|---|"]
    if m["target_met"] is None:
        lines.append(f"| (a) a {m['target_side']} x {m['target_side']} map in <= {m['target_seconds']:.0f} s | "
                     f"{size} x {size} map in {m['seconds']:.1f} s | {verdict(None)}: not the target's size (its "
                     "fixed costs, the workers' start-up, the linear map, the curves, the figure, do not scale with "
                     "the cells: run the full benchmark for the verdict) |")
    else:
        lines.append(f"| (a) a {m['target_side']} x {m['target_side']} map in <= {m['target_seconds']:.0f} s | "
                     f"{m['seconds']:.1f} s | {verdict(m['target_met'])} |")
    lines += [f"| (b) {c['target_points']} continuation points in <= {c['target_seconds']:.0f} s | "
              f"{c['points']} points in {c['seconds']:.2f} s: {1e3 * c['seconds_per_point']:.1f} ms per point, "
              f"{c['seconds_for_200_points']:.2f} s per 200 | {verdict(c['target_met'])} |",
              f"| (c) find_cycles, 16 PI loops | median {1e3 * f['seconds']['median']:.0f} ms, max "
              f"{1e3 * f['seconds']['max']:.0f} ms, {f['total_seconds']:.2f} s in all | no target |", ""]

    lines += [f"## (a) The hunting map: {size} x {size} cells, jobs = {m['jobs']}, no cache, curves", "",
              f"`dfwb.hunting_map(\"friction\", \"{r['G']}\", (\"Kp\", 1, 50, {size}), (\"Ki\", 0.1, 25, {size}), "
              f"jobs={m['jobs']}, cache=False, curves=True, out_dir=<a temporary folder>)`, after a warm-up 2 x 2 "
              "map in this process (imports, the FMU, matplotlib); the workers are spawned inside the call.", "",
              f"- **map wall time**: {m['seconds']:.1f} s"
              + (" (runs: " + ", ".join(f"{run['seconds']:.1f}" for run in m["runs"]) + " s)" if m["repeats"] > 1
                 else "")
              + f"; the response's own `seconds`: {m['runs'][-1]['library_seconds']:.1f} s (from after the "
              "argument checks to the curves' end, the folder's writing not included)",
              f"- **time per cell**: {m['seconds_per_cell']:.3f} s of wall time ({m['cells']} cells); the cells "
              f"phase alone {m['cells_seconds_per_cell']:.3f} s per cell"
              + (f"; the workers' CPU: {m['workers_cpu_seconds']:.1f} s in all (their start-up included), "
                 f"{m['workers_cpu_seconds_per_cell']:.3f} s per cell: {m['workers_busy']:.0%} of {m['jobs']} cores "
                 "over the cells phase" if m["workers_cpu_seconds"] is not None else ""),
              "- phases: " + ", ".join(f"{p} {v:.2f} s" for p, v in m["phases"].items()),
              f"- **per-cell compute time** ({len(s['cells'])} cells, an evenly spaced {s['side']} x {s['side']} "
              "subgrid, classified again one at a time in this process as a worker does): median "
              f"{s['seconds']['median']:.3f} s, 90th percentile {s['seconds']['p90']:.3f} s, max "
              f"{s['seconds']['max']:.3f} s, mean {s['seconds']['mean']:.3f} s (of which `classify` "
              f"{s['classify_seconds']['mean']:.3f} s); by the truth's class: "
              + "; ".join(f"{k} {d['count']} cells, median {d['median']:.3f} s, max {d['max']:.3f} s"
                          for k, d in s["by_truth_class"].items())
              + f". The same classes as the map in {s['same_as_map']} of {len(s['cells'])}. The shared DF map took "
              f"{s['df_map_seconds']:.2f} s here.",
              f"- the sample's mean x {m['cells']} cells / {m['jobs']} workers = {s['projected_cells_seconds']:.1f} s "
              f"of cells on ideally shared workers, against {m['phases']['cells']:.1f} s measured for the cells "
              f"phase: the difference is the workers' start-up (a fresh interpreter importing dfwb's map modules: "
              f"{m['worker_start_seconds']:.2f} s here, then each builds its DF engine), the last chunks' "
              "imbalance and the machine's other load (load average "
              + ", ".join(f"{run['load_average']:.2f}" for run in m["runs"] if run["load_average"] is not None)
              + " when the map started, this benchmark's own process included).",
              "- truth: " + ", ".join(f"{n} {k}" for k, n in sorted(m["truth"].items(), key=lambda kv: -kv[1]))
              + "; DF: " + ", ".join(f"{n} {k}" for k, n in sorted(m["df"].items(), key=lambda kv: -kv[1]))
              + "; bifurcation curves: " + (", ".join(f"{cv['source']} {cv['kind']} ({cv['points']} columns)"
                                                      for cv in m["curves"]) or "none"), "",
              "Slowest sampled cells:", ""]
    for cell in sorted(s["cells"], key=lambda cell: -cell["seconds"])[:5]:
        lines.append(f"- Kp = {cell['x']:.4g}, Ki = {cell['y']:.4g}: {cell['seconds']:.3f} s, truth {cell['truth']} "
                     f"({cell['runs']} runs), DF {cell['df']}")
    lines += ["", "```", m["summary"].rstrip(), "```", ""]

    name, lo, hi = c["parameter"]
    lines += [f"## (b) Continuation of the true cycles in {name} over [{lo:g}, {hi:g}], Kp in "
              f"{{{', '.join(f'{k:g}' for k in c['Kp'])}}}", "",
              f"`dfwb.continuation(\"friction\", \"{r['G']}\", \"{name}\", {lo:g}, {hi:g}, sources=\"truth\", "
              f"max_points={c['max_points']}, Kp=Kp)`. Split (timed by wrapping): the searches for starts "
              "(`find_cycles` at both ends) / following (`follow`: the arclength steps) / bifurcations (detected "
              "and located) / other.", "",
              "| Kp | continuation wall time [s] | points (branches) | time per point [ms] | split searches / "
              "following / bifurcations / other [s] | bifurcations |", "|---|---|---|---|---|---|"]
    for row in c["continuations"]:
        split = " / ".join(f"{row['split'][k]:.2f}" for k in ("searches", "following", "bifurcations", "other"))
        found = "; ".join(f"{kind} at {value:.4g}" for kind, value in row["bifurcations"]) or "none"
        lines.append(f"| {row['Kp']:g} | {row['seconds']:.2f} | {row['points']} "
                     f"({' + '.join(str(n) for n in row['branches'])}) | {1e3 * row['seconds_per_point']:.1f} | "
                     f"{split} | {found} |")
    lines += ["", f"In all: {c['points']} points in {c['seconds']:.2f} s, **time per point** "
              f"{1e3 * c['seconds_per_point']:.1f} ms (searches included; following and bifurcations alone "
              f"{1e3 * c['following_seconds_per_point']:.1f} ms), so {c['seconds_for_200_points']:.2f} s per 200 "
              f"points against the target's {c['target_seconds']:.0f} s: {verdict(c['target_met'])}. No single "
              "continuation of this loop reaches 200 points: each branch ends where it must (the range's end, or "
              "infinity at the linear boundary) well before max_points.", ""]

    lines += ["## (c) find_cycles on 16 PI loops", "",
              "`find_cycles(LoopProblem(\"friction\", f\"{Kp} + {Ki}/s\"))`: default starts (output amplitudes over "
              "the loop's span, displacing x, v and the integrator both ways), no DF predictions, basin boundaries "
              "bisected; the problem's construction included.", "",
              "| Kp | Ki | find_cycles [ms] | runs | outcomes | cycles (omega, X, stable) |",
              "|---|---|---|---|---|---|"]
    for p in f["pairs"]:
        found = "; ".join(f"{cy['omega']:.4g}, {cy['amplitude_x']:.4g}, {'s' if cy['stable'] else 'u'}"
                          for cy in p["cycles"]) or "none"
        outcomes = ", ".join(f"{n} {k}" for k, n in p["outcomes"].items())
        lines.append(f"| {p['Kp']:g} | {p['Ki']:g} | {1e3 * p['seconds']:.0f} | {p['runs']} | {outcomes} | {found} |")
    d = f["seconds"]
    lines += ["", f"find_cycles per loop: median {1e3 * d['median']:.0f} ms, 90th percentile {1e3 * d['p90']:.0f} ms, "
              f"max {1e3 * d['max']:.0f} ms; {f['total_seconds']:.2f} s for the 16.", ""]
    load, end = machine["load_average"], machine.get("load_average_end")
    lines.append(f"Machine: {machine['cpus']} shared, noisy cores ({machine['platform']}, Python {machine['python']}"
                 + (f"; load average {load[0]:.2f} at the start" if load else "")
                 + (f", {end[0]:.2f} at the end" if end else "") + ").")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
