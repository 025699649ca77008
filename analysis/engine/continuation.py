"""Limit cycles followed in one parameter: pseudo-arclength continuation of the true cycles and of the DF's
predictions, their bifurcations detected and located.

A branch is a curve of solutions of H(y) = 0 with y = (x, lambda): for a true
cycle x are the section coordinates u of its state and H(u, lambda) =
P^returns(u; lambda) - u (the return map of :mod:`dfwb.engine.periodic` at
that parameter value); for a DF prediction x = (ln F, ln w) and H is the
harmonic balance 1 + G(jw) N(F, w) (real and imaginary parts). The curve is
followed by arclength in coordinates scaled by the orbit's swing and by the
parameter's own size where the branch is (:func:`parameter_scale`: never the
range's width alone, so a range of 1 to 1e308 follows the branch a range of
1 to 30 follows), so it passes smooth folds where the parameter turns back:
each step predicts along the tangent (the null vector of dH, oriented as the
last one) and corrects by Newton's method on H = 0 and the arclength
condition, the step halved where the corrector fails and grown where it
converges at once.

Between two accepted points of a branch of true cycles a bifurcation is
detected and then located by walking the branch from the earlier point with
steps halved wherever the next one is past the change, to 1e-7 of the
parameter's scale:

* **discontinuity-induced**, from the cycle's event sequence over a period
  (its signature): a stick phase or contact appearing or vanishing
  (``sliding``), an impact or an engagement appearing or vanishing
  (``grazing``); where the branch turns back there, two branches meet at a
  ``nonsmooth-fold``: their Floquet multipliers need not pass through 1, so
  only the events see it (the hunting cycle and the unstable cycle above it
  of a PI-controlled friction mass meet that way);
* **smooth**, from the Floquet multipliers: a real one leaving the unit
  circle through +1 where the parameter turns back (``fold``), through -1
  (``period-doubling``), a complex pair leaving it (``torus``);
* a branch whose amplitude grows without bound ends at ``infinity``: where
  the linear loop (the nonlinearity removed) loses its stability; one whose
  amplitude falls to zero ends where the cycle ``shrinks-to-rest`` (as the
  hunting cycle does when the static friction falls to the Coulomb level).

A DF branch has ``fold`` points, where -1/N touches G(jw) (the parameter
turns back, Loeb's stability verdict changes).

Every loop is bounded: a branch by ``max_points`` and by the step's lower
bound, a corrector by MAX_CORRECTOR iterations, a location by MAX_LOCATE steps.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.defaults import BRANCH_POINTS
from dfwb.base.errors import DfwbError, InputError
from dfwb.engine.periodic import jacobian, same_events
from dfwb.fmus.exact import PlantError

TOL = 1e-10  # the corrector's residual (scaled)
MAX_CORRECTOR = 8  # Newton iterations per corrector, at most
REFRESHES = 2  # fresh Jacobians a corrector may take when the chord converges slowly
FD = 1e-7  # finite-difference step, scaled
DS = (1e-6, 0.02, 0.15)  # the step: smallest, first, largest (scaled arclength)
MAX_LOCATE = 400  # steps of a bifurcation's location, at most
LOCATE = 1e-7  # a bifurcation is located when the step onto it is this small (scaled: see parameter_scale)
RELATIVE = 30.0  # the parameter's scale is at most this many times its size where the branch is ...
FLOOR = 1e-3  # ... or than this, near 0 (and at most the range's width)
AMPLITUDE_LIMIT = 1e3  # a branch whose amplitude grows (falls) this many times its start's goes to infinity (rest)
TURN = 1e-3  # a step this small without a solution: look for the other side of a kink (see _turn)
COS_TURN = 0.9  # a step whose tangent turns more than this (cosine) is halved, unless it is already that small
TURN_REACH = (1e-3, 1e-2, 3e-2)  # how far past the last point it is looked for (scaled)
SPENT = "the work budget ran out (a study's exact runs are bounded; its bifurcations are not located)"


@dataclass
class Point:
    """One solution on a branch: the cycle (or prediction) at one parameter value."""

    parameter: float
    omega: float
    amplitude_x: float
    F: float
    stable: bool
    multipliers: list
    period: float
    signature: tuple = ()
    state: list = field(default_factory=list, repr=False)

    def as_dict(self):
        return {"parameter": self.parameter, "omega": self.omega, "amplitude_x": self.amplitude_x, "F": self.F,
                "stable": self.stable, "multipliers": self.multipliers, "period": self.period,
                "events": list(self.signature)}


@dataclass
class Branch:
    """A branch of cycles (``source`` "truth") or of DF predictions ("df"), its points in arclength order."""

    source: str
    points: list
    ends: list = field(default_factory=list)  # [(parameter, why it stops)] at the first and last point
    returns: int = 1

    def as_dict(self):
        return {"source": self.source, "returns": self.returns, "points": [p.as_dict() for p in self.points],
                "ends": [{"parameter": value, "reason": reason} for value, reason in self.ends]}


@dataclass
class Bifurcation:
    """Where a branch changes its nature: ``kind`` (see the module docstring), located to ``accuracy``."""

    kind: str
    parameter: float
    omega: float
    amplitude_x: float
    source: str
    detail: str = ""
    accuracy: float = 0.0
    state: list = field(default=None, repr=False)  # the located solution: its coordinates, then the parameter
    side: float = 0.0  # +1 where the branch reached it with the parameter rising, -1 falling
    returns: int = 1  # section hits per period of the cycles there

    def as_dict(self):
        return {"kind": self.kind, "parameter": self.parameter, "omega": self.omega,
                "amplitude_x": self.amplitude_x, "source": self.source, "detail": self.detail,
                "accuracy": self.accuracy}


# -- the two systems: H(y) = 0 for true cycles and for DF predictions ------------------------------------------------
def parameter_scale(span, value):
    """The parameter's unit in the scaled coordinates at ``value``: the range's width ``span``, but at most
    RELATIVE times the value's size (FLOOR near 0). The steps, the finite differences and a bifurcation's
    accuracy are fractions of it: were it the width of a range far wider than the branch (1 to 1e8), the first
    step would jump over the whole branch and a finite difference would leave it."""
    return min(span, RELATIVE * max(abs(value), FLOOR))


class _Parameter:
    """The parameter's scale of a system, taken where the branch is: at the first residual asked (its start),
    then at each solution described."""

    def __init__(self, span):
        self.span, self.at = span, None

    def seen(self, value, described=False):
        if described or self.at is None:
            self.at = float(value)

    def unit(self):
        return self.span if self.at is None else parameter_scale(self.span, self.at)


class CycleSystem:
    """H(u, lambda) = P^returns(u) - u of the exact loop at each parameter value, scaled by the swing."""

    source = "truth"

    def __init__(self, family, name, span, returns, swing, period, fmu_dir=None, budget=None, section=0):
        self.family, self.name, self.span, self.returns, self.section = family, name, span, returns, section
        self.parameter = _Parameter(span)
        self.swing = np.asarray(swing, dtype=float)  # of the section coordinates u
        self.period, self.fmu_dir, self.budget = period, fmu_dir, budget
        self.spent = False  # the work budget ran out: every later residual is refused
        self._problems = {}

    def problem(self, value):
        """The loop at a parameter value (a few kept: a corrector and its Jacobian revisit them)."""
        problem = self._problems.get(value)
        if problem is None:
            if len(self._problems) > 8:
                self._problems.clear()
            problem = self.family.problem({self.name: value}, self.fmu_dir, self.budget)
            problem = self._problems[value] = problem.alternate() if self.section else problem  # the cycle's section
            if self.budget is None:
                self.budget = problem.budget  # every problem of the branch draws on the first one's budget
        return problem

    def scale(self):
        return np.concatenate([self.swing, [self.parameter.unit()]])

    def residual(self, y):
        """H(y) scaled by the swing, and (the return time, the events fired); (None, None) where the orbit does
        not return."""
        value = float(y[-1])
        self.parameter.seen(value)
        try:
            problem = self.problem(value)
        except DfwbError:  # a parameter value the plant or G refuses (a mass through 0, eps below 0, ...)
            return None, None
        X = problem.on_section(list(y[:-1]))
        try:
            result = problem.first_return(X, self.returns, 20.0 * self.period)
        except PlantError:  # the budget is spent (first_return raises nothing else): the branch ends here
            self.spent = True
            return None, None
        if result is None:
            return None, None
        return (np.array(problem.reduced(result[0])) - y[:-1]) / self.swing, result[1:]

    same_kind = staticmethod(same_events)

    def describe(self, y, J, info):
        """The :class:`Point` at y (J: dH/dy scaled; info: the return time and the events)."""
        T = info[0]
        problem = self.problem(float(y[-1]))
        X = problem.on_section(list(y[:-1]))
        n = len(y) - 1
        M = J[:, :n] + np.eye(n)
        spectrum = sorted((complex(m) for m in np.linalg.eigvals(M)), key=abs, reverse=True)
        harmonics, F, _counts, trace = problem.period_trace(X, T)
        self.period = T
        swing = problem._swing(X, T)
        self.swing = np.maximum(np.array([v for i, v in enumerate(swing) if i != problem.pivot]), 1e-300)
        self.parameter.seen(y[-1], described=True)
        return Point(parameter=float(y[-1]), omega=2.0 * math.pi / T, amplitude_x=harmonics[1], F=F,
                     stable=all(abs(m) < 1.0 for m in spectrum), multipliers=[abs(m) for m in spectrum], period=T,
                     signature=tuple(str(k) for _t, k in trace["events"]), state=X), spectrum

    def signature(self, y, info):
        """The event kinds of one period from the section state at y (info: the return time, the events)."""
        problem = self.problem(float(y[-1]))
        solver = problem._make(problem.on_section(list(y[:-1])))
        solver.event_log = []
        solver.advance(info[0])
        return tuple(str(k) for _t, k in solver.event_log)


class PredictionSystem:
    """H(ln F, ln w, lambda) = 1 + G(jw) N(F, w): the DF's harmonic balance at each parameter value."""

    source = "df"

    def __init__(self, family, name, span, engine, F_range):
        self.family, self.name, self.span, self.engine = family, name, span, engine
        self.parameter = _Parameter(span)
        self.log_F = (math.log(F_range[0]), math.log(F_range[1]))
        self._cache = {}

    def scale(self):
        return np.array([1.0, 1.0, self.parameter.unit()])

    @staticmethod
    def same_kind(a, b):
        return True

    def residual(self, y):
        u, v, value = (float(c) for c in y)
        self.parameter.seen(value)
        if not self.log_F[0] <= u <= self.log_F[1] or not -9.0 <= v <= 11.5:
            return None, None
        try:
            G, params = self._at(value)
            point = self.engine.point(math.exp(u), math.exp(v), params)
        except (InputError, PlantError):
            return None, None
        if point.N == 0:
            return None, None  # the plant does not move: no balance
        R = 1.0 + complex(G(1j * math.exp(v))) * point.N
        return np.array([R.real, R.imag]), point

    def _at(self, value):
        """(G as a function of s, the plant's parameters) at a parameter value (a few kept)."""
        if value not in self._cache:
            if len(self._cache) > 16:
                self._cache.clear()
            num, den = self.family.coefficients({self.name: value})
            params = self.family.df_params({self.name: value})
            if params is None:  # a compensated loop whose plant is no plant here: the DF branch ends
                raise InputError(f"{self.name} = {value:g}: no DF of the compensated loop")
            self._cache[value] = (lambda s: np.polyval(num, s) / np.polyval(den, s), params)
        return self._cache[value]

    def describe(self, y, J, point):
        self.parameter.seen(y[2], described=True)
        F, omega = math.exp(y[0]), math.exp(y[1])
        loeb = float(J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0])
        return Point(parameter=float(y[2]), omega=omega, amplitude_x=point.amplitude_x, F=F, stable=loeb > 0.0,
                     multipliers=[], period=2.0 * math.pi / omega, state=[F, omega]), loeb


