"""The ``dfwb`` command line.

Bad input (an unknown plant or parameter, a value out of the range the
engine accepts, NaN, a malformed option) is one line on stderr and exit
code 2, before anything is computed or written. Repeated options accumulate
(``--set eps=0.2 --set h=0.05`` sets both; ``--F 10 --F 20`` gives two
forces); a name or a single-valued option given twice with two different
values is an error, never a silent choice of the last.
"""

import argparse
import json
import os
import sys
import traceback
import warnings
from pathlib import Path

from dfwb.base.defaults import BRANCH_POINTS, DF_MAP_SIZE, JUDGE_SAMPLES, K_COUNT, K_RANGE, SAMPLES_PER_PERIOD
from dfwb.base.errors import InputError, RunError
from dfwb.base.values import decimal, short, whole

EXAMPLES = {  # one runnable example per subcommand, shown at the end of its --help
    "build": "dfwb build --native --fmi-version 3 --out out/fmus",
    "info": "dfwb info out/fmus/TwoMassBacklash.fmu",
    "df": "dfwb df friction --F 10 20 --omega 1",
    "sweep": "dfwb sweep backlash --F 20 50 --omega-log 1 100 20 --grid eps=0.2,0.8 --out out/sweep --plot",
    "limit-cycle": "dfwb limit-cycle friction --G 'Kp + Ki/s' --set Kp=10 Ki=2 --exact --plot out/lc.png",
    "continue": "dfwb continue friction --G 'Kp + Ki/s' --set Kp=10 --parameter Ki=1:30 --plot out/branch.png",
    "map": "dfwb map friction --G 'Kp + Ki/s' --x Kp=1:50:8 --y Ki=0.1:25:8 --out out/map",
    "margin": "dfwb margin friction --G '20 + 100/s + 2*s/(0.1*s+1)'",
    "tune": "dfwb tune friction --G 'Kp + Ki/s' --compensate deadband --free Kp=2:50 Ki=0.2:10 d=0.01:0.5 "
            "--tolerance 0.1 --robust Fc=0.2 Fs=0.1",
    "examples": "dfwb examples --out out/examples",
    "bench": "dfwb bench --quick --out out/bench",
    "stress": "dfwb stress --quick",
    "run": "dfwb run scenes/fig08_backlash_nyquist_eps.toml --out out/fig08",
    "paper": "dfwb paper --out out/paper",
    "demo": "dfwb demo --out out",
}


def _fmu_dir_help():
    """The FMU folder as it will be used here, and the rule that chose it."""
    from dfwb.fmi.location import default_fmu_dir

    return f"{default_fmu_dir()}: $DFWB_FMU_DIR, else $XDG_CACHE_HOME/dfwb/fmus, else ~/.cache/dfwb/fmus"


def _cache_dir_help():
    from dfwb.base.files import user_cache_dir

    return f"{user_cache_dir()}: $XDG_CACHE_HOME/dfwb, else ~/.cache/dfwb"
FIGURE_COMMANDS = {"sweep", "limit-cycle", "continue", "map", "margin", "examples", "bench", "run", "paper", "demo"}
PLOT_COMMANDS = {"sweep", "limit-cycle", "continue", "margin"}  # they draw only with --plot




class _Parser(argparse.ArgumentParser):
    """argparse with its errors in one line (``dfwb df: error: ...``), exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


class _Commands:
    """The subcommands: each with its one-line help as its description and a runnable example at the end."""

    def __init__(self, subparsers):
        self._subparsers = subparsers

    def add_parser(self, name, help):
        description = help[0].upper() + help[1:] + "."
        return self._subparsers.add_parser(name, help=help, description=description,
                                           epilog=f"example:\n  {EXAMPLES[name]}",
                                           formatter_class=argparse.RawDescriptionHelpFormatter)


class _Once(argparse.Action):
    """A single-valued option: given twice with two values is an error, not a silent choice of the last."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = namespace.__dict__.setdefault("_given", {})
        if self.dest in seen and seen[self.dest] != values:
            parser.error(f"{option_string} given twice ({_shown(seen[self.dest])} and {_shown(values)}): give it once")
        seen[self.dest] = values
        setattr(namespace, self.dest, values)


def _shown(values):
    return " ".join(map(str, values)) if isinstance(values, (list, tuple)) else str(values)


