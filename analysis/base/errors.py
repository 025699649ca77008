"""The errors dfwb raises for reasons a user can act on, all under :class:`DfwbError`.

The command line turns a :class:`DfwbError` (or an ``OSError``) into one line
and exit code 2; any other exception is a defect of dfwb and is reported as
one. ``DfwbError`` itself is defined with the plant solvers, the lowest
layer, because they travel inside the FMUs without the rest of dfwb.
"""

from dfwb.fmus.exact import DfwbError, PlantError

__all__ = ["DfwbError", "PlantError", "InputError", "RunError", "fmu_only"]

# DfwbError and PlantError are documented here, where the public API takes them from: their module
# (dfwb.fmus.exact) is bundled into the FMUs, whose hash covers its text, so a longer docstring there
# would make every FMU be built again.
DfwbError.__doc__ = """Base of every error dfwb raises for a reason the user can act on (a value, a file, a run).

    Its subclasses say which: :class:`PlantError` (a plant, its parameters or an FMU),
    :class:`InputError` (any other value given to dfwb) and :class:`RunError` (a run that cannot go on).
    Catch ``DfwbError`` to report all of them in one line, as the command line does (exit code 2).

    Examples
    --------
    >>> import dfwb
    >>> [error.__name__ for error in (dfwb.PlantError, dfwb.InputError, dfwb.RunError)
    ...  if issubclass(error, dfwb.DfwbError)]
    ['PlantError', 'InputError', 'RunError']
    >>> try:
    ...     dfwb.describing_function("friction", F=10.0, omega=1.0, M=-1.0)
    ... except dfwb.DfwbError as error:
    ...     print(f"{type(error).__name__}: {error}")
    PlantError: M = -1.0 is out of range: M must be in [1e-06, 1e+06] kg
    """

PlantError.__doc__ = """A parameter, input or step the plant cannot accept.

    Also a plant that is not registered, an entry that contradicts its FMU facade, and a user's FMU
    that dfwb cannot run (:func:`dfwb.fmu_plant`). A ``ValueError`` too.

    Examples
    --------
    >>> import dfwb
    >>> [cls.__name__ for cls in dfwb.PlantError.__mro__]
    ['PlantError', 'DfwbError', 'ValueError', 'Exception', 'BaseException', 'object']
    >>> dfwb.describing_function("friction", F=10.0, omega=1.0, Fs=1.0)
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: Fs = 1.0 is out of range: Fs must be >= Fc = 5.0 (N)
    """


class InputError(DfwbError, ValueError):
    """A value given to dfwb (an option, a transfer function, a file's content) that it cannot use.

    A ``ValueError`` too; the values of a plant are refused with :class:`PlantError` instead.

    Examples
    --------
    >>> import dfwb
    >>> [cls.__name__ for cls in dfwb.InputError.__mro__]
    ['InputError', 'DfwbError', 'ValueError', 'Exception', 'BaseException', 'object']
    >>> dfwb.transfer_function("Kp + Ki/s")
    Traceback (most recent call last):
    ...
    dfwb.base.errors.InputError: G(s) = Kp + Ki/s: the parameter Kp is given no value (set it, e.g. Kp=1)
    >>> dfwb.describing_function("friction", F=10.0, omega=1.0, harmonics=0.5)
    Traceback (most recent call last):
    ...
    dfwb.base.errors.InputError: harmonics = 0.5 is not an integer
    """


class RunError(DfwbError, RuntimeError):
    """A run that cannot go on for a reason outside dfwb's code (a worker of another version, a scheduler).

    Also a folder to write into that is a file. A ``RuntimeError`` too.

    Examples
    --------
    >>> import tempfile, dfwb
    >>> from dfwb.studies.scene import parse_scene
    >>> [cls.__name__ for cls in dfwb.RunError.__mro__]
    ['RunError', 'DfwbError', 'RuntimeError', 'Exception', 'BaseException', 'object']
    >>> scene = parse_scene('title = "t"\\n[[series]]\\nname = "s"\\nplant = "friction"\\nF = [10]\\nomega = [1]\\n')
    >>> with tempfile.NamedTemporaryFile(suffix=".txt") as file:  # doctest: +ELLIPSIS
    ...     dfwb.run_scene(scene, file.name, jobs=1, cache=False)
    Traceback (most recent call last):
    ...
    dfwb.base.errors.RunError: --out ....txt is a file, not a folder
    """


OWN_PLANTS = "dfwb's own plants derive their ranges and are computed exactly"  # fmu_only's reason, by default


def fmu_only(given, own=OWN_PLANTS):
    """Refuse, in one line, the options only a user's FMU takes when dfwb's own plant was given them: ``given``
    maps each option's name to (value, default); the ones away from their defaults are named, then ``own``
    (why dfwb's plants need none)."""
    named = [name for name, (value, default) in given.items()
             if value is not default and (default is None or value != default)]
    if named:
        raise InputError(f"{', '.join(named)}: for a user's FMU only ({own})")
