"""A user's co-simulation FMU: N_error within 1 to 100 times the true error, and output jumps located.

Closed forms (:mod:`foreign_models`): the mass-spring-damper, the saturation (below and above its kink) and
a relay with hysteresis that switches inside doStep (``RelayCS``), all run as held-input co-simulation FMUs.
The estimate must never be below the truth (honest) nor above 100 times it (saying something); the relay's
jumps must be located inside the steps, to 1e-6 of its DF.
"""

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


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bounds")
    return {name: foreign_models.build(name, folder) for name in {case[0] for case in CASES}}


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
