"""Benchmark: ``dfwb paper`` from an empty cache against the work in it, then again into the same folder and a new one.

Each repeat starts ``dfwb paper`` as a subprocess, the way a user does,
with a new empty result cache (the FMUs are built once beforehand, in
``--fmus``, and not timed), then reruns it into the same folder (up to date)
and into a new folder (every scene copied from the cache). Interleaved with
it, under the same load:

- the in-process solver time of the same DF points (a subprocess that
  computes each point the paper computes, once, on one engine per plant and
  setting made beforehand, and times only the points): the run's "points"
  phase against it is issue 31's first target (at most 2x);
- ``dfwb --help`` (the bare start-up) and the same paper command with every
  figure drawn in the run's own process, one after the other (as before
  ``dfwb.studies.drawing``), from an empty cache too: its "figures" phase is
  the figures' drawing time, and issue 31's second target is the paper from
  an empty cache within 3x ``dfwb --help`` plus that drawing time.

Prints one row per repeat and the medians (the machine this runs on may be
shared: compare the ratios, measured side by side, more than the seconds).

Usage: ``.venv/bin/python benchmarks/paper.py [--repeats 5] [--fmus DIR]``
"""

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from startup import _dfwb, _runs  # the command that starts dfwb; a bounded repeat count

POINTS_TARGET = 2.0  # the points phase against the in-process solver time of the same points
START_TARGET = 3.0  # the paper from an empty cache against dfwb --help, the figures' drawing time aside
SEQUENTIAL = """
import sys
from dfwb import cli
from dfwb.studies import reproduce
reproduce.Drawing = lambda jobs: None  # every figure drawn in this process, one after the other
sys.exit(cli.main(sys.argv[1:]))
"""
SOLVER = """
import json, sys, time
from dfwb.base.defaults import HARMONICS
from dfwb.engine.describing import DFEngine
from dfwb.fmi.location import fmu_path
from dfwb.studies.reproduce import paper_scenes

fmus = sys.argv[1]
done, work, engines = {}, [], {}
for _path, scene in paper_scenes():  # the runner's order: a point recorded with harmonics serves one without
    harmonics = HARMONICS if scene.needs_harmonics else 1
    for p in scene.points():
        spec = scene.plant(p.plant)
        params = spec.checked(p.params)
        point = (p.plant, p.F, p.omega, tuple(sorted(spec.complete(params).items())))
        if done.get(point, -1) >= harmonics:
            continue
        done[point] = harmonics
        e = scene.engine
        settings = (p.plant, harmonics, e.drive, e.max_periods, e.samples_per_period)
        if settings not in engines:
            engines[settings] = DFEngine(p.plant, fmu=fmu_path(spec, fmus), drive=e.drive, harmonics=harmonics,
                                         max_periods=e.max_periods, samples_per_period=e.samples_per_period)
        work.append((engines[settings], p.F, p.omega, params))
started = time.perf_counter()
for engine, F, omega, params in work:
    engine.point(F, omega, params)
print(json.dumps({"points": len(work), "seconds": time.perf_counter() - started}))
"""
_PHASE = re.compile(r"(\w+) ([0-9.]+) s")


def run(command):
    """(wall seconds, stdout) of a command that must succeed."""
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed (exit {done.returncode}): {done.stderr.strip()[-2000:]}")
    return seconds, done.stdout


def phases(stdout):
    """{phase: seconds} of the paper's last line ('... written in 8.1 s: start 0.18 s, points 4.02 s, ...')."""
    line = stdout.strip().splitlines()[-1]
    return {name: float(value) for name, value in _PHASE.findall(line.partition(": ")[2])}


def measure(repeats, fmus):
    """One dict of seconds per repeat: paper, points, solver, help, drawing, same folder, new folder."""
    dfwb = _dfwb()
    subprocess.run(dfwb + ["build", "--out", str(fmus)], check=True, stdout=subprocess.DEVNULL)
    rows = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory(prefix="dfwb-paper-bench-") as work:
            work = Path(work)
            options = ["paper", "--quiet", "--fmus", str(fmus)]
            paper = dfwb + options + ["--cache", str(work / "cache")]
            row = {"help": statistics.median(run(dfwb + ["--help"])[0] for _ in range(3))}
            row["paper"], out = run(paper + ["--out", str(work / "a")])
            row["points"] = phases(out)["points"]
            solver = json.loads(run([sys.executable, "-c", SOLVER, str(fmus)])[1])
            row["solver"], row["solver points"] = solver["seconds"], solver["points"]
            row["computed"] = int(re.search(r"\(([0-9]+) DF points? computed", (work / "a" / "report.md").read_text())
                                  .group(1))
            row["same folder"] = run(paper + ["--out", str(work / "a")])[0]
            row["new folder"] = run(paper + ["--out", str(work / "b")])[0]
            sequential = [sys.executable, "-c", SEQUENTIAL] + options
            row["in turn"], out = run(sequential + ["--cache", str(work / "cache2"), "--out", str(work / "c")])
            row["drawing"] = phases(out)["figures"]
            rows.append(row)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=_runs, default=5, help="repeats (default 5)")
    parser.add_argument("--fmus", type=Path, default=None, help="FMU folder (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="dfwb-paper-fmus-") as scratch:
        rows = measure(args.repeats, args.fmus or Path(scratch))
    for row in rows:
        row["points / solver"] = row["points"] / row["solver"]
        row["paper / (3 help + drawing)"] = row["paper"] / (START_TARGET * row["help"] + row["drawing"])
    columns = ["paper", "points", "solver", "points / solver", "help", "drawing", "paper / (3 help + drawing)",
               "same folder", "new folder", "in turn"]
    print("Seconds (wall) and ratios of each repeat; 'solver': the in-process solver time of the same points; "
          "'drawing': the figures phase of the run with every figure drawn in turn ('in turn': that run).\n")
    print("| repeat | " + " | ".join(columns) + " |\n|---" * 1 + "|---" * len(columns) + "|")
    for i, row in enumerate(rows, 1):
        print(f"| {i} | " + " | ".join(f"{row[name]:.2f}" for name in columns) + " |")
    print("| median | " + " | ".join(f"{statistics.median(row[name] for row in rows):.2f}" for name in columns) + " |")
    counts = {(row["computed"], row["solver points"]) for row in rows}
    ratio = statistics.median(row["points / solver"] for row in rows)
    start = statistics.median(row["paper / (3 help + drawing)"] for row in rows)
    print(f"\nDF points computed by the paper / timed in process: {', '.join(f'{a} / {b}' for a, b in counts)}")
    print(f"points phase / in-process solver time: median {ratio:.2f} (target at most {POINTS_TARGET:g}; "
          f"{min(row['points / solver'] for row in rows):.2f} to {max(row['points / solver'] for row in rows):.2f})")
    print(f"paper from an empty cache / ({START_TARGET:g} x dfwb --help + drawing time): median {start:.2f} "
          f"(target at most 1; {args.repeats} repeats)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
