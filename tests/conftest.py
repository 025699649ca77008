"""Shared fixtures: the FMUs (plants and controller) and the C core, built once from the current sources.

Every build goes into a folder of the checkout's ``build/`` keyed by its sources' hash, under a lock: the
pytest-xdist workers (``make test`` runs one per core) and later sessions share it, so the first to need an FMU
builds it and the others find it up to date.
"""

import contextlib
import fcntl
import os
import shutil
import tempfile
from pathlib import Path

import pytest
from fmpy.fmi1 import calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from hypothesis import settings

from dfwb.build_fmus import build_all
from dfwb.build_fmus.builder import build
from dfwb.fmi.location import NATIVE_FMI3_FOLDER, NATIVE_FOLDER
from dfwb.fmi.simulation import unpacked
from dfwb.fmus.loop_facade import LOOPS

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "build"
# The tests share one FMU folder in the checkout (built once, reused across sessions and by the
# subprocesses they start), instead of the per-user default.
os.environ["DFWB_FMU_DIR"] = str(ROOT / "build" / "fmus")

# Property tests: 50 random cases each in CI; DFWB_HYPOTHESIS=stress for 1000.
settings.register_profile("default", max_examples=50, deadline=None)
settings.register_profile("stress", max_examples=1000, deadline=None)
settings.load_profile(os.environ.get("DFWB_HYPOTHESIS", "default"))


@contextlib.contextmanager
def _one_builder(name):
    """Hold build/.NAME.lock while building: one worker builds, the others wait and then find it up to date."""
    BUILD.mkdir(exist_ok=True)
    with open(BUILD / f".{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield BUILD / name


def _has_cc():
    return any(shutil.which(name) for name in ("cc", "gcc", "clang"))


def _needs_cc(what):
    if not _has_cc():
        pytest.skip(f"no C compiler (cc) on PATH to build {what}")


@pytest.fixture(scope="session")
def fmus():
    """{model name: path} of every FMU the project builds (:func:`project_fmus`)."""
    return project_fmus()


def project_fmus():
    """{model name: path} of every FMU the project builds (the plants, their naive twins, LinearSystem, the
    exact closed loops), built into build/fmus if stale; with a C compiler
    the native plant FMUs (FMI 2.0) too, into its native/, where the runs of the default FMU kind find them
    (built here once, not by every worker that runs a plant first)."""
    with _one_builder("fmus") as folder:
        paths = build_all(folder, report=lambda message: None) + build(folder, LOOPS, report=lambda message: None)
        if _has_cc():
            from dfwb.build_fmus.native import build_native

            build_native(folder / NATIVE_FOLDER, report=lambda message: None)
    return {path.stem: path for path in paths}


WARNINGS = ("-Wall", "-Wextra", "-Werror")  # the test builds of the C sources: any warning fails them
_KEEP_ALIVE = []  # raw instances are never freed: after a fatal status pythonfmu 0.7.0 would free twice


def new_instance(path, name="raw"):
    """(FMU2Slave instantiated through fmpy's raw FMI 2.0 API, its model description, its log [(status, text)])."""
    directory, description = unpacked(path)
    messages = []

    def log(_env, _instance, status, _category, text):
        messages.append((status, text.decode()))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    fmu = FMU2Slave(guid=description.guid, unzipDirectory=directory,
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(loggingOn=True, callbacks=callbacks)
    _KEEP_ALIVE.append((fmu, callbacks))
    return fmu, description, messages


@pytest.fixture
def raw_fmu(fmus):
    """make(model) -> (instance initialised at t = 0 through fmpy's raw FMI 2.0 API, its log messages)."""

    def make(model):
        fmu, _, messages = new_instance(fmus[model])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        return fmu, messages

    return make


@pytest.fixture(autouse=True, scope="session")
def private_cache(tmp_path_factory):
    """Tests never read or fill the user's cache ($XDG_CACHE_HOME/dfwb): each session gets its own."""
    os.environ["XDG_CACHE_HOME"] = str(tmp_path_factory.mktemp("xdg-cache"))


@pytest.fixture
def killed_run_tmpdir():
    """A folder for the TMPDIR of a run the test kills with SIGKILL, removed after the test: what the run
    unpacked stays there, not in the machine's temporary folder. Short, under the machine's: a fork server's
    socket lives there too, and a socket's path has at most 107 bytes (an xdist worker's tmp_path is longer)."""
    folder = Path(tempfile.mkdtemp(prefix="dfwb-test-"))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session")
def core():
    """The C core (fmus/native), compiled with warnings as errors (skips without a C compiler)."""
    from dfwb.build_fmus.core import build_core
    from dfwb.fmus.native_core import load

    _needs_cc("fmus/native")
    with _one_builder("test-core") as folder:
        return load(build_core(folder, extra_flags=WARNINGS))


def native_of(fmi_version, fmus):
    """{model name: path} of the native plant FMUs of FMI ``fmi_version`` that dfwb runs: the FMU folder's
    (FMI 2.0: built with ``fmus``; FMI 3.0: built here, once). Their sources compile without a warning:
    tests/test_native_fmus.py builds one of them with :data:`WARNINGS`."""
    from dfwb.build_fmus.native import build_native

    _needs_cc("the native FMUs")
    folder = fmus["FrictionMass"].parent / (NATIVE_FOLDER if fmi_version == 2 else NATIVE_FMI3_FOLDER)
    with _one_builder(f"native-fmi{fmi_version}"):
        paths = build_native(folder, report=lambda message: None, fmi_version=fmi_version)
    return {path.stem: path for path in paths}


@pytest.fixture(scope="session")
def native_fmus(fmus):
    """{model name: path} of the native plant FMUs (C core + FMI wrapper) (skips without a C compiler)."""
    return native_of(2, fmus)


@pytest.fixture(scope="session")
def fmi3_fmus(fmus):
    """{model name: path} of the native plant FMUs as FMI 3.0."""
    return native_of(3, fmus)


@pytest.fixture
def solver(monkeypatch):
    """use(kind) for the FMUs on the compiled core: None unsets DFWB_FMU_SOLVER, "python" or "native" sets it
    (for the instances made next)."""
    from dfwb.fmus import facade

    def use(kind):
        if kind is None:
            monkeypatch.delenv(facade.SOLVER_VARIABLE, raising=False)
        else:
            monkeypatch.setenv(facade.SOLVER_VARIABLE, kind)

    use(None)
    return use
