"""The integrated solver family (dfwb.fmus.integrated) against closed forms: the exact Motion, and the exact
friction mass with its slides integrated instead of solved. Its error bound must hold (never below the true
error) and be tight (within a factor of 1000), its result must not depend on where it is asked, and every
refusal must be one line."""

import math

import pytest

from dfwb.fmus.contract import EventKind
from dfwb.fmus.exact import Motion, PlantError
from dfwb.fmus.friction import SLIDE, FrictionLoop, FrictionMass
from dfwb.fmus.integrated import GAUSS_NODES, GAUSS_WEIGHTS, Trajectory, _stop
from dfwb.fmus.piecewise import Search


class Linear:
    """v' = -lam v + a + b cos(omega t + phi): the law of a closed-form Motion."""

    scale = math.inf  # no feature in v

    def __init__(self, lam, a, b, omega, phi):
        self.lam, self.a, self.b, self.omega, self.phi = lam, a, b, omega, phi

    def __call__(self, t, v):
        return -self.lam * v + self.a + self.b * math.cos(self.omega * t + self.phi)

    def size(self, t, v):
        return abs(self.lam * v) + abs(self.a) + abs(self.b)


CASES = [  # lam, a, b, omega, phi, t0, x0, v0
    (0.5, -5.0, 10.0, 1.0, 0.3, 0.2, 1.0, 2.0),
    (0.0, -2.0, 1.0, 3.0, -1.0, 0.0, 0.0, 4.0),
    (20.0, -1.0, 30.0, 5.0, 2.0, 1.5, -3e5, 0.7),  # fast decay, far from the origin
]


def test_the_gauss_rule_is_exact_to_degree_17():
    for degree in range(18):
        assert abs(sum(w * x ** degree for x, w in zip(GAUSS_NODES, GAUSS_WEIGHTS)) - 1 / (degree + 1)) < 4e-16


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("rtol", [1e-6, 1e-9, 1e-12])
def test_a_trajectory_is_the_closed_form_within_its_bound(case, rtol):
    """Read as a plant reads it: integrated to each time in turn, up to its stop."""
    lam, a, b, omega, phi, t0, x0, v0 = case
    exact = Motion(t0, x0, v0, lam, a, b, omega, phi)
    trajectory = Trajectory(Linear(lam, a, b, omega, phi), t0, x0, v0, 1, omega, 3, rtol)
    stop = Trajectory(Linear(lam, a, b, omega, phi), t0, x0, v0, 1, omega, 3, rtol).first_zero(t0, t0 + 100.0)
    assert stop is not None
    assert abs(exact.state(stop)[1]) < 1e3 * rtol * abs(v0) + 1e-15  # it stops where the velocity is zero
    scale = max(abs(v0) * (stop - t0), 1e-300)  # the displacement's scale
    lo = t0
    for t in [t0 + (stop - t0) * k / 7 for k in range(1, 8)]:
        assert trajectory.first_zero(lo, t) == (stop if t == stop else None)
        lo = t
        x, v = exact.state(t)
        xi, vi = trajectory.state(t)
        assert abs(xi - x) <= 1e3 * rtol * scale + 4e-16 * abs(x0)
        truth, mine = exact.integrals(t, 3), trajectory.integrals(t, 3)
        error, bound = max(abs(p - q) for p, q in zip(truth, mine)), trajectory.integral_error(t)
        rounding = 64 * 2.2e-16 * (abs(x0) + scale) * (t - t0 + 1 / omega)  # the closed form's own (by parts)
        assert error <= bound + rounding, (t, error, bound)  # honest
        assert bound <= 1e3 * max(error, rounding, 1e-3 * rtol * scale * (t - t0)), (t, error, bound)  # tight


