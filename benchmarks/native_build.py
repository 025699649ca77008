"""Benchmark: how long ``dfwb build --native`` takes, for FMI 2.0 and 3.0, with every platform this machine builds.

Issue 23's target: the native FMUs of both FMI versions and both platforms (linux64, and win64 with mingw-w64)
built in under a minute on this machine. Measured, never asserted (the exit code is 0): each FMI version built
from scratch (``force``) ``--repeats`` times into a temporary folder, with the median and the spread, and
their sum; the platforms compile side by side (one compiler process each).

Run: ``.venv/bin/python benchmarks/native_build.py [--repeats 3]``; writes ``out/bench/native_build.md``.
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from dfwb.build_fmus.native import FMI_VERSIONS, build_native, platforms


def timings(repeats):
    """{FMI version: [seconds of one full build of the three FMUs, ...]}."""
    seconds = {version: [] for version in FMI_VERSIONS}
    with tempfile.TemporaryDirectory(prefix="dfwb_bench_native_") as tmp:
        for _ in range(repeats):
            for version in FMI_VERSIONS:
                started = time.perf_counter()
                build_native(Path(tmp) / f"fmi{version}", force=True, report=lambda message: None,
                             fmi_version=version)
                seconds[version].append(time.perf_counter() - started)
    return seconds


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    args = parser.parse_args(argv)
    seconds = timings(max(1, args.repeats))
    lines = ["# `dfwb build --native`: build time", "",
             f"Platforms: {' + '.join(platforms())}; {args.repeats} builds of each FMI version, from scratch.", "",
             "| FMI | median (s) | min (s) | max (s) |", "|---|---|---|---|"]
    for version, values in seconds.items():
        lines.append(f"| {version}.0 | {statistics.median(values):.1f} | {min(values):.1f} | {max(values):.1f} |")
    total = sum(statistics.median(values) for values in seconds.values())
    lines += ["", f"Both FMI versions, all platforms: {total:.1f} s (target: under 60 s)."]
    args.out.mkdir(parents=True, exist_ok=True)
    report = args.out / "native_build.md"
    report.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\nwritten {report}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
