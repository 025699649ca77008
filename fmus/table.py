"""A plant described once: what every layer of dfwb reads instead of repeating it.

A plant's model module declares one :class:`PlantTable`: its constants
(masses, frictions, clearances) and its initial values, each a
:class:`Parameter` with its default, unit, description and bounds; its
outputs (:class:`Output`); and what the engine needs of its motion (the DF
signal, the section and modes, the translation). From it come the solver's
and the closed loop's keyword defaults, the FMU's variables and ranges
(pythonfmu and native), the C core's parameter orders, the engine's accepted
ranges and the registry entry's facts. A default written anywhere else is a
copy that can drift; ``tests/test_table.py`` holds every constructor to it.

The C core's orders follow one rule: a plant solver takes the constants,
the excitation ``F, omega, phi``, the initial values, then ``f, harmonics``;
a closed loop takes the constants and the initial values.

Plain Python only: this module runs inside the FMUs.

Examples
--------
>>> from dfwb.fmus.friction import TABLE
>>> TABLE.defaults["Fs"], TABLE.default.Fc
(7.0, 5.0)
>>> TABLE.core_order
('M', 'B', 'Fc', 'Fs', 'Dv', 'F', 'omega', 'phi', 'x0', 'v0', 'f', 'harmonics')
>>> TABLE.loop_order
('M', 'B', 'Fc', 'Fs', 'Dv', 'x0', 'v0')
"""

import keyword
import sys
from typing import NamedTuple, Optional

__all__ = ["Parameter", "Output", "PlantTable", "EXCITATION", "EXCITATION_NAMES", "INPUT_NAMES", "START", "MASS",
           "FORCE", "VELOCITY", "POSITION"]

EXCITATION_NAMES = ("F", "omega", "phi")
"""The built-in excitation F cos(omega t + phi), between the constants and the initial values in the C order."""
INPUT_NAMES = ("f", "harmonics")
"""The input at t = 0 and the number of harmonics: last in the C order."""


class Parameter(NamedTuple):
    """One parameter of a plant.

    ``bounds`` are the (min, max) the FMU's model description states (None:
    unbounded on that side; the solver's own check decides, with its
    message). ``accepted`` is the (low, high) the describing-function engine
    accepts (None: the solver's check alone), the edges ``dfwb stress``
    covers. ``start`` is the FMU's start value when the default is not a
    number (gap0: None in Python, -1 in an FMU, both meaning h/2). ``half_of``
    names the parameter whose half a default None stands for (gap0: ``"h"``),
    for the C core, which takes numbers only.
    """

    name: str
    default: Optional[float]
    unit: Optional[str]
    description: str
    bounds: tuple = (None, None)
    accepted: Optional[tuple] = None
    start: Optional[float] = None
    half_of: Optional[str] = None

    @property
    def fmu_start(self):
        """The FMU variable's start value."""
        return self.default if self.start is None else self.start


# The ranges the engine accepts for the common kinds of parameter: the edges ``dfwb stress`` covers and the
# engine computes (the solvers accept more). Positions only translate a plant, which the engine removes: their
# bound merely keeps the mean far from overflow.
MASS = (1e-6, 1e6)
FORCE = (0.0, 1e9)
VELOCITY = (-1e6, 1e6)
POSITION = (-1e30, 1e30)


class Output(NamedTuple):
    """One output of a plant's FMU.

    A ``counter`` is an integer the solver keeps as an attribute of that
    name (``impacts``); the others are the fields of its ``output()``, in
    order. ``feedthrough``: the input feeds it directly (stuck friction's
    force is the input), which the model description states.
    """

    name: str
    unit: Optional[str]
    description: str
    integer: bool = False
    counter: bool = False
    feedthrough: bool = False


START = (
    Parameter("x0", 0.0, "m", "initial position", accepted=POSITION),
    Parameter("v0", 0.0, "m/s", "initial velocity", accepted=VELOCITY),
)
"""The initial values of a plant with one mass: its position and velocity, at rest at the origin by default."""

EXCITATION = (
    Parameter("F", 0.0, "N", "amplitude of the built-in excitation F cos(omega t + phi)"),
    Parameter("omega", 1.0, "rad/s", "angular frequency of the built-in excitation (> 0)"),
    Parameter("phi", 0.0, "rad", "phase of the built-in excitation"),
)


class _Defaults:
    """The defaults as attributes (``TABLE.default.M``), for keyword defaults in signatures."""

    def __init__(self, parameters):
        self.__dict__.update((p.name, p.default) for p in parameters)


