"""Cycles followed in one parameter (dfwb.engine.continuation, dfwb.continuation, dfwb continue): every
bifurcation is located and then confirmed by what the search finds on its two sides.

- The PI-controlled friction mass (Kp = 10) hunts for Ki from 0 up to a nonsmooth fold near Ki = 24.77,
  where the stable hunting cycle (with stick phases) meets the unstable cycle above it (without them)
  with multipliers near 0.8 and 2.2, not 1 (the issue's observation); the unstable branch goes to
  infinity as Ki falls to the linear loop's stability boundary Ki = B Kp / M = 5 (Routh: M s^3 + B s^2 +
  Kp s + Ki). Both are confirmed 1e-4 on either side by the systematic search and by python-control.
- The DF's prediction for a PID controller turns back at a smooth fold (-1/N touches G(jw)); confirmed by
  the DF search on both sides.
- The hunting cycle shrinks to rest as the static friction falls to the Coulomb level.
- A branch whose work budget runs out ends there, keeping its points; a cached record of another shape
  is recomputed, never trusted.
- The command line prints the documented JSON and refuses hostile input in one line before anything runs.
"""

import json
import math

import control
import numpy as np
import pytest

import dfwb
from dfwb.engine.cycles import find_cycles
from dfwb.engine.family import LoopFamily
from dfwb.engine.limit_cycles import search
from dfwb.engine.scales import search_ranges

PI = "Kp + Ki/s"
PID = "Kp + Ki/s + Kd*s/(Tf*s + 1)"


@pytest.fixture(scope="module")
def pi_in_ki():
    return dfwb.continuation("friction", PI, "Ki", 1.0, 30.0, Kp=10, sources="truth")


def _kinds(response):
    return {b.kind: b for b in response.bifurcations}


def test_the_hunting_branch_of_pi_ends_at_a_nonsmooth_fold(pi_in_ki):
    fold = _kinds(pi_in_ki)["nonsmooth-fold"]
    assert fold.source == "truth" and 24.5 < fold.parameter < 25.0
    assert fold.accuracy <= 1e-4 * fold.parameter
    assert "break-" in fold.detail and "two branches meet" in fold.detail
    sides = [float(m) for m in fold.detail.split("|multipliers| ")[1].split(" on ")[0].replace("|", ",").split(",")]
    assert max(sides) > 2.0 and 0.7 < max(m for m in sides if m < 1.0) < 0.9  # about 0.8 and 2.2, not 1
    family = LoopFamily("friction", PI, {"Kp": 10}, free=("Ki",))
    below = find_cycles(family.problem({"Ki": fold.parameter * (1 - 1e-4)}))
    above = find_cycles(family.problem({"Ki": fold.parameter * (1 + 1e-4)}))
    hunting = below.stable()
    assert len(hunting) == 1 and "break-" in hunting[0].signature  # the stable cycle sticks
    assert hunting[0].amplitude_x == pytest.approx(fold.amplitude_x, rel=1e-2)
    assert above.cycles == [] and above.coverage.outcomes.get("diverged", 0) > 0  # beyond: every motion grows


def test_the_unstable_branch_goes_to_infinity_at_the_linear_boundary(pi_in_ki):
    end = _kinds(pi_in_ki)["infinity"]
    assert end.parameter == pytest.approx(5.0, rel=1e-9)  # B Kp / M
    plant = control.tf([1.0], [1.0, 0.5, 0.0])  # the friction mass without friction: 1 / (M s^2 + B s)
    for Ki, stable in ((5.0 * (1 - 1e-4), True), (5.0 * (1 + 1e-4), False)):
        poles = control.feedback(control.tf([10.0, Ki], [1.0, 0.0]) * plant, 1).poles()
        assert bool(np.all(poles.real < 0)) is stable
    (branch,) = pi_in_ki.branches
    unstable = [p for p in branch.points if not p.stable]
    assert unstable and min(p.parameter for p in unstable) < 5.1 and max(p.amplitude_x for p in unstable) > 100.0
    stable = [p for p in branch.points if p.stable]
    assert stable[0].parameter == 1.0 and all(len(p.signature) == 4 for p in stable)  # two stick phases a period


def test_the_branch_is_the_truth_at_its_points(pi_in_ki):
    """Points of the branch are the search's cycles at their parameter values (same w and X to 1e-8)."""
    (branch,) = pi_in_ki.branches
    family = LoopFamily("friction", PI, {"Kp": 10}, free=("Ki",))
    for point in [p for p in branch.points if p.stable][::12]:
        cycles = find_cycles(family.problem({"Ki": point.parameter}), boundaries=False).stable()
        assert any(abs(c.omega / point.omega - 1) < 1e-8 and abs(c.amplitude_x / point.amplitude_x - 1) < 1e-8
                   for c in cycles), point


def test_the_df_prediction_of_a_pid_controller_turns_at_a_smooth_fold():
    response = dfwb.continuation("friction", PID, "Ki", 10.0, 300.0, Kp=20, Kd=2, Tf=0.1, sources="df",
                                 starts=[100.0])
    folds = [b for b in response.bifurcations if b.kind == "fold"]
    assert len(folds) == 1 and folds[0].source == "df"
    fold = folds[0]
    assert fold.accuracy <= 1e-4 * fold.parameter
    family = LoopFamily("friction", PID, {"Kp": 20, "Kd": 2, "Tf": 0.1}, free=("Ki",))

    def near(value):
        problem = family.problem({"Ki": value})
        F, omega = search_ranges(problem)
        found = search("friction", problem.G, problem.params, F, omega, n_F=32, n_omega=96).cycles
        return [p for p in found if abs(math.log(p.omega / fold.omega)) < 0.2]

    assert len(near(fold.parameter * (1 - 1e-4))) == 2  # the stable and the unstable prediction, close
    assert near(fold.parameter * (1 + 1e-4)) == []


