"""Benchmark: the speed targets of compensation (issue 33), measured: a compensation map and ``dfwb tune``.

The loop: the friction mass (default parameters) under PI. Reported, never asserted (exit code 0 either way):

(a) **a compensation map**: ``dfwb.hunting_map("friction", "Kp + 2/s", ("Kp", 5, 20, N), ("d", 0.01, 0.3, N),
    compensate="deadband", jobs=2, cache=False, curves=False)``, N = 30 (``--quick``: 8): the truth and the cost
    in every cell. Target: at most 60 s for N = 30. Beside it, measured in the same run, **the uncompensated
    map** the issue compares it with, ``("Kp", 1, 50, N) x ("Ki", 0.1, 25, N)`` of ``Kp + Ki/s`` with its DF
    (curves off too). Both run on the compiled loop (the compensated one without the DF, which a compensated
    loop does not have, but with the cost of a step response in every cell).
(b) **dfwb tune**: ``dfwb.tune("friction", "Kp + Ki/s", compensate="deadband", free={"Kp": (2, 50), "Ki":
    (0.2, 10), "d": (0.01, 0.5)}, tolerance=0.1, robust={"Fc": 0.2, "Fs": 0.1})`` with 5 values each, its
    confirmation by the reference included. Target: at most 2 minutes.
(c) **a dithered map**: ``dfwb.hunting_map("friction", "10 + 2/s", ("a", 0.5, 10, M), ("w_d", 1, 9, M),
    compensate="dither", jobs=2, cache=False)``, M = 8 (``--quick``: 4): the stroboscopic search and the cost
    in every cell (no target in the issue); and one cell's search (a = 1 N, w_d = 5 rad/s, 20 starts) on the
    compiled loop and on the Python loop, side by side.
(d) **a backlash inverse's map**: ``dfwb.hunting_map("static-backlash", "20*(s+a)/(s+20)", ("h_hat", 0, 0.3, M),
    ("a", 0.5, 8, M), compensate="backlash-inverse", jobs=2, cache=False, curves=False)``: the truth and the cost
    in every cell (no target in the issue).

(e) **the dither's DF**: a point of ``dfwb.engine.dither_df.DitherDFEngine`` on the friction mass (F = 10 N,
    a = 10 N, w_d = 5 rad/s) at w = w_d / r for r = 0.1, 1.3, 5.3, 20.3 and 50.3 dither periods a forcing period,
    the map's coarse twin and the precise engine, side by side (no target in the issue: what a study's DF map
    and its Newton steps cost).

Usage: ``.venv/bin/python benchmarks/compensation.py [--quick] [--out out/bench_compensation]``; writes
``compensation.md`` and ``compensation.json`` there.
"""

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import dfwb

TARGETS = {"map": 60.0, "tune": 120.0}  # seconds (the map's for N = 30)


def dither_cell(native):
    """One dithered cell's stroboscopic search (a = 1 N, w_d = 5 rad/s, the map's 20 starts): its seconds, and its
    outcomes (the same on either loop)."""
    from dfwb.engine.dither import find_responses
    from dfwb.engine.hunting import MAP_AMPLITUDES
    from dfwb.engine.periodic import LoopProblem
    from dfwb.fmus.compensation import Dither
    from dfwb.fmus.friction import FrictionLoop

    problem = LoopProblem("friction", "10 + 2/s", compensation=Dither(1.0, 5.0))
    if not native:  # the Python loop, with modes of its own (a study's modes dict holds one kind)
        problem.cls, problem._modes = FrictionLoop, {}
    found, seconds = timed(lambda: find_responses(problem, problem.scales.amplitudes(MAP_AMPLITUDES)))
    return seconds, found.coverage.outcomes


def dither_df_points():
    """[(r, seconds of the coarse twin, seconds of the precise engine, its N_error / |N|)] at w = w_d / r."""
    from dfwb.engine.dither_df import DitherDFEngine
    from dfwb.plants import plant

    engine = DitherDFEngine(plant("friction"))
    coarse, rows = engine.coarse(), []
    for r in (0.1, 1.3, 5.3, 20.3, 50.3):
        values = {"a": 10.0, "w_d": 5.0}
        _, t_coarse = timed(lambda: coarse.point(10.0, 5.0 / r, values))
        point, t_fine = timed(lambda: engine.point(10.0, 5.0 / r, values))
        rows.append((r, t_coarse, t_fine, point.N_error / abs(point.N)))
    return rows


