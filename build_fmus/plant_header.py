"""The C core's list of plants and their parameter orders, written from the plants' tables (:mod:`dfwb.fmus.table`).

``dfwb_plants.h`` is not a file of the tree: :func:`dfwb.build_fmus.core.sources`
writes it into every build of the core, and into every FMU that carries the
core's sources (which then build anywhere without Python: an importer's
cmake build of a sources FMU). ``python -m dfwb.build_fmus.plant_header``
prints it.

It defines each plant's kind ``DFWB_PLANT_<P>`` (a state's header names it:
plants are appended, never renumbered), ``DFWB_PLANTS(X)``, which expands
``X(kind, name)`` for every plant (the core's table of classes: plant
``name`` defines ``dfwb_<name>_class`` in its own file), and the orders of
its parameters: ``DFWB_<P>_PARAMS`` (the length of ``dfwb_plant_new``'s
array) and ``DFWB_<P>_<name>`` (a parameter's index there), then
``DFWB_LOOP_<P>_PARAMS`` and ``DFWB_<P>_LOOP_<name>`` for ``dfwb_loop_new``.
"""

import sys

from dfwb.fmus.plants import TABLES, c_name

NAME = "dfwb_plants.h"
PLANTS = tuple((c_name(table), table) for table in TABLES)
"""(C name, table) of the core's plants (:data:`dfwb.fmus.plants.TABLES`), in the order of their kinds."""


def _block(title, count, prefix, names):
    width = max(len(f"{prefix}_{name}") for name in names) + 1
    lines = [f"/* {title}: {{{', '.join(names)}}} */", f"#define {count} {len(names)}"]
    lines += [f"#define {f'{prefix}_{name}':<{width}}{index}" for index, name in enumerate(names)]
    return lines + [""]


def header_text():
    """The text of dfwb_plants.h."""
    lines = ["/* dfwb_plants.h - the plants of the C core and their parameter orders, written from their tables",
             " * (fmus/table.py) into every build by dfwb.build_fmus.core.sources; do not edit. */",
             "#ifndef DFWB_PLANTS_H", "#define DFWB_PLANTS_H", "",
             "/* The plants' kinds (a state's header names its kind: plants are appended, never renumbered). */"]
    lines += [f"#define DFWB_PLANT_{name.upper()} {kind}" for kind, (name, _table) in enumerate(PLANTS, start=1)]
    lines += ["", "/* X(kind, name) for every plant: plant name defines dfwb_<name>_class in its own file. */",
              "#define DFWB_PLANTS(X) \\"]
    lines += [f"    X(DFWB_PLANT_{name.upper()}, {name})" + (" \\" if kind < len(PLANTS) else "")
              for kind, (name, _table) in enumerate(PLANTS, start=1)]
    lines.append("")
    for name, table in PLANTS:
        prefix = name.upper()
        lines += _block(f"dfwb_plant_new, the {name.replace('_', ' ')}", f"DFWB_{prefix}_PARAMS", f"DFWB_{prefix}",
                        table.core_order)
        lines += _block(f"dfwb_loop_new, the {name.replace('_', ' ')} loop", f"DFWB_LOOP_{prefix}_PARAMS",
                        f"DFWB_{prefix}_LOOP", table.loop_order)
    return "\n".join(lines + ["#endif", ""])


def main():
    sys.stdout.write(header_text())


if __name__ == "__main__":
    main()
