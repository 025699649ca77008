"""The true limit cycles of the exact closed loop (dfwb.engine.periodic, dfwb.engine.cycles): shooting on the
event section, Floquet stability, the systematic search and its links to the DF.

Every cycle is checked against what it claims: a periodic orbit (Newton's
residual, and an independent scipy event-driven loop that returns to the same
state after one period), the same orbit shot from another point of it,
harmonics that do not move with the quadrature, and a stability verdict that
a simulation from a perturbed start confirms.
"""

import json
import math

import numpy as np
import pytest

from dfwb.engine import periodic
from dfwb.engine.cycles import find_cycles, link, relative_errors
from dfwb.engine.limit_cycles import Cycle
from dfwb.engine.periodic import LoopProblem
from dfwb.plants.loop_reference import closed_loop_reference

# (plant, G, params, rest start): the four examples' loops and five more controllers
LOOPS = {
    "friction_pid": ("friction", "20 + 100/s + 2*s/(0.1*s+1)", {}, 0.3),
    "friction_pi": ("friction", "30 + 60/s", {}, 0.1),
    "friction_pid_stiff": ("friction", "40 + 200/s + 4*s/(0.05*s+1)", {}, 0.1),
    "backlash_lead_eps02": ("backlash", "200*(s+2)/(s+20)", {"eps": 0.2}, 0.03),
    "backlash_lead_eps08": ("backlash", "200*(s+2)/(s+20)", {"eps": 0.8}, 0.03),
    "backlash_lead_eps05": ("backlash", "100*(s+1)/(s+10)", {"eps": 0.5}, 0.03),
    "backlash_lead_plastic": ("backlash", "50*(s+3)/(s+30)", {"eps": 0.0}, 0.1),
    "static_backlash_lead": ("static-backlash", "20*(s+2)/(s+20)", {}, 0.3),
    "static_backlash_lead2": ("static-backlash", "40*(s+1)/(s+10)", {}, 0.01),
}


def settled(problem, start, hits=300):
    """The section state a simulation from rest at ``start`` reaches after ``hits`` section hits."""
    solver = problem.solver(problem.rest_start(start))
    for _ in range(hits):
        assert problem.hit(solver, problem.horizon)
    return solver.state()


@pytest.fixture(scope="module")
def stable_cycles():
    """The stable cycle each loop settles to from rest."""
    found = {}
    for name, (plant, G, params, start) in LOOPS.items():
        problem = LoopProblem(plant, G, params)
        cycle = problem.shoot(settled(problem, start), on_section=True)
        assert cycle is not None, name
        found[name] = (problem, cycle)
    return found


def along(problem, cycle, fraction):
    """The cycle's state a fraction of its period after its section state (away from events, in general)."""
    solver = problem.solver(cycle.state)
    solver.advance(fraction * cycle.period)
    return solver.state()


def _swing(problem, cycle):
    trace_states = []
    solver = problem.solver(cycle.state)
    for t in np.linspace(0.0, cycle.period, 33)[1:]:
        solver.advance(float(t))
        trace_states.append(solver.state())
    states = np.array(trace_states)
    return np.maximum(np.ptp(states, axis=0), 1e-9 * np.abs(states).max())


@pytest.mark.parametrize("name", list(LOOPS))
def test_a_cycle_is_periodic_to_the_residual_and_for_scipy(stable_cycles, name):
    problem, cycle = stable_cycles[name]
    assert cycle.residual <= 1e-10
    assert cycle.stable and max(cycle.multipliers) < 1.0
    assert cycle.period > 0.0 and cycle.amplitude_x > 0.0 and cycle.F > 0.0
    assert cycle.returns == 1 and len(cycle.sections) == 1 and len(cycle.signature) == cycle.counts["events"]
    # an independent event-driven scipy loop, one period from a state of the cycle, comes back to it
    start = along(problem, cycle, 0.37)
    reference = closed_loop_reference(problem.spec.name, problem.b, problem.a, cycle.period, problem.params,
                                      state=start)
    swing = _swing(problem, cycle)
    error = np.abs(np.array(reference["state"]) - np.array(start)) / swing
    assert error.max() < 1e-10, (name, error)  # seen: 1e-13 to 2e-12
    assert len(reference["events"]) == cycle.counts["events"]


