"""The README cannot go stale where it can be checked: the plant table, the module names, the pasteable blocks.

The table of plants between the ``plants`` markers is generated from the registry
(:mod:`dfwb.plants`); after adding a plant, ``python tests/test_readme.py`` rewrites it.
"""

import importlib
import re
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
BEGIN = "<!-- plants: generated from the registry; `python tests/test_readme.py` rewrites it -->"
END = "<!-- /plants -->"


def _value(default, unit):
    return f"{default:g}" + (f" {unit}" if unit else "")


def plants_table():
    """The README's table of plants, one row per registered plant, from the registry and the FMU facades."""
    from dfwb.plants import names, plant

    rows = ["| plant | FMU | what it is | parameters (defaults) | outputs | DF of |", "|---|---|---|---|---|---|"]
    for name in names():
        entry = plant(name)
        parameters = ", ".join(f"`{p}` {_value(default, unit)}" for p, default, unit, _ in entry.model.parameters)
        outputs = ", ".join(f"`{o}`" for o, *_ in entry.model.outputs)
        rows.append(f"| `{name}` | `{entry.fmu_name}.fmu` | {entry.summary} | {parameters} | {outputs} | "
                    f"`{entry.output}` |")
    return "\n".join(rows)


def _split(text):
    """(before, table, after) around the generated table."""
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[:start], text[start:end].strip(), text[end:]


def test_the_plant_table_is_the_registrys():
    _, table, _ = _split(README.read_text())
    assert table == plants_table(), "README.md's plant table is stale: run `python tests/test_readme.py`"


def test_every_dfwb_name_in_the_readme_exists():
    """`dfwb.engine.describing.F_RANGE` and the like: a module moved or renamed breaks this."""
    missing = []
    for name in sorted(set(re.findall(r"`(dfwb(?:\.[A-Za-z_]\w*)+)", README.read_text()))):
        parts = name.split(".")
        for i in range(len(parts), 0, -1):
            try:
                obj = importlib.import_module(".".join(parts[:i]))
            except ImportError:
                continue
            try:
                for part in parts[i:]:
                    obj = getattr(obj, part)
            except AttributeError:
                missing.append(name)
            break
    assert not missing, f"README.md names what does not exist: {missing}"


def test_shell_blocks_can_be_pasted():
    """No `$ ` prompts in ```sh blocks (output goes in a plain ``` block)."""
    blocks = re.findall(r"```sh\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks
    prompted = [line for block in blocks for line in block.splitlines() if line.lstrip().startswith("$ ")]
    assert not prompted, prompted


def test_no_reference_to_a_missing_file():
    text = README.read_text()
    assert "MODELS.md" not in text
    root = README.parent
    for path in re.findall(r"\]\(((?:docs|examples|tests|scenes)/[^)#]+)\)", text):
        assert (root / path).exists(), path


if __name__ == "__main__":
    before, _, after = _split(README.read_text())
    README.write_text(f"{before}\n\n{plants_table()}\n\n{after}")
    print(f"{README}: plant table rewritten from the registry", file=sys.stderr)
