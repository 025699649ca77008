"""Benchmark: the cost and error of a DF point of a user's FMU, beside the built-in exact engine, in one run.

Issue 22's cost targets, measured and reported (never asserted; the exit code is 0), by the same code as
``dfwb bench``'s section on it (:mod:`dfwb.verify.foreign_bench`), alone:

- **model exchange at 1e-8**: small C model-exchange FMUs (:mod:`dfwb.build_fmus.c_models`: a
  mass-spring-damper, a saturation, a relay with hysteresis), each point's true error against its closed
  form and its ``N_error`` (the full set also at the driver's default rtol 1e-10);
- **co-simulation at 1e-6**: dfwb's own native plant FMUs run as black boxes (input ``f``; held input,
  refined, extrapolated) at the plants' benchmark points (quick or full), against the exact engine on the
  same FMU: true error, ``N_error`` and time, side by side.

Run: ``.venv/bin/python benchmarks/foreign_plant.py [--quick] [--repeats 3]``; writes
``out/bench/foreign_plant.md`` (about a minute quick, three full).
"""

import argparse
import sys
from pathlib import Path

from dfwb.verify.foreign_bench import foreign_markdown, foreign_rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="the plants' quick points, rtol 1e-8 only")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    args = parser.parse_args(argv)
    lines = ["# A DF point of a user's FMU: cost and error", ""] + foreign_markdown(
        foreign_rows(quick=args.quick, repeats=args.repeats))
    args.out.mkdir(parents=True, exist_ok=True)
    report = args.out / "foreign_plant.md"
    report.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\nwritten {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
