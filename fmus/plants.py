"""The plants of dfwb, listed once: their tables, in the order of their kinds in the C core.

A plant's kind numbers its states (the C core writes it into their
header), so the list is appended to, never reordered. Everything that
enumerates dfwb's own plants below the registry reads it: the C core's
generated list of plants (:mod:`dfwb.build_fmus.plant_header`), the native
FMUs' kinds and the C binding's.

Plain Python only: this module runs inside the FMUs.

Examples
--------
>>> from dfwb.fmus.plants import KINDS, TABLES
>>> [table.name for table in TABLES], KINDS["backlash"]
(['friction', 'backlash', 'static-backlash'], 2)
"""

from . import backlash, friction, static_backlash

__all__ = ["TABLES", "KINDS", "c_name"]

TABLES = (friction.TABLE, backlash.TABLE, static_backlash.TABLE)
KINDS = {table.name: kind for kind, table in enumerate(TABLES, start=1)}
"""{plant name: its kind in the C core (DFWB_PLANT_*)}."""


def c_name(table):
    """The plant's name in C: ``static_backlash`` (its class ``dfwb_static_backlash_class``, its kind
    ``DFWB_PLANT_STATIC_BACKLASH``)."""
    return table.name.replace("-", "_")