# -- pseudo-arclength ------------------------------------------------------------------------------------------------
def _jacobian(system, y, r, extra=None):
    """dH/dy (scaled columns: d/d(y_j / scale_j)) by forward differences (:func:`~dfwb.engine.periodic.jacobian`,
    a side of another kind, ``system.same_kind``, replaced by the other), or None."""
    if extra is None:
        r, extra = system.residual(y)
    return jacobian(system.residual, np.asarray(y, dtype=float), (r, extra), FD, same_kind=system.same_kind,
                    scale=system.scale())


def _tangent(J, previous):
    """The unit null vector of J oriented along ``previous`` (the bordered system [J; previous] t = e_n)."""
    n = J.shape[1]
    A = np.vstack([J, previous])
    b = np.zeros(n)
    b[-1] = 1.0
    try:
        t = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        t = np.linalg.svd(J)[2][-1]
        t = t if t @ previous >= 0 else -t
    return t / np.linalg.norm(t)


def _correct(system, y_start, normal, anchor, J=None):
    """Newton on [H(y) = 0, normal . (y - anchor) / scale = 0] from y_start: (y, r, extra, J) or None."""
    D = system.scale()
    y = np.array(y_start, dtype=float)
    r, extra = system.residual(y)
    if r is None:
        return None
    refreshes = 0
    if J is None:
        J = _jacobian(system, y, r, extra)
        if J is None:
            return None
    previous = math.inf
    for _ in range(MAX_CORRECTOR):
        condition = float(normal @ ((y - anchor) / D))
        size = max(float(np.abs(r).max()), abs(condition))
        if size <= TOL:
            return y, r, extra, J
        if size > 0.25 * previous and refreshes < REFRESHES:  # the chord converges slowly: a fresh Jacobian
            J = _jacobian(system, y, r, extra)
            refreshes += 1
            if J is None:
                return None
        previous = size
        try:
            step = np.linalg.solve(np.vstack([J, normal]), -np.concatenate([r, [condition]]))
        except np.linalg.LinAlgError:
            return None
        y = y + step * D
        r, extra = system.residual(y)
        if r is None:
            return None
    condition = float(normal @ ((y - anchor) / D))
    return (y, r, extra, J) if max(float(np.abs(r).max()), abs(condition)) <= TOL else None


