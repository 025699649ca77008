"""The pythonfmu plant FMUs on the compiled core (resources/libdfwb_core.so), against the pure-Python oracle.

The same FMU runs either way: with the core (the default when it loads) or with
``DFWB_FMU_SOLVER=python``. fmpy runs the FMU in this process, so the variable
set here is what the instance reads at exitInitializationMode. Every output
(events and the Fourier integrals included) must agree bit for bit, refusals
must say the same, FMU states must continue bit for bit, and a crafted state
must be refused cleanly. ``pytest -s`` prints a DF point's time both ways.
"""

import time

import native_fmu_helpers as helpers
import pytest

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


@pytest.fixture(scope="module")
def plant_fmus(tmp_path_factory):
    """{model: path} of the three plant FMUs, built with the compiled core into a private folder."""
    return helpers.build_with_core(tmp_path_factory.mktemp("plant_fmus"), [getattr(facade, model) for model in PLANTS])


@pytest.mark.parametrize("model", PLANTS)
@pytest.mark.parametrize("case", range(3))
def test_outputs_are_bit_identical_to_the_python_solver(plant_fmus, solver, model, case):
    start, t0, stop, dt = CASES[model][case]
    native, native_log, python_log = helpers.identical_on_both(plant_fmus[model], solver, start, t0, stop, dt)
    assert abs(native["time"][0] - t0) < 1e-12  # every output, Ic0..Is10 included, bit for bit
    assert any(status == 0 and "runs on the compiled core" in text for status, text in native_log), native_log
    assert any(status == 0 and "runs on the pure-Python solver (DFWB_FMU_SOLVER=python)" in text
               for status, text in python_log), python_log
    assert not [m for m in native_log + python_log if m[0] >= 1]


@pytest.mark.parametrize("model, bad, text", REFUSED)
def test_a_refused_parameter_says_the_same_on_both_solvers(plant_fmus, solver, model, bad, text):
    start = dict(CASES[model][0][0], **bad)
    native_log, _, _, _ = helpers.refused_on_both(plant_fmus[model], solver, start, 1.0)
    native_errors = [m for m in native_log if m[0] >= 3]
    assert native_errors[0][1].startswith(f"{model}: {text}"), native_errors


@pytest.mark.parametrize("damage, reason", [(None, "the FMU has no compiled core (no resources/libdfwb_core.so)"),
                                            (b"not a library\n", "cannot load the C core")])
def test_the_fmu_falls_back_to_python_with_one_warning(plant_fmus, solver, tmp_path, damage, reason):
    log, errors = helpers.falls_back(plant_fmus["FrictionMass"], tmp_path, solver, damage, CASES["FrictionMass"][0])
    warnings = [text for status, text in log if status >= 1]
    assert len(warnings) == 1 and reason in warnings[0], log
    assert warnings[0].endswith("it runs on the pure-Python solver")
    assert [status for status, text in log if text == warnings[0]] == [1]  # status warning
    assert errors and errors[0].startswith("FrictionMass: DFWB_FMU_SOLVER=native, but the compiled core cannot be "
                                           "used: ") and reason in errors[0]


def test_a_bad_solver_choice_is_refused(plant_fmus, solver):
    assert helpers.refuses_a_bad_choice(plant_fmus["StaticBacklash"], solver)[0] == (
        "StaticBacklash: DFWB_FMU_SOLVER = 'fortran' is refused: it must be 'native' (the compiled core; an error "
        "if it cannot be used) or 'python' (the pure-Python solver), or unset")


# -- FMU state -------------------------------------------------------------------------------------

@pytest.mark.parametrize("model", PLANTS)
def test_states_continue_bit_identically_on_the_core(plant_fmus, solver, model):
    helpers.states_continue(plant_fmus[model], STATE_START[model], solver, 0.9, 1.5, 0.05)


@pytest.mark.parametrize("source, target", [("python", None), (None, "python")])
def test_a_state_of_either_solver_is_accepted_by_either_instance(plant_fmus, solver, source, target):
    helpers.state_crosses_solvers(plant_fmus["TwoMassBacklash"], STATE_START["TwoMassBacklash"], solver, source, target,
                          0.3, 0.8, 0.02)


def _other_plant(decoded, native_state):
    decoded.solver = native_state("StaticBacklash", decoded.solver.data)


def _not_bytes(decoded, native_state):
    decoded.solver = native_state("FrictionMass", list(decoded.solver.data[:8]))


@pytest.mark.parametrize("label, change, message", [
    ("magic", helpers.flip(0), "serialized state refused"),
    ("header", helpers.flip(9), "serialized state refused"),
    ("payload", helpers.flip(60), "serialized state refused"),
    ("last byte", helpers.flip(-1), "serialized state refused"),
    ("other plant", _other_plant, "the state's solver is a compiled 'StaticBacklash', not a FrictionMass"),
    ("data not bytes", _not_bytes, "the state's native solver is damaged"),
])
def test_a_crafted_native_state_is_refused(plant_fmus, solver, label, change, message):
    fmu, good, t1, errors = helpers.crafted_is_refused(plant_fmus["FrictionMass"], "facade", STATE_START["FrictionMass"],
                                               solver, change, 0.5, 0.1)
    assert len(errors) == 1 and message in errors[0], (label, errors)
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))  # a good state leaves the Error state
    helpers.run(fmu, t1, 0.8, 0.1)


def test_a_native_state_of_other_parameters_is_refused(plant_fmus, solver):
    """The facade values say M = 1; the (genuine, checksummed) C solver state is one of M = 2."""
    path = plant_fmus["FrictionMass"]
    fmu, description, messages = helpers.instance(path, STATE_START["FrictionMass"], None, solver)
    other, _, _ = helpers.instance(path, dict(STATE_START["FrictionMass"], M=2.0), None, solver)
    for each in (fmu, other):
        helpers.run(each, 0.0, 0.5, 0.1)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    cls = helpers.fmu_classes(path, "facade")[0]
    foreign = cls._fmu_state_from_bytes(other.serializeFMUstate(other.getFMUstate())).solver.data

    def change(decoded, _native_state):
        decoded.solver.data = foreign

    bad = helpers.crafted(path, "facade", good, change)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(bad))
    assert [text for status, text in messages if status >= 3] == [
        "FrictionMass: the state's solver does not match its parameters"]
    fmu.setFMUstate(fmu.deSerializeFMUstate(good))
    helpers.run(fmu, 0.5, 0.8, 0.1)


def test_a_native_state_into_an_fmu_without_core_is_refused(plant_fmus, solver, tmp_path):
    assert helpers.refused_without_core(plant_fmus["FrictionMass"], STATE_START["FrictionMass"], solver, tmp_path) == [
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
        helpers.simulate(*unpacked(plant_fmus["FrictionMass"]), dict(start, F=50.0), t0, 200.0, 0.5)
        runs[kind] = time.perf_counter() - started
        results[kind].pop("seconds")
    assert results[None] == results["python"]
    print(f"\nDF point friction F=10 omega=1 (mean of {repeats}): compiled core {seconds[None] * 1e3:.2f} ms, "
          f"DFWB_FMU_SOLVER=python {seconds['python'] * 1e3:.2f} ms ({seconds['python'] / seconds[None]:.1f}x); "
          f"fmpy run of 200 s, F=50: {runs[None] * 1e3:.1f} ms vs {runs['python'] * 1e3:.1f} ms "
          f"({runs['python'] / runs[None]:.1f}x)")
