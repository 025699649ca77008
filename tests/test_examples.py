"""The examples in ``examples/`` run as a user would run them, using only the public API.

The scripts run in a subprocess with ``MPLBACKEND=Agg``, writing into a
temporary folder. The notebook is executed without a Jupyter kernel
(nbclient is not a dependency): its code cells run in order with ``exec``
in one namespace, after nbformat has read and validated the file; a
notebook's last expression is not displayed, which changes nothing here.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))


def test_the_examples_exist():
    assert {p.name for p in SCRIPTS} >= {"df_sweep.py", "limit_cycle_study.py"}
    assert (EXAMPLES / "df_sweep.ipynb").exists()


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_an_example_uses_only_the_public_api(path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        else:
            continue
        assert all(name == "dfwb" or not name.startswith("dfwb") for name in names), f"{path.name}: {names}"


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_an_example_script_runs(fmus, tmp_path, path):
    env = dict(os.environ, MPLBACKEND="Agg", MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, str(path), str(tmp_path / "out")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    pngs = list((tmp_path / "out").glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mpl", "out"]  # nothing written elsewhere


def test_the_notebook_runs(fmus, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    notebook = nbformat.read(EXAMPLES / "df_sweep.ipynb", as_version=4)
    nbformat.validate(notebook)
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__main__"}
    cells = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert cells
    try:
        for i, cell in enumerate(cells):
            for line in cell.source.splitlines():
                assert not line.lstrip().startswith(("%", "!")), f"cell {i}: a magic cannot run without IPython"
                assert not line.lstrip().startswith(("from dfwb.", "import dfwb.")), f"cell {i}: not the public API"
            exec(compile(cell.source, f"df_sweep.ipynb cell {i}", "exec"), namespace)
        assert namespace["response"].N.shape == (3, 20) and len(namespace["lines"]) == 3
    finally:
        plt.close("all")
    assert list(tmp_path.iterdir()) == []  # the notebook writes no file