@dataclass
class _Node:
    """An accepted point with what the next step needs."""

    y: np.ndarray
    J: np.ndarray
    tangent: np.ndarray
    point: Point
    detail: object  # the system's: the spectrum (truth) or Loeb's value (DF)
    info: object  # the residual's extra: (return time, events) (truth) or the DF point (DF)


def _node(system, y, r, extra, J, previous_tangent):
    """Describe an accepted solution (a fresh Jacobian there: the tangent and the multipliers)."""
    J = _jacobian(system, y, r, extra) if J is None else J
    if J is None:
        return None
    point, detail = system.describe(y, J, extra)
    return _Node(y, J, _tangent(J, previous_tangent), point, detail, extra)


def follow(system, y0, direction, bounds, max_points=BRANCH_POINTS, limit=AMPLITUDE_LIMIT, progress=None):
    """The branch from the solution y0 in the direction of the parameter's sign ``direction``, within ``bounds``.

    Returns (nodes, reason): the accepted nodes in order (y0's first) and why the branch stopped (SPENT
    where the system's work budget ran out: the nodes found until then are kept).
    """
    nodes = []
    try:
        return _follow(system, y0, direction, bounds, max_points, limit, progress, nodes)
    except PlantError:
        if not _spent(system):
            raise
        return nodes, SPENT


