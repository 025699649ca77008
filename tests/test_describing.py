"""The DF engine against closed forms, python-control, and its own conventions."""

import math

import control as ct
import numpy as np
import pytest

from dfwb.engine.describing import DFEngine
from dfwb.fmus import PlantError
from dfwb.plants.closed_forms import backlash_df, static_backlash_plant_df, validity_frequencies


@pytest.fixture(scope="module")
def friction(fmus):
    return DFEngine("friction")


@pytest.fixture(scope="module")
def static(fmus):
    return DFEngine("static-backlash")


@pytest.fixture(scope="module")
def backlash(fmus):
    return DFEngine("backlash")


@pytest.mark.parametrize("omega", [0.01, 0.1, 1.0, 10.0, 100.0, 1000.0])
def test_linear_limit_is_exact(friction, omega):
    """Fc = Fs = 0: -1/N = M w^2 - j B w (docs/models.md's check for any implementation), to 1e-10."""
    result = friction.point(10.0, omega, {"Fc": 0.0, "Fs": 0.0})
    assert result.periodic
    assert result.minus_inverse == pytest.approx(omega ** 2 - 0.5j * omega, rel=1e-10)


@pytest.mark.parametrize("F, omega", [(50.0, 20.0), (50.0, 10.0), (10.0, 5.0), (60.0, 30.0), (5.0, 2.0)])
def test_static_backlash_equals_its_closed_form(static, F, omega):
    result = static.point(F, omega)
    assert result.N == pytest.approx(complex(static_backlash_plant_df(F, omega)), rel=1e-8)


@pytest.mark.parametrize("X", [0.0500001, 0.051, 0.07, 0.1, 0.5, 10.0])
def test_backlash_closed_form_equals_python_control(X):
    assert complex(backlash_df(X, k=1.0, h=0.1)) == pytest.approx(
        ct.friction_backlash_nonlinearity(0.1).describing_function(X), rel=1e-12, abs=1e-15)


def test_backlash_that_never_engages_gives_zero_and_says_so(static, backlash):
    quiet = static.point(1.0, 20.0)  # X = 1 / 800 < h / 2
    assert quiet.N == 0 and quiet.minus_inverse is None and "does not engage" in quiet.note
    apart = backlash.point(0.01, 50.0)  # M2 swings 4e-6 m inside a 0.05 m half clearance
    assert apart.N == 0 and apart.minus_inverse is None and "do not touch" in apart.note
    assert apart.as_dict()["minus_inv_N_re"] is None


@pytest.mark.parametrize("omega", [23.0, 25.0, 30.0])
def test_static_backlash_engaged_only_in_the_transient_gives_zero(static, omega):
    """h/4 < X < h/2: x (from rest, mean X) drags y once, then swings inside the play: N = 0."""
    X = 50.0 / (2.0 * omega ** 2)
    assert 0.025 < X < 0.05
    result = static.point(50.0, omega)
    assert result.N == 0 and "does not engage" in result.note
    assert complex(static_backlash_plant_df(50.0, omega)) == 0


def test_alternating_approach_is_a_one_period_orbit(backlash):
    """A multiplier near -1 repeats every 2 periods before every period; it is still period 1."""
    result = backlash.point(50.0, 30.0, {"eps": 0.9})
    assert result.periodic and result.orbit_periods == 1


def test_converging_position_is_not_called_a_drift(friction):
    result = friction.point(30.0, 1.0)
    assert result.periodic and "drift" not in result.note


def test_stick_slip_point_repeats_after_the_first_stick(friction):
    result = friction.point(10.0, 1.0)
    assert result.periodic and result.periods <= 3 and result.orbit_periods == 1
    assert len(result.harmonics) == 11 and result.harmonics[2] < 1e-12 * result.harmonics[1]  # odd symmetry


def test_higher_force_is_closer_to_linear(friction):
    """Paper, Fig. 4: the higher F, the closer -1/N to the linear case, especially the real part."""
    linear = 1.0 - 0.5j
    errors = [abs(friction.point(F, 1.0).minus_inverse - linear) for F in (10.0, 20.0, 50.0)]
    assert errors[0] > errors[1] > errors[2]


@pytest.mark.parametrize("F, omega", [(50.0, 11.77), (30.0, 10.0)])
def test_non_periodic_response_is_flagged_and_averaged(backlash, F, omega):
    """Impacts at eps = 0.8 below w_J: no orbit within the transient cap (chaotic here)."""
    result = backlash.point(F, omega, {"eps": 0.8})
    assert not result.periodic
    assert result.periods == backlash.max_periods
    assert "average of the last 20" in result.note and math.isfinite(abs(result.N)) and result.N != 0
    again = backlash.point(F, omega, {"eps": 0.8})
    assert again.N == result.N  # deterministic


