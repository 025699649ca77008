"""The backlash inverse in the exact loop (issue 33): the controller sees ``y + k h_hat/2 s``, s the side of the
play's last touch.

Checked against the independent reference (:func:`dfwb.plants.loop_reference.closed_loop_reference` with
``inverse``: solve_ivp between events, the correction a number the reference's engagements and impacts set,
written apart from dfwb's coordinate of the loop state) on the static backlash under the lead
``20 (s + 2)/(s + 20)``, which hunts uncompensated (7.0 s, 0.107 m), on the two-mass backlash (impacts, plastic
contact, a start on a wall) and on the drivetrain without load friction; its closed-form DF against the exact
plant's own harmonic integrals.
"""

import cmath
import math
import re

import numpy as np
import pytest
from drivetrain_reference import simulate

import dfwb
from dfwb.engine.inverse_df import InverseDFEngine
from dfwb.fmus.backlash import BacklashLoop
from dfwb.fmus.compensation import BacklashInverse
from dfwb.fmus.contract import EventKind
from dfwb.fmus.drivetrain import DrivetrainLoop
from dfwb.fmus.exact import PlantError
from dfwb.fmus.static_backlash import StaticBacklash, StaticBacklashLoop
from dfwb.plants import plant
from dfwb.plants.closed_forms import backlash_df
from dfwb.plants.loop_reference import closed_loop_reference

LEAD = ([20.0, 40.0], [20.0])  # 20 (s + 2)/(s + 20) in (b, a)
H = 0.1  # the static backlash's play (its default)


def reference(h_hat, t_end, **more):
    return closed_loop_reference("static-backlash", *LEAD, t_end, inverse=h_hat, max_events=100_000, **more)


# -- the loop ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("h_hat, start", [(0.05, {"x0": 0.3}), (H, {"x0": 0.3}), (0.2, {"x0": -0.3}),
                                          (H, {"state": [0.04, 0.5, 0.0, 0.0]})])
def test_the_compensated_loop_fires_the_references_events(h_hat, start):
    loop = StaticBacklashLoop(*LEAD, **start, compensation=BacklashInverse(h_hat))
    loop.event_log = []
    times = np.linspace(0.0, 60.0, 31)
    states = loop.sample(list(times))
    params = {"x0": start["x0"]} if "x0" in start else None
    ref = reference(h_hat, 60.0, params=params, state=start.get("state"), t_eval=times)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert len(loop.event_log) > 20
    assert max(abs(t - u) for (t, _), (u, _) in zip(loop.event_log, ref["events"])) < 1e-9
    assert np.allclose(states, ref["samples"], rtol=0.0, atol=1e-9)  # the correction is not in the state


@pytest.mark.parametrize("h_hat, eps, start", [(0.1, 0.8, {"x1_0": 0.03}), (0.05, 0.0, {"x1_0": 0.03}),
                                               (0.2, 0.0, {"x1_0": 0.03, "gap0": 0.0})])