def _spent(system):
    """Whether a system's work budget ran out (a DF system has none)."""
    budget = getattr(system, "budget", None)
    return getattr(system, "spent", False) or (budget is not None and budget.left < 0)


def _follow(system, y0, direction, bounds, max_points, limit, progress, nodes):
    r, extra = system.residual(y0)
    J = None if r is None else _jacobian(system, y0, r, extra)
    if J is None:
        return nodes, SPENT if _spent(system) else "the start is not a solution" if r is None else \
            "the start's neighbourhood does not return to the section"
    start = np.zeros(len(y0))
    start[-1] = direction
    node = _node(system, y0, r, extra, J, start)
    nodes.append(node)
    ds = DS[1]
    amplitude0 = max(node.point.amplitude_x, 1e-300)
    lo, hi = bounds
    if (y0[-1] >= hi and node.tangent[-1] > 0) or (y0[-1] <= lo and node.tangent[-1] < 0):
        return nodes, "the end of the range"  # it starts on the edge, heading out
    while len(nodes) < max_points:
        if _spent(system):
            return nodes, SPENT
        D = system.scale()
        last = nodes[-1]
        predicted = last.y + ds * last.tangent * D
        corrected = None
        if lo <= predicted[-1] <= hi:
            corrected = _correct(system, predicted, last.tangent, predicted, last.J)
        else:  # beyond the range: end exactly on its edge (the parameter fixed there)
            edge = hi if predicted[-1] > hi else lo
            fixed = np.zeros(len(y0))
            fixed[-1] = 1.0
            guess = last.y + (edge - last.y[-1]) / (predicted[-1] - last.y[-1]) * (predicted - last.y)
            guess[-1] = edge
            corrected = _correct(system, guess, fixed, guess, last.J)
            if corrected is not None:
                node = _node(system, *corrected[:3], None, last.tangent)
                if node is not None:
                    nodes.append(node)
                    return nodes, "the end of the range"
            corrected = None
        node = None if corrected is None else _step(system, last, *corrected[:3], ds)
        if node is None:  # no solution, or the branch bends too sharply for this step: a smaller one
            ds *= 0.5
            if ds < TURN and getattr(system, "source", "") == "truth":
                turned = _turn(system, last)
                if turned is not None:  # the branch turned back at a kink: go on along the other side
                    nodes.append(turned)
                    ds = DS[1]
                    continue
            if _spent(system):
                return nodes, SPENT
            if ds < DS[0]:
                return nodes, "the branch cannot be followed further (the corrector fails even at tiny steps)"
            continue
        nodes.append(node)
        if progress:
            progress(len(nodes))
        if node.point.amplitude_x > limit * amplitude0:
            return nodes, "infinity"
        if node.point.amplitude_x < amplitude0 / limit:
            return nodes, "rest"
        ds = min(DS[2], ds * 1.5)
    return nodes, f"{max_points} points"


