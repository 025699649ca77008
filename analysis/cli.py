"""The ``dfwb`` command line.

Bad input (an unknown plant or parameter, F <= 0, omega <= 0, NaN, a value
out of the plant's range) is one line on stderr and exit code 2, before
anything is computed or written.
"""

import argparse
import json
import signal
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


def cmd_limit_cycle(args):
    from .limit_cycles import check_range, search
    from .plants import plant
    from .transfer import from_coefficients, parse_transfer_function

    if (args.G is None) == (args.num is None):
        raise InputError("give the controller either as --G EXPR or as --num ... --den ...")
    G = parse_transfer_function(args.G) if args.G is not None else from_coefficients(args.num, args.den or [])
    params = plant(args.plant).check(_assignments(args.set, "--set"))
    F_range = check_range("--F-range", args.F_range)
    omega_range = check_range("--omega-range", args.omega_range)
    from .describing import DFEngine

    engine = DFEngine(args.plant, args.fmus)
    cycles, F_grid, omega_grid, N_grid = search(args.plant, G, params, F_range, omega_range, engine=engine,
                                                progress=not args.json)
    report = {"plant": args.plant, "G": {"num": [float(c) for c in G.num[0][0]],
                                         "den": [float(c) for c in G.den[0][0]]},
              "params": params, "predictions": [c.as_dict() for c in cycles]}
    runs = []
    if args.verify:
        from .closed_loop import verify

        report["verification"] = []
        for cycle in cycles:
            outcome, run = verify(args.plant, G, cycle, params, args.samples_per_period, fmu_dir=args.fmus)
            report["verification"].append(outcome)
            runs.append((cycle, run))
    if args.plot:
        from .plots import limit_cycle_figure

        limit_cycle_figure(Path(args.plot), G, F_grid, omega_grid, N_grid, cycles, runs)
    if args.json:
        json.dump(report, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(f"{len(cycles)} limit cycle(s) of {args.plant} under G(s) in F {F_range}, omega {omega_range}")
        for i, c in enumerate(cycles):
            line = (f"  F = {c.F:.8g} N, omega = {c.omega:.8g} rad/s, period {c.period:.6g} s, amplitude "
                    f"{c.amplitude_x:.6g}, {'stable' if c.stable else 'unstable'}, distortion {c.distortion:.3g}")
            if args.verify:
                v = report["verification"][i]
                line += (f"\n    judge: {'settled' if v['settled'] else 'NOT settled'} at F = {v['F']:.6g}, "
                         f"omega = {v['omega']:.6g} (errors {v['rel_error_F']:.2%}, {v['rel_error_omega']:.2%})")
            print(line)
    return 0


def cmd_examples(args):
    from .examples import run_examples

    run_examples(args.out, args.samples_per_period)
    return 0


def cmd_bench(args):
    from .bench import run_bench

    path = run_bench(args.out, quick=args.quick)
    print(f"{path} written")
    return 0


def cmd_stress(args):
    from .stress import run_stress

    if not 1 <= args.part <= args.parts:
        raise InputError(f"--part {args.part} of --parts {args.parts}: expected 1 <= PART <= PARTS")
    outcome = run_stress(quick=args.quick, progress=not args.json, part=args.part - 1, parts=args.parts)
    if args.json:
        json.dump(outcome, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        print(f"{outcome['cases']} cases, {outcome['failed']} failed, {outcome['seconds']:.1f} s")
        for failure in outcome["failures"]:
            print(f"  {failure['case']}: {failure['check']} ({failure.get('detail', '')})")
    return 0 if outcome["failed"] == 0 else 1


def _cache(args):
    return False if args.no_cache else (args.cache or True)


def cmd_run(args):
    from .runner import run_scene
    from .scene import load_scene

    scenes = [(path, load_scene(path)) for path in args.scenes]  # every scene is checked before any runs
    for path, scene in scenes:
        single = len(args.scenes) == 1 and args.out
        out = args.out if single else (args.out or Path("out/scenes")) / path.stem
        o = run_scene(scene, out, args.jobs, args.dask, _cache(args), args.fmus, progress=not args.quiet)
        if o.up_to_date:
            print(f"{o.out_dir}/summary.md: up to date ({o.points} points, {len(o.figures)} figure(s)), "
                  f"{o.seconds:.2f} s")
        else:
            print(f"{o.out_dir}/summary.md: {o.points} points ({o.computed} computed, {o.cache_hits} cached, "
                  f"{o.resumed} resumed), {len(o.figures)} figure(s), {o.seconds:.1f} s")
    return 0


def cmd_paper(args):
    from .paper import run_paper

    run_paper(args.out, args.jobs, args.fmus, progress=not args.quiet, cache=_cache(args), dask=args.dask)
    return 0


def cmd_demo(args):
    from .demo import run_demo

    run_demo(_fmus(args.fmus), args.out)
    return 0


def parser():
    top = argparse.ArgumentParser(prog="dfwb", description="Describing-function workbench for friction and backlash.")
    commands = top.add_subparsers(dest="command", required=True)

    build = commands.add_parser("build", help="build the FMUs, plants and controller (skips those whose sources are unchanged)")
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

    cycle = commands.add_parser("limit-cycle", help="predict (and verify) limit cycles under a controller G(s)")
    cycle.add_argument("plant", choices=PLANT_NAMES, help="the plant")
    cycle.add_argument("--G", help="controller as an expression in s, e.g. '100*(s+1)/(s+10)'")
    cycle.add_argument("--num", type=float, nargs="+", help="controller numerator coefficients, highest power first")
    cycle.add_argument("--den", type=float, nargs="+", help="controller denominator coefficients")
    cycle.add_argument("--set", nargs="+", metavar="NAME=VALUE", help="plant parameters")
    cycle.add_argument("--F-range", type=float, nargs=2, default=(0.1, 1000.0), metavar=("LO", "HI"),
                       help="force amplitudes searched [N] (default: %(default)s)")
    cycle.add_argument("--omega-range", type=float, nargs=2, default=(0.05, 100.0), metavar=("LO", "HI"),
                       help="frequencies searched [rad/s] (default: %(default)s)")
    cycle.add_argument("--verify", action="store_true", help="check each cycle by closed-loop co-simulation")
    cycle.add_argument("--samples-per-period", type=int, default=512,
                       help="co-simulation steps per predicted period with --verify (default: %(default)s)")
    cycle.add_argument("--plot", help="write the Nyquist (and time-response) figure to this PNG")
    cycle.add_argument("--json", action="store_true", help="print one JSON object")
    cycle.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")
    cycle.set_defaults(run=cmd_limit_cycle)

    examples = commands.add_parser("examples", help="the shipped limit-cycle examples, predicted, judged and plotted")
    examples.add_argument("--out", type=Path, default=Path("out/examples"), help="output folder (default: %(default)s)")
    examples.add_argument("--samples-per-period", type=int, default=512,
                          help="co-simulation steps per predicted period (default: %(default)s)")
    examples.set_defaults(run=cmd_examples)

    bench = commands.add_parser("bench", help="run time against error of every method (Pareto plots, bench.md)")
    bench.add_argument("--quick", action="store_true", help="the quick set (under 3 minutes)")
    bench.add_argument("--out", type=Path, default=Path("out/bench"), help="output folder (default: %(default)s)")
    bench.set_defaults(run=cmd_bench)

    stress = commands.add_parser("stress", help="the numerical stress suite: invariants at the edges")
    stress.add_argument("--quick", action="store_true", help="the quick set (at least 50 cases, under 2 minutes)")
    stress.add_argument("--json", action="store_true", help="print one JSON object (cases, failed, failures)")
    stress.add_argument("--part", type=int, default=1, help="run only this piece of the set (default: %(default)s)")
    stress.add_argument("--parts", type=int, default=1, help="split the set into this many pieces (default: 1)")
    stress.set_defaults(run=cmd_stress)

    def scene_options(command):
        command.add_argument("--jobs", type=int, default=None,
                             help="worker processes, or Dask workers with --dask local (default: all cores)")
        command.add_argument("--dask", metavar="ADDRESS|local",
                             help="compute on a dask.distributed scheduler (tcp://host:8786), or on a LocalCluster")
        command.add_argument("--cache", type=Path, metavar="DIR",
                             help="cache folder (default: $XDG_CACHE_HOME/dfwb, else ~/.cache/dfwb)")
        command.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
        command.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")
        command.add_argument("--quiet", action="store_true", help="no progress display")

    run = commands.add_parser("run", help="run scene files: only what each needs, cached, resumable")
    run.add_argument("scenes", type=Path, nargs="+", metavar="SCENE.toml", help="scene file(s), e.g. scenes/*.toml")
    run.add_argument("--out", type=Path, help="output folder (default: out/scenes/<scene>; with several scenes, "
                                              "one subfolder each)")
    scene_options(run)
    run.set_defaults(run=cmd_run)

    paper = commands.add_parser("paper", help="run the paper's scenes (figures 3-6, 8-12) and write report.md")
    paper.add_argument("--out", type=Path, default=Path("out/paper"), help="output folder (default: %(default)s)")
    scene_options(paper)
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
    previous = signal.signal(signal.SIGTERM, _interrupt)  # kill: stop the workers and keep what is done
    try:
        return args.run(args)
    except (InputError, PlantError, ValueError, RuntimeError) as error:
        top.exit(2, f"dfwb {args.command}: error: {error}\n")
    except OSError as error:
        top.exit(2, f"dfwb {args.command}: error: {error.filename or ''}: {error.strerror or error}\n")
    except KeyboardInterrupt:
        top.exit(130, f"dfwb {args.command}: interrupted\n")
    finally:
        signal.signal(signal.SIGTERM, previous)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


if __name__ == "__main__":
    sys.exit(main())
