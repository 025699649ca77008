"""The naive fixed-step FMUs (the benchmark's fmu-fixedstep baseline): drop-in variables, convergence in dt, errors."""

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from dfwb.fmi.simulation import FMUError, simulate
from dfwb.fmus import naive

EXACT = {"NaiveFrictionMass": "FrictionMass", "NaiveTwoMassBacklash": "TwoMassBacklash",
         "NaiveStaticBacklash": "StaticBacklash"}
MODELS = list(EXACT)
SOLVERS = {"NaiveFrictionMass": naive.NaiveFrictionMass, "NaiveTwoMassBacklash": naive.NaiveTwoMassBacklash,
           "NaiveStaticBacklash": naive.NaiveStaticBacklash}
CASES = {  # model: (start values, stop time: a few forcing periods, outputs compared)
    "NaiveFrictionMass": ({"F": 10.0, "omega": 1.0}, 4 * math.pi, ["x", "v", "mode", "Ic1", "Is1"]),
    "NaiveTwoMassBacklash": ({"F": 50.0, "omega": 20.0, "eps": 0.2}, 4 * math.pi / 20,
                             ["x1", "v1", "gap", "v2", "contact", "impacts", "Ic1"]),
    "NaiveStaticBacklash": ({"F": 50.0, "omega": 20.0}, 4 * math.pi / 20, ["x", "v", "y", "engaged", "Ic1"]),
}


def position(model):
    return "x1" if model == "NaiveTwoMassBacklash" else "x"


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate_finds_no_problem(fmus, model):
    assert validate_fmu(str(fmus[model])) == []


@pytest.mark.parametrize("model", MODELS)
def test_same_variables_as_the_exact_fmu_plus_dt(fmus, model):
    """A drop-in replacement: every variable of the exact FMU, same type, causality and unit; dt in seconds."""
    naive_vars = {v.name: v for v in fmpy.read_model_description(str(fmus[model])).modelVariables}
    exact_vars = {v.name: v for v in fmpy.read_model_description(str(fmus[EXACT[model]])).modelVariables}
    assert set(naive_vars) == set(exact_vars) | {"dt"}
    for name, variable in exact_vars.items():
        twin = naive_vars[name]
        assert (twin.type, twin.causality, twin.variability, twin.unit) == \
               (variable.type, variable.causality, variable.variability, variable.unit), name
    dt = naive_vars["dt"]
    assert (dt.type, dt.causality, dt.unit, float(dt.start)) == ("Real", "parameter", "s", 1e-3)
    assert dt.description
    assert "baseline" in fmpy.read_model_description(str(fmus[model])).description


@pytest.mark.parametrize("model", MODELS)
def test_fmu_runs_the_naive_solver(fmus, model):
    """What fmpy reads is, bit for bit, the in-process naive solver advanced to the same points."""
    start, stop, outputs = CASES[model]
    result = simulate(fmus[model], stop, stop / 40, dict(start, dt=2e-3), outputs)
    solver = SOLVERS[model](dt=2e-3, **start)
    for row in result[1:]:
        solver.advance(row["time"])
        assert row[outputs[0]] == solver.output()[0]
        assert solver.t == row["time"]


@pytest.mark.parametrize("model", MODELS)
def test_naive_result_approaches_the_exact_one_as_dt_shrinks(fmus, model):
    start, stop, outputs = CASES[model]
    name = position(model)
    interval = stop / 40  # > dt: the internal step is not cut short by the communication step
    exact = simulate(fmus[EXACT[model]], stop, interval, start, [name])
    scale = np.max(np.abs(exact[name]))
    errors = {}
    for dt in (1e-2, 1e-3):
        result = simulate(fmus[model], stop, interval, dict(start, dt=dt), outputs)
        assert np.array_equal(result["time"], exact["time"])
        errors[dt] = np.max(np.abs(result[name] - exact[name])) / scale
    # first order: seen 0.12 (backlash), 0.12 (static); friction 0.26: its stick band is dt-sized
    assert errors[1e-3] < 0.5 * errors[1e-2], errors
    assert errors[1e-3] < 0.1, errors


