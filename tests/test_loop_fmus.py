"""The closed-loop FMUs (plant + controller -G(s) in one FMU): exact, step-independent, refusing, restorable."""

import math
import pickle
import re
import tempfile

import fmpy
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu
from native_fmu_helpers import initialised, read, run

from dfwb.build_fmus import builder
from dfwb.fmi import location
from dfwb.fmus import facade, loop_facade, state
from dfwb.fmus.backlash import BacklashLoop
from dfwb.fmus.contract import EventKind
from dfwb.fmus.friction import FrictionLoop
from dfwb.fmus.hybrid import Mode, Polynomial
from dfwb.fmus.linear_system import LinearSystem
from dfwb.fmus.static_backlash import StaticBacklashLoop

MODELS = ["FrictionMassLoop", "TwoMassBacklashLoop", "StaticBacklashLoop"]
START = {  # model: start values of a loop with events (stick-slip hunting, impacts, engagements)
    # PID with a filtered derivative: (2 s^2 + 30 s + 60) / (s (0.05 s + 1))
    "FrictionMassLoop": {"order": 2, "b0": 40.0, "b1": 600.0, "b2": 1200.0, "a1": 20.0, "x0": 1.0},
    # PD with a filtered derivative: (2 s + 20) / (0.05 s + 1)
    "TwoMassBacklashLoop": {"order": 1, "b0": 40.0, "b1": 400.0, "a1": 20.0, "x1_0": 1.0, "eps": 0.5},
    "StaticBacklashLoop": {"order": 1, "b0": 100.0, "b1": 400.0, "a1": 20.0, "x0": 1.0, "z1_0": 0.01},
}
OUTPUTS = {
    "FrictionMassLoop": ["x", "v", "Ff", "f", "mode", "events", "sticks"],
    "TwoMassBacklashLoop": ["x1", "v1", "x2", "v2", "gap", "f", "contact", "events", "impacts"],
    "StaticBacklashLoop": ["x", "v", "y", "f", "engaged", "events", "engagements"],
}
PLANTS = {"FrictionMassLoop": facade.FrictionMass, "TwoMassBacklashLoop": facade.TwoMassBacklash,
          "StaticBacklashLoop": facade.StaticBacklash}
SOLVERS = {"FrictionMassLoop": FrictionLoop, "TwoMassBacklashLoop": BacklashLoop,
           "StaticBacklashLoop": StaticBacklashLoop}
Y0 = {"FrictionMassLoop": "x0", "TwoMassBacklashLoop": "x1_0", "StaticBacklashLoop": "x0"}  # initial position
FACADES = {model.__name__: model for model in loop_facade.LOOPS}
CONTROLLER = ["order"] + [f"b{i}" for i in range(9)] + [f"a{i}" for i in range(1, 9)]
EXCITATION = {"F", "omega", "phi", "harmonics", "f"}


@pytest.fixture(scope="module")
def loop_fmus():
    """{model: path} of the three loop FMUs, built through dfwb.fmi.location (into build/fmus, see conftest)."""
    return {model: location.fmu_path(model) for model in MODELS}


def _solver(model, start=None):
    """The in-process solver of a model with the FMU's start values (the FMU's defaults otherwise)."""
    values = {name: default for name, default, *_ in FACADES[model].parameters}
    values.update(dict(loop_facade.CONTROLLER_DEFAULTS))
    values.update(START[model] if start is None else start)
    order = values["order"]
    b = [values[f"b{i}"] for i in range(order + 1)]
    a = [values[f"a{i}"] for i in range(1, order + 1)]
    z0 = [values[f"z{i}_0"] for i in range(1, order + 1)]
    kwargs = FACADES[model].solver_kwargs({name: values[name] for name, *_ in FACADES[model].parameters})
    return SOLVERS[model](b, a, z0=z0, **kwargs)


def _expected(model, solver):
    """The FMU's outputs computed from the in-process solver (named as OUTPUTS[model])."""
    X = solver.state()
    f = solver.force(X)
    mode = FACADES[model].mode_keys[solver.key]
    counter = list(solver.counts().values())[0]
    if model == "FrictionMassLoop":
        ff = f if mode == 0 else mode * solver.Fc + solver.B * X[1]
        return (X[0], X[1], ff, f, mode, solver.events, counter)
    if model == "TwoMassBacklashLoop":
        return (X[0], X[1], X[0] + X[2], X[1] + X[3], X[2], f, mode, solver.events, counter)
    return (X[0], X[1], X[2], f, mode, solver.events, counter)


