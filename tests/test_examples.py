"""The examples in ``examples/`` run as a user would run them, using only the public API.

The scripts run in a subprocess with ``MPLBACKEND=Agg``, writing into a
temporary folder. The notebooks are executed without a Jupyter kernel
(nbclient is not a dependency): their code cells run in order with ``exec``
in one namespace, after nbformat has read and validated the file; a
notebook's last expression is not displayed, which changes nothing here.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))


def test_the_examples_exist():
    assert {p.name for p in SCRIPTS} >= {"df_sweep.py", "limit_cycle_study.py", "drive_train.py"}
    assert (EXAMPLES / "df_sweep.ipynb").exists()
    assert (EXAMPLES / "hunting.ipynb").exists()


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


@pytest.mark.slow
@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_an_example_script_runs(fmus, tmp_path, path):
    env = dict(os.environ, MPLBACKEND="Agg", MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, str(path), str(tmp_path / "out")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)  # a guard against a hang, loose for a busy machine
    assert done.returncode == 0, done.stderr
    pngs = list((tmp_path / "out").glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mpl", "out"]  # nothing written elsewhere


def test_the_notebook_runs(fmus, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    try:
        namespace = _run_notebook(nbformat, "df_sweep.ipynb")
        assert namespace["response"].N.shape == (3, 20) and len(namespace["lines"]) == 3
    finally:
        plt.close("all")
    assert list(tmp_path.iterdir()) == []  # the notebook writes no file


def _run_notebook(nbformat, name):
    """The namespace after the code cells of ``examples/<name>`` ran in order (the file read and validated)."""
    notebook = nbformat.read(EXAMPLES / name, as_version=4)
    nbformat.validate(notebook)
    namespace = {"__name__": "__main__"}
    cells = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert cells
    for i, cell in enumerate(cells):
        for line in cell.source.splitlines():
            assert not line.lstrip().startswith(("%", "!")), f"cell {i}: a magic cannot run without IPython"
            assert not line.lstrip().startswith(("from dfwb.", "import dfwb.")), f"cell {i}: not the public API"
        exec(compile(cell.source, f"{name} cell {i}", "exec"), namespace)
    return namespace


def _hunting(hunting_map):
    """(linear loop stable, hunts by the truth, hunts by the DF): boolean arrays over a map's cells."""
    linear = np.array([[cell["linear"]["stable"] for cell in row] for row in hunting_map.cells])
    return linear, hunting_map.classes("truth") == "stable", hunting_map.classes("df") == "stable"


