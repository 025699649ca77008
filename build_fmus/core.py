"""Compile dfwb's exact plant solvers in C (``fmus/native/*.c``) into a shared library for ctypes.

:func:`build_core` compiles the sources with the system C compiler into
``<out_dir>/libdfwb_core-<hash>.so``. The hash covers the compiler command,
the flags and every source (name and contents), so a library whose name
matches is reused as it is, and an edited source or flag builds a new one
next to it. The library is written to a temporary name and renamed into
place (atomic: a concurrent build or reader never sees half a file).

Flags: ``-O2 -std=c99 -fPIC -shared``, with ``-ffp-contract=off`` (no fused
multiply-add: every operation rounds as the Python oracle's does) and
``-fvisibility=hidden`` (only the ``DFWB_API`` functions of ``dfwb_core.h``
are exported); never ``-ffast-math``. The tests add ``-Wall -Wextra -Werror``.

The core's list of plants, ``dfwb_plants.h``, is not a file of the tree:
:func:`sources` writes it from the plants' tables
(:mod:`dfwb.build_fmus.plant_header`) into every build, beside the files
of ``fmus/native``, and every FMU that carries the core's sources carries it
too (they build without Python).

Examples
--------
>>> from dfwb.build_fmus.core import sources
>>> [name for name in sources() if name.endswith(".h")][:2]
['dfwb_core.h', 'dfwb_plants.h']
"""

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from .errors import BuildError

__all__ = ["build_core", "build_library", "sources", "compiler", "win64_compiler", "NATIVE_DIR", "FLAGS", "WIN64_CC",
           "CoreBuildError"]

# dfwb.fmus's native/ folder: ../fmus next to this package, in a checkout and in an installed wheel alike
NATIVE_DIR = Path(__file__).resolve().parent.parent / "fmus" / "native"
FLAGS = ("-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off", "-fvisibility=hidden")
LIBS = ("-lm",)
PREFIX = "libdfwb_core-"
WIN64_CC = "x86_64-w64-mingw32-gcc"  # mingw-w64 (Debian: gcc-mingw-w64-x86-64): the win64 binaries of the FMUs


class CoreBuildError(BuildError):
    """The C core cannot be compiled: no compiler, or the compiler failed (the message says which, in one line)."""


def sources():
    """{name: bytes} of the core's C sources and headers, sorted by name: the files of ``fmus/native`` and the
    generated ``dfwb_plants.h``."""
    from .plant_header import NAME, header_text  # the solver package's tables: only when building

    folder = NATIVE_DIR
    found = sorted(path for path in folder.iterdir() if path.suffix in (".c", ".h")) if folder.is_dir() else []
    if not any(path.suffix == ".c" for path in found):
        raise CoreBuildError(f"no C sources of the core in {folder}")
    files = {path.name: path.read_bytes() for path in found}
    files[NAME] = header_text().encode()
    return dict(sorted(files.items()))


def compiler():
    """The C compiler as a command list: $CC, else cc, gcc or clang on PATH (CoreBuildError if none)."""
    for name in ([os.environ["CC"]] if os.environ.get("CC") else []) + ["cc", "gcc", "clang"]:
        words = name.split()
        found = shutil.which(words[0]) if words else None
        if found:
            return [found] + words[1:]
    raise CoreBuildError("building the C core needs a C compiler: no $CC, cc, gcc or clang on PATH")


def win64_compiler():
    """The path of :data:`WIN64_CC`, or None where it is not installed (the FMUs then carry no dfwb-built win64
    binary)."""
    return shutil.which(WIN64_CC)


def _digest(command, files):
    h = hashlib.sha256()
    h.update("\0".join(command).encode())
    for name, content in files.items():
        h.update(b"\0" + name.encode() + b"\0")
        h.update(content)
    return h.hexdigest()[:16]


def build_core(out_dir, extra_flags=()):
    """Compile the core into ``out_dir/libdfwb_core-<hash>.so`` (reused if present) and return its path.

    ``extra_flags`` are added to :data:`FLAGS` (and to the hash), e.g.
    ``("-Wall", "-Wextra", "-Werror")``. Raises :class:`CoreBuildError` (a
    ``dfwb.build_fmus.BuildError``, hence a ``DfwbError``) with a one-line
    message when no compiler is found or the compilation fails.
    """
    return build_library(out_dir, sources(), PREFIX, extra_flags, "the C core")


def build_library(out_dir, files, prefix, extra_flags=(), what="the C library"):
    """Compile the C ``files`` (with their headers: paths, or {name: bytes}) into ``out_dir/<prefix><hash>.so``
    as :func:`build_core` does the core (the same flags, reuse and atomic rename; compiled in a temporary folder
    that holds them); its path. ``what`` names it in errors."""
    out_dir = Path(out_dir)
    if not isinstance(files, dict):
        paths = [Path(path) for path in files]
        names = [path.name for path in paths]
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise CoreBuildError(f"compiling {what}: two files named {repeated[0]} (they are compiled side by side)")
        files = {path.name: path.read_bytes() for path in paths}
    cc = compiler()
    flags = list(FLAGS) + [str(flag) for flag in extra_flags]
    target = out_dir / f"{prefix}{_digest(cc + flags + list(LIBS), files)}.so"
    if target.is_file():
        return target
    out_dir.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=".so.tmp", dir=out_dir)
    os.close(handle)
    try:
        with tempfile.TemporaryDirectory(prefix="dfwb_c_") as stage:
            for name, content in files.items():
                Path(stage, name).write_bytes(content)
            command = (cc + flags + ["-o", os.path.abspath(temporary)] + [name for name in files if name.endswith(".c")]
                       + list(LIBS))
            try:
                run = subprocess.run(command, capture_output=True, text=True, cwd=stage)
            except OSError as error:
                raise CoreBuildError(f"compiling {what} failed: {' '.join(cc)}: {error}") from None
        if run.returncode != 0:
            lines = [line.strip() for line in run.stderr.splitlines() if line.strip()]
            first = next((line for line in lines if "error" in line), lines[0] if lines else "no message")
            raise CoreBuildError(f"compiling {what} failed (exit {run.returncode}, "
                                 f"{len(lines)} lines of diagnostics): {first}")
        os.chmod(temporary, 0o755)
        os.replace(temporary, target)
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)
    return target
