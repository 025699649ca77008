"""The closed-loop FMUs on the compiled core (resources/libdfwb_core.so), against the pure-Python loops.

The same loop FMU runs either way: with the core (the default when it loads) or with
``DFWB_FMU_SOLVER=python``. fmpy runs the FMU in this process, so the variable set here is
what the instance reads at exitInitializationMode. Every output must agree bit for bit
(several controllers, every plant, start times other than 0), refusals must say the same,
the log must say which solver runs (one warning when the core is missing), FMU states must
continue bit for bit, and crafted states must be refused cleanly (no crash: the fuzzing runs
in a subprocess). ``pytest -s`` prints the time of one loop FMU run both ways.
"""

import json
import math
import shutil
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path

import fmpy
import pytest
from conftest import new_instance
from fmpy.fmi1 import FMICallException

from dfwb.build_fmus import builder
from dfwb.fmi.simulation import unpacked
from dfwb.fmus import facade, loop_facade

pytestmark = pytest.mark.needs_cc

MODELS = ("FrictionMassLoop", "TwoMassBacklashLoop", "StaticBacklashLoop")
NATIVE = {"FrictionMassLoop": "FrictionLoop", "TwoMassBacklashLoop": "BacklashLoop",
          "StaticBacklashLoop": "StaticBacklashLoop"}


def _order8():
    """G(s) = 2 * 8! / ((s + 1) ... (s + 8)), z1_0 = 1: an order-8 controller."""
    coefficients = [1.0]
    for pole in range(1, 9):
        coefficients = [c + pole * p for c, p in zip(coefficients + [0.0], [0.0] + coefficients)]
    return dict({f"a{i}": coefficients[i] for i in range(1, 9)}, order=8, b8=coefficients[8] * 2.0, z1_0=1.0)


CASES = {  # model: [(start values, start time, stop time, communication step)]
    "FrictionMassLoop": [
        # PID with a filtered derivative: (40 s^2 + 600 s + 1200) / (s (s + 20)): stick-slip hunting
        ({"order": 2, "b0": 40.0, "b1": 600.0, "b2": 1200.0, "a1": 20.0, "x0": 1.0}, 0.0, 10.0, 0.05),
        # PI (20 s + 8) / s, from t0 = 1.5
        ({"order": 1, "b0": 20.0, "b1": 8.0, "a1": 0.0, "x0": 1.0, "B": 1.0, "Fs": 7.0}, 1.5, 31.5, 0.05),
        # order 3, strictly proper, with an initial controller state
        ({"order": 3, "b2": 300.0, "b3": 200.0, "a1": 30.0, "a2": 300.0, "x0": 1.0, "z1_0": 0.001, "B": 0.2},
         0.0, 20.0, 0.02),
    ],
    "TwoMassBacklashLoop": [
        # PD with a filtered derivative: (40 s + 400) / (s + 20): impacts
        ({"order": 1, "b0": 40.0, "b1": 400.0, "a1": 20.0, "x1_0": 1.0, "eps": 0.5}, 0.0, 5.0, 0.01),
        # order 2, plastic impacts from a wall, from t0 = 2.5
        ({"order": 2, "b0": 10.0, "b1": 200.0, "b2": 500.0, "a1": 20.0, "x1_0": 0.5, "eps": 0.0, "gap0": 0.0,
          "v2_0": 1.0}, 2.5, 6.0, 0.005),
        # lead (30 s + 90) / (s + 3), nearly elastic, a narrow clearance and M1 = 2
        ({"order": 1, "b0": 30.0, "b1": 90.0, "a1": 3.0, "x1_0": -0.3, "eps": 0.9, "h": 0.05, "M1": 2.0},
         0.0, 8.0, 0.02),
    ],
    "StaticBacklashLoop": [
        # lead (100 s + 400) / (s + 20), z1_0 = 0.01: engagements
        ({"order": 1, "b0": 100.0, "b1": 400.0, "a1": 20.0, "x0": 1.0, "z1_0": 0.01}, 0.0, 5.0, 0.01),
        # order 8 from t0 = 2
        (dict(_order8(), x0=0.05), 2.0, 6.0, 0.25),
        # order 2, k = 2, h = 0.3, from t0 = 0.75
        ({"order": 2, "b1": 50.0, "b2": 100.0, "a1": 10.0, "a2": 25.0, "x0": -0.7, "v0": 2.0, "k": 2.0, "h": 0.3},
         0.75, 10.0, 0.05),
    ],
}
REFUSED = [  # (model, start values, the start of the error they get: the Python solver's text)
    ("FrictionMassLoop", {"order": 9}, "invalid parameter: order = 9 is out of range"),
    ("FrictionMassLoop", {"Dv": 1.0}, "invalid parameter: Dv = 1.0 is out of range"),
    ("FrictionMassLoop", {"M": 0.0}, "invalid parameter: M = 0.0 is out of range"),
    ("FrictionMassLoop", {"Fc": 5.0, "Fs": 3.0}, "invalid parameter: Fs = 3.0 is out of range"),
    ("TwoMassBacklashLoop", {"eps": 2.0}, "invalid parameter: eps = 2.0 is out of range"),
    ("TwoMassBacklashLoop", {"gap0": 0.2}, "invalid parameter: gap0 = 0.2 is out of range"),
    ("TwoMassBacklashLoop", {"order": 2, "z3_0": 1.0}, "invalid parameter: z3_0 = 1.0 is out of range"),
    ("StaticBacklashLoop", {"b1": math.nan}, "invalid parameter: b1 = nan is out of range"),
    ("StaticBacklashLoop", {"h": -0.1}, "invalid parameter: h = -0.1 is out of range"),
    ("StaticBacklashLoop", {"order": 1, "b0": 1e300, "x0": 1e300}, "invalid parameter: the initial outputs overflow"),
    # positive feedback f = +1e6 y: the motion overflows, doStep is refused
    ("FrictionMassLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x0": 1.0}, "step from t = "),
    ("TwoMassBacklashLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x1_0": 1.0}, "step from t = "),
    ("StaticBacklashLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x0": 1.0}, "step from t = "),
]
STATE_START = {model: CASES[model][0][0] for model in MODELS}
HEADER = 24  # the C state's header: magic, ABI, kind, length, CRC-32; then 8-byte fields
FIELD = {"M": 0, "order": 32, "t": 192, "events": 200, "count": 208, "key": 216}  # payload offsets of some


