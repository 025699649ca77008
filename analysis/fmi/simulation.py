"""Run an FMU with fmpy, and never accept a quietly shortened result.

fmpy's ``simulate_fmu`` stops without an error when an FMU discards a step,
and an FMU's own explanation only reaches a logger that fmpy leaves off by
default. :func:`simulate` turns on the logger, keeps the FMU's warnings and
errors, and raises :class:`FMUError` naming the FMU, the time and the reason
when a call fails or the result ends before ``stop_time``.
"""

import atexit
import ctypes
import functools
import hashlib
import multiprocessing.util
import os
import shutil
import tempfile
from pathlib import Path

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException

from dfwb.base import stop
from dfwb.base.errors import DfwbError
from dfwb.fmi.status import Messages


class FMUError(DfwbError, RuntimeError):
    """An FMU refused a call or a step; the message says which, when and why."""


_FOLDERS = []  # (pid, folder): the folders each process unpacked FMUs into (a forked child inherits the list)
_HOOKED = set()  # the processes (pids) whose multiprocessing exit removes their folders too


@atexit.register
def _remove_folders():
    """Remove the unpacked FMUs when the process exits (registered first, so run last: after the release below,
    which finds the loaded libraries by their paths). Only this process's own: a forked child's exit leaves
    its parent's folders, which the parent still uses."""
    for pid, folder in _FOLDERS:
        if pid == os.getpid():
            shutil.rmtree(folder, ignore_errors=True)


@atexit.register
def release_pythonfmu_states():
    """Empty every loaded pythonfmu library's Python state before the process exits.

    A pythonfmu 0.7.0 binary can never be unloaded (a thread pins it), and at
    exit its C++ static ``shared_ptr<PyState>`` is destroyed before the
    library's destructor assigns to it again: a use-after-free that corrupts
    the heap in some runs ("corrupted double-linked list"). Calling the
    exported ``finalizePythonInterpreter`` while Python is alive empties that
    pointer first (in a Python host the state owns nothing else), whichever
    importer loaded the FMU (fmpy, a session, libcosim).
    """
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split(None, 5)[-1].strip().removesuffix(" (deleted)") for line in maps
                     if "/binaries/linux64/" in line and ".so" in line}
    except OSError:
        return
    for path in paths:
        try:
            library = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_NOW)
        except OSError:
            continue
        release = getattr(library, "finalizePythonInterpreter", None)
        if release is not None:
            release()


def _at_process_end():
    """The release, then the removal, as at exit (each harmless twice)."""
    release_pythonfmu_states()
    _remove_folders()


@functools.lru_cache(maxsize=None)
def _extract(fmu_path, digest):
    """Unzip an FMU once per process and content (fmpy would unzip at every run).

    A pool's worker forked by multiprocessing (the fork and forkserver start methods) ends by ``os._exit``,
    after multiprocessing's own exit function but without the atexit handlers: its folders are removed
    there too (a finalizer registered in each process that unpacks: a fork drops its parent's finalizers).
    One ended by a signal removes nothing; the local pools of :mod:`dfwb.studies.executor` have their
    workers unpack inside a folder of the run, which the run removes."""
    if os.getpid() not in _HOOKED:
        _HOOKED.add(os.getpid())
        multiprocessing.util.Finalize(None, _at_process_end, exitpriority=-100)  # last: after children are joined
    target = Path(tempfile.mkdtemp(prefix=f"dfwb_{Path(fmu_path).stem}_"))
    _FOLDERS.append((os.getpid(), target))
    return fmpy.extract(fmu_path, unzipdir=str(target)), fmpy.read_model_description(fmu_path)


def unpacked(fmu_path):
    """(directory, model description) of an FMU, extracted once and reused."""
    fmu_path = str(Path(fmu_path).resolve())
    digest = hashlib.sha256(Path(fmu_path).read_bytes()).hexdigest()
    return _extract(fmu_path, digest)


def sine_input(amplitude, omega, stop_time, samples_per_period, name="f", phase=0.0):
    """Input table for fmpy: ``amplitude cos(omega t + phase)`` sampled on a grid.

    fmpy holds each value over a communication step (pythonfmu FMUs do not
    take input derivatives), so the grid should match the output interval.
    """
    step = 2.0 * np.pi / omega / samples_per_period
    times = np.arange(0.0, stop_time + 0.5 * step, step)
    table = np.zeros(len(times), dtype=[("time", np.float64), (name, np.float64)])
    table["time"] = times
    table[name] = amplitude * np.cos(omega * times + phase)
    return table


def simulate(fmu_path, stop_time, output_interval, start_values=None, outputs=None, input=None):
    """Simulate a co-simulation FMU with fmpy; raise FMUError instead of truncating.

    Returns fmpy's structured array (a column ``time`` plus the outputs).
    """
    if not (output_interval > 0.0):
        raise FMUError(f"output_interval = {output_interval!r}: the communication step must be > 0")
    directory, description = unpacked(fmu_path)
    name = description.modelName
    messages = Messages(labelled=True)
    try:
        result = fmpy.simulate_fmu(
            directory, model_description=description, stop_time=stop_time,
            output_interval=output_interval, start_values=dict(start_values or {}),
            output=outputs, input=input, logger=messages.fmi2(), debug_logging=True, validate=False)
    except FMICallException as error:
        if stop.requested():  # a Ctrl-C or kill that landed inside the FMU's Python code
            raise KeyboardInterrupt from None
        raise FMUError(f"{name}: {error} ({messages.reasons(otherwise='no message from the FMU')})") from None
    reached = float(result["time"][-1]) if len(result) else float("nan")
    if not reached >= stop_time - 1e-9 * max(1.0, abs(stop_time)):
        reasons = messages.reasons(otherwise="the FMU discarded a step without a message")
        raise FMUError(f"{name}: the simulation stopped at t = {reached!r} before "
                       f"stop_time = {stop_time!r} ({reasons})")
    return result
