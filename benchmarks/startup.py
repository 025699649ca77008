"""Benchmark: a cached re-run of a scene into a new folder, against the bare start-up (``dfwb --help``).

A scene is run once (computing its points and drawing its figures into a
private cache), then, interleaved so that both see the same machine load,
``dfwb --help`` and ``dfwb run SCENE --out <a new folder>`` (every point and
figure from the cache) are each timed ``--runs`` times as subprocesses, the
way a user starts them. Prints both medians and their ratio (issue 14's
and 24's target: a cached re-run within 2x of the bare start-up).

Usage: ``.venv/bin/python benchmarks/startup.py [--runs 7] [--scene SCENE.toml | --shipped] [--fmus DIR] [--quiet]``
(default scene: two friction points and one Nyquist figure; ``--shipped``: every scene of ``scenes/``, one
row each, and the largest ratio; ``--fmus``: the FMU folder, default dfwb's own). :func:`measure` returns
the numbers, for a caller that reports them elsewhere. Both commands run in the environment as
it is. ``make`` compiles dfwb's bytecode when it installs the venv (as pip
does for a regular install); with ``PYTHONDONTWRITEBYTECODE=1`` and no
bytecode, every dfwb module would be compiled at each start, which costs
both, the re-run more (it imports more of dfwb).
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENE = '''
title = "startup benchmark: two points, one figure"
[[series]]
name = "friction"
plant = "friction"
F = [10.0]
omega = [1.0, 2.0]

[[figure]]
name = "nyquist"
kind = "nyquist"
series = ["friction"]
'''
MAX_RUNS = 1000


def _runs(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not 1 <= value <= MAX_RUNS:
        raise argparse.ArgumentTypeError(f"{value} is out of range: an integer from 1 to {MAX_RUNS}")
    return value


def _dfwb():
    """The command that starts dfwb: the venv's console script next to this Python, else ``python -m``."""
    script = Path(sys.executable).with_name("dfwb")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "dfwb.cli"]


def timed(command, env):
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed (exit {done.returncode}): {done.stderr.strip()}")
    return seconds


def measure(runs=7, scene=None, fmus=None, quiet=False):
    """(first run, median of ``dfwb --help``, median of the cached re-run) in seconds, ``runs`` of each."""
    dfwb = _dfwb()
    with tempfile.TemporaryDirectory(prefix="dfwb_startup_") as tmp:
        tmp = Path(tmp)
        path = tmp / "scene.toml"
        if scene is None:
            path.write_text(SCENE)
        else:
            shutil.copyfile(scene, path)
        env = dict(os.environ, MPLCONFIGDIR=str(tmp / "mpl"))
        run = dfwb + ["run", str(path), "--cache", str(tmp / "cache")] + (["--fmus", str(fmus)] if fmus else [])
        run += ["--quiet"] if quiet else []
        first = timed(run + ["--out", str(tmp / "first")], env)
        timed(run + ["--out", str(tmp / "warm")], env)  # the operating system's file cache, warm for both
        bare, cached = [], []
        for i in range(runs):
            bare.append(timed(dfwb + ["--help"], env))
            cached.append(timed(run + ["--out", str(tmp / f"rerun{i}")], env))
    return first, statistics.median(bare), statistics.median(cached)


SCENES = Path(__file__).resolve().parents[1] / "scenes"


def shipped(runs, fmus, quiet):
    """A row per shipped scene (first run, ``dfwb --help``, cached re-run, ratio) and the largest ratio."""
    print("| scene | first run (s) | dfwb --help (s) | cached re-run (s) | ratio |\n|---|---|---|---|---|")
    ratios = []
    for scene in sorted(SCENES.glob("*.toml")):
        first, help_s, rerun_s = measure(runs, scene, fmus, quiet)
        ratios.append(rerun_s / help_s)
        print(f"| {scene.stem} | {first:.2f} | {help_s:.3f} | {rerun_s:.3f} | {ratios[-1]:.2f}x |", flush=True)
    print(f"\nlargest ratio: {max(ratios):.2f}x, median {statistics.median(ratios):.2f}x (target: within 2x; "
          f"medians of {runs} interleaved runs each)")
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=_runs, default=7, help="timed runs of each command (default: %(default)s)")
    parser.add_argument("--scene", type=Path, help="the scene file (default: two points and one figure)")
    parser.add_argument("--fmus", type=Path, help="FMU folder (default: dfwb's own)")
    parser.add_argument("--shipped", action="store_true", help="every shipped scene (scenes/*.toml), one row each")
    parser.add_argument("--quiet", action="store_true", help="time the re-run with --quiet (no progress display)")
    args = parser.parse_args(argv)
    if args.scene is not None and not args.scene.is_file():
        parser.error(f"--scene {args.scene}: no such file")
    if args.shipped:
        if args.scene is not None:
            parser.error("--scene and --shipped: give one")
        return shipped(args.runs, args.fmus, args.quiet)
    first, help_s, rerun_s = measure(args.runs, args.scene, args.fmus, args.quiet)
    print(f"first run (computes and draws):  {first:.2f} s")
    print(f"dfwb --help:                     {help_s:.3f} s (median of {args.runs})")
    print(f"cached re-run into a new folder: {rerun_s:.3f} s (median of {args.runs})")
    print(f"ratio: {rerun_s / help_s:.2f}x (target: within 2x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
