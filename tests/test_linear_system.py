"""LinearSystem: the transfer-function controller, its solver and its FMU."""

import math
from decimal import Decimal, localcontext

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu
from scipy import signal

from dfwb.fmi.simulation import FMUError, simulate, sine_input
from dfwb.fmus import LinearSystem, PlantError
from dfwb.fmus.linear_system import expm

EPS = 2.0 ** -52


def normalized(num, den):
    """(b, a) of LinearSystem from polynomial coefficients, highest power first."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    return list(num / den[0]), list(den[1:] / den[0])


# A PID with a derivative filter: (8 s^2 + 40 s + 60) / (s (0.01 s + 1)), order 2 and proper
# (b0 = 800: a direct feedthrough), and the same PID with one more lag, order 3, strictly proper.
PID = normalized([8.0, 40.0, 60.0], np.polymul([1.0, 0.0], [0.01, 1.0]))
PID_LAG = normalized([8.0, 40.0, 60.0], np.polymul(np.polymul([1.0, 0.0], [0.01, 1.0]), [0.1, 1.0]))


def start_values(b, a):
    values = {"order": len(a)}
    values.update({f"b{i}": value for i, value in enumerate(b)})
    values.update({f"a{i}": value for i, value in enumerate(a, start=1)})
    return values


# -- the matrix exponential ----------------------------------------------------

def expm_decimal(M, digits=60):
    """exp(M) at 60 significant digits (decimal scaling and squaring, Taylor to 1e-65)."""
    n = len(M)
    with localcontext() as context:
        context.prec = digits
        X = [[Decimal(value) for value in row] for row in M]  # the binary entries, exactly
        norm = max(sum(abs(X[i][j]) for i in range(n)) for j in range(n))
        squarings = 0
        while norm > Decimal("0.001"):
            norm /= 2
            squarings += 1
        X = [[value / 2 ** squarings for value in row] for row in X]
        E = [[Decimal(int(i == j)) for j in range(n)] for i in range(n)]
        term = [row[:] for row in E]
        for k in range(1, 200):
            term = [[sum(term[i][m] * X[m][j] for m in range(n)) / k for j in range(n)] for i in range(n)]
            E = [[E[i][j] + term[i][j] for j in range(n)] for i in range(n)]
            if max(abs(value) for row in term for value in row) < Decimal(10) ** -(digits + 5):
                break
        for _ in range(squarings):
            E = [[sum(E[i][m] * E[m][j] for m in range(n)) for j in range(n)] for i in range(n)]
        return np.array([[float(value) for value in row] for row in E])


@pytest.mark.parametrize("scale", [1e-3, 0.1, 1.0, 10.0, 100.0])
def test_expm_matches_a_60_digit_reference(scale):
    """Random matrices of size 1..10 (the augmented matrix of order 9 is 10 x 10)."""
    rng = np.random.default_rng(7)
    for n in range(1, 11):
        M = rng.standard_normal((n, n)) * scale
        reference = expm_decimal(M.tolist())
        error = np.linalg.norm(np.array(expm(M.tolist())) - reference, 1) / np.linalg.norm(reference, 1)
        # exp is conditioned like the norm of M; seen: at most 11 roundings per unit of norm
        assert error <= 32 * EPS * max(1.0, np.linalg.norm(M, 1)), (n, error)


def test_expm_exact_cases():
    assert expm([[0.0, 0.0], [0.0, 0.0]]) == [[1.0, 0.0], [0.0, 1.0]]
    for w in (1e-3, 0.5, 3.0, 40.0):  # a rotation
        E = expm([[0.0, w], [-w, 0.0]])
        assert np.allclose(E, [[math.cos(w), math.sin(w)], [-math.sin(w), math.cos(w)]], rtol=0, atol=4 * EPS * max(1, w))
    h = 0.3  # a nilpotent chain: exp is the finite series
    E = expm([[0.0, h, 0.0], [0.0, 0.0, h], [0.0, 0.0, 0.0]])
    assert np.allclose(E, [[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]], rtol=2 * EPS, atol=0)
    for x in (-30.0, -1.0, 1e-8, 2.0, 20.0):
        assert abs(expm([[x]])[0][0] / math.exp(x) - 1.0) <= 4 * EPS * max(1.0, abs(x))


# -- the solver ------------------------------------------------------------------

def test_step_response_of_a_first_order_lag_is_exact():
    system = LinearSystem([0.0, 1.0], [1.0])  # 1 / (s + 1)
    system.set_input(1.0)
    assert system.output() == 0.0
    worst = 0.0
    for k in range(1, 301):
        system.advance(k * 0.1)
        worst = max(worst, abs(system.output() - (1.0 - math.exp(-system.t))))
    assert worst <= 1e-13


def test_integrators_are_exact():
    """A pole at 0 (no inverse of A): 1/s and 1/s^2 under a held unit input."""
    single = LinearSystem([0.0, 1.0], [0.0])
    double = LinearSystem([0.0, 0.0, 1.0], [0.0, 0.0])
    for system in (single, double):
        system.set_input(1.0)
    for k in range(1, 101):
        t = k * 0.37
        single.advance(t)
        double.advance(t)
        assert single.output() == pytest.approx(t, rel=1e-14)
        assert double.output() == pytest.approx(t * t / 2, rel=1e-14)


@pytest.mark.parametrize("b, a", [PID, PID_LAG], ids=["pid-order2-proper", "pid-lag-order3"])
def test_held_sine_matches_scipy_zoh(b, a):
    dt, omega = 0.01, 2.0
    times = np.arange(0, 1001) * dt
    u = 1.5 * np.sin(omega * times)
    A, B, C, D = signal.tf2ss(np.trim_zeros(b, "f"), [1.0] + a)
    discrete = signal.cont2discrete((A, B, C, D), dt, method="zoh")
    _t, expected, _x = signal.dlsim(discrete, u, t=times)
    expected = expected[:, 0]

    system = LinearSystem(b, a)
    assert system.order == len(a)
    actual = []
    for t, value in zip(times, u):
        system.advance(t)
        system.set_input(value)
        actual.append(system.output())
    scale = np.max(np.abs(expected))
    assert np.max(np.abs(np.array(actual) - expected)) <= 1e-10 * scale


def test_step_lengths_share_one_transition():
    system = LinearSystem(*PID_LAG)
    system.set_input(1.0)
    for k in range(1, 11):
        system.advance(k * 0.25)  # 0.25 is a power of two: every step is exactly 0.25
    assert list(system._transitions) == [0.25]
    system.advance(system.t)  # an empty step changes nothing
    assert system.t == 2.5


@pytest.mark.parametrize("b, a, message", [
    ([1.0], [], r"order = 0 is out of range: .*1\.\.8"),
    ([0.0] * 10, [1.0] * 9, r"order = 9 is out of range: .*1\.\.8"),
    ([0.0, 1.0], [math.nan], r"a1 = nan is out of range: a1 must be a finite number"),
    ([0.0, 1.0, math.inf], [1.0, 2.0], r"b2 = inf is out of range: b2 must be a finite number"),
    ([1.0], [1.0], r"number of numerator coefficients = 1 is out of range: an order-1 G\(s\) needs 2"),
])
def test_bad_coefficients_are_refused_naming_them(b, a, message):
    with pytest.raises(PlantError, match=message):
        LinearSystem(b, a)


def test_bad_input_or_step_is_refused():
    system = LinearSystem([0.0, 1.0], [1.0])
    with pytest.raises(PlantError, match="u = nan is out of range"):
        system.set_input(math.nan)
    with pytest.raises(PlantError, match="u = inf is out of range"):
        system.set_input(math.inf)
    with pytest.raises(PlantError, match="t_end = nan is out of range"):
        system.advance(math.nan)
    system.advance(1.0)
    with pytest.raises(PlantError, match=r"t_end = 0\.5 is out of range: the end of a step must be >= the current time 1\.0"):
        system.advance(0.5)


# -- the FMU -----------------------------------------------------------------------

def test_fmpy_validate_finds_no_problem(fmus):
    assert validate_fmu(str(fmus["LinearSystem"])) == []


def test_variables_defaults_and_descriptions(fmus):
    description = fmpy.read_model_description(str(fmus["LinearSystem"]))
    assert description.defaultExperiment is not None
    assert description.coSimulation.modelIdentifier == "LinearSystem"
    variables = {variable.name: variable for variable in description.modelVariables}
    assert list(variables) == ["order"] + [f"b{i}" for i in range(9)] + [f"a{i}" for i in range(1, 9)] + ["u", "y"]
    assert all(variable.description for variable in variables.values())
    assert variables["order"].type == "Integer" and variables["order"].start == "1"
    starts = {name: float(variables[name].start) for name in variables if name not in ("order", "y")}
    assert starts == {name: 1.0 if name in ("b1", "a1") else 0.0 for name in starts}
    assert (variables["u"].causality, variables["y"].causality) == ("input", "output")


def test_default_is_a_first_order_lag(fmus):
    table = np.array([(0.0, 1.0), (10.0, 1.0)], dtype=[("time", np.float64), ("u", np.float64)])
    result = simulate(fmus["LinearSystem"], 5.0, 0.1, None, ["y"], input=table)
    assert np.max(np.abs(result["y"] - (1.0 - np.exp(-result["time"])))) <= 1e-13


@pytest.mark.parametrize("b, a", [PID, PID_LAG], ids=["pid-order2-proper", "pid-lag-order3"])
def test_fmu_runs_the_solver_bit_for_bit(fmus, b, a):
    """What fmpy reads is what the solver computes in-process, with the input fmpy held.

    fmpy records after each doStep and before it sets the next input, so the
    recorded u of a row is the input held over the step that ended there.
    """
    omega, samples, stop = 2.0, 64, 10.0
    table = sine_input(1.5, omega, stop, samples, name="u")
    result = simulate(fmus["LinearSystem"], stop, 2 * math.pi / omega / samples, start_values(b, a), ["y", "u"],
                      input=table)
    assert len(result) > 100
    system = LinearSystem(b, a)
    system.set_input(result[0]["u"])
    assert result[0]["y"] == system.output()
    for row in result[1:]:
        system.set_input(row["u"])
        system.advance(row["time"])
        assert row["y"] == system.output()


@pytest.mark.parametrize("values, message", [
    ({"order": 0}, r"order = 0 is out of range: the order must be an integer in 1\.\.8"),
    ({"order": 9}, r"order = 9 is out of range: the order must be an integer in 1\.\.8"),
    ({"a1": math.nan}, r"a1 = nan is out of range: a1 must be a finite number"),
    ({"b0": math.inf}, r"b0 = inf is out of range"),
    ({"a3": 2.0}, r"a3 = 2\.0 is out of range: a3 is above the order 1 and must be 0"),
])
def test_bad_parameter_is_an_error_naming_it(fmus, values, message):
    with pytest.raises(FMUError, match=f"LinearSystem: .*invalid parameter: {message}"):
        simulate(fmus["LinearSystem"], 1.0, 0.1, values)


def test_nan_input_is_an_error_with_its_time(fmus):
    table = sine_input(1.0, 1.0, 2.0, 16, name="u")
    table["u"][5] = np.nan
    with pytest.raises(FMUError, match=r"LinearSystem: .*t = 1\.96.*u = nan is out of range"):
        simulate(fmus["LinearSystem"], 2.0, 2 * math.pi / 16, None, ["y"], input=table)


@pytest.mark.parametrize("time, step, message", [
    (0.1, 0.0, "communication step 0.0 at t = 0.1: it must be > 0 and finite"),
    (0.1, -0.1, "communication step -0.1 at t = 0.1: it must be > 0 and finite"),
    (0.1, math.nan, "communication step nan at t = 0.1: it must be > 0 and finite"),
    (0.5, 0.1, "doStep at t = 0.5, but the FMU is at t = 0.1"),
])
def test_bad_step_is_refused_by_the_fmu(raw_fmu, time, step, message):
    fmu, messages = raw_fmu("LinearSystem")
    fmu.doStep(0.0, 0.1)
    with pytest.raises(Exception, match="fmi2DoStep failed"):
        fmu.doStep(time, step)
    assert (3, f"LinearSystem: {message}") in messages
