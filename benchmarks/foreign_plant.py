"""Benchmark: the cost of a DF point of a user's FMU, beside the built-in exact engine, measured in one run.

Issue 22's cost targets, measured and reported (never asserted; the exit code is 0):

- **model exchange at 1e-8**: the C model-exchange FMUs the tests compile
  (``tests/foreign_models.py``: a mass-spring-damper, a saturation, a relay with
  hysteresis), each point's true error against its closed form and its
  ``N_error``, at the driver's rtol 1e-8 (the target's) and 1e-10 (the default);
- **co-simulation at 1e-6**: dfwb's own native plant FMUs run as black boxes
  (input ``f``; held input, refined, extrapolated), at the plants' quick
  benchmark points, against the exact engine on the same FMU: true error,
  ``N_error`` and time, side by side.

Times are medians of ``--repeats`` runs of each point after one warm-up (the
worker process started), wall clock on this machine as it is (2 shared cores:
the ratios matter more than the seconds).

Run: ``.venv/bin/python benchmarks/foreign_plant.py [--repeats 3]``; writes
``out/bench/foreign_plant.md``.
"""

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import dfwb
from dfwb.fmi.location import fmu_path
from dfwb.plants import PLANTS

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import foreign_models  # noqa: E402  (the tests' C model-exchange FMUs)

ME_POINTS = [("MassSpringDamper", 1.0, 1.0, lambda F, w: foreign_models.msd_df(w)),
             ("MassSpringDamper", 2.0, 2.0, lambda F, w: foreign_models.msd_df(w)),
             ("Saturation", 3.0, 1.0, lambda F, w: foreign_models.saturation_df(F)),
             ("Relay", 3.0, 2.0, lambda F, w: foreign_models.relay_df(F))]
OUTPUTS = {"friction": "x", "backlash": "x1", "static-backlash": "y"}


def timed(run, repeats):
    """(median seconds, last result) of ``repeats`` runs after one warm-up."""
    result = run()
    seconds = []
    for _ in range(repeats):
        started = time.perf_counter()
        result = run()
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds), result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("out/bench"))
    args = parser.parse_args(argv)
    lines = ["# A DF point of a user's FMU: cost and error", "",
             "## Model exchange (C FMUs of the tests, closed forms)", "",
             "| FMU | F [N] | omega [rad/s] | rtol | true error (rel) | N_error (rel) | ms per point |",
             "|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="dfwb_bench_foreign_") as folder:
        built = {name: foreign_models.build(name, folder) for name in {p[0] for p in ME_POINTS}}
        for rtol in (1e-8, 1e-10):
            engines = {name: dfwb.fmu_plant(path) for name, path in built.items()}
            for name, F, omega, exact in ME_POINTS:
                seconds, response = timed(lambda: dfwb.describing_function(engines[name], F, omega, rtol=rtol),
                                          args.repeats)
                truth = exact(F, omega)
                error = abs(complex(response.N) - truth) / abs(truth)
                lines.append(f"| {name} | {F:g} | {omega:g} | {rtol:g} | {error:.1e} "
                             f"| {float(response.N_error) / abs(truth):.1e} | {seconds * 1e3:.0f} |")
    lines += ["", "## Co-simulation under a held input (dfwb's native FMUs as black boxes)", "",
              "| plant | F [N] | omega [rad/s] | params | true error (rel) | N_error (rel) | ms generic | ms exact "
              "| ratio |",
              "|---|---|---|---|---|---|---|---|---|"]
    for name, output in OUTPUTS.items():
        entry = PLANTS[name]
        path = fmu_path(entry).parent / "native" / f"{entry.fmu_name}.fmu"
        path = path if path.is_file() else fmu_path(entry)
        own = dfwb.fmu_plant(path, input="f", output=output)
        for F, omega, params in entry.bench["quick"]:
            generic_s, generic = timed(lambda: dfwb.describing_function(own, F, omega, **params), args.repeats)
            exact_s, exact = timed(lambda: dfwb.describing_function(name, F, omega, **params), args.repeats)
            truth = complex(exact.N)
            lines.append(f"| {name} | {F:g} | {omega:g} | {params or ''} | "
                         f"{abs(complex(generic.N) - truth) / abs(truth):.1e} | "
                         f"{float(generic.N_error) / abs(truth):.1e} | {generic_s * 1e3:.0f} | {exact_s * 1e3:.2f} | "
                         f"{generic_s / exact_s:.0f} |")
    args.out.mkdir(parents=True, exist_ok=True)
    report = args.out / "foreign_plant.md"
    report.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\nwritten {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
