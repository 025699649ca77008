"""The native plant FMUs (C core + fmus/native/fmu/fmi2_plant.c): twins of the pythonfmu FMUs without Python.

What is proved here: the model descriptions agree with the pythonfmu FMUs' (names, value references,
types, causality, start values, ranges, units) and pass fmpy's validation; every output, the Fourier
integrals and the counters included, is bit-identical to the pythonfmu FMU running the pure-Python
oracle, from t0 = 0 and from another start time; refusals carry the same messages; the FMU state
round-trips exactly in memory and as bytes, and crafted bytes are refused (or run cleanly), never crash;
the binary links no libpython.
"""

import contextlib
import ctypes
import fcntl
import io
import json
import math
import os
import random
import shutil
import zlib

import fmpy
import numpy as np
import pytest
from conftest import WARNINGS, new_instance
from fmpy.validation import validate_fmu

from dfwb.fmi.location import FMU_KINDS, fmu_kind, fmu_path
from dfwb.fmi.simulation import FMUError, simulate
from dfwb.fmus import facade
from dfwb.fmus.piecewise import PlantError

pytestmark = pytest.mark.needs_cc

MODELS = tuple(model.__name__ for model in facade.PLANTS)  # every plant of dfwb.fmus.plants has one
CASES = [
    ("FrictionMass", {"F": 10.0, "omega": 1.0}),
    ("FrictionMass", {"F": 6.0, "omega": 3.0, "Fs": 9.0, "B": 0.1, "harmonics": 3}),
    ("FrictionMass", {"F": 20.0, "omega": 0.5, "x0": 1.0, "v0": -2.0, "phi": 0.7}),
    ("FrictionMass", {"F": 10.0, "omega": 1.0, "Dv": 0.01}),  # Karnopp's band
    ("FrictionMass", {"F": 1e6, "omega": 1e3, "M": 1e-3, "Fs": 5.0, "B": 0.0}),
    ("TwoMassBacklash", {"F": 50.0, "omega": 20.0}),
    ("TwoMassBacklash", {"F": 5.0, "omega": 2.0, "eps": 0.0, "gap0": 0.0}),
    ("TwoMassBacklash", {"F": 1.0, "omega": 7.0, "eps": 1.0, "h": 0.01, "M1": 3.0}),
    ("StaticBacklash", {"F": 1.0, "omega": 1.0}),
    ("StaticBacklash", {"F": 3.0, "omega": 2.0, "k": 2.0, "h": 0.5, "harmonics": 0}),
]


@pytest.fixture
def python_oracle(monkeypatch):
    """The pythonfmu FMUs run their pure-Python solver (the oracle), not the C core."""
    monkeypatch.setenv("DFWB_FMU_SOLVER", "python")


def outputs_of(path, type=None):
    """The FMU's outputs (of that type: "Real", "Integer" only)."""
    return [v.name for v in fmpy.read_model_description(str(path)).modelVariables
            if v.causality == "output" and type in (None, v.type)]


def variables(path):
    description = fmpy.read_model_description(str(path))
    return [(v.name, v.valueReference, v.type, v.causality, v.variability, v.start, v.min, v.max, v.unit,
             v.description) for v in description.modelVariables]


@pytest.mark.parametrize("model", MODELS)
def test_same_variables_and_valid(native_fmus, fmus, model):
    assert variables(native_fmus[model]) == variables(fmus[model])
    assert validate_fmu(str(native_fmus[model])) == []
    description = fmpy.read_model_description(str(native_fmus[model]))
    assert description.coSimulation.modelIdentifier == model
    assert not description.coSimulation.needsExecutionTool


@pytest.mark.parametrize("model", MODELS)
def test_no_python_inside(native_fmus, model):
    import zipfile

    with zipfile.ZipFile(native_fmus[model]) as archive:
        names = archive.namelist()
        binary = archive.read(f"binaries/linux64/{model}.so")
    assert b"Py_Initialize" not in binary and b"libpython" not in binary
    assert "sources/fmi2_plant.c" in names and "sources/dfwb_model.h" in names
    assert not any(name.startswith("resources/") and name.endswith(".py") for name in names)


