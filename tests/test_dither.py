"""Dither in the exact loop (issue 33): ``a sin(w_d t)`` added to the force, its responses by the stroboscopic map.

Every verdict is checked against the independent reference (:func:`dfwb.plants.loop_reference.
closed_loop_reference` with ``dither``: solve_ivp between events, the dither a function of time, written apart
from dfwb's oscillator): the friction mass under PI ``10 + 2/s``, which hunts undithered (57 s).
"""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

import dfwb
from dfwb.base.errors import InputError
from dfwb.engine.cycles import starts
from dfwb.engine.dither import find_responses
from dfwb.engine.hunting import truth_class
from dfwb.engine.periodic import LoopProblem
from dfwb.fmus.compensation import Dither
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop
from dfwb.plants.loop_reference import closed_loop_reference

PI = ([10.0, 2.0], [0.0])  # 10 + 2/s in (b, a)
DFWB = [sys.executable, "-m", "dfwb.cli"]


def reference(a, w_d, t_end, state, **more):
    return closed_loop_reference("friction", *PI, t_end, state=list(state), dither=(a, w_d), max_events=100_000,
                                 **more)


def strobe(a, w_d, periods, state):
    """The reference's states at the dither's phase 0, periods 0..periods."""
    T = 2.0 * math.pi / w_d
    return reference(a, w_d, periods * T, state, t_eval=np.arange(periods + 1) * T)["samples"]


# -- the loop ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("a, w_d, t_end", [(1.0, 5.0, 100.0), (6.0, 3.0, 20.0), (10.0, 5.0, 30.0)])
def test_the_dithered_loop_fires_the_references_events(a, w_d, t_end):
    loop = FrictionLoop(*PI, state=[-0.7, 0.0, 0.0], compensation=Dither(a, w_d))
    loop.event_log = []
    loop.advance(t_end)
    ref = reference(a, w_d, t_end, [-0.7, 0.0, 0.0])
    assert [str(kind) for _t, kind in loop.event_log] == [kind for _t, kind in ref["events"]]
    assert len(loop.event_log) >= 3
    assert max(abs(t - u) for (t, _), (u, _) in zip(loop.event_log, ref["events"])) < 1e-9
    assert np.allclose(loop.state(), ref["state"], rtol=0.0, atol=1e-8)  # the oscillator is not in the state


def test_a_breakaway_on_a_grazing_dither_peak_is_not_stepped_over():
    """Under a = 3 N at 20 rad/s the stuck mass breaks away at t = 10.758 s where a dither peak lifts the force
    above Fs for 3.5 ms only, by 1.9e-3 N: the closed form of the force while stuck (x held, the integrator
    ramping) shows it; dfwb breaks away where it starts. (The reference, sampling its event functions at steps
    of a 32nd of the dither period, 9.8 ms, steps over it: its motion differs from there on.)"""
    loop = FrictionLoop(*PI, state=[-0.7, 0.0, 0.0], compensation=Dither(3.0, 20.0))
    loop.event_log = []
    loop.advance(11.0)
    (t0, stick), (t1, kind) = loop.event_log[44], loop.event_log[45]
    assert (str(stick), str(kind)) == ("band", "break+") and 10.7582 < t1 < 10.7583
    again = FrictionLoop(*PI, state=[-0.7, 0.0, 0.0], compensation=Dither(3.0, 20.0))
    again.advance(t0)
    x, v, z = again.state()
    assert v == 0.0
    t = np.linspace(t0, t1 + 0.05, 2_000_001)
    force = -(10.0 * x + 2.0 * (z + x * (t - t0))) + 3.0 * np.sin(20.0 * t)  # were it to stay stuck
    above = t[force > 7.0]
    assert abs(above.min() - t1) < 1e-7 and 3e-3 < above.max() - above.min() < 4e-3  # Fs = 7 N
    assert 1e-3 < force.max() - 7.0 < 3e-3


def test_a_dither_of_zero_is_none_and_a_bad_one_is_refused_by_the_loop():
    for cls in (FrictionLoop, LoopProblem("friction", "10 + 2/s").cls):  # the Python loop, the compiled one
        runs = []
        for compensation in (None, Dither(0.0, 5.0)):
            loop = cls(*PI, x0=0.7, compensation=compensation)
            loop.advance(100.0)
            runs.append((loop.state(), loop.events))
        assert runs[0] == runs[1] and runs[0][1] > 0
    with pytest.raises(PlantError, match="w_d = 0.0 is out of range"):
        Dither(1.0, 0.0)
    with pytest.raises(PlantError, match="a = nan is out of range"):
        Dither(math.nan, 1.0)