def test_the_hunting_cycle_shrinks_to_rest_as_static_friction_falls_to_coulomb():
    response = dfwb.continuation("friction", PI, "Fs", 5.0, 9.0, Kp=10, Ki=2, sources="truth")
    rest = _kinds(response)["shrinks-to-rest"]
    assert rest.parameter == pytest.approx(5.0, abs=1e-3)  # Fc
    (branch,) = response.branches
    amplitudes = [p.amplitude_x for p in sorted(branch.points, key=lambda p: p.parameter)]
    assert all(b > a for a, b in zip(amplitudes, amplitudes[1:]))  # more static friction, more hunting
    assert find_cycles(LoopFamily("friction", PI, {"Kp": 10, "Ki": 2, "Fs": 5.0}).problem()).cycles == []


def test_the_command_line_prints_the_documented_json(fmus, capsys):
    from dfwb.cli import main

    assert main(["continue", "friction", "--G", PI, "--set", "Kp=10", "--parameter", "Ki=1:30", "--source", "truth",
                 "--json", "--fmus", str(fmus["FrictionMass"].parent)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["parameter"] == "Ki" and report["range"] == [1.0, 30.0]
    (branch,) = report["branches"]
    assert branch["source"] == "truth"
    assert {"parameter", "omega", "amplitude_x", "F", "stable", "multipliers"} <= set(branch["points"][0])
    kinds = {b["kind"]: b for b in report["bifurcations"]}
    assert set(kinds) == {"nonsmooth-fold", "infinity"}
    assert {"kind", "parameter", "omega", "amplitude_x", "source"} <= set(kinds["infinity"])


@pytest.mark.parametrize("argv, message", [
    (["--G", PI, "--parameter", "Ki=1:30"], "the parameter Kp is given no value"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "Ki=nan:30"], "Ki start = nan: the range's ends must be finite"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "Ki=1:inf"], "Ki stop = inf: the range's ends must be finite"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "Ki=3:3"], "the range is empty"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "Ki=-1e308:1e308"], "wider than the floats"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "s=1:3"], "s is the variable of G(s), not a parameter"),
    (["--G", PI, "--set", "Kp=10", "s=2", "--parameter", "Ki=1:3"], "s is the variable of G(s), not a parameter"),
    (["--G", PI, "--set", "Kp=10", "Ki=2", "--parameter", "Ki=1:3"], "Ki is the parameter followed"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "x0=1:3"], "unknown parameter 'x0'"),
    (["--G", PI, "--set", "Kp=10", "--parameter", "Ki"], "expected NAME=START:STOP"),
    (["--G", PI, "--set", "Kp=10", "Ki=2", "--parameter", "M=-1:1"], "M = -1:1: M = -1.0 is out of range: M must be in [1e-06, 1e+06] kg"),
])
def test_hostile_input_is_one_line_before_anything_runs(capsys, argv, message):
    from dfwb.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["continue", "friction"] + argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_a_branch_whose_budget_runs_out_ends_there_with_its_points():
    from dfwb.engine.continuation import SPENT, CycleSystem, follow
    from dfwb.fmus.hybrid import Budget

    family = LoopFamily("friction", PI, {"Kp": 10}, free=("Ki",))
    problem = family.problem({"Ki": 2.0})
    (cycle,) = find_cycles(problem).stable()
    swing = [v for i, v in enumerate(cycle.swing) if i != problem.pivot]
    system = CycleSystem(family, "Ki", 29.0, cycle.returns, swing, cycle.period, None, Budget(2000))
    nodes, reason = follow(system, np.array(problem.reduced(cycle.state) + [2.0]), 1.0, (1.0, 30.0))
    assert reason == SPENT and 2 <= len(nodes) and system.budget.left < 0
    values = [node.y[-1] for node in nodes]
    assert values == sorted(values) and values[-1] < 24.0  # short of the fold: the branch is cut, not made up
    for node in nodes[1:3]:  # what it kept is the truth
        (found,) = find_cycles(family.problem({"Ki": float(node.y[-1])})).stable()
        assert found.period == pytest.approx(node.point.period, rel=1e-8)


def test_a_cached_continuation_of_another_shape_is_recomputed(pi_in_ki):
    from dfwb.studies.responses import ContinuationResponse
    from dfwb.studies.runner import _cached_continuation

    record = json.loads(json.dumps(pi_in_ki.as_dict()))
    again = _cached_continuation(record)
    assert again.as_dict() == record and again.summary() == pi_in_ki.summary()
    crafted = []
    for path, value in [(("range",), ["1", 30.0]), (("range",), [1.0]), (("branches",), [{"source": "truth"}]),
                        (("branches", 0, "points"), []), (("branches", 0, "returns"), 0),
                        (("branches", 0, "points", 0, "stable"), "yes"), (("bifurcations", 0, "parameter"), math.nan),
                        (("bifurcations", 0, "kind"), ["fold"]), (("notes",), "text"), (("unit",), None),
                        (("searches",), [{"parameter": 1.0}]), ((), [1, 2])]:
        document = json.loads(json.dumps(record))
        if not path:
            document = value
        else:
            target = document
            for key in path[:-1]:
                target = target[key]
            target[path[-1]] = value
        crafted.append(document)
    deep = []
    for _ in range(100_000):
        deep = [deep]
    crafted.append(dict(record, notes=deep))
    for document in crafted:
        assert _cached_continuation(document) is None
        with pytest.raises(ValueError):
            ContinuationResponse.from_dict(document)