def test_the_two_mass_backlash_fires_the_references_events(h_hat, eps, start):
    """The two masses (impacts with restitution eps; plastic, eps = 0, with contact phases; a start on a wall):
    the controller sees x1 + h_hat/2 s, s the wall of M2's last touch, set before the impact's logic (which
    decides contact or flight with the force that follows)."""
    G = ([200.0, 400.0], [20.0])  # 200 (s + 2)/(s + 20)
    loop = BacklashLoop(*G, eps=eps, **start, compensation=BacklashInverse(h_hat))
    loop.event_log = []
    times = np.linspace(0.0, 5.0, 26)
    states = loop.sample(list(times))
    ref = closed_loop_reference("backlash", *G, 5.0, dict(start, eps=eps), inverse=h_hat, t_eval=times,
                                max_events=100_000)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert len(loop.event_log) > 20
    assert max(abs(t - u) for (t, _), (u, _) in zip(loop.event_log, ref["events"])) < 1e-9
    assert np.allclose(states, ref["samples"], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("h_hat, eps", [(0.1, 0.8), (0.05, 0.0)])
def test_the_drivetrain_without_load_friction_is_the_two_mass_backlash_with_its_inverse(h_hat, eps):
    """The drivetrain's play is the two-mass backlash's (its inverse the same); with B = Fc = Fs = 0 it follows
    the reference's two-mass backlash event for event (no reference has the load's friction)."""
    G, p = ([200.0, 400.0], [20.0]), {"M1": 1.0, "M2": 1.0, "h": 0.1, "eps": eps, "x1_0": 0.03}
    loop = DrivetrainLoop(*G, B=0.0, Fc=0.0, Fs=0.0, **p, compensation=BacklashInverse(h_hat))
    loop.event_log = []
    times = np.linspace(0.0, 5.0, 26)
    states = loop.sample(list(times))
    ref = closed_loop_reference("backlash", *G, 5.0, p, inverse=h_hat, t_eval=times, max_events=100_000)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert len(loop.event_log) > 20
    assert np.allclose(states, ref["samples"], rtol=0.0, atol=1e-9)


def test_with_the_true_play_the_controller_sees_the_mass_while_the_play_is_closed():
    """h_hat = h: engaged, y + w = k x exactly (y = k (x - s h/2), w = k h s/2); inside the play it holds the
    value of the last contact, and an inverse of 0 is no inverse, bit for bit."""
    loop = StaticBacklashLoop(*LEAD, x0=0.3, compensation=BacklashInverse(H))
    seen = {"engaged": 0, "free": 0}
    for t in np.linspace(0.05, 30.0, 600):
        loop.advance(float(t))
        X = loop._integrated()
        x, y, w = X[0], X[2], X[-1]
        if loop.key[0] == "engaged":
            seen["engaged"] += 1
            assert abs(y + w - loop.k * x) < 1e-12 and w == 0.5 * H * loop.key[1]
        else:
            seen["free"] += 1
            assert abs(w) == 0.5 * H or w == 0.0
    assert min(seen.values()) > 50
    plain, none = (StaticBacklashLoop(*LEAD, x0=0.3, compensation=c) for c in (None, BacklashInverse(0.0)))
    plain.advance(30.0)
    none.advance(30.0)
    assert plain.state() == none.state() and plain.events == none.events


# -- the truth: its hunting cycles, against long independent simulations --------------------------------------
@pytest.fixture(scope="module")
def found():
    return {h_hat: dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", exact=True, compensate="backlash-inverse",
                                     h_hat=h_hat) for h_hat in (H, 0.2)}


@pytest.mark.parametrize("h_hat, omega, amplitude", [(H, 1.175402538, 0.0233804351), (0.2, 1.716257481, 0.0112846222)])
def test_the_inverse_shrinks_the_hunting_but_does_not_stop_it(found, h_hat, omega, amplitude):
    """One stable cycle, checked against the reference run 200 s from x0 = 0.3: its period from the late upward
    engagements and its output's first harmonic over the last period (20000 samples) to 1e-6; its section
    state (just after an upward engagement) to 1e-8. Uncompensated the loop hunts at 0.107 m."""
    result = found[h_hat]
    cycles = result.cycles
    assert len(cycles) == 1 and cycles[0].stable and result.coverage.complete
    cycle = cycles[0]
    assert cycle.omega == pytest.approx(omega, rel=1e-8) and cycle.amplitude_x == pytest.approx(amplitude, rel=1e-8)
    ups = [t for t, kind in reference(h_hat, 200.0, params={"x0": 0.3})["events"] if kind == "engage+"]
    assert abs(ups[-1] - ups[-2] - cycle.period) < 1e-6 * cycle.period
    t1 = ups[-1]
    times = np.linspace(t1 - cycle.period, t1, 20001)
    ref = reference(h_hat, float(t1), params={"x0": 0.3}, t_eval=np.append(times, t1))
    y = ref["samples"][:-1, 2]
    first = 2.0 * abs(np.mean(y[:-1] * np.exp(-1j * cycle.omega * times[:-1])))
    assert abs(first - cycle.amplitude_x) < 1e-6 * cycle.amplitude_x
    on_section = ref["samples"][-1]  # the state at the engagement (y on the edge, z, no correction)
    assert np.allclose(on_section, cycle.state, rtol=0.0, atol=1e-8)


