"""FMU state, start time and refused calls, through fmpy's raw FMI 2.0 API and on the facades directly.

Statuses: a refused call logs an error (status 3) and returns normally from
Python; the C shim of the FMU turns that into fmi2Error. The tests that
read statuses through fmpy (``_refused``) expect fmi2Error.
"""

import copy
import json
import math
import os
import pickle

import pytest
from conftest import new_instance
from native_fmu_helpers import initialised, read, run

from dfwb.fmus import facade, state
from dfwb.fmus.backlash import TwoMassBacklash
from dfwb.fmus.friction import FrictionMass
from dfwb.fmus.static_backlash import StaticBacklash

START = {  # model: start values (an excitation that makes events happen)
    "FrictionMass": {"F": 10.0, "omega": 1.0, "B": 0.5, "Dv": 0.01},
    "TwoMassBacklash": {"F": 50.0, "omega": 20.0, "eps": 0.5},
    "StaticBacklash": {"F": 50.0, "omega": 20.0},
    "LinearSystem": {"order": 2, "b2": 1.0, "b1": 0.5, "b0": 0.25, "a1": 0.4, "a2": 4.0},
    "NaiveTwoMassBacklash": {"F": 50.0, "omega": 20.0, "eps": 0.5, "dt": 1e-3},
}
MODELS = list(START)


def _instance(fmus, model, start_time=0.0, start=None, initialise=True):
    """(raw FMU2Slave, its description, its log) with the model's start values set."""
    if not initialise:
        return new_instance(fmus[model], model)
    return initialised(fmus[model], START[model] if start is None else start, start_time, name=model)


def _refused(call):
    """The call must fail with fmi2Error (status 3)."""
    with pytest.raises(Exception, match="failed with status 3"):
        call()


@pytest.mark.parametrize("model", MODELS)
def test_rollback_is_bit_identical(fmus, model):
    fmu, description, messages = _instance(fmus, model)
    t1 = run(fmu, 0.0, 0.5, 0.05)
    saved = fmu.getFMUstate()
    t2 = run(fmu, t1, 1.0, 0.05)
    first = read(fmu, description)
    fmu.setFMUstate(saved)
    again = run(fmu, t1, 1.0, 0.05)
    assert again == t2
    assert read(fmu, description) == first
    fmu.setFMUstate(saved)  # a state can be set again, and freed
    assert run(fmu, t1, 1.0, 0.05) == t2 and read(fmu, description) == first
    fmu.freeFMUstate(saved)
    assert not [m for m in messages if m[0] >= 3]


@pytest.mark.parametrize("model", MODELS)
def test_serialized_state_continues_bit_identically_in_a_fresh_instance(fmus, model):
    fmu, description, _ = _instance(fmus, model)
    t1 = run(fmu, 0.0, 0.4, 0.05)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    assert data.startswith(state.MAGIC)
    run(fmu, t1, 1.0, 0.05)
    original = read(fmu, description)
    # a fresh instance, initialised with the default parameters: the state brings its own
    fresh, _, messages = _instance(fmus, model, start={})
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    run(fresh, t1, 1.0, 0.05)
    assert read(fresh, description) == original
    assert not [m for m in messages if m[0] >= 3]


def test_serialized_state_restores_an_instance_that_was_never_initialised(fmus):
    fmu, description, _ = _instance(fmus, "TwoMassBacklash")
    t1 = run(fmu, 0.0, 0.4, 0.05)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    run(fmu, t1, 1.0, 0.05)
    fresh, _, messages = _instance(fmus, "TwoMassBacklash", initialise=False)
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    run(fresh, t1, 1.0, 0.05)
    assert read(fresh, description) == read(fmu, description)
    assert not [m for m in messages if m[0] >= 3]


def _evil_pickle():
    class Evil:
        def __reduce__(self):
            return os.system, ("touch /tmp/dfwb-state-pwned",)

    return pickle.dumps(((Evil(),), None), protocol=4)


@pytest.mark.parametrize("kind", ["garbage", "os.system", "truncated", "other model", "other build"])
def test_crafted_serialized_state_is_refused_with_an_error(fmus, kind):
    fmu, description, messages = _instance(fmus, "FrictionMass")
    run(fmu, 0.0, 0.3, 0.1)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    header = good[len(state.MAGIC):].split(b"\n", 1)[0]
    if kind == "garbage":
        data = b"\x80\x04garbage" * 10
    elif kind == "os.system":
        fields = json.loads(header)  # a crafted file whose checksum was made to match: the unpickler refuses
        data = state.frame(fields["model"], fields["package"], _evil_pickle())
    elif kind == "truncated":
        data = good[:-7]
    elif kind == "other model":
        other, _, _ = _instance(fmus, "TwoMassBacklash")
        data = other.serializeFMUstate(other.getFMUstate())
    else:
        fields = json.loads(header)
        fields["package"] = "dfwb_fmus_0000000000000000"
        data = state.MAGIC + json.dumps(fields).encode() + b"\n" + good.split(b"\n", 2)[2]
    before = read(fmu, description)

    def restore():
        fmu.setFMUstate(fmu.deSerializeFMUstate(data))

    _refused(restore)
    assert not os.path.exists("/tmp/dfwb-state-pwned")
    assert any(status == 3 and "refused" in text for status, text in messages), messages
    assert read(fmu, description) == before  # nothing was changed, the getters still work
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))  # a good state leaves the Error state
    fmu.doStep(0.3, 0.1)


