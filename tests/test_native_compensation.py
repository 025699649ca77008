"""The compensators in the compiled loop (fmus/native loops.c) against the Python loop (fmus/loops.py), bit for bit.

The C core runs the Coulomb feedforward of the velocity, the integrator reset at rest, the integrator
deadband and the dither (its oscillator two more coordinates of the solver's state) as the Python loop does (same modes, events, operation order); the feedforward of the controller's
sign stays Python's alone, and the C loop refuses it in one line. On loops that hunt, stick, cross the
deadband's edges and reset, both give the same event sequences, states, deadband sides, crossings, cycles,
step costs and work; every refusal is the same text; a compensated loop's state as bytes reads back and goes
on bit for bit, and crafted compensator fields are refused in one line.
"""

import math
import re
import struct

import pytest
from native_fmu_helpers import HEADER, with_crc
from test_native_loop import LEAD, PI, PID, refusal

from dfwb.engine.cost import step_cost
from dfwb.engine.cycles import find_cycles
from dfwb.engine.dither import find_responses
from dfwb.engine.periodic import LoopProblem
from dfwb.fmus.backlash import BacklashLoop
from dfwb.fmus.compensation import BacklashInverse, Coulomb, Deadband, Dither, Reset
from dfwb.fmus.drivetrain import DrivetrainLoop
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop
from dfwb.fmus.hybrid import Budget
from dfwb.fmus.native_core import NativeMode
from dfwb.fmus.state import StateRefused
from dfwb.fmus.static_backlash import StaticBacklashLoop
from dfwb.fmus.stribeck import StribeckLoop

pytestmark = pytest.mark.needs_cc

HUNTS = ([10.0, 2.0], [0.0])  # 10 + 2/s: the friction mass hunts (period 57 s)
LEAD_PI = ([20.0, 40.0, 10.0], [20.0, 0.0])  # (20 s^2 + 40 s + 10) / (s (s + 20))
LEAD_20 = ([20.0, 40.0], [20.0])  # 20 (s + 2)/(s + 20): the static backlash hunts (period 7.0 s)
PYTHON = {"friction": FrictionLoop, "backlash": BacklashLoop, "static-backlash": StaticBacklashLoop,
          "stribeck": StribeckLoop, "drivetrain": DrivetrainLoop}
NATIVE = {"friction": "FrictionLoop", "backlash": "BacklashLoop", "static-backlash": "StaticBacklashLoop",
          "stribeck": "StribeckLoop", "drivetrain": "DrivetrainLoop"}

