"""Compensated loops in the studies (issue 33): ``compensate=`` and ``--compensate`` on limit-cycle, continue, map
and margin, the compensators' parameters set and swept like G's, and the cost of each verdict.

The verdicts are checked against the independent reference (:func:`dfwb.plants.loop_reference.
closed_loop_reference`, solve_ivp between events, its compensators written apart): the friction mass under
PI, ``10 + 2/s``, which hunts uncompensated.
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
from dfwb.engine.compensators import Compensation
from dfwb.engine.cost import step_cost
from dfwb.engine.family import LoopFamily
from dfwb.engine.hunting import valid_cell
from dfwb.plants.loop_reference import closed_loop_reference

PI = ([10.0, 2.0], [0.0])  # 10 + 2/s in (b, a)
DFWB = [sys.executable, "-m", "dfwb.cli"]


def cli(*words, cwd=None):
    done = subprocess.run(DFWB + list(words), capture_output=True, text=True, cwd=cwd, timeout=600)
    return done.returncode, done.stdout, done.stderr


# -- the verdicts, against the reference ---------------------------------------------------------------------------
def test_a_wide_deadband_stops_the_hunting_and_the_reference_agrees_from_every_start():
    """d = 0.2 m under 10 + 2/s: the exact search finds no cycle from its 36 starts (9 amplitudes over 1e-2 to 1e2
    times the length scale, displacing x, v and the integrator both ways); the reference, from rest at 0.7 m and
    from four displaced starts, comes to rest within the band and stays there to 2000 s."""
    response = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, compensate="deadband", Kp=10, Ki=2, d=0.2)
    assert response.cycles == [] and response.coverage.complete
    assert response.coverage.outcomes == {"rest": 36}
    assert response.predictions == [] and response.N_grid.size == 0  # no DF of a compensated loop
    for state in ([-0.7, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 2.0, 0.0], [1.5, 0.0, -3.0], [-5.0, 0.0, 10.0]):
        ref = closed_loop_reference("friction", *PI, 2000.0, state=state, deadband=0.2, max_events=10_000)
        assert ref["mode"] == "stick" and abs(ref["state"][0]) < 0.2, state
        later = closed_loop_reference("friction", *PI, 1000.0, state=ref["state"], deadband=0.2)
        assert later["events"] == [] and later["state"] == ref["state"]  # at rest for good


def test_the_cost_of_the_deadband_is_the_references_step_response():
    """The step response from rest at -S (S = 0.6986 m, the loop's length scale): where it rests (the standing
    error), when it settles and how far it overshoots, against the reference's samples to 1e-7."""
    cost = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, compensate="deadband", Kp=10, Ki=2, d=0.2).cost
    S = cost.step
    times = np.linspace(0.0, cost.horizon, 4001)
    ref = closed_loop_reference("friction", *PI, cost.horizon, state=[-S, 0.0, 0.0], deadband=0.2, t_eval=times,
                                max_events=10_000)
    y = ref["samples"][:, 0]
    assert abs(cost.standing_error - abs(ref["state"][0])) < 1e-7
    assert 0.0 < cost.standing_error < 0.2
    assert abs(cost.overshoot - max(0.0, y.max()) / S) < 1e-3  # (sampled on other grids)
    outside = np.nonzero(np.abs(y - y[-1]) > 0.02 * S)[0]
    assert abs(cost.settling_time - times[outside[-1] + 1]) <= 2 * cost.horizon / 2000
    f = -(10.0 * y + 2.0 * ref["samples"][:, 2])  # f = -(Kp y + Ki xi), z = xi
    assert abs(cost.peak_force - np.abs(f).max()) < 1e-3 * cost.peak_force
    assert abs(cost.rms_force - math.sqrt(np.trapezoid(f * f, times) / cost.horizon)) < 1e-2 * cost.rms_force


def test_a_hunting_loop_has_no_standing_error():
    cost = step_cost(LoopFamily("friction", "10 + 2/s").problem())
    assert cost.standing_error is None and cost.settling_time is None and cost.note == ""
    assert cost.overshoot > 0.2 and cost.peak_force > 7.0  # it breaks away at Fs = 7 N