@pytest.mark.slow
def test_the_hunting_notebook_answers(fmus, tmp_path, monkeypatch):
    """examples/hunting.ipynb on 3 x 3 maps (DFWB_HUNTING_N; 12 x 12 as committed): what it says holds.

    With Fs > Fc every PI and PID setting whose linear loop is stable hunts by the truth, and the DF misses
    most of the hunting; with Fs = Fc nothing hunts; the PI loop at Kp = 10, Ki = 2 hunts with a period of
    57.26 s that the DF cannot represent; the hunting branch in Ki ends in a nonsmooth fold near 24.77 and
    at infinity at the linear boundary Ki = 5; the PID's margin: it hunts for any larger gain, the DF says not;
    with a gear's play in front of the load (drivetrain), every stabilizing PI still hunts and the DF misses
    most of that; with Stribeck friction (stribeck) a stiff Kp with a weak Ki comes to rest from every start.
    """
    nbformat = pytest.importorskip("nbformat")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    notebook = nbformat.read(EXAMPLES / "hunting.ipynb", as_version=4)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert all(cell.outputs == [] and cell.execution_count is None for cell in code)  # committed without outputs
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DFWB_HUNTING_N", "3")
    try:
        namespace = _run_notebook(nbformat, "hunting.ipynb")
    finally:
        plt.close("all")
    assert list(tmp_path.iterdir()) == []  # the notebook writes no file
    assert namespace["N"] == 3

    one = namespace["one"]
    assert one.predictions == [] and len(one.cycles) == 1
    cycle = one.cycles[0]
    assert cycle.stable and cycle.period == pytest.approx(57.26, abs=0.01) and cycle.F < 7.0
    assert "below the threshold 7 N" in cycle.df

    for name in ("pi_map", "pid_map"):  # Fs = 7 N > Fc = 5 N
        linear, truth, df = _hunting(namespace[name])
        assert linear.shape == (3, 3) and linear.any(), name
        assert truth[linear].all(), f"{name}: a stabilizing setting that does not hunt"
        assert (truth & ~df).sum() > truth.sum() / 2, f"{name}: the DF sees most of the hunting"
        assert not (df & ~truth).any(), f"{name}: the DF predicts hunting the truth does not find"
    linear, truth, df = _hunting(namespace["gear_map"])  # the drivetrain under PI
    assert linear.any() and truth[linear].all(), "gear_map: a stabilizing setting that does not hunt"
    assert (truth & linear & ~df).sum() > (truth & linear).sum() / 2, "gear_map: the DF sees most of the hunting"
    assert not (df & ~truth).any(), "gear_map: the DF predicts hunting the truth does not find"
    stribeck = namespace["stribeck_map"]  # the Stribeck fall: stiff Kp with weak Ki comes to rest
    linear, truth, df = _hunting(stribeck)
    assert truth[linear].any() and not truth[0, -1], "stribeck_map: no hunting, or hunting at Kp 40, Ki 2"
    assert stribeck.cells[0][-1]["truth"]["class"] == "none"
    assert set(stribeck.cells[0][-1]["truth"]["coverage"]["outcomes"]) == {"rest"}  # every start, proven
    assert not (df & ~truth).any(), "stribeck_map: the DF predicts hunting the truth does not find"
    for name in ("pi_coulomb", "pid_coulomb"):  # Fs = Fc = 5 N
        linear, truth, df = _hunting(namespace[name])
        assert linear.any() and not truth.any(), f"{name}: hunts without static friction"
        assert df.any(), f"{name}: the DF's false alarm is gone"
        assert set(namespace[name].classes("truth").ravel()) <= {"none", "diverges", "unstable", "incomplete"}
    for row in namespace["pi_coulomb"].cells:  # under PI, every run came to rest (a PID start may creep on)
        for cell in row:
            if cell["linear"]["stable"]:
                assert cell["truth"]["class"] == "none", cell
                assert set(cell["truth"]["coverage"]["outcomes"]) == {"rest"}, cell
    assert namespace["pi_coulomb"].values["Fs"] == namespace["pid_coulomb"].values["Fs"] == 5.0  # Fc = 5 N
    assert "Fs" not in namespace["pi_map"].values and "Fs" not in namespace["pid_map"].values  # 7 N

    kinds = [(b.kind, b.parameter) for b in namespace["branch"].bifurcations]
    assert any(kind == "nonsmooth-fold" and 24.0 < value < 25.5 for kind, value in kinds), kinds
    assert any(kind == "infinity" and value == pytest.approx(5.0, abs=1e-6) for kind, value in kinds), kinds
    df_stable = [p.parameter for b in namespace["df_branch"].branches for p in b.points if p.stable]
    assert df_stable and min(df_stable) > 12.0  # the DF is blind to the hunting at small Ki
    assert any(b.kind == "fold" and 25.0 < b.parameter < 26.5 for b in namespace["df_branch"].bifurcations)

    margin = namespace["margin"]
    assert margin.truth.hunts_at(1.0) and margin.truth.hunts_at(2.0) and margin.truth.hunts_at(50.0)
    assert not margin.truth.hunts_at(0.1)  # it diverges (the nonsmooth fold at k = 0.277)
    assert margin.df.hunts_at(1.0) and not margin.df.hunts_at(2.0)  # the DF's false cure: more gain