def _step(system, last, y, r, extra, ds):
    """The node at a corrected solution, or None where the branch turns by more than COS_TURN from last's
    tangent and the step is not yet tiny (a large step there may have jumped to another branch)."""
    J = _jacobian(system, y, r, extra)
    if J is None:
        return None
    chord = (y - last.y) / system.scale()
    tangent = _tangent(J, chord)  # oriented along the step taken (past a kink: away from it)
    if float(tangent @ last.tangent) < COS_TURN and ds > TURN:
        return None
    point, detail = system.describe(y, J, extra)
    return _Node(y, J, tangent, point, detail, extra)


def _turn(system, last):
    """The other side of a kink just past node ``last``: a solution at last's parameter value with other events.

    Where the step has shrunk without a solution, the branch may turn back sharply at a kink (a stick phase
    shrinking to nothing, where the cycle meets one without it): no hyperplane across the old tangent meets
    the returning side. Newton at last's parameter value from points a little past last along its tangent
    (the solution there of another event sequence lies that way) finds it; its tangent points away from last.
    Returns the new node, or None.
    """
    D = system.scale()
    fixed = np.zeros(len(last.y))
    fixed[-1] = 1.0
    for reach in TURN_REACH:
        guess = last.y + reach * last.tangent * D
        guess[-1] = last.y[-1]
        corrected = _correct(system, guess, fixed, guess)
        if corrected is None or system.same_kind(corrected[2], last.info):
            continue
        y, r, extra, J = corrected
        away = (y - last.y) / D
        node = _node(system, y, r, extra, None, away / max(np.linalg.norm(away), 1e-300))
        if node is not None and node.point.signature != last.point.signature:
            return node
    return None


# -- bifurcations ------------------------------------------------------------------------------------------------------
def locate(system, a, b, differs):
    """Follow the branch from node a towards node b until just before ``differs(y, r, extra)`` turns True.

    Small arclength steps, the tangent renewed at each accepted point (so the walk stays on a's side of the
    branch up to a kink, where a straight march would leave it), the step halved where the next point differs
    or cannot be found. Returns (the last solution like a, (y, r, extra, J); the first that differs, or None;
    the bracket's width in the parameter), when the step is LOCATE (scaled) or after MAX_LOCATE steps.
    """
    D = system.scale()
    here, tangent = (a.y, None, a.info, a.J), a.tangent
    ds = 0.5 * float(np.linalg.norm((b.y - a.y) / D))
    after = None
    for _ in range(MAX_LOCATE):
        if ds <= LOCATE:
            break
        predicted = here[0] + ds * tangent * D
        solution = _correct(system, predicted, tangent, predicted)
        if solution is None or differs(*solution[:3]):
            after = solution or after
            ds *= 0.5
            continue
        J = _jacobian(system, solution[0], solution[1], solution[2])
        if J is None:
            ds *= 0.5
            continue
        here, tangent = (solution[0], solution[1], solution[2], J), _tangent(J, tangent)
    return here, after, float(ds * D[-1])


def _side(a, value):
    """+1 where node a lies below the located parameter value (the branch reaches it rising), else -1."""
    return 1.0 if value >= a.y[-1] else -1.0


def _measure(system, solution):
    """The :class:`Point` of a located solution (y, r, extra, J)."""
    y, _r, extra, J = solution
    J = J if J is not None else _jacobian(system, y, None)
    return system.describe(y, J, extra)[0]


def _outside(multipliers):
    """(real > +1, real < -1, complex) counts of multipliers outside the unit circle (1e-9 of slack)."""
    out = [m for m in multipliers if abs(m) > 1.0 + 1e-9]
    return (sum(1 for m in out if abs(m.imag) <= 1e-9 * abs(m) and m.real > 0),
            sum(1 for m in out if abs(m.imag) <= 1e-9 * abs(m) and m.real < 0),
            sum(1 for m in out if abs(m.imag) > 1e-9 * abs(m)))


STICKS = {"break+", "break-", "release"}  # events that begin or end a stick phase or a contact
TOUCHES = {"gap 0", "gap h", "engage+", "engage-", "reverse"}  # impacts and engagements