# -- building and the model description ----------------------------------------------

def test_location_lists_and_builds_the_loops(loop_fmus):
    assert set(loop_facade.LOOPS) <= set(location.models())
    for model, path in loop_fmus.items():
        assert path.name == f"{model}.fmu" and builder.recorded_hash(path) == builder.source_hash(FACADES[model])
        bundled = builder.sources(FACADES[model])
        assert {"loop_facade.py", "loops.py", "hybrid.py"} <= set(bundled) and "naive.py" not in bundled


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate_finds_no_problem(loop_fmus, model):
    assert validate_fmu(str(loop_fmus[model])) == []
    fmpy.read_model_description(str(loop_fmus[model]), validate=True)


@pytest.mark.parametrize("model", MODELS)
def test_variables_are_the_plants_and_the_controllers(loop_fmus, model):
    """The plant FMU's parameters (no excitation) and continuous outputs, LinearSystem.fmu's controller, no input."""
    description = fmpy.read_model_description(str(loop_fmus[model]))
    plant = {v.name: v for v in fmpy.read_model_description(str(location.fmu_path(PLANTS[model].__name__)))
             .modelVariables}
    controller = fmpy.read_model_description(str(location.fmu_path("LinearSystem"))).modelVariables
    variables = {v.name: v for v in description.modelVariables}
    assert not [v for v in description.modelVariables if v.causality == "input"]
    parameters = [v.name for v in description.modelVariables if v.causality == "parameter"]
    assert parameters == [v for v in plant if plant[v].causality == "parameter" and v not in EXCITATION] \
        + CONTROLLER + [f"z{i}_0" for i in range(1, 9)]
    for name in parameters[:len(parameters) - len(CONTROLLER) - 8]:
        mine, theirs = variables[name], plant[name]
        assert (mine.type, mine.start, mine.unit) == (theirs.type, theirs.start, theirs.unit), name
        assert mine.description == theirs.description or name == "Dv", name
    for theirs in controller:
        if theirs.causality == "parameter":
            mine = variables[theirs.name]
            assert (mine.type, mine.start, mine.min, mine.max) == (theirs.type, theirs.start, theirs.min, theirs.max)
    assert (variables["order"].start, variables["b0"].start, variables["b1"].start, variables["a1"].start) == \
        ("1", "0", "1", "1")  # G(s) = 1 / (s + 1)
    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    assert outputs == OUTPUTS[model]
    assert {v.name for v in plant.values() if v.causality == "output" and v.variability == "continuous"
            and not v.name.startswith("I")} <= set(outputs)
    assert variables["f"].unit == "N" and variables["events"].type == "Integer"
    for variable in description.modelVariables:
        assert variable.description, variable.name
    assert all(unknown.dependencies == [] for unknown in description.outputs)


# -- exactness -------------------------------------------------------------------------------

@pytest.mark.parametrize("model", MODELS)
def test_result_is_bit_identical_for_any_communication_step_and_equals_the_solver(loop_fmus, model):
    finals = []
    for interval in (0.1, 0.0137, 0.001):
        result = fmpy.simulate_fmu(str(loop_fmus[model]), stop_time=10.0, output_interval=interval,
                                   start_values=START[model], output=OUTPUTS[model])
        assert result["time"][-1] == 10.0
        finals.append(tuple(result[-1])[1:])
        if interval == 0.1:  # every communication point, the solver advanced through the same times
            solver = _solver(model)
            for row in result:
                solver.advance(float(row["time"]))
                assert tuple(row)[1:] == _expected(model, solver), row["time"]
    assert finals[0] == finals[1] == finals[2]
    solver = _solver(model)
    solver.advance(10.0)  # in one call
    assert finals[0] == _expected(model, solver)
    assert solver.events > 5 and list(solver.counts().values())[0] > 1  # the loop did switch


