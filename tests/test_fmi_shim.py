"""The FMI shim (build_fmus/shim/fmi2_shim.c): errors are fmi2Error, the Error state, no crash, no preload.

Every FMU's binaries/linux64/<Model>.so is the shim, forwarding to pythonfmu's
binary <Model>.pythonfmu.so. The tests drive it the way a foreign master
does: fmpy's low-level FMU2Slave in a fresh subprocess that does not import
dfwb (a crash, a heap corruption at exit, shows as a non-zero exit code), the
C host of tests/c_host with an empty environment, and fmpy's command line.

Besides the production FMUs, a tiny test-only pythonfmu FMU, ``Boom``, built
here and packaged with the shim as the builder does: its doStep logs an error
and returns False for a non-finite or huge input f (the way the facades refuse
a call), and raises for f = -1 (pythonfmu's fatal path, which the facades
never take).
"""

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import pytest
from pythonfmu.builder import FmuBuilder

from dfwb.build_fmus import builder

pytestmark = pytest.mark.needs_cc

OK, WARNING, DISCARD, ERROR, FATAL = range(5)

BOOM = '''\
"""Test FMU: x integrates the input f; a non-finite or huge f is refused (error status), f = -1 raises."""
import builtins
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Real
from pythonfmu.enums import Fmi2Status

builtins.__dict__.setdefault("_dfwb_shim_test_pins", []).append(globals())  # see dfwb.fmus.facade.pin


class Boom(Fmi2Slave):
    """Test FMU of the shim."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.f = 0.0
        self.x = 0.0
        self.register_variable(Real("f", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        if not math.isfinite(self.f) or abs(self.f) > 1e100:
            self.log(f"Boom: f = {self.f!r} is refused (100% sure)", status=Fmi2Status.error)
            return False
        if self.f == -1.0:
            raise RuntimeError("Boom: raised on purpose")
        self.x += self.f * step_size
        return True
'''

# Runs in a subprocess without dfwb: every FMI call after a failure, statuses as JSON on stdout.
DRIVER = '''
import json, sys
import fmpy
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

fmu, bad = sys.argv[1], float(sys.argv[2])
md = fmpy.read_model_description(fmu)
vr = {v.name: v.valueReference for v in md.modelVariables}
s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="shim-test")
s.instantiate(loggingOn=False)
log = []

def call(name, *args):
    try:
        getattr(s, name)(*args)
        log.append([name, 0])
    except FMICallException as error:
        log.append([name, error.status])

def init():
    call("setupExperiment", None, 0.0)
    call("enterInitializationMode")
    call("exitInitializationMode")

init()
call("doStep", 0.0, 0.1)
call("setReal", [vr["f"]], [bad])
call("doStep", 0.1, 0.1)            # the failure
call("getReal", [vr["x"]])          # allowed for diagnosis
call("setReal", [vr["f"]], [1.0])   # refused in the Error state
call("doStep", 0.2, 0.1)            # refused
call("terminate")                   # refused
call("reset")
init()
call("setReal", [vr["f"]], [1.0])
call("doStep", 0.0, 0.1)
call("getReal", [vr["x"]])
call("terminate")
call("doStep", 0.1, 0.1)            # after terminate: refused
call("reset")
s.freeInstance()
print(json.dumps(log))
'''


def python_env(temporary):
    """The environment of a subprocess: this Python, no dfwb on the path beyond what it has installed, its
    temporary files (fmpy unpacks the FMU there and leaves it) in the folder ``temporary``."""
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH",)}
    return dict(env, TMPDIR=str(temporary))


@pytest.fixture(scope="module")
def boom(tmp_path_factory):
    """Boom.fmu, built by pythonfmu and given the shim as the builder does."""
    tmp = tmp_path_factory.mktemp("boom")
    script = tmp / "Boom.py"
    script.write_text(BOOM)
    raw = FmuBuilder.build_FMU(script, dest=tmp / "raw")
    fmu = tmp / "Boom.fmu"
    with zipfile.ZipFile(raw) as source, zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            data = source.read(item.filename)
            platform = builder._shim_platform(item.filename, ["linux64"])
            if platform:
                builder._shimmed(item, data, target, platform)
            else:
                target.writestr(item, data)
        target.writestr(builder.PYTHON_RECORD, builder.python_record())
    return fmu


def drive(fmu, bad, temporary):
    run = subprocess.run([sys.executable, "-c", DRIVER, str(fmu), repr(bad)], capture_output=True, text=True,
                         timeout=120, env=python_env(temporary))
    assert run.returncode == 0, f"the host died ({run.returncode}):\n{run.stdout}\n{run.stderr}"
    return [tuple(entry) for entry in json.loads(run.stdout.splitlines()[-1])], run.stdout


EXPECTED = [
    ("setupExperiment", OK), ("enterInitializationMode", OK), ("exitInitializationMode", OK),
    ("doStep", OK), ("setReal", OK),
    ("doStep", ERROR), ("getReal", OK), ("setReal", ERROR), ("doStep", ERROR), ("terminate", ERROR),
    ("reset", OK), ("setupExperiment", OK), ("enterInitializationMode", OK), ("exitInitializationMode", OK),
    ("setReal", OK), ("doStep", OK), ("getReal", OK), ("terminate", OK), ("doStep", ERROR), ("reset", OK),
]