def _has_cc():
    return any(shutil.which(name) for name in ("cc", "gcc", "clang"))


@pytest.fixture(scope="module")
def loop_fmus(tmp_path_factory):
    """{model: path} of the three loop FMUs, built with the compiled core into a private folder."""
    if not _has_cc():
        pytest.skip("no C compiler (cc) on PATH to build the core")
    core, why = builder.core_binary()
    assert core is not None, why
    assert all(builder.native(model) for model in loop_facade.LOOPS)
    lines = []
    paths = builder.build(tmp_path_factory.mktemp("loop_fmus"), list(loop_facade.LOOPS), report=lines.append)
    assert not [line for line in lines if "cannot" in line], lines
    for path in paths:
        with zipfile.ZipFile(path) as archive:
            assert archive.read(builder.CORE_RESOURCE) == core
    return {path.stem: path for path in paths}


@pytest.fixture
def solver(monkeypatch):
    """use(kind): None unsets DFWB_FMU_SOLVER, "python" or "native" sets it (for the instances made next)."""

    def use(kind):
        if kind is None:
            monkeypatch.delenv(facade.SOLVER_VARIABLE, raising=False)
        else:
            monkeypatch.setenv(facade.SOLVER_VARIABLE, kind)

    use(None)
    return use


def _simulate(directory, description, start, t0, stop, dt):
    """(fmpy's result, its log [(status, text)], the error or None) of one run of every output."""
    messages = []

    def logger(_env, _instance, status, _category, text):
        messages.append((status, text.decode()))

    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    try:
        result = fmpy.simulate_fmu(str(directory), model_description=description, start_time=t0, stop_time=stop,
                                   output_interval=dt, start_values=dict(start), output=outputs, logger=logger,
                                   debug_logging=True, validate=False)
    except FMICallException as error:
        return None, messages, str(error)
    return result, messages, None


