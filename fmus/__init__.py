"""The plant models of dfwb and their exact, event-driven solvers (plain Python).

:class:`Solver` is the interface a plant solver offers its FMU facade (the
closed-form solvers implement it; so may a plant integrated another way),
:class:`EventKind` the events of the closed-form solvers.
"""

from .backlash import TwoMassBacklash
from .contract import EventKind, Solver
from .friction import FrictionMass
from .linear_system import LinearSystem
from .piecewise import PlantError
from .static_backlash import StaticBacklash

__all__ = ["FrictionMass", "TwoMassBacklash", "StaticBacklash", "LinearSystem", "PlantError", "Solver", "EventKind"]
