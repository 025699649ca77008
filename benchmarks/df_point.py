"""Benchmark: one describing-function point, through the FMU against scipy, side by side.

For each friction point: the FMU engine (exact, through fmpy) and scipy's
``solve_ivp`` (DOP853, rtol 1e-9, event-driven: what a user would write
instead) are timed interleaved in the same run, medians of repeats; both
are checked against a tight scipy reference (rtol 1e-12). Then ``dfwb paper``
end to end from an empty folder. Run: ``.venv/bin/python benchmarks/df_point.py``
(``--quick`` for fewer repeats). Writes ``out/bench/df_point.md``.
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dfwb.describing import DFEngine
from dfwb.reference import describing_function_reference

POINTS = [(10.0, 1.0), (30.0, 1.0), (50.0, 0.5), (10.0, 0.1), (20.0, 5.0)]


def timed(function):
    started = time.perf_counter()
    value = function()
    return time.perf_counter() - started, value


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    parser.add_argument("--no-paper", action="store_true", help="skip the dfwb paper timing")
    args = parser.parse_args()
    repeats = 5 if args.quick else 21
    engine = DFEngine("friction")
    engine.point(10.0, 1.0)  # warm the FMU instance
    lines = ["| F [N] | w [rad/s] | FMU median [ms] | scipy DOP853 rtol 1e-9 median [ms] | ratio | "
             "FMU error | scipy error | periods |", "|---|---|---|---|---|---|---|---|"]
    for F, omega in POINTS:
        reference = describing_function_reference("friction", F, omega, rtol=1e-12)["N"]
        fmu_times, scipy_times = [], []
        for _ in range(repeats):  # interleaved: both see the same machine load
            seconds, fmu = timed(lambda: engine.point(F, omega))
            fmu_times.append(seconds)
            if len(scipy_times) < max(3, repeats // 4):
                seconds, ref = timed(lambda: describing_function_reference("friction", F, omega, rtol=1e-9))
                scipy_times.append(seconds)
        fmu_ms, scipy_ms = 1e3 * statistics.median(fmu_times), 1e3 * statistics.median(scipy_times)
        fmu_error = abs(fmu.N - reference) / abs(reference)
        scipy_error = abs(ref["N"] - reference) / abs(reference)
        lines.append(f"| {F:g} | {omega:g} | {fmu_ms:.3f} | {scipy_ms:.1f} | {scipy_ms / fmu_ms:.0f}x | "
                     f"{fmu_error:.1e} | {scipy_error:.1e} | {fmu.periods} |")
        print(lines[-1], flush=True)
    text = ["# One DF point: FMU engine against scipy", "",
            f"{repeats} repeats of the FMU point, interleaved with scipy runs; errors against scipy DOP853 at "
            "rtol 1e-12. Machine: 2 shared cores.", ""] + lines
    if not args.no_paper:
        with tempfile.TemporaryDirectory() as tmp:
            seconds, run = timed(lambda: subprocess.run(
                [sys.executable, "-m", "dfwb.cli", "paper", "--out", tmp, "--quiet"], capture_output=True, text=True))
            if run.returncode:
                raise SystemExit(run.stderr)
        text += ["", f"`dfwb paper` end to end from an empty folder: {seconds:.1f} s."]
        print(text[-1])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "df_point.md").write_text("\n".join(text) + "\n")


if __name__ == "__main__":
    main()
