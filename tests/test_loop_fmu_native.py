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
import struct
import subprocess
import sys
import time
from pathlib import Path

import native_fmu_helpers as helpers
import pytest

from dfwb.build_fmus import builder
from dfwb.fmi.simulation import unpacked
from dfwb.fmus import loop_facade

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
    ("StaticBacklashLoop", {"order": 1, "b0": 1e300, "x0": 1e300},
     "invalid parameter: the state is beyond [-1e+150, 1e+150] at t = 0.0 s"),
    ("StaticBacklashLoop", {"order": 1, "b0": 1e300, "x0": 1e100}, "invalid parameter: the initial outputs overflow"),
    # positive feedback f = +1e6 y: the motion overflows, doStep is refused
    ("FrictionMassLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x0": 1.0}, "step from t = "),
    ("TwoMassBacklashLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x1_0": 1.0}, "step from t = "),
    ("StaticBacklashLoop", {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, "x0": 1.0}, "step from t = "),
]
STATE_START = {model: CASES[model][0][0] for model in MODELS}
FIELD = {"M": 0, "order": 56, "t": 256, "events": 264, "count": 272, "key": 280}  # payload offsets of some


@pytest.fixture(scope="module")
def loop_fmus(tmp_path_factory):
    """{model: path} of the three loop FMUs, built with the compiled core into a private folder."""
    assert all(builder.native(model) for model in loop_facade.LOOPS)
    return helpers.build_with_core(tmp_path_factory.mktemp("loop_fmus"), loop_facade.LOOPS)


# -- outputs and refusals -------------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("case", range(3))
def test_outputs_are_bit_identical_to_the_python_loop(loop_fmus, solver, model, case):
    start, t0, stop, dt = CASES[model][case]
    native, native_log, python_log = helpers.identical_on_both(loop_fmus[model], solver, start, t0, stop, dt)
    assert native["time"][0] == t0 and abs(native["time"][-1] - stop) < 1e-9  # every output, counters included
    assert [(status, text.split(" (")[0]) for status, text in native_log] == [
        (0, f"{model}: runs on the compiled core")], native_log
    assert "libdfwb_core.so" in native_log[0][1]
    assert python_log == [(0, f"{model}: runs on the pure-Python solver (DFWB_FMU_SOLVER=python)")]


@pytest.mark.parametrize("model, bad, text", REFUSED)
def test_a_refusal_says_the_same_on_both_solvers(loop_fmus, solver, model, bad, text):
    native_log, python_log, error, python_error = helpers.refused_on_both(loop_fmus[model], solver, bad, 2.0)
    assert error == python_error  # the same call fails
    native_errors = [m for m in native_log if m[0] >= 3]
    assert native_errors[0][1].startswith(f"{model}: {text}"), native_errors
    assert "runs on the compiled core" in native_log[0][1] and "DFWB_FMU_SOLVER=python" in python_log[0][1]


# -- which solver runs -------------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("damage, reason", [(None, "the FMU has no compiled core (no resources/libdfwb_core.so)"),
                                            (b"not a library\n", "cannot load the C core")])
def test_the_fmu_falls_back_to_python_with_one_warning(loop_fmus, solver, tmp_path, model, damage, reason):
    log, errors = helpers.falls_back(loop_fmus[model], tmp_path, solver, damage, CASES[model][0])
    assert len(log) == 1 and log[0][0] == 1, log  # status warning, the only message
    assert log[0][1].startswith(f"{model}: the compiled core cannot be used (") and reason in log[0][1]
    assert log[0][1].endswith("it runs on the pure-Python solver")
    assert len(errors) == 1 and errors[0].startswith(f"{model}: DFWB_FMU_SOLVER=native, but the compiled core "
                                                     f"cannot be used: ") and reason in errors[0]