@pytest.mark.parametrize("start_time", [0.0, 1.25])
@pytest.mark.parametrize("model, start_values", CASES)
def test_bit_identical_to_the_python_oracle(native_fmus, fmus, python_oracle, model, start_values, start_time):
    names = outputs_of(fmus[model])
    runs = [fmpy.simulate_fmu(str(path), start_time=start_time, stop_time=start_time + 7.0, output_interval=0.013,
                              start_values=start_values, output=names) for path in (fmus[model], native_fmus[model])]
    assert len(runs[0]) == len(runs[1]) > 500
    for name in names:
        assert np.array_equal(runs[0][name], runs[1][name]), f"{model}.{name} differs"


def refusal(path, start_values, stop_time=1.0, step=0.01):
    with pytest.raises(FMUError) as refused:
        simulate(path, stop_time, step, start_values, ["x" if "Friction" in str(path) else "gap"])
    return str(refused.value)


@pytest.mark.parametrize("model, start_values, words", [
    ("FrictionMass", {"Fs": 1.0}, "Fs = 1.0 is out of range"),
    ("FrictionMass", {"M": -1.0}, "M = -1.0 is out of range"),
    ("FrictionMass", {"harmonics": 11}, "harmonics = 11"),
    ("TwoMassBacklash", {"eps": 1.5}, "eps = 1.5 is out of range"),
    ("TwoMassBacklash", {"gap0": 0.5}, "gap0 = 0.5 is out of range: gap0 must be in [0, h] = [0, 0.1] (m), or -1 "
                                       "in an FMU (h/2)"),  # what the FMU accepts: its start value -1 too
    ("FrictionMass", {"f": float("nan")}, "f = nan is out of range"),
])
def test_same_refusals(native_fmus, fmus, python_oracle, model, start_values, words):
    native, python = refusal(native_fmus[model], start_values), refusal(fmus[model], start_values)
    assert words in native
    assert native == python


def run_raw(path, values, steps, step=0.1, start_time=0.0, name="native_test"):
    """(instance, {name: value reference}, its log, its time) after ``steps`` steps from ``start_time``."""
    fmu, description, log = new_instance(path, name)
    vr = {v.name: v.valueReference for v in description.modelVariables}
    for key, value in values.items():
        fmu.setReal([vr[key]], [value])
    fmu.setupExperiment(startTime=start_time)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    t = start_time
    for _ in range(steps):
        fmu.doStep(t, step)
        t += step
    return fmu, vr, log, t


@pytest.mark.parametrize("call, expected", [
    (lambda fmu, vr: fmu.doStep(0.5, 0.1), "doStep at t = 0.5, but the FMU is at t = 0.30000000000000004"),
    (lambda fmu, vr: fmu.doStep(0.30000000000000004, -1.0), "communication step -1.0 at t ="),
    (lambda fmu, vr: fmu.doStep(0.30000000000000004, 1e8), "a step spans at most 1e+06 periods of the drive"),
    (lambda fmu, vr: fmu.setReal([vr["M"]], [2.0]), "setReal of M = 2.0 refused: M is a fixed parameter"),
    (lambda fmu, vr: fmu.setReal([vr["x"]], [2.0]), "setReal: x is an output and cannot be set"),
    (lambda fmu, vr: fmu.setReal([vr["f"]], [1e101]), "f = 1e+101 is out of range"),
    (lambda fmu, vr: fmu.getReal([vr["mode"]]), "is not of type Real"),
])
def test_step_and_setter_refusals_match(native_fmus, fmus, python_oracle, call, expected):
    logs = []
    for path in (native_fmus["FrictionMass"], fmus["FrictionMass"]):
        fmu, vr, log, _t = run_raw(path, {"F": 10.0}, 3)
        with pytest.raises(Exception):
            call(fmu, vr)
        errors = [text for status, text in log if status == 3]
        assert any(expected in text for text in errors), errors
        with pytest.raises(Exception):  # the Error state: stepping on is refused
            fmu.doStep(0.30000000000000004, 0.1)
        logs.append(errors[0])
    assert logs[0] == logs[1]