WALLS = ("gap 0", "gap h")


def essential(signature):
    """An event sequence with each run of impacts at one wall that ends in contact written once, as
    "gap h ... contact": how many bounces an accumulation takes before the masses move together depends on
    where it is cut (the next bounce below 1e-12 h), not on the cycle, so it is no bifurcation."""
    events, out, i = list(signature), [], 0
    while i < len(events):
        j = i
        while j + 1 < len(events) and events[j + 1] == events[i]:
            j += 1
        if events[i] in WALLS and j + 1 < len(events) and events[j + 1] == "release":
            out.append(f"{events[i]} ... contact")
        else:
            out.extend(events[i:j + 1])
        i = j + 1
    return tuple(out)


def _changed(before, after):
    """What appears or vanishes between two event sequences, in words, and the kind of bifurcation it makes."""
    from collections import Counter

    gained, lost = Counter(after) - Counter(before), Counter(before) - Counter(after)
    moved = set(gained) | set(lost)
    kind = "sliding" if moved & STICKS else "grazing"
    what = []
    if gained:
        what.append("gains " + ", ".join(f"{n} {k}" for k, n in sorted(gained.items())))
    if lost:
        what.append("loses " + ", ".join(f"{n} {k}" for k, n in sorted(lost.items())))
    if not what:
        what.append("reorders its events")
    return kind, "the period " + " and ".join(what) + f" ({' '.join(before)} -> {' '.join(after)})"


MAX_CHANGES = 8  # changes of the event sequence located between two points of a branch, at most


def _nonsmooth(system, a, b):
    """[(Bifurcation, its two sides' Points)] where the event sequence changes between nodes a and b.

    Each change is located from the side before it; several may lie between two points (an impact after
    another vanishing as a restitution grows), so the walk goes on from the far side of each, at most
    MAX_CHANGES times. A change where the branch turns back (the far side heads back in the parameter) is a
    nonsmooth fold."""
    found, target = [], essential(b.point.signature)
    for _ in range(MAX_CHANGES):
        signature = essential(a.point.signature)
        if signature == target:
            break
        before, after, width = locate(system, a, b, lambda y, r, T: essential(system.signature(y, T)) != signature)
        value = float(before[0][-1])
        edge = _node(system, *before, a.tangent)
        far = _node(system, *after, a.tangent) if after is not None else (edge and _turn(system, edge))
        sides = [edge.point if edge else _measure(system, before)] + ([far.point] if far else [])
        rising = value - a.y[-1]
        fold = far.tangent[-1] * rising < 0.0 if far else (a.y[-1] - value) * (b.y[-1] - value) > 0.0
        kind, what = _changed(signature, essential(sides[-1].signature) if far else target)
        multipliers = " | ".join(", ".join(f"{m:.3g}" for m in side.multipliers) for side in sides)
        where = "on its two sides" if len(sides) == 2 else "there"
        found.append((Bifurcation("nonsmooth-fold" if fold else kind, value, sides[0].omega, sides[0].amplitude_x,
                                  system.source, f"{what}; |multipliers| {multipliers} {where}"
                                  + ("; two branches meet and end there" if fold else ""), width, list(before[0]),
                                  _side(a, value)), sides))
        if far is None:
            break
        a = far
    return found


