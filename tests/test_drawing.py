"""Figures drawn in worker processes (:mod:`dfwb.studies.drawing`), as ``dfwb paper`` draws them while the
next scene computes: the same figures as drawn in the run's process, a figure's error raised where the
run waits for it, and the folder unlocked either way."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_hardening import FIGURE_SCENE

from dfwb.base.errors import RunError
from dfwb.studies.drawing import Drawing
from dfwb.studies.runner import begin_scene, run_scene
from dfwb.studies.scene import parse_scene

# A paper figure over points it cannot be drawn from: fig12 wants its own scene's frequencies.
BROKEN = FIGURE_SCENE + '''
[[figure]]
name = "p"
kind = "paper"
paper = "fig12"

[[series]]
name = "backlash_F50"
plant = "backlash"
F = [50.0]
omega = [20.0]
'''


def test_figures_drawn_in_worker_processes_equal_those_drawn_here(fmus, tmp_path):
    cache, folder = tmp_path / "cache", fmus["FrictionMass"].parent
    here = run_scene(parse_scene(FIGURE_SCENE.replace("one figure", "figure 0"), "f.toml"), tmp_path / "here",
                     jobs=1, cache=False, fmu_dir=folder, progress=False)
    with Drawing(2) as drawing:
        runs = [begin_scene(parse_scene(FIGURE_SCENE.replace("one figure", f"figure {n}"), "f.toml"),
                            tmp_path / f"pool{n}", 1, None, cache, folder, False, drawing) for n in range(2)]
        outcomes = [run.finish() for run in runs]
    for n, outcome in enumerate(outcomes):
        assert [path.name for path in outcome.figures] == ["nyquist.png"] == [path.name for path in here.figures]
        assert (tmp_path / f"pool{n}" / "nyquist.png").stat().st_size > 10_000
        assert (tmp_path / f"pool{n}" / "nyquist.svg").stat().st_size > 10_000
        assert "figures" in outcome.phases and not (tmp_path / f"pool{n}" / ".dfwb.lock").exists()
    assert (tmp_path / "pool0" / "nyquist.png").read_bytes() == (tmp_path / "here" / "nyquist.png").read_bytes()
    assert outcomes[1].computed == 0 and not outcomes[1].copied  # another scene over the same points


def test_a_figure_that_fails_in_a_drawing_process_fails_the_run_and_unlocks_the_folder(fmus, tmp_path):
    folder = fmus["FrictionMass"].parent
    with Drawing(1) as drawing:
        run = begin_scene(parse_scene(BROKEN, "b.toml"), tmp_path / "out", 1, None, False, folder, False, drawing)
        with pytest.raises(RunError, match="figure p: the paper's fig12 cannot be drawn from this scene's points"):
            run.finish()
    assert not (tmp_path / "out" / ".dfwb.lock").exists() and not (tmp_path / "out" / "manifest.json").exists()
    again = run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "out", jobs=1, cache=False, fmu_dir=folder,
                      progress=False)  # the folder is free again
    assert again.points == 2 and (tmp_path / "out" / "nyquist.png").exists()


def _children(pid):
    """The pids of the processes whose parent is ``pid`` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def _alive(pid):
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_the_drawing_processes_end_when_the_run_is_killed(fmus, tmp_path, killed_run_tmpdir):
    """kill -9 of ``dfwb paper`` skips every cleanup: its fork server and drawing processes still end."""
    command = [sys.executable, "-m", "dfwb.cli", "paper", "--quiet", "--out", str(tmp_path / "p"),
               "--cache", str(tmp_path / "c"), "--fmus", str(fmus["FrictionMass"].parent)]
    run = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           env=dict(os.environ, TMPDIR=str(killed_run_tmpdir)))
    try:
        drawing = []
        for _ in range(300):  # until the fork server has forked its drawing processes (at most 30 s)
            servers = [pid for pid in _children(run.pid)
                       if b"forkserver" in (Path("/proc") / str(pid) / "cmdline").read_bytes()]
            drawing = [(server, _children(server)) for server in servers]
            if any(children for _, children in drawing) or run.poll() is not None:
                break
            time.sleep(0.1)
        assert run.poll() is None and drawing, "the run ended before it drew"
        os.kill(run.pid, signal.SIGKILL)
        run.wait()
        left = [pid for server, children in drawing for pid in [server, *children]]
        for _ in range(100):  # the orphan watch looks every 0.5 s
            left = [pid for pid in left if _alive(pid)]
            if not left:
                break
            time.sleep(0.1)
        assert left == []
    finally:
        if run.poll() is None:
            run.kill()