CASES = {  # (plant, G, parameters, compensation, t_end): every compensator, each kind of event
    "deadband holds": ("friction", HUNTS, {"x0": 0.7}, Deadband(0.2), 200.0),
    "deadband crossed": ("friction", HUNTS, {"x0": 0.7}, Deadband(0.05), 300.0),
    "reset": ("friction", HUNTS, {"x0": 0.7}, Reset(), 300.0),
    "under-compensation": ("friction", HUNTS, {"x0": 0.7}, Coulomb(1.0), 300.0),
    "over-compensation": ("friction", HUNTS, {"x0": 0.7}, Coulomb(3.0), 300.0),
    "all three, PID": ("friction", PID, {"x0": 0.3}, [Coulomb(1.5), Reset(), Deadband(0.01)], 20.0),
    "controller's sign at 0": ("friction", HUNTS, {"x0": 0.7}, Coulomb(0.0, "control"), 200.0),
    "deadband 0 (none)": ("friction", HUNTS, {"x0": 0.7}, Deadband(0.0), 200.0),
    "deadband below y's rounding": ("friction", PID, {"x0": 0.3}, Deadband(1e-300), 20.0),
    "backlash deadband": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, Deadband(0.004), 5.0),
    "static backlash deadband": ("static-backlash", LEAD_PI, {"x0": 0.3}, Deadband(0.05), 20.0),
    "stribeck, all three": ("stribeck", HUNTS, {"x0": 0.7}, [Coulomb(1.0), Reset(), Deadband(0.05)], 100.0),
    "dither beyond Fs": ("friction", HUNTS, {"x0": 0.7}, Dither(10.0, 5.0), 100.0),
    "dither grazing Fs": ("friction", HUNTS, {"x0": -0.7}, Dither(3.0, 20.0), 100.0),
    "dither, deadband, feedforward": ("friction", HUNTS, {"x0": 0.7}, [Coulomb(1.0), Deadband(0.05),
                                                                        Dither(2.0, 3.0)], 200.0),
    "backlash dither": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, Dither(0.5, 40.0), 5.0),
    "static backlash dither": ("static-backlash", LEAD_PI, {"x0": 0.3}, Dither(0.2, 10.0), 20.0),
    "stribeck dither": ("stribeck", HUNTS, {"x0": 0.7}, Dither(3.0, 10.0), 100.0),
    "dither of 0 (none)": ("friction", HUNTS, {"x0": 0.7}, Dither(0.0, 10.0), 100.0),
    "backlash inverse": ("static-backlash", LEAD_20, {"x0": 0.3}, BacklashInverse(0.1), 60.0),
    "backlash inverse over": ("static-backlash", LEAD_20, {"x0": -0.3}, BacklashInverse(0.2), 60.0),
    "backlash inverse, deadband, dither": ("static-backlash", LEAD_PI, {"x0": 0.3},
                                           [BacklashInverse(0.05), Deadband(0.05), Dither(0.2, 10.0)], 20.0),
    "backlash inverse of 0 (none)": ("static-backlash", LEAD_20, {"x0": 0.3}, BacklashInverse(0.0), 60.0),
    "backlash inverse, impacts": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, BacklashInverse(0.1), 5.0),
    "backlash inverse, plastic": ("backlash", LEAD, {"eps": 0.0, "x1_0": 0.03}, BacklashInverse(0.05), 5.0),
    "backlash inverse on a wall at t = 0": ("backlash", PID, {"gap0": 0.1, "x1_0": 0.03},
                                            [BacklashInverse(0.1), Deadband(0.01)], 5.0),
    "drivetrain backlash inverse": ("drivetrain", PID, {"x1_0": 0.03}, BacklashInverse(0.1), 5.0),
}


def pair(core, case, **kw):
    plant, G, params, compensation, _t_end = CASES[case]
    loops = tuple(cls(G[0], G[1], **params, compensation=compensation, **kw)
                  for cls in (PYTHON[plant], getattr(core, NATIVE[plant])))
    for loop in loops:
        loop.event_log = []
    return loops


def same(py, c):
    assert c.t == py.t and c.state() == py.state() and c.key == py.key and c.band == py.band
    assert c.events == py.events and c.counts() == py.counts()
    assert c.event_log == py.event_log and c.crossings == py.crossings


@pytest.mark.parametrize("case", CASES)
def test_a_compensated_loop_is_bit_identical(core, case):
    t_end = CASES[case][-1]
    py, c = pair(core, case, section=0.0)
    for k in range(1, 8):  # stepped, with stops at the section
        py.advance(k * t_end / 7.0, stop_at_section=k % 2 == 0)
        c.advance(k * t_end / 7.0, stop_at_section=k % 2 == 0)
        same(py, c)
    kinds = {kind for _t, kind in py.event_log}
    assert py.events > 0
    if "deadband crossed" in case:
        assert "deadband" in kinds  # the case does what it is here for
    times = [c.t + 0.37 * k for k in range(1, 40)]
    assert c.readings(times) == py.readings(times)  # the force on the plant, feedforward included
    same(py, c)


def test_the_deadband_and_the_reset_act(core):
    """The cases are not vacuous: the deadband holds the integrator (the loop rests off target), the reset clears
    it, the feedforward changes the motion."""
    runs = {}
    for case in ("deadband holds", "reset", "over-compensation"):
        _py, c = pair(core, case)
        c.advance(CASES[case][-1])
        runs[case] = c
    plain = core.FrictionLoop(*HUNTS, x0=0.7)
    plain.advance(300.0)
    held = runs["deadband holds"]
    assert held.band == 0 and 0.0 < abs(held.output()) < 0.2 and held.state()[1] == 0.0
    assert runs["reset"].state() != plain.state() and runs["over-compensation"].state() != plain.state()