# -- its responses, against the reference ----------------------------------------------------------------------
def test_a_strong_dither_settles_on_its_own_response_as_the_reference_does():
    """a = 10 N (beyond Fs = 7 N) at 5 rad/s: every run settles on one response at the dither's period, mean 0
    (the integrator), residual oscillation 0.4026 m; it is a fixed point of the reference's stroboscopic map to
    1e-9, the reference reaches it from rest, and the cost's residual oscillation is the reference's."""
    response = dfwb.limit_cycles("friction", "10 + 2/s", exact=True, compensate="dither", a=10, w_d=5,
                                 amplitudes=[0.7], n_F=2, n_omega=2)  # the truth's test: a DF map of 4 points
    assert response.cycles == [] and response.coverage.outcomes == {"dithered": 4}
    (r,) = response.responses
    assert r.stable and r.returns == 1 and abs(r.period - 2 * math.pi / 5) < 1e-15 and abs(r.harmonics[0]) < 1e-9
    assert abs(r.amplitude_x - 0.4026) < 1e-4 and max(r.multipliers) < 0.8
    X, swing = np.array(r.state), np.array(r.swing)
    assert np.abs((reference(10.0, 5.0, r.period, X)["state"] - X) / swing).max() < 1e-9
    samples = strobe(10.0, 5.0, 120, [-0.7, 0.0, 0.0])
    assert np.abs((samples[-1] - X) / swing).max() < 1e-9
    times = np.linspace(0.0, r.period, 8001)  # one period of the reference from the response's state
    y = reference(10.0, 5.0, r.period, X, t_eval=times)["samples"][:, 0]
    first = abs(np.trapezoid(y * np.exp(-5j * times), times)) * 2.0 / r.period
    assert abs(r.amplitude_x - first) < 1e-6
    cost = response.cost  # the step response ends on the same response: its residual oscillation is the harmonic
    assert abs(cost.residual_oscillation - r.amplitude_x) < 1e-9 and cost.standing_error < 1e-9
    assert cost.settling_time < 5.0 and cost.peak_force > 10.0  # the dither's force is part of the force


def test_a_hunting_cycle_locked_to_the_dither_is_the_references():
    """a = 2 N at 0.5 rad/s: the hunting locks to the dither, one stable cycle of three dither periods
    (37.7 s); the reference returns to it after three periods to 1e-9 and reaches it from rest."""
    response = dfwb.limit_cycles("friction", "10 + 2/s", exact=True, compensate="dither", a=2, w_d=0.5,
                                 amplitudes=[0.7], n_F=2, n_omega=2)
    assert response.coverage.outcomes == {"cycle": 4} and response.responses == []
    (c,) = response.cycles
    assert c.stable and c.returns == 3 and abs(c.period - 6 * math.pi / 0.5) < 1e-12
    assert abs(c.amplitude_x - 0.2987) < 1e-4 and max(c.multipliers) < 0.2
    swing = np.array(c.swing)
    for S in c.sections:
        assert np.abs((reference(2.0, 0.5, c.period, S)["state"] - np.array(S)) / swing).max() < 1e-9
    samples = strobe(2.0, 0.5, 60, [0.7, 0.0, 0.0])
    assert min(np.abs((samples[-1] - np.array(S)) / swing).max() for S in c.sections) < 1e-9
    assert truth_class(dfwb.engine.cycles.CycleSearch(response.cycles, [], response.coverage, []))[0] == "stable"


def test_a_weak_dither_leaves_hunting_that_is_not_locked_as_the_reference_does():
    """a = 1 N at 5 rad/s: a run hunts, not locked to the dither (no periodic orbit), swinging about 0.12 m every
    100 s or so (the others stick for longer than the horizon); the reference from its start hunts alike to its
    end, its samples never repeating."""
    problem = LoopProblem("friction", "10 + 2/s", compensation=Dither(1.0, 5.0))
    found = find_responses(problem, amplitudes=[0.7])
    assert found.cycles == found.responses == [] and set(found.coverage.outcomes) <= {"hunting", "rest"}
    assert truth_class(found)[0] == "hunts"
    hunting = found.hunting()[0]
    assert "not locked to the dither" in hunting.detail
    start = next(s for s in starts(problem, [0.7]) if s.label == hunting.start)
    samples = strobe(1.0, 5.0, 800, start.state)  # 1005 s
    y = samples[:, 0]
    late = y[400:]
    assert 0.15 < np.ptp(late) < 0.4  # dfwb's swings: 0.12 m each side
    ups = np.nonzero((late[:-1] < 0.0) & (late[1:] >= 0.0))[0]
    assert len(ups) >= 3  # it keeps hunting
    swing = np.ptp(samples[400:], axis=0)
    distance = np.abs((samples[-1] - samples[-9:-1]) / swing).max(axis=1)  # no period of 1 to 8 dither periods
    assert distance.min() > 1e-3


