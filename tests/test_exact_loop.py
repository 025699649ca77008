"""The exact closed loops (dfwb.fmus.loops) against an independent solve_ivp reference, and their guarantees.

``dfwb.fmus.loops`` walks a plant in feedback with -G(s) piece by piece with
Taylor series and a certified root search; ``dfwb.plants.loop_reference``
integrates the same physics with ``solve_ivp`` (DOP853, rtol = 1e-12) and
terminal events. They share only the controller's matrices, so agreement on
the event sequence, the event times and the final state checks both.

Measured agreement (the cases of ``AGREEMENT``, 11 to 203 events each):
event times within 1.4e-11 s, 5.1e-12 relative to max(1, t); final states
within 1.5e-11 of the state's largest component. The tolerances below (1e-10
and 1e-9) keep a margin of about 20 and 65 over that.

Then the exact solver's own promises: bit-identical results for any
communication step, its invariants (play, gap, exact stick, momentum across
impacts), and PlantError naming the value for every input it cannot take.
The regressions of defects found this way are named after what they check.
"""

import math
import re

import numpy as np
import pytest

from dfwb.base.errors import RunError
from dfwb.fmus.backlash import BacklashLoop
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop
from dfwb.fmus.loops import STICK
from dfwb.fmus.static_backlash import StaticBacklashLoop
from dfwb.plants.loop_reference import closed_loop_reference

TIME_TOL = 1e-10  # |t_exact - t_reference| <= TIME_TOL * max(1, t)
STATE_TOL = 1e-9  # |X_exact - X_reference| <= STATE_TOL * max |X_exact|

PID = ([40.0, 300.0, 1000.0], [10.0, 0.0])  # 20 + 100/s + 2s/(0.1s + 1)
PI = ([30.0, 60.0], [0.0])  # 30 + 60/s
LEAD = ([200.0, 400.0], [20.0])  # 200 (s + 2)/(s + 20)
LEAD_LOW = ([20.0, 40.0], [20.0])  # 20 (s + 2)/(s + 20)
THIRD = ([0.0, 0.0, 0.0, 200.0], [3.0, 3.0, 1.0])  # 200/(s + 1)^3
CLASSES = {"friction": FrictionLoop, "backlash": BacklashLoop, "static-backlash": StaticBacklashLoop}

AGREEMENT = {
    "friction PID": ("friction", PID, {"x0": 0.3}, 20.0),
    "friction PI": ("friction", PI, {"x0": 0.3}, 20.0),
    "friction third order": ("friction", THIRD, {"x0": 0.3}, 20.0),
    "backlash lead eps 0.2": ("backlash", LEAD, {"eps": 0.2, "x1_0": 0.03}, 10.0),
    "backlash lead eps 0.8": ("backlash", LEAD, {"eps": 0.8, "x1_0": 0.03}, 10.0),
    # impacts accumulating into contact and releases (the Zeno rule)
    "backlash PID eps 0.8": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, 5.0),
    "backlash PID eps 0 (plastic)": ("backlash", PID, {"eps": 0.0, "x1_0": 0.03}, 10.0),
    "static backlash lead": ("static-backlash", LEAD_LOW, {"x0": 0.3}, 20.0),
    "static backlash PI": ("static-backlash", PI, {"x0": 0.3}, 20.0),
}


def exact_run(plant, G, params, t_end, steps=None):
    """The exact loop advanced to t_end (in one call, or through the communication points ``steps``)."""
    loop = CLASSES[plant](b=G[0], a=G[1], **params)
    loop.event_log = []
    for t in steps or (t_end,):
        loop.advance(t)
    return loop


def grid(t_end, dt):
    """Communication points dt, 2 dt, ... ending exactly at t_end."""
    count = math.ceil(t_end / dt)
    return [min(k * dt, t_end) for k in range(1, count + 1)]