def _both(path, solver, start, t0, stop, dt):
    directory, description = unpacked(path)
    solver(None)
    native = _simulate(directory, description, start, t0, stop, dt)
    solver("python")
    python = _simulate(directory, description, start, t0, stop, dt)
    solver(None)
    return native, python


# -- outputs and refusals -------------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("case", range(3))
def test_outputs_are_bit_identical_to_the_python_loop(loop_fmus, solver, model, case):
    start, t0, stop, dt = CASES[model][case]
    (native, native_log, error), (python, python_log, python_error) = _both(loop_fmus[model], solver, start, t0,
                                                                            stop, dt)
    assert error is None and python_error is None, (native_log, python_log)
    assert native.dtype == python.dtype and len(native) == len(python) > 10
    assert native.tobytes() == python.tobytes()  # every output, events and the counter included
    assert native["events"][-1] > 0  # the cases switch
    assert native["time"][0] == t0 and abs(native["time"][-1] - stop) < 1e-9
    assert [(status, text.split(" (")[0]) for status, text in native_log] == [
        (0, f"{model}: runs on the compiled core")], native_log
    assert "libdfwb_core.so" in native_log[0][1]
    assert python_log == [(0, f"{model}: runs on the pure-Python solver (DFWB_FMU_SOLVER=python)")]


@pytest.mark.parametrize("model, bad, text", REFUSED)
def test_a_refusal_says_the_same_on_both_solvers(loop_fmus, solver, model, bad, text):
    (_, native_log, error), (_, python_log, python_error) = _both(loop_fmus[model], solver, bad, 0.0, 2.0, 0.1)
    assert error and python_error and error == python_error  # the same call fails
    native_errors = [m for m in native_log if m[0] >= 3]
    python_errors = [m for m in python_log if m[0] >= 3]
    assert native_errors == python_errors and len(native_errors) == 1, (native_log, python_log)
    assert native_errors[0][1].startswith(f"{model}: {text}"), native_errors
    assert "runs on the compiled core" in native_log[0][1] and "DFWB_FMU_SOLVER=python" in python_log[0][1]


# -- which solver runs -------------------------------------------------------------------------------