@pytest.mark.parametrize("model", MODELS)
def test_force_is_minus_G_of_the_plant_output(loop_fmus, model):
    """f = -(C z + D y) of LinearSystem's realisation of G, bit for bit; a pure gain K: f = -K y."""
    result = fmpy.simulate_fmu(str(loop_fmus[model]), stop_time=3.0, output_interval=0.1,
                               start_values=START[model], output=OUTPUTS[model])
    solver = _solver(model)
    order = START[model]["order"]
    controller = LinearSystem([START[model].get(f"b{i}", 0.0) for i in range(order + 1)],
                              [START[model].get(f"a{i}", 0.0) for i in range(1, order + 1)])
    y_name = {"FrictionMassLoop": "x", "TwoMassBacklashLoop": "x1", "StaticBacklashLoop": "y"}[model]
    for row in result[1:]:
        solver.advance(float(row["time"]))
        controller.x = solver.state()[len(solver.coordinates):]
        assert row["f"] == -controller.output(row[y_name])
    gain = {"order": 1, "b0": -30.0, "b1": -30.0 * 4.0, "a1": 4.0, Y0[model]: 1.0}  # G = -30 (s + 4) / (s + 4)
    result = fmpy.simulate_fmu(str(loop_fmus[model]), stop_time=3.0, output_interval=0.1, start_values=gain,
                               output=[y_name, "f"])
    assert all(row["f"] == 30.0 * row[y_name] for row in result)
    assert max(abs(row["f"]) for row in result) > 1.0


def test_a_high_order_controller_and_a_start_time(loop_fmus):
    """Order 8 (poles at -1..-8, z1_0 = 1) from t0 = 2: the FMU at t0 + T is the solver at T."""
    coefficients = [1.0]
    for pole in range(1, 9):  # (s + 1) ... (s + 8)
        coefficients = [c + pole * p for c, p in zip(coefficients + [0.0], [0.0] + coefficients)]
    start = dict({f"a{i}": coefficients[i] for i in range(1, 9)}, order=8, b8=coefficients[8] * 2.0, z1_0=1.0,
                 x0=0.05)
    fmu, description, messages = _instance(loop_fmus, "StaticBacklashLoop", start, start_time=2.0)
    t = run(fmu, 2.0, 4.0, 0.25)
    solver = _solver("StaticBacklashLoop", start)
    solver.advance(t - 2.0)
    assert _outputs(fmu, description, "StaticBacklashLoop") == _expected("StaticBacklashLoop", solver)
    assert solver.events > 0 and not [m for m in messages if m[0] >= 3]


# -- refusals ----------------------------------------------------------------------------------

def _simulate_logged(path, start, stop_time=1.0):
    messages = []

    def logger(_env, _instance, status, _category, text):
        messages.append((status, text.decode()))

    with tempfile.TemporaryDirectory() as folder, \
            pytest.raises(FMICallException, match="failed with status 3") as raised:  # (fmpy leaves its own
        fmpy.extract(str(path), unzipdir=folder)  # unpacked copy behind when the run raises)
        fmpy.simulate_fmu(folder, stop_time=stop_time, output_interval=0.1, start_values=start, logger=logger,
                          debug_logging=True)
    choice = [m for m in messages if m[0] == 0 and ": runs on the " in m[1]]  # which solver (status ok)
    assert len(choice) == 1, messages
    return str(raised.value), [m for m in messages if m not in choice]


@pytest.mark.parametrize("model, start, message", [
    ("FrictionMassLoop", {"order": 9}, "order = 9 is out of range: the order must be an integer in 1..8"),
    ("TwoMassBacklashLoop", {"eps": 2.0}, r"eps = 2.0 is out of range: eps must be in \[0, 1\]"),
    ("FrictionMassLoop", {"Dv": 1.0}, "Dv = 1.0 is out of range: Dv must be 0 in the exact closed loop"),
    ("StaticBacklashLoop", {"b1": math.nan}, "b1 = nan is out of range: b1 must be a finite number"),
    ("StaticBacklashLoop", {"b3": 1.0}, "b3 = 1.0 is out of range: b3 is above the order 1 and must be 0"),
    ("TwoMassBacklashLoop", {"order": 2, "z3_0": 1.0}, "z3_0 = 1.0 is out of range: z3_0 is above the order 2"),
    ("FrictionMassLoop", {"M": 0.0}, "M = 0.0 is out of range"),
])
def test_a_bad_parameter_is_an_error_naming_it(loop_fmus, model, start, message):
    error, messages = _simulate_logged(loop_fmus[model], start)
    assert "fmi2ExitInitializationMode" in error
    assert [status for status, _ in messages] == [3]
    assert messages[0][1].startswith(f"{model}: invalid parameter: ")
    assert re.search(message, messages[0][1]), messages


