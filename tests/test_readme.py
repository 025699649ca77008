"""The README and the documentation pages cannot go stale where they can be checked.

- The table of plants between the ``plants`` markers (docs/guide/plant-fmus.md) is generated from the
  registry (:mod:`dfwb.plants`); after adding a plant, ``python tests/test_readme.py`` rewrites it.
- Every ``dfwb.x.y`` a page names exists; every relative link points to a file that exists; shell blocks
  can be pasted (no ``$`` prompts).
- The README's tour runs: each command of its shell blocks after the set-up (with the venv's ``dfwb`` and
  ``fmpy``, in a temporary folder) and its Python blocks, in order.
"""

import importlib
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README] + sorted((ROOT / "docs").rglob("*.md"))
PLANT_PAGE = ROOT / "docs" / "guide" / "plant-fmus.md"
BEGIN = "<!-- plants: generated from the registry; `python tests/test_readme.py` rewrites it -->"
END = "<!-- /plants -->"


def _value(default, unit):
    return f"{default:g}" + (f" {unit}" if unit else "")


def plants_table():
    """The table of plants, one row per registered plant, from the registry and the FMU facades."""
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


def _pages():
    return [page for page in PAGES if "_build" not in page.parts and "examples" not in page.parent.parts[-1:]]


def test_the_plant_table_is_the_registrys():
    _, table, _ = _split(PLANT_PAGE.read_text())
    assert table == plants_table(), f"{PLANT_PAGE.name}'s plant table is stale: run `python tests/test_readme.py`"


def test_every_dfwb_name_in_the_pages_exists():
    """`dfwb.engine.describing.F_RANGE` and the like: a module moved or renamed breaks this."""
    missing = []
    for page in _pages():
        for name in sorted(set(re.findall(r"`(dfwb(?:\.[A-Za-z_]\w*)+)", page.read_text()))):
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
                    missing.append(f"{page.name}: {name}")
                break
    assert not missing, f"the pages name what does not exist: {missing}"


def test_shell_blocks_can_be_pasted():
    """No `$ ` prompts in ```sh blocks (output goes in a plain ``` block)."""
    prompted = []
    for page in _pages():
        for block in re.findall(r"```sh\n(.*?)```", page.read_text(), flags=re.S):
            prompted += [f"{page.name}: {line}" for line in block.splitlines() if line.lstrip().startswith("$ ")]
    assert not prompted, prompted


def test_no_link_to_a_missing_file():
    missing = []
    for page in _pages():
        text = page.read_text()
        assert "MODELS.md" not in text, page
        for target in re.findall(r"\]\(([^)#:\s]+)(?:#[^)]*)?\)", text):
            if not (page.parent / target).exists():
                missing.append(f"{page.relative_to(ROOT)}: {target}")
    assert not missing, missing


def _tour():
    """(shell commands, python blocks) of the README after its set-up block."""
    text = README.read_text().split("## A five-minute tour", 1)[1].split("\n## ", 1)[0]
    commands = [line.split("  #")[0].strip() for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S)
                for line in block.splitlines() if line.strip()]
    return commands, re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.mark.slow
def test_the_readme_tour_runs(fmus, tmp_path):
    commands, python = _tour()
    assert len(commands) >= 8 and all(command.startswith(".venv/bin/") for command in commands)
    bin_dir = Path(sys.executable).parent
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    (tmp_path / "out").mkdir()
    env = dict(os.environ, MPLBACKEND="Agg")
    for command in commands:
        words = shlex.split(command)
        words[0] = str(bin_dir / Path(words[0]).name)
        run = subprocess.run(words, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, f"{command}:\n{run.stderr[-2000:]}"
    assert (tmp_path / "out" / "lc.png").stat().st_size > 10_000 and (tmp_path / "out" / "backlash.csv").exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["out", "scenes"]  # all of it in out/
    import matplotlib

    matplotlib.use("Agg")
    namespace = {}
    for block in python:
        exec(compile(block, "README.md", "exec"), namespace)
    assert namespace["r"].cycles and namespace["r"].coverage


if __name__ == "__main__":
    before, _, after = _split(PLANT_PAGE.read_text())
    PLANT_PAGE.write_text(f"{before}\n\n{plants_table()}\n\n{after}")
    print(f"{PLANT_PAGE}: plant table rewritten from the registry", file=sys.stderr)
