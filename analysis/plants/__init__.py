"""The plants: the contract every plant fulfils, the registry, and the three built-in plants.

Examples
--------
>>> from dfwb.plants import names
>>> "friction" in names()
True
"""

from dfwb.plants import builtin  # noqa: F401  (registers the built-in plants)
from dfwb.plants.registry import PLANTS, RANGES, Demo, Plant, check_range, names, plant, register, unregister

__all__ = ["Plant", "Demo", "register", "unregister", "plant", "names", "PLANTS", "RANGES", "check_range"]
