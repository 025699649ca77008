"""Bounds (issue 10): inputs that passed every check and then ran forever, the engine's ranges, translation.

Each former hang runs in a child process with a time limit: a regression fails
the test (it times out) instead of hanging the suite.
"""

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from dfwb.engine.describing import F_RANGE, OMEGA_RANGE, DFEngine, check_point
from dfwb.fmus import PlantError
from dfwb.plants.registry import plant

ROOT = Path(__file__).resolve().parents[1]
LIMIT = 60  # seconds: each case below ends within a few seconds


def run_python(code, limit=LIMIT):
    """stdout of ``code`` run by a fresh interpreter in the project root; fail on a time-out or a crash."""
    try:
        done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=ROOT, capture_output=True,
                              text=True, timeout=limit)
    except subprocess.TimeoutExpired:
        pytest.fail(f"still running after {limit} s (a loop without bound):\n{code}")
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def outcome(statement, setup=""):
    """What ``statement`` does in a child process: 'ok <repr>' or 'PlantError: <message>'."""
    return run_python(f"""
        import math
        from dfwb.fmus import FrictionMass, TwoMassBacklash, StaticBacklash, PlantError
        from dfwb.fmus.exact import Drive, first_root
        {setup}
        try:
            print("ok", repr({statement}))
        except PlantError as error:
            print("PlantError:", error)
        """)


# -- the solvers: every loop bounded -----------------------------------------------------
@pytest.mark.parametrize("statement, message", [
    # a motion 1e30 times the clearance, and a clearance of 1e-200 m: the event search ends
    ("TwoMassBacklash(F=1e30, omega=1.0).advance(2 * math.pi)", "needed more than 100000 evaluations"),
    ("TwoMassBacklash(F=10.0, omega=1.0, h=1e-200).advance(2 * math.pi)", "needed more than 100000 evaluations"),
    # a clearance whose 1e-12 h is no normal float (below 1e-312 a pressed bounce never came to rest:
    # 1e5 impacts per period, minutes per period)
    ("TwoMassBacklash(F=10.0, omega=1.0, h=1e-300)", "h = 1e-300 is out of range: h must be >= 1e-290 (m)"),
    ("TwoMassBacklash(F=10.0, omega=1.0, h=5e-324).advance(2 * math.pi)", "h = 5e-324 is out of range"),
    # a phase that cannot resolve a period: Drive.crossing added 2 pi to it for ever
    ("FrictionMass(F=10.0, omega=1.0, phi=1e300)", "phi = 1e+300 is out of range: phi must be in [-1e+10, 1e+10] rad"),
    ("Drive(0.0, 10.0, 1.0, 1e300).crossing(0.0, 5.0, True)", "t = 0.0 is out of range: the phase omega*t + phi"),
    ("Drive(0.0, 10.0, 1.0, 0.0).crossing(1e300, 5.0, True)", "t = 1e+300 is out of range: the phase omega*t + phi"),
    # a step too long for the phase: 1e300 s of search chunks (or of stick-slip events)
    ("FrictionMass(F=10.0, omega=1.0).advance(1e300)", "t_end = 1e+300 is out of range: the phase omega*t + phi"),
    ("TwoMassBacklash(F=0.0, omega=1.0, v1_0=1.0).advance(1e11)", "t_end = 100000000000.0 is out of range"),
    # a zero search with nothing to clear it: 1e16 evaluations
    ("first_root(lambda t: (1e-300, 0.0), 0.0, 1.0, 1.0)", "needed more than 100000 evaluations"),
])
def test_a_former_hang_is_refused_with_a_message(statement, message):
    result = outcome(statement)
    assert result.startswith("PlantError:") and message in result, result


def test_a_huge_force_on_the_backlash_ends():
    """F = -1.7e308: the rounding of u overflowed, contact was never reached (2e5 impacts, minutes)."""
    result = outcome("TwoMassBacklash(F=-1.7e308, omega=1.0).advance(2 * math.pi)")
    assert result.startswith(("ok", "PlantError:")), result


def test_the_sign_of_a_huge_force_is_its_sign():
    """The rounding allowance of u overflowed to inf for F near the largest float: the trend decided."""
    from dfwb.fmus.exact import Drive

    drive = Drive(0.0, -1.7e308, 1.0, 0.0)  # u = -1.7e308 cos(t)
    assert drive.below(0.0, 0.0) and not drive.above(0.0, 0.0)


