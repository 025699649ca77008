"""Ctrl-C: a run ends quietly, at once, with exit code 130, and leaves nothing running.

A terminal's Ctrl-C sends SIGINT to every process of the foreground group: the run, its spawned point
workers, the drawing processes and their fork server. Only the run reports it ("interrupted", exit 130);
the others ignore it, no process prints a traceback, and every one of them is gone soon after. The
``dfwb paper --jobs 2`` run is interrupted while its points are computed on two workers, and while its
figures are drawn (its drawing processes were once left running, the run waiting for them at exit).
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

PAPER_FIRST = "fig06_friction_harmonics"  # the paper's first scene (harmonics first): its points come first


def group(pgid):
    """{pid: (state, command line)} of the live processes (not zombies) of the process group ``pgid``."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rpartition(")")[2].split()
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # gone meanwhile
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            found[int(entry.name)] = (fields[0], command)
    return found


def rows(path):
    try:
        return max(0, len(path.read_bytes().splitlines()) - 1)
    except OSError:
        return 0


def reached(moment, pgid, out):
    """Whether the run (process group ``pgid``) is at ``moment``: "points", its two spawned point workers
    started and points coming back; "figures", drawing processes forked by the fork server (its children
    run its command line too)."""
    commands = [command for _, command in group(pgid).values()]
    if moment == "points":
        return sum("spawn_main" in command for command in commands) >= 2 and rows(out / PAPER_FIRST / "results.csv")
    return sum("multiprocessing.forkserver" in command for command in commands) >= 2


@pytest.mark.parametrize("moment", ["points", "figures"])
def test_ctrl_c_ends_every_process_quietly(fmus, tmp_path, moment):
    out = tmp_path / "paper"
    argv = [sys.executable, "-m", "dfwb.cli", "paper", "--out", str(out), "--jobs", "2", "--quiet",
            "--cache", str(tmp_path / "cache"), "--fmus", str(Path(fmus["FrictionMass"]).parent)]
    run = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and run.poll() is None and not reached(moment, run.pid, out):
            time.sleep(0.02)
        assert run.poll() is None and reached(moment, run.pid, out), f"the run never reached its {moment}"
        os.killpg(run.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        _, err = run.communicate(timeout=60)
        err = err.decode(errors="replace")
        assert run.returncode == 130, err
        assert "Traceback" not in err and err.strip().splitlines() == ["dfwb paper: interrupted"], err
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and group(run.pid):
            time.sleep(0.2)
        assert not group(run.pid), f"left running after Ctrl-C: {group(run.pid)}"
    finally:
        if run.poll() is None or group(run.pid):
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert not (out / PAPER_FIRST / "manifest.json").exists()  # an interrupted scene never looks finished


HELD = """
import os, signal, time
from dfwb.studies.executor import interrupts_held

# Python's own Ctrl-C handling to start from, whatever the test process passed on (an ignored SIGINT or a blocked
# one is inherited across exec)
signal.signal(signal.SIGINT, signal.default_int_handler)
signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})

steps = []
try:
    with interrupts_held():
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # a KeyboardInterrupt would have come here
        steps.append("started")
    steps.append("not reached")
except KeyboardInterrupt:
    steps.append("interrupted")
print(steps, signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


def test_a_ctrl_c_while_processes_start_is_held_then_delivered_once():
    """In a process of its own: a test process's signal handling is not the test's own (a native library an
    earlier test loaded may have set its own SIGINT handler)."""
    done = subprocess.run([sys.executable, "-c", HELD], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[0] == "['started', 'interrupted'] True"


def test_a_ctrl_c_before_the_command_runs_is_one_line(monkeypatch, capsys):
    """Ctrl-C while the parser is built (the command's modules imported, its arguments read): exit 130 and
    one line, as during the run."""
    from dfwb import cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "parser", interrupted)
    assert cli.main(["--version"]) == 130
    assert capsys.readouterr().err == "dfwb: interrupted\n"


_GIVEN_UP = """
import sys, threading, time
from dfwb.studies import executor

reported = []
threading.excepthook = lambda failure: reported.append(failure.exc_type.__name__)


def chunk_work(chunk):
    time.sleep(0.05 if chunk == 0 else 60)
    return executor.code_revision(), [chunk]


def stop_late(pool, abort, stop=executor.stop_pool):  # the race's other side, made sure: the pool's thread
    for process in list(pool._processes.values()):  # sees its processes gone before it is told to shut down
        process.terminate()
    time.sleep(1)
    stop(pool, abort)


if __name__ == "__main__":
    executor.stop_pool = stop_late
    with executor.Executor(2) as run:
        chunks = run.run(range(8), chunk_work)
        next(chunks)
        chunks.close()  # the rest given up, as on Ctrl-C or an error
        outlived = run._pool is not None
    assert not reported, reported
    assert not outlived, "the pool outlived the run that gave up its chunks"
"""


def test_chunks_given_up_end_the_pool_without_a_traceback(tmp_path):
    """A run that stops early (Ctrl-C, an error) gives up its waiting chunks. Cancelled from the run's thread,
    a waiting chunk's Future met the pool's own thread, which marks every waiting Future failed once a
    process is gone: CPython 3.11 raises InvalidStateError there, and its traceback once broke a Ctrl-C."""
    script = tmp_path / "given_up.py"
    script.write_text(_GIVEN_UP)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