@pytest.mark.parametrize("model", MODELS)
def test_a_diverging_loop_is_an_error_and_the_outputs_stay_finite(loop_fmus, model):
    """Positive feedback f = +1e6 y: the motion overflows; doStep fails with a message, no NaN is served."""
    start = {"order": 1, "b0": -1e6, "b1": -1e6, "a1": 1.0, Y0[model]: 1.0}
    error, messages = _simulate_logged(loop_fmus[model], start, stop_time=2.0)
    assert "fmi2DoStep" in error and [status for status, _ in messages] == [3]
    assert "refused" in messages[0][1], messages
    fmu, description, messages = _instance(loop_fmus, model, start)
    with pytest.raises(Exception, match="failed with status 3"):
        run(fmu, 0.0, 2.0, 0.1)
    assert all(math.isfinite(value) for value in fmu.getReal([v.valueReference for v in description.modelVariables
                                                              if v.type == "Real"]))
    with pytest.raises(Exception, match="failed with status 3"):  # the Error state: no more steps
        fmu.doStep(0.0, 0.1)


def test_a_step_backwards_or_of_bad_length_is_refused(loop_fmus):
    fmu, _, messages = _instance(loop_fmus, "FrictionMassLoop", START["FrictionMassLoop"])
    fmu.doStep(0.0, 0.1)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.doStep(0.0, 0.1)
    assert (3, "FrictionMassLoop: doStep at t = 0.0, but the FMU is at t = 0.1") in messages
    fmu, _, messages = _instance(loop_fmus, "FrictionMassLoop", START["FrictionMassLoop"])
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.doStep(0.0, -0.1)
    assert (3, "FrictionMassLoop: communication step -0.1 at t = 0.0: it must be > 0 and finite") in messages


def test_no_exception_leaves_a_callback():
    fmu = loop_facade.FrictionMassLoop(instance_name="direct")
    vr = {row[0]: i for i, row in enumerate(fmu._layout)}
    assert fmu.get_real([10_000]) == [0.0]  # a bad value reference: logged, zeros of the right length
    assert fmu.do_step(0.0, 0.1) is False
    fmu = loop_facade.FrictionMassLoop(instance_name="direct")
    fmu.setup_experiment(0.0, None, None)
    fmu.enter_initialization_mode()
    fmu.set_real([vr["f"]], [1.0])  # an output
    assert "f is an output and cannot be set" in _errors(fmu)[-1]
    fmu = _direct("FrictionMassLoop")
    fmu.set_integer([vr["order"]], [2])  # a fixed parameter after initialisation
    assert "order is a fixed parameter" in _errors(fmu)[-1] and fmu.order == 2


# -- FMU state ---------------------------------------------------------------------------------

def _instance(fmus, model, start, start_time=0.0):
    """(raw FMU2Slave initialised with ``start``, its description, its log)."""
    return initialised(fmus[model], start, start_time, name=model)


def _outputs(fmu, description, model):
    by_name = {v.name: v for v in description.modelVariables}
    values = []
    for name in OUTPUTS[model]:
        var = by_name[name]
        get = fmu.getInteger if var.type == "Integer" else fmu.getReal
        values.append(get([var.valueReference])[0])
    return tuple(values)


@pytest.mark.parametrize("model", MODELS)
def test_state_save_continue_restore_continue_is_bit_identical(loop_fmus, model):
    fmu, description, messages = _instance(loop_fmus, model, START[model])
    t1 = run(fmu, 0.0, 1.5, 0.0137)
    saved = fmu.getFMUstate()
    data = fmu.serializeFMUstate(saved)
    t2 = run(fmu, t1, 3.0, 0.0137)
    first = read(fmu, description)
    fmu.setFMUstate(saved)
    assert run(fmu, t1, 3.0, 0.0137) == t2
    assert read(fmu, description) == first
    fresh, _, fresh_messages = _instance(loop_fmus, model, {})  # default parameters: the state brings its own
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    run(fresh, t1, 3.0, 0.0137)
    assert read(fresh, description) == first
    fmu.freeFMUstate(saved)
    assert not [m for m in messages + fresh_messages if m[0] >= 3]
    solver = _solver(model)
    solver.advance(t2)
    assert _outputs(fresh, description, model) == _expected(model, solver)


def _direct(model, **values):
    fmu = FACADES[model](instance_name="direct")
    fmu.setup_experiment(0.0, None, None)
    fmu.enter_initialization_mode()
    for name, value in dict(START[model], **values).items():
        setattr(fmu, name, value)
    fmu.exit_initialization_mode()
    return fmu


def _errors(fmu):
    return [message.msg for message in fmu.log_queue if message.status >= 3]