class PlantTable:
    """A plant described once.

    Parameters
    ----------
    name : str
        The plant's name (the command line's, the registry's).
    model : str
        The name of its FMU (``FrictionMass``), of its facade and of its solver on the C core; its closed
        loop's FMU is ``model + "Loop"``.
    summary : str
        What the plant is, in one line (lower case, no full stop): the registry's summary and, capitalised,
        its FMUs' description.
    constants, initial : tuple of Parameter
        The plant's constants, then its initial values.
    outputs : tuple of Output
        The FMU's outputs.
    signal : str
        The output whose Fourier integrals the FMU computes, its DF's (default: the first).
    section : tuple of str
        The continuous outputs read at whole periods: an orbit repeats when they do (the Poincare section).
    modes : tuple of str
        The discrete outputs read with them.
    starts : dict
        Section component -> the parameter that sets it at t = 0 (shooting starts there).
    shifts : dict
        How each section component and the signal move when the plant is translated by 1 m: a number, or
        the name of the parameter that is the factor (``"k"``).
    position : str
        The parameter that translates the whole plant.
    counter : str
        The integer output that counts engagements (``"events"``: every event).
    integrated : bool
        Its solver integrates some modes (:mod:`.integrated`) and bounds the error of its Fourier integrals
        (``integrals_error()``): its FMU outputs that bound as ``I_error``, the engine reports ``N_error``.
    """

    def __init__(self, name, constants, initial, outputs=(), signal=None, section=(), modes=(), starts=None,
                 shifts=None, position=None, counter="events", model=None, summary="", integrated=False):
        self.name, self.model, self.summary = name, model, summary
        self.integrated = bool(integrated)
        self.constants, self.initial = tuple(constants), tuple(initial)
        self.section, self.modes, self.position, self.counter = tuple(section), tuple(modes), position, counter
        self.starts, self.shifts = dict(starts or {}), dict(shifts or {})
        self.outputs = tuple(outputs)
        self.signal = signal if signal is not None else (self.outputs[0].name if self.outputs else None)
        self.solver_outputs = tuple(o.name for o in self.outputs if not o.counter)
        self.counters = tuple(o.name for o in self.outputs if o.counter)
        names = [o.name for o in self.outputs]
        bad = [n for n in names if not (isinstance(n, str) and n.isidentifier()) or keyword.iskeyword(n)
               or n.startswith("_") or names.count(n) > 1]
        if bad:
            raise ValueError(f"plant {name!r}: output name {bad[0]!r} is refused: outputs need distinct names that "
                             f"are identifiers, not keywords, not starting with '_'")
        self.output_type = NamedTuple(f"{model or 'Plant'}Output", [
            (o.name, int if o.integer else float) for o in self.outputs if not o.counter])
        """The named tuple of the solver's ``output()``: the outputs that are not counters, in order."""
        # pickled as the attribute it is, TABLE.output_type of the module that declares the table
        self.output_type.__module__ = sys._getframe(1).f_globals.get("__name__", __name__)
        self.output_type.__qualname__ = "TABLE.output_type"
        if self.outputs and self.signal not in self.solver_outputs:
            raise ValueError(f"the signal {self.signal!r} is not one of the outputs {self.solver_outputs}")
        self.parameters = self.constants + self.initial
        names = [p.name for p in self.parameters + EXCITATION] + list(INPUT_NAMES)
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise ValueError(f"parameters {repeated} are declared twice")
        self.names = tuple(p.name for p in self.parameters)
        self.defaults = {p.name: p.default for p in self.parameters}
        self.default = _Defaults(self.parameters)
        self.core_order = (tuple(p.name for p in self.constants) + EXCITATION_NAMES
                           + tuple(p.name for p in self.initial) + INPUT_NAMES)
        self.loop_order = self.names

    def fmu_parameters(self):
        """((name, start, unit, description)) of the FMU facade, in its variables' order."""
        return tuple((p.name, p.fmu_start, p.unit, p.description) for p in self.parameters)

    def bounds(self):
        """{name: (min, max)} stated in the model description (parameters with a bound only)."""
        return {p.name: p.bounds for p in self.parameters if p.bounds != (None, None)}

    def fmu_outputs(self):
        """((name, unit, description, is_integer)) of the FMU facade, in its variables' order."""
        return tuple((o.name, o.unit, o.description, o.integer) for o in self.outputs)

    def feedthrough(self):
        """{output: "dependent"} of the outputs the input feeds directly."""
        return {o.name: "dependent" for o in self.outputs if o.feedthrough}

    def fmu_signal(self):
        """(name, unit) of the signal whose Fourier integrals the FMU computes."""
        return next((o.name, o.unit) for o in self.outputs if o.name == self.signal)

    def accepted(self):
        """{name: (low, high, unit)} the engine accepts (parameters with such a range only)."""
        return {p.name: p.accepted + (p.unit or "",) for p in self.parameters if p.accepted is not None}
