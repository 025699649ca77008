"""The drivetrain (fmus/drivetrain.py): a gear with play driving a load that sticks.

Checked against its limits (the two-mass backlash without load friction, the friction mass of mass M1 + M2
with a rigid coupling), the independent event-driven reference (tests/drivetrain_reference.py, scipy,
open and closed loop), closed forms (the masses parting although the force presses them together) and
balances (momentum and energy across elastic impacts while the load slides). What every plant shares (the
C twin bit for bit, states, FMUs, loops in C) is tests/test_every_plant.py's.
"""

import copy
import re

import numpy as np
import pytest
from drivetrain_reference import simulate

from dfwb.fmus.backlash import BacklashLoop, TwoMassBacklash
from dfwb.fmus.drivetrain import Drivetrain, DrivetrainLoop
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop, FrictionMass

TIMES = np.linspace(0.0, 12.0, 241)


def _trace(plant, fields, times=TIMES):
    rows = []
    for t in times:
        plant.advance(float(t))
        output = plant.output()
        rows.append([getattr(output, field) for field in fields])
    return np.array(rows)


@pytest.mark.parametrize("eps, F, omega", [(0.5, 50.0, 20.0), (0.0, 30.0, 5.0), (0.8, 10.0, 1.0)])
def test_without_load_friction_it_is_the_two_mass_backlash(eps, F, omega):
    ours = Drivetrain(eps=eps, B=0.0, Fc=0.0, Fs=0.0, F=F, omega=omega)
    theirs = TwoMassBacklash(eps=eps, F=F, omega=omega)
    fields = ["x1", "v1", "gap", "v2"]
    difference = np.abs(_trace(ours, fields) - _trace(theirs, fields))
    assert ours.impacts == theirs.impacts >= 20
    assert difference.max() < 1e-11, difference.max(axis=0)


@pytest.mark.parametrize("F, omega, f", [(10.0, 1.0, 0.0), (30.0, 5.0, 2.0), (6.0, 1.0, 0.0)])
def test_a_rigid_coupling_is_the_friction_mass_of_both_masses(F, omega, f):
    ours = Drivetrain(h=0.0, M1=0.7, M2=1.3, F=F, omega=omega, f=f)
    theirs = FrictionMass(M=2.0, F=F, omega=omega, f=f)
    times = np.linspace(0.0, 30.0, 301)
    a, b = _trace(ours, ["x1", "v1", "x2", "gap"], times), _trace(theirs, ["x", "v"], times)
    assert np.abs(a[:, :2] - b).max() < 1e-12
    assert np.array_equal(a[:, 2], a[:, 0]) and not a[:, 3].any()  # one body
    assert ours.events == theirs.events


@pytest.mark.parametrize("parameters", [dict(F=10.0, omega=1.0), dict(F=30.0, omega=5.0), dict(F=8.0, omega=2.0, eps=0.0),
                                        dict(F=20.0, omega=3.0, eps=0.8, f=1.0), dict(F=15.0, omega=2.0, M1=3.0, h=0.5)])
def test_it_follows_the_independent_reference(parameters):
    plant = Drivetrain(**parameters)
    plant.event_log = []
    ours = _trace(plant, ["x1", "v1", "gap"])
    _, reference, events = simulate(12.0, times=TIMES, **parameters)
    assert len(plant.event_log) == len(events) > 10
    assert np.abs(ours - reference[:, :3]).max() < 1e-10


@pytest.mark.parametrize("b, a, parameters", [
    ([10.0, 2.0], [0.0], dict(x1_0=0.5)),  # PI: the load hunts
    ([30.0, 60.0], [0.0], dict(x1_0=0.3, eps=0.0)),
    ([4.0, 1.0], [2.0], dict(x1_0=0.5, v2_0=1.0)),
    ([50.0, 20.0, 5.0], [3.0, 0.0], dict(x1_0=-0.4, h=0.02)),
])
def test_its_closed_loop_follows_the_independent_reference(b, a, parameters):
    times = np.linspace(0.0, 60.0, 121)
    _, reference, events = simulate(60.0, times=times, b=b, a=a, **parameters)
    loop = DrivetrainLoop(b, a, **parameters)
    states = []
    for t in times:
        loop.advance(float(t))
        states.append(loop.state())
    assert len(events) > 5
    assert np.abs(np.array(states) - reference).max() < 1e-9