def test_the_controllers_feedforward_through_the_api_is_the_loops_cycle():
    """F_hat = 3 N of the controller's sign, named and valued like G's parameters: the same cycle, to the bit, as
    the loop given the compensator itself, the cycle tests/test_compensation.py closes with the reference."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem
    from dfwb.fmus.compensation import Coulomb

    response = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, compensate="coulomb", Kp=10, Ki=2, F_hat=3,
                                 signal="control")
    (cycle,) = response.cycles
    (direct,) = find_cycles(LoopProblem("friction", "10 + 2/s", compensation=Coulomb(3.0, "control"))).cycles
    assert cycle.stable and (cycle.period, cycle.state) == (direct.period, direct.state)
    assert abs(cycle.period - 24.99064581) < 1e-6
    assert "coulomb (F_hat = 3, signal = control)" in response.summary()
    assert cycle.df == ""  # no word on a DF that was not computed


def test_an_over_compensating_feedforward_is_refused_as_chatter_quickly():
    """F_hat = 9 N > Fs of the controller's sign switches ever faster (the reference meets the same: thousands of
    switches within seconds): a run is refused in one line once it switched 1000 times within 10 chunks of the
    fastest mode, and the cost says why instead of failing."""
    problem = LoopFamily("friction", "10 + 2/s", {"F_hat": 9, "signal": "control"}, compensate="coulomb").problem()
    with pytest.raises(dfwb.PlantError, match="chatters"):
        problem.solver(problem.rest_start(-0.7)).advance(100.0)
    cost = step_cost(problem)
    assert "chatters" in cost.note and cost.peak_force is None and "not computed" in cost.summary()
    with pytest.raises(dfwb.RunError, match="events"):
        closed_loop_reference("friction", *PI, 100.0, state=[-0.7, 0.0, 0.0], coulomb=(9.0, "control"),
                              max_events=2000)


# -- the studies ------------------------------------------------------------------------------------------------
def test_a_compensators_parameter_continues_like_gs():
    r = dfwb.continuation("friction", "Kp + Ki/s", "F_hat", 0, 6, Kp=10, Ki=2, compensate="coulomb",
                          signal="control")
    (branch,) = r.branches
    assert branch.source == "truth" and all(p.stable for p in branch.points)
    assert any("DF of this compensated loop is not computed" in note for note in r.notes)
    grazing = [b.parameter for b in r.bifurcations if b.parameter > 1.0]
    assert len(grazing) == 1 and abs(grazing[0] - 3.2764121) < 1e-6
    assert "compensated by coulomb" in r.summary()


def test_a_compensation_map_has_the_truth_and_the_cost(tmp_path):
    m = dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 8, 12, 2), ("d", 0.05, 0.25, 2), jobs=1, Ki=2,
                         compensate="deadband", out_dir=tmp_path / "map")
    assert m.compensated and m.curves == []
    assert m.classes("truth").tolist() == [["stable", "stable"], ["none", "none"]]
    assert (m.classes("df") == "uncomputed").all()
    errors = m.costs("standing_error")
    assert np.isnan(errors[0]).all() and (0.0 < errors[1]).all() and (errors[1] < 0.25).all()
    assert all(valid_cell(cell) for row in m.cells for cell in row)
    assert "cost: 2 cells come to rest" in m.summary() and (tmp_path / "map" / "hunting_map.png").is_file()
    again = dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 8, 12, 2), ("d", 0.05, 0.25, 2), jobs=1, Ki=2,
                             compensate="deadband", out_dir=tmp_path / "map")
    assert again.counts["resumed"] == 4 and again.cells == m.cells
    with pytest.raises(InputError, match="holds a different map"):  # the compensators are part of the map
        dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 8, 12, 2), ("d", 0.05, 0.25, 2), jobs=1, Ki=2,
                         compensate=["deadband", "reset"], out_dir=tmp_path / "map")


def test_a_compensated_margin_is_the_truths():
    m = dfwb.limit_cycle_margin("friction", "10 + 2/s", count=5, compensate="deadband", d=0.2)
    assert m.df is None and "compensated by deadband" in m.G


# -- refused in one line -------------------------------------------------------------------------------------
@pytest.mark.parametrize("compensate, values, message", [
    ("dither", {"a": 1}, "the parameter w_d is given no value"),
    ("dither", {"a": 1, "w_d": 0}, "w_d = 0.0 is out of range"),
    ("backlash-inverse", {"h_hat": 0.1}, "the backlash inverse needs a plant with a play"),
    ("backlash-inverse", {"h_hat": 0.0}, "the backlash inverse needs a plant with a play (backlash, static-backlash, "
                                         "drivetrain); friction has none"),  # whatever h_hat, before its value
    ("friction", {}, "not a compensator"),
    (["reset", "reset"], {}, "named twice"),
    (3, {}, "give a compensator's name"),
    ("coulomb", {}, "F_hat is given no value"),
    ("coulomb", {"F_hat": -1}, "F_hat = -1.0 is out of range"),
    ("coulomb", {"F_hat": "inf"}, "F_hat = 'inf': give a finite number"),
    ("coulomb", {"F_hat": 1, "signal": "up"}, "signal = 'up': one of velocity, control"),
    ("deadband", {"d": -0.1}, "d = -0.1 is out of range"),
    ("deadband", {"d": 0.1, "Kp": 1}, "unknown parameter 'Kp'"),
])
def test_a_bad_compensation_is_one_line(compensate, values, message):
    with pytest.raises(InputError, match=re.escape(message)):
        LoopFamily("friction", "10 + 2/s", values, compensate=compensate)


@pytest.mark.parametrize("values, message", [
    ({}, "the parameter h_hat is given no value"),
    ({"h_hat": -0.1}, "h_hat = -0.1 is out of range"),
    ({"h_hat": 1e308}, "h_hat = 1e+308 is out of range: the backlash inverse's estimated play, a number of metres "
                       "from 0 to 1000"),
    ({"h_hat": 1.01}, "h_hat = 1.01 is out of range: the backlash inverse's estimate of the play h = 0.1 m, at most "
                      "10 times it"),
])
def test_a_bad_estimate_of_the_play_is_one_line(values, message):
    with pytest.raises(InputError, match=re.escape(message)):
        LoopFamily("static-backlash", "20*(s+2)/(s+20)", values, compensate="backlash-inverse")


def test_a_compensator_that_does_not_fit_is_refused_before_anything_runs():
    with pytest.raises(InputError, match="needs a plant with friction"):
        LoopFamily("backlash", "200*(s+2)/(s+20)", {"F_hat": 1}, compensate="coulomb")
    with pytest.raises(InputError, match="G\\(s\\) has none"):
        LoopFamily("friction", "10*(s+1)/(s+10)", compensate="reset")
    with pytest.raises(InputError, match="not a number: set it"):
        LoopFamily("friction", "10 + 2/s", {"F_hat": 1}, free=("signal",), compensate="coulomb")
    with pytest.raises(InputError, match="add exact"):
        dfwb.limit_cycles("friction", "10 + 2/s", compensate="deadband", d=0.1)
    assert Compensation().build({}) is None and not Compensation([])


@pytest.mark.parametrize("words, message", [
    (["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "backlash-inverse", "--set",
      "h_hat=0"], "the backlash inverse needs a plant with a play (backlash, static-backlash, drivetrain); friction "
                  "has none"),
    (["tune", "stribeck", "--G", "Kp + 2/s", "--compensate", "backlash-inverse", "--free", "Kp=5:30",
      "h_hat=0:0.2"], "stribeck has none"),
    (["limit-cycle", "static-backlash", "--G", "20*(s+2)/(s+20)", "--exact", "--compensate", "backlash-inverse",
      "--set", "h_hat=0.1", "h=1e-9"], "h_hat = 0.1 is out of range: the backlash inverse's estimate of the play "
                                       "h = 1e-09 m, at most 10 times it"),
    (["continue", "static-backlash", "--G", "20*(s+2)/(s+20)", "--compensate", "backlash-inverse", "--parameter",
      "h_hat=0:1e308"], "h_hat = 0:1e+308: h_hat = 1e+308 is out of range"),
    (["map", "static-backlash", "--G", "20*(s+a)/(s+20)", "--compensate", "backlash-inverse", "--x", "h_hat=0:3:3",
      "--y", "a=1:4:2"], "h_hat = 0:3: h_hat = 3.0 is out of range: the backlash inverse's estimate of the play "
                         "h = 0.1 m, at most 10 times it"),  # (a map over h_hat and h checks its cells)
    (["map", "static-backlash", "--G", "20*(s+2)/(s+20)", "--compensate", "backlash-inverse", "--x",
      "h_hat=-0.1:0.2:3", "--y", "M=1:2:2"], "h_hat = -0.1:0.2: h_hat = -0.1 is out of range"),
    (["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "dither", "--set", "a=1"],
     "the parameter w_d is given no value"),
    (["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "coulomb"], "F_hat is given no"),
    (["limit-cycle", "friction", "--G", "10 + 2/s", "--exact", "--compensate", "deadband", "--set", "d=-1"],
     "d = -1.0 is out of range"),
    (["limit-cycle", "friction", "--G", "10 + 2/s", "--compensate", "reset"], "add exact"),
    (["map", "friction", "--G", "Kp + 2/s", "--compensate", "coulomb", "--x", "signal=0:1:2", "--y", "Kp=1:2:2"],
     "signal is a choice"),
    (["continue", "friction", "--G", "10 + 2/s", "--compensate", "coulomb", "--set", "F_hat=1",
      "--parameter", "F_hat=0:1"], "F_hat is the parameter followed"),
    (["margin", "static-backlash", "--G", "20*(s+2)/(s+20)", "--compensate", "coulomb", "--set", "F_hat=1"],
     "needs a plant with friction"),
    # a compensator's range is checked at both ends, as a plant parameter's (it ran, refusing cells or starts)
    (["continue", "friction", "--G", "10 + 2/s", "--compensate", "coulomb", "--parameter", "F_hat=-1:3"],
     "F_hat = -1:3: F_hat = -1.0 is out of range: a finite number of newtons, at least 0"),
    (["map", "friction", "--G", "Kp + 2/s", "--compensate", "deadband", "--x", "Kp=1:2:2", "--y", "d=-0.1:0.3:2"],
     "d = -0.1:0.3: d = -0.1 is out of range"),
    (["tune", "friction", "--G", "Kp + Ki/s", "--compensate", "coulomb", "--free", "Kp=2:50", "Ki=0.2:10",
      "F_hat=-1:3"], "F_hat = -1:3: F_hat = -1.0 is out of range"),
    (["map", "friction", "--G", "Kp + Ki/s", "--x", "Kp=1:2:2", "--y", "Ki=0:1e308:2"],
     "y Ki = 0:1e+308: each end within +-1e+150"),  # (an internal error in the figure's ticks)
])
def test_the_command_line_refuses_in_one_line_and_writes_nothing(tmp_path, words, message):
    code, out, err = cli(*words, cwd=tmp_path)
    assert code == 2 and out == "" and err.count("\n") == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_the_command_line_prints_the_cost_in_json(tmp_path):
    code, out, err = cli("limit-cycle", "friction", "--G", "Kp + Ki/s", "--set", "Kp=10", "Ki=2", "d=0.2",
                         "--compensate", "deadband", "--exact", "--json", cwd=tmp_path)
    assert code == 0, err
    document = json.loads(out)
    assert document["cycles"] == [] and document["compensation"] == "deadband (d = 0.2)"
    assert set(document["cost"]) == {"step", "horizon", "standing_error", "settling_time", "overshoot", "peak_force",
                                     "rms_force", "note", "residual_oscillation"}
    assert document["cost"]["residual_oscillation"] is None  # (a dither's)
    assert 0.0 < document["cost"]["standing_error"] < 0.2


SCENE = '''title = "Compensating the hunting friction mass"

[[limit_cycle]]
name = "feedforward"
plant = "friction"
G = "Kp + Ki/s"
params = {Kp = 10, Ki = 2, F_hat = 3, signal = "control"}
compensate = ["coulomb"]
exact = true

[[continuation]]
name = "deadband"
plant = "friction"
G = "10 + 2/s"
compensate = ["deadband"]
parameter = "d"
start = 0.01
stop = 0.3
sources = ["truth"]

[[figure]]
name = "lc"
kind = "limit_cycle"
series = ["feedforward"]
'''


def test_a_scene_compensates_as_the_api_does(tmp_path):
    """``compensate = [...]`` in a scene's sections, ``signal`` among its params: the cycle the API finds, and the
    deadband's fold, where the hunting under 10 + 2/s ends (d = 0.178 m), in summary.md."""
    (tmp_path / "scene.toml").write_text(SCENE)
    code, out, err = cli("run", "scene.toml", "--out", "out", "--quiet", cwd=tmp_path)
    assert code == 0, err
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "not computed: no DF of the loop compensated by coulomb (F_hat = 3, signal = control)" in summary
    assert "| 0.25142149 |" in summary and "Cost: step of 0.6986 m: does not come to rest" in summary
    assert "truth fold at d = 0.17819" in summary and (tmp_path / "out" / "lc_feedforward.png").is_file()
    assert results is not None


