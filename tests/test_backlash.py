"""The two-mass backlash solver: conservation laws, the clearance, Zeno, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dfwb.fmus import PlantError, TwoMassBacklash
from dfwb.fmus.backlash import FREE, LOWER, UPPER


def impulse(plant, t):
    """Integral of u from 0 to t, in closed form."""
    d = plant.drive
    return d.f * t + d.F / d.omega * (math.sin(d.omega * t + d.phi) - math.sin(d.phi))


@settings(deadline=None)
@given(M1=st.floats(0.05, 20), M2=st.floats(0.05, 20), h=st.floats(1e-3, 1.0), eps=st.floats(0, 1),
       F=st.floats(0, 100), w=st.floats(1, 60), f=st.floats(-20, 20), v1=st.floats(-1, 1), v2=st.floats(-1, 1))
def test_momentum_balance_and_clearance(M1, M2, h, eps, F, w, f, v1, v2):
    """M1 v1 + M2 v2 = initial momentum + int f dt, and 0 <= gap <= h, at every sample."""
    plant = TwoMassBacklash(M1=M1, M2=M2, h=h, eps=eps, F=F, omega=w, f=f, v1_0=v1, v2_0=v2)
    period = 2 * math.pi / w
    p0 = M1 * v1 + M2 * v2
    scale = abs(p0) + (F / w + abs(f) * 10 * period) + (M1 + M2) * (abs(v1) + abs(v2))
    for t in np.arange(1, 10 * 40 + 1) * period / 40:
        plant.advance(t)
        _x1, v1t, _x2, v2t, gap = plant.output()
        assert M1 * v1t + M2 * v2t - p0 == pytest.approx(impulse(plant, t), abs=1e-12 * scale)
        assert -1e-12 * h <= gap <= h * (1 + 1e-12)
        if plant.contact != FREE:
            sigma = -1 if plant.contact == LOWER else 1
            assert sigma * plant.drive.u(t) >= -1e-12 * (F + abs(f))  # contact only while u presses


def test_energy_balance_at_eps_one():
    """Elastic impacts: kinetic energy changes only by the work of u on M2, to 1e-12.

    The work is integrated by Gauss-Legendre between the recorded impacts (the
    integrand u v2 is smooth there), on a second run of the same deterministic plant.
    """
    kwargs = dict(M1=1.0, M2=0.7, h=0.1, eps=1.0, F=30.0, omega=15.0)
    first = TwoMassBacklash(**kwargs)
    first.event_log = []
    stop = 3.0
    first.advance(stop)
    impacts = [t for t, kind in first.event_log]
    assert first.impacts >= 20
    nodes, weights = np.polynomial.legendre.leggauss(24)
    edges = [0.0] + impacts + [stop]
    plant = TwoMassBacklash(**kwargs)
    work = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a <= 0.0:
            continue
        for node, weight in zip(nodes, weights):
            t = 0.5 * (a + b) + 0.5 * (b - a) * node
            plant.advance(t)
            work += 0.5 * (b - a) * weight * plant.drive.u(t) * plant.output()[3]
    plant.advance(stop)
    _x1, v1, _x2, v2, _gap = plant.output()
    energy = 0.5 * kwargs["M1"] * v1 ** 2 + 0.5 * kwargs["M2"] * v2 ** 2
    assert energy == pytest.approx(work, rel=1e-12)


def test_free_elastic_flight_conserves_energy_exactly():
    plant = TwoMassBacklash(M1=2.0, M2=0.5, eps=1.0, v1_0=0.3, v2_0=-1.1)
    e0 = 0.5 * 2.0 * 0.3 ** 2 + 0.5 * 0.5 * 1.1 ** 2
    plant.advance(100.0)
    _x1, v1, _x2, v2, _gap = plant.output()
    assert plant.impacts > 50
    assert 0.5 * 2.0 * v1 ** 2 + 0.5 * 0.5 * v2 ** 2 == pytest.approx(e0, rel=1e-13)


@pytest.mark.parametrize("eps", [0.0, 0.2, 0.5, 0.9])
def test_zeno_accumulation_ends_in_contact(eps):
    """A constant force pressing the masses together: impacts accumulate, then contact."""
    plant = TwoMassBacklash(eps=eps, f=-10.0)
    plant.advance(5.0)
    assert plant.contact == LOWER
    assert plant.output()[4] == 0.0
    assert 1 <= plant.impacts <= 400
    x1, v1, x2, v2, _ = plant.output()
    assert v1 == v2 == pytest.approx(-10.0 * 5.0 / 2.0, rel=1e-12)  # momentum of the pair


@pytest.mark.parametrize("eps", [0.0, 0.2, 0.8, 1.0 - 1e-9, 1.0])
def test_forced_impacts_stay_bounded_per_period(eps):
    """The paper's case (F = 50, w = 20): every eps runs 50 periods with few events."""
    plant = TwoMassBacklash(eps=eps, F=50.0, omega=20.0)
    plant.advance(50 * 2 * math.pi / 20.0)
    assert plant.events / 50 < 300
    assert all(math.isfinite(value) for value in plant.output())


def test_upper_contact_and_release():
    """Pulling M2 away from M1 holds the gap at h; reversing the force releases it."""
    plant = TwoMassBacklash(eps=0.3, f=10.0)
    plant.advance(2.0)
    assert plant.contact == UPPER and plant.output()[4] == plant.h
    plant.set_input(-10.0)
    plant.advance(2.0 + 1e-6)
    assert plant.contact == FREE
    plant.advance(6.0)
    assert plant.contact == LOWER


@pytest.mark.parametrize("kwargs, name", [
    ({"M1": 0.0}, "M1"), ({"M2": -1.0}, "M2"), ({"h": 0.0}, "h"), ({"h": -0.1}, "h"),
    ({"eps": -0.1}, "eps"), ({"eps": 1.5}, "eps"), ({"gap0": -0.01}, "gap0"), ({"gap0": 0.2}, "gap0"),
    ({"eps": math.nan}, "eps"), ({"omega": -1.0}, "omega"),
])
def test_bad_parameters_are_refused_with_their_name(kwargs, name):
    with pytest.raises(PlantError, match=rf"^{name} = .* is out of range"):
        TwoMassBacklash(**kwargs)


def test_chattering_beyond_the_event_limit_is_an_error_not_a_hang(monkeypatch):
    from dfwb.fmus import piecewise

    monkeypatch.setattr(piecewise, "EVENTS_PER_PERIOD_LIMIT", 5)
    plant = TwoMassBacklash(eps=0.9, f=-10.0)  # a Zeno accumulation of ~130 impacts
    with pytest.raises(PlantError, match="more than 5 events per period between t = 0.0 and t = "):
        plant.advance(1.0)
