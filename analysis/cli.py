"""The ``dfwb`` command line."""

import argparse
import sys
from pathlib import Path

DEFAULT_FMU_DIR = Path("build/fmus")


def _fmus(out_dir):
    from dfwb.build_fmus import build_all

    return {path.stem: path for path in build_all(out_dir, report=lambda message: None)}


def cmd_build(args):
    from dfwb.build_fmus import build_all

    build_all(args.out, force=args.force)
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

    demo = commands.add_parser("demo", help="drive each FMU with a sine through fmpy and plot the response")
    demo.add_argument("--out", type=Path, default=Path("out"), help="output folder (default: %(default)s)")
    demo.add_argument("--fmus", type=Path, default=DEFAULT_FMU_DIR, help="FMU folder (default: %(default)s)")
    demo.set_defaults(run=cmd_demo)
    return top


def main(argv=None):
    args = parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
