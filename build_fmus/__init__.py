"""Builds the FMUs of dfwb: pythonfmu FMUs made FMI-compliant (:mod:`.builder`), the C core (:mod:`.core`) and
the native FMUs (:mod:`.native`).

The builder is imported on first use of its names: a run whose FMUs are up to date never loads it.
"""

from .errors import BuildError

__all__ = ["build", "build_all", "source_hash", "sources", "BuildError"]


def __getattr__(name):
    if name in ("build", "build_all", "source_hash", "sources"):
        from . import builder

        return getattr(builder, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