def test_a_dither_with_a_rest_is_at_rest_in_the_reference():
    """a = 6 N at 20 rad/s: every run from 0.7 m ends stuck, no event for the horizon (200 s); the reference from
    the same start sticks for good too: its last event comes before 250 s of a 400 s run."""
    problem = LoopProblem("friction", "10 + 2/s", compensation=Dither(6.0, 20.0))
    found = find_responses(problem, amplitudes=[0.7], horizon=200.0)
    assert found.coverage.outcomes == {"rest": 4} and truth_class(found)[0] == "none"
    assert max(f.time for f in found.fates) < 450.0
    ref = reference(6.0, 20.0, 400.0, starts(problem, [0.7])[0].state)
    assert ref["mode"] == "stick" and len(ref["events"]) > 10 and ref["events"][-1][0] < 250.0


# -- the interfaces ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("values, message", [
    ({"a": 1.0, "w_d": 1e12}, "w_d = 1e+12 rad/s is out of range for this loop: the exact loop's steps"),
    ({"a": 1.0, "w_d": 1e-300}, "w_d = 1e-300 rad/s is out of range for this loop: its period 6.283e+300 s is"),
    ({"a": 1.0}, "the parameter w_d is given no value"),
    ({"a": 1.0, "w_d": 0.0}, "w_d = 0.0 is out of range"),
    ({"a": 1.0, "w_d": math.inf}, "w_d = inf"),
    ({"a": -1.0, "w_d": 5.0}, "a = -1.0 is out of range"),
])
def test_a_bad_dither_is_one_line(values, message):
    with pytest.raises(InputError, match=re.escape(message)):
        dfwb.limit_cycles("friction", "10 + 2/s", exact=True, compensate="dither", **values)


def test_the_command_line_prints_the_dithers_responses_and_cost_in_json(tmp_path):
    done = subprocess.run(DFWB + ["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "dither",
                                  "--set", "a=10", "w_d=5", "--map-size", "2", "2", "--json"], capture_output=True, text=True, cwd=tmp_path,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    document = json.loads(done.stdout)
    assert document["compensation"] == "dither (a = 10, w_d = 5)"
    assert document["cycles"] == [] and document["hunting"] == [] and len(document["responses"]) == 1
    assert abs(document["responses"][0]["amplitude_x"] - 0.4026) < 1e-4
    assert abs(document["cost"]["residual_oscillation"] - 0.4026) < 1e-4
    bad = subprocess.run(DFWB + ["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "dither",
                                 "--set", "a=1", "w_d=0"], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert bad.returncode == 2 and bad.stdout == "" and len(bad.stderr.strip().splitlines()) == 1
    assert "w_d = 0.0 is out of range" in bad.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_dithered_map_has_the_hunting_that_is_not_locked_and_the_residual_oscillation(tmp_path):
    """a x w_d over 1 and 10 N, 5 and 6 rad/s: the weak dither's cells hunt unlocked (the class "hunts"), the strong
    one's do not, and their cost is the residual oscillation (0.4026 m at 5 rad/s, as limit-cycle finds it); the
    figure's cost panel shows it."""
    response = dfwb.hunting_map("friction", "10 + 2/s", ("a", 1, 10, 2), ("w_d", 5, 6, 2), compensate="dither",
                                out_dir=tmp_path, amplitudes=2)
    classes = response.classes("truth")
    assert classes[:, 0].tolist() == ["hunts", "hunts"] and classes[:, 1].tolist() == ["none", "none"]
    residual = response.costs("residual_oscillation")
    assert abs(residual[0, 1] - 0.4026) < 1e-4 and residual[1, 1] < residual[0, 1]
    assert np.isnan(residual[:, 0]).all()  # hunting: it never settles
    assert not response.has_df and (tmp_path / "hunting_map.png").exists()


def test_tune_holds_a_dithers_residual_oscillation_to_the_tolerance():
    """Over a = 1 and 10 N at 5 rad/s: the weak dither hunts; the strong one stops it but shakes the mass by 0.4026
    m, which a tolerance of 0.1 m refuses and one of 1 m accepts. The confirmation at rest does not apply to a
    dithered loop and says so (it crashed on the dither's missing d)."""
    strict = dfwb.tune("friction", "10 + 2/s", compensate="dither", free={"a": (1, 10)}, count=2, tolerance=0.1,
                       w_d=5)
    assert strict.settings is None
    assert [(c["verdict"], c["detail"]) for c in strict.candidates] == [("hunts", "hunts at nominal"),
                                                                         ("standing error", "0.4026 at nominal")]
    loose = dfwb.tune("friction", "10 + 2/s", compensate="dither", free={"a": (1, 10)}, count=2, tolerance=1.0,
                      w_d=5)
    assert loose.settings == {"a": 10.0} and loose.confirmed is None
    assert "never at rest" in loose.confirmation