@pytest.mark.parametrize("x0", [0.3, 1.0])
def test_its_closed_loop_reduces_to_the_friction_and_backlash_loops(x0):
    times = np.linspace(0.0, 100.0, 101)[1:]
    pairs = [(DrivetrainLoop([10.0, 2.0], [0.0], h=0.0, M1=0.5, M2=1.5, x1_0=x0),
              FrictionLoop([10.0, 2.0], [0.0], M=2.0, x0=x0)),
             (DrivetrainLoop([4.0, 1.0], [2.0], B=0.0, Fc=0.0, Fs=0.0, x1_0=x0),
              BacklashLoop([4.0, 1.0], [2.0], x1_0=x0))]
    for ours, theirs in pairs:
        for t in times:
            ours.advance(float(t))
            theirs.advance(float(t))
            assert ours.state()[:2] == pytest.approx(theirs.state()[:2], rel=0.0, abs=1e-12), t
    assert pairs[1][0].impacts == pairs[1][1].impacts > 10


def test_the_masses_part_where_the_force_presses_but_the_load_brakes_harder():
    """Together at gap h moving backwards, u = 1 N presses M2 onto the load, but the load's friction brakes it at
    5 m/s^2 against M2's 1 m/s^2: they part at once (the backlash's rule, sigma u > 0, would hold them), and the
    gap closes as h - 0.5 (5 - 1) t^2 until the load stops."""
    plant = Drivetrain(B=0.0, Fc=5.0, Fs=7.0, f=1.0, gap0=0.1, v1_0=-1.0, v2_0=-1.0)
    for t in (0.01, 0.05, 0.1):
        plant.advance(t)
        assert plant.contact == 0 and plant.slip == -1
        assert plant.output().gap == pytest.approx(0.1 - 2.0 * t * t, abs=1e-15)
        assert plant.output().v1 == pytest.approx(-1.0 + 5.0 * t, abs=1e-15)


def test_momentum_and_energy_balance_across_elastic_impacts_while_the_load_slides():
    """No force on M2, the load braked by Coulomb friction alone, elastic impacts: the momentum falls at the
    rate Fc and the energy by Fc times the load's path, whatever the impacts do."""
    M1, M2, Fc = 1.5, 0.5, 1.0
    plant = Drivetrain(M1=M1, M2=M2, h=0.05, eps=1.0, B=0.0, Fc=Fc, Fs=Fc, v1_0=1.0, v2_0=3.0)
    P0, E0 = M1 * 1.0 + M2 * 3.0, 0.5 * M1 + 0.5 * M2 * 9.0
    checked = 0
    for t in np.linspace(0.0, 3.0, 301)[1:]:
        plant.advance(float(t))
        if plant.slip != 1:
            break
        out = plant.output()
        assert M1 * out.v1 + M2 * out.v2 + Fc * t == pytest.approx(P0, abs=1e-12)
        assert 0.5 * M1 * out.v1 ** 2 + 0.5 * M2 * out.v2 ** 2 + Fc * out.x1 == pytest.approx(E0, abs=1e-12)
        checked += 1
    assert plant.impacts > 5 and checked > 50


def test_the_result_does_not_depend_on_the_communication_step():
    one = Drivetrain(F=20.0, omega=3.0, eps=0.8, f=1.0)
    one.advance(20.0)
    many = Drivetrain(F=20.0, omega=3.0, eps=0.8, f=1.0)
    for t in np.linspace(0.0, 20.0, 1001)[1:]:
        many.advance(float(t))
    assert one.output() == many.output() and one.integrals() == many.integrals() and one.events == many.events


def test_a_copy_continues_as_the_original_and_input_changes_restart_it():
    plant = Drivetrain(F=20.0, omega=3.0, f=1.0)
    plant.advance(3.3)
    twin = copy.deepcopy(plant)
    for solver in (plant, twin):
        for k, t in enumerate(np.linspace(3.3, 9.0, 58)[1:]):
            solver.set_input(4.0 * np.sin(k))
            solver.advance(float(t))
    assert plant.output() == twin.output() and plant.impacts == twin.impacts


@pytest.mark.parametrize("name, value, text", [
    ("M1", 0.0, "M1 must be > 0"), ("M1", 2 ** 1100, "M1 must be > 0"), ("M2", -1.0, "M2 must be > 0"), ("h", 1e-300, "h must be 0 (rigid) or >= 1e-290"),
    ("eps", 1.5, "eps must be in [0, 1]"), ("B", -0.1, "B must be >= 0"), ("Fc", float("nan"), "Fc must be >= 0"),
    ("Fs", 4.0, "Fs must be >= Fc = 5.0"), ("gap0", 0.2, "gap0 must be in [0, h] = [0, 0.1]"),
    ("x1_0", float("inf"), "x1_0 must be a finite number"), ("v2_0", "1", "v2_0 must be a finite number"),
])
def test_each_parameter_out_of_range_is_refused_by_name(name, value, text):
    for make in (lambda: Drivetrain(**{name: value}), lambda: DrivetrainLoop([1.0, 1.0], [0.0], **{name: value})):
        with pytest.raises(PlantError, match=f"^{name} = .* is out of range: {re.escape(text)}"):
            make()