def timed(call):
    started = time.perf_counter()
    value = call()
    return value, time.perf_counter() - started


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="8 x 8 maps")
    parser.add_argument("--out", type=Path, default=Path("out/bench_compensation"))
    args = parser.parse_args(argv)
    n = 8 if args.quick else 30
    args.out.mkdir(parents=True, exist_ok=True)
    dfwb.hunting_map("friction", "Kp + 2/s", ("Kp", 5, 20, 2), ("d", 0.01, 0.3, 2), compensate="deadband", jobs=1,
                     curves=False)  # warm: imports, the FMUs, the compiled core
    with tempfile.TemporaryDirectory() as folder:
        compensated, t_compensated = timed(lambda: dfwb.hunting_map(
            "friction", "Kp + 2/s", ("Kp", 5, 20, n), ("d", 0.01, 0.3, n), compensate="deadband", jobs=2,
            cache=False, curves=False, out_dir=Path(folder) / "compensated"))
        plain, t_plain = timed(lambda: dfwb.hunting_map(
            "friction", "Kp + Ki/s", ("Kp", 1, 50, n), ("Ki", 0.1, 25, n), jobs=2, cache=False, curves=False,
            out_dir=Path(folder) / "plain"))
    m = 4 if args.quick else 8
    with tempfile.TemporaryDirectory() as folder:
        dithered, t_dithered = timed(lambda: dfwb.hunting_map(
            "friction", "10 + 2/s", ("a", 0.5, 10, m), ("w_d", 1, 9, m), compensate="dither", jobs=2, cache=False,
            out_dir=Path(folder) / "dithered"))
        inverse, t_inverse = timed(lambda: dfwb.hunting_map(
            "static-backlash", "20*(s+a)/(s+20)", ("h_hat", 0, 0.3, m), ("a", 0.5, 8, m),
            compensate="backlash-inverse", jobs=2, cache=False, curves=False, out_dir=Path(folder) / "inverse"))
    (t_cell_c, outcomes_c), (t_cell_py, outcomes_py) = dither_cell(True), dither_cell(False)
    didf = dither_df_points()
    tuned, t_tune = timed(lambda: dfwb.tune("friction", "Kp + Ki/s", compensate="deadband",
                                            free={"Kp": (2, 50), "Ki": (0.2, 10), "d": (0.01, 0.5)}, tolerance=0.1,
                                            robust={"Fc": 0.2, "Fs": 0.1}))
    report = {
        "machine": f"{platform.node()}, {os.cpu_count()} cores, Python {platform.python_version()}",
        "size": n,
        "compensated_map": {"seconds": t_compensated, "cells": n * n, "per_cell": t_compensated / (n * n),
                            "truth": compensated.classes("truth").ravel().tolist().count("stable"),
                            "target": TARGETS["map"] if n == 30 else None},
        "uncompensated_map": {"seconds": t_plain, "cells": n * n, "per_cell": t_plain / (n * n)},
        "ratio": t_compensated / t_plain,
        "tune": {"seconds": t_tune, "settings": tuned.settings, "confirmed": tuned.confirmed,
                 "target": TARGETS["tune"]},
        "dithered_map": {"seconds": t_dithered, "cells": m * m, "per_cell": t_dithered / (m * m),
                         "classes": dithered.classes("truth").ravel().tolist()},
        "inverse_map": {"seconds": t_inverse, "cells": m * m, "per_cell": t_inverse / (m * m),
                        "classes": inverse.classes("truth").ravel().tolist()},
        "dither_df": [{"r": r, "coarse": tc, "precise": tf, "relative_error": e} for r, tc, tf, e in didf],
        "dithered_cell": {"compiled": t_cell_c, "python": t_cell_py, "ratio": t_cell_py / t_cell_c,
                          "same_outcomes": outcomes_c == outcomes_py, "outcomes": outcomes_c},
    }
    lines = ["# Compensation: measured", "", f"Machine: {report['machine']}. One run, the maps side by side.", "",
             "| what | seconds | per cell | target |", "|---|---|---|---|",
             f"| compensated map {n} x {n} (deadband, Kp x d; truth and cost) | {t_compensated:.1f} | "
             f"{t_compensated / (n * n) * 1e3:.0f} ms | " + (f"{TARGETS['map']:.0f} s: "
                                                          f"{'PASS' if t_compensated <= TARGETS['map'] else 'FAIL'}"
                                                          if n == 30 else "(N = 30 only)") + " |",
             f"| uncompensated map {n} x {n} (Kp x Ki, truth and DF) | {t_plain:.1f} | "
             f"{t_plain / (n * n) * 1e3:.0f} ms | |",
             f"| dfwb tune (125 settings, 5 corners, confirmed) | {t_tune:.1f} | | {TARGETS['tune']:.0f} s: "
             f"{'PASS' if t_tune <= TARGETS['tune'] else 'FAIL'} |",
             f"| dithered map {m} x {m} (a x w_d; the stroboscopic search and the cost) | {t_dithered:.1f} | "
             f"{t_dithered / (m * m) * 1e3:.0f} ms | |",
             f"| backlash inverse's map {m} x {m} (static backlash, h_hat x a; truth and cost) | {t_inverse:.1f} | "
             f"{t_inverse / (m * m) * 1e3:.0f} ms | |",
             f"| one dithered cell's search, compiled loop / Python loop | {t_cell_c:.2f} / {t_cell_py:.2f} | | "
             f"{t_cell_py / t_cell_c:.1f} x faster; same outcomes: {outcomes_c == outcomes_py} |"]
    lines += [f"| the dither's DF, a point at {r:g} dither periods a period: coarse / precise "
              f"(N_error {e:.1e} of N) | {tc:.2f} / {tf:.2f} | | |" for r, tc, tf, e in didf]
    lines += ["",
             f"The compensated map takes {report['ratio']:.2f} times the uncompensated one. "
             f"Tune chose {tuned.settings}, confirmed: {tuned.confirmed}."]
    (args.out / "compensation.md").write_text("\n".join(lines) + "\n")
    (args.out / "compensation.json").write_text(json.dumps(report, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
