"""No litter: the folders FMUs are unpacked into (``$TMPDIR/dfwb_*``) are gone when a run ends, also after Ctrl-C.

Each process unpacks an FMU once into a folder of its own, removed by its exit handlers. Two kinds of process
run none: a pool's worker ended by a signal (a Ctrl-C, or an error, stops the run's pool with SIGTERM), and
a worker forked by multiprocessing (the fork and forkserver start methods: it ends by ``os._exit``, after
multiprocessing's own exit function). Hundreds of ``/tmp/dfwb_FrictionMass_*`` were once left so. The run's
pool workers now keep their temporary files in a folder of the pool's, which the run removes once they are
gone; a forked worker removes its own folders in multiprocessing's exit function, and never its parent's.
"""

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from test_interrupt import group, rows

POINTS = ["--F", "5", "10", "20", "40", "--omega-log", "0.5", "20", "60"]  # 240 points: several seconds


def _sweep(fmus, tmp_path):
    """(argv, env) of a ``dfwb sweep`` of the friction plant on two spawned workers, its $TMPDIR empty."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    argv = [sys.executable, "-m", "dfwb.cli", "sweep", "friction", *POINTS, "--out", str(tmp_path / "out"),
            "--jobs", "2", "--no-cache", "--quiet", "--fmus", str(Path(fmus["FrictionMass"]).parent)]
    return argv, dict(os.environ, TMPDIR=str(temporary))


def test_a_sweep_on_worker_processes_leaves_no_folder(fmus, tmp_path):
    argv, env = _sweep(fmus, tmp_path)
    argv[argv.index("--omega-log") + 3] = "8"  # 32 points: done in a moment
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "32 points" in done.stdout, done.stderr
    assert sorted(os.listdir(env["TMPDIR"])) == []


def test_a_ctrl_c_while_the_workers_compute_leaves_no_folder(fmus, tmp_path):
    argv, env = _sweep(fmus, tmp_path)
    temporary, results = Path(env["TMPDIR"]), tmp_path / "out" / "results.csv"
    run = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and run.poll() is None and rows(results) < 4:
            time.sleep(0.02)
        assert run.poll() is None and rows(results) >= 4, "the workers never returned points"
        assert any(temporary.iterdir())  # what the workers unpacked
        os.killpg(run.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        _, err = run.communicate(timeout=60)
        assert run.returncode == 130 and err.decode() == "dfwb sweep: interrupted\n", err
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and group(run.pid):
            time.sleep(0.2)
        assert not group(run.pid)
    finally:
        if run.poll() is None or group(run.pid):
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert sorted(p.name for p in temporary.iterdir()) == []


# A pool of forked workers, each unpacking an FMU the parent has unpacked too (a forked worker finds the parent's
# folder: it must not remove it) and one it has not (it must remove that one when it ends).
_FORKED = """
import concurrent.futures as futures, multiprocessing, os, sys
from pathlib import Path
from dfwb.fmi.simulation import unpacked

def unpack(path):
    return str(unpacked(path)[0])

if __name__ == "__main__":
    method, shared, own = sys.argv[1:]
    mine = unpack(shared)
    with futures.ProcessPoolExecutor(2, multiprocessing.get_context(method)) as pool:
        theirs = set(pool.map(unpack, [shared, own] * 4)) - {mine}
    assert theirs and not any(map(os.path.exists, theirs)), theirs  # each removed by the worker that made it
    assert os.path.isdir(mine), mine  # the parent's, still in use
"""


@pytest.mark.parametrize("method", ["fork", "forkserver"])
def test_forked_pool_workers_remove_their_folders_and_only_theirs(fmus, tmp_path, method):
    script = tmp_path / "forked.py"
    script.write_text(_FORKED)
    # a short folder: a fork server's socket lives in it, and a socket's path has at most 107 bytes (pytest's
    # tmp_path under an xdist worker is too long for it)
    temporary = Path(tempfile.mkdtemp(prefix="dfwb_test_"))
    try:
        done = subprocess.run([sys.executable, str(script), method, str(fmus["FrictionMass"]),
                               str(fmus["StaticBacklash"])], env=dict(os.environ, TMPDIR=str(temporary)),
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        assert sorted(p.name for p in temporary.iterdir()) == []
    finally:
        shutil.rmtree(temporary, ignore_errors=True)