def _without_core(path, tmp_path, replacement=None):
    """A copy of the FMU whose core is missing (or replaced by ``replacement`` bytes)."""
    copy = tmp_path / "bare" / path.name
    copy.parent.mkdir(exist_ok=True)
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(copy, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            if item.filename == builder.CORE_RESOURCE:
                if replacement is not None:
                    target.writestr(item, replacement)
            else:
                target.writestr(item, source.read(item.filename))
    return copy


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("damage, reason", [(None, "the FMU has no compiled core (no resources/libdfwb_core.so)"),
                                            (b"not a library\n", "cannot load the C core")])
def test_the_fmu_falls_back_to_python_with_one_warning(loop_fmus, solver, tmp_path, model, damage, reason):
    path = loop_fmus[model]
    directory, description = unpacked(_without_core(path, tmp_path, damage))
    start, t0, stop, dt = CASES[model][0]
    result, log, error = _simulate(directory, description, start, t0, stop, dt)
    assert error is None
    assert len(log) == 1 and log[0][0] == 1, log  # status warning, the only message
    assert log[0][1].startswith(f"{model}: the compiled core cannot be used (") and reason in log[0][1]
    assert log[0][1].endswith("it runs on the pure-Python solver")
    solver("python")
    reference, _, _ = _simulate(*unpacked(path), start, t0, stop, dt)
    assert result.tobytes() == reference.tobytes()

    solver("native")  # the core is required: its absence is an error at exitInitializationMode
    result, log, error = _simulate(directory, description, start, t0, stop, dt)
    assert result is None and "ExitInitializationMode" in error
    errors = [text for status, text in log if status >= 3]
    assert len(errors) == 1 and errors[0].startswith(f"{model}: DFWB_FMU_SOLVER=native, but the compiled core "
                                                     f"cannot be used: ") and reason in errors[0]


def test_native_forced_runs_on_the_core_and_a_bad_choice_is_refused(loop_fmus, solver):
    start, t0, stop, dt = CASES["StaticBacklashLoop"][0]
    (default, _, _), _ = _both(loop_fmus["StaticBacklashLoop"], solver, start, t0, stop, dt)
    solver("native")
    result, log, error = _simulate(*unpacked(loop_fmus["StaticBacklashLoop"]), start, t0, stop, dt)
    assert error is None and result.tobytes() == default.tobytes()
    assert len(log) == 1 and log[0][0] == 0 and "StaticBacklashLoop: runs on the compiled core" in log[0][1]
    solver("fortran")
    result, log, error = _simulate(*unpacked(loop_fmus["StaticBacklashLoop"]), start, 0.0, 1.0, 0.1)
    assert result is None and error
    assert [text for status, text in log if status >= 3] == [
        "StaticBacklashLoop: DFWB_FMU_SOLVER = 'fortran' is refused: it must be 'native' (the compiled core; an "
        "error if it cannot be used) or 'python' (the pure-Python solver), or unset"]


def test_the_facade_outside_an_fmu_runs_python_without_a_warning(solver):
    fmu = loop_facade.FrictionMassLoop(instance_name="direct")
    fmu.setup_experiment(0.0, None, None)
    fmu.enter_initialization_mode()
    fmu.exit_initialization_mode()
    assert [(m.status, m.msg) for m in fmu.log_queue] == [
        (0, "FrictionMassLoop: runs on the pure-Python solver (no resources folder (the facade does not run "
            "inside an FMU))")]
    assert type(fmu.solver) is loop_facade.FrictionMassLoop.solver_class and fmu.do_step(0.0, 1.0)


# -- FMU state ---------------------------------------------------------------------------------------

def _instance(path, start, kind, solver, start_time=0.0):
    """(raw FMU2Slave initialised with ``start`` on the solver ``kind``, its description, its log)."""
    solver(kind)
    fmu, description, messages = new_instance(path, "state")
    fmu.setupExperiment(startTime=start_time)
    fmu.enterInitializationMode()
    by_name = {v.name: v for v in description.modelVariables}
    for name, value in start.items():
        var = by_name[name]
        if var.type == "Integer":
            fmu.setInteger([var.valueReference], [int(value)])
        else:
            fmu.setReal([var.valueReference], [float(value)])
    fmu.exitInitializationMode()
    solver(None)
    return fmu, description, messages


def _read(fmu, description):
    """Every Real (as bit patterns) and Integer variable."""
    reals = [v.valueReference for v in description.modelVariables if v.type == "Real"]
    integers = [v.valueReference for v in description.modelVariables if v.type == "Integer"]
    return [struct.pack("<d", value) for value in fmu.getReal(reals)], list(fmu.getInteger(integers))


def _run(fmu, t, t_end, dt):
    while t < t_end - 1e-12:
        fmu.doStep(t, dt)
        t += dt
    return t


def _solver_log(messages):
    return [text for status, text in messages if "runs on" in text]


@pytest.mark.parametrize("model", MODELS)
def test_states_continue_bit_identically_on_the_core(loop_fmus, solver, model):
    path, start = loop_fmus[model], STATE_START[model]
    python, description, _ = _instance(path, start, "python", solver, start_time=0.5)
    _run(python, 0.5, 3.0, 0.0137)
    reference = _read(python, description)

    fmu, _, messages = _instance(path, start, None, solver, start_time=0.5)
    assert "runs on the compiled core" in _solver_log(messages)[0]
    t1 = _run(fmu, 0.5, 1.7, 0.0137)
    saved = fmu.getFMUstate()
    data = fmu.serializeFMUstate(saved)
    _run(fmu, t1, 3.0, 0.0137)
    assert _read(fmu, description) == reference
    fmu.setFMUstate(saved)  # in memory: the C loop copied
    _run(fmu, t1, 3.0, 0.0137)
    assert _read(fmu, description) == reference
    fmu.setFMUstate(fmu.deSerializeFMUstate(data))  # from bytes: read back by the instance's own core
    _run(fmu, t1, 3.0, 0.0137)
    assert _read(fmu, description) == reference
    fmu.freeFMUstate(saved)

    fresh, _, fresh_messages = _instance(path, {}, None, solver)  # another instance, default parameters
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    _run(fresh, t1, 3.0, 0.0137)
    assert _read(fresh, description) == reference
    assert len(_solver_log(fresh_messages)) == 1  # restoring a state logs no new choice
    assert not [m for m in messages + fresh_messages if m[0] >= 1]
    cls = _fmu_classes(path)[0]
    assert type(cls._fmu_state_from_bytes(data).solver).__name__ == "NativeState"  # the C loop's bytes


@pytest.mark.parametrize("source, target", [("python", None), (None, "python")])
def test_a_state_of_either_solver_is_accepted_by_either_instance(loop_fmus, solver, source, target):
    path, start = loop_fmus["TwoMassBacklashLoop"], STATE_START["TwoMassBacklashLoop"]
    fmu, description, _ = _instance(path, start, source, solver)
    t1 = _run(fmu, 0.0, 1.0, 0.02)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    _run(fmu, t1, 2.0, 0.02)
    other, _, messages = _instance(path, {}, target, solver)
    other.setFMUstate(other.deSerializeFMUstate(data))
    _run(other, t1, 2.0, 0.02)
    assert _read(other, description) == _read(fmu, description)
    assert not [m for m in messages if m[0] >= 1]


def _fmu_classes(path):
    """(the FMU's own facade class, its state module): the FMU runs in this process under its package name."""
    package = f"dfwb_fmus_{builder.recorded_hash(path)}"
    return getattr(sys.modules[f"{package}.loop_facade"], path.stem), sys.modules[f"{package}.state"]


def _crafted(path, data, change):
    """``data`` (serialized) decoded by the FMU's own code, changed by change(state, NativeState), encoded again."""
    cls, state_module = _fmu_classes(path)
    decoded = cls._fmu_state_from_bytes(data)
    assert type(decoded.solver).__name__ == "NativeState"
    change(decoded, state_module.NativeState)
    return cls._fmu_state_to_bytes(decoded)


def _flip(offset):
    def change(decoded, _native_state):
        raw = bytearray(decoded.solver.data)
        raw[offset % len(raw)] ^= 0x10
        decoded.solver.data = bytes(raw)
    return change


def _field(name, value):
    """Set a field of the C loop's payload (the checksum made valid again: only the C core's checks stand)."""
    def change(decoded, _native_state):
        raw = bytearray(decoded.solver.data)
        offset = HEADER + FIELD[name]
        raw[offset:offset + 8] = struct.pack("<d", value) if type(value) is float else struct.pack("<q", value)
        raw[20:24] = struct.pack("<I", zlib.crc32(bytes(raw[HEADER:])))
        decoded.solver.data = bytes(raw)
    return change


def _relabel(plant):
    def change(decoded, native_state):
        decoded.solver = native_state(plant, decoded.solver.data)
    return change


def _not_bytes(decoded, native_state):
    decoded.solver = native_state("FrictionLoop", list(decoded.solver.data[:8]))


def _facade_time(decoded, _native_state):
    decoded.values["_time"] += 0.5


@pytest.mark.parametrize("label, change, message", [
    ("magic", _flip(0), "serialized state refused: these bytes are not a state of the dfwb C core"),
    ("abi", _flip(9), "serialized state refused: the state was written by core ABI"),
    ("kind", _flip(12), "serialized state refused: the state is one of a"),
    ("payload", _flip(100), "serialized state refused: the state's checksum does not match its bytes"),
    ("last byte", _flip(-1), "serialized state refused: the state's checksum does not match its bytes"),
    ("negative mass", _field("M", -1.0), "the state's parameters are refused: M = -1.0 is out of range"),
    ("order 9", _field("order", 9), "serialized state refused: the state's order"),
    ("negative time", _field("t", -1.0), "serialized state refused: the state's t"),
    ("NaN time", _field("t", math.nan), "serialized state refused: the state's t"),
    ("mode key", _field("key", 7), "serialized state refused: the state's mode"),
    ("counter", _field("count", -1), "serialized state refused: the state's count"),
    ("another mass", _field("M", 2.0), "the state's solver does not match its parameters"),
    ("later time", _field("t", 1.001), "the state's solver time does not match the state's time"),
    ("facade time", _facade_time, "the state's solver time does not match the state's time"),
    ("other loop", _relabel("BacklashLoop"), "the state's solver is a compiled 'BacklashLoop', not a FrictionLoop"),
    ("a plant", _relabel("FrictionMass"), "the state's solver is a compiled 'FrictionMass', not a FrictionLoop"),
    ("data not bytes", _not_bytes, "the state's native solver is damaged"),
])
def test_a_crafted_native_state_is_refused(loop_fmus, solver, label, change, message):
    path = loop_fmus["FrictionMassLoop"]
    fmu, description, messages = _instance(path, STATE_START["FrictionMassLoop"], None, solver)
    t1 = _run(fmu, 0.0, 1.0, 0.1)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    bad = _crafted(path, good, change)
    assert bad != good
    before = _read(fmu, description)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(bad))
    errors = [text for status, text in messages if status >= 3]
    assert len(errors) == 1 and errors[0].startswith("FrictionMassLoop: ") and message in errors[0], (label, errors)
    assert _read(fmu, description) == before  # nothing changed, the getters still work
    with pytest.raises(Exception, match="failed with status 3"):  # the Error state
        fmu.doStep(t1, 0.1)
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))  # a good state leaves the Error state
    _run(fmu, t1, 1.5, 0.1)


