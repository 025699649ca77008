"""What a cached re-run of a scene loads: never the heavy libraries it does not need.

A scene whose points, traces and figures are all in the cache, written into a
new folder, only copies: it must not import python-control (only the limit
cycles need it) nor pyplot (the figures come from the cache), nor the engine's
FMU runtime (fmpy, numpy: nothing is simulated), the worker pool, the
progress display. Checked by the modules a fresh process has loaded
(not by timing, which the machine's load blurs), with the command line run
as a user runs it. ``benchmarks/startup.py`` measures the time.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_hardening import FIGURE_SCENE  # a scene with two points and one figure

SCENE = FIGURE_SCENE + '''
[[trace]]
name = "short"
plant = "friction"
F = 10.0
omega = 1.0
stop = 1.0
step = 0.01
outputs = ["x"]
'''

# Never loaded by a cached re-run of SCENE (no log-spaced grid, no limit cycle): what runs, draws or shows work.
NOT_NEEDED = ("control", "matplotlib", "fmpy", "numpy", "scipy", "rich", "multiprocessing",
              "concurrent.futures.process", "dfwb.fmi.session", "dfwb.fmi.simulation", "dfwb.plotting.plots",
              "dfwb.build_fmus.builder", "pydantic")

PROBE = """
import json
import sys
from dfwb.cli import main
code = main(["run", sys.argv[1], "--out", sys.argv[2], "--cache", sys.argv[3], "--fmus", sys.argv[4]])
print("LOADED", json.dumps([code, sorted(name for name in sys.modules if not name.startswith("_"))]))
"""


def _run(tmp_path, scene, out, fmus):
    """(exit code, the modules the command's process has loaded)."""
    env = dict(os.environ, MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, "-c", PROBE, str(scene), str(out), str(tmp_path / "cache"), str(fmus)],
                          capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    code, modules = json.loads(done.stdout.split("LOADED")[-1])
    return code, set(modules)


@pytest.fixture(scope="module")
def runs(fmus, tmp_path_factory):
    """The folder, and (code, modules) of a first run that computes and draws, then of a cached re-run."""
    tmp_path = tmp_path_factory.mktemp("startup")
    scene = tmp_path / "two.toml"
    scene.write_text(SCENE)
    folder = fmus["FrictionMass"].parent
    first = _run(tmp_path, scene, tmp_path / "first", folder)
    second = _run(tmp_path, scene, tmp_path / "second", folder)
    return tmp_path, first, second


def test_a_cached_rerun_imports_neither_control_nor_pyplot(runs):
    tmp_path, (code, first), (again, second) = runs
    assert code == again == 0
    assert "control" not in first and "matplotlib.pyplot" in first  # it draws
    assert "control" not in second and "matplotlib.pyplot" not in second
    assert (tmp_path / "second" / "nyquist.png").stat().st_size > 10_000
    assert (tmp_path / "second" / "traces" / "short.csv").read_text() == \
        (tmp_path / "first" / "traces" / "short.csv").read_text()


def test_a_cached_rerun_loads_no_engine_pool_or_display(runs):
    """Nothing runs an FMU, spawns a worker or shows progress: fmpy, numpy, scipy, the pool and rich
    stay unloaded (the first run, which computes, loads the engine: the probe sees imports)."""
    _, (_, first), (_, second) = runs
    assert {"fmpy", "numpy", "dfwb.fmi.simulation"} <= first
    assert sorted(name for name in NOT_NEEDED if name in second) == []


SHIPPED = sorted((Path(__file__).resolve().parents[1] / "scenes").glob("*.toml"))


@pytest.fixture(scope="module")
def two_workers():
    """One executor of 2 local worker processes for the shipped scenes' first runs: its pool starts once, not once
    a scene (as ``dfwb paper`` shares one among its scenes)."""
    from dfwb.studies.executor import Executor

    with Executor(2) as executor:
        yield executor


@pytest.mark.slow
@pytest.mark.parametrize("path", SHIPPED, ids=lambda path: path.stem)
def test_a_cached_rerun_of_every_shipped_scene_is_a_copy_that_loads_nothing_heavy(fmus, two_workers, tmp_path, path):
    """Log-spaced grids, paper figures and limit cycles included: python-control, numpy and pyplot stay
    unloaded (``benchmarks/startup.py --shipped`` times the same re-runs)."""
    from dfwb.studies.runner import begin_scene

    folder = fmus["FrictionMass"].parent
    first = begin_scene(path, tmp_path / "first", cache=tmp_path / "cache", fmu_dir=folder, progress=False,
                        executor=two_workers).finish()  # run_scene(path, jobs=2, ...) on the shared pool
    assert not first.copied and not first.failed
    code, modules = _run(tmp_path, path, tmp_path / "second", folder)
    assert code == 0 and sorted(name for name in NOT_NEEDED if name in modules) == []
    assert "every output copied from the cache" in (tmp_path / "second" / "summary.md").read_text()
    assert (tmp_path / "second" / "results.json").read_bytes() == (tmp_path / "first" / "results.json").read_bytes()


def test_a_run_says_where_its_time_went(fmus, tmp_path):
    from dfwb.studies.runner import phase_times, run_scene
    from dfwb.studies.scene import parse_scene

    outcome = run_scene(parse_scene(FIGURE_SCENE), tmp_path / "out", jobs=1, cache=tmp_path / "cache",
                        fmu_dir=fmus["FrictionMass"].parent)
    assert {"start", "points", "traces", "limit cycles", "results", "figures"} == set(outcome.phases)
    assert 0.0 < sum(outcome.phases.values()) <= outcome.seconds + 1e-9  # the phases add up to the run
    assert outcome.phases["figures"] > 0.0 and "figures" in phase_times(outcome.phases)
    assert phase_times(outcome.phases) in (tmp_path / "out" / "summary.md").read_text()