def test_where_it_is_asked_changes_nothing():
    """The steps are the error control's alone: the same bits however the stop is searched and read."""
    lam, a, b, omega, phi, t0, x0, v0 = CASES[0]

    def run(grid):
        trajectory = Trajectory(Linear(lam, a, b, omega, phi), t0, x0, v0, 1, omega, 3)
        lo = t0
        for hi in grid:
            stop = trajectory.first_zero(lo, hi)
            if stop is not None:
                return stop, trajectory.state(stop), trajectory.integrals(stop, 3), trajectory.taken
            lo = hi

    assert run([t0 + 0.01 * k for k in range(1, 200)]) == run([2.0]) == run([1.31, 1.5, 9.0])
    with pytest.raises(PlantError, match="out of range: this integrated piece holds"):
        Trajectory(Linear(lam, a, b, omega, phi), t0, x0, v0, 1, omega, 3).state(t0 + 1.0)  # not integrated yet


class IntegratedFriction(FrictionMass):
    """The friction mass (Dv = 0) with each slide integrated by the family instead of solved in closed form."""

    rtol = 1e-9

    def _slide(self, t, x, v, s, departing):
        self.mode, self.direction = SLIDE, s
        d = self.drive
        law = Linear(self.B / self.M, (d.f - s * self.Fc) / self.M, d.F / self.M, d.omega, d.phi)
        trajectory = Trajectory(law, t, x, v, s, d.omega, self.harmonics, self.rtol, self._velocity_error)
        self._begin(t, trajectory, searches=[Search(trajectory, None, t, EventKind.BAND)])


@pytest.mark.parametrize("params", [dict(F=10.0, omega=1.0), dict(F=20.0, omega=3.0, B=2.0, Fs=9.0),
                                    dict(F=8.0, omega=0.5, M=3.0, Fc=2.0, Fs=2.0, phi=1.0)])
@pytest.mark.parametrize("rtol", [1e-7, 1e-10])
def test_integrated_slides_give_the_exact_friction_mass(params, rtol):
    """Stick-slip over ten periods: the same events, the describing function's integrals within the bound."""
    exact, integrated = FrictionMass(**params, harmonics=3), IntegratedFriction(**params, harmonics=3)
    integrated.rtol = rtol
    period = 2 * math.pi / params["omega"]
    exact.event_log, integrated.event_log = [], []
    for k in range(1, 81):
        exact.advance(k * period / 8)
        integrated.advance(k * period / 8)
        truth, mine = exact.integrals(), integrated.integrals()
        error, bound = max(abs(p - q) for p, q in zip(truth, mine)), integrated.integrals_error()
        assert error <= bound + 1e-13 * k, (k, error, bound)
        assert bound <= 1e3 * max(error, 1e-3 * rtol * k), (k, error, bound)
        assert abs(integrated.output().x - exact.output().x) < 1e4 * rtol
    assert [kind for _t, kind in integrated.event_log] == [kind for _t, kind in exact.event_log]
    assert max(abs(p[0] - q[0]) for p, q in zip(integrated.event_log, exact.event_log)) < 1e4 * rtol
    assert exact.events > 10


def test_the_friction_mass_integrated_does_not_depend_on_the_communication_step():
    runs = []
    for n in (3, 8, 50):
        plant = IntegratedFriction(F=10.0, omega=1.0, harmonics=2)
        for k in range(1, 4 * n + 1):
            plant.advance(k * 2 * math.pi / n)
        runs.append((plant.output(), plant.integrals(), plant.integrals_error(), plant.events))
    assert runs[0] == runs[1] == runs[2]


@pytest.mark.parametrize("law, message", [
    (Linear(1e6, 1e6, 0.0, 1.0, 0.0), "too stiff for the integrated solver: its step"),  # v -> 1, never stops
    (Linear(math.nan, 0.0, 0.0, 1.0, 0.0), "cannot resolve"),
])
def test_a_law_it_cannot_integrate_is_refused_in_one_line(law, message):
    trajectory = Trajectory(law, 0.0, 0.0, 0.5, 1, 1.0, 0)
    with pytest.raises(PlantError, match=message) as caught:
        trajectory.first_zero(0.0, 1e6)
    assert "\n" not in str(caught.value)