@pytest.mark.parametrize("text, message", [
    ('compensate = ["backlash-inverse"]\nparams = {h_hat = 0}', "friction has none"),
    ('compensate = ["deadband"]\nparams = {d = "0.2"}', "params.d = '0.2': text where a number belongs"),
    ('compensate = ["dither"]\nparams = {a = 1, w_d = -2}', "w_d = -2.0 is out of range"),
    ('compensate = ["deadband"]\nparams = {d = "wide"}', "params.d = 'wide': text where a number belongs"),
    ('compensate = "deadband"\nparams = {d = 1}', "compensate: Input should be a valid list"),
    ('compensate = ["coulomb"]\nparams = {F_hat = 1, signal = "sign"}', "signal = 'sign': one of velocity"),
    ('compensate = ["deadband"]\nparams = {d = 0.2}\nverify = true', "verify co-simulates"),  # never dropped
])
def test_a_scene_refuses_a_bad_compensation_in_one_line(tmp_path, text, message):
    (tmp_path / "bad.toml").write_text('title = "bad"\n[[limit_cycle]]\nname = "x"\nplant = "friction"\n'
                                       f'G = "10 + 2/s"\nexact = true\n{text}\n')
    code, out, err = cli("run", "bad.toml", "--out", "out", cwd=tmp_path)
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "out").exists()


