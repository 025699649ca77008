"""The numerical stress suite (dfwb.verify.stress): the quick set passes, and a broken solver is caught."""

import functools
import json
import math

import pytest

from dfwb.fmus import FrictionMass, StaticBacklash, TwoMassBacklash, piecewise
from dfwb.plants import PLANTS, builtin
from dfwb.verify import stress


@pytest.fixture(scope="module")
def quick_result():
    return stress.run_stress(quick=True)


def _report(result):
    lines = [f"{result['failed']} of {result['cases']} cases failed:"]
    for failure in result["failures"]:
        lines.append(f"- [{failure['check']}] {failure['case']}\n    {failure['detail']}")
    return "\n".join(lines)


@pytest.mark.slow
def test_quick_suite_passes(quick_result):
    """The whole quick set (~370 cases): every invariant holds on every case."""
    assert quick_result["cases"] >= 50
    assert quick_result["failed"] == 0, _report(quick_result)


def test_result_is_plain_json(quick_result):
    text = json.dumps(quick_result)
    back = json.loads(text)
    assert set(back) >= {"cases", "failed", "failures", "seconds"}
    assert back["failed"] == len({f["case"] for f in back["failures"]})


def _case(plant, params, n_periods=4, **kwargs):
    times, stepping = stress.uniform(n_periods * 2 * math.pi / params.get("omega", 1.0), 32 * n_periods)
    return stress.Case(plant, params, times, stepping, note="test", **kwargs)


def _checks(case):
    failures, _seconds, _notes = stress.run_case(case)
    return {f["check"] for f in failures}


FRICTION = dict(M=1.0, B=0.0, Fc=5.0, Fs=5.0, F=10.0, omega=1.0)
BACKLASH = dict(M1=1.0, M2=1.0, h=0.1, eps=0.5, F=50.0, omega=20.0)
STATIC = dict(M=2.0, k=1.0, h=0.1, F=50.0, omega=20.0)
STRIBECK = dict(M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, F=10.0, omega=1.0)
DRIVETRAIN = dict(BACKLASH, B=0.5, Fc=5.0, Fs=7.0)
REFERENCE_CASES = {"friction": FRICTION, "backlash": BACKLASH, "static-backlash": STATIC,
                   "stribeck": STRIBECK, "drivetrain": DRIVETRAIN}  # plant: a plain case
STRESSED = [entry.name for entry in PLANTS.values() if entry.stress is not None]


def test_every_registered_plant_has_a_reference_case():
    """A stressed plant missing from REFERENCE_CASES fails here; the built-in plants are all stressed."""
    missing = sorted(set(STRESSED) - set(REFERENCE_CASES))
    assert not missing, f"add a plain case to REFERENCE_CASES for {missing}"
    assert {builtin.FRICTION.name, builtin.BACKLASH.name, builtin.STATIC_BACKLASH.name} <= set(STRESSED)


@functools.lru_cache(maxsize=None)
def _all_cases(quick):
    return stress.all_cases(quick=quick)


@pytest.mark.parametrize("plant", STRESSED)
def test_every_plant_is_stressed(plant):
    """Its own valid cases, its long cases and its invalid parameters are in the sets, named by the plant."""
    quick, full = _all_cases(True), _all_cases(False)
    valid = [c for c in quick if isinstance(c, stress.Case) and c.plant == plant]
    assert len(valid) >= 10
    long = [c for c in full if isinstance(c, stress.Case) and c.plant == plant and c.long]
    assert len(long) == len(PLANTS[plant].stress.long)
    invalid = [c for c in quick if isinstance(c, stress.InvalidCase) and c.plant == plant]
    assert len(invalid) >= len(PLANTS[plant].stress.invalid) + 18 + 3 + 4  # its own, the excitation's, f, t_end
    assert all(c.describe().startswith(plant + "[") for c in valid)


@pytest.mark.parametrize("plant", STRESSED)
def test_the_reference_cases_pass_unbroken(plant):
    assert _checks(_case(plant, REFERENCE_CASES[plant])) == set()


def test_a_wrong_stribeck_law_is_caught(monkeypatch):
    """The Stribeck mass sliding on Coulomb friction alone (its fall lost) breaks the observer's law."""
    from dfwb.fmus import stribeck

    monkeypatch.setattr(stribeck, "stribeck_factor", lambda v, vs, delta: 0.0)
    assert "slide" in _checks(_case("stribeck", STRIBECK))


def test_a_stribeck_mass_gaining_energy_is_caught(monkeypatch):
    """A slide pushed on by its friction (the fall's sign flipped) gains energy the force did not give."""
    from dfwb.fmus import stribeck

    monkeypatch.setattr(stribeck.StribeckSlide, "friction",
                        lambda self, v: -self.s * (self.Fc + self.drop) + self.B * v)
    assert "energy" in _checks(_case("stribeck", dict(STRIBECK, B=0.0)))


def test_a_stuck_load_that_moves_is_caught(monkeypatch):
    """The drivetrain reporting its load stuck (slip 0) while it slides breaks the load's stick check."""
    from dfwb.fmus import drivetrain

    original = drivetrain.Drivetrain.output

    def output(self):
        values = original(self)
        return values._replace(v1=values.v1 + 1e-3) if self.slip == 0 else values

    monkeypatch.setattr(drivetrain.Drivetrain, "output", output)
    assert "stick" in _checks(_case("drivetrain", DRIVETRAIN))