class Damping:
    """law(v) = -lam v: the viscous term, moved out of a mode's matrix into its nonlinear term."""

    scale = math.inf

    def __init__(self, lam):
        self.lam = lam

    def __call__(self, v):
        return -self.lam * v

    def slope(self, v):
        return -self.lam


class IntegratedFrictionLoop(FrictionLoop):
    """The friction mass's loop with each slide's damping as an integrated mode's nonlinear term."""

    rtol = 1e-10

    def plant_mode(self, key):
        P, p, phi, events = super().plant_mode(key)
        if key[0] != "slide":
            return P, p, phi, events
        return [[0.0, 1.0], [0.0, 0.0]], p, phi, events, (1, 1, Damping(self.B / self.M))


LOOPS = [(([2.0, 1.0], [0.0]), {}), (([10.0, 2.0], [0.0]), dict(Fs=5.0, M=2.0)),
         (([3.0, 4.0, 1.0], [2.0, 0.0]), dict(B=2.0))]


@pytest.mark.parametrize("G, params", LOOPS)
def test_an_integrated_loop_mode_gives_the_exact_friction_loop(G, params):
    """100 s of hunting from a displaced start: the same events in order, the states within 1e-8."""
    exact, integrated = FrictionLoop(*G, x0=0.3, **params), IntegratedFrictionLoop(*G, x0=0.3, **params)
    exact.event_log, integrated.event_log = [], []
    for k in range(1, 401):
        exact.advance(0.25 * k)
        integrated.advance(0.25 * k)
        assert max(abs(p - q) for p, q in zip(exact.state(), integrated.state())) < 1e-8, 0.25 * k
        assert integrated.key == exact.key
    assert [kind for _t, kind in integrated.event_log] == [kind for _t, kind in exact.event_log]
    assert exact.events >= 1 and integrated.sticks == exact.sticks


def test_an_integrated_loop_does_not_depend_on_the_communication_step():
    G, params = LOOPS[1]
    runs = []
    for n in (1, 7, 40):
        loop = IntegratedFrictionLoop(*G, x0=0.3, **params)
        for k in range(1, 20 * n + 1):
            loop.advance(k / n)
        runs.append((loop.state(), loop.events, loop.key))
    assert runs[0] == runs[1] == runs[2]


@pytest.mark.parametrize("fun, g0, left, expected", [
    (lambda th: 1.0 - 2.0 * th, 1.0, True, 0.5),  # resolved from the start: the zero, refined
    (lambda th: 1e-17 * math.sin(20.0 * th), 0.0, True, None),  # within the floor throughout: rounding, no stop
    (lambda th: 1e-17 - 4.0 * th * th + 3.0 * th, 1e-17, True, 0.75 + 1e-17 / 3.0),  # armed by a sample
    (lambda th: -th, 0.0, False, 0.125),  # a departure that never left: at the first sample beyond the floor
    (lambda th: -th, 0.0, True, 0.0),  # later in the piece: from the step's start
    (lambda th: -1e-15 - th, -1e-15, True, 0.0),  # below the floor at the start already
    (lambda th: 1e-17 - th, 1e-17, True, 1e-17),  # unresolved at the start, falls through: from the last positive
])
def test_a_stop_counts_once_its_function_is_resolved(fun, g0, left, expected):
    """_stop (the slides' and the loop's modes' stop, C's dfwb_in_stop): a fall to zero within the floor (1e-16
    here) is rounding, not a stop; below it, or after the function was resolved, it is one."""
    theta = _stop(fun, g0, 1e-16, left=left)
    if expected is None:
        assert theta is None
    else:
        assert theta == pytest.approx(expected, rel=0.0, abs=1e-15)