@pytest.mark.parametrize("case", AGREEMENT)
def test_exact_loop_agrees_with_the_reference(case):
    plant, G, params, t_end = AGREEMENT[case]
    loop = exact_run(plant, G, params, t_end)
    ref = closed_loop_reference(plant, G[0], G[1], t_end, params)
    kinds = [str(kind) for _t, kind in loop.event_log]
    assert kinds == [kind for _t, kind in ref["events"]]
    assert len(kinds) >= 10  # the case exercises the switching
    t_exact = np.array([t for t, _kind in loop.event_log])
    t_ref = np.array([t for t, _kind in ref["events"]])
    assert np.max(np.abs(t_exact - t_ref) / np.maximum(1.0, t_exact)) <= TIME_TOL
    X, X_ref = np.array(loop.state()), np.array(ref["state"])
    assert np.max(np.abs(X - X_ref)) <= STATE_TOL * np.max(np.abs(X))
    assert ref["counts"] == loop.counts()


def test_release_is_not_followed_by_a_phantom_contact():
    G = ([0.0, 50.0], [1.0])  # 50/(s + 1): f = -50 z1 alone
    loop = exact_run("backlash", G, {"eps": 0.2, "x1_0": 0.03}, 3.0)
    ref = closed_loop_reference("backlash", G[0], G[1], 3.0, {"eps": 0.2, "x1_0": 0.03})
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]


@pytest.mark.parametrize("cls, state", [(BacklashLoop, [0.0, 0.0, 0.0, 0.0, 0.0]),
                                        (StaticBacklashLoop, [0.05, 0.0, 0.0, 0.0])])
def test_rest_on_a_boundary_has_no_events(cls, state):
    loop = cls(b=LEAD[0], a=LEAD[1], state=state)
    loop.event_log = []
    loop.advance(2.0)
    assert loop.state() == state
    assert loop.event_log == []


def test_reference_rest_on_a_boundary_has_no_events():
    for plant, state in (("backlash", [0.0] * 5), ("static-backlash", [0.05, 0.0, 0.0, 0.0])):
        ref = closed_loop_reference(plant, LEAD[0], LEAD[1], 2.0, state=state)
        assert ref["events"] == [] and ref["state"] == state


# -- communication-step independence ------------------------------------------------------------------

STEPPED = {
    "friction PID": ("friction", PID, {"x0": 0.3}, 20.0),
    "backlash lead eps 0.8": ("backlash", LEAD, {"eps": 0.8, "x1_0": 0.03}, 20.0),
    "backlash PID eps 0.8": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, 5.0),
    "static backlash lead": ("static-backlash", LEAD_LOW, {"x0": 0.3}, 20.0),
}


@pytest.mark.parametrize("case", STEPPED)
def test_any_communication_step_gives_identical_results(case):
    plant, G, params, t_end = STEPPED[case]
    whole = exact_run(plant, G, params, t_end)
    for dt in (0.1, 0.0137, 1e-3):
        stepped = exact_run(plant, G, params, t_end, grid(t_end, dt))
        assert stepped.t == t_end
        assert stepped.state() == whole.state()  # bit for bit
        assert stepped.event_log == whole.event_log
        assert stepped.events == whole.events


# -- invariants ----------------------------------------------------------------------------------------------

def sampled(loop, t_end, count=2001):
    """(t, state, mode key) at ``count`` times in [0, t_end] (not on the communication grid of any event)."""
    out = []
    for t in np.linspace(0.0, t_end, count)[1:]:
        loop.advance(float(t))
        out.append((float(t), loop.state(), loop.key))
    return out


def test_static_backlash_keeps_the_play():
    loop = StaticBacklashLoop(b=LEAD_LOW[0], a=LEAD_LOW[1], x0=0.3)
    loop.event_log = []
    engaged = 0
    for _t, (x, _v, y, *_z), key in sampled(loop, 20.0):
        assert abs(x - y / loop.k) <= 0.5 * loop.h * (1.0 + 1e-12)
        engaged += key != ("free", 0)
    assert engaged and len(loop.event_log) >= 10


@pytest.mark.parametrize("G, eps", [(LEAD, 0.2), (LEAD, 0.8), (PID, 0.8), (PID, 0.0)])
def test_backlash_gap_stays_in_the_clearance(G, eps):
    loop = BacklashLoop(b=G[0], a=G[1], eps=eps, x1_0=0.03)
    loop.event_log = []
    for _t, (_x1, _v1, gap, _w, *_z), _key in sampled(loop, 5.0):
        assert 0.0 <= gap <= loop.h
    assert loop.impacts >= 5