@pytest.mark.parametrize("d", [1e-300, 5e-324])
def test_a_band_narrower_than_the_rounding_is_crossed_once(core, d):
    """Each pass through a deadband narrower than y's rounding is two events (in, out), as through a band of 1e-12
    m: the exit's side is the motion's, not y's sign (once 0.0 there, it fired the edges back and forth at one
    instant, 3.6 million times, 8 minutes in Python, before the event bound refused it)."""
    for cls in (FrictionLoop, core.FrictionLoop):
        runs = []
        for width in (d, 1e-12):
            loop = cls(*PID, x0=0.3, compensation=Deadband(width))
            loop.event_log = []
            loop.advance(20.0)
            runs.append([kind for _t, kind in loop.event_log])
        assert runs[0] == runs[1] and runs[0].count("deadband") >= 4


@pytest.mark.parametrize("signal", ["velocity", "control"])
def test_a_feedforward_of_zero_is_none_on_any_plant(core, signal):
    """F_hat = 0 adds nothing, so it asks nothing of the plant: a backlash without friction takes it (it was refused
    as the velocity's feedforward needing friction, even with the controller's signal chosen)."""
    for cls in (StaticBacklashLoop, core.StaticBacklashLoop):
        runs = []
        for compensation in (None, Coulomb(0.0, signal)):
            loop = cls(*LEAD_PI, x0=0.3, compensation=compensation)
            loop.advance(20.0)
            runs.append((loop.state(), loop.events))
        assert runs[0] == runs[1] and runs[0][1] > 0


def _problem(core, plant, G, compensation, native):
    p = LoopProblem(plant, G, compensation=compensation)
    p.cls = getattr(core, NATIVE[plant]) if native else PYTHON[plant]
    p._modes, p.budget = {}, Budget(p.budget.total)
    return p


@pytest.mark.parametrize("plant, G, compensation", [
    ("friction", "10 + 2/s", Deadband(0.05)), ("friction", "10 + 2/s", Coulomb(3.0)),
    ("friction", "10 + 2/s", Reset()), ("static-backlash", "20*(s+2)/(s+20)", BacklashInverse(0.1))], ids=repr)
def test_cycles_and_costs_are_bit_identical(core, plant, G, compensation):
    found = []
    for native in (False, True):
        p = _problem(core, plant, G, compensation, native)
        search = find_cycles(p, [], amplitudes=[0.3, 1.0])
        cost = step_cost(p)
        found.append(([(c.omega, c.amplitude_x, c.stable, c.multipliers) for c in search.cycles],
                      [vars(f) for f in search.fates], cost, p.budget.left, sorted(map(str, p._modes))))
    assert found[0] == found[1]
    assert found[0][0]  # each of them still hunts (tests/test_compensate.py holds them to the reference)


@pytest.mark.parametrize("dither", [Dither(10.0, 5.0), Dither(1.0, 5.0)], ids=repr)
def test_a_dithered_search_and_its_cost_are_bit_identical(core, dither):
    found = []
    for native in (False, True):
        p = _problem(core, "friction", "10 + 2/s", dither, native)
        search = find_responses(p, amplitudes=[0.7])
        cost = step_cost(p)
        found.append(([(c.omega, c.amplitude_x, c.stable, c.multipliers) for c in search.cycles + search.responses],
                      [vars(f) for f in search.fates], cost, p.budget.left))
    assert found[0] == found[1]
    assert found[0][1] and found[0][2].peak_force > 0.0


def test_a_compensated_problem_runs_the_compiled_loop(core):
    """LoopProblem picks the C loop for every compensator but the feedforward of the controller's sign."""
    assert LoopProblem("friction", "10 + 2/s", compensation=Deadband(0.1)).cls.__name__ == "NativeFrictionLoop"
    assert LoopProblem("friction", "10 + 2/s", compensation=Dither(1.0, 5.0)).cls.__name__ == "NativeFrictionLoop"
    assert LoopProblem("static-backlash", "20*(s+2)/(s+20)",
                       compensation=BacklashInverse(0.1)).cls.__name__ == "NativeStaticBacklashLoop"
    assert LoopProblem("friction", "10 + 2/s", compensation=Coulomb(2.0, "control")).cls is FrictionLoop
    with pytest.raises(PlantError, match=re.escape("the compiled loop has no Coulomb feedforward of the controller's "
                                                   "sign")):
        core.FrictionLoop(*HUNTS, compensation=Coulomb(2.0, "control"))


