"""Benchmark: one describing-function point, through the FMU against scipy, side by side.

For each of a plant's benchmark points (its registry entry's ``bench["full"]``;
``--plant``, default friction): the FMU engine (exact, through fmpy) and
scipy's ``solve_ivp`` (DOP853, rtol 1e-9: what a user would write instead,
the entry's ``scipy``) are timed interleaved in the same run, medians of
repeats; both are checked against the plant's reference (the entry's
``reference``: scipy at rtol 1e-12, or a closed form). Then ``dfwb paper``
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

from dfwb.engine.describing import DFEngine
from dfwb.plants import PLANTS

# the plants this benchmark can run: a scipy rival, a reference and benchmark points
CHOICES = [e.name for e in PLANTS.values() if e.scipy is not None and e.reference is not None and e.bench.get("full")]


def timed(function):
    started = time.perf_counter()
    value = function()
    return time.perf_counter() - started, value


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    parser.add_argument("--no-paper", action="store_true", help="skip the dfwb paper timing")
    parser.add_argument("--plant", choices=CHOICES, default="friction", help="the plant (default: %(default)s)")
    args = parser.parse_args()
    repeats = 5 if args.quick else 21
    entry = PLANTS[args.plant]
    engine = DFEngine(entry.name)
    engine.point(*entry.bench["full"][0])  # warm the FMU instance
    with_params = any(params for _F, _omega, params in entry.bench["full"])  # a column only where a point sets some
    lines = ["| F [N] | w [rad/s] | " + ("params | " if with_params else "") + "FMU median [ms] | "
             "scipy DOP853 rtol 1e-9 median [ms] | ratio | FMU error | scipy error | periods |",
             "|---|---|" + ("---|" if with_params else "") + "---|---|---|---|---|---|"]
    for F, omega, params in entry.bench["full"]:
        reference = entry.reference(F, omega, dict(params))
        fmu_times, scipy_times = [], []
        for _ in range(repeats):  # interleaved: both see the same machine load
            seconds, fmu = timed(lambda: engine.point(F, omega, params))
            fmu_times.append(seconds)
            if len(scipy_times) < max(3, repeats // 4):
                seconds, ref = timed(lambda: entry.scipy(F, omega, dict(params), "DOP853", 1e-9))
                scipy_times.append(seconds)
        fmu_ms, scipy_ms = 1e3 * statistics.median(fmu_times), 1e3 * statistics.median(scipy_times)
        fmu_error = abs(fmu.N - reference) / abs(reference)
        scipy_error = abs(ref - reference) / abs(reference)
        setting = (", ".join(f"{k} = {v:g}" for k, v in params.items()) or "defaults") + " | " if with_params else ""
        lines.append(f"| {F:g} | {omega:g} | {setting}{fmu_ms:.3f} | {scipy_ms:.1f} | {scipy_ms / fmu_ms:.0f}x | "
                     f"{fmu_error:.1e} | {scipy_error:.1e} | {fmu.periods} |")
        print(lines[-1], flush=True)
    text = [f"# One DF point ({entry.name}): FMU engine against scipy", "",
            f"{repeats} repeats of the FMU point, interleaved with scipy runs; errors against the plant's reference "
            "(scipy DOP853 at rtol 1e-12, or a closed form). Machine: 2 shared cores.", ""] + lines
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
