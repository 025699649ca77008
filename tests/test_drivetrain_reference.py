"""The independent drivetrain reference (tests/drivetrain_reference.py) against its two limits: dfwb's two-mass
backlash when the load has no friction, and the friction mass of mass M1 + M2 as the clearance closes."""

import math

import numpy as np
import pytest
from drivetrain_reference import simulate

from dfwb.fmus.backlash import TwoMassBacklash
from dfwb.fmus.friction import FrictionMass

TIMES = np.linspace(0.0, 12.0, 241)


def _exact(plant, field):
    values = []
    for t in TIMES:
        plant.advance(float(t))
        values.append(getattr(plant.output(), field))
    return np.array(values)


@pytest.mark.parametrize("eps, F, omega", [(0.5, 50.0, 20.0), (0.0, 30.0, 5.0), (0.8, 10.0, 1.0)])
def test_without_friction_it_is_the_two_mass_backlash(eps, F, omega):
    _, states, events = simulate(12.0, eps=eps, B=0.0, Fc=0.0, Fs=0.0, F=F, omega=omega, times=TIMES)
    assert len(events) > 50  # impacts and contacts all along
    assert np.max(np.abs(states[:, 0] - _exact(TwoMassBacklash(eps=eps, F=F, omega=omega), "x1"))) < 1e-11
    assert np.max(np.abs(states[:, 2] - _exact(TwoMassBacklash(eps=eps, F=F, omega=omega), "gap"))) < 1e-11


@pytest.mark.parametrize("F, omega", [(10.0, 1.0), (8.0, 2.0)])
def test_as_the_clearance_closes_it_tends_to_the_friction_mass_as_sqrt_h(F, omega):
    """With eps = 0, each flight across the play lasts ~sqrt(2 h M2 / |u|), the load decelerating alone: the
    distance to the friction mass of mass M1 + M2 falls as sqrt(h) (measured: 1.14 sqrt(h) at F = 10 N)."""
    x = _exact(FrictionMass(M=2.0, F=F, omega=omega), "x")
    ratios = []
    for h in (1e-8, 1e-10, 1e-12):
        _, states, events = simulate(12.0, h=h, eps=0.0, F=F, omega=omega, times=TIMES)
        assert any(kind == "stop" for _t, kind in events)  # the load sticks
        ratios.append(np.max(np.abs(states[:, 0] - x)) / math.sqrt(h))
    assert max(ratios) < 3.0 and max(ratios) / min(ratios) < 1.5, ratios
