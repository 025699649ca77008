"""Benchmark of the scene runner: what skipping work saves.

1. A DF-only scene against the same scene with harmonics, time traces and
   figures (both from an empty cache into an empty folder).
2. A second run of each against the first: into the same folder (up to date:
   nothing to do) and into a new folder (every point from the cache, the
   figures redrawn). Target: the second run at least 50 times faster.

Runs are interleaved and repeated (``--repeats``), each cold run with its own
empty cache; medians are reported. ``run_scene`` is timed in this process;
the command line's wall time (Python start-up and imports included) is
measured once per case as well.

Usage: ``.venv/bin/python benchmarks/scenes.py [--repeats 3] [--out out/bench_scenes]``
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from dfwb.studies.runner import run_scene

GRID = """
[[series]]
name = "backlash"
plant = "backlash"
grid = { eps = [0.2, 0.8] }
F = [10.0, 20.0, 30.0, 40.0, 50.0]
omega = { log = [1.0, 100.0, 41], values = [15.0, 20.0, 25.0, 30.0, 35.0, 40.0] }
"""
DF_ONLY = 'title = "backlash, DF only"\n' + GRID
FULL = 'title = "backlash, DF, harmonics, traces and figures"\nharmonics = true\n' + GRID + """
[[trace]]
name = "w20_eps08"
plant = "backlash"
params = { eps = 0.8 }
F = 50.0
omega = 20.0
start = 1.65
stop = 2.1
step = 0.0002
outputs = ["x1", "v1", "gap"]

[[trace]]
name = "w40_eps02"
plant = "backlash"
params = { eps = 0.2 }
F = 50.0
omega = 40.0
start = 1.65
stop = 2.1
step = 0.0002
outputs = ["x1", "v1", "gap"]

[[figure]]
name = "nyquist"
kind = "nyquist"
series = ["backlash"]
marks = [15.0, 20.0, 25.0, 30.0, 35.0, 40.0]

[[figure]]
name = "re_im"
kind = "re_im"
series = ["backlash"]

[[figure]]
name = "harmonics"
kind = "harmonics"
series = ["backlash"]

[[figure]]
name = "traces"
kind = "trace"
series = ["w20_eps08", "w40_eps02"]
"""


def timed(scene, out, cache):
    started = time.perf_counter()
    outcome = run_scene(scene, out, cache=cache, progress=False)
    return time.perf_counter() - started, outcome


def cli_seconds(scene, out, cache):
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "dfwb.cli", "run", str(scene), "--out", str(out), "--cache", str(cache),
                    "--quiet"], check=True, capture_output=True)
    return time.perf_counter() - started


def main():
    options = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options.add_argument("--repeats", type=int, default=3)
    options.add_argument("--out", type=Path, default=Path("out/bench_scenes"))
    args = options.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    times = {(name, case): [] for name in ("DF only", "full") for case in ("first", "same folder", "new folder")}
    cli = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = {}
        for name, text in (("DF only", DF_ONLY), ("full", FULL)):
            files[name] = tmp / f"{name.replace(' ', '_')}.toml"
            files[name].write_text(text)
        points = None
        for repeat in range(args.repeats):
            for name, path in files.items():
                cache, out = tmp / f"cache_{name}_{repeat}", tmp / f"out_{name}_{repeat}"
                seconds, outcome = timed(path, out, cache)
                assert outcome.computed == outcome.points, "the first run must start from nothing"
                points = outcome.points
                times[name, "first"].append(seconds)
                seconds, outcome = timed(path, out, cache)
                assert outcome.up_to_date
                times[name, "same folder"].append(seconds)
                seconds, outcome = timed(path, tmp / f"again_{name}_{repeat}", cache)
                assert outcome.computed == 0
                times[name, "new folder"].append(seconds)
                if repeat == 0:
                    cli[name, "same folder"] = cli_seconds(path, out, cache)
                    cli[name, "new folder"] = cli_seconds(path, tmp / f"cli_{name}", cache)
    median = {key: statistics.median(values) for key, values in times.items()}
    lines = [f"# Scene runner benchmark ({points} DF points of the two-mass backlash; medians of {args.repeats})", "",
             "| scene | first run [s] | second run, same folder [s] | speed-up | second run, new folder [s] | "
             "speed-up | CLI wall, same folder [s] | CLI wall, new folder [s] |", "|---|---|---|---|---|---|---|---|"]
    for name in ("DF only", "full"):
        first = median[name, "first"]
        lines.append(f"| {name} | {first:.2f} | {median[name, 'same folder']:.4f} | "
                     f"{first / median[name, 'same folder']:.0f}x | {median[name, 'new folder']:.2f} | "
                     f"{first / median[name, 'new folder']:.1f}x | {cli[name, 'same folder']:.2f} | "
                     f"{cli[name, 'new folder']:.2f} |")
    lines += ["", f"Harmonics, traces and figures cost {median['full', 'first'] / median['DF only', 'first']:.2f}x "
              "the DF-only first run.", ""]
    text = "\n".join(lines)
    (args.out / "scenes.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
