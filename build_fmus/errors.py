"""The error of a build: one line saying what cannot be built and why."""

from dfwb.fmus.exact import DfwbError

__all__ = ["BuildError"]


class BuildError(DfwbError, ValueError):
    """An FMU or the core that cannot be built: a module that cannot be bundled (the message says which
    import), no compiler, a compilation that failed."""
