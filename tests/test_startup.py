"""What a cached re-run of a scene loads: never the heavy libraries it does not need.

A scene whose points and figures are all in the cache, written into a new
folder, only copies: it must not import python-control (only the limit
cycles need it) nor pyplot (the figures come from the cache). Measured with
the command line in a fresh process, as a user runs it.
"""

import os
import subprocess
import sys

from test_hardening import FIGURE_SCENE as SCENE  # a scene with two points and one figure

PROBE = """
import sys
from dfwb.cli import main
code = main(["run", sys.argv[1], "--out", sys.argv[2], "--cache", sys.argv[3], "--fmus", sys.argv[4]])
print("LOADED", "control" in sys.modules, "matplotlib.pyplot" in sys.modules, code)
"""


def _run(tmp_path, scene, out, fmus):
    env = dict(os.environ, MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, "-c", PROBE, str(scene), str(out), str(tmp_path / "cache"), str(fmus)],
                          capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    return done.stdout.split("LOADED")[-1].split()


def test_a_cached_rerun_imports_neither_control_nor_pyplot(fmus, tmp_path):
    scene = tmp_path / "two.toml"
    scene.write_text(SCENE)
    folder = fmus["FrictionMass"].parent
    assert _run(tmp_path, scene, tmp_path / "first", folder) == ["False", "True", "0"]  # it draws
    assert _run(tmp_path, scene, tmp_path / "second", folder) == ["False", "False", "0"]
    assert (tmp_path / "second" / "nyquist.png").stat().st_size > 10_000


def test_a_run_says_where_its_time_went(fmus, tmp_path):
    from dfwb.studies.runner import phase_times, run_scene
    from dfwb.studies.scene import parse_scene

    outcome = run_scene(parse_scene(SCENE), tmp_path / "out", jobs=1, cache=tmp_path / "cache",
                        fmu_dir=fmus["FrictionMass"].parent)
    assert {"start", "points", "traces", "limit cycles", "results", "figures"} == set(outcome.phases)
    assert 0.0 < sum(outcome.phases.values()) <= outcome.seconds
    assert outcome.phases["figures"] > 0.0 and "figures" in phase_times(outcome.phases)
    assert phase_times(outcome.phases) in (tmp_path / "out" / "summary.md").read_text()