def test_a_cycle_is_reached_from_every_start_and_costs_a_standing_oscillation(found):
    result = found[H]
    assert result.coverage.outcomes == {"cycle": result.coverage.starts}
    assert result.cost.settling_time is None and result.cost.peak_force > 0.0
    text = str(result)
    assert "compensated by backlash-inverse (h_hat = 0.1)" in text and "1 true cycle" in text


# -- the DF: the static backlash seen through its inverse, in closed form -----------------------------------------
def _sampled_df(F, omega, h_hat, M=2.0, k=1.0, h=0.1, periods=4):
    """N of y + k h_hat/2 s from the exact plant's own harmonic integrals over its 4th period, the side s taken
    from its engagement events: int (y + w) exp(-i w t) = I_1 + sum of the side's pieces, each in closed form."""
    plant = StaticBacklash(M=M, k=k, h=h, F=F, omega=omega, harmonics=1)
    plant.event_log = []
    T = 2.0 * math.pi / omega
    t0, t1 = (periods - 1) * T, periods * T
    plant.advance(t0)
    first = plant.integrals()[1]
    plant.advance(t1)
    total = plant.integrals()[1] - first
    touches = [(t, 1 if kind is EventKind.ENGAGE_UP else -1) for t, kind in plant.event_log
               if kind in (EventKind.ENGAGE_UP, EventKind.ENGAGE_DOWN)]
    side = [s for t, s in touches if t <= t0][-1]
    edges = [t0] + [t for t, _s in touches if t0 < t < t1] + [t1]
    sides = [side] + [s for t, s in touches if t0 < t < t1]
    for a, b, s in zip(edges, edges[1:], sides):
        total += s * 0.5 * k * h_hat * 1j / omega * (cmath.exp(-1j * omega * b) - cmath.exp(-1j * omega * a))
    return 2.0 * total / (T * F)


@pytest.mark.parametrize("F, omega", [(50.0, 20.0), (1.0, 2.0), (3.0, 1.0), (0.3, 1.0)])
def test_the_closed_form_df_is_the_exact_plants_seen_through_the_inverse(F, omega):
    engine = InverseDFEngine(plant("static-backlash"))
    for h_hat in (0.0, 0.05, 0.1, 0.2):
        point = engine.point(F, omega, {"h_hat": h_hat})
        assert abs(point.N - _sampled_df(F, omega, h_hat)) < 1e-12 * abs(point.N)
    X = F / (2.0 * omega ** 2)  # without the inverse: the backlash's DF (Phillips and Harbor), the output's
    assert engine.point(F, omega, {"h_hat": 0.0}).N == pytest.approx(-complex(backlash_df(X)) / (2.0 * omega ** 2),
                                                                     rel=1e-14)
    assert engine.point(F, omega, {"h_hat": 0.1}).amplitude_x == pytest.approx(abs(complex(backlash_df(X))) * X,
                                                                              rel=1e-14)
    assert engine.point(0.1, 10.0, {"h_hat": 0.1}).N == 0  # X = 5e-4 m < h/2: the play never closes
    for params, message in [({"h_hat": -1.0}, "h_hat = -1.0 is out of range"),
                            ({"h_hat": 1.5}, "h_hat = 1.5 is out of range: the backlash inverse's estimate of the play "
                                             "h = 0.1 m, at most 10 times it"),
                            ({}, "h_hat: the backlash inverse's estimated play needs a value"),
                            ("h_hat", "params = 'h_hat' is not a mapping")]:
        with pytest.raises(PlantError, match=re.escape(message)):
            engine.point(1.0, 1.0, params)