@pytest.mark.parametrize("name", ["friction_pid", "backlash_lead_eps02", "static_backlash_lead"])
def test_the_same_cycle_from_another_point_and_quadrature(stable_cycles, name, monkeypatch):
    problem, cycle = stable_cycles[name]
    again = problem.shoot(along(problem, cycle, 0.61))
    assert again is not None
    for key in ("omega", "amplitude_x", "F"):
        assert getattr(again, key) == pytest.approx(getattr(cycle, key), rel=1e-8)
    assert again.signature == cycle.signature
    monkeypatch.setattr(periodic, "GAUSS_NODES", 10)
    harmonics, F, counts, _ = problem.period_trace(cycle.state, cycle.period)
    assert harmonics[1] == pytest.approx(cycle.amplitude_x, rel=1e-11)
    assert F == pytest.approx(cycle.F, rel=1e-11)
    assert counts == cycle.counts


def _hits(problem, state, count):
    """The section states of ``count`` hits from ``state``."""
    solver, hits = problem.solver(state), []
    for _ in range(count):
        assert problem.hit(solver, problem.horizon)
        hits.append(np.array(solver.state()))
    return hits


@pytest.mark.parametrize("name", ["friction_pid", "backlash_lead_eps08", "static_backlash_lead2"])
def test_a_stable_cycle_attracts_a_perturbed_start(stable_cycles, name):
    problem, cycle = stable_cycles[name]
    swing = _swing(problem, cycle)
    start = np.array(along(problem, cycle, 0.5))
    start += 1e-3 * swing * np.where(np.arange(len(swing)) == problem.output, 0.0, 1.0)
    if problem.spec.name == "static-backlash":  # stay inside the play: move x towards its middle
        start[0] -= 2e-3 * swing[0] * np.sign(start[0] - start[2] / problem.params.get("k", 1.0))
    hits = _hits(problem, list(start), 60)
    distance = np.abs((hits[-1] - np.array(cycle.state)) / swing).max()
    assert distance < 1e-7


def test_the_issue_table_truths_and_the_unstable_cycle():
    """The truths behind the DF predictions of issue 13's table, both stable and unstable."""
    pid = LoopProblem("friction", "20 + 100/s + 2*s/(0.1*s+1)")
    predictions = [Cycle(F=8.6348346, omega=3.4061359, N=0.269278 / 8.6348346, amplitude_x=0.269278,
                         distortion=0.08, stable=True, loeb=1.0, residual=0.0, periodic=True),
                   Cycle(F=15.557092, omega=4.728799, N=0.572046 / 15.557092, amplitude_x=0.572046,
                         distortion=0.02, stable=False, loeb=-1.0, residual=0.0, periodic=True)]
    found = find_cycles(pid, predictions)
    cycles, links = found.cycles, found.links
    assert len(cycles) == 2 and links == [0, 1]
    stable, unstable = cycles
    assert (round(stable.omega, 3), round(stable.amplitude_x, 4)) == (3.697, 0.3122)
    assert (round(unstable.omega, 3), round(unstable.amplitude_x, 4)) == (4.703, 0.5630)
    assert stable.stable and not unstable.stable and max(unstable.multipliers) > 1.5
    assert unstable.residual <= 1e-10 and "prediction 1 (shot)" in unstable.started_from
    errors = relative_errors(predictions[0], stable)
    assert errors["omega"] == pytest.approx(3.4061359 / stable.omega - 1.0)
    # the simulation's verdict: a start next to the unstable cycle leaves it
    swing = _swing(pid, unstable)
    start = np.array(along(pid, unstable, 0.5)) + 1e-4 * swing * np.array([0.0, 1.0, 1.0, 1.0])
    hits = _hits(pid, list(start), 30)
    assert np.abs((hits[-1] - np.array(unstable.state)) / swing).max() > 1e-2
    # what the search covered: every run's fate counted, the stable cycle reached from most starts
    coverage = found.coverage
    assert coverage.complete and coverage.predictions == 2 and coverage.starts == len(found.fates)
    assert sum(coverage.outcomes.values()) == coverage.starts and coverage.outcomes["cycle"] > 10


def test_a_cycle_the_df_misses_and_a_false_alarm():
    """eps = 0.8: the DF finds no periodic balance, the loop has a stable cycle; a made-up prediction has none."""
    problem = LoopProblem("backlash", "200*(s+2)/(s+20)", {"eps": 0.8})
    far = Cycle(F=50.0, omega=0.5, N=1e-3, amplitude_x=0.05, distortion=0.0, stable=True, loeb=1.0, residual=0.0,
                periodic=True)
    cycles = find_cycles(problem, [], amplitudes=[0.03]).cycles
    assert len(cycles) == 1 and cycles[0].prediction is None and cycles[0].stable
    assert cycles[0].omega == pytest.approx(22.8769, rel=1e-5)
    assert link([far], cycles) == [None]


