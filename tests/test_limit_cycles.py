"""Limit cycles: the G(s) parser, the prediction against python-control, Loeb's criterion, the judge."""

import json
import math

import control as ct
import numpy as np
import pytest

from dfwb.cli import main
from dfwb.engine.closed_loop import controller_values, measure, run_loop
from dfwb.engine.describing import DFEngine
from dfwb.engine.limit_cycles import predict
from dfwb.engine.transfer import from_coefficients, parse_transfer_function

LEAD = ct.tf([20.0, 40.0], [1.0, 20.0])  # 20 (s + 2) / (s + 20)
PID = "20 + 100/s + 2*s/(0.1*s+1)"


@pytest.mark.parametrize("text, num, den", [
    ("100*(s+1)/(s+10)", [100, 100], [1, 10]),
    ("40 + 60/s + 8*s/(0.01*s+1)", [8.4, 40.6, 60], [0.01, 1, 0]),
    ("1/(s**2 + 2*s + 1)", [1], [1, 2, 1]),
    ("-(s+1)/(s*(s+3))", [-1, -1], [1, 3, 0]),
])
def test_expressions_become_transfer_functions(text, num, den):
    G = parse_transfer_function(text)
    assert np.allclose(G.num[0][0], num) and np.allclose(G.den[0][0], den)


@pytest.mark.parametrize("text, message", [
    ("2s", "does not parse"),
    ("__import__('os').system('true')", "not allowed"),
    ("s.real", "not allowed"),
    ("x + 1", "the parameter x is given no value"),
    ("5", "has no s"),
    ("s**2/(s+1)", "improper"),
    ("s**0.5", "integer powers"),
    ("", "empty"),
    ("(s+1)/(s-s)", "zero denominator"),
])
def test_bad_expressions_are_refused_with_a_reason(text, message):
    with pytest.raises(ValueError, match=message):
        parse_transfer_function(text)


def test_coefficients_and_improper_coefficients():
    assert np.allclose(from_coefficients([1, 2], [1, 3, 2]).den[0][0], [1, 3, 2])
    with pytest.raises(ValueError, match="improper"):
        from_coefficients([1, 0, 0], [1, 1])


def test_static_backlash_cycle_equals_python_control(fmus):
    """Amplitude-only case: our (F, w) search equals describing_function_response on
    G(s) / ((M1 + M2) s^2) with friction_backlash_nonlinearity(h), X = F / ((M1 + M2) w^2), to 1e-6."""
    M, h = 2.0, 0.1
    cycles = predict("static-backlash", LEAD, F_range=(0.01, 100), omega_range=(0.1, 50))
    assert len(cycles) == 1 and cycles[0].residual < 1e-9
    response = ct.describing_function_response(LEAD * ct.tf([1], [M, 0, 0]), ct.friction_backlash_nonlinearity(h),
                                               np.linspace(0.0501, 5, 400), omega=np.geomspace(0.05, 100, 400))
    (X_ref, w_ref), = response.intersections
    c = cycles[0]
    assert c.F / (M * c.omega ** 2) == pytest.approx(X_ref, rel=1e-6)
    assert c.omega == pytest.approx(w_ref, rel=1e-6)


@pytest.mark.slow
def test_pid_hunting_pair_stable_and_unstable(fmus):
    """Integral action and static friction: a stable cycle and, above it, an unstable one (Loeb)."""
    cycles = predict("friction", parse_transfer_function(PID), F_range=(7.0001, 300), omega_range=(0.05, 50))
    assert [c.stable for c in cycles] == [True, False]
    for c in cycles:
        assert c.residual < 1e-8 and c.periodic
        N = DFEngine("friction").point(c.F, c.omega).N
        assert abs(1 + complex(parse_transfer_function(PID)(1j * c.omega)) * N) < 1e-8