def test_the_bytes_of_another_loop_labelled_as_this_one_are_refused(loop_fmus, solver):
    path = loop_fmus["FrictionMassLoop"]
    fmu, _, messages = _instance(path, STATE_START["FrictionMassLoop"], None, solver)
    other_path = loop_fmus["StaticBacklashLoop"]
    other, _, _ = _instance(other_path, STATE_START["StaticBacklashLoop"], None, solver)
    foreign = _fmu_classes(other_path)[0]._fmu_state_from_bytes(other.serializeFMUstate(other.getFMUstate()))
    good = fmu.serializeFMUstate(fmu.getFMUstate())

    def change(decoded, _native_state):
        decoded.solver.data = foreign.solver.data

    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(_crafted(path, good, change)))
    assert [text for status, text in messages if status >= 3] == [
        "FrictionMassLoop: the state was refused when it was deserialized: serialized state refused: the state is "
        "one of a dfwb_static_backlash_loop, not of a dfwb_friction_loop"]


def test_a_native_state_into_an_fmu_without_core_is_refused(loop_fmus, solver, tmp_path):
    path = loop_fmus["TwoMassBacklashLoop"]
    fmu, _, _ = _instance(path, STATE_START["TwoMassBacklashLoop"], None, solver)
    _run(fmu, 0.0, 0.5, 0.1)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    bare, description, messages = _instance(_without_core(path, tmp_path), {}, None, solver)
    assert [status for status, text in messages if "runs on the pure-Python solver" in text] == [1]
    with pytest.raises(Exception, match="failed with status 3"):
        bare.setFMUstate(bare.deSerializeFMUstate(data))
    assert [text for status, text in messages if status >= 3] == [
        "TwoMassBacklashLoop: the state holds a solver of the compiled core, which this instance cannot use: the "
        "FMU has no compiled core (no resources/libdfwb_core.so)"]


