"""The ``dfwb`` command line.

Bad input (an unknown plant or parameter, F <= 0, omega <= 0, NaN, a value
out of the plant's range) is one line on stderr and exit code 2, before
anything is computed or written.
"""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

DEFAULT_FMU_DIR = Path("build/fmus")
PLANT_NAMES = ("friction", "backlash", "static-backlash")


class InputError(Exception):
    """Bad command-line input: reported in one line, exit code 2."""


def _assignments(items, option):
    """{name: value} from NAME=VALUE words."""
    values = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE")
        values[name] = value
    return values


def _grid_values(items):
    """{name: [values]} from NAME=V1,V2,... words."""
    return {name: [float(v) for v in text.split(",")] for name, text in _assignments(items, "--grid").items()}


def _omegas(args):
    if args.omega_log:
        lo, hi, n = args.omega_log
        if not (lo > 0 and hi > lo and n >= 2 and n == int(n)):
            raise InputError(f"--omega-log {lo:g} {hi:g} {n:g}: expected 0 < LO < HI and an integer N >= 2")
        return list(np.geomspace(lo, hi, int(n)))
    if not args.omega:
        raise InputError("give --omega W [W ...] or --omega-log LO HI N")
    return args.omega


def _fmus(out_dir):
    from dfwb.build_fmus import build_all

    return {path.stem: path for path in build_all(out_dir, report=lambda message: None)}


def cmd_build(args):
    from dfwb.build_fmus import build_all

    build_all(args.out, force=args.force)
    return 0


def cmd_df(args):
    from .describing import DFEngine, check_point
    from .plants import plant

    params = plant(args.plant).check(_assignments(args.set, "--set"))
    omegas = _omegas(args)
    for F in args.F:  # every point is checked before anything is built or computed
        for omega in omegas:
            check_point(F, omega)
    engine = DFEngine(args.plant, args.fmus, args.drive, args.samples_per_period)
    results = [engine.point(F, omega, params).as_dict() for F in args.F for omega in omegas]
    if args.json:
        json.dump(results, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(_table(results))
    return 0


def _table(results):
    header = f"{'F':>10} {'omega':>11} {'Re N':>13} {'Im N':>13} {'Re -1/N':>13} {'Im -1/N':>13} {'periodic':>8} {'periods':>7} {'ms':>8}  note"
    lines = [header]
    for r in results:
        inv = ("", "") if r["minus_inv_N_re"] is None else (f"{r['minus_inv_N_re']:13.6g}", f"{r['minus_inv_N_im']:13.6g}")
        lines.append(f"{r['F']:10.4g} {r['omega']:11.5g} {r['N_re']:13.6g} {r['N_im']:13.6g} {inv[0]:>13} {inv[1]:>13} "
                     f"{str(r['periodic']):>8} {r['periods']:7d} {r['seconds'] * 1e3:8.2f}  {r['note']}")
    return "\n".join(lines)


def cmd_sweep(args):
    from .sweep import grid, run_sweep

    points = grid(args.F, _omegas(args), _assignments(args.set, "--set"), _grid_values(args.grid))
    rows = run_sweep(args.plant, points, args.out, args.jobs, args.drive, args.samples_per_period, args.fmus,
                     progress=not args.quiet, resume=not args.no_resume)
    print(f"{len(rows)} points in {args.out}/results.csv and results.json")
    return 0


def cmd_paper(args):
    from .paper import run_paper

    run_paper(args.out, args.jobs, args.fmus, progress=not args.quiet)
    return 0


def cmd_demo(args):
    from .demo import run_demo

    run_demo(_fmus(args.fmus), args.out)
    return 0


def parser():
    top = argparse.ArgumentParser(prog="dfwb", description="Describing-function workbench for friction and backlash.")
    commands = top.add_subparsers(dest="command", required=True)

    build = commands.add_parser("build", help="build the plant FMUs (skips those whose sources are unchanged)")
    build.add_argument("--out", type=Path, default=DEFAULT_FMU_DIR, help="output folder (default: %(default)s)")
    build.add_argument("--force", action="store_true", help="rebuild even if up to date")
    build.set_defaults(run=cmd_build)

    def point_options(command):
        command.add_argument("plant", choices=PLANT_NAMES, help="the plant")
        command.add_argument("--F", type=float, nargs="+", required=True, help="force amplitudes [N]")
        command.add_argument("--omega", type=float, nargs="+", help="frequencies [rad/s]")
        command.add_argument("--omega-log", type=float, nargs=3, metavar=("LO", "HI", "N"),
                             help="N log-spaced frequencies from LO to HI")
        command.add_argument("--set", nargs="+", metavar="NAME=VALUE", help="plant parameters (e.g. eps=0.2)")
        command.add_argument("--drive", choices=("internal", "input"), default="internal",
                             help="internal: the FMU's exact built-in excitation; input: the sine sampled by the "
                                  "master into the input f, held over each step (default: %(default)s)")
        command.add_argument("--samples-per-period", type=int, default=64,
                             help="communication steps per period with --drive input (default: %(default)s)")
        command.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")

    df = commands.add_parser("df", help="describing function N(F, omega) of a plant, one point per (F, omega)")
    point_options(df)
    df.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    df.set_defaults(run=cmd_df)

    sweep = commands.add_parser("sweep", help="a resumable parallel sweep of DF points, written to a folder")
    point_options(sweep)
    sweep.add_argument("--grid", nargs="+", metavar="NAME=V1,V2", help="plant parameters to sweep")
    sweep.add_argument("--out", type=Path, required=True, help="result folder (resumed if it holds this sweep)")
    sweep.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    sweep.add_argument("--no-resume", action="store_true", help="start over instead of resuming")
    sweep.add_argument("--quiet", action="store_true", help="no progress bar")
    sweep.set_defaults(run=cmd_sweep)

    paper = commands.add_parser("paper", help="reproduce the paper's figures 3-6 and 8-12 and write report.md")
    paper.add_argument("--out", type=Path, default=Path("out/paper"), help="output folder (default: %(default)s)")
    paper.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    paper.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")
    paper.add_argument("--quiet", action="store_true", help="no progress bars")
    paper.set_defaults(run=cmd_paper)

    demo = commands.add_parser("demo", help="drive each FMU with a sine through fmpy and plot the response")
    demo.add_argument("--out", type=Path, default=Path("out"), help="output folder (default: %(default)s)")
    demo.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")
    demo.set_defaults(run=cmd_demo)
    return top


def main(argv=None):
    from dfwb.fmus.piecewise import PlantError

    top = parser()
    args = top.parse_args(argv)
    try:
        return args.run(args)
    except (InputError, PlantError, ValueError) as error:
        top.exit(2, f"dfwb {args.command}: error: {error}\n")
    except KeyboardInterrupt:
        top.exit(130, f"dfwb {args.command}: interrupted\n")


if __name__ == "__main__":
    sys.exit(main())
