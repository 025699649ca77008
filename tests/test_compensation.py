"""Compensators in the exact closed loop (issue 33): the Coulomb feedforward, against an independent reference.

The reference is :func:`dfwb.plants.loop_reference.closed_loop_reference` with its own Coulomb feedforward
(solve_ivp between events, the switching written apart from dfwb's loop); the friction mass under PI,
``G = 10 + 2/s``, which hunts uncompensated (Olsson and Astrom, 2001: an integrator and stiction), from a
displaced start.
"""

import math

import pytest

from dfwb.fmus.compensation import Coulomb, Deadband
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop
from dfwb.fmus.loops import STICK
from dfwb.plants.loop_reference import closed_loop_reference

PI = ([10.0, 2.0], [0.0])  # 10 + 2/s
START = {"x0": 0.3}
T = 60.0


def run(compensation, T=T, **params):
    loop = FrictionLoop(*PI, **dict(START, **params), compensation=compensation)
    loop.event_log = []
    loop.advance(T)
    return loop


@pytest.mark.parametrize("F_hat, signal", [(3.0, "velocity"), (5.0, "velocity"), (8.0, "velocity"),
                                           (3.0, "control"), (6.0, "control")])
def test_the_compensated_loop_is_the_reference_event_for_event(F_hat, signal):
    """Under-, exact and over-compensation of Fc = 5 N by the velocity's sign; the controller's sign below Fs -
    Fc and beyond it: the same events in the same order, their times within 1e-9 s, the state at 60 s within
    1e-8 (the reference's tolerance, rtol 1e-12, over up to 61 events)."""
    loop = run(Coulomb(F_hat, signal))
    ref = closed_loop_reference("friction", *PI, T, START, coulomb=(F_hat, signal), max_events=10_000)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert len(loop.event_log) >= 10
    assert max(abs(t - r) for (t, _), (r, _) in zip(loop.event_log, ref["events"])) < 1e-9
    assert max(abs(x - r) for x, r in zip(loop.state(), ref["state"])) < 1e-8
    if signal == "control":
        assert "coulomb" in [str(kind) for _t, kind in loop.event_log]


def test_no_feedforward_is_the_uncompensated_loop_bit_for_bit():
    plain = FrictionLoop(*PI, **START)
    plain.event_log = []
    plain.advance(T)
    for signal in ("velocity", "control"):
        loop = run(Coulomb(0.0, signal))
        assert loop.state() == plain.state() and loop.event_log == plain.event_log


def test_the_velocitys_feedforward_is_a_lower_coulomb_level():
    """F_hat sgn(v) added to the force is Fc - F_hat in every slide, and nothing at rest: the loop with Fc = 5,
    F_hat = 2 is the loop with Fc = 3 (M = 1: the same numbers to the bit)."""
    loop = run(Coulomb(2.0, "velocity"))
    lower = FrictionLoop(*PI, **START, Fc=3.0)
    lower.event_log = []
    lower.advance(T)
    assert loop.state() == lower.state() and loop.event_log == lower.event_log


def test_the_controllers_feedforward_acts_on_a_stuck_mass():
    """At rest at x0 = 0.3 the controller pushes f = -3 N: with the feedforward of its sign, -3 - 5 = -8 N is
    beyond Fs = 7 N and the mass breaks away at once; without it, it stays stuck until the integrator has wound
    up (t = 2 s)."""
    loop = FrictionLoop(*PI, **START, compensation=Coulomb(5.0, "control"))
    assert loop.key == ("slide", -1) and loop.sigma == -1
    assert FrictionLoop(*PI, **START).key == STICK


@pytest.mark.parametrize("make, message", [
    (lambda: Coulomb(-1.0), "F_hat = -1.0 is out of range"),
    (lambda: Coulomb(math.nan), "F_hat = nan is out of range"),
    (lambda: Coulomb(True), "F_hat = True is out of range"),
    (lambda: Coulomb(1.0, "position"), "signal = 'position' is not a signal"),
    (lambda: Coulomb(10 ** 400), "F_hat = 1000.* is out of range"),
    (lambda: Deadband(-0.1), "d = -0.1 is out of range"),
    (lambda: Deadband(10 ** 400), "d = 1000.* is out of range"),
    (lambda: FrictionLoop(*PI, compensation="coulomb"), "is not a compensator of the loop"),
])
def test_a_bad_compensator_is_one_line(make, message):
    with pytest.raises(PlantError, match=message):
        make()