def test_communication_points_are_honoured(fmus):
    """Steps that are not multiples of dt end exactly on the communication points."""
    start, stop, outputs = CASES["NaiveStaticBacklash"]
    result = simulate(fmus["NaiveStaticBacklash"], 0.1, 0.0037, dict(start, dt=1e-3), ["x"])
    assert np.allclose(np.diff(result["time"])[:-1], 0.0037, rtol=0, atol=1e-15)
    solver = naive.NaiveStaticBacklash(dt=1e-3, **start)
    solver.advance(0.0037)
    assert solver.t == 0.0037
    assert solver.output()[0] == result["x"][1]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("dt", [0.0, -1.0, math.nan])
def test_bad_dt_is_an_error_naming_it(fmus, model, dt):
    with pytest.raises(FMUError, match=f"{model}: .*dt = {dt!r} is out of range: dt must be > 0"):
        simulate(fmus[model], 1.0, 0.1, {"dt": dt})


@pytest.mark.parametrize("model, values, message", [
    ("NaiveFrictionMass", {"Fs": 1.0}, "Fs = 1.0 is out of range: Fs must be >= Fc"),
    ("NaiveTwoMassBacklash", {"eps": 1.5}, "eps = 1.5 is out of range: eps must be in \\[0, 1\\]"),
    ("NaiveStaticBacklash", {"h": -0.1}, "h = -0.1 is out of range"),
])
def test_bad_parameter_gives_the_exact_fmus_message(fmus, model, values, message):
    with pytest.raises(FMUError, match=f"{model}: .*{message}"):
        simulate(fmus[model], 1.0, 0.1, values)


def test_friction_sticks_with_a_fixed_step():
    """The band max(Dv, Fs dt / M) lets the fixed step stick: the mass stops and stays (mode 0) under |f| <= Fs."""
    solver = naive.NaiveFrictionMass(v0=1.0, dt=1e-2)
    solver.advance(5.0)
    x, v, ff, mode = solver.output()
    assert mode == 0 and abs(v) <= solver.band and ff == 0.0
    solver.set_input(6.0)  # below Fs = 7: still stuck, friction balances the force
    solver.advance(6.0)
    assert solver.output()[2:] == (6.0, 0)
    solver.set_input(8.0)  # above Fs: breaks away forwards
    solver.advance(7.0)
    assert solver.output()[3] == 1 and solver.output()[1] > 0.0


def test_backlash_keeps_momentum_and_the_gap():
    """Clamping and restitution keep M1 v1 + M2 v2 = int u dt (the naive sum) and 0 <= gap <= h."""
    solver = naive.NaiveTwoMassBacklash(F=50.0, omega=20.0, eps=0.3, dt=1e-3)
    momentum = 0.0
    for i in range(1, 1001):
        t = i * 1e-3
        momentum += 1e-3 * 50.0 * math.cos(20.0 * (t - 1e-3))
        solver.advance(t)
        x1, v1, x2, v2, gap = solver.output()
        assert 0.0 <= gap <= 0.1
        assert abs(v1 + v2 - momentum) <= 1e-12 * max(1.0, abs(momentum))
    assert solver.impacts > 0 and solver.events >= solver.impacts


def test_integrals_are_left_rectangles():
    solver = naive.NaiveStaticBacklash(F=50.0, omega=20.0, dt=1e-3, harmonics=3)
    expected = [0j] * 4
    for i in range(500):
        y = solver.output()[2]
        for k in range(4):
            expected[k] += 1e-3 * y * complex(math.cos(20.0 * k * i * 1e-3), -math.sin(20.0 * k * i * 1e-3))
        solver.advance((i + 1) * 1e-3)
    assert np.allclose(solver.integrals(), expected, rtol=1e-12, atol=1e-15)
