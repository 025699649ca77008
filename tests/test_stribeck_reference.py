"""The independent Stribeck reference (tests/stribeck_reference.py) against its limits: dfwb's friction mass when
Fs = Fc, and as the Stribeck velocity vs falls to 0."""

import numpy as np
import pytest
from stribeck_reference import simulate

from dfwb.fmus.friction import FrictionLoop, FrictionMass

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
    Fc beyond) falls with vs (measured: 0.32, 0.089, 0.022 m at vs = 1e-1 .. 1e-3 m/s)."""
    x = _friction_x(F=10.0, omega=1.0)
    distances = [np.max(np.abs(simulate(12.0, vs=vs, F=10.0, omega=1.0, times=TIMES)[1][:, 0] - x))
                 for vs in (1e-1, 1e-2, 1e-3)]
    assert all(a > 3 * b for a, b in zip(distances, distances[1:])), distances
    assert distances[-1] < 3e-2, distances


LOOP_TIMES = np.linspace(0.0, 60.0, 601)


@pytest.mark.parametrize("b, a", [([2.0, 1.0], [0.0]),  # PI (2 s + 1) / s: one breakaway, one stop, stuck
                                  ([10.0, 2.0], [0.0]),  # PI 10 + 2/s: hunts, a stick at every reversal
                                  ([3.0, 4.0, 1.0], [2.0, 0.0]),  # second order (3 s + 1)(s + 1) / (s (s + 2))
                                  ([100.0, 2.0], [0.0]),  # stiff PI: stops where it slides on, reversing
                                  ([2.0, 100.0, 5.0], [3.0, 0.0])])  # PID-like with a filtered derivative
def test_without_the_stribeck_drop_the_closed_loop_is_the_friction_loop(b, a):
    """Fs = Fc under -G(s) x from x0 = 0.3: dfwb's exact friction loop, its state [x, v, z1..zn] in the same
    controllable canonical form (measured: x, v and z agree to 4e-12 or better over 60 s), and a stick phase of
    the loop for each breakaway of the reference (and one more if it ends stuck)."""
    params = dict(M=1.0, B=0.5, Fc=5.0, Fs=5.0)
    _, states, events = simulate(60.0, x0=0.3, b=b, a=a, times=LOOP_TIMES, **params)
    loop, exact = FrictionLoop(b, a, x0=0.3, **params), []
    for t in LOOP_TIMES:
        loop.advance(float(t))
        exact.append(loop.state())
    exact = np.array(exact)
    assert states.shape == exact.shape == (len(LOOP_TIMES), 2 + len(a))
    assert np.max(np.abs(states[:, :2] - exact[:, :2])) < 1e-8
    assert np.max(np.abs(states[:, 2:] - exact[:, 2:])) < 1e-8  # the same z
    breakaways = sum(kind == "breakaway" for _t, kind in events)
    assert loop.sticks == breakaways + (states[-1, 1] == 0.0)