@pytest.mark.parametrize("bad", [float("nan"), 1e300])
def test_every_call_after_an_error(boom, bad, tmp_path):
    statuses, output = drive(boom, bad, tmp_path)
    assert statuses == EXPECTED
    assert "is refused (100% sure)" in output  # the FMU's message, at the default logger, '%' intact
    assert "fmi2DoStep: the FMU is in the error state; call fmi2Reset" in output
    assert "fmi2DoStep: the FMU is terminated" in output


def test_a_production_fmu_after_an_error(fmus, tmp_path):
    """f = 1e300 is refused by the facade (status error), then the same sequence: exit 0."""
    statuses, output = drive(fmus["FrictionMass"], 1e300, tmp_path)
    expected = list(EXPECTED)
    expected[4] = ("setReal", ERROR)  # the facade refuses the value at once; the doStep after it is refused too
    assert statuses == expected
    assert "out of range" in output
    assert "fmi2DoStep: the FMU is in the error state" in output


def test_fatal_inside_is_contained(boom, tmp_path):
    """pythonfmu's fatal path (a Python exception): every later call is fmi2Fatal, no crash at exit."""
    statuses, output = drive(boom, -1.0, tmp_path)
    assert statuses[:5] == EXPECTED[:5]
    assert statuses[5] == ("doStep", FATAL)
    assert all(status == FATAL for _name, status in statuses[6:])
    assert "only fmi2FreeInstance may be called" in output


RESETS = '''
import sys
import fmpy
from fmpy.fmi2 import FMU2Slave

fmu = sys.argv[1]
md = fmpy.read_model_description(fmu)
s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu), modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName="resets")
s.instantiate()
for _ in range(200):
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.doStep(0.0, 0.1)
    s.reset()
s.terminate() if False else None
s.freeInstance()
print("done")
'''


def test_200_resets_20_processes(fmus, tmp_path):
    """200 resets in one instance, in 20 fresh processes: every one exits 0."""
    for _ in range(20):
        run = subprocess.run([sys.executable, "-c", RESETS, str(fmus["FrictionMass"])], capture_output=True,
                             text=True, timeout=300, env=python_env(tmp_path))
        assert run.returncode == 0 and run.stdout.strip() == "done", run.stderr


def test_error_message_in_fmpy_cli(boom, tmp_path):
    """fmpy's command line shows the FMU's error without --debug-logging."""
    run = subprocess.run([sys.executable, "-m", "fmpy", "simulate", str(boom), "--start-values", "f", "1e300",
                          "--stop-time", "1", "--output-file", str(tmp_path / "out.csv")],
                         capture_output=True, text=True, timeout=120, env=python_env(tmp_path), cwd=tmp_path)
    assert "Boom: f = 1e+300 is refused (100% sure)" in run.stdout + run.stderr


def test_model_description_and_layout(fmus):
    """The shim is binaries/linux64/<Model>.so, pythonfmu's binary is next to it; fmpy validate passes."""
    with zipfile.ZipFile(fmus["FrictionMass"]) as archive:
        names = set(archive.namelist())
    assert {"binaries/linux64/FrictionMass.so", "binaries/linux64/FrictionMass.pythonfmu.so",
            "resources/dfwb_python.txt", "documentation/fmi2_shim.c", "binaries/win64/FrictionMass.dll"} <= names
    assert not any(name.startswith("sources/") for name in names)  # fmpy would list a c-code platform
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmus["FrictionMass"])) == []


def test_shim_is_compiled_once():
    assert builder.shim_binary() is builder.shim_binary()


def test_missing_compiler_is_one_line(monkeypatch):
    monkeypatch.setenv("CC", "no-such-compiler-dfwb")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(builder.BuildError, match="needs a C compiler"):
        builder._compiler()


def test_c_host_without_python_environment(fmus, tmp_path):
    """The C host runs every production FMU with an empty environment (no LD_PRELOAD, no PYTHONHOME)."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    source = Path(__file__).resolve().parent / "c_host" / "fmu_host.c"
    host = tmp_path / "fmu_host"
    headers = Path(fmpy.__file__).resolve().parent / "c-code"
    subprocess.run([cc, "-std=c99", "-D_DEFAULT_SOURCE", "-O1", f"-I{headers}", str(source), "-o", str(host),
                    "-ldl", "-lm"], check=True)
    for model in ("FrictionMass", "TwoMassBacklash", "StaticBacklash", "LinearSystem"):
        directory = fmpy.extract(str(fmus[model]), unzipdir=str(tmp_path / model))
        run = subprocess.run([str(host), directory, model, "0.5", "0.1"], env={}, cwd=tmp_path,
                             capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, f"{model}: {run.stderr}"
        assert len(run.stdout.splitlines()) == 6