# -- dfwb tune -------------------------------------------------------------------------------------------------
TUNE = dict(compensate="deadband", free={"Kp": (2, 50), "Ki": (0.2, 10), "d": (0.01, 0.5)}, robust={"Fc": 0.2,
                                                                                                   "Fs": 0.1})


def _rests(b, a, d, state, params, T=2000.0):
    """The reference from ``state``: where it rests at T, or None if it still moves in its last quarter."""
    ref = closed_loop_reference("friction", b, a, T, params, state=state, deadband=d, max_events=100_000)
    late = [t for t, _kind in ref["events"] if t > 0.75 * T]
    return None if late or ref["mode"] != "stick" else ref["state"][0]


def test_tune_chooses_the_fastest_pi_whose_deadband_stops_the_hunting_within_the_tolerance():
    """Kp + Ki/s with an integrator deadband, Fc +-20 % and Fs +-10 %, standing error at most 0.1 m: the highest
    crossover on the grid (Kp = 50, Ki = 10) with the smallest deadband that stops its hunting (0.0707 m). The
    reference: the two smaller deadbands still hunt; the chosen one rests within 0.1 m of the target at every
    corner, from the step and from displaced starts."""
    r = dfwb.tune("friction", "Kp + Ki/s", tolerance=0.1, count=5, **TUNE)
    assert r.settings == {"Kp": 50.0, "Ki": 10.0, "d": pytest.approx(0.0707107, rel=1e-6)}
    assert abs(r.crossover - 7.06365) < 1e-5 and r.confirmed is True
    assert [c["verdict"] for c in r.candidates[:3]] == ["hunts", "hunts", "accepted"]
    b, a = [50.0, 10.0], [0.0]
    for d in (0.01, 0.0265915):  # the deadbands refused: they hunt, by the reference too (from their cycle)
        found = dfwb.limit_cycles("friction", "50 + 10/s", exact=True, compensate="deadband", d=d)
        stable = [c for c in found.cycles if c.stable]
        assert stable and _rests(b, a, d, stable[0].state, {}) is None
    S = r.cost["step"]
    for corner in r.corners:
        params = {k: v for k, v in corner.items() if k in ("Fc", "Fs")}
        for state in ([-S, 0.0, 0.0], [0.5, 0.0, 0.0], [2.0, 0.0, -5.0]):
            rest = _rests(b, a, r.settings["d"], state, params)
            assert rest is not None and abs(rest) <= 0.1, (corner, state, rest)
    assert "chosen: Kp = 50, Ki = 10, d = 0.0707107" in r.summary() and "at the end of the range" in r.summary()


