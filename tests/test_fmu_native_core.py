"""The pythonfmu plant FMUs on the compiled core (resources/libdfwb_core.so), against the pure-Python oracle.

The same FMU runs either way: with the core (the default when it loads) or with
``DFWB_FMU_SOLVER=python``. fmpy runs the FMU in this process, so the variable
set here is what the instance reads at exitInitializationMode. Every output
(events and the Fourier integrals included) must agree bit for bit, refusals
must say the same, FMU states must continue bit for bit, and a crafted state
must be refused cleanly. ``pytest -s`` prints a DF point's time both ways.
"""

import shutil
import struct
import sys
import time
import zipfile

import fmpy
import pytest
from conftest import new_instance
from fmpy.fmi1 import FMICallException

from dfwb.build_fmus import builder
from dfwb.fmi.simulation import unpacked
from dfwb.fmus import facade

pytestmark = pytest.mark.needs_cc

PLANTS = ("FrictionMass", "TwoMassBacklash", "StaticBacklash")
CASES = {  # model: [(start values, start time, stop time, communication step)]
    "FrictionMass": [
        ({"F": 10.0, "omega": 1.0}, 0.0, 20.0, 0.05),
        ({"F": 8.0, "omega": 3.0, "B": 0.0, "Dv": 0.01, "x0": 0.5, "v0": -1.0, "phi": 0.3, "f": 1.5}, 0.0, 8.0, 0.02),
        ({"F": 20.0, "omega": 0.5, "M": 2.0, "Fs": 5.0, "harmonics": 3}, 1.7, 30.0, 0.1),
    ],
    "TwoMassBacklash": [
        ({"F": 50.0, "omega": 20.0, "eps": 0.5}, 0.0, 2.0, 0.005),
        ({"F": 30.0, "omega": 7.0, "eps": 0.0, "gap0": 0.0, "v1_0": 0.3}, 0.0, 3.0, 0.01),
        ({"F": 80.0, "omega": 15.0, "eps": 1.0, "h": 0.05, "M1": 2.0, "phi": -0.4}, 2.5, 4.5, 0.004),
    ],
    "StaticBacklash": [
        ({"F": 50.0, "omega": 20.0}, 0.0, 2.0, 0.005),
        ({"F": 10.0, "omega": 3.0, "k": 2.0, "h": 0.3, "x0": 0.1, "f": -0.5}, 0.0, 6.0, 0.02),
        ({"F": 40.0, "omega": 9.0, "M": 0.5, "harmonics": 10}, 3.25, 5.0, 0.01),
    ],
}
REFUSED = [  # (model, a bad parameter set, the start of the message it gets: the Python solver's text)
    ("FrictionMass", {"Fc": 5.0, "Fs": 3.0}, "invalid parameter: Fs = 3.0 is out of range"),
    ("FrictionMass", {"M": 0.0}, "invalid parameter: M = 0.0 is out of range"),
    ("FrictionMass", {"omega": -1.0}, "invalid parameter: omega = -1.0 is out of range"),
    ("FrictionMass", {"phi": 1e11}, "invalid parameter: phi = 100000000000.0 is out of range"),
    ("FrictionMass", {"harmonics": 11}, "invalid parameter: harmonics = 11 is out of range"),
    ("FrictionMass", {"F": 1e300, "M": 1e-300}, ""),  # overflows: the same refusal either way
    ("TwoMassBacklash", {"eps": 1.5}, "invalid parameter: eps = 1.5 is out of range"),
    ("TwoMassBacklash", {"gap0": 0.2}, "invalid parameter: gap0 = 0.2 is out of range"),
    ("TwoMassBacklash", {"h": 0.0}, "invalid parameter: h = 0.0 is out of range"),
    ("StaticBacklash", {"h": -0.1}, "invalid parameter: h = -0.1 is out of range"),
    ("StaticBacklash", {"k": 0.0}, "invalid parameter: k = 0.0 is out of range"),
]
STATE_START = {"FrictionMass": {"F": 10.0, "omega": 1.0, "Dv": 0.01}, "TwoMassBacklash": {"F": 50.0, "omega": 20.0},
               "StaticBacklash": {"F": 50.0, "omega": 20.0}}


