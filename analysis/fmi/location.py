"""Where the FMUs live: a per-user folder by default, each built there on first use.

The FMUs are derived from the sources, so by default they are built into the
user's cache, ``$XDG_CACHE_HOME/dfwb/fmus`` (else ``~/.cache/dfwb/fmus``),
never into whatever folder the user stands in. ``DFWB_FMU_DIR`` or a
command's ``--fmus DIR`` choose another folder. :func:`fmu_path` builds only
the FMU it is asked for, and only when it is missing there or was built from
other sources (each FMU's hash covers the modules it bundles: see
:mod:`dfwb.build_fmus.builder`).
"""

import os
from pathlib import Path

from dfwb.base.files import user_cache_dir
from dfwb.fmus.piecewise import PlantError

__all__ = ["default_fmu_dir", "fmu_path", "models", "build_fmus"]


def default_fmu_dir():
    """``$DFWB_FMU_DIR`` if set, else the user's cache folder ``.../dfwb/fmus``."""
    chosen = os.environ.get("DFWB_FMU_DIR")
    return Path(chosen) if chosen else user_cache_dir() / "fmus"


def models(naive=False):
    """The facade classes of the registered plants and LinearSystem (the controller); ``naive``: their twins too."""
    from dfwb.fmus.facade import LinearSystem
    from dfwb.plants.registry import PLANTS

    found = [entry.model for entry in PLANTS.values()] + [LinearSystem]
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


def fmu_path(model, fmu_dir=None):
    """Path of one FMU (a registry Plant, or a model name like "LinearSystem"), built first if missing or stale."""
    from dfwb.build_fmus.builder import build

    fmu_dir = default_fmu_dir() if fmu_dir is None else Path(fmu_dir)
    return build(fmu_dir, [_model(model)], report=lambda message: None)[0]


def build_fmus(fmu_dir=None, naive=False, force=False, report=print):
    """Build the FMUs of :func:`models` into ``fmu_dir`` (default :func:`default_fmu_dir`); their paths."""
    from dfwb.build_fmus.builder import build

    return build(default_fmu_dir() if fmu_dir is None else fmu_dir, models(naive), force=force, report=report)