@pytest.mark.parametrize("model", MODELS)
def test_fmu_state_round_trip(native_fmus, model):
    fmu, vr, _log, t = run_raw(native_fmus[model], {"F": 8.0, "omega": 3.0}, 7, 0.3, 0.5, "state")
    reals = [vr[name] for name in outputs_of(native_fmus[model], "Real")]
    state = fmu.getFMUstate()
    data = fmu.serializeFMUstate(state)
    fmu.freeFMUstate(state)

    def go_on(t):
        for _ in range(9):
            fmu.doStep(t, 0.21)
            t += 0.21
        return fmu.getReal(reals), fmu.getInteger([vr["events"]])

    first = go_on(t)
    fmu.setFMUstate(restored := fmu.deSerializeFMUstate(data))
    fmu.freeFMUstate(restored)
    assert go_on(t) == first
    fmu.reset()  # a state restored into a reset instance, parameters included
    fmu.setFMUstate(again := fmu.deSerializeFMUstate(data))
    fmu.freeFMUstate(again)
    assert go_on(t) == first


def test_crafted_states_are_refused_never_crash(native_fmus):
    fmu, vr, log, t = run_raw(native_fmus["TwoMassBacklash"], {"F": 50.0, "omega": 20.0}, 30, 0.01, 0.0, "crafted")
    state = fmu.getFMUstate()
    data = bytes(fmu.serializeFMUstate(state))
    fmu.freeFMUstate(state)

    def attempt(blob):
        try:
            restored = fmu.deSerializeFMUstate(blob)
        except Exception:
            return "refused at deserialization"
        try:
            fmu.setFMUstate(restored)
        except Exception:
            return "refused when set"
        finally:
            fmu.freeFMUstate(restored)
        try:
            fmu.doStep(t, 0.05)
            values = fmu.getReal([vr["x1"], vr["gap"]])
            assert all(math.isfinite(value) for value in values)
            return "ran"
        except Exception:
            return "step refused"

    # a parameter of the facade other than the solver's: M1 is the first value after the header
    header = 16 + 40 + 24
    forged = bytearray(data)
    forged[header:header + 8] = bytearray(ctypes.c_double(2.0))
    assert attempt(bytes(forged)) == "refused at deserialization"  # its CRC-32 no longer matches
    forged[-4:] = zlib.crc32(forged[:-4]).to_bytes(4, "little")  # a crafted state, sealed again
    assert attempt(bytes(forged)) == "refused when set"
    assert any("does not match its parameters" in text for _status, text in log)
    assert attempt(data[:-1]) == "refused at deserialization"
    assert attempt(b"DFWBFMUS" + data[8:16] + b"x" * 40 + data[56:]) == "refused at deserialization"
    rng = random.Random(14)
    outcomes = set()
    for _ in range(300):
        blob = bytearray(data)
        for _ in range(rng.randint(1, 3)):
            blob[rng.randrange(len(blob))] ^= 1 << rng.randrange(8)
        fmu.reset()
        outcomes.add(attempt(bytes(blob)))
    assert "refused at deserialization" in outcomes


def _serialized(path, values, steps):
    fmu, vr, log, t = run_raw(path, values, steps)
    state = fmu.getFMUstate()
    data = bytes(fmu.serializeFMUstate(state))
    fmu.freeFMUstate(state)
    return fmu, log, data