def _tamper(solver, how):
    if how == "chunk length":
        solver._mode.h *= 0.5
    elif how == "mode key":
        solver._modes[("slide", 7)] = solver._modes.pop(solver.key)
        solver.key = ("slide", 7)
    elif how == "state size":
        solver._X.append(0.0)
    elif how == "infinite state":
        solver._X[0] = math.inf
    elif how == "chunk":
        solver._a = -1.0
    elif how == "time":
        solver.t += 1.0
    elif how == "gain":
        solver.C[0] *= 2.0
    elif how == "event kind":
        solver._mode.events = tuple((str(kind), L, l0) for kind, L, l0 in solver._mode.events)
    elif how == "counter":
        solver.sticks = -1


TAMPERED = {  # what a crafted state changes: what the refusal says
    "chunk length": "mode ('slide', 1) does not match its parameters",
    "mode key": "modes are not modes of this loop",
    "state size": "loop state does not match the loop's size or is not finite",
    "infinite state": "loop state does not match the loop's size or is not finite",
    "chunk": "chunk does not match its time",
    "time": "solver time does not match the state's time",
    "gain": "solver does not match its parameters (C)",
    "event kind": "mode ('slide', 1) does not match its parameters",
    "counter": "sticks is not a count",
}


@pytest.mark.parametrize("how", list(TAMPERED))
@pytest.mark.parametrize("serialized", [False, True])
def test_a_crafted_state_is_refused_and_changes_nothing(how, serialized):
    fmu = _direct("FrictionMassLoop")
    assert fmu.do_step(0.0, 2.0)
    good = fmu._get_fmu_state()
    crafted = fmu._get_fmu_state()
    _tamper(crafted.solver, how)
    if serialized:  # written without the writer's own check (a crafted file, its checksum made to match),
        payload = pickle.dumps((crafted.values, crafted.solver), protocol=4)  # read through the checks
        crafted = type(fmu)._fmu_state_from_bytes(state.frame(good.model, good.package, payload))
    reals = [vr for vr, row in enumerate(fmu._layout) if row[1] == "Real"]
    before = fmu.get_real(reals)
    fmu._set_fmu_state(crafted)
    assert _errors(fmu) == [f"FrictionMassLoop: the state's {TAMPERED[how]}"]
    assert fmu.get_real(reals) == before and fmu._values["x"] != 1.0  # the outputs at t = 2 (x0 = 1)
    assert fmu.do_step(2.0, 0.5) is False  # the Error state
    fmu._set_fmu_state(good)  # a good state leaves it
    assert fmu.do_step(2.0, 0.5)


def test_the_unpickler_names_the_loop_classes_and_no_others():
    for model in loop_facade.LOOPS:
        table = model._state_table()
        allowed = set(table.values())
        assert {Mode, model.solver_class, EventKind} <= allowed
        assert Polynomial not in allowed and model not in allowed and LinearSystem not in allowed
        with pytest.raises(state.StateRefused, match="not a class of this FMU's state"):
            state._Unpickler(b"", table).find_class("dfwb.fmus.hybrid", "Polynomial")
    other = _direct("StaticBacklashLoop")._get_fmu_state()
    data = loop_facade.StaticBacklashLoop._fmu_state_to_bytes(other)
    refused = loop_facade.FrictionMassLoop._fmu_state_from_bytes(data)
    assert isinstance(refused, state.RefusedState) and "not 'FrictionMassLoop'" in refused.refused


def test_a_state_taken_in_initialisation_mode_restores_it():
    fmu = loop_facade.TwoMassBacklashLoop(instance_name="direct")
    fmu.setup_experiment(1.0, None, None)
    fmu.enter_initialization_mode()
    for name, value in START["TwoMassBacklashLoop"].items():
        setattr(fmu, name, value)
    saved = fmu._get_fmu_state()
    fmu.exit_initialization_mode()
    fmu.do_step(1.0, 0.5)
    outputs = dict(fmu._values)
    fmu._set_fmu_state(saved)
    assert fmu.solver is None and fmu._phase == facade.INITIALIZATION and fmu._values == {}
    fmu.exit_initialization_mode()
    assert fmu.do_step(1.0, 0.5) and not _errors(fmu) and fmu._values == outputs


def test_a_loop_starting_at_a_wall_with_no_force_yet_runs():
    """gap0 = 0, f(0) = 0 and f turning to press: contact, not an endless release/impact at t = 0."""
    fmu = _direct("TwoMassBacklashLoop", order=1, b0=0.0, b1=100.0, a1=10.0, x1_0=1.0, gap0=0.0, eps=0.5)
    assert fmu.do_step(0.0, 0.001), _errors(fmu)
