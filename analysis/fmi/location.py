"""Where the FMUs live: a per-user folder by default, each built there on first use.

The FMUs are derived from the sources, so by default they are built into the
user's cache, ``$XDG_CACHE_HOME/dfwb/fmus`` (else ``~/.cache/dfwb/fmus``),
never into whatever folder the user stands in. ``DFWB_FMU_DIR`` or a
command's ``--fmus DIR`` choose another folder. :func:`fmu_path` builds only
the FMU it is asked for, and only when it is missing there or was built from
other sources (each FMU's hash covers the modules it bundles: see
:mod:`dfwb.build_fmus.builder`).

Two kinds of plant FMUs: ``native`` (the C core with an FMI wrapper, no Python
inside: :mod:`dfwb.build_fmus.native`), the default, kept in the folder's
``native/`` subfolder, and ``python`` (pythonfmu). Both give the same numbers,
bit for bit; ``DFWB_FMU`` or a command's ``--fmu`` chooses. The controller
and the closed loops exist only as pythonfmu FMUs.
"""

import os
from pathlib import Path

from dfwb.base.files import user_cache_dir
from dfwb.fmus.exact import DfwbError
from dfwb.fmus.piecewise import PlantError

__all__ = ["default_fmu_dir", "fmu_folder", "fmu_kind", "fmu_path", "models", "build_fmus", "native_core",
           "FMU_KINDS"]

FMU_KINDS = ("native", "python")
NATIVE_FOLDER = "native"
NATIVE_FMI3_FOLDER = "native/fmi3"  # dfwb build --native --fmi-version 3


def default_fmu_dir():
    """``$DFWB_FMU_DIR`` if set, else the user's cache folder ``.../dfwb/fmus``."""
    chosen = os.environ.get("DFWB_FMU_DIR")
    return Path(chosen).expanduser().absolute() if chosen else user_cache_dir() / "fmus"


def fmu_folder(fmu_dir=None):
    """The FMU folder asked for (None: :func:`default_fmu_dir`); PlantError unless it is a path."""
    if fmu_dir is None:
        return default_fmu_dir()
    if not isinstance(fmu_dir, (str, os.PathLike)) or not isinstance(os.fspath(fmu_dir), str) \
            or not os.fspath(fmu_dir):
        raise PlantError(f"fmu_dir = {fmu_dir!r} is not a folder: give a path (str or pathlib.Path)")
    return Path(fmu_dir)


def fmu_kind(kind=None):
    """The kind of plant FMU to run: ``kind``, else ``$DFWB_FMU``, else "native"; PlantError unless in FMU_KINDS."""
    chosen = kind if kind is not None else os.environ.get("DFWB_FMU") or "native"
    if chosen not in FMU_KINDS:
        source = "kind" if kind is not None else "DFWB_FMU"
        raise PlantError(f"{source} = {chosen!r} is not an FMU kind (allowed: {', '.join(FMU_KINDS)})")
    return chosen


def models(naive=False):
    """The facade classes of the registered plants, LinearSystem (the controller) and the closed loops
    (FrictionMassLoop, TwoMassBacklashLoop, StaticBacklashLoop); ``naive``: the plants' twins too."""
    from dfwb.fmus.facade import LinearSystem
    from dfwb.fmus.loop_facade import LOOPS
    from dfwb.plants.registry import PLANTS

    found = [entry.model for entry in PLANTS.values()] + [LinearSystem] + list(LOOPS)
    if naive:
        found += [entry.naive for entry in PLANTS.values() if entry.naive is not None]
    return list(dict.fromkeys(found))


def _model(model):
    """The facade class of a registry Plant or of a model name like "LinearSystem"."""
    if not isinstance(model, str):
        return model.model
    known = {cls.__name__: cls for cls in models(naive=True)}
    if model not in known:
        raise PlantError(f"unknown FMU model {model!r} (allowed: {', '.join(known)})")
    return known[model]


def fmu_path(model, fmu_dir=None, kind=None):
    """Path of one FMU (a registry Plant, or a model name like "LinearSystem"), built first if missing or stale.

    ``kind`` (:func:`fmu_kind`): "native" gives the native FMU of a plant that has one (in the folder's
    ``native/``), the pythonfmu FMU otherwise; "python" always the pythonfmu FMU.
    """
    cls = _model(model)
    if fmu_kind(kind) == "native":
        from dfwb.build_fmus.native import build_native, native_models

        if cls in native_models():
            return build_native(fmu_folder(fmu_dir) / NATIVE_FOLDER, [cls], report=lambda message: None)[0]
    from dfwb.build_fmus.builder import build

    return build(fmu_folder(fmu_dir), [cls], report=lambda message: None)[0]


_CORES = {}  # {folder: NativeCore}: each core is built (sources hashed) and loaded once per process and folder


def native_core(fmu_dir=None, kind=None):
    """The compiled core (:class:`dfwb.fmus.native_core.NativeCore`) for solvers run in this process, or None.

    None when ``kind`` (:func:`fmu_kind`) is "python", or, with a warning, when the core cannot be built
    or loaded (the caller then runs the pure-Python solvers, which give the same numbers). Built on
    first use into the FMU folder's ``native/`` (reused while its sources are unchanged).
    """
    if fmu_kind(kind) != "native":
        return None
    import warnings

    from dfwb.build_fmus.core import build_core
    from dfwb.fmus.native_core import load

    folder = fmu_folder(fmu_dir) / NATIVE_FOLDER
    try:
        if folder not in _CORES:  # a continuation makes a problem per gain: hash the sources once
            _CORES[folder] = load(build_core(folder))
        return _CORES[folder]
    except (DfwbError, OSError) as error:
        warnings.warn(f"the compiled core cannot be used ({error}): the pure-Python solvers run instead",
                      RuntimeWarning, stacklevel=2)
        return None


def build_fmus(fmu_dir=None, naive=False, force=False, report=print):
    """Build the FMUs of :func:`models` into ``fmu_dir`` (default :func:`default_fmu_dir`), and the native plant
    FMUs into its ``native/``; the paths of the former."""
    from dfwb.build_fmus.builder import build
    from dfwb.build_fmus.native import build_native

    folder = fmu_folder(fmu_dir)
    paths = build(folder, models(naive), force=force, report=report)
    build_native(folder / NATIVE_FOLDER, force=force, report=report)
    return paths