def test_friction_sticks_with_v_exactly_zero():
    loop = FrictionLoop(b=PID[0], a=PID[1], x0=0.3)
    loop.event_log = []
    stuck, held = 0, {}
    for t in np.linspace(0.0, 20.0, 4001)[1:]:
        loop.advance(float(t))
        x, v, *_z = loop.state()
        if loop.key == STICK:
            stuck += 1
            assert v == 0.0
            # x does not move while stuck: one value through the whole stick phase (from its "band" event)
            phase = max(t for t, kind in loop.event_log if str(kind) == "band")
            assert held.setdefault(phase, x) == x
        else:
            assert v != 0.0 or str(loop.event_log[-1][1]).startswith("break")
    assert stuck >= 100 and len(held) >= 10
    # stick phases are the spans from a "band" (v reaching 0) to the next "break": v is 0 inside them
    log = loop.event_log
    phases = [(t0, t1) for (t0, k0), (t1, k1) in zip(log, log[1:]) if str(k0) == "band" and str(k1) != "band"]
    assert len(phases) == loop.sticks >= 10
    probe = FrictionLoop(b=PID[0], a=PID[1], x0=0.3)
    for t0, t1 in phases:
        probe.advance(t0 + 0.5 * (t1 - t0))
        assert probe.state()[1] == 0.0 and probe.key == STICK


def momentum(loop, X):
    """M1 v1 + M2 v2 of the backlash loop's state."""
    return (loop.M1 + loop.M2) * X[1] + loop.M2 * X[3]


def test_momentum_is_kept_by_impacts_without_force():
    # G = 0: no force, the two masses bounce between the walls with momentum M2 v2_0 for ever
    loop = BacklashLoop(b=[0.0, 0.0], a=[1.0], M1=1.0, M2=3.0, eps=0.9, v2_0=1.0)
    loop.event_log = []
    P0 = momentum(loop, loop.state())
    for _t, X, _key in sampled(loop, 5.0, 501):
        assert momentum(loop, X) == pytest.approx(P0, rel=1e-14, abs=0.0)
        assert 0.0 <= X[2] <= loop.h
    assert loop.impacts >= 10


def test_impacts_carry_no_impulse_in_feedback():
    # with the controller on, P' = f: across an impact the momentum moves by f dt only, w by (1 + eps) |w|
    G, eps = LEAD, 0.8
    whole = exact_run("backlash", G, {"eps": eps, "x1_0": 0.03}, 3.0)
    impacts = [t for t, kind in whole.event_log if str(kind).startswith("gap")][:8]
    assert len(impacts) == 8
    dt = 1e-9
    for t in impacts:
        loop = BacklashLoop(b=G[0], a=G[1], eps=eps, x1_0=0.03)
        loop.advance(t - dt)
        before = loop.state()
        loop.advance(t)
        after = loop.state()
        w, f = before[3], loop.force(before)
        assert after[3] == pytest.approx(-eps * w, rel=1e-6)
        assert abs(momentum(loop, after) - momentum(loop, before)) <= 2.0 * abs(f) * dt + 1e-14


# -- hostile inputs --------------------------------------------------------------------------------------

def raises_naming(text, make):
    """``make()`` raises PlantError whose message names ``text``."""
    with pytest.raises(PlantError, match=re.escape(text)):
        make()


@pytest.mark.parametrize("b, a, text", [
    ([1.0], [], "order = 0 "),
    ([1.0] * 10, [1.0] * 9, "order = 9 "),
    ([1.0, 2.0, 3.0], [1.0], "number of numerator coefficients = 3 "),
    ([1.0], [1.0], "number of numerator coefficients = 1 "),
    ([1.0, math.nan], [1.0], "b1 = nan "),
    ([1.0, 2.0], [math.inf], "a1 = inf "),
    ([1.0, 2.0, 3.0], [1.0, -math.inf], "a2 = -inf "),
])
@pytest.mark.parametrize("cls", [FrictionLoop, BacklashLoop, StaticBacklashLoop])
def test_bad_controllers_are_refused(cls, b, a, text):
    raises_naming(text, lambda: cls(b=b, a=a))
    plant = {FrictionLoop: "friction", BacklashLoop: "backlash", StaticBacklashLoop: "static-backlash"}[cls]
    raises_naming(text, lambda: closed_loop_reference(plant, b, a, 1.0))


