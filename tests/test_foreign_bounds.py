"""A user's FMU: N_error within 1 to 100 times the true error, model exchange and co-simulation; jumps located.

Closed forms (:mod:`foreign_models`): the mass-spring-damper, the saturation (below and above its kink) and
a relay with hysteresis that switches inside doStep (``RelayCS``), all run as held-input co-simulation FMUs;
and the model-exchange cases of ``test_foreign`` (mass-spring-damper up to Q = 50, saturation, relay,
drifting mass). The estimate must never be below the truth (honest) nor above 100 times it (saying
something); the relay's jumps must be located inside the steps, to 1e-6 of its DF.

Model exchange is exact to rounding on most of these, so its truth is compared as at least
:data:`FLOOR` ulps of |N| (a true error of 1e-16 on N = 0.4 is rounding: N_error may say 1e-14).
"""

import math
import sys
from pathlib import Path

import pytest

import dfwb

sys.path.insert(0, str(Path(__file__).parent))
import foreign_models  # noqa: E402

msd, sat, relay = foreign_models.msd_df, foreign_models.saturation_df, foreign_models.relay_df
CASES = [
    ("MassSpringDamper", 1.0, 1.0, {}, msd(1.0)),
    ("MassSpringDamper", 1.0, 2.0, {}, msd(2.0)),  # resonance, Q = 5
    ("Saturation", 0.5, 1.0, {}, sat(0.5)),  # linear: the held output lags half a step (order 1)
    ("Saturation", 3.0, 1.0, {}, sat(3.0)),
    ("RelayCS", 1.0, 1.0, {}, relay(1.0)),
    ("RelayCS", 3.0, 2.0, {"a": 0.7, "Y": 2.0}, relay(3.0, Y=2.0, a=0.7)),
]


FLOOR = 16 * sys.float_info.epsilon  # a model-exchange true error below 16 ulps of |N| counts as 16 ulps
ME_CASES = [
    ("MassSpringDamper", 1.0, 1.0, {}, msd(1.0)),  # the loose section's transient dominates
    ("MassSpringDamper", 2.0, 2.0, {}, msd(2.0)),  # resonance, Q = 5: shot
    ("MassSpringDamper", 0.5, 7.0, {"c": 0.02}, msd(7.0, c=0.02)),  # Q = 50: shot, its rounding decays slowly
    ("Saturation", 0.5, 1.0, {}, sat(0.5)),
    ("Saturation", 3.0, 1.0, {}, sat(3.0)),  # kinks (events): was 1140 times the true error
    ("Saturation", 2.0, 3.0, {}, sat(2.0)),
    ("Saturation", 10.0, 7.0, {"a": 2.0}, sat(10.0, a=2.0)),
    ("Relay", 1.0, 1.0, {}, relay(1.0)),
    ("Relay", 3.0, 2.0, {"a": 0.7, "Y": 2.0}, relay(3.0, Y=2.0, a=0.7)),
    ("DriftingMass", 2.0, 3.0, {"v0": 0.3}, -1.0 / 9.0),  # the ramp removed
]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bounds")
    return {name: foreign_models.build(name, folder) for name in {case[0] for case in CASES + ME_CASES}}


@pytest.mark.parametrize("name, F, omega, params, truth", ME_CASES)
def test_model_exchange_error_bound_is_honest_and_tight(built, name, F, omega, params, truth):
    response = dfwb.describing_function(dfwb.fmu_plant(built[name]), F, omega, **params)
    assert response.points[0]["drive"] == "model-exchange"
    error, bound = abs(complex(response.N) - truth), float(response.N_error)
    assert error <= bound and math.isfinite(bound), (response.N, truth, bound)
    assert 1.0 <= bound / max(error, FLOOR * abs(truth)) <= 100.0, (error, bound)


@pytest.mark.parametrize("name, F, omega, params, truth", CASES)
def test_cosimulation_error_bound_is_honest_and_tight(built, name, F, omega, params, truth):
    response = dfwb.describing_function(dfwb.fmu_plant(built[name], kind="co-simulation"), F, omega, **params)
    error, bound = abs(complex(response.N) - truth), float(response.N_error)
    assert error <= 1e-6 * abs(truth), (response.N, truth)
    assert 1.0 <= bound / error <= 100.0, (error, bound, response.points[0]["note"])


def test_a_relays_jumps_are_located_inside_the_steps(built):
    """Without locating, the held relay's switching sits on the step grid (7.9e-4 true error at F = 1)."""
    response = dfwb.describing_function(dfwb.fmu_plant(built["RelayCS"], kind="co-simulation"), 1.0, 1.0)
    note = response.points[0]["note"]
    assert "output jumps located inside steps" in note and "not)" not in note
    assert abs(complex(response.N) - relay(1.0)) <= 1e-7