def _integer(lo, hi):
    """An argparse type: an integer in [lo, hi]."""

    def convert(text):
        try:
            value = whole(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{short(text)} is not an integer") from None
        except OverflowError:
            raise argparse.ArgumentTypeError(f"{short(text)} is out of range: an integer from {lo} to {hi}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{value} is out of range: an integer from {lo} to {hi}")
        return value

    return convert


def _real(text):
    """An argparse type: a number in its plain decimal form (not '1_0', which Python's float reads as 10)."""
    try:
        return decimal(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _named(what):
    """An argparse type for an option that names something: an empty (or blank) value is refused, not read as
    the current folder ('' is '.' to pathlib) nor as the option not given."""

    def convert(text):
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{text!r} is empty: give {what}")
        return text

    return convert


def _folder(text):
    """A folder option (--out, --cache, --fmus): a path, never empty."""
    return Path(_named("a folder (. for the current one)")(text))


_PNG = _named("a file name ending in .png")  # --plot


def _jobs(text):
    """--jobs: an integer within the executor's bound (imported only when the option is given)."""
    from dfwb.studies.executor import MAX_JOBS

    return _integer(1, MAX_JOBS)(text)


def _assignments(items, option):
    """{name: value} from NAME=VALUE words; a name given twice with two values is an error."""
    values = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE")
        if name in values and values[name] != value:
            raise InputError(f"{option} {name} given twice ({values[name]} and {value}): give it once")
        values[name] = value
    return values


def _number(text, what):
    try:
        return decimal(text)
    except ValueError as error:
        raise InputError(f"{what} = {error}") from None


def _grid_values(items):
    """{name: [values]} from NAME=V1,V2,... words."""
    return {name: [_number(v, f"--grid {name}") for v in text.split(",")]
            for name, text in _assignments(items, "--grid").items()}


def _omegas(args):
    from dfwb.engine.describing import OMEGA_RANGE
    from dfwb.studies.sweep import MAX_POINTS

    if args.omega_log and args.omega:
        raise InputError("give either --omega W [W ...] or --omega-log LO HI N, not both")
    if args.omega_log:
        lo, hi, n = args.omega_log
        if not (OMEGA_RANGE[0] <= lo < hi <= OMEGA_RANGE[1] and 2 <= n <= MAX_POINTS and n == int(n)):
            raise InputError(f"--omega-log {lo:g} {hi:g} {n:g}: expected {OMEGA_RANGE[0]:g} <= LO < HI <= "
                             f"{OMEGA_RANGE[1]:g} rad/s and an integer N from 2 to {MAX_POINTS}")
        from dfwb.base.grids import log_grid

        return log_grid(lo, hi, n)
    if not args.omega:
        raise InputError("give --omega W [W ...] or --omega-log LO HI N")
    return args.omega


def _points(args):
    """(forces, frequencies), each checked against the engine's ranges before anything runs."""
    from dfwb.engine.describing import check_force, check_frequency
    from dfwb.studies.sweep import check_size, grid_size

    omegas = _omegas(args)
    check_size(grid_size(len(args.F), len(omegas)), "the grid")
    for F in args.F:
        check_force(F)
    for omega in omegas:
        check_frequency(omega)
    return args.F, omegas


def _fmus(out_dir):
    from dfwb.fmi.location import build_fmus

    return {path.stem: path for path in build_fmus(out_dir, report=lambda message: None)}


def cmd_info(args):
    from dfwb.foreign.description import describe

    info = describe(args.fmu)
    print(f"{info.model_name}: FMI {info.fmi_version}, {' and '.join(info.kinds)} (runs here; the first is used)")
    print(f"  continuous Real inputs (--input): {', '.join(info.real_inputs()) or 'none'}")
    print(f"  Real outputs (--output): {', '.join(info.real_outputs()) or 'none'}")
    if info.parameters:
        print("  parameters (--set NAME=VALUE):")
        width = max(len(name) for name in info.parameters)
        for p in info.parameters.values():
            limits = f"[{p.min:g}, {p.max:g}]" if (p.min, p.max) != (-float("inf"), float("inf")) else ""
            print(f"    {p.name:<{width}}  {p.type:<7} {p.start:<12g} {p.unit or '-':<8} {limits:<18} "
                  f"{p.description}".rstrip())
    else:
        print("  parameters: none")
    return 0


def cmd_build(args):
    """Build the production FMUs (the registry's plants, LinearSystem and the exact closed loops); ``--naive``: the
    plants' fixed-step twins too."""
    from dfwb.fmi.location import NATIVE_FMI3_FOLDER, NATIVE_FOLDER, build_fmus, fmu_folder

    if args.native:
        from dfwb.build_fmus.native import build_native

        if args.naive:
            raise InputError("--native and --naive: the naive twins exist only as pythonfmu FMUs")
        default = fmu_folder() / (NATIVE_FMI3_FOLDER if args.fmi_version == 3 else NATIVE_FOLDER)
        build_native(args.out if args.out is not None else default, force=args.force, fmi_version=args.fmi_version,
                     reuse=default)  # built there already: copied
        return 0
    if args.fmi_version == 3:
        raise InputError("--fmi-version 3 needs --native: the FMI 3.0 FMUs are the native plant FMUs")
    build_fmus(args.out, naive=args.naive, force=args.force)
    return 0


def _own_fmu(args):
    """The user's FMU named as the plant (--input, --output, --kind), or None for a built-in plant."""
    from dfwb.foreign.plant import fmu_plant, is_fmu_path

    if not is_fmu_path(args.plant):
        given = [f"--{name}" for name in ("input", "output", "kind") if getattr(args, name, None) is not None]
        if given:
            raise InputError(f"{', '.join(given)}: only for a plant given as the path of an FMU")
        return None
    return fmu_plant(args.plant, input=args.input, output=args.output, kind=args.kind)


def _plant(args):
    """The plant to hand to :mod:`dfwb.api`: a registered plant's name, or the user's FMU (--input, --output,
    --kind)."""
    return _own_fmu(args) or args.plant


def _params(args, function):
    """--set's {name: value}; a name that is one of ``function``'s own keywords cannot be a parameter there, and
    says so (``rtol`` is --rtol's, which sets the Stribeck mass's tolerance as it sets a user's FMU's)."""
    import inspect

    values = _assignments(args.set, "--set")
    taken = sorted(set(values) & set(inspect.signature(function).parameters))
    if taken:
        name = taken[0]
        option = {"rtol": "--rtol", "timeout": "--timeout"}.get(name)
        raise InputError(f"--set {name}={values[name]}: " + (f"give it as {option} {values[name]}" if option else
                         f"{name} is a setting of dfwb itself here (dfwb.{function.__name__}'s), not a parameter of "
                         "G or of the plant"))
    return values


def cmd_df(args):
    import numpy as np

    from dfwb.api.functions import describing_function

    params = _params(args, describing_function)
    forces, omegas = _points(args)
    response = describing_function(_plant(args), np.array(forces)[:, None], np.array(omegas)[None, :],
                                   drive=args.drive, samples_per_period=args.samples_per_period, fmu_dir=args.fmus,
                                   rtol=args.rtol, timeout=args.timeout, **params)
    results = response.points
    failed = [r for r in results if r["note"].startswith("failed:")]
    if args.json:
        _json(results)
    else:
        print(_table(results))
    if failed:
        raise RunError(failed[0]["note"].removeprefix("failed: ") +
                       (f" (and {len(failed) - 1} more points failed)" if len(failed) > 1 else ""))
    return 0


def _table(results):
    estimated = any(r.get("N_error") is not None for r in results)
    header = (f"{'F [N]':>10} {'omega [rad/s]':>13} {'Re N [m/N]':>13} {'Im N [m/N]':>13} "
              + (f"{'|error| [m/N]':>13} " if estimated else "")
              + f"{'Re -1/N [N/m]':>13} {'Im -1/N [N/m]':>13} {'periodic':>8} {'periods':>7} {'time [ms]':>9}  note")
    lines = [header]
    for r in results:
        inv = ("", "") if r["minus_inv_N_re"] is None else \
            (f"{r['minus_inv_N_re']:13.6g}", f"{r['minus_inv_N_im']:13.6g}")
        error = f"{r['N_error']:13.2g} " if estimated else ""
        lines.append(f"{r['F']:10.4g} {r['omega']:13.5g} {r['N_re']:13.6g} {r['N_im']:13.6g} {error}{inv[0]:>13} "
                     f"{inv[1]:>13} {str(r['periodic']):>8} {r['periods']:7d} {r['seconds'] * 1e3:9.2f}  "
                     f"{r['note']}".rstrip())
    return "\n".join(lines)


def cmd_sweep(args):
    from dfwb.api.studies import grid, sweep

    params = _params(args, sweep)
    grids = _grid_values(args.grid)
    both = sorted(set(params) & set(grids))
    if both:
        raise InputError(f"{both[0]} is given both by --set and by --grid: give it in one of them")
    forces, omegas = _points(args)
    cache = _cache(args)
    rows = sweep(_plant(args), grid(forces, omegas, params, grids), args.out, jobs=args.jobs, drive=args.drive,
                 samples_per_period=args.samples_per_period, fmu_dir=args.fmus, progress=not args.quiet,
                 resume=not args.no_resume, rtol=args.rtol, timeout=args.timeout, cache=cache)
    failed = [r for r in rows if r["note"].startswith("failed:")]
    png = rows.figure(args.out / "nyquist.png") if args.plot and rows.drawable() else None
    print(f"{len(rows)} points in {args.out}/results.csv and results.json ({rows.computed} computed, "
          f"{rows.cached} from the cache, {rows.resumed} resumed)"
          + (f"; {len(failed)} failed (kept out of results.csv: a resumed sweep computes them again)"
             if failed else "")
          + (f"; the -1/N curves in {png} and .svg" if png else ""))
    if args.plot and png is None:  # the results are written: only the figure is missing
        raise RunError(f"--plot: no point has a finite -1/N (N = 0, or the point failed, at every one): no curves "
                       f"to draw; the results are in {args.out}")
    return 0


def _controller(args):
    """The controller as the user gave it: an expression (its parameters set by --set), or --num/--den."""
    from dfwb.engine.transfer import from_coefficients

    if args.den is not None and args.num is None:  # --G or --num: the parser requires one of them
        raise InputError("--den goes with --num: give the controller as --G EXPR or as --num ... --den ...")
    return args.G if args.G is not None else from_coefficients(args.num, args.den or [])


def cmd_limit_cycle(args):
    from dfwb.api.functions import limit_cycles

    plot = _plot_path(args.plot) if args.plot else None
    n_F, n_omega = args.map_size or (None, None)  # None: the DF's own size
    response = limit_cycles(_plant(args), _controller(args), F_range=args.F_range, omega_range=args.omega_range,
                            n_F=n_F, n_omega=n_omega, exact=args.exact, verify=args.verify,
                            samples_per_period=args.samples_per_period, fmu_dir=args.fmus, progress=not args.json,
                            rtol=args.rtol, timeout=args.timeout, compensate=args.compensate,
                            **_params(args, limit_cycles))
    return _answer(args, response, plot)


def _json(document):
    """``document`` on stdout as strict JSON: a number that is not finite (a failed point's N) is null."""
    from dfwb.studies.cache import finite

    json.dump(finite(document), sys.stdout, indent=1, allow_nan=False)
    sys.stdout.write("\n")


def _answer(args, response, plot=None):
    """What an analysis command prints: its figure written to ``plot``, then JSON (--json) or its summary."""
    if plot:
        response.figure(plot)
    if args.json:
        _json(response.as_dict())
    else:
        print(response.summary())
    return 0


def _range(text, option):
    """NAME=START:STOP of --parameter and --free (LO:HI), NAME=START:STOP:N of --x and --y."""
    name, sep, rest = text.partition("=")
    parts = rest.split(":")
    if not sep or not name or len(parts) != (3 if option in ("--x", "--y") else 2):
        raise InputError(f"{option} {text!r}: expected NAME=" + ("LO:HI" if option == "--free" else "START:STOP")
                         + (":N" if option in ("--x", "--y") else ""))
    return name, [_number(part, f"{option} {name}") for part in parts]


def cmd_continue(args):
    from dfwb.api.functions import continuation

    plot = _plot_path(args.plot) if args.plot else None
    name, bounds = _range(args.parameter, "--parameter")
    sources = ("truth", "df") if args.source == "both" else (args.source,)
    own, ranges = _own_fmu_ranges(args)
    if args.samples is not None:
        if own is None:
            raise InputError("--samples: only for a plant given as the path of an FMU (dfwb's own plants' cycles "
                             "are continued, not sampled)")
        ranges["samples"] = args.samples
    response = continuation(own or args.plant, _controller(args), name, *bounds, sources=sources,
                            max_points=args.max_points, fmu_dir=args.fmus, progress=not args.json, **ranges,
                            compensate=args.compensate, **_params(args, continuation))
    return _answer(args, response, plot)


def cmd_map(args):
    from dfwb.api.functions import hunting_map

    axes = []
    for option, text in (("--x", args.x), ("--y", args.y)):
        name, parts = _range(text, option)
        if len(parts) != 3 or not parts[2].is_integer():
            raise InputError(f"{option} {text!r}: expected NAME=START:STOP:N with N a whole number of cells")
        axes.append((name, parts[0], parts[1], int(parts[2])))
    own, ranges = _own_fmu_ranges(args)
    name = Path(args.plant).stem if own is not None else args.plant
    out = args.out or Path("out/maps") / f"{name}_{axes[0][0]}_{axes[1][0]}"
    response = hunting_map(own or args.plant, _controller(args), *axes, out_dir=out, jobs=args.jobs, dask=args.dask,
                           cache=_cache(args), fmu_dir=args.fmus, curves=not args.no_curves,
                           resume=not args.no_resume, progress=not (args.json or args.quiet), **ranges,
                           compensate=args.compensate, **_params(args, hunting_map))
    return _answer(args, response)


def cmd_margin(args):
    from dfwb.api.functions import limit_cycle_margin

    plot = _plot_path(args.plot) if args.plot else None
    own, ranges = _own_fmu_ranges(args)
    response = limit_cycle_margin(own or args.plant, _controller(args), k_range=tuple(args.k_range),
                                  count=args.count, fmu_dir=args.fmus, progress=not args.json, **ranges,
                                  compensate=args.compensate, **_params(args, limit_cycle_margin))
    return _answer(args, response, plot)


def cmd_tune(args):
    from dfwb.api.functions import tune

    plot = _plot_path(args.plot) if args.plot else None
    free = {}
    for text in args.free:
        name, bounds = _range(text, "--free")
        if name in free:
            raise InputError(f"--free {name} given twice: give it once")
        free[name] = tuple(bounds)
    robust = {name: _number(value, f"--robust {name}") for name, value in _assignments(args.robust, "--robust").items()}
    response = tune(args.plant, _controller(args), free=free, compensate=args.compensate, tolerance=args.tolerance,
                    robust=robust, count=args.count, fmu_dir=args.fmus, progress=not args.json,
                    **_params(args, tune))
    return _answer(args, response, plot)


def _own_fmu_ranges(args):
    """(the user's FMU or None, the keywords of its DF map and driver) of ``map`` and ``margin``."""
    own = _own_fmu(args)
    if own is None:
        if (args.F_range, args.omega_range, args.map_size) != (None, None, None):
            raise InputError("--F-range, --omega-range, --map-size: only for a plant given as the path of an FMU "
                             "(dfwb's own plants derive their ranges)")
        return None, {"rtol": args.rtol, "timeout": args.timeout}
    ranges = {"F_range": args.F_range, "omega_range": args.omega_range, "rtol": args.rtol, "timeout": args.timeout}
    if args.map_size:
        ranges.update(n_F=args.map_size[0], n_omega=args.map_size[1])
    return own, ranges


def _plot_path(text):
    """The --plot file, checked before anything is computed: a .png in a folder that exists."""
    path = Path(text)
    if text.endswith(("/", os.sep)) or path.suffix.lower() != ".png" or path.name in (".png", ""):
        raise InputError(f"--plot {text}: expected a file name ending in .png (the SVG is written beside it)")
    if path.is_dir():
        raise InputError(f"--plot {text} is a folder: give a file name ending in .png")
    if not path.parent.is_dir():
        raise InputError(f"--plot {text}: the folder {path.parent} does not exist")
    return path


def cmd_examples(args):
    from dfwb.studies.examples import run_examples

    run_examples(args.out, args.samples_per_period, fmu_dir=args.fmus)
    return 0


def cmd_bench(args):
    from dfwb.verify.bench import run_bench

    path = run_bench(args.out, quick=args.quick, fmu_dir=args.fmus)
    print(f"{path} written")
    return 0


def cmd_stress(args):
    from dfwb.verify.stress import run_stress

    if not 1 <= args.part <= args.parts:
        raise InputError(f"--part {args.part} of --parts {args.parts}: expected 1 <= PART <= PARTS")
    outcome = run_stress(quick=args.quick, progress=not args.json, part=args.part - 1, parts=args.parts)
    if args.json:
        _json(outcome)
    else:
        print(f"{outcome['cases']} cases, {outcome['failed']} failed, {outcome['seconds']:.1f} s")
        for failure in outcome["failures"]:
            print(f"  {failure['case']}: {failure['check']} ({failure.get('detail', '')})")
    return 0 if outcome["failed"] == 0 else 1


def _cache(args):
    if args.no_cache and args.cache:
        raise InputError("give --cache DIR or --no-cache, not both")
    return False if args.no_cache else (args.cache or True)


def cmd_run(args):
    from dfwb.api.studies import run_scene
    from dfwb.base.files import UnsafePath, inside
    from dfwb.studies.runner import phase_times
    from dfwb.studies.scene import load_scene

    scenes = [(path, load_scene(path)) for path in args.scenes]  # every scene is checked before any runs
    folders = {}
    for path, _ in scenes:
        try:
            out = args.out if len(args.scenes) == 1 and args.out else inside(args.out or Path("out/scenes"), path.stem)
        except UnsafePath:
            raise InputError(f"{path}: the file name {path.stem!r} cannot name an output folder "
                             "(letters, digits, _ . + - and no leading dot)") from None
        if out in folders:
            raise InputError(f"{folders[out]} and {path} would both write to {out}: rename one, or run them "
                             "separately with --out")
        folders[out] = path
    for (path, scene), out in zip(scenes, folders):
        o = run_scene(scene, out, jobs=args.jobs, dask=args.dask, cache=_cache(args), fmu_dir=args.fmus,
                      progress=not args.quiet)
        if o.up_to_date or o.copied:
            how = "up to date" if o.up_to_date else "copied from the cache (the same scene, code and FMUs)"
            print(f"{o.out_dir}/summary.md: {how} ({o.points} points, {len(o.figures)} figure(s)), {o.seconds:.2f} s")
        else:
            df_hits = o.points - o.computed - o.resumed  # o.cache_hits also counts traces and judge runs
            others = o.cache_hits - df_hits
            print(f"{o.out_dir}/summary.md: {o.points} points ({o.computed} computed, {df_hits} cached, "
                  f"{o.resumed} resumed)" + (f", {others} trace(s) and closed-loop run(s) cached" if others else "")
                  + f", {len(o.figures)} figure(s), {o.seconds:.1f} s ({phase_times(o.phases)})")
    return 0


def cmd_paper(args):
    from dfwb.studies.reproduce import run_paper

    run_paper(args.out, args.jobs, args.fmus, progress=not args.quiet, cache=_cache(args), dask=args.dask)
    return 0


def cmd_demo(args):
    from dfwb.studies.demo import run_demo

    run_demo(_fmus(args.fmus), args.out)
    return 0


def cache_options(command):
    """--cache DIR and --no-cache: the content-addressed cache of computed points, shared by every command."""
    command.add_argument("--cache", action=_Once, type=_folder, metavar="DIR",
                         help=f"cache folder (default: {_cache_dir_help()})")
    command.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")


def fmu_folder_option(command):
    """--fmus DIR: where the FMUs are (built there if missing or stale)."""
    command.add_argument("--fmus", action=_Once, type=_folder, default=None,
                         help=f"FMU folder (default: {_fmu_dir_help()})")


def fmu_options(command):
    """--fmus DIR and --fmu-kind KIND: where dfwb's own FMUs are, and which kind of them runs."""
    fmu_folder_option(command)
    command.add_argument("--fmu-kind", action=_Once, choices=("native", "python"), default=None,
                         help="which of dfwb's own plant FMUs run: native (the C core, no Python inside) or python "
                              "(pythonfmu); the same numbers (default: $DFWB_FMU, else native)")


def parser():
    from dfwb.plants import names

    plant_names = names()
    version = sys.modules[__package__].__version__  # dfwb, loaded with this module (not imported: a higher layer)
    top = _Parser(prog="dfwb", description="Describing-function workbench for friction and backlash: exact DFs, "
                                           "limit cycles and hunting under a controller G(s), the plants as FMUs.",
                  epilog="dfwb COMMAND --help: each command's options and an example.")
    top.add_argument("--version", action="version", version=f"dfwb {version}")
    commands = _Commands(top.add_subparsers(dest="command", required=True, metavar="COMMAND"))

    build = commands.add_parser("build",
                                help="build the FMUs: plants, controller and exact closed loops (skips those "
                                     "whose sources are unchanged)")
    build.add_argument("--out", action=_Once, type=_folder, default=None,
                       help=f"output folder (default: {_fmu_dir_help()}); the native plant FMUs (the kind dfwb runs by "
                            "default) go into its native/")
    build.add_argument("--force", action="store_true", help="rebuild even if up to date")
    build.add_argument("--naive", action="store_true", help="also build the benchmark's fixed-step twins")
    build.add_argument("--native", action="store_true",
                       help="build only the native plant FMUs (C core, no Python needed by the importer; binaries for "
                            "linux64, and win64 where mingw-w64 is installed) into --out (default: the FMU folder's "
                            "native/, or native/fmi3/ for FMI 3.0)")
    build.add_argument("--fmi-version", action=_Once, type=int, choices=(2, 3), default=2,
                       help="FMI version of the native FMUs: 2 (2.0) or 3 (3.0); default: 2")
    build.set_defaults(run=cmd_build)

    info = commands.add_parser("info", help="what your own FMU offers: its inputs, outputs and parameters "
                                            "(units, start values, ranges)")
    info.add_argument("fmu", metavar="PATH.fmu", help="an FMI 2.0 or 3.0 FMU")
    info.set_defaults(run=cmd_info)

    plant_help = f"the plant: {', '.join(plant_names)}, or the path of your own FMU (PATH.fmu)"

    def plant_argument(text):
        if text in plant_names or text.lower().endswith(".fmu"):
            return text
        raise argparse.ArgumentTypeError(f"unknown plant {text!r} (allowed: {', '.join(plant_names)}, "
                                         "or the path of an FMU, PATH.fmu)")

    def own_fmu_options(command):
        command.add_argument("--input", action=_Once, type=_named("the name of a variable"), metavar="NAME",
                             help="your FMU's continuous Real input the force enters (default: its only one)")
        command.add_argument("--output", action=_Once, type=_named("the name of a variable"), metavar="NAME",
                             help="your FMU's Real output whose DF is taken (default: its only one)")
        command.add_argument("--kind", action=_Once, choices=("model-exchange", "co-simulation"), default=None,
                             help="which interface of your FMU runs (default: model exchange if it has it)")
        command.add_argument("--rtol", action=_Once, type=_real, default=None,
                             help="accuracy aimed at with your FMU: the integrator's tolerance for model exchange "
                                  "(default 1e-10), the extrapolated DF's for co-simulation (default 1e-6); with an "
                                  "integrated plant of dfwb's (stribeck), its parameter rtol")
        command.add_argument("--timeout", action=_Once, type=_real, default=None,
                             help="seconds one point of your FMU may take; a point cut is tried once more with twice "
                                  "the limit, then skipped (default: 120 s per 150 periods allowed, and at least 10 "
                                  "times the slowest point so far)")

    def point_options(command):
        command.add_argument("plant", type=plant_argument, metavar="PLANT", help=plant_help)
        command.add_argument("--F", type=_real, nargs="+", action="extend", required=True, help="force amplitudes [N]")
        command.add_argument("--omega", type=_real, nargs="+", action="extend", help="frequencies [rad/s]")
        command.add_argument("--omega-log", action=_Once, type=_real, nargs=3, metavar=("LO", "HI", "N"),
                             help="N log-spaced frequencies from LO to HI")
        command.add_argument("--set", nargs="+", action="extend", metavar="NAME=VALUE",
                             help="plant parameters (e.g. eps=0.2)")
        command.add_argument("--drive", action=_Once, choices=("internal", "input"), default="internal",
                             help="internal: the FMU's exact built-in excitation; input: the sine sampled by the "
                                  "master into the input f, held over each step (default: %(default)s)")
        command.add_argument("--samples-per-period", action=_Once, type=_integer(4, 100_000),
                             default=SAMPLES_PER_PERIOD,
                             help="communication steps per period with --drive input (default: %(default)s)")
        own_fmu_options(command)
        fmu_options(command)

    df = commands.add_parser("df", help="describing function N(F, omega) of a plant, one point per (F, omega)")
    point_options(df)
    df.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    df.set_defaults(run=cmd_df)

    sweep = commands.add_parser("sweep", help="a resumable parallel sweep of DF points, written to a folder")
    point_options(sweep)
    sweep.add_argument("--grid", nargs="+", action="extend", metavar="NAME=V1,V2", help="plant parameters to sweep")
    sweep.add_argument("--out", action=_Once, type=_folder, required=True,
                       help="result folder (resumed if it holds this sweep)")
    sweep.add_argument("--jobs", action=_Once, type=_jobs, default=None, help="worker processes (default: all cores)")
    sweep.add_argument("--no-resume", action="store_true", help="start over instead of resuming")
    sweep.add_argument("--plot", action="store_true",
                       help="draw the -1/N curves (one per force and parameter set) into OUT/nyquist.png and .svg")
    cache_options(sweep)
    sweep.add_argument("--quiet", action="store_true", help="no progress bar")
    sweep.set_defaults(run=cmd_sweep)

    def controller_options(command, own=False):
        if own:
            command.add_argument("plant", type=plant_argument, metavar="PLANT", help=plant_help)
            own_fmu_options(command)
        else:
            command.add_argument("plant", choices=plant_names, help="the plant")
        controller = command.add_mutually_exclusive_group(required=True)
        controller.add_argument("--G", action=_Once, help="controller as an expression in s, its parameters named, "
                                                          "e.g. 'Kp + Ki/s'")
        controller.add_argument("--num", type=_real, nargs="+", action="extend",
                                help="controller numerator coefficients, highest power first (with --den)")
        command.add_argument("--den", type=_real, nargs="+", action="extend",
                             help="controller denominator coefficients")
        command.add_argument("--set", nargs="+", action="extend", metavar="NAME=VALUE",
                             help="parameters of G, of the plant and of the compensators (e.g. Fs=8 Kp=10 for "
                                  "G = 'Kp + Ki/s', F_hat=3 signal=control)")
        command.add_argument("--compensate", nargs="+", action="extend", metavar="NAME",
                             help="compensators between G and the plant, judged by the exact loop with their "
                                  "cost: coulomb (F_hat, signal = velocity or control), deadband (d), reset, "
                                  "dither (a, w_d), backlash-inverse (h_hat)")

    cycle = commands.add_parser("limit-cycle", help="predict (and verify) limit cycles under a controller G(s)")
    controller_options(cycle, own=True)
    cycle.add_argument("--F-range", action=_Once, type=_real, nargs=2, default=None, metavar=("LO", "HI"),
                       help="force amplitudes searched [N] (default: derived from the plant and G)")
    cycle.add_argument("--omega-range", action=_Once, type=_real, nargs=2, default=None, metavar=("LO", "HI"),
                       help="frequencies searched [rad/s] (default: derived from the plant and G)")
    cycle.add_argument("--map-size", action=_Once, type=_integer(2, 1000), nargs=2, default=None,
                       metavar=("N_F", "N_OMEGA"), help="the DF map's points in F and in omega, where the candidates "
                                                        f"are located (default: {DF_MAP_SIZE[0]} {DF_MAP_SIZE[1]}; "
                                                        "4 12 for the dither's DF, whose points cost)")
    cycle.add_argument("--verify", action="store_true", help="check each cycle by closed-loop co-simulation")
    cycle.add_argument("--exact", action="store_true",
                       help="find the true cycles of the exact closed loop (shooting, Floquet stability) and the "
                            "DF's errors against them")
    cycle.add_argument("--samples-per-period", action=_Once, type=_integer(16, 100_000), default=JUDGE_SAMPLES,
                       help="co-simulation steps per predicted period with --verify (default: %(default)s)")
    cycle.add_argument("--plot", action=_Once, type=_PNG,
                       help="write the Nyquist (and time-response) figure to this PNG")
    cycle.add_argument("--json", action="store_true", help="print one JSON object")
    fmu_options(cycle)
    cycle.set_defaults(run=cmd_limit_cycle)

    def scene_options(command):
        command.add_argument("--jobs", action=_Once, type=_jobs, default=None,
                             help="worker processes, or Dask workers with --dask local (default: all cores)")
        command.add_argument("--dask", action=_Once, type=_named("a scheduler's address or local"),
                             metavar="ADDRESS|local",
                             help="compute on a dask.distributed scheduler (tcp://host:8786), or on a LocalCluster")
        cache_options(command)
        fmu_options(command)
        command.add_argument("--quiet", action="store_true", help="no progress display")

    def own_map_options(command):
        command.add_argument("--F-range", action=_Once, type=_real, nargs=2, default=None, metavar=("LO", "HI"),
                             help="your FMU only: the force amplitudes of its DF map [N]")
        command.add_argument("--omega-range", action=_Once, type=_real, nargs=2, default=None, metavar=("LO", "HI"),
                             help="your FMU only: the frequencies of its DF map [rad/s]")
        command.add_argument("--map-size", action=_Once, type=_integer(2, 1000), nargs=2, default=None,
                             metavar=("N_F", "N_OMEGA"), help="your FMU only: its DF map's points in F and in omega "
                                                              f"(default: {DF_MAP_SIZE[0]} {DF_MAP_SIZE[1]})")

    follow = commands.add_parser("continue", help="follow limit cycles in one parameter of G or of the plant: "
                                                 "branches, bifurcations, the diagram")
    controller_options(follow, own=True)
    own_map_options(follow)
    follow.add_argument("--parameter", action=_Once, required=True, metavar="NAME=START:STOP",
                        help="the parameter followed and its range, e.g. Ki=1:30")
    follow.add_argument("--source", action=_Once, choices=("both", "truth", "df"), default="both",
                        help="follow the true cycles, the DF's predictions, or both (default: %(default)s)")
    follow.add_argument("--max-points", action=_Once, type=_integer(2, 10_000), default=BRANCH_POINTS,
                        help="points per branch, at most (default: %(default)s)")
    follow.add_argument("--samples", action=_Once, type=_integer(2, 1000), default=None,
                        help="your FMU only: the values where its true cycles are searched (default: 11)")
    follow.add_argument("--plot", action=_Once, type=_PNG,
                        help="write the bifurcation diagram to this PNG")
    follow.add_argument("--json", action="store_true", help="print one JSON object")
    fmu_options(follow)
    follow.set_defaults(run=cmd_continue)

    hunting = commands.add_parser("map", help="which settings of two parameters make the machine hunt: truth and "
                                              "DF side by side, cached and resumable")
    controller_options(hunting, own=True)
    own_map_options(hunting)
    hunting.add_argument("--x", action=_Once, required=True, metavar="NAME=START:STOP:N",
                         help="the horizontal axis: a parameter of G or of the plant, e.g. Kp=1:50:30")
    hunting.add_argument("--y", action=_Once, required=True, metavar="NAME=START:STOP:N",
                         help="the vertical axis, e.g. Ki=0.1:25:30")
    hunting.add_argument("--out", action=_Once, type=_folder,
                         help="output folder (default: out/maps/<plant>_<x>_<y>); resumed if it holds this map")
    hunting.add_argument("--no-resume", action="store_true", help="start over instead of resuming")
    hunting.add_argument("--no-curves", action="store_true", help="skip the bifurcation curves")
    hunting.add_argument("--json", action="store_true", help="print one JSON object")
    scene_options(hunting)
    hunting.set_defaults(run=cmd_map)

    margin = commands.add_parser("margin", help="the gain factors k for which k G hunts, truth and DF: how much "
                                                "more gain before it hunts")
    controller_options(margin, own=True)
    own_map_options(margin)
    margin.add_argument("--k-range", action=_Once, type=_real, nargs=2, default=K_RANGE, metavar=("LO", "HI"),
                        help=f"gain factors searched, LO < 1 < HI (default: {K_RANGE[0]:g} {K_RANGE[1]:g})")
    margin.add_argument("--count", action=_Once, type=_integer(3, 1000), default=K_COUNT,
                        help="gain factors scanned, log-spaced (default: %(default)s)")
    margin.add_argument("--plot", action=_Once, type=_PNG,
                        help="write the plot to this PNG")
    margin.add_argument("--json", action="store_true", help="print one JSON object")
    fmu_options(margin)
    margin.set_defaults(run=cmd_margin)

    tuning = commands.add_parser("tune", help="the fastest controller, with its compensators, that does not hunt")
    controller_options(tuning)
    tuning.add_argument("--free", nargs="+", action="extend", metavar="NAME=LO:HI", required=True,
                        help="the parameters searched, G's and the compensators' (e.g. Kp=2:50 Ki=0.2:10 d=0:0.5)")
    tuning.add_argument("--tolerance", action=_Once, type=_real,
                        help="the largest standing error allowed after a step [the output's unit]")
    tuning.add_argument("--robust", nargs="+", action="extend", metavar="NAME=REL",
                        help="relative errors of the plant's parameters, each corner checked (e.g. Fc=0.2)")
    tuning.add_argument("--count", action=_Once, type=_integer(2, 50), default=5,
                        help="values per free parameter (default: %(default)s)")
    tuning.add_argument("--plot", action=_Once, type=_PNG, help="write the candidates' map to this PNG")
    tuning.add_argument("--json", action="store_true", help="print one JSON object")
    fmu_options(tuning)
    tuning.set_defaults(run=cmd_tune)

    examples = commands.add_parser("examples", help="the shipped limit-cycle examples, predicted, judged and plotted")
    examples.add_argument("--out", action=_Once, type=_folder, default=Path("out/examples"),
                          help="output folder (default: %(default)s)")
    examples.add_argument("--samples-per-period", action=_Once, type=_integer(16, 100_000), default=JUDGE_SAMPLES,
                          help="co-simulation steps per predicted period (default: %(default)s)")
    fmu_options(examples)
    examples.set_defaults(run=cmd_examples)

    bench = commands.add_parser("bench", help="run time against error of every method (Pareto plots, bench.md)")
    bench.add_argument("--quick", action="store_true", help="the quick set (about a minute on 2 cores)")
    bench.add_argument("--out", action=_Once, type=_folder, default=Path("out/bench"),
                       help="output folder (default: %(default)s)")
    fmu_folder_option(bench)  # every kind of plant FMU is measured: no --fmu
    bench.set_defaults(run=cmd_bench)

    stress = commands.add_parser("stress", help="the numerical stress suite: invariants at the edges")
    stress.add_argument("--quick", action="store_true", help="the quick set (649 cases, about 80 s)")
    stress.add_argument("--json", action="store_true", help="print one JSON object (cases, failed, failures)")
    stress.add_argument("--part", action=_Once, type=_integer(1, 10_000), default=1,
                        help="run only this piece of the set (default: %(default)s)")
    stress.add_argument("--parts", action=_Once, type=_integer(1, 10_000), default=1,
                        help="split the set into this many pieces (default: 1)")
    stress.set_defaults(run=cmd_stress)

    run = commands.add_parser("run", help="run scene files: only what each needs, cached, resumable")
    run.add_argument("scenes", type=Path, nargs="+", action="extend", metavar="SCENE.toml",
                     help="scene file(s), e.g. scenes/fig08_backlash_nyquist_eps.toml")
    run.add_argument("--out", action=_Once, type=_folder,
                     help="output folder (default: out/scenes/<scene>; with several scenes, "
                                              "one subfolder each)")
    scene_options(run)
    run.set_defaults(run=cmd_run)

    paper = commands.add_parser("paper", help="run the paper's scenes (figures 3-6, 8-12) and write report.md")
    paper.add_argument("--out", action=_Once, type=_folder, default=Path("out/paper"),
                       help="output folder (default: %(default)s)")
    scene_options(paper)
    paper.set_defaults(run=cmd_paper)

    demo = commands.add_parser("demo", help="drive each FMU with a sine through fmpy and plot the response")
    demo.add_argument("--out", action=_Once, type=_folder, default=Path("out"),
                      help="output folder (default: %(default)s)")
    fmu_options(demo)
    demo.set_defaults(run=cmd_demo)
    return top


def main(argv=None):
    try:
        return _main(argv)
    except KeyboardInterrupt:  # Ctrl-C while the parser is built or the arguments read: no traceback either
        sys.stderr.write("dfwb: interrupted\n")
        return 130


def _main(argv):
    from dfwb.base.errors import DfwbError
    from dfwb.base.stop import handling_signals

    top = parser()
    args = top.parse_args(argv)
    prog = f"dfwb {args.command}"
    if getattr(args, "fmu_kind", None):  # the process and its workers run this kind of plant FMU
        os.environ["DFWB_FMU"] = args.fmu_kind
    if args.command in FIGURE_COMMANDS and (args.command not in PLOT_COMMANDS or args.plot):
        from dfwb.plotting.backend import use_batch_backend

        use_batch_backend()  # figures go to files, in batch: no display is needed
    shown = warnings.showwarning
    warnings.showwarning = lambda message, *_, **__: sys.stderr.write(f"{prog}: warning: {message}\n")
    try:
        with handling_signals():  # Ctrl-C and kill: stop the workers and keep what is done
            return args.run(args)
    except DfwbError as error:
        top.exit(2, f"{prog}: error: {_one_line(error)}\n")
    except BrokenPipeError:  # the reader went away (dfwb ... | head): nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        top.exit(2, f"{prog}: error: {where}{error.strerror or _one_line(error)}\n")
    except KeyboardInterrupt:
        top.exit(130, f"{prog}: interrupted\n")
    except (RecursionError, MemoryError) as error:
        top.exit(2, f"{prog}: error: the input is too large or too deeply nested ({type(error).__name__})\n")
    except Exception as error:  # a defect of dfwb: one line, the traceback on request
        if os.environ.get("DFWB_TRACEBACK"):
            traceback.print_exc()
        top.exit(1, f"{prog}: internal error: {type(error).__name__}: {_one_line(error)} "
                    "(please report it; DFWB_TRACEBACK=1 shows the traceback)\n")
    finally:
        warnings.showwarning = shown


def _one_line(error, width=600):
    """The error's text on one line, cut to ``width`` characters (a state printed in full can run long)."""
    text = " ".join(str(error).split())
    return text if len(text) <= width else text[:width - 3] + "..."


if __name__ == "__main__":
    sys.exit(main())