def test_the_df_of_the_compensated_loop_finds_its_frequency(found):
    """At h_hat = h the DF's cycle is the true one's within 2 % in frequency (1.196 against 1.175 rad/s), 8 % in
    the force's first harmonic (the force on the plant, the correction's jumps included: 0.1991 N) and 30 % in
    amplitude (the output's, not what the controller sees)."""
    result = found[H]
    assert len(result.predictions) == 1 and result.links == [0]
    prediction, cycle = result.predictions[0], result.cycles[0]
    assert abs(prediction.omega / cycle.omega - 1.0) < 0.02 and prediction.stable
    assert 0.2 < prediction.amplitude_x / cycle.amplitude_x - 1.0 < 0.4
    assert cycle.F == pytest.approx(0.1990525491, rel=1e-8) and abs(prediction.F / cycle.F - 1.0) < 0.08
    assert "the play seen through the inverse, in closed form" in str(result)
    hunting = dfwb.hunting_map("static-backlash", "20*(s+a)/(s+20)", ("h_hat", 0.0, 0.2, 3), ("a", 1.0, 4.0, 2),
                               compensate="backlash-inverse", jobs=1, cache=False, curves=False)
    assert set(hunting.classes("truth").ravel()) == set(hunting.classes("df").ravel()) == {"stable"}


# -- the drivetrain: gear play with a sticking load ---------------------------------------------------------------
NAMES = {"gap 0": "lower", "gap h": "upper", "band": "stop", "release": "release", "break+": "breakaway",
         "break-": "breakaway"}  # dfwb's event kinds -> the drivetrain reference's


@pytest.mark.parametrize("h_hat, x1_0", [(0.1, 0.1302), (0.05, 0.03)])
def test_the_drivetrain_with_its_load_friction_follows_its_reference(h_hat, x1_0):
    """With the load's friction (B, Fc, Fs of the defaults) against tests/drivetrain_reference.py (its own
    scipy walk, the inverse's correction set at each wall): the same events, within 1e-9 s, and states."""
    G = ([200.0, 400.0], [20.0])
    loop = DrivetrainLoop(*G, x1_0=x1_0, compensation=BacklashInverse(h_hat))
    loop.event_log = []
    times = np.linspace(0.0, 10.0, 21)
    states = loop.sample(list(times))
    _t, ref, events = simulate(10.0, b=G[0], a=G[1], x1_0=x1_0, times=times, inverse=h_hat)
    assert [NAMES[str(kind)] for _t, kind in loop.event_log] == [kind for _t, kind in events]
    assert len(events) > 50 and max(abs(t - u) for (t, _), (u, _) in zip(loop.event_log, events)) < 1e-9
    assert np.allclose(states, ref, rtol=0.0, atol=1e-9)


def test_on_the_drivetrain_the_inverse_makes_the_hunting():
    """Under 200 (s + 2)/(s + 20) the drivetrain rests from every start (standing error 0.027 m); with the
    inverse at h_hat = h its motor rattles across the play and the load with it: a stable cycle of 0.246 s,
    by impacts alone (the load never stops: found on the drivetrain's second section, M2's walls). The
    reference, run 30 s from the step's start, has the same period between its last upward impacts."""
    G = "200*(s+2)/(s+20)"
    plain = dfwb.limit_cycles("drivetrain", G, exact=True, compensate="backlash-inverse", h_hat=0.0)
    assert plain.coverage.outcomes == {"rest": plain.coverage.starts} and not plain.cycles
    result = dfwb.limit_cycles("drivetrain", G, exact=True, compensate="backlash-inverse", h_hat=0.1)
    [cycle] = result.cycles
    assert cycle.stable and cycle.section == 1 and cycle.period == pytest.approx(0.2461558371, rel=1e-8)
    _t, _ref, events = simulate(30.0, b=[200.0, 400.0], a=[20.0], x1_0=0.1302, times=[0.0], inverse=0.1)
    ups = [t for t, kind in events if kind == "upper"]
    assert abs(ups[-1] - ups[-2] - cycle.period) < 1e-6 * cycle.period