@pytest.mark.parametrize("kind", ["native", "python"])
def test_bytes_that_are_not_a_state_are_refused_at_deserialization(native_fmus, fmus, kind):
    """Issue 23's audit: both kinds refuse at fmi2DeSerializeFMUstate (fmi2Error, the reason logged) garbage,
    truncated or extended bytes, a flipped bit, another model's state and the other kind's state; the host's
    state handle is left as it was, and the instance still takes its own state afterwards."""
    mine, theirs = (native_fmus, fmus) if kind == "native" else (fmus, native_fmus)
    fmu, log, data = _serialized(mine["TwoMassBacklash"], {"F": 50.0, "omega": 20.0}, 5)
    other_model = _serialized(mine["FrictionMass"], {"F": 10.0}, 3)[2]
    other_kind = _serialized(theirs["TwoMassBacklash"], {"F": 50.0, "omega": 20.0}, 5)[2]
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0x10
    bad = {"garbage": b"\x00garbage" * 20, "truncated": data[:-1], "extended": data + b"\x00",
           "flipped bit": bytes(flipped), "another model": other_model, "the other kind": other_kind,
           "empty": b""}
    deserialize = getattr(fmu.dll, "fmi2DeSerializeFMUstate")  # raw: a status, not an exception
    for label, blob in bad.items():
        handle = fmpy.fmi2.fmi2FMUstate()
        before = len(log)
        status = deserialize(fmu.component, blob, len(blob), ctypes.byref(handle))
        assert status == 3 and not handle, (label, status)  # fmi2Error, the handle untouched (NULL)
        assert any(level == 3 and "refused" in text for level, text in log[before:]), (label, log[before:])
    restored = fmu.deSerializeFMUstate(data)  # the error state allows it; setting it leaves that state
    fmu.setFMUstate(restored)
    fmu.freeFMUstate(restored)
    assert bytes(fmu.serializeFMUstate(kept := fmu.getFMUstate())) == data
    fmu.freeFMUstate(kept)