@pytest.mark.parametrize("model", ["FrictionMass", "LinearSystem"])
def test_start_time_is_honoured(fmus, model):
    """Starting at t0: the plant starts there, the excitation is in absolute time."""
    fmu, description, messages = _instance(fmus, model, start_time=2.0)
    run(fmu, 2.0, 3.0, 0.1)
    assert not [m for m in messages if m[0] >= 3]
    _refused(lambda: fmu.doStep(0.0, 0.1))  # the FMU is at t = 3, not 0
    assert any("but the FMU is at t = 3.0" in text for _, text in messages)


def _plant(model=facade.FrictionMass, start_time=0.0, **values):
    fmu = model(instance_name="direct")
    fmu.setup_experiment(start_time, None, None)
    fmu.enter_initialization_mode()
    for name, value in values.items():
        setattr(fmu, name, value)
    fmu.exit_initialization_mode()
    return fmu


def _vr(model, name):
    return [row[0] for row in model._layout].index(name)


def test_start_time_shifts_the_plant_and_keeps_absolute_phase():
    """From t0 the FMU equals the solver started at 0 with phase phi + omega t0; I_k carries exp(-i k omega t0)."""
    t0, omega = 2.0, 1.0
    fmu = _plant(start_time=t0, F=10.0, omega=omega)
    t = t0
    for _ in range(10):
        assert fmu.do_step(t, 0.1)
        t += 0.1
    solver = FrictionMass(F=10.0, omega=omega, phi=omega * t0)
    solver.advance(t - t0)
    assert fmu.get_real([_vr(facade.FrictionMass, "x")]) == [solver.output().x]
    integral = solver.integrals()[1] * complex(math.cos(omega * t0), -math.sin(omega * t0))
    ic, is_ = fmu.get_real([_vr(facade.FrictionMass, "Ic1"), _vr(facade.FrictionMass, "Is1")])
    assert ic == pytest.approx(integral.real, rel=1e-14) and is_ == pytest.approx(-integral.imag, rel=1e-14)
    zero = _plant(F=10.0)  # start time 0: exactly the solver as before
    zero.do_step(0.0, 1.0)
    reference = FrictionMass(F=10.0)
    reference.advance(1.0)
    assert zero.get_real([_vr(facade.FrictionMass, "Ic1")]) == [reference.integrals()[1].real]


def _errors(fmu):
    return [msg.msg for msg in fmu.log_queue if msg.status >= 3]


def test_a_fixed_parameter_cannot_change_after_initialisation():
    fmu = _plant(F=10.0)
    fmu.set_real([_vr(facade.FrictionMass, "M")], [3.0])
    assert _errors(fmu) == ["FrictionMass: setReal of M = 3.0 refused: M is a fixed parameter and cannot be set "
                            "after initialisation (M stays 1.0)"]
    assert fmu.get_real([_vr(facade.FrictionMass, "M")]) == [1.0]
    assert fmu.do_step(0.0, 0.1) is False  # the Error state


def test_do_step_after_terminate_is_refused():
    fmu = _plant(F=10.0)
    assert fmu.do_step(0.0, 0.1)
    fmu.terminate()
    assert fmu.do_step(0.1, 0.1) is False
    assert "the FMU is terminated" in _errors(fmu)[-1]


@pytest.mark.parametrize("value", [math.nan, math.inf, 1e300])
def test_a_bad_input_is_refused_and_the_outputs_stay(value):
    fmu = _plant(F=10.0)
    fmu.do_step(0.0, 0.1)
    x = fmu.get_real([_vr(facade.FrictionMass, "x")])
    fmu.set_real([_vr(facade.FrictionMass, "f")], [value])
    assert f"f = {value!r} is out of range" in _errors(fmu)[-1]
    assert fmu.get_real([_vr(facade.FrictionMass, "f")]) == [0.0]
    assert fmu.do_step(0.1, 0.1) is False
    assert fmu.get_real([_vr(facade.FrictionMass, "x")]) == x