def test_tune_says_when_no_setting_passes():
    r = dfwb.tune("friction", "Kp + Ki/s", tolerance=0.005, count=3, **TUNE)
    assert r.settings is None and r.confirmed is None and "no setting on the grid passes" in r.summary()
    assert {c["verdict"] for c in r.candidates} <= {"hunts", "standing error", "linear loop unstable"}


def test_tune_on_the_command_line_prints_the_interface_the_issue_names(tmp_path):
    code, out, err = cli("tune", "friction", "--G", "Kp + Ki/s", "--compensate", "deadband", "--free", "Kp=2:50",
                         "Ki=0.2:10", "d=0.01:0.5", "--tolerance", "0.1", "--robust", "Fc=0.2", "Fs=0.1",
                         "--count", "3", "--json", cwd=tmp_path)
    assert code == 0, err
    document = json.loads(out)
    assert {"settings", "crossover", "cost", "confirmed"} <= set(document) and document["confirmed"] is True
    assert document["settings"]["Kp"] == 50.0 and len(document["corners"]) == 5


@pytest.mark.parametrize("words, message", [
    (["--free", "Kp=2"], "--free 'Kp=2': expected NAME=LO:HI"),
    (["--free", "Kp=2:50", "Kp=3:4"], "--free Kp given twice"),
    (["--free", "Kp=50:2"], "expected lo < hi"),
    (["--free", "Kp=2:50", "M=1:2"], "free M: a parameter of the plant"),
    (["--free", "Kp=2:50", "--robust", "Kp=0.1"], "robust Kp: not a parameter of the friction plant"),
    (["--free", "Kp=2:50", "--robust", "Fc=2"], "a relative error between 0 and 1"),
    (["--free", "Kp=2:50", "--robust", "Fc=0.2", "Fs=0.2"], "the corner Fc = 6, Fs = 5.6 is refused"),
    (["--free", "Kp=2:50", "--tolerance", "0"], "tolerance = 0: a standing error above 0"),
    (["--free", "Kp=2:50", "--count", "99"], "--count: 99 is out of range"),
    (["--free", "Kp=2:50", "--set", "Dv=0.01"], "tune: Dv = 0.01 is out of range: Dv must be 0 in the exact"),
])
def test_tune_refuses_in_one_line(tmp_path, words, message):
    code, out, err = cli("tune", "friction", "--G", "Kp + Ki/s", "--set", "Ki=1", "d=0.1", "--compensate",
                         "deadband", *words, cwd=tmp_path)
    assert code == 2 and err.count("\n") == 1 and message in err, err