def bifurcations(system, nodes, span=None):
    """The bifurcations between consecutive nodes of a branch, each located (see the module docstring):
    [(i, Bifurcation, the located Points to insert after node i)]. ``span`` (the range's width) is not used:
    each is located in the system's own scale, which the range only bounds."""
    found = []
    truth = system.source == "truth"
    for i, (a, b) in enumerate(zip(nodes, nodes[1:])):
        turns = a.tangent[-1] * b.tangent[-1] < 0.0
        if truth and essential(a.point.signature) != essential(b.point.signature):
            found += [(i, bifurcation, sides) for bifurcation, sides in _nonsmooth(system, a, b)]
            continue
        if turns:
            sign = a.tangent[-1]

            def beyond(y, r, extra):
                J = _jacobian(system, y, r, extra)
                return J is not None and _tangent(J, a.tangent)[-1] * sign < 0.0

            before, after, width = locate(system, a, b, beyond)
            value = float(before[0][-1]) if after is None else 0.5 * float(before[0][-1] + after[0][-1])
            here = _measure(system, before)
            found.append((i, Bifurcation("fold", value, here.omega, here.amplitude_x, system.source,
                                         "the branch turns back: two cycles meet" if truth else
                                         "the branch turns back: -1/N touches G(jw)", width, list(before[0]),
                                         _side(a, value)), [here]))
            continue
        if truth:
            outside_a, outside_b = _outside(a.detail), _outside(b.detail)
            for index, kind in ((1, "period-doubling"), (2, "torus"), (0, "branch-point")):
                if outside_a[index] != outside_b[index]:
                    def crossed(y, r, extra, index=index):
                        J = _jacobian(system, y, r, extra)
                        if J is None:
                            return False
                        n = len(y) - 1
                        return _outside(np.linalg.eigvals(J[:, :n] + np.eye(n)))[index] != outside_a[index]

                    before, after, width = locate(system, a, b, crossed)
                    value = float(before[0][-1]) if after is None else 0.5 * float(before[0][-1] + after[0][-1])
                    here = _measure(system, before)
                    found.append((i, Bifurcation(kind, value, here.omega, here.amplitude_x, system.source,
                                                 "a multiplier leaves the unit circle through -1" if index == 1
                                                 else "a complex pair of multipliers leaves the unit circle"
                                                 if index == 2 else
                                                 "a multiplier passes through +1 where the branch does not turn",
                                                 width, list(before[0]), _side(a, value)), [here]))
    return found


# -- whole branches ----------------------------------------------------------------------------------------------------
def _known(branches, source, value, point):
    """Whether a solution at ``value`` lies on a branch already followed: between two of its points that bracket
    the value, w and X interpolated within 1% and the same stability and events."""
    for branch in branches:
        if branch.source != source:
            continue
        for p, q in zip(branch.points, branch.points[1:] or branch.points):
            lo, hi = sorted((p.parameter, q.parameter))
            if not lo - 1e-12 * max(abs(value), 1.0) <= value <= hi + 1e-12 * max(abs(value), 1.0):
                continue
            w = 0.0 if hi == lo else (value - p.parameter) / (q.parameter - p.parameter)
            omega = p.omega + w * (q.omega - p.omega)
            amplitude = p.amplitude_x + w * (q.amplitude_x - p.amplitude_x)
            near = abs(omega - point.omega) <= 1e-2 * point.omega and \
                abs(amplitude - point.amplitude_x) <= 1e-2 * point.amplitude_x
            signature = essential(getattr(point, "signature", ()))
            if near and p.stable == point.stable and signature in (essential(p.signature), ()):
                return True
    return False


def linear_boundary(family, name, value, direction, bounds, fmu_dir=None):
    """Where the linear loop's stability changes next from ``value`` towards ``direction`` within bounds, or None."""
    from dfwb.engine.scales import linear_poles

    def stable(v):
        try:
            return all(p.real < 0.0 for p in linear_poles(family.problem({name: v}, fmu_dir)))
        except InputError:
            return None

    here = stable(value)
    edge = bounds[1] if direction > 0 else bounds[0]
    reach = parameter_scale(abs(edge - value), value)  # evenly near the branch, then geometrically to a far edge
    grid = np.linspace(value, value + math.copysign(reach, edge - value), 65)[1:]
    if reach < abs(edge - value):
        grid = np.concatenate([grid, value + np.sign(edge - value) * np.geomspace(reach, abs(edge - value), 33)[1:]])
    previous = value
    for v in grid:  # bounded: a scan, then a bisection
        state = stable(float(v))
        if state is not None and state != here:
            lo, hi = previous, float(v)
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if stable(mid) == here:
                    lo = mid
                else:
                    hi = mid
            return 0.5 * (lo + hi)
        previous = float(v)
    return None


def trace(system_of, y0, bounds, max_points=BRANCH_POINTS, progress=None):
    """The branch through the solution y0, followed both ways: (nodes, [(system, nodes, reason)] per half).

    ``system_of()`` makes a fresh system (each half carries its own scales)."""
    halves = []
    for direction in (-1.0, 1.0):
        system = system_of()
        nodes, reason = follow(system, np.array(y0, dtype=float), direction, bounds, max_points, progress=progress)
        halves.append((system, nodes, reason))
    back, forward = halves[0][1], halves[1][1]
    return back[::-1] + forward[1:], halves