def test_no_exception_leaves_a_callback():
    fmu = facade.FrictionMass(instance_name="direct")
    assert fmu.get_real([10_000]) == [0.0]  # a bad value reference: logged, zeros of the right length
    assert fmu.get_integer([0, 1]) == [0, 0]
    assert fmu.get_boolean([0]) == [False] and fmu.get_string([0]) == [""]
    fmu.set_boolean([0], [True])
    assert fmu.do_step(0.0, 0.1) is False
    fmu.terminate()
    fmu._set_fmu_state("not a state")
    assert isinstance(facade.FrictionMass._fmu_state_from_bytes(b"x" * 10), state.RefusedState)
    assert facade.FrictionMass._fmu_state_to_bytes(object()).startswith(state.MAGIC)
    assert len(_errors(fmu)) == 8  # one per refused call
    assert fmu.get_integer([facade.PHASE_VR]) == [facade.PHASES.index(facade.ERROR)]


def test_a_state_taken_in_initialisation_mode_restores_it():
    fmu = facade.FrictionMass(instance_name="direct")
    fmu.setup_experiment(1.0, None, None)
    fmu.enter_initialization_mode()
    fmu.F = 10.0
    saved = fmu._get_fmu_state()
    fmu.exit_initialization_mode()
    fmu.do_step(1.0, 0.5)
    fmu._set_fmu_state(saved)
    assert fmu.solver is None and fmu._phase == facade.INITIALIZATION
    fmu.exit_initialization_mode()
    assert fmu.do_step(1.0, 0.5) and not _errors(fmu)


# -- the solver snapshot ---------------------------------------------------------

def _mutable_ids(obj, seen=None):
    """ids of the mutable containers and objects reachable from obj."""
    seen = set() if seen is None else seen
    todo, found = [obj], set()
    while todo:
        item = todo.pop()
        if id(item) in seen or isinstance(item, (int, float, complex, str, type(None))):
            continue
        seen.add(id(item))
        if isinstance(item, (list, dict)) or hasattr(item, "__dict__") or hasattr(type(item), "__slots__"):
            found.add(id(item))
        if isinstance(item, dict):
            todo.extend(item.values())
        elif isinstance(item, (list, tuple)):
            todo.extend(item)
        else:
            todo.extend(getattr(item, "__dict__", {}).values())
            for klass in type(item).__mro__:
                todo.extend(getattr(item, slot) for slot in getattr(klass, "__slots__", ()) if hasattr(item, slot))
    return found


CASES = [  # (solver, time of the snapshot: mid-piece, with a pending search)
    (lambda: FrictionMass(F=10.0, omega=1.0, B=0.5, Dv=0.01), 2.3),
    (lambda: FrictionMass(F=10.0, omega=1.0, B=0.0), 1.7),
    (lambda: TwoMassBacklash(F=50.0, omega=20.0, eps=0.5), 0.33),
    (lambda: TwoMassBacklash(F=5.0, omega=2.0, eps=0.0, M1=1e-3), 1.1),
    (lambda: StaticBacklash(F=50.0, omega=20.0), 0.41),
]


@pytest.mark.parametrize("case", range(len(CASES)))
@pytest.mark.parametrize("how", ["deepcopy", "bytes"])
def test_solver_snapshot_mid_piece_continues_exactly(case, how):
    make, t_snap = CASES[case]
    solver = make()
    solver.advance(t_snap)
    solver.integrals()  # a search may be pending past t_snap: it must be copied too
    assert solver._searches or solver._analytic < math.inf
    table = facade.PlantFMU._state_table.__func__(type("F", (facade.PlantFMU,), {"solver_class": type(solver)}))
    if how == "deepcopy":
        twin = state.copy_solver(solver)
        assert not _mutable_ids(twin) & _mutable_ids(solver)  # shares nothing mutable
    else:
        snap = state.FMUState("m", "p", {}, solver)
        twin = state.decode(state.encode(snap, table), "m", "p", table).solver
    for t in (t_snap + 0.01, t_snap + 0.5, t_snap + 3.0):
        solver.set_input(0.5)
        twin.set_input(0.5)
        solver.advance(t)
        twin.advance(t)
        assert twin.output() == solver.output()
        assert twin.integrals() == solver.integrals()
        assert twin.events == solver.events


def test_the_unpickler_names_only_the_state_classes():
    table = facade.FrictionMass._state_table()
    for module, name in [("os", "system"), ("builtins", "eval"), ("builtins", "getattr"),
                         ("dfwb.fmus.facade", "FrictionMass"), ("dfwb.fmus.exact", "math")]:
        with pytest.raises(state.StateRefused, match="not a class of this FMU's state"):
            state._Unpickler(b"", table).find_class(module, name)
    assert state._Unpickler(b"", table).find_class("builtins", "complex") is complex
    bad = copy.deepcopy(FrictionMass())
    bad.t = math.nan
    with pytest.raises(state.StateRefused, match="NaN"):
        state.check_graph(bad, table)