def test_shared_modes_with_a_deadband_are_keyed_as_in_python(core):
    keys = []
    for cls in (FrictionLoop, core.FrictionLoop):
        modes = {}
        loop = cls(*HUNTS, x0=0.7, compensation=Deadband(0.05), modes=modes)
        loop.advance(300.0)
        cls(*HUNTS, x0=0.0, compensation=Deadband(0.05), modes=modes)  # a second loop of the study shares them
        keys.append(sorted(modes, key=str))
        assert loop.mode(loop.key) is modes[(loop.key, 0, loop.band)]
    assert keys[0] == keys[1] and len(keys[0]) >= 4
    assert all(type(mode) is NativeMode for mode in modes.values())


@pytest.mark.parametrize("plant, G, params, compensation, text", [
    ("friction", LEAD, {}, Deadband(0.1), "this G(s) has none (its denominator's coefficients after s^n: [20.0])"),
    ("friction", ([0.0, 0.0, 1.0], [0.0, 0.0]), {}, Reset(), "this G(s) has a double one"),
    ("friction", ([1.0] * 10, [0.0] * 9), {}, Deadband(0.1), "order = 9 "),
    ("backlash", PID, {}, Reset(), "the integrator reset needs a plant that comes to rest; BacklashLoop has no"),
    ("static-backlash", PI, {}, Coulomb(1.0), "velocity needs a plant with friction; StaticBacklashLoop has none"),
    ("backlash", PID, {"M1": -1.0}, Coulomb(1.0), "M1 = -1.0 is out of range"),  # the plant's checks first
    ("friction", LEAD, {"Fs": 1.0}, Deadband(0.1), "Fs = 1.0 is out of range"),
    ("friction", PI, {"section": math.nan}, Coulomb(1.0), "section = nan"),
    ("friction", PI, {}, BacklashInverse(0.1), "the backlash inverse needs a plant with a play between the mass and "
                                               "the output; FrictionLoop has none"),
])
def test_refusals_are_the_same_text(core, plant, G, params, compensation, text):
    py = refusal(lambda: PYTHON[plant](*G, **params, compensation=compensation))
    c = refusal(lambda: getattr(core, NATIVE[plant])(*G, **params, compensation=compensation))
    assert py is not None and c == py and text in py[1]


@pytest.mark.parametrize("case", ["deadband crossed", "all three, PID", "static backlash deadband", "dither grazing Fs",
                                  "dither, deadband, feedforward"])
def test_state_round_trip_goes_on_bit_for_bit(core, case):
    t_end = CASES[case][-1]
    py, c = pair(core, case, section=0.0)
    py.advance(t_end)
    for k in range(1, 12):
        c.advance(k * t_end / 11.0)
        data = c.to_bytes()
        again = type(c).from_bytes(data)
        assert again.to_bytes() == data and again.same_parameters(c) and again.band == c.band
        assert (again.coulomb is None) == (c.coulomb is None) and again.deadband == c.deadband
        assert repr(again.dither) == repr(c.dither)
        again.advance(t_end)
        assert again.state() == py.state() and again.events == py.events and again.band == py.band
    plant, G, params, _compensation, _t = CASES[case]
    assert not c.same_parameters(getattr(core, NATIVE[plant])(*G, **params, section=0.0))


def _field(data, index, value):
    raw = struct.pack("<d", value) if isinstance(value, float) else struct.pack("<q", value)
    return with_crc(data[:HEADER + 8 * index] + raw + data[HEADER + 8 * (index + 1):])