def _assemble(source, halves, span, family, name, bounds, fmu_dir, returns=1):
    """The Branch and its bifurcations from the two halves traced from one start."""
    found, ends, runs = [], [], []
    for system, nodes, reason in halves:
        try:
            located = [] if reason == SPENT else bifurcations(system, nodes)  # none located without work
        except PlantError:
            if not _spent(system):
                raise
            located = []
        if _spent(system):  # spent while locating: what was located may be wrong
            located, reason = [], SPENT
        found += [bifurcation for _i, bifurcation, _points in located]
        inserts = {}
        for i, _bifurcation, points in located:
            inserts.setdefault(i, []).extend(points)
        runs.append([point for i, node in enumerate(nodes) for point in [node.point] + inserts.get(i, [])])
        if not nodes:
            continue
        last = nodes[-1]
        ends.append((last.point.parameter, reason))
        if reason == "rest" and len(nodes) >= 2:  # the amplitude falls linearly to zero: extrapolate where
            a, b = nodes[-2].point, nodes[-1].point
            value = b.parameter - b.amplitude_x * (b.parameter - a.parameter) / (b.amplitude_x - a.amplitude_x)
            found.append(Bifurcation("shrinks-to-rest", value, b.omega, 0.0, source,
                                     "the cycle shrinks to nothing: its amplitude falls to zero (extrapolated "
                                     "linearly from the branch's last points)", abs(value - b.parameter)))
        if reason == "infinity":
            direction = 1.0 if last.tangent[-1] > 0 else -1.0
            value = linear_boundary(family, name, last.point.parameter, direction, bounds, fmu_dir)
            detail = ("the amplitude grows without bound as the parameter approaches the linear loop's stability "
                      "boundary" if value is not None else "the amplitude grows without bound (no change of the "
                      "linear loop's stability found in the range)")
            found.append(Bifurcation("infinity", last.point.parameter if value is None else value, last.point.omega,
                                     last.point.amplitude_x, source, detail))
    back, forward = runs
    for bifurcation in found:
        bifurcation.returns = returns
    return Branch(source, back[::-1] + forward[1:], ends, returns), found


def distinct(bifurcations):
    """The bifurcations with those found twice (by two branches through one point) kept once."""
    kept = []
    for b in bifurcations:
        if not any(k.kind == b.kind and k.source == b.source and abs(k.parameter - b.parameter)
                   <= 10.0 * max(k.accuracy, b.accuracy, 1e-9 * max(abs(b.parameter), 1.0)) for k in kept):
            kept.append(b)
    return kept


def continue_cycles(family, name, bounds, starts, fmu_dir=None, max_points=BRANCH_POINTS, progress=None):
    """Branches of true cycles through each start ``(value, TrueCycle)``, and their bifurcations.

    A start on a branch already followed is skipped. All problems of one branch share one work budget.
    """
    span = bounds[1] - bounds[0]
    branches, found = [], []
    for value, cycle in starts:
        if _known(branches, "truth", value, cycle):
            continue
        problem = family.problem({name: value}, fmu_dir)
        problem = problem.alternate() if cycle.section else problem  # the section it was shot on
        swing = [v for i, v in enumerate(cycle.swing) if i != problem.pivot]
        y0 = problem.reduced(cycle.state) + [value]

        def system_of(cycle=cycle, swing=swing, budget=problem.budget):
            return CycleSystem(family, name, span, cycle.returns, swing, cycle.period, fmu_dir, budget,
                               cycle.section)

        _nodes, halves = trace(system_of, y0, bounds, max_points, progress)
        branch, more = _assemble("truth", halves, span, family, name, bounds, fmu_dir, cycle.returns)
        if branch.points:
            branches.append(branch)
            found += more
    return branches, distinct(found)


def _df_end(system, nodes, reason):
    """Why a DF branch ends, in the DF's terms: where the force falls to what barely moves the plant, N -> 0."""
    if nodes and reason.startswith("the branch cannot") and nodes[-1].y[0] <= system.log_F[0] + 1e-3:
        return "the force falls to the least that moves the plant (below it N = 0: no balance)"
    return reason


def continue_predictions(family, name, bounds, starts, engine, F_range, max_points=BRANCH_POINTS, progress=None):
    """Branches of DF predictions through each start ``(value, Cycle)``, and their folds."""
    span = bounds[1] - bounds[0]
    branches, found = [], []
    for value, prediction in starts:
        if _known(branches, "df", value, prediction):
            continue
        y0 = [math.log(prediction.F), math.log(prediction.omega), value]
        _nodes, halves = trace(lambda: PredictionSystem(family, name, span, engine, F_range), y0, bounds,
                               max_points, progress)
        halves = [(system, nodes, _df_end(system, nodes, reason)) for system, nodes, reason in halves]
        branch, more = _assemble("df", halves, span, family, name, bounds, None)
        if branch.points:
            branches.append(branch)
            found += more
    return branches, distinct(found)