def test_links_pair_each_prediction_with_its_nearest_cycle_once():
    def fake(omega, x):
        return Cycle(F=1.0, omega=omega, N=x, amplitude_x=x, distortion=0.0, stable=True, loeb=1.0, residual=0.0,
                     periodic=True)

    truths = [fake(1.0, 1.0), fake(3.0, 1.0)]
    assert link([fake(1.1, 1.2), fake(1.05, 1.0), fake(2.5, 0.9), fake(10.0, 1.0)], truths) == [None, 0, 1, None]


def test_refusals_name_the_value():
    with pytest.raises(Exception, match="Dv"):
        LoopProblem("friction", "10 + 1/s", {"Dv": 0.01})
    with pytest.raises(Exception, match="order"):
        LoopProblem("friction", "1/(s+1)**9")
    with pytest.raises(Exception, match="improper"):
        LoopProblem("backlash", "s**2/(s+1)")
    assert math.isfinite(LoopProblem("backlash", "2/(s+1)").b[1])


def test_the_command_line_reports_the_truth_beside_the_prediction(fmus, capsys, tmp_path):
    from dfwb.cli import main

    argv = ["limit-cycle", "static-backlash", "--G", "20*(s+2)/(s+20)", "--F-range", "0.01", "100",
            "--omega-range", "0.1", "50", "--exact", "--fmus", str(fmus["StaticBacklash"].parent)]
    assert main(argv + ["--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report) >= {"plant", "G", "params", "predictions", "cycles"}
    (prediction,), cycles = report["predictions"], report["cycles"]
    assert {"F", "omega", "amplitude_x", "stable", "true_cycle", "error"} <= set(prediction)
    j = prediction["true_cycle"]
    cycle = cycles[j]
    assert {"omega", "period", "amplitude_x", "F", "stable", "multipliers", "prediction"} <= set(cycle)
    assert cycle["prediction"] == 0 and cycle["stable"] is True
    assert cycle["omega"] == pytest.approx(0.8974612278741, rel=1e-9)
    assert cycle["period"] == pytest.approx(2 * math.pi / cycle["omega"], rel=1e-14)
    assert prediction["error"]["omega"] == pytest.approx(prediction["omega"] / cycle["omega"] - 1.0, rel=1e-12)
    assert all(m < 1.0 for m in cycle["multipliers"])
    png = tmp_path / "truth.png"
    assert main(argv + ["--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "true cycle [0]: DF error omega +1.81%" in text and "1 true cycle(s)" in text
    assert png.stat().st_size > 20_000


def test_the_command_line_refuses_a_loop_it_cannot_integrate(fmus, capsys):
    from dfwb.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["limit-cycle", "friction", "--G", "10 + 5/s", "--set", "Dv=0.01", "--exact",
              "--fmus", str(fmus["FrictionMass"].parent)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Dv" in err[0]


def test_a_search_of_a_loop_too_stiff_for_its_budget_says_it_is_incomplete():
    problem = LoopProblem("friction", "20 + 100/s + 2*s/(1e-4*s+1)", max_chunks=20_000)
    found = find_cycles(problem, [])
    assert problem.budget.left < 0 and not found.coverage.complete
    assert "INCOMPLETE: the work budget ran out" in found.coverage.summary()


@pytest.mark.needs_cc
def test_the_compiled_loop_runs_by_default_and_finds_the_python_loops_cycles(monkeypatch):
    """LoopProblem runs the C loop (the default kind, native) and DFWB_FMU=python the Python loop: the
    same cycles, bit for bit (periods, states, multipliers)."""
    from dfwb.fmus.friction import FrictionLoop

    monkeypatch.delenv("DFWB_FMU", raising=False)
    native = LoopProblem("friction", "20 + 100/s + 2*s/(0.1*s+1)")
    assert native.cls.__name__ == "NativeFrictionLoop"
    monkeypatch.setenv("DFWB_FMU", "python")
    python = LoopProblem("friction", "20 + 100/s + 2*s/(0.1*s+1)")
    assert python.cls is FrictionLoop
    found = [find_cycles(problem, [], amplitudes=[0.3], boundaries=False).cycles for problem in (native, python)]
    assert len(found[0]) == len(found[1]) >= 1
    for a, b in zip(*found):
        assert (a.period, a.state, a.multipliers, a.amplitude_x) == (b.period, b.state, b.multipliers, b.amplitude_x)