def test_a_huge_initial_velocity_is_integrated():
    """v0 = 1e300 decays as exp(-B t / M): the search bound decays with it (it ran for ever)."""
    result = outcome("p.output()[1]", "p = FrictionMass(F=10.0, omega=1.0, v0=1e300); p.advance(20 * math.pi)")
    assert result.startswith("ok"), result
    v = float(result.split()[1])
    assert v == pytest.approx(1e300 * math.exp(-0.5 * 20 * math.pi), rel=1e-12)


def test_an_fmu_refuses_a_phase_it_cannot_resolve(fmus):
    code = f"""
        from dfwb.fmi.simulation import FMUError, simulate
        for values, stop in (({{"F": 10.0, "phi": 1e300}}, 6.3), ({{"F": 10.0, "omega": 1e9}}, 100.0)):
            try:
                simulate({str(fmus["FrictionMass"])!r}, stop, stop, start_values=values)
                print("ok")
            except FMUError as error:
                print("FMUError:", error)
        """
    first, second = run_python(code).splitlines()
    assert first.startswith("FMUError:") and "phi = 1e+300 is out of range" in first, first
    assert second.startswith("FMUError:") and "t_end = 100.0 is out of range" in second, second


@pytest.mark.parametrize("argv, message", [
    (["df", "backlash", "--F", "1e30", "--omega", "1"], "F = 1e+30 is out of range: F must be in [1e-06, 1e+09] N"),
    (["df", "backlash", "--F", "10", "--omega", "1", "--set", "h=1e-300"],
     "h = 1e-300 is out of range: h must be in [1e-09, 1000] m"),
    (["df", "friction", "--F", "10", "--omega", "1", "--set", "v0=1e300"],
     "v0 = 1e+300 is out of range: v0 must be in [-1e+06, 1e+06] m/s"),
])
def test_dfwb_df_refuses_what_used_to_hang(fmus, argv, message):
    cli = "import sys; from dfwb.cli import main; sys.exit(main(sys.argv[1:]))"
    try:
        done = subprocess.run([sys.executable, "-c", cli, *argv], cwd=ROOT, capture_output=True, text=True,
                              timeout=LIMIT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"dfwb {' '.join(argv)} still running after {LIMIT} s")
    assert done.returncode == 2 and message in done.stderr, done.stderr


# -- the ranges the engine accepts ---------------------------------------------------------
def test_check_point_accepts_its_ranges_and_refuses_outside():
    assert F_RANGE == (1e-6, 1e9) and OMEGA_RANGE == (1e-4, 1e5)
    for F in F_RANGE:
        for omega in OMEGA_RANGE:
            check_point(F, omega)
    for F, omega, message in [
        (1e30, 1.0, "F = 1e+30 is out of range: F must be in [1e-06, 1e+09] N"),
        (9.9e-7, 1.0, "F = 9.9e-07 is out of range"),
        (0.0, 1.0, "F = 0.0 is out of range"),
        (math.nan, 1.0, "F = nan is out of range"),
        (1.0, 1e6, "omega = 1000000.0 is out of range: omega must be in [0.0001, 100000] rad/s"),
        (1.0, 9e-5, "omega = 9e-05 is out of range"),
        (1.0, -math.inf, "omega = -inf is out of range"),
    ]:
        with pytest.raises(PlantError) as error:
            check_point(F, omega)
        assert str(error.value) == message or str(error.value).startswith(message)


