"""The C core's parameter orders, written from the plants' tables (:mod:`dfwb.fmus.table`).

``fmus/native/dfwb_parameters.h`` is generated, and kept in the tree so
that the core's sources build anywhere without Python (an importer's cmake
build of a sources FMU). ``tests/test_table.py`` fails when it is stale;
``python -m dfwb.build_fmus.parameters`` writes it again.

For each plant ``P`` it defines ``DFWB_P_PARAMS`` (the length of
``dfwb_P_new``'s array) and ``DFWB_P_<name>`` (a parameter's index there),
then ``DFWB_LOOP_P_PARAMS`` and ``DFWB_P_LOOP_<name>`` for ``dfwb_loop_new``.
"""

import sys
from pathlib import Path

from dfwb.fmus import backlash, friction, static_backlash

from .core import NATIVE_DIR

HEADER = NATIVE_DIR / "dfwb_parameters.h"
PLANTS = (("FRICTION", friction.TABLE), ("BACKLASH", backlash.TABLE), ("STATIC_BACKLASH", static_backlash.TABLE))
"""(C prefix, table) of the core's plants, in the order of their DFWB_PLANT_* kinds."""


def _block(title, count, prefix, names):
    width = max(len(f"{prefix}_{name}") for name in names) + 1
    lines = [f"/* {title}: {{{', '.join(names)}}} */", f"#define {count} {len(names)}"]
    lines += [f"#define {f'{prefix}_{name}':<{width}}{index}" for index, name in enumerate(names)]
    return lines + [""]


def header_text():
    """The text of dfwb_parameters.h."""
    lines = ["/* dfwb_parameters.h - the plants' parameter orders in the C core, written from their tables",
             " * (fmus/table.py) by `python -m dfwb.build_fmus.parameters`; do not edit. */",
             "#ifndef DFWB_PARAMETERS_H", "#define DFWB_PARAMETERS_H", ""]
    for prefix, table in PLANTS:
        name = prefix.lower()
        lines += _block(f"dfwb_{name}_new", f"DFWB_{prefix}_PARAMS", f"DFWB_{prefix}", table.core_order)
        lines += _block(f"dfwb_loop_new, the {name.replace('_', ' ')} loop", f"DFWB_LOOP_{prefix}_PARAMS",
                        f"DFWB_{prefix}_LOOP", table.loop_order)
    return "\n".join(lines + ["#endif", ""])


def main():
    HEADER.write_text(header_text())
    print(f"wrote {HEADER}", file=sys.stderr)


if __name__ == "__main__":
    main()