FUZZ = r"""
import json, math, struct, sys, zlib
sys.path.insert(0, sys.argv[3])
from conftest import new_instance
from dfwb.build_fmus import builder
from pathlib import Path

path, start = Path(sys.argv[1]), json.loads(sys.argv[2])
fmu, description, messages = new_instance(path, "fuzz")
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
by_name = {v.name: v for v in description.modelVariables}
for name, value in start.items():
    var = by_name[name]
    (fmu.setInteger if var.type == "Integer" else fmu.setReal)([var.valueReference], [type(value)(value)])
fmu.exitInitializationMode()
reals = [v.valueReference for v in description.modelVariables if v.type == "Real"]
package = f"dfwb_fmus_{builder.recorded_hash(path)}"
cls = getattr(sys.modules[f"{package}.loop_facade"], path.stem)
HEADER = 24
SPECIAL = [math.nan, math.inf, -math.inf, -1.0, 0.0, -0.0, 0.5, 2.0, 1e308, 5e-324]
INTS = [-1, 1, 2, 3, 9, 2**31 - 1, -2**63]
tally = {"refused": 0, "accepted": 0, "stepped": 0, "step refused": 0}
t = 0.0
for point in (0.7, 1.9):
    while t < point - 1e-12:
        fmu.doStep(t, 0.1)
        t += 0.1
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    decoded = cls._fmu_state_from_bytes(good)
    data = decoded.solver.data
    for i in range((len(data) - HEADER) // 8):
        for value in SPECIAL + INTS:
            raw = bytearray(data)
            raw[HEADER + 8 * i:HEADER + 8 * i + 8] = (struct.pack("<d", value) if type(value) is float
                                                      else struct.pack("<q", value))
            raw[20:24] = struct.pack("<I", zlib.crc32(bytes(raw[HEADER:])))
            if bytes(raw) == data:
                continue
            decoded.solver.data = bytes(raw)
            bad = cls._fmu_state_to_bytes(decoded)
            errors = len([m for m in messages if m[0] >= 3])
            handle = fmu.deSerializeFMUstate(bad)
            try:
                fmu.setFMUstate(handle)
            except Exception:
                assert len([m for m in messages if m[0] >= 3]) == errors + 1, messages[-3:]
                assert messages[-1][1].startswith(path.stem + ": the state"), messages[-1]
                tally["refused"] += 1
            else:
                tally["accepted"] += 1
                try:
                    fmu.doStep(t, 0.5)
                    tally["stepped"] += 1
                except Exception:
                    tally["step refused"] += 1
                assert all(math.isfinite(x) for x in fmu.getReal(reals))
            fmu.freeFMUstate(handle)
            handle = fmu.deSerializeFMUstate(good)
            fmu.setFMUstate(handle)  # always restorable
            fmu.freeFMUstate(handle)
    decoded.solver.data = data
print(json.dumps(tally))
"""


