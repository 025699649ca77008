"""The plant models of dfwb and their exact, event-driven solvers (plain Python)."""

from .backlash import TwoMassBacklash
from .friction import FrictionMass
from .linear_system import LinearSystem
from .piecewise import PlantError
from .static_backlash import StaticBacklash

__all__ = ["FrictionMass", "TwoMassBacklash", "StaticBacklash", "LinearSystem", "PlantError"]
