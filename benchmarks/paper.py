"""Benchmark: ``dfwb paper`` from an empty cache, then again into the same folder and into a new one.

Each repeat starts ``dfwb paper --quiet`` as a subprocess, the way a user
does, with a new empty result cache (the FMUs are built once beforehand, in
``--fmus``, and not timed), then reruns it into the same folder (up to date)
and into a new folder (every scene copied from the cache). Interleaved with
it, the same command with every figure drawn in the run's own process, one
after the other (as before ``dfwb.studies.drawing``), from an empty cache
too: the two are measured side by side under the same load. Prints the
median wall time of each over ``--repeats`` (issue 24's target: at most 3 s
from an empty cache).

Usage: ``.venv/bin/python benchmarks/paper.py [--repeats 5] [--fmus DIR]``
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from startup import _dfwb, _runs  # the command that starts dfwb; a bounded repeat count

TARGET = 3.0  # seconds from an empty cache
SEQUENTIAL = """
import sys
from dfwb import cli
from dfwb.studies import reproduce
reproduce.Drawing = lambda jobs: None  # every figure drawn in this process, one after the other
sys.exit(cli.main(sys.argv[1:]))
"""


def timed(command):
    started = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def measure(repeats, fmus):
    """{"empty cache": [s], "same folder": [s], "new folder": [s]} over ``repeats`` repeats."""
    dfwb = _dfwb()
    subprocess.run(dfwb + ["build", "--out", str(fmus)], check=True, stdout=subprocess.DEVNULL)
    times = {"empty cache": [], "same folder": [], "new folder": [], "empty cache, figures drawn in turn": []}
    for _ in range(repeats):
        with tempfile.TemporaryDirectory(prefix="dfwb-paper-bench-") as work:
            work = Path(work)
            options = ["paper", "--quiet", "--fmus", str(fmus)]
            paper = dfwb + options + ["--cache", str(work / "cache")]
            times["empty cache"].append(timed(paper + ["--out", str(work / "a")]))
            times["same folder"].append(timed(paper + ["--out", str(work / "a")]))
            times["new folder"].append(timed(paper + ["--out", str(work / "b")]))
            sequential = [sys.executable, "-c", SEQUENTIAL] + options
            times["empty cache, figures drawn in turn"].append(
                timed(sequential + ["--cache", str(work / "cache2"), "--out", str(work / "c")]))
    return times


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=_runs, default=5, help="repeats (default 5)")
    parser.add_argument("--fmus", type=Path, default=None, help="FMU folder (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="dfwb-paper-fmus-") as scratch:
        times = measure(args.repeats, args.fmus or Path(scratch))
    print("| dfwb paper | median (s) | min (s) | max (s) |\n|---|---|---|---|")
    for name, values in times.items():
        print(f"| {name} | {statistics.median(values):.2f} | {min(values):.2f} | {max(values):.2f} |")
    median, before = (statistics.median(times[name]) for name in ("empty cache", "empty cache, figures drawn in turn"))
    print(f"\nfrom an empty cache: {median:.2f} s (target: at most {TARGET:g} s; {args.repeats} repeats, wall "
          f"time of the command); figures drawn in turn: {before:.2f} s, {before / median:.2f}x as long")
    return 0


if __name__ == "__main__":
    sys.exit(main())