def test_a_drivetrain_in_contact_while_pulled_apart_is_caught(monkeypatch):
    """Contact kept while the motor side pulls away from the load (its pressing force negated) is caught."""
    from dfwb.fmus import drivetrain

    monkeypatch.setattr(drivetrain.Drivetrain, "_pressing", lambda self, t, s, v: -(
        self.M1 * self.drive.u(t) + self.M2 * (self.Fc * s + self.B * v)))
    assert "gap" in _checks(_case("drivetrain", dict(DRIVETRAIN, eps=0.0)))


def test_a_nan_output_is_caught(monkeypatch):
    original = FrictionMass.output

    def nan_after_first_event(self):
        x, v, ff, mode = original(self)
        return (math.nan if self.events else x), v, ff, mode

    monkeypatch.setattr(FrictionMass, "output", nan_after_first_event)
    assert "finite" in _checks(_case("friction", FRICTION))


def test_lost_momentum_is_caught(monkeypatch):
    original = TwoMassBacklash.output

    def slow_m2(self):  # v2 off by 1e-7 relative: a physics error far above rounding
        x1, v1, x2, v2, gap = original(self)
        return x1, v1, x2, v2 * (1 + 1e-7), gap

    monkeypatch.setattr(TwoMassBacklash, "output", slow_m2)
    assert "momentum" in _checks(_case("backlash", BACKLASH))


def test_a_gap_outside_the_clearance_is_caught(monkeypatch):
    original = TwoMassBacklash.output

    def overshoot(self):  # 1% of h below the true gap: negative near the lower edge
        x1, v1, x2, v2, gap = original(self)
        return x1, v1, x2, v2, gap - 0.01 * self.h

    monkeypatch.setattr(TwoMassBacklash, "output", overshoot)
    assert "gap" in _checks(_case("backlash", BACKLASH))


def test_a_leaking_play_is_caught(monkeypatch):
    original = StaticBacklash.output

    def leak(self):
        x, v, y = original(self)
        return x + 0.6 * self.h, v, y

    monkeypatch.setattr(StaticBacklash, "output", leak)
    assert "play" in _checks(_case("static-backlash", STATIC))


def test_sticking_under_a_large_force_is_caught(monkeypatch):
    """A solver that reports stick (mode 0, v = 0) while |u| > Fs."""
    original = FrictionMass.output

    def always_stuck(self):
        x, _v, _ff, _mode = original(self)
        return x, 0.0, self.drive.u(self.t), 0

    monkeypatch.setattr(FrictionMass, "output", always_stuck)
    assert "stick" in _checks(_case("friction", FRICTION))


def test_non_determinism_is_caught(monkeypatch):
    original = FrictionMass.output
    calls = []

    def drifting(self):
        calls.append(None)
        x, v, ff, mode = original(self)
        return x + len(calls) * 1e-12, v, ff, mode

    monkeypatch.setattr(FrictionMass, "output", drifting)
    assert "deterministic" in _checks(_case("friction", FRICTION))


def test_wrong_fourier_integrals_are_caught(monkeypatch):
    original = StaticBacklash.integrals

    def off(self):
        values = original(self)
        return [values[0]] + [z * (1 + 1e-6) for z in values[1:]]

    monkeypatch.setattr(StaticBacklash, "integrals", off)
    assert "fourier" in _checks(_case("static-backlash", STATIC))


def test_events_and_time_budget_are_enforced(monkeypatch):
    case = _case("backlash", BACKLASH, budget=0.0)
    monkeypatch.setattr(stress, "EVENTS_PER_PERIOD", 0.5)
    assert {"time", "events"} <= _checks(case)


def test_a_solver_error_is_a_failure(monkeypatch):
    monkeypatch.setattr(piecewise, "EVENTS_PER_PERIOD_LIMIT", 1)
    times, stepping = stress.uniform(4 * 2 * math.pi / 20.0, 1)  # ~16 events in one step: over the limit of 5
    assert "exception" in _checks(stress.Case("backlash", BACKLASH, times, stepping))


def test_an_accepted_bad_parameter_is_caught(monkeypatch):
    monkeypatch.setattr(piecewise, "check", lambda name, value, ok, allowed: None)
    monkeypatch.setattr("dfwb.fmus.backlash.check", lambda name, value, ok, allowed: None)
    failures, _, _ = stress.run_case(stress.InvalidCase("backlash", {"eps": 1.5}, "eps"))
    assert [f["check"] for f in failures] == ["refused"]
    assert failures[0]["detail"]["why"] == "accepted"


def test_full_set_is_larger_reproducible_and_split_into_parts():
    quick = [c.describe() for c in stress.all_cases(quick=True)]
    full = [c.describe() for c in stress.all_cases(quick=False)]
    assert len(full) > len(quick) and full == [c.describe() for c in stress.all_cases(quick=False)]
    assert any("1e5 periods" in d for d in full) and not any("1e5 periods" in d for d in quick)
    parts = len(full)  # one case per part: the last one, an invalid parameter, runs at once
    result = stress.run_stress(quick=False, part=parts - 1, parts=parts)
    assert result["cases"] == 1 and (result["part"], result["parts"]) == (parts - 1, parts)
    with pytest.raises(ValueError):
        stress.run_stress(quick=False, part=3, parts=3)
