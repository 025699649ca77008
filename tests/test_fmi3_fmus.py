"""The native plants as FMI 3.0 co-simulation FMUs, and every native FMU built from its sources by fmpy.

FMI 3.0 (``dfwb build --native --fmi-version 3``): the same C instance as the
FMI 2.0 FMU under a thin FMI 3.0 layer, its model description translated
from the FMI 2.0 one. So the oracle is the FMI 2.0 FMU: fmpy's validator
finds no problem, and fmpy's simulation of both gives the same numbers bit
for bit (the outputs, the counters and the Fourier integrals, from t0 = 0 and
from t0 = 1.5); the FMU state round trips exactly (a restored run repeats
the original; bytes read back serialize to the same bytes) and bad bytes are
refused at deserialization; a refusal is fmi3Error with the FMU's message
through logMessage; what the FMU does not provide is refused by name.

Source FMUs: a test deletes an FMU's binaries, builds it with fmpy's
from-source build (``fmpy.build.build_platform_binary``: cmake over the
FMI 2.0 SourceFiles or FMI 3.0's ``sources/buildDescription.xml``) and gets
the shipped binary's numbers, bit for bit (both are gcc on x86_64 at -O2 and
-O3, without fused multiply-add, which baseline x86_64 lacks).
"""

import ctypes
import shutil
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.fmi3 import FMU3Slave, fmi3FMUState
from fmpy.validation import validate_fmu

pytestmark = pytest.mark.needs_cc

CASES = {
    "FrictionMass": ({"F": 10.0, "omega": 1.0}, ["x", "v", "Ff", "mode", "events", "Ic1", "Is1", "Ic3"]),
    "TwoMassBacklash": ({"F": 50.0, "omega": 20.0, "eps": 0.7}, ["x1", "v2", "gap", "contact", "impacts", "events",
                                                                 "Ic1", "Is2"]),
    "StaticBacklash": ({"F": 1.0, "omega": 2.0}, ["y", "v", "engaged", "events", "Ic1", "Is1"]),
}


def _simulate(path, start_values, outputs, start_time=0.0, stop_time=2.0):
    return fmpy.simulate_fmu(str(path), start_time=start_time, stop_time=stop_time, output_interval=0.01,
                             start_values=start_values, output=outputs)


def test_fmpy_validates_them(fmi3_fmus):
    for model, path in fmi3_fmus.items():
        assert validate_fmu(str(path)) == [], model
        description = fmpy.read_model_description(str(path))
        assert description.fmiVersion == "3.0" and description.coSimulation is not None
        assert [v.name for v in description.modelVariables if v.causality == "independent"] == ["time"]
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
        assert f"binaries/x86_64-linux/{model}.so" in names and "sources/buildDescription.xml" in names


@pytest.mark.parametrize("model", list(CASES))
@pytest.mark.parametrize("start_time", [0.0, 1.5])
def test_same_numbers_as_fmi2(native_fmus, fmi3_fmus, model, start_time):
    values, outputs = CASES[model]
    two = _simulate(native_fmus[model], values, outputs, start_time, start_time + 2.0)
    three = _simulate(fmi3_fmus[model], values, outputs, start_time, start_time + 2.0)
    assert len(three) == len(two) == 201
    for name in ["time"] + outputs:
        np.testing.assert_array_equal(three[name], two[name], err_msg=f"{model}.{name}")
    assert np.max(np.abs(two[outputs[0]])) > 0  # the plant moved


def _instance(path, log, folder, name="fmi3"):
    """An instance of the FMU ``path``, unpacked into ``folder`` (fmpy's own temporary folder would stay)."""
    description = fmpy.read_model_description(str(path))
    fmu = FMU3Slave(guid=description.guid, unzipDirectory=fmpy.extract(str(path), unzipdir=str(folder)),
                    modelIdentifier=description.coSimulation.modelIdentifier, instanceName=name)

    def message(_env, status, _category, text):
        log.append((status, text.decode()))

    fmu.instantiate(loggingOn=True, logMessage=message)
    return fmu, {v.name: v.valueReference for v in description.modelVariables}


def _run(fmu, vr, t, steps, outputs=("x1", "gap", "Ic1")):
    rows = []
    for _ in range(steps):
        fmu.doStep(t, 0.01)
        t += 0.01
        rows.append(fmu.getFloat64([vr[name] for name in outputs]) + fmu.getInt32([vr["events"]]))
    return rows, t