def _has_cc():
    return any(shutil.which(name) for name in ("cc", "gcc", "clang"))


@pytest.fixture(scope="module")
def plant_fmus(tmp_path_factory):
    """{model: path} of the three plant FMUs, built with the compiled core into a private folder."""
    if not _has_cc():
        pytest.skip("no C compiler (cc) on PATH to build the core")
    core, why = builder.core_binary()
    assert core is not None, why
    lines = []
    paths = builder.build(tmp_path_factory.mktemp("plant_fmus"), [getattr(facade, model) for model in PLANTS],
                          report=lines.append)
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
    """(fmpy's result as bytes, its log [(status, text)], the error or None) of one run of every output."""
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
    return native, python


@pytest.mark.parametrize("model", PLANTS)
@pytest.mark.parametrize("case", range(3))
def test_outputs_are_bit_identical_to_the_python_solver(plant_fmus, solver, model, case):
    start, t0, stop, dt = CASES[model][case]
    (native, native_log, error), (python, python_log, python_error) = _both(plant_fmus[model], solver, start, t0,
                                                                            stop, dt)
    assert error is None and python_error is None, (native_log, python_log)
    assert native.dtype == python.dtype and len(native) == len(python) > 10
    assert native.tobytes() == python.tobytes()  # every output, events and Ic0..Is10 included
    assert native["events"][-1] > 0  # the cases exercise events
    assert abs(native["time"][0] - t0) < 1e-12
    assert any(status == 0 and "runs on the compiled core" in text for status, text in native_log), native_log
    assert any(status == 0 and "runs on the pure-Python solver (DFWB_FMU_SOLVER=python)" in text
               for status, text in python_log), python_log
    assert not [m for m in native_log + python_log if m[0] >= 1]


@pytest.mark.parametrize("model, bad, text", REFUSED)
def test_a_refused_parameter_says_the_same_on_both_solvers(plant_fmus, solver, model, bad, text):
    start = dict(CASES[model][0][0], **bad)
    (_, native_log, error), (_, python_log, python_error) = _both(plant_fmus[model], solver, start, 0.0, 1.0, 0.1)
    assert error and python_error
    native_errors = [m for m in native_log if m[0] >= 3]
    python_errors = [m for m in python_log if m[0] >= 3]
    assert native_errors == python_errors and len(native_errors) == 1
    assert native_errors[0][1].startswith(f"{model}: {text}"), native_errors