def test_crafted_compensators_are_refused(core):
    data = core.FrictionLoop(*HUNTS, x0=0.7, compensation=[Reset(), Deadband(0.1)]).to_bytes()
    plain = core.FrictionLoop(*HUNTS, x0=0.7).to_bytes()
    first = 7 + 1 + 9 + 8 + 2  # the fields before the compensators: par, order, b, a, section flag and level
    cases = [
        (_field(data, first, 2), "compensation flags"),
        (_field(data, first + 1, 1.5), "F_hat = 1.5 is out of range: must be 0 without a Coulomb feedforward"),
        (_field(data, first + 3, -0.1), "compensators are refused: d = -0.1 is out of range"),
        (_field(data, first + 4, 3), "deadband side = 3 is out of range"),
        (_field(plain, first + 4, 0), "deadband side = 0 is out of range"),
        (_field(_field(plain, first, 1), first + 1, -1.0), "F_hat = -1.0 is out of range"),
        (_field(data, 17, 20.0), "compensators are refused: integrator management (reset, deadband) needs"),  # a1
    ]
    for crafted, text in cases:
        with pytest.raises(StateRefused, match=re.escape(text)) as error:
            core.FrictionLoop.from_bytes(crafted)
        assert "\n" not in str(error.value)
    dithered = core.FrictionLoop(*HUNTS, x0=0.7, compensation=Dither(2.0, 5.0)).to_bytes()
    last = (len(dithered) - HEADER) // 8 - 5  # the dither's fields come last (flag, a, w_d), then the inverse's
    for crafted, text in [
        (_field(dithered, last, 0), "dither flag = 0 is out of range: must be 1 with a dither's amplitude above 0"),
        (_field(dithered, last + 1, 0.0), "dither flag = 1 is out of range"),
        (_field(dithered, last + 2, 0.0), "compensators are refused: w_d = 0.0 is out of range"),
        (_field(dithered, last + 2, math.inf), "compensators are refused: w_d = inf is out of range"),
        (_field(dithered, last + 1, -2.0), "dither flag = 1 is out of range"),
        (_field(plain, last + 2, 5.0), "w_d = 5.0 is out of range: must be 0 without a dither"),
    ]:
        with pytest.raises(StateRefused, match=re.escape(text)):
            core.FrictionLoop.from_bytes(crafted)
    inverted = core.StaticBacklashLoop(*LEAD_20, x0=0.3, compensation=BacklashInverse(0.1))
    inverted.advance(1.0)  # engaged down: the correction is -k h_hat/2
    inverted = inverted.to_bytes()
    correction = first + 5 + 11 + 4  # X after the compensators (5) and the solver (11): x, v, y, z1, then w
    static = core.StaticBacklashLoop
    for cls, crafted, text in [
        (static, _field(inverted, last + 3, 0), "backlash inverse flag = 0 is out of range: must be 1 with an estimated"),
        (static, _field(inverted, last + 4, -0.1), "backlash inverse flag = 1 is out of range"),
        (static, _field(inverted, last + 4, math.nan), "backlash inverse flag = 1 is out of range"),
        (static, _field(inverted, last + 4, 1e4), "compensators are refused: h_hat = 10000.0 is out of range: the "
                                                   "backlash inverse's estimated play, a number of metres from 0 to"),
        (core.FrictionLoop, _field(_field(plain, last + 3, 1), last + 4, 0.1),
         "compensators are refused: the backlash inverse needs a plant with a play between the mass and the output; "
         "FrictionLoop has none"),
        (static, _field(inverted, correction, 0.03), "backlash inverse's correction = 0.03 is out of range: must be"),
        (static, _field(inverted, correction, math.inf), "backlash inverse's correction = inf is out of range"),
    ]:
        with pytest.raises(StateRefused, match=re.escape(text)):
            cls.from_bytes(crafted)
    reset_backlash = _field(core.BacklashLoop(*PID).to_bytes(), first + 2, 1)
    with pytest.raises(StateRefused, match="BacklashLoop has no such event"):
        core.BacklashLoop.from_bytes(reset_backlash)


def test_a_state_whose_deadband_side_is_not_the_outputs_is_refused(core):
    """A crafted side (band 0 with y = 0.7 > d, or below) or a d the output is not beyond is no state of the loop."""
    loop = core.FrictionLoop(*HUNTS, x0=0.7, compensation=Deadband(0.2))
    data, first = loop.to_bytes(), 27
    built = struct.unpack("<q", data[HEADER + 8 * 36:HEADER + 8 * 37])[0]
    every_side = _field(data, 36, built | built << 9 | built << 18)  # the modes of every side built
    for crafted in (_field(every_side, first + 4, 0), _field(every_side, first + 4, -1),
                    _field(every_side, first + 3, 1e300)):
        with pytest.raises(StateRefused, match="deadband side = .* must be the output's"):
            core.FrictionLoop.from_bytes(crafted)
    assert core.FrictionLoop.from_bytes(data).band == 1


@pytest.mark.parametrize("cls", ["python", "native"])
def test_an_integrator_coordinate_that_overflows_is_refused(core, cls):
    make = FrictionLoop if cls == "python" else core.FrictionLoop
    with pytest.raises(PlantError, match=re.escape("a1 = 5e-324 is out of range: integrator management (reset, "
                                                   "deadband) needs 1 / a1 finite")):
        make([1.0, 2.0, 1.0], [5e-324, 0.0], x0=0.7, compensation=Deadband(0.1))