def test_the_velocitys_feedforward_needs_friction():
    from dfwb.fmus.backlash import BacklashLoop

    with pytest.raises(PlantError, match="needs a plant with friction"):
        BacklashLoop([200.0, 400.0], [20.0], compensation=Coulomb(1.0, "velocity"))
    BacklashLoop([200.0, 400.0], [20.0], compensation=Coulomb(1.0, "control")).advance(1.0)


def test_a_velocity_feedforward_finds_the_cycles_of_the_lower_coulomb_level():
    """The systematic search over the compensated loop (the Python loop) finds what it finds over the friction
    mass with Fc - F_hat (the compiled loop): the same cycle to the bit."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem

    compensated = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Coulomb(2.0, "velocity"))).cycles
    lower = find_cycles(LoopProblem("friction", "10 + 2/s", {"Fc": 3.0})).cycles
    assert [(c.period, c.amplitude_x, c.stable) for c in compensated] == \
        [(c.period, c.amplitude_x, c.stable) for c in lower]
    assert len(lower) == 1 and lower[0].stable


@pytest.mark.parametrize("F_hat", [1.0, 3.0])
def test_the_controllers_feedforward_hunts_on_a_cycle_the_reference_confirms(F_hat):
    """Under 10 + 2/s the mass hunts with the feedforward of the controller's sign too, faster (57.3 s
    uncompensated; 46.5 s at F_hat = 1 N, 25.0 s at 3 N) at about the same amplitude. The reference,
    started on the cycle's section state, returns to it after one period: time and state within 1e-7."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem

    cycles = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Coulomb(F_hat, "control"))).cycles
    assert len(cycles) == 1 and cycles[0].stable
    cycle = cycles[0]
    assert cycle.period < 50.0 and 0.2 < cycle.amplitude_x < 0.3
    armed = []

    def stop(kind, before):  # the section: x at a minimum (band from slide-), then at a maximum (from slide+)
        armed.append(kind == "band" and before == "slide-")
        return any(armed) and kind == "band" and before == "slide+"

    ref = closed_loop_reference("friction", *PI, 10 * cycle.period, state=cycle.state, coulomb=(F_hat, "control"),
                                until=stop, max_events=10_000)
    assert abs(ref["t"] - cycle.period) < 1e-7 * cycle.period
    swing = [max(s, 1e-12) for s in cycle.swing]
    assert max(abs(x - y) / s for x, y, s in zip(ref["state"], cycle.state, swing)) < 1e-7


def pid(Kp, Ki, Kd, Tf):
    """Kp + Ki/s + Kd s/(Tf s + 1) as (b, a)."""
    return [(Kp * Tf + Kd) / Tf, (Kp + Ki * Tf) / Tf, Ki / Tf], [1.0 / Tf, 0.0]


@pytest.mark.parametrize("b, a", [PI, ([30.0, 20.0], [0.0]), pid(20.0, 10.0, 2.0, 0.1)], ids=["PI", "stiff PI", "PID"])
@pytest.mark.parametrize("coulomb", [None, (3.0, "control")])
def test_the_integrator_reset_is_the_reference_event_for_event(b, a, coulomb):
    """The reset clears the integrator's mode of the controller (dfwb: its closed form in the canonical
    coordinates; the reference: the null spaces of Ac, numerically) each time the mass comes to rest, before it
    sticks or breaks away; with the controller's feedforward, its sign follows the force's jump."""
    from dfwb.fmus.compensation import Reset

    compensation = Reset() if coulomb is None else [Reset(), Coulomb(*coulomb)]
    loop = FrictionLoop(b, a, **START, compensation=compensation)
    loop.event_log = []
    loop.advance(T)
    ref = closed_loop_reference("friction", b, a, T, START, coulomb=coulomb, reset=True, max_events=10_000)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert max(abs(t - r) for (t, _), (r, _) in zip(loop.event_log, ref["events"])) < 1e-8
    assert max(abs(x - r) for x, r in zip(loop.state(), ref["state"])) < 1e-8


