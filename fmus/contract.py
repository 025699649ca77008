"""What an FMU facade needs of a plant solver: the :class:`Solver` protocol and the event kinds.

A plant solver is any object with the members of :class:`Solver`; it does
not inherit from anything. The closed-form solvers of :mod:`.friction`,
:mod:`.backlash` and :mod:`.static_backlash` (all built on
:class:`~.piecewise.PiecewisePlant`) and the fixed-step baselines of
:mod:`.naive` implement it, and so can a plant integrated another way (its
own closed form, a series, an implicit scheme): the facade
(:class:`~.facade.PlantFMU`) and the stress suite use only these members.

The constructor is part of the contract too, by convention: keyword
arguments only, the facade's parameters plus ``F``, ``omega``, ``phi``
(the built-in excitation ``F cos(omega t + phi)``), ``f`` (the input at
t = 0) and ``harmonics`` (0..10); a value it cannot accept raises
:class:`~.exact.PlantError` naming it, before anything runs.

Plain Python only: this module runs inside the FMUs.
"""

import enum
from typing import Protocol, runtime_checkable

__all__ = ["Solver", "EventKind"]


@runtime_checkable
class Solver(Protocol):
    """The interface of a plant solver, as the FMU facade drives it.

    Attributes
    ----------
    t : float
        The current time (s); starts at 0.
    events : int
        Events counted so far (mode changes, impacts): the FMU's ``events``.
    """

    t: float
    events: int

    def set_input(self, f: float) -> None:
        """Set the input force, held constant until the next call (PlantError unless finite)."""

    def advance(self, t_end: float) -> None:
        """Integrate from ``t`` to ``t_end`` (>= t) with the input held; then ``t == t_end``."""

    def integrals(self) -> list:
        """Running integrals ``I_k(t) = int_0^t y(s) exp(-i k omega s) ds``, k = 0..harmonics (complex)."""

    def output(self) -> tuple:
        """The continuous outputs at ``t`` as the plant table's ``output_type`` (the FMU's output names)."""


class EventKind(str, enum.Enum):
    """What an event of a closed-form solver is (``PiecewisePlant.event_log`` records ``(t, kind)``).

    A ``str`` enum: a kind compares equal to its value (``EventKind.APEX ==
    "apex"``) and prints as it.
    """

    # friction (.friction)
    BREAK_UP = "break+"  # the force exceeds the break-away level upwards: slide or push +1
    BREAK_DOWN = "break-"  # ... downwards
    RELEASE = "release"  # the force falls back (friction: to Fs; backlash: stops pressing into a wall)
    EDGE = "edge"  # pushed through the Karnopp band to its edge
    BAND = "band"  # a sliding velocity reached the band
    # two-mass backlash (.backlash)
    WALL_LOWER = "gap 0"  # the gap closes at 0
    WALL_UPPER = "gap h"  # the gap opens to h
    APEX = "apex"  # the separation speed from the wall just left falls to zero (not counted)
    # static backlash (.static_backlash)
    ENGAGE_UP = "engage+"  # x reaches the upper edge of the play and drags y
    ENGAGE_DOWN = "engage-"  # ... the lower edge
    REVERSE = "reverse"  # the engaged mass's velocity reverses: y is let go
    # compensators in the closed loop (.compensation)
    COULOMB = "coulomb"  # the controller's force crosses zero: the Coulomb feedforward of its sign switches
    DEADBAND = "deadband"  # the output reaches the integrator deadband's edge: the integrator holds or resumes

    def __str__(self):
        return self.value