@pytest.mark.parametrize("name, params, message", [
    ("backlash", {"h": 1e-300}, "h = 1e-300 is out of range: h must be in [1e-09, 1000] m"),
    ("backlash", {"h": "2e3"}, "h = 2000.0 is out of range: h must be in [1e-09, 1000] m"),
    ("backlash", {"M1": 1e7}, "M1 = 10000000.0 is out of range: M1 must be in [1e-06, 1e+06] kg"),
    ("backlash", {"M2": 1e-7}, "M2 = 1e-07 is out of range: M2 must be in [1e-06, 1e+06] kg"),
    ("backlash", {"v2_0": -2e6}, "v2_0 = -2000000.0 is out of range: v2_0 must be in [-1e+06, 1e+06] m/s"),
    ("backlash", {"x1_0": 1e31}, "x1_0 = 1e+31 is out of range: x1_0 must be in [-1e+30, 1e+30] m"),
    ("friction", {"v0": 1e300}, "v0 = 1e+300 is out of range: v0 must be in [-1e+06, 1e+06] m/s"),
    ("friction", {"M": 0.0}, "M = 0.0 is out of range: M must be in [1e-06, 1e+06] kg"),
    ("friction", {"B": 2e9}, "B = 2000000000.0 is out of range: B must be in [0, 1e+09] N.s/m"),
    ("friction", {"Fs": 2e9}, "Fs = 2000000000.0 is out of range: Fs must be in [0, 1e+09] N"),
    ("friction", {"Dv": -1.0}, "Dv = -1.0 is out of range: Dv must be in [0, 1000] m/s"),
    ("static-backlash", {"k": 1e7}, "k = 10000000.0 is out of range: k must be in [1e-06, 1e+06]"),
    ("static-backlash", {"x0": -math.inf}, "x0 = -inf is out of range: x0 must be in [-1e+30, 1e+30] m"),
])
def test_plant_check_refuses_values_outside_the_ranges(name, params, message):
    with pytest.raises(PlantError) as error:
        plant(name).check(params)
    assert str(error.value) == message or str(error.value).startswith(message)


def test_plant_check_accepts_the_edges_of_the_ranges():
    assert plant("backlash").check({"h": 1e-9, "M1": 1e6, "M2": 1e-6, "v1_0": -1e6, "x1_0": 1e30}) == {
        "h": 1e-9, "M1": 1e6, "M2": 1e-6, "v1_0": -1e6, "x1_0": 1e30}
    plant("backlash").check({"h": 1e3, "gap0": 1e3})
    plant("friction").check({"M": 1e-6, "B": 1e9, "Fc": 1e9, "Fs": 1e9, "Dv": 1e3, "v0": 1e6})
    plant("static-backlash").check({"k": 1e-6, "h": 1e3, "x0": -1e30})


def test_max_periods_is_bounded(fmus):
    for bad in (0, math.inf, math.nan, 1.5, 10 ** 6):
        with pytest.raises(PlantError, match="max_periods"):
            DFEngine("friction", max_periods=bad)


# -- the DF does not depend on a translation -----------------------------------------------
@pytest.mark.parametrize("name, position, F, omega, params, per_metre", [
    ("friction", "x0", 10.0, 1.0, {}, 1.0),
    ("backlash", "x1_0", 10.0, 1.0, {}, 1.0),
    ("static-backlash", "x0", 50.0, 20.0, {"k": 2.0}, 2.0),
])
def test_the_df_does_not_depend_on_the_position(fmus, name, position, F, omega, params, per_metre):
    engine = DFEngine(name)
    at_rest = engine.point(F, omega, params)
    assert at_rest.N != 0
    for x in (1e20, 1e9, -1e15):
        moved = engine.point(F, omega, dict(params, **{position: x}))
        assert moved.N == at_rest.N and moved.X[1:] == at_rest.X[1:]  # bit for bit
        assert (moved.periodic, moved.periods, moved.note) == (at_rest.periodic, at_rest.periods, at_rest.note)
        assert moved.X[0] == at_rest.X[0] + per_metre * x  # the mean carries the translation
        assert moved.harmonics[0] == abs(moved.X[0]) and moved.harmonics[1:] == at_rest.harmonics[1:]
        assert moved.params[position] == x


def test_dfwb_df_gives_the_same_N_far_from_the_origin(fmus, capsys):
    from dfwb.cli import main

    rows = []
    for extra in ([], ["--set", "x0=1e20"]):
        assert main(["df", "friction", "--F", "10", "--omega", "1", "--json", *extra]) == 0
        rows.append(json.loads(capsys.readouterr().out)[0])
    assert (rows[1]["N_re"], rows[1]["N_im"]) == (rows[0]["N_re"], rows[0]["N_im"])
    assert rows[1]["periodic"] and rows[1]["note"] == rows[0]["note"] == ""
