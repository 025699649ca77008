"""The README and the documentation pages cannot go stale where they can be checked.

- The table of plants (docs/guide/plant-fmus.md) is no copy: docs/conf.py writes it from the registry
  (``dfwb.plants.markdown_table``) when the docs are built.
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
MARK = "<!-- plants: the table of the registered plants"


def test_the_plant_table_is_written_when_the_docs_are_built():
    """plant-fmus.md holds no copy of the table (docs/conf.py writes dfwb.plants.markdown_table() there)."""
    from dfwb.plants import markdown_table, names

    page = PLANT_PAGE.read_text()
    assert MARK in page and "| plant | FMU |" not in page
    rows = markdown_table().splitlines()[2:]
    assert [row.split("`")[1] for row in rows] == list(names())


def _pages():
    return [page for page in PAGES if "_build" not in page.parts and "examples" not in page.parent.parts[-1:]]


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