def test_a_slow_weak_drive_knocks_the_stuck_load_along_in_c_as_in_python(core):
    """1e-6 N at a period of 2813 s (a corner of the DF map): M2 drifts into the stuck load and kicks it along in
    ever shorter cycles of an impact and a stop until they move together. A piece's searches end at the
    first event found: past the stop, the force pressing the masses together tends to zero, and resolving it
    there once took more than 1e5 evaluations."""
    parameters = dict(F=1e-6, omega=0.0022335738043193646)
    python, c = Drivetrain(**parameters), core.Drivetrain(**parameters)
    for solver in (python, c):
        solver.advance(2813.063662829918)
    assert python.output() == c.output() and python.events == c.events > 20 and python.impacts > 10


@pytest.mark.parametrize("B", [5.0, 1e9])
def test_a_light_load_braked_hard_is_resolved_by_decaying_bounds(core, B):
    """M1 = 1e-6 kg at 1e6 m/s with B = 5 or 1e9 N.s/m (within the ranges the engine accepts): the load's
    deceleration, up to 1e27 m/s^2, is gone within nanoseconds, and the searches' bounds decay with it (bounds
    held at their start needed more than 1e5 evaluations for one search)."""
    parameters = dict(F=20.0, omega=3.0, M1=1e-6, B=B, h=1e-9, v1_0=1e6)
    python, c = Drivetrain(**parameters), core.Drivetrain(**parameters)
    for solver in (python, c):
        solver.advance(5.0)
    assert python.output() == c.output() and python.events == c.events > 30


def test_a_state_beyond_the_resolution_of_time_is_refused_in_one_line(core):
    """A load at 1e100 m/s braked by viscous friction decelerates at 5e99 m/s^2: by t = 1e-32 s the events
    come within ulps of each other, and both solvers refuse the step instead of grinding through them."""
    for make in (Drivetrain, core.Drivetrain):
        plant = make(F=20.0, omega=3.0, v1_0=1e100)
        with pytest.raises(PlantError, match=r"^more than 1000 events within 64 ulp of each other at t = .*: the "
                                             r"motion chatters below the resolution of time$"):
            plant.advance(1e-6)


def test_a_motion_that_never_crosses_the_section_is_shot_on_the_second_one():
    """Without load friction the drivetrain is the two-mass backlash, which hunts under 200 (s + 2)/(s + 20) at
    12.73 rad/s with impacts only: the load never stops, so the drivetrain's section (the load's stops) is never
    hit (its search said "36 rest", no cycle). A wait without a hit whose output still turns with events firing
    moves on (never rest); such a run runs again on the drivetrain's second section, M2's walls, and finds the
    two-mass backlash's cycle to the digits. Without a second section the search says it is incomplete."""
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.periodic import LoopProblem

    G = "200*(s+2)/(s+20)"
    problem = LoopProblem("drivetrain", G, {"B": 0.0, "Fc": 0.0, "Fs": 0.0})
    frictionless = find_cycles(problem, [], amplitudes=[0.01, 0.1])
    backlash = find_cycles(LoopProblem("backlash", G), [], amplitudes=[0.01, 0.1])
    assert frictionless.coverage.outcomes == {"cycle": frictionless.coverage.starts}
    [cycle], [twin] = frictionless.cycles, backlash.cycles
    assert cycle.section == 1 and twin.section == 0 and cycle.stable
    assert cycle.omega == pytest.approx(twin.omega, rel=1e-9) and cycle.amplitude_x == pytest.approx(
        twin.amplitude_x, rel=1e-9) and cycle.F == pytest.approx(twin.F, rel=1e-9)
    assert "below the size at which the plant's output moves" in cycle.df  # no threshold of 0 N
    alone = copy.copy(problem)
    alone.alternate = lambda: None  # no second section: the runs move on, and the search proves no absence
    unseen = find_cycles(alone, [], amplitudes=[0.01])
    assert unseen.coverage.outcomes == {"moving": unseen.coverage.starts} and not unseen.coverage.settled
    assert "INCOMPLETE: runs moved on without crossing the section" in unseen.coverage.summary()
    stuck = find_cycles(LoopProblem("drivetrain", G), [], amplitudes=[0.01])  # the load sticks: at rest
    assert stuck.coverage.outcomes == {"rest": stuck.coverage.starts}