@pytest.mark.parametrize("Dv", [0.01, -1e-9, math.nan])
def test_friction_needs_exact_stick(Dv):
    raises_naming(f"Dv = {Dv!r} ", lambda: FrictionLoop(b=PID[0], a=PID[1], Dv=Dv))
    raises_naming(f"Dv = {Dv!r} ", lambda: closed_loop_reference("friction", PID[0], PID[1], 1.0, {"Dv": Dv}))


@pytest.mark.parametrize("cls, state, text", [
    (FrictionLoop, [0.0, 0.0], "length of state = 2 "),
    (FrictionLoop, [0.0, 0.0, 0.0, 0.0], "length of state = 4 "),
    (FrictionLoop, [0.0, math.nan, 0.0], "v = nan "),
    (FrictionLoop, [0.0, 0.0, math.inf], "z1_0 = inf "),
    (BacklashLoop, [0.0, 0.0, 0.05, 0.0, 0.0, 0.0], "length of state = 6 "),
    (BacklashLoop, [math.nan, 0.0, 0.05, 0.0, 0.0], "x1 = nan "),
    (BacklashLoop, [0.0, 0.0, 0.05, 0.0, math.nan], "z1_0 = nan "),
    (BacklashLoop, [0.0, 0.0, 0.2, 0.0, 0.0], "gap = 0.2 "),
    (BacklashLoop, [0.0, 0.0, -0.01, 0.0, 0.0], "gap = -0.01 "),
    (BacklashLoop, [0.0, 0.0, math.nan, 0.0, 0.0], "gap = nan "),
    (StaticBacklashLoop, [0.0, 0.0, 0.0, 0.0, 0.0], "length of state = 5 "),
    (StaticBacklashLoop, [0.0, math.nan, 0.0, 0.0], "v = nan "),
    (StaticBacklashLoop, [0.2, 0.0, 0.0, 0.0], "x - y/k = 0.2 "),
])
def test_bad_states_are_refused(cls, state, text):
    raises_naming(text, lambda: cls(b=LEAD[0], a=LEAD[1], state=state))


@pytest.mark.parametrize("cls", [BacklashLoop, StaticBacklashLoop])
def test_short_states_are_refused(cls):
    raises_naming("length of state = 2 ", lambda: cls(b=LEAD[0], a=LEAD[1], state=[0.0, 0.0]))


@pytest.mark.parametrize("gap0", [0.2, -0.01, math.nan])
def test_gap_outside_the_clearance_is_refused(gap0):
    raises_naming(f"gap0 = {gap0!r} ", lambda: BacklashLoop(b=LEAD[0], a=LEAD[1], gap0=gap0))
    raises_naming(f"gap0 = {gap0!r} ",
                  lambda: closed_loop_reference("backlash", LEAD[0], LEAD[1], 1.0, {"gap0": gap0}))


@pytest.mark.parametrize("t_end", [math.nan, -1.0, math.inf, 0.5])
def test_bad_end_times_are_refused(t_end):
    loop = FrictionLoop(b=PID[0], a=PID[1], x0=0.3)
    loop.advance(1.0)
    raises_naming(f"t_end = {t_end!r} ", lambda: loop.advance(t_end))
    assert loop.t == 1.0


@pytest.mark.parametrize("t_end", [math.nan, -1.0, math.inf])
def test_reference_refuses_bad_end_times(t_end):
    raises_naming(f"t_end = {t_end!r} ", lambda: closed_loop_reference("friction", PID[0], PID[1], t_end))


def test_reference_refuses_what_it_cannot_simulate():
    raises_naming("plant = 'gearbox' ", lambda: closed_loop_reference("gearbox", PID[0], PID[1], 1.0))
    raises_naming("'Fs2' is not a parameter", lambda: closed_loop_reference("friction", PID[0], PID[1], 1.0,
                                                                           {"Fs2": 1.0}))
    raises_naming("length of state = 3 ", lambda: closed_loop_reference("friction", PID[0], PID[1], 1.0,
                                                                       state=[0.0, 0.0, 0.0]))
    raises_naming("gap = 0.2 ", lambda: closed_loop_reference("backlash", LEAD[0], LEAD[1], 1.0,
                                                             state=[0.0, 0.0, 0.2, 0.0, 0.0]))
    with pytest.raises(RunError, match="more than 3 events"):
        closed_loop_reference("friction", PID[0], PID[1], 20.0, {"x0": 0.3}, max_events=3)