def test_a_reset_integrator_still_hunts_twice_as_fast():
    """Under 10 + 2/s the reset at rest does not stop the hunting: the stuck mass's integrator winds up again from
    0, so it breaks away sooner (period 29.6 s against 57.3 s) at the same amplitude. The reference confirms the
    cycle: from its section state it returns there after one period, within 1e-7."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem
    from dfwb.fmus.compensation import Reset

    cycles = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Reset())).cycles
    assert len(cycles) == 1 and cycles[0].stable
    cycle = cycles[0]
    assert abs(cycle.period - 29.64) < 0.01 and abs(cycle.amplitude_x - 0.2365) < 1e-3
    armed = []

    def stop(kind, before):
        armed.append(kind == "band" and before == "slide-")
        return any(armed) and kind == "band" and before == "slide+"

    ref = closed_loop_reference("friction", *PI, 10 * cycle.period, state=cycle.state, reset=True, until=stop,
                                max_events=10_000)
    assert abs(ref["t"] - cycle.period) < 1e-7 * cycle.period
    assert max(abs(x - y) / max(s, 1e-12) for x, y, s in zip(ref["state"], cycle.state, cycle.swing)) < 1e-7


@pytest.mark.parametrize("a", [[1.0], [0.0, 0.0], [2.0, 1.0, 0.0, 0.0]])
def test_the_reset_needs_one_integrator(a):
    from dfwb.fmus.compensation import Reset

    with pytest.raises(PlantError, match="needs a controller with one integrator"):
        FrictionLoop([1.0] * (len(a) + 1), a, compensation=Reset())


def test_the_reset_needs_a_plant_that_comes_to_rest_and_each_compensator_once():
    from dfwb.fmus.backlash import BacklashLoop
    from dfwb.fmus.compensation import Reset

    with pytest.raises(PlantError, match="needs a plant that comes to rest"):
        BacklashLoop([200.0, 400.0], [0.0], compensation=Reset())
    with pytest.raises(PlantError, match="each once"):
        FrictionLoop(*PI, compensation=[Reset(), Reset()])


@pytest.mark.parametrize("b, a", [PI, ([30.0, 20.0], [0.0]), pid(20.0, 10.0, 2.0, 0.1)], ids=["PI", "stiff PI", "PID"])
@pytest.mark.parametrize("d", [0.05, 0.2])
@pytest.mark.parametrize("reset", [False, True])
def test_the_integrator_deadband_is_the_reference_event_for_event(b, a, d, reset):
    """Within |y| < d the integrator's mode holds (dfwb: Bc - e_1 / w_1; the reference: Bc minus the null vector
    of Ac, numerically), the controller's other modes go on; the edges are events of the loop."""
    from dfwb.fmus.compensation import Deadband, Reset

    loop = FrictionLoop(b, a, **START, compensation=[Deadband(d), Reset()] if reset else Deadband(d))
    loop.event_log = []
    loop.advance(100.0)
    ref = closed_loop_reference("friction", b, a, 100.0, START, deadband=d, reset=reset, max_events=10_000)
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert max((abs(t - r) for (t, _), (r, _) in zip(loop.event_log, ref["events"])), default=0.0) < 1e-8
    assert max(abs(x - r) for x, r in zip(loop.state(), ref["state"])) < 1e-8


def test_a_wide_enough_deadband_stops_the_hunting_at_a_standing_error_below_it():
    """Under 10 + 2/s a deadband of 0.05 m leaves the hunting as it was (period 57.3 s, from 22 of the 36 starts;
    the others come to rest within the band); one of 0.2 m stops it: no cycle from any of the 36 starts (output
    amplitudes 0.007 to 70 m). The absence is checked by the reference from five starts, 0.3 to 10 m and -2 m:
    each comes to rest within the band within 15 s and stays there, no event, to 2000 s."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem
    from dfwb.fmus.compensation import Deadband

    narrow = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Deadband(0.05)))
    assert [round(c.period, 1) for c in narrow.cycles] == [57.3] and narrow.coverage.outcomes["rest"] > 0
    wide = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Deadband(0.2)))
    assert wide.cycles == [] and wide.coverage.outcomes == {"rest": 36}
    for x0 in (0.3, 1.0, 3.0, -2.0, 10.0):
        r = closed_loop_reference("friction", *PI, 2000.0, {"x0": x0}, deadband=0.2, max_events=10_000)
        assert r["mode"] == "stick" and r["events"][-1][0] < 15.0 and abs(r["state"][0]) < 0.2
