"""The errors dfwb raises for reasons a user can act on, all under :class:`DfwbError`.

The command line turns a :class:`DfwbError` (or an ``OSError``) into one line
and exit code 2; any other exception is a defect of dfwb and is reported as
one. ``DfwbError`` itself is defined with the plant solvers, the lowest
layer, because they travel inside the FMUs without the rest of dfwb.
"""

from dfwb.fmus.exact import DfwbError, PlantError

__all__ = ["DfwbError", "PlantError", "InputError", "RunError"]


class InputError(DfwbError, ValueError):
    """A value given to dfwb (an option, a transfer function, a file's content) that it cannot use."""


class RunError(DfwbError, RuntimeError):
    """A run that cannot go on for a reason outside dfwb's code (a worker of another version, a scheduler)."""