@pytest.mark.parametrize("model", MODELS)
def test_state_fuzzing_never_crashes(loop_fmus, model):
    """Every field of the C loop's bytes set to extreme values (checksum made valid), at two points of a run:
    refused with one error, or accepted and stepped with finite outputs; a good state always restores. In a
    subprocess, so that a crash would fail the test, not end it."""
    tests = str(Path(__file__).resolve().parent)
    run = subprocess.run([sys.executable, "-c", FUZZ, str(loop_fmus[model]), json.dumps(STATE_START[model]), tests],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"the fuzzing process failed (exit {run.returncode}): {run.stderr[-2000:]}"
    tally = json.loads(run.stdout.strip().splitlines()[-1])
    print(f"\n{model} FMU state fuzzing: {tally}")
    assert tally["refused"] > 300 and tally["accepted"] + tally["refused"] > 800


# -- speed -------------------------------------------------------------------------------------------------

def test_speed_of_a_loop_fmu_run(loop_fmus, solver):
    """Printed with -s, not asserted: fmpy runs of loop FMUs on the core and in Python."""
    rows = []
    for model, case, stop in (("TwoMassBacklashLoop", 0, 50.0), ("FrictionMassLoop", 0, 100.0)):
        start, t0, _stop, dt = CASES[model][case]
        seconds, results = {}, {}
        for kind in (None, "python"):
            solver(kind)
            directory, description = unpacked(loop_fmus[model])
            _simulate(directory, description, start, t0, 1.0, dt)  # warm-up: the extraction, the library
            started = time.perf_counter()
            results[kind], _, error = _simulate(directory, description, start, t0, stop, dt)
            seconds[kind] = time.perf_counter() - started
            assert error is None
        assert results[None].tobytes() == results["python"].tobytes()
        rows.append(f"{model} {stop:g} s, step {dt:g}, {results[None]['events'][-1]} events: compiled core "
                    f"{seconds[None] * 1e3:.0f} ms, DFWB_FMU_SOLVER=python {seconds['python'] * 1e3:.0f} ms "
                    f"({seconds['python'] / seconds[None]:.1f}x)")
    print("\n" + "\n".join(rows))