@pytest.fixture(scope="module")
def built_native(tmp_path_factory, fmus):
    """(a folder whose native/ ``dfwb build --native --out`` filled, starting empty, its exit code, what it printed):
    copied from the FMU folder (``fmus`` built them there), once for the command's test and for fmu_path's,
    which finds them there up to date. Once per session:
    pytest-xdist workers share it (the session's temporary folder, under a lock), so that the two tests need not
    run on the same worker."""
    from dfwb.cli import main

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's folder, above each worker's own
    folder, record = root / "native-build", root / "native-build.json"
    with open(root / "native-build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not record.exists():
            folder.mkdir()
            with contextlib.redirect_stdout(io.StringIO()) as out:
                code = main(["build", "--native", "--out", str(folder / "native")])
            record.write_text(json.dumps([code, out.getvalue()]))
        code, out = json.loads(record.read_text())
    return folder, code, out


def test_fmu_kind_and_path(monkeypatch, built_native, fmus):
    """fmu_path in a folder where the FMUs asked for are up to date: the native FrictionMass that
    ``dfwb build --native`` wrote (built_native), copies of the session's pythonfmu LinearSystem and
    FrictionMass. (fmu_path building a missing FMU: tests/test_location.py, and the build test below.)"""
    assert FMU_KINDS == ("native", "python")
    monkeypatch.delenv("DFWB_FMU", raising=False)
    assert fmu_kind() == "native"
    monkeypatch.setenv("DFWB_FMU", "python")
    assert fmu_kind() == "python" and fmu_kind("native") == "native"
    monkeypatch.setenv("DFWB_FMU", "rust")
    with pytest.raises(PlantError, match="DFWB_FMU = 'rust' is not an FMU kind"):
        fmu_kind()
    with pytest.raises(PlantError, match="kind = 'c' is not an FMU kind"):
        fmu_kind("c")
    monkeypatch.delenv("DFWB_FMU")
    folder = built_native[0]
    for model in ("LinearSystem", "FrictionMass"):
        shutil.copy2(fmus[model], folder / f"{model}.fmu")
    built = {path: path.stat().st_mtime_ns for path in folder.rglob("*.fmu")}
    native = fmu_path("FrictionMass", folder)
    assert native == folder / "native" / "FrictionMass.fmu"
    assert fmu_path("LinearSystem", folder) == folder / "LinearSystem.fmu"  # no native twin
    assert fmu_path("FrictionMass", folder, kind="python") == folder / "FrictionMass.fmu"
    assert {path: path.stat().st_mtime_ns for path in folder.rglob("*.fmu")} == built  # found, not rebuilt


@pytest.mark.parametrize("model", MODELS)
def test_checker_finds_no_error(native_fmus, model):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    fmutool = shutil.which("fmutool") or str(Path(sys.executable).with_name("fmutool"))
    if not Path(fmutool).exists():
        pytest.skip("fmu-manipulation-toolbox is not installed (pip install .[test])")
    run = subprocess.run([fmutool, "-input", str(native_fmus[model]), "-check"], capture_output=True, text=True,
                         timeout=120)
    report = run.stdout + run.stderr
    assert run.returncode == 0 and "seems to be compliant with FMI-2.0" in report, report
    assert "No semantic error" in report and "ERROR" not in report, report


@pytest.mark.needs_libcosim
@pytest.mark.parametrize("model, start_values", [CASES[0], CASES[5], CASES[8]])
def test_libcosim_runs_them_as_fmpy_does(native_fmus, model, start_values):
    try:
        from dfwb.fmi.cosim import simulate_cosim
    except (ImportError, OSError) as error:
        pytest.skip(f"libcosimpy cannot be imported: {error}")
    names = [name for name in outputs_of(native_fmus[model]) if name[:2] not in ("Ic", "Is") or name[2:] == "1"]
    expected = simulate(native_fmus[model], 1.0, 0.005, start_values, names)
    actual = simulate_cosim(native_fmus[model], 1.0, 0.005, start_values=start_values, outputs=names)
    for name in names:  # libcosim's grid is n * step, fmpy's a running sum: the same to rounding
        scale = 1e-12 * np.max(np.abs(expected[name])) + 1e-15
        np.testing.assert_allclose(actual[name], expected[name], rtol=0, atol=scale, err_msg=name)


def test_dfwb_build_native_writes_every_plants_fmu(built_native, native_fmus, capsys):
    from dfwb.cli import main

    folder, code, out = built_native
    tmp_path = folder / "native"  # where the command wrote them, into a fresh folder
    assert code == 0
    assert sorted(path.name for path in tmp_path.iterdir()) == sorted(f"{model}.fmu" for model in MODELS)
    # the FMU folder holds them built from the same sources (the fmus fixture): copied, not compiled again
    assert out.count(": copied from ") == len(MODELS), out
    for model in MODELS:
        assert (tmp_path / f"{model}.fmu").read_bytes() == native_fmus[model].read_bytes()
    assert main(["build", "--native", "--out", str(tmp_path)]) == 0  # up to date: nothing rebuilt
    assert capsys.readouterr().out.count(": up to date (native") == len(MODELS)
    with pytest.raises(SystemExit) as stopped:
        main(["build", "--native", "--naive", "--out", str(tmp_path)])
    assert stopped.value.code == 2 and "--native and --naive" in capsys.readouterr().err


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_the_native_fmus_compile_without_a_warning(tmp_path, fmi_version):
    """With -Wall -Wextra -Werror: every model for linux64 at -O0 (its wrapper and model header; the core's
    warnings at -O2, whose analysis finds more, are the core fixture's), and one for win64 where mingw is
    here, at -O2. The FMUs dfwb runs are built from the same sources without these flags."""
    from dfwb.build_fmus.native import build_native, native_models, platforms

    paths = build_native(tmp_path / "linux64", report=lambda message: None, fmi_version=fmi_version,
                         extra_flags=WARNINGS + ("-O0",), targets=("linux64",))
    assert sorted(path.stem for path in paths) == sorted(MODELS)
    if "win64" in platforms():
        [path] = build_native(tmp_path / "win64", native_models()[:1], report=lambda message: None,
                              fmi_version=fmi_version, extra_flags=WARNINGS, targets=("win64",))
        assert path.is_file()