@pytest.mark.parametrize("given, message", [
    ({"robust": [1, 2]}, "robust = [1, 2]: give {name: relative error}"),
    ({"free": {"Kp": (1, 1e400)}}, "free Kp hi = inf: give a finite number"),
    ({"free": {"Kp": (1, 2, 3)}}, "free Kp = (1, 2, 3): give (lo, hi)"),
    ({"free": {}}, "free = {}: give {name: (lo, hi)}"),
])
def test_tune_refuses_a_bad_value_of_the_api_in_one_line(given, message):
    with pytest.raises(InputError) as error:
        dfwb.tune("friction", "Kp + Ki/s", **dict(dict(free={"Kp": (1, 2)}, Ki=1, count=2), **given))
    assert str(error.value) == message or str(error.value).startswith(message), str(error.value)


# -- the DF of a compensated loop, where the compensated plant is a plant -------------------------------------------
PID = "20 + 100/s + 2*s/(0.1*s+1)"


def test_the_velocity_feedforward_is_the_friction_mass_with_less_coulomb_friction():
    """F_hat sgn(v) on the friction mass (Fc = 5, Fs = 7) is the mass with Fc = 3 and the same Fs: the exact loops
    find the same true cycles (to rounding: F_hat enters as a force of its own)."""
    pairs = []
    for compensate, values in (("coulomb", {"F_hat": 2.0}), (None, {"Fc": 3.0})):
        found = dfwb.limit_cycles("friction", PID, exact=True, compensate=compensate, amplitudes=[0.3], **values)
        pairs.append(sorted((c.omega, c.amplitude_x, c.stable) for c in found.cycles))
    assert len(pairs[0]) == len(pairs[1]) == 2
    for a, b in zip(*pairs):
        assert a[2] == b[2] and abs(a[0] - b[0]) < 1e-9 * b[0] and abs(a[1] - b[1]) < 1e-9 * b[1]


