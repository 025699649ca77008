"""Benchmark: a DF point of issue 32's plants beside the plant each is measured against, native FMUs.

Issue 32's targets, measured in one run and reported (never asserted; the exit code is 0):

1. ``stribeck`` (integrated slides, rtol 1e-9): a DF point in at most 1 ms (the exact friction mass, the same
   friction without the Stribeck fall: about 0.1 ms), on the 40-point friction set of ``df_point.py``;
2. ``drivetrain`` (exact): a DF point as fast as ``backlash``'s, on backlash's benchmark points (the same
   clearance and restitution; the load's friction is the drivetrain's own).

Each plant runs through its native FMU (``fmu-native`` of :data:`dfwb.verify.bench.EXACT`), in rounds: each
round sweeps each plant's set point after point, the plants interleaved, so that a pair's ratio is measured
side by side. A point's time is the median over the rounds (each point is run twice in a row and the second
timed, as a sweep computes it, caches warm); a set's cost is the mean of its points' medians. ``stribeck``'s
largest ``N_error`` over the set is reported with it.

Run: ``.venv/bin/python benchmarks/new_plants.py [--quick]``; writes ``out/bench/new_plants.md``. ``--quick``:
fewer rounds (about 20 s); the full run takes about a minute.
"""

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

from df_point import FRICTION_SET

from dfwb.plants import PLANTS
from dfwb.verify.bench import EXACT, label

BACKLASH_SET = PLANTS["backlash"].bench["full"]
PAIRS = (("stribeck", "friction", FRICTION_SET), ("drivetrain", "backlash", BACKLASH_SET))
STRIBECK_POINT = 1e-3  # s: the target for a stribeck point


def engines():
    """{plant: ExactFMU} of the native FMU of every plant of PAIRS, built if needed."""
    from dfwb.verify.bench import ExactFMU

    method, kind, solver = EXACT[0]
    found = {}
    for pair in PAIRS:
        for plant in pair[:2]:
            points = pair[2]
            found[plant] = ExactFMU(plant, method, kind, solver, points[0])
            if found[plant].why:
                raise SystemExit(f"the native FMU of {plant} cannot run here: {found[plant].why}")
    return found


def measure(rounds, report):
    """{plant: [median seconds per point]} and {plant: [DFResult]} over the rounds, the sets interleaved."""
    fmus = engines()
    times = {plant: [[] for _ in points] for new, old, points in PAIRS for plant in (new, old)}
    results = {}
    for round_ in range(rounds):
        for new, old, points in PAIRS:
            for plant in (new, old):
                for i, (F, omega, params) in enumerate(points):
                    fmus[plant].point(F, omega, params)
                    started = time.perf_counter()
                    results.setdefault(plant, {})[i] = fmus[plant].point(F, omega, params)
                    times[plant][i].append(time.perf_counter() - started)
        report(f"round {round_ + 1} of {rounds}")
    medians = {plant: [statistics.median(t) for t in per_point] for plant, per_point in times.items()}
    return medians, {plant: [r[i] for i in sorted(r)] for plant, r in results.items()}


def lines(medians, results):
    text = ["| plant | points | mean point [ms] | median point [ms] | slowest point [ms] | periods per point "
            "(mean) | against |", "|---|---|---|---|---|---|---|"]
    verdicts = []
    for new, old, points in PAIRS:
        for plant in (new, old):
            t = medians[plant]
            periods = statistics.mean(r.periods for r in results[plant])
            ratio = "" if plant == old else f"{statistics.mean(t) / statistics.mean(medians[old]):.2f}x {old}"
            text.append(f"| {plant} | {len(points)} | {1e3 * statistics.mean(t):.3f} | "
                        f"{1e3 * statistics.median(t):.3f} | {1e3 * max(t):.3f} | {periods:.1f} | {ratio} |")
    stribeck = statistics.mean(medians["stribeck"])
    slowest = max(range(len(FRICTION_SET)), key=lambda i: medians["stribeck"][i])
    errors = [r.N_error for r in results["stribeck"]]
    relative = max(r.N_error / abs(r.N) for r in results["stribeck"] if r.N)
    drivetrain = statistics.mean(medians["drivetrain"]) / statistics.mean(medians["backlash"])
    verdicts.append(f"- stribeck, mean DF point at rtol 1e-9: {1e3 * stribeck:.3f} ms (target <= "
                    f"{1e3 * STRIBECK_POINT:g} ms): **{'PASS' if stribeck <= STRIBECK_POINT else 'FAIL'}**; its "
                    f"slowest point {label(*FRICTION_SET[slowest])} at {1e3 * medians['stribeck'][slowest]:.3f} ms; "
                    f"N_error at most {max(errors):.1e} (relative to |N|: {relative:.1e})")
    verdicts.append(f"- drivetrain against backlash, mean DF point: {drivetrain:.2f}x (target: as fast, <= 1x): "
                    f"**{'PASS' if drivetrain <= 1.0 else 'FAIL'}**")
    return text, verdicts


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds")
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    args = parser.parse_args()
    try:  # before anything runs: a folder that cannot be written costs one line, not the measurement
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        parser.error(f"--out {str(args.out)!r} cannot be made: {error.strerror}")
    rounds = 3 if args.quick else 9
    started = time.perf_counter()
    medians, results = measure(rounds, report=lambda line: print(line, flush=True))
    table, verdicts = lines(medians, results)
    text = ["# A DF point of issue 32's plants, native FMUs", "",
            f"{'Quick' if args.quick else 'Full'} run on this machine (2 shared cores): {rounds} rounds, each "
            "sweeping every plant's set point after point (each point twice in a row, the second timed); a "
            "point's time is its median over the rounds. stribeck and friction: the 40-point friction set (F = "
            "10..50 N, w = 0.03..100 rad/s); drivetrain and backlash: backlash's benchmark points.", ""]
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    text += table + [""] + verdicts + ["", f"Benchmark run time: {time.perf_counter() - started:.0f} s. Machine: "
                                       f"{os.cpu_count()} shared, noisy cores ({platform.platform()}, Python "
                                       f"{platform.python_version()}"
                                       + (f"; load average {load[0]:.2f} at the end" if load else "") + ")."]
    (args.out / "new_plants.md").write_text("\n".join(text) + "\n")
    print("\n".join(table + verdicts))
    print(f"{args.out / 'new_plants.md'} written")


if __name__ == "__main__":
    main()