def test_native_forced_runs_on_the_core_and_a_bad_choice_is_refused(loop_fmus, solver):
    start, t0, stop, dt = CASES["StaticBacklashLoop"][0]
    (default, _, _), _ = helpers.both(loop_fmus["StaticBacklashLoop"], solver, start, t0, stop, dt)
    solver("native")
    result, log, error = helpers.simulate(*unpacked(loop_fmus["StaticBacklashLoop"]), start, t0, stop, dt)
    assert error is None and result.tobytes() == default.tobytes()
    assert len(log) == 1 and log[0][0] == 0 and "StaticBacklashLoop: runs on the compiled core" in log[0][1]
    assert helpers.refuses_a_bad_choice(loop_fmus["StaticBacklashLoop"], solver) == [
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

@pytest.mark.parametrize("model", MODELS)
def test_states_continue_bit_identically_on_the_core(loop_fmus, solver, model):
    data, _, fresh_messages = helpers.states_continue(loop_fmus[model], STATE_START[model], solver, 1.7, 3.0, 0.0137)
    assert len(helpers.solver_log(fresh_messages)) == 1  # restoring a state logs no new choice
    cls = helpers.fmu_classes(loop_fmus[model], "loop_facade")[0]
    assert type(cls._fmu_state_from_bytes(data).solver).__name__ == "NativeState"  # the C loop's bytes


@pytest.mark.parametrize("source, target", [("python", None), (None, "python")])
def test_a_state_of_either_solver_is_accepted_by_either_instance(loop_fmus, solver, source, target):
    helpers.state_crosses_solvers(loop_fmus["TwoMassBacklashLoop"], STATE_START["TwoMassBacklashLoop"], solver, source,
                          target, 1.0, 2.0, 0.02)


def _field(name, value):
    """Set a field of the C loop's payload (the checksum made valid again: only the C core's checks stand)."""
    def change(decoded, _native_state):
        raw = bytearray(decoded.solver.data)
        offset = helpers.HEADER + FIELD[name]
        raw[offset:offset + 8] = struct.pack("<d", value) if type(value) is float else struct.pack("<q", value)
        decoded.solver.data = helpers.with_crc(raw)
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
    ("magic", helpers.flip(0), "serialized state refused: these bytes are not a state of the dfwb C core"),
    ("abi", helpers.flip(9), "serialized state refused: the state was written by core ABI"),
    ("kind", helpers.flip(12), "serialized state refused: the state is one of a"),
    ("payload", helpers.flip(100), "serialized state refused: the state's checksum does not match its bytes"),
    ("last byte", helpers.flip(-1), "serialized state refused: the state's checksum does not match its bytes"),
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
    fmu, good, t1, errors = helpers.crafted_is_refused(loop_fmus["FrictionMassLoop"], "loop_facade",
                                               STATE_START["FrictionMassLoop"], solver, change, 1.0, 0.1)
    assert len(errors) == 1 and errors[0].startswith("FrictionMassLoop: ") and message in errors[0], (label, errors)
    with pytest.raises(Exception, match="failed with status 3"):  # the Error state
        fmu.doStep(t1, 0.1)
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))  # a good state leaves the Error state
    helpers.run(fmu, t1, 1.5, 0.1)


def test_the_bytes_of_another_loop_labelled_as_this_one_are_refused(loop_fmus, solver):
    path = loop_fmus["FrictionMassLoop"]
    fmu, _, messages = helpers.instance(path, STATE_START["FrictionMassLoop"], None, solver)
    other_path = loop_fmus["StaticBacklashLoop"]
    other, _, _ = helpers.instance(other_path, STATE_START["StaticBacklashLoop"], None, solver)
    cls = helpers.fmu_classes(other_path, "loop_facade")[0]
    foreign = cls._fmu_state_from_bytes(other.serializeFMUstate(other.getFMUstate()))
    good = fmu.serializeFMUstate(fmu.getFMUstate())

    def change(decoded, _native_state):
        decoded.solver.data = foreign.solver.data

    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(helpers.crafted(path, "loop_facade", good, change)))
    assert [text for status, text in messages if status >= 3] == [
        "FrictionMassLoop: the state was refused when it was deserialized: serialized state refused: the state is "
        "one of a dfwb_static_backlash_loop, not of a dfwb_friction_loop"]


def test_a_native_state_into_an_fmu_without_core_is_refused(loop_fmus, solver, tmp_path):
    assert helpers.refused_without_core(loop_fmus["TwoMassBacklashLoop"], STATE_START["TwoMassBacklashLoop"], solver,
                                tmp_path) == [
        "TwoMassBacklashLoop: the state holds a solver of the compiled core, which this instance cannot use: the "
        "FMU has no compiled core (no resources/libdfwb_core.so)"]


FUZZ = r"""
import json, math, struct, sys
sys.path.insert(0, sys.argv[3])
from native_fmu_helpers import HEADER, fmu_classes, initialised, with_crc
from pathlib import Path

path, start = Path(sys.argv[1]), json.loads(sys.argv[2])
fmu, description, messages = initialised(path, start, name="fuzz")
reals = [v.valueReference for v in description.modelVariables if v.type == "Real"]
cls = fmu_classes(path, "loop_facade")[0]
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
            raw = with_crc(raw)
            if raw == data:
                continue
            decoded.solver.data = raw
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
            helpers.simulate(directory, description, start, t0, 1.0, dt)  # warm-up: the extraction, the library
            started = time.perf_counter()
            results[kind], _, error = helpers.simulate(directory, description, start, t0, stop, dt)
            seconds[kind] = time.perf_counter() - started
            assert error is None
        assert results[None].tobytes() == results["python"].tobytes()
        rows.append(f"{model} {stop:g} s, step {dt:g}, {results[None]['events'][-1]} events: compiled core "
                    f"{seconds[None] * 1e3:.0f} ms, DFWB_FMU_SOLVER=python {seconds['python'] * 1e3:.0f} ms "
                    f"({seconds['python'] / seconds[None]:.1f}x)")
    print("\n" + "\n".join(rows))