def test_the_df_of_the_velocity_feedforward_predicts_the_compensated_cycles():
    response = dfwb.limit_cycles("friction", PID, exact=True, compensate="coulomb", F_hat=2.0)
    assert response.as_dict()["df_params"] == {"Fc": 3.0} and len(response.predictions) == 2
    for i, prediction in enumerate(response.predictions):  # each DF cycle has its true cycle, within 2 %
        true = response.cycles[response.links[i]]
        assert abs(prediction.omega / true.omega - 1.0) < 0.02 and prediction.stable == true.stable
    assert "as the plant with Fc = 3" in response.summary()


@pytest.mark.parametrize("compensate, values", [("coulomb", {"F_hat": 6.0}), ("coulomb", {"F_hat": 2.0,
                                                "signal": "control"}), (["coulomb", "reset"], {"F_hat": 2.0})])
def test_a_compensated_loop_with_no_equivalent_plant_has_no_df(compensate, values):
    """Over-compensation (F_hat > Fc), the controller's sign and the integrator's management are no plant."""
    family = LoopFamily("friction", PID, values, compensate=compensate)
    assert family.compensation.equivalent(family.spec, family.params(), family.merged()) is None


def test_a_map_over_the_feedforward_has_its_df_where_the_compensated_plant_is_a_plant(tmp_path):
    """Up to F_hat = Fc each cell's DF is the plant's with Fc - F_hat, side by side with the truth and the cost;
    beyond (over-compensation) there is none. The figure then has three panels."""
    response = dfwb.hunting_map("friction", PID.replace("20", "Kp", 1), ("Kp", 18, 24, 2), ("F_hat", 0, 6, 3),
                                compensate="coulomb", jobs=1, cache=False, curves=False, out_dir=tmp_path / "map")
    df, truth = response.classes("df"), response.classes("truth")
    assert list(df[-1]) == ["uncomputed", "uncomputed"]  # F_hat = 6 > Fc = 5
    assert "uncomputed" not in df[:-1] and (df[0] == truth[0]).all() and "stable" in truth[0]
    assert response.has_df and response.compensated and len(response.plot()) == 3
    assert "the DF misses" in response.summary() and "cost:" in response.summary()


def test_the_feedforward_followed_in_f_hat_has_its_df_branches_up_to_their_fold():
    """Under the PID, the stable true cycle ends at a fold at F_hat = 2.107 N (it meets the unstable one); the DF
    of the plant with Fc - F_hat has its two branches meet at 2.21 N, 5 % beyond. Past Fc the DF has no plant."""
    branch = dfwb.continuation("friction", PID, "F_hat", 0.0, 6.0, compensate="coulomb")
    truth = [b.parameter for b in branch.bifurcations if b.source == "truth"]
    df_ends = [max(p.parameter for p in b.points) for b in branch.branches if b.source == "df"]
    assert len(truth) == 1 and abs(truth[0] - 2.1069249) < 1e-5
    assert len(df_ends) == 2 and all(abs(end / truth[0] - 1.0) < 0.06 for end in df_ends)
    assert any("F_hat = 6: no DF" in note for note in branch.notes)