def _without_core(path, tmp_path, replacement=None):
    """A copy of the FMU whose core is missing (or replaced by ``replacement`` bytes)."""
    copy = tmp_path / "bare" / path.name
    copy.parent.mkdir()
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(copy, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            if item.filename == builder.CORE_RESOURCE:
                if replacement is not None:
                    target.writestr(item, replacement)
            else:
                target.writestr(item, source.read(item.filename))
    return copy


@pytest.mark.parametrize("damage, reason", [(None, "the FMU has no compiled core (no resources/libdfwb_core.so)"),
                                            (b"not a library\n", "cannot load the C core")])
def test_the_fmu_falls_back_to_python_with_one_warning(plant_fmus, solver, tmp_path, damage, reason):
    path = plant_fmus["FrictionMass"]
    directory, description = unpacked(_without_core(path, tmp_path, damage))
    start, t0, stop, dt = CASES["FrictionMass"][0]
    result, log, error = _simulate(directory, description, start, t0, stop, dt)
    assert error is None
    warnings = [text for status, text in log if status >= 1]
    assert len(warnings) == 1 and reason in warnings[0], log
    assert warnings[0].endswith("it runs on the pure-Python solver")
    assert [status for status, text in log if text == warnings[0]] == [1]  # status warning
    solver("python")
    reference, _, _ = _simulate(*unpacked(path), start, t0, stop, dt)
    assert result.tobytes() == reference.tobytes()

    solver("native")  # the core is required: its absence is an error at exitInitializationMode
    result, log, error = _simulate(directory, description, start, t0, stop, dt)
    assert result is None and "ExitInitializationMode" in error
    errors = [text for status, text in log if status >= 3]
    assert errors and errors[0].startswith("FrictionMass: DFWB_FMU_SOLVER=native, but the compiled core cannot be "
                                           "used: ") and reason in errors[0]


def test_a_bad_solver_choice_is_refused(plant_fmus, solver):
    solver("fortran")
    result, log, error = _simulate(*unpacked(plant_fmus["StaticBacklash"]), {"F": 1.0}, 0.0, 1.0, 0.1)
    assert result is None and error
    assert [text for status, text in log if status >= 3][0] == (
        "StaticBacklash: DFWB_FMU_SOLVER = 'fortran' is refused: it must be 'native' (the compiled core; an error "
        "if it cannot be used) or 'python' (the pure-Python solver), or unset")


# -- FMU state -------------------------------------------------------------------------------------

def _instance(path, start, kind, solver, start_time=0.0):
    solver(kind)
    fmu, description, messages = new_instance(path, "state")
    fmu.setupExperiment(startTime=start_time)
    fmu.enterInitializationMode()
    by_name = {v.name: v for v in description.modelVariables}
    for name, value in start.items():
        fmu.setReal([by_name[name].valueReference], [float(value)])
    fmu.exitInitializationMode()
    solver(None)
    return fmu, description, messages


def _read(fmu, description):
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


@pytest.mark.parametrize("model", PLANTS)
def test_states_continue_bit_identically_on_the_core(plant_fmus, solver, model):
    path, start = plant_fmus[model], STATE_START[model]
    python, description, _ = _instance(path, start, "python", solver, start_time=0.5)
    _run(python, 0.5, 1.5, 0.05)
    reference = _read(python, description)

    fmu, _, messages = _instance(path, start, None, solver, start_time=0.5)
    assert "runs on the compiled core" in _solver_log(messages)[0]
    t1 = _run(fmu, 0.5, 0.9, 0.05)
    saved = fmu.getFMUstate()
    data = fmu.serializeFMUstate(saved)
    _run(fmu, t1, 1.5, 0.05)
    assert _read(fmu, description) == reference
    fmu.setFMUstate(saved)  # in memory: the C solver copied
    _run(fmu, t1, 1.5, 0.05)
    assert _read(fmu, description) == reference
    fmu.setFMUstate(fmu.deSerializeFMUstate(data))  # from bytes: read back by the instance's own core
    _run(fmu, t1, 1.5, 0.05)
    assert _read(fmu, description) == reference

    fresh, _, fresh_messages = _instance(path, {}, None, solver)  # another instance, default parameters
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    _run(fresh, t1, 1.5, 0.05)
    assert _read(fresh, description) == reference
    assert not [m for m in messages + fresh_messages if m[0] >= 1]


@pytest.mark.parametrize("source, target", [("python", None), (None, "python")])
def test_a_state_of_either_solver_is_accepted_by_either_instance(plant_fmus, solver, source, target):
    path, start = plant_fmus["TwoMassBacklash"], STATE_START["TwoMassBacklash"]
    fmu, description, _ = _instance(path, start, source, solver)
    t1 = _run(fmu, 0.0, 0.3, 0.02)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    _run(fmu, t1, 0.8, 0.02)
    other, _, messages = _instance(path, {}, target, solver)
    other.setFMUstate(other.deSerializeFMUstate(data))
    _run(other, t1, 0.8, 0.02)
    assert _read(other, description) == _read(fmu, description)
    assert not [m for m in messages if m[0] >= 1]


def _fmu_classes(path):
    """(the FMU's own facade class, its state module): the FMU runs in this process under its package name."""
    package = f"dfwb_fmus_{builder.recorded_hash(path)}"
    return getattr(sys.modules[f"{package}.facade"], path.stem), sys.modules[f"{package}.state"]


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


def _other_plant(decoded, native_state):
    decoded.solver = native_state("StaticBacklash", decoded.solver.data)


def _not_bytes(decoded, native_state):
    decoded.solver = native_state("FrictionMass", list(decoded.solver.data[:8]))


@pytest.mark.parametrize("label, change, message", [
    ("magic", _flip(0), "serialized state refused"),
    ("header", _flip(9), "serialized state refused"),
    ("payload", _flip(60), "serialized state refused"),
    ("last byte", _flip(-1), "serialized state refused"),
    ("other plant", _other_plant, "the state's solver is a compiled 'StaticBacklash', not a FrictionMass"),
    ("data not bytes", _not_bytes, "the state's native solver is damaged"),
])
def test_a_crafted_native_state_is_refused(plant_fmus, solver, label, change, message):
    path = plant_fmus["FrictionMass"]
    fmu, description, messages = _instance(path, STATE_START["FrictionMass"], None, solver)
    t1 = _run(fmu, 0.0, 0.5, 0.1)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    bad = _crafted(path, good, change)
    assert bad != good
    before = _read(fmu, description)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(bad))
    errors = [text for status, text in messages if status >= 3]
    assert len(errors) == 1 and message in errors[0], (label, errors)
    assert _read(fmu, description) == before  # nothing changed, the getters still work
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))  # a good state leaves the Error state
    _run(fmu, t1, 0.8, 0.1)


