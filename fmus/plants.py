"""The plants of dfwb, listed once: their model modules, in the order of their kinds in the C core.

A plant's model module holds its ``TABLE`` (:class:`~.table.PlantTable`),
its exact solver ``SOLVER`` and its closed loop ``LOOP``
(:class:`~.loops.FeedbackLoop`). A plant's kind numbers its states (the C
core writes it into their header), so the list is appended to, never
reordered. Everything that enumerates dfwb's own plants reads it: the FMU
facades of the plants and their loops (generated from the modules), the C
binding's classes, the C core's list of plants (``dfwb_plants.h``, written
into every build by :mod:`dfwb.build_fmus.plant_header`), the native FMUs' kinds and the
registry.

Plain Python only: this module runs inside the FMUs.

Examples
--------
>>> from dfwb.fmus.plants import KINDS, TABLES
>>> [table.name for table in TABLES[:3]], KINDS["backlash"]
(['friction', 'backlash', 'static-backlash'], 2)
"""

from . import backlash, drivetrain, friction, static_backlash, stribeck

__all__ = ["MODULES", "TABLES", "KINDS", "c_name"]

MODULES = (friction, backlash, static_backlash, drivetrain, stribeck)
TABLES = tuple(module.TABLE for module in MODULES)
KINDS = {table.name: kind for kind, table in enumerate(TABLES, start=1)}
"""{plant name: its kind in the C core (DFWB_PLANT_*)}."""


def _distinct():
    """Every name a plant gives the generated classes is its own: a plant copied from another and not renamed
    would silently replace that plant's FMU, loop FMU or C classes."""
    for what, names in (("plant", [m.TABLE.name for m in MODULES]), ("C", [c_name(m.TABLE) for m in MODULES]),
                        ("FMU", [m.TABLE.model for m in MODULES]),
                        ("solver", [m.SOLVER.__name__ for m in MODULES]),
                        ("loop", [m.LOOP.__name__ for m in MODULES])):
        repeated = sorted({name for name in names if names.count(name) > 1})
        if repeated:
            raise ValueError(f"dfwb.fmus.plants: two plants have the {what} name {repeated[0]!r}")


def c_name(table):
    """The plant's name in C: ``static_backlash`` (its class ``dfwb_static_backlash_class``, its kind
    ``DFWB_PLANT_STATIC_BACKLASH``)."""
    return table.name.replace("-", "_")


_distinct()
