"""Benchmark: a DF point of issue 32's plants beside the plant each is measured against, native FMUs.

Issue 32's targets, measured in one run and reported (never asserted; the exit code is 0):

1. ``stribeck`` (integrated slides, rtol 1e-9): a DF point in at most 1 ms (the exact friction mass, the same
   friction without the Stribeck fall: about 0.1 ms), on the 40-point friction set of ``df_point.py``;
2. ``drivetrain`` (exact): a DF point as fast as ``backlash``'s, on backlash's benchmark points (the same
   clearance and restitution; the load's friction is the drivetrain's own). The drivetrain with its load's
   friction off (``Fc = Fs = B = 0``: backlash to rounding) is measured beside them, so that the report
   separates what the machinery costs from what the load's friction costs.

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
# the drivetrain with its load's friction off: the two-mass backlash to rounding, so its ratio to backlash is the
# cost of the machinery alone, and the rest of the drivetrain's is the cost of the load's friction
FREE_LOAD = "drivetrain, Fc = Fs = B = 0"
FREE_SET = tuple((F, omega, dict(params, Fc=0.0, Fs=0.0, B=0.0)) for F, omega, params in BACKLASH_SET)
PAIRS = (("stribeck", "friction", FRICTION_SET), ("drivetrain", "backlash", BACKLASH_SET),
         (FREE_LOAD, "backlash", FREE_SET))
PLANT = {FREE_LOAD: "drivetrain"}  # a row's plant, where the row is not named by it
STRIBECK_POINT = 1e-3  # s: the target for a stribeck point


def engines():
    """{plant: ExactFMU} of the native FMU of every plant of PAIRS, built if needed."""
    from dfwb.verify.bench import ExactFMU

    method, kind, solver = EXACT[0]
    found = {}
    for row, points in rows().items():
        plant = PLANT.get(row, row)
        if plant not in found:
            found[plant] = ExactFMU(plant, method, kind, solver, points[0])
            if found[plant].why:
                raise SystemExit(f"the native FMU of {plant} cannot run here: {found[plant].why}")
    return found


def rows():
    """{row: its points}, each row once (a plant measured against in two pairs runs once a round)."""
    found = {}
    for new, old, points in PAIRS:
        found.setdefault(new, points)
        found.setdefault(old, {"friction": FRICTION_SET, "backlash": BACKLASH_SET}[old])
    return found


def measure(rounds, report):
    """{row: [median seconds per point]} and {row: [DFResult]} over the rounds, the rows interleaved."""
    fmus = engines()
    measured = rows()
    times = {row: [[] for _ in points] for row, points in measured.items()}
    results = {}
    for round_ in range(rounds):
        for row, points in measured.items():
            fmu = fmus[PLANT.get(row, row)]
            for i, (F, omega, params) in enumerate(points):
                fmu.point(F, omega, params)
                started = time.perf_counter()
                results.setdefault(row, {})[i] = fmu.point(F, omega, params)
                times[row][i].append(time.perf_counter() - started)
        report(f"round {round_ + 1} of {rounds}")
    medians = {plant: [statistics.median(t) for t in per_point] for plant, per_point in times.items()}
    return medians, {plant: [r[i] for i in sorted(r)] for plant, r in results.items()}


def lines(medians, results):
    text = ["| plant | points | mean point [ms] | median point [ms] | slowest point [ms] | periods per point "
            "(mean) | against |", "|---|---|---|---|---|---|---|"]
    verdicts = []
    against = {new: old for new, old, _points in PAIRS}
    for plant, points in rows().items():
        t = medians[plant]
        periods = statistics.mean(r.periods for r in results[plant])
        old = against.get(plant)
        ratio = "" if old is None else f"{statistics.mean(t) / statistics.mean(medians[old]):.2f}x {old}"
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
    free = statistics.mean(medians[FREE_LOAD]) / statistics.mean(medians["backlash"])
    periods = {row: sum(r.periods for r in results[row]) for row in ("drivetrain", FREE_LOAD, "backlash")}
    verdicts.append(f"- drivetrain against backlash, mean DF point: {drivetrain:.2f}x (target: as fast, <= 1x): "
                    f"**{'PASS' if drivetrain <= 1.0 else 'FAIL'}**. With the load's friction off ({FREE_LOAD}) it "
                    f"is {free:.2f}x, in {periods[FREE_LOAD]} periods against backlash's {periods['backlash']}: the "
                    f"rest is the load's friction, whose slow transient (B / M1 = 0.5 1/s) and sticks take "
                    f"{periods['drivetrain']} periods")
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
