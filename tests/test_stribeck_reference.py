"""The independent Stribeck reference (tests/stribeck_reference.py) against its limits: dfwb's friction mass when
Fs = Fc, and as the Stribeck velocity vs falls to 0."""

import numpy as np
import pytest
from stribeck_reference import simulate

from dfwb.fmus.friction import FrictionMass

TIMES = np.linspace(0.0, 12.0, 241)


def _friction_x(**params):
    plant, x = FrictionMass(**params), []
    for t in TIMES:
        plant.advance(float(t))
        x.append(plant.output().x)
    return np.array(x)


@pytest.mark.parametrize("F, omega", [(10.0, 1.0), (20.0, 0.5), (8.0, 2.0)])
def test_without_the_stribeck_drop_it_is_the_friction_mass(F, omega):
    _, states, events = simulate(12.0, Fs=5.0, F=F, omega=omega, times=TIMES)
    assert any(kind == "stop" for _t, kind in events)  # it comes to rest (and sticks or slides on)
    assert np.max(np.abs(states[:, 0] - _friction_x(Fs=5.0, F=F, omega=omega))) < 1e-9


def test_as_the_stribeck_velocity_falls_it_tends_to_the_friction_mass():
    """The drop from Fs to Fc happens within |v| ~ vs: the distance to the friction mass (Fs = 7 N at rest,
    Fc beyond) falls with vs (measured: 0.32, 0.089, 0.022, 0.0049 m at vs = 1e-1 .. 1e-4 m/s)."""
    x = _friction_x(F=10.0, omega=1.0)
    distances = [np.max(np.abs(simulate(12.0, vs=vs, F=10.0, omega=1.0, times=TIMES)[1][:, 0] - x))
                 for vs in (1e-1, 1e-2, 1e-3, 1e-4)]
    assert all(a > 3 * b for a, b in zip(distances, distances[1:])), distances
    assert distances[-1] < 1e-2, distances