def test_input_drive_converges_to_the_exact_drive(fmus):
    """The master-sampled sine (held per step) has an O(1/N) error (about 3/N: the hold delays
    the input by half a step), its free-mass drift removed."""
    exact = DFEngine("static-backlash").point(50.0, 20.0).N
    errors = [abs(DFEngine("static-backlash", drive="input", samples_per_period=n).point(50.0, 20.0).N - exact)
              / abs(exact) for n in (16, 64, 256)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.02
    assert all(error * n < 4.0 for error, n in zip(errors[1:], (64, 256)))  # first order once resolved


def test_validity_frequencies():
    w = validity_frequencies(50.0, M2=1.0, h=0.1, eps=0.5)
    assert w["w_J"] == pytest.approx(math.sqrt(500.0))
    assert w["w_L"] == pytest.approx(2 * math.sqrt(500.0))
    assert w["w_C"] == pytest.approx((1000.0 ** 2 * 0.5 ** 5) ** 0.25)
    assert w["w_C"] < w["w_J"] < w["w_L"]


@pytest.mark.parametrize("F, omega, params, text", [
    (0.0, 1.0, {}, "F = 0.0 is out of range"),
    (1.0, -1.0, {}, "omega = -1.0 is out of range"),
    (math.nan, 1.0, {}, "F = nan is out of range"),
    (1.0, 1.0, {"Fs": 1.0}, "Fs = 1.0 is out of range"),
    (1.0, 1.0, {"nope": 1.0}, "unknown parameter 'nope'"),
    (1.0, 1.0, {"omega": 2.0}, "omega is set by the describing-function engine"),
])
def test_bad_points_are_refused(friction, F, omega, params, text):
    with pytest.raises(PlantError, match=text):
        friction.point(F, omega, params)


def test_results_serialise_with_the_documented_fields(friction):
    data = friction.point(20.0, 2.0).as_dict()
    for name in ("plant", "F", "omega", "params", "N_re", "N_im", "periodic", "periods", "harmonics", "seconds"):
        assert name in data
    assert isinstance(data["periodic"], bool) and isinstance(data["periods"], int)
    assert np.all(np.isfinite(data["harmonics"])) and len(data["harmonics"]) == 11


def test_a_refused_run_keeps_its_instance_and_the_next_run_is_exact(fmus):
    """fmi2Error leaves the instance usable: the session resets it instead of instantiating anew."""
    from dfwb.fmi.session import _ABANDONED, FMUSession
    from dfwb.fmi.simulation import FMUError

    def run(session, values):
        session.start(values)
        for _ in range(4):
            session.step(0.25, {"f": 3.0})
        return session.reals(["x", "v", "Ic1"]) + session.integers(["events"])

    session, fresh = FMUSession(fmus["FrictionMass"]), FMUSession(fmus["FrictionMass"])
    abandoned = len(_ABANDONED)
    with pytest.raises(FMUError, match="M = -1.0 is out of range"):
        session.start({"M": -1.0})
    instance = session._instance
    session.start({"F": 10.0})
    with pytest.raises(FMUError, match="the input f must be a finite number"):
        session.step(0.25, {"f": math.nan})
    assert session._instance is instance and len(_ABANDONED) == abandoned
    assert run(session, {"F": 10.0, "omega": 1.5}) == run(fresh, {"F": 10.0, "omega": 1.5})


def test_a_refused_read_is_an_fmu_error_naming_it(fmus, monkeypatch):
    """The per-period reads check their status like every FMI call: a refusal is FMUError, one line, and the
    instance is reset before the next run (dfwb.fmi.status's rule)."""
    from fmpy.fmi1 import FMICallException

    from dfwb.fmi import instance as instance_module
    from dfwb.fmi.session import FMUSession
    from dfwb.fmi.simulation import FMUError

    session = FMUSession(fmus["FrictionMass"])
    session.start({"F": 10.0, "omega": 1.0})
    read = session.reader(["x", "v"], ["events"])
    assert read()[0] == [0.0, 0.0]

    def refuse(function, status):
        raise FMICallException(function=function, status=3)

    monkeypatch.setattr(instance_module, "check", refuse)
    with pytest.raises(FMUError, match=r"^FrictionMass: reading the outputs failed at t = 0\.0: fmi2GetReal failed"):
        read()
    monkeypatch.undo()
    session.start({"F": 10.0, "omega": 1.0})  # reset, as after any refused call
    session.step(0.5, {"f": 0.0})
    assert read()[1] == [0] and read()[0][0] != 0.0


def test_a_tail_of_two_rates_is_extrapolated_to_the_same_orbit(fmus, monkeypatch):
    """The drivetrain at F 50 N, omega 20 rad/s converges at two rates (the gear's rattle, the load's creep):
    Aitken cannot take that tail and plain iteration needs 68 periods; the degree-2 extrapolation and one
    shooting period close the orbit in at most 25, at the N that plain iteration reaches (within 1e-9)."""
    from dfwb.engine import describing

    engine = DFEngine("drivetrain")
    fast = engine.point(50.0, 20.0, {"eps": 0.5})
    assert fast.periodic and fast.periods <= 25 and "confirmed by shooting" in fast.note
    monkeypatch.setattr(describing._Search, "extrapolate", lambda self, sections, counts: None)
    plain = engine.point(50.0, 20.0, {"eps": 0.5})
    assert plain.periodic and plain.periods > 50
    assert abs(fast.N - plain.N) < 1e-9 * abs(plain.N)