def test_a_native_state_of_other_parameters_is_refused(plant_fmus, solver):
    """The facade values say M = 1; the (genuine, checksummed) C solver state is one of M = 2."""
    path = plant_fmus["FrictionMass"]
    fmu, description, messages = _instance(path, STATE_START["FrictionMass"], None, solver)
    other, _, _ = _instance(path, dict(STATE_START["FrictionMass"], M=2.0), None, solver)
    for instance in (fmu, other):
        _run(instance, 0.0, 0.5, 0.1)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    foreign = _fmu_classes(path)[0]._fmu_state_from_bytes(other.serializeFMUstate(other.getFMUstate())).solver.data

    def change(decoded, _native_state):
        decoded.solver.data = foreign

    bad = _crafted(path, good, change)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(bad))
    assert [text for status, text in messages if status >= 3] == [
        "FrictionMass: the state's solver does not match its parameters"]
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))
    _run(fmu, 0.5, 0.8, 0.1)


def test_a_native_state_into_an_fmu_without_core_is_refused(plant_fmus, solver, tmp_path):
    path = plant_fmus["FrictionMass"]
    fmu, _, _ = _instance(path, STATE_START["FrictionMass"], None, solver)
    _run(fmu, 0.0, 0.5, 0.1)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    bare, description, messages = _instance(_without_core(path, tmp_path), {}, None, solver)
    assert [status for status, text in messages if "runs on the pure-Python solver" in text] == [1]
    with pytest.raises(Exception, match="failed with status 3"):
        bare.setFMUstate(bare.deSerializeFMUstate(data))
    assert [text for status, text in messages if status >= 3] == [
        "FrictionMass: the state holds a solver of the compiled core, which this instance cannot use: the FMU has "
        "no compiled core (no resources/libdfwb_core.so)"]


# -- speed ----------------------------------------------------------------------------------------

def test_speed_of_a_df_point(plant_fmus, solver):
    """Printed with -s, not asserted: a DF point of the friction mass (and a long run), on the core and in Python."""
    from dfwb.engine.describing import DFEngine

    repeats = 20
    seconds, results, runs = {}, {}, {}
    start, t0, stop, dt = CASES["FrictionMass"][0]
    for kind in (None, "python"):
        solver(kind)
        engine = DFEngine("friction", fmu=plant_fmus["FrictionMass"])
        engine.point(F=10.0, omega=1.0)  # warm-up: the instances, the extraction, the library
        started = time.perf_counter()
        for _ in range(repeats):
            results[kind] = engine.point(F=10.0, omega=1.0).as_dict()
        seconds[kind] = (time.perf_counter() - started) / repeats
        started = time.perf_counter()
        _simulate(*unpacked(plant_fmus["FrictionMass"]), dict(start, F=50.0), t0, 200.0, 0.5)
        runs[kind] = time.perf_counter() - started
        results[kind].pop("seconds")
    assert results[None] == results["python"]
    print(f"\nDF point friction F=10 omega=1 (mean of {repeats}): compiled core {seconds[None] * 1e3:.2f} ms, "
          f"DFWB_FMU_SOLVER=python {seconds['python'] * 1e3:.2f} ms ({seconds['python'] / seconds[None]:.1f}x); "
          f"fmpy run of 200 s, F=50: {runs[None] * 1e3:.1f} ms vs {runs['python'] * 1e3:.1f} ms "
          f"({runs['python'] / runs[None]:.1f}x)")