def test_state_round_trips_exactly_and_bad_bytes_are_refused(fmi3_fmus, tmp_path):
    log = []
    fmu, vr = _instance(fmi3_fmus["TwoMassBacklash"], log, tmp_path)
    fmu.setFloat64([vr["F"], vr["omega"]], [50.0, 20.0])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    _, t = _run(fmu, vr, 0.0, 30)
    state = fmu.getFMUState()
    data = fmu.serializeFMUState(state)
    fmu.freeFMUState(state)
    first, _ = _run(fmu, vr, t, 40)
    restored = fmu.deserializeFMUState(data)
    assert fmu.serializeFMUState(restored) == data  # bytes read back serialize to the same bytes
    fmu.setFMUState(restored)
    fmu.freeFMUState(restored)
    again, _ = _run(fmu, vr, t, 40)
    assert again == first and len(first) == 40 and first[-1][-1] > first[0][-1]  # the same events, and some
    deserialize = getattr(fmu.dll, "fmi3DeserializeFMUState")  # raw: a status, not an exception
    flipped = bytearray(data)
    flipped[-3] ^= 0x01
    for label, blob in {"cut": data[:-1], "extended": data + b"\0", "garbage": b"\0" * 300,
                        "flipped": bytes(flipped)}.items():
        handle = fmi3FMUState()
        before = len(log)
        buffer = (ctypes.c_ubyte * max(len(blob), 1)).from_buffer_copy(blob.ljust(1, b"\0"))
        status = deserialize(fmu.component, buffer, len(blob), ctypes.byref(handle))
        assert status == 3 and not handle, label  # fmi3Error
        assert any(level == 3 and "refused" in text for level, text in log[before:]), (label, log[before:])
    fmu.freeInstance()


def test_time_is_the_independent_variable(fmi3_fmus, tmp_path):
    log = []
    fmu, vr = _instance(fmi3_fmus["FrictionMass"], log, tmp_path)
    fmu.enterInitializationMode(startTime=1.5)
    fmu.exitInitializationMode()
    assert fmu.getFloat64([vr["time"]]) == [1.5]
    fmu.doStep(1.5, 0.25)
    assert fmu.getFloat64([vr["time"]]) == [1.75]
    with pytest.raises(Exception):
        fmu.setFloat64([vr["time"]], [3.0])
    assert "time is the independent variable and cannot be set" in log[-1][1]
    fmu.freeInstance()


@pytest.mark.parametrize("call, words", [
    (lambda fmu, vr: fmu.exitInitializationMode(), "eps = 1.5 is out of range"),
    (lambda fmu, vr: fmu.enterEventMode(), "fmi3EnterEventMode refused: the FMU has no Event Mode"),
    (lambda fmu, vr: fmu.getBoolean([vr["eps"]]), "this FMU has no Boolean variable"),
    (lambda fmu, vr: fmu.getFloat64([vr["events"]]), "is not of type Float64"),
    (lambda fmu, vr: fmu.doStep(0.0, 0.1), "doStep called before initialisation"),
])
def test_errors_are_fmi3error_with_the_message(fmi3_fmus, call, words, tmp_path):
    log = []
    fmu, vr = _instance(fmi3_fmus["TwoMassBacklash"], log, tmp_path)
    fmu.setFloat64([vr["eps"]], [1.5])
    fmu.enterInitializationMode()
    with pytest.raises(Exception) as refused:
        call(fmu, vr)
    assert "status 3" in str(refused.value) or "(error)" in str(refused.value)
    assert any(level == 3 and words in text for level, text in log), log
    fmu.freeInstance()


def test_event_mode_is_refused_at_instantiation(fmi3_fmus, tmp_path):
    log = []
    description = fmpy.read_model_description(str(fmi3_fmus["StaticBacklash"]))
    folder = fmpy.extract(str(fmi3_fmus["StaticBacklash"]), unzipdir=str(tmp_path))
    fmu = FMU3Slave(guid=description.guid, unzipDirectory=folder, modelIdentifier="StaticBacklash",
                    instanceName="events")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(eventModeUsed=True, logMessage=lambda _e, status, _c, text: log.append((status, text)))
    assert log and b"no Event Mode" in log[0][1]


# -- source FMUs -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cmake():
    if not shutil.which("cmake"):
        pytest.skip("no cmake on PATH (fmpy builds source FMUs with it)")


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("model", ["FrictionMass", "TwoMassBacklash"])
def test_fmpy_builds_the_fmu_from_its_sources(native_fmus, fmi3_fmus, cmake, tmp_path, version, model):
    """No binary left: fmpy compiles the FMU from sources/ (FMI 2.0's SourceFiles, FMI 3.0's buildDescription)."""
    from fmpy.build import build_platform_binary

    shipped = (native_fmus if version == 2 else fmi3_fmus)[model]
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(shipped) as archive:
        archive.extractall(folder)
    shutil.rmtree(folder / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(folder, build_dir=tmp_path / "build")
    rebuilt = tmp_path / f"{model}.fmu"
    with zipfile.ZipFile(rebuilt, "w") as archive:
        for path in sorted(Path(folder).rglob("*")):
            archive.write(path, path.relative_to(folder).as_posix())
    assert [p.parent.name for p in (folder / "binaries").rglob("*.so")] == \
        ["linux64" if version == 2 else "x86_64-linux"]
    values, outputs = CASES[model]
    ours, theirs = _simulate(shipped, values, outputs), _simulate(rebuilt, values, outputs)
    for name in ["time"] + outputs:
        np.testing.assert_array_equal(theirs[name], ours[name], err_msg=f"{model}.{name} (FMI {version})")
