"""The plants: the contract every plant fulfils, the registry, and the built-in plants.

Examples
--------
>>> from dfwb.plants import names
>>> "friction" in names()
True
"""

from dfwb.plants import builtin  # noqa: F401  (registers the built-in plants)
from dfwb.plants.registry import (
                                  PLANTS,
                                  RANGES,
                                  Demo,
                                  Plant,
                                  check_range,
                                  markdown_table,
                                  names,
                                  plant,
                                  register,
                                  unregister,
)

__all__ = ["Plant", "Demo", "register", "unregister", "plant", "names", "markdown_table", "PLANTS", "RANGES",
           "check_range"]