@pytest.mark.slow
def test_no_cycle_is_an_empty_answer(fmus):
    assert predict("friction", parse_transfer_function("40 + 60/s + 8*s/(0.01*s+1)"),
                   F_range=(7.0001, 300), omega_range=(0.05, 50)) == []


def test_controller_fmu_values_are_minus_G():
    values = controller_values(parse_transfer_function("2*(s+3)/(4*s+8)"))
    assert values == {"order": 1, "b0": -0.5, "b1": -1.5, "a1": 2.0}


@pytest.mark.slow
def test_judge_converges_towards_the_static_backlash_prediction(fmus):
    """The co-simulated cycle approaches the prediction as the communication step shrinks."""
    cycle, = predict("static-backlash", LEAD, F_range=(0.01, 100), omega_range=(0.1, 50))
    errors = []
    for samples in (128, 512):
        run = run_loop("static-backlash", LEAD, step=cycle.period / samples, stop_time=40 * cycle.period,
                       initial={"x0": 0.15})
        found = measure(run, rtol=5e-3)
        assert found.settled
        errors.append(abs(found.omega - cycle.omega) / cycle.omega)
    assert errors[1] < errors[0] and errors[1] < 0.02


def test_cli_json_contract(fmus, capsys):
    code = main(["limit-cycle", "static-backlash", "--G", "20*(s+2)/(s+20)", "--F-range", "0.01", "100",
                 "--omega-range", "0.1", "50", "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    (p,) = report["predictions"]
    for name in ("F", "omega", "amplitude_x", "stable", "distortion"):
        assert name in p
    assert p["stable"] is True and math.isclose(p["omega"], 0.9137317, rel_tol=1e-6)


@pytest.mark.parametrize("argv, message", [
    (["--G", "2s+1"], "does not parse"),
    (["--G", "3"], "has no s"),
    (["--G", "s**2/(s+1)"], "improper"),
    (["--G", "1/(s+1)", "--F-range", "10", "1"], "is not a range"),
    (["--G", "1/(s+1)", "--omega-range", "0", "1"], "is not a range"),
    (["--G", "1/(s+1)", "--set", "eps=3"], "eps = 3.0 is out of range"),
    (["--G", "1/(s+1)", "--num", "1"], "argument --num: not allowed with argument --G"),
    (["--G", "1/(s+1)", "--den", "1", "1"], "--den goes with --num"),
])
def test_cli_bad_input_is_one_line_exit_2(capsys, argv, message):
    with pytest.raises(SystemExit) as stop:
        main(["limit-cycle", "backlash"] + argv)
    assert stop.value.code == 2
    assert message in capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.slow
def test_two_mass_backlash_example_has_a_stable_cycle_at_eps_02(fmus):
    cycles = predict("backlash", parse_transfer_function("200*(s+2)/(s+20)"), {"eps": 0.2},
                     F_range=(0.01, 100), omega_range=(0.1, 60))
    (c,) = cycles
    assert c.stable and c.periodic and c.residual < 1e-8
    assert c.F == pytest.approx(2.11872, rel=1e-4) and c.omega == pytest.approx(7.52788, rel=1e-4)


@pytest.mark.slow
def test_cli_verify_reports_the_judge_in_prediction_order(fmus, capsys, tmp_path):
    figure = tmp_path / "cycle.png"
    code = main(["limit-cycle", "static-backlash", "--G", "20*(s+2)/(s+20)", "--F-range", "0.01", "100",
                 "--omega-range", "0.1", "50", "--verify", "--samples-per-period", "256", "--plot", str(figure),
                 "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert len(report["verification"]) == len(report["predictions"]) == 1
    check = report["verification"][0]
    for name in ("F", "omega", "amplitude_x", "settled", "rel_error_F", "rel_error_omega"):
        assert name in check
    assert check["settled"] and check["perturbed"]["settled"]
    assert check["rel_error_omega"] < 0.05  # the hold's error at 256 steps per period (see examples.md)
    assert figure.stat().st_size > 10_000
