"""The three plants in feedback with a linear controller, as exact hybrid systems.

    f = -G(s) y,   G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an),   n = 1..8

The plant's output y (the friction mass's x, the two-mass backlash's x1, the
static backlash's output y) drives the controller; its output is the force
on the plant. The controller is realised as :class:`~.linear_system.LinearSystem`
realises it (controllable canonical form, state z), so the loop's state is
the plant's coordinates followed by z, and every mode of the plant makes the
loop an affine system X' = A X + c, integrated exactly by
:class:`~.hybrid.HybridSolver`:

* friction (Dv = 0): slide +-1 (Ff = Fc sgn v + B v) until v reaches 0;
  stick (v = 0, x held) until |f| exceeds Fs, breaking away in the direction
  of f; at v = 0 the mass sticks while |f| <= Fs.
* two-mass backlash: flight until the gap g reaches 0 or h, an impact
  (w -> -eps w, momentum kept); contact (the masses move together) while f
  presses them into the wall and the next bounce would rise less than 1e-12 h
  (the accumulation of impacts is over), released when f turns.
* static backlash: y held while x moves in the play; engaged (y = k (x -+ h/2))
  from x reaching an edge until its velocity reverses.

Plain Python only: this module runs inside the FMUs.
"""

from .backlash import TABLE as BACKLASH
from .backlash import TwoMassBacklash, check_backlash
from .contract import EventKind
from .friction import TABLE as FRICTION
from .friction import FrictionMass, check_friction
from .hybrid import HybridSolver
from .linear_system import LinearSystem
from .piecewise import check
from .static_backlash import TABLE as STATIC_BACKLASH
from .static_backlash import StaticBacklash, check_static_backlash

_fr, _bl, _sb = FRICTION.default, BACKLASH.default, STATIC_BACKLASH.default  # the plants' defaults (fmus/table.py)

STICK = ("stick", 0)
FREE = ("free", 0)


def _controller(b, a):
    """(Ac, Bc, C, D) of -G(s): the force is -G(s) y (checked as LinearSystem checks it)."""
    system = LinearSystem(b, a)
    Ac, Bc, C, D = system.matrices()
    return Ac, Bc, [-value for value in C], -D


class FeedbackLoop(HybridSolver):
    """A plant whose coordinates are ``q`` (``coordinates``), y = q[OUTPUT], in feedback with -G(s).

    Subclasses describe each mode by the plant's part (:meth:`plant_mode`):
    q' = P q + p + phi f, and event functions Lq.q + Lf f + l0; this class
    couples them with the controller into the loop's A, c and L.

    ``state`` (the whole loop state) overrides the initial values; ``section``
    watches the output rising through that level (``crossings``); ``modes``
    (a dict) and ``budget`` (a :class:`~.hybrid.Budget`) are shared by the
    solvers of one study.
    """

    coordinates = ()
    OUTPUT = 0
    initial_parameters = ()  # the plant parameters that set q at t = 0 (superseded by ``state``)
    plant = None  # the plant's open-loop solver (:mod:`.friction` ...): its orbits start a shooting
    KEYS = ()  # the mode keys, in the compiled core's order
    # The Poincare section every periodic orbit crosses: legs, each the (mode key, event kind) pairs that end it
    # (an event of the first leg, then one of the second: a lower turn, then an upper one). A point of the
    # section is the state the last leg's event leaves; there coordinate PIVOT is fixed by the others (pivot()).
    SECTION = ()
    PIVOT = 0

    @staticmethod
    def coordinates_of(output):
        """The loop's plant coordinates q from the open-loop solver's ``output()``."""
        raise NotImplementedError

    def check_coordinates(self, q):
        """Refuse plant coordinates that are no state of the plant (PlantError naming them)."""

    def translate(self, q, d):
        """q with the plant moved so that its output moves by d (the plant is translation invariant)."""
        q = list(q)
        q[self.OUTPUT] += d
        return q

    def pivot(self, X):
        """The value of coordinate PIVOT on the section, given the state's other coordinates."""
        raise NotImplementedError

    def linear(self):
        """(num, den) of the plant with its nonlinearity removed, from the force to the output."""
        raise NotImplementedError

    def nonlinearity(self):
        """("force", F) or ("length", d): the size of the nonlinearity, as a force or in output units."""
        raise NotImplementedError

    def still(self, F, omega):
        """Whether F cos(omega t) leaves the output still (its describing function is 0 there)."""
        raise NotImplementedError

    def __init__(self, b, a, q0, z0=None, state=None, section=None, modes=None, budget=None):
        self.Ac, self.Bc, self.C, self.D = _controller(b, a)
        self.order = n = len(self.Ac)
        m = len(self.coordinates)
        if state is not None:  # the whole loop state: the plant's coordinates, then z
            check("length of state", len(state), len(state) == m + n,
                  f"the loop's state has {m} plant coordinates {self.coordinates} and {n} controller states")
            q0, z0 = list(state[:m]), list(state[m:])
            for name, value in zip(self.coordinates, q0):
                check(name, value, True, f"{name} must be a finite number")
            self.check_coordinates(q0)
        z0 = [0.0] * n if z0 is None else list(z0)
        check("length of z0", len(z0), len(z0) == n, f"z0 needs {n} components (the controller's order)")
        for i, value in enumerate(z0, start=1):
            check(f"z{i}_0", value, True, f"the controller state z{i}_0 must be a finite number")
        watch = None
        if section is not None:  # upward crossings of y through the level ``section``
            check("section", section, True, "the section level must be a finite number")
            L = [0.0] * (m + n)
            L[self.OUTPUT] = 1.0
            watch = (L, -float(section))
        super().__init__(watch, modes, budget)
        key, X0, departing = self.initial(list(q0) + z0)
        self.start(0.0, X0, key, departing)

    # -- the loop's equations --------------------------------------------------------
    def force(self, X):
        """f = -G(s) y: D y + C z at the state X."""
        m = len(self.coordinates)
        return self.D * X[self.OUTPUT] + sum(c * z for c, z in zip(self.C, X[m:]))

    def system(self, key):
        P, p, phi, events = self.plant_mode(key)
        m, n, out = len(self.coordinates), self.order, self.OUTPUT
        # f = D y + C z: a row over the whole state
        f_row = [0.0] * (m + n)
        f_row[out] += self.D
        f_row[m:] = list(self.C)
        A = []
        for i in range(m):
            row = list(P[i]) + [0.0] * n
            A.append([value + phi[i] * fv for value, fv in zip(row, f_row)])
        for i in range(n):
            row = [0.0] * m + list(self.Ac[i])
            row[out] += self.Bc[i]
            A.append(row)
        c = list(p) + [0.0] * n
        full = []
        for kind, Lq, Lf, l0 in events:
            L = list(Lq) + [0.0] * n
            full.append((kind, [value + Lf * fv for value, fv in zip(L, f_row)], l0))
        return A, c, full

    def plant_mode(self, key):
        raise NotImplementedError

    def initial(self, X):
        """(mode key, state, departing event index) at t = 0."""
        raise NotImplementedError

    # -- outputs -------------------------------------------------------------------------
    def output(self):
        """The plant's output y at self.t."""
        return self.state()[self.OUTPUT]

    def counts(self):
        """What the loop counts (stick phases, impacts, engagements)."""
        return {}


class FrictionLoop(FeedbackLoop):
    """The friction mass (CVS friction, Dv = 0) in feedback with -G(s); q = (x, v), y = x."""

    coordinates = ("x", "v")
    initial_parameters = ("x0", "v0")
    plant = FrictionMass
    KEYS = (STICK, ("slide", 1), ("slide", -1))
    SECTION = (((("slide", -1), EventKind.BAND),), ((("slide", 1), EventKind.BAND),))  # x at a minimum, a maximum
    PIVOT = 1  # v = 0

    def pivot(self, X):
        return 0.0

    def linear(self):
        return [1.0], [self.M, self.B, 0.0]

    def nonlinearity(self):
        return "force", max(self.Fs, self.Fc)

    def still(self, F, omega):
        return F <= self.Fs  # the mass never breaks away

    @staticmethod
    def coordinates_of(output):
        return [output.x, output.v]

    def __init__(self, b, a, M=_fr.M, B=_fr.B, Fc=_fr.Fc, Fs=_fr.Fs, Dv=_fr.Dv, x0=_fr.x0, v0=_fr.v0, z0=None,
                 state=None, section=None, modes=None, budget=None):
        check_friction(M, B, Fc, Fs, Dv, x0, v0, exact_stick=True)
        self.M, self.B, self.Fc, self.Fs = M, B, Fc, Fs
        self.sticks = 0
        super().__init__(b, a, (x0, v0), z0, state, section, modes, budget)

    def plant_mode(self, key):
        M = self.M
        if key == STICK:
            return ([[0.0, 0.0], [0.0, 0.0]], [0.0, 0.0], [0.0, 0.0],
                    [(EventKind.BREAK_UP, (0.0, 0.0), -1.0, self.Fs),  # Fs - f > 0
                     (EventKind.BREAK_DOWN, (0.0, 0.0), 1.0, self.Fs)])  # f + Fs > 0
        s = key[1]
        return ([[0.0, 1.0], [0.0, -self.B / M]], [0.0, -s * self.Fc / M], [0.0, 1.0 / M],
                [(EventKind.BAND, (0.0, float(s)), 0.0, 0.0)])  # s v > 0

    def initial(self, X):
        v = X[1]
        if v != 0.0:
            return ("slide", 1 if v > 0.0 else -1), X, None
        return self._rest(X)

    def _rest(self, X):
        """At v = 0: stick while -Fs <= f <= Fs, else slide in the direction of f."""
        if self.after(STICK, 0, X) < 0:
            return ("slide", 1), X, 0
        if self.after(STICK, 1, X) < 0:
            return ("slide", -1), X, 0
        self.sticks += 1
        return STICK, X, None

    def _fire(self, t, kind, X):
        if kind is EventKind.BAND:
            X[1] = 0.0
            return self._rest(X)
        return ("slide", 1 if kind is EventKind.BREAK_UP else -1), X, 0

    def counts(self):
        return {"sticks": self.sticks}


class BacklashLoop(FeedbackLoop):
    """The two-mass backlash in feedback with -G(s); q = (x1, v1, g, w), y = x1, f on M2."""

    coordinates = ("x1", "v1", "gap", "w")
    initial_parameters = ("x1_0", "v1_0", "v2_0", "gap0")
    plant = TwoMassBacklash
    KEYS = (FREE, ("contact", -1), ("contact", 1))
    SECTION = (((FREE, EventKind.WALL_LOWER),), ((FREE, EventKind.WALL_UPPER),))  # an impact at 0, then at h
    PIVOT = 2  # gap = h

    def pivot(self, X):
        return self.h

    def linear(self):
        return [1.0], [self.M1 + self.M2, 0.0, 0.0]

    def nonlinearity(self):
        return "length", self.h

    def still(self, F, omega):
        return F <= 0.25 * self.h * self.M2 * omega * omega  # M2 from rest at the centre never reaches a wall

    @staticmethod
    def coordinates_of(output):
        return [output.x1, output.v1, output.gap, output.v2 - output.v1]

    def __init__(self, b, a, M1=_bl.M1, M2=_bl.M2, h=_bl.h, eps=_bl.eps, x1_0=_bl.x1_0, v1_0=_bl.v1_0, v2_0=_bl.v2_0,
                 gap0=_bl.gap0, z0=None, state=None, section=None, modes=None, budget=None):
        gap0 = check_backlash(M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)
        self.M1, self.M2, self.h, self.eps = M1, M2, h, eps
        self.r2 = M2 / (M1 + M2)
        self.tol_h = 1e-12 * h
        self.impacts = 0
        super().__init__(b, a, (x1_0, v1_0, gap0, v2_0 - v1_0), z0, state, section, modes, budget)

    def check_coordinates(self, q):
        check("gap", q[2], lambda: 0.0 <= q[2] <= self.h, f"the gap must be in [0, h] = [0, {self.h!r}] (m)")

    def plant_mode(self, key):
        if key == FREE:
            return ([[0.0, 1.0, 0.0, 0.0], [0.0] * 4, [0.0, 0.0, 0.0, 1.0], [0.0] * 4], [0.0] * 4,
                    [0.0, 0.0, 0.0, 1.0 / self.M2],
                    [(EventKind.WALL_LOWER, (0.0, 0.0, 1.0, 0.0), 0.0, 0.0),  # g > 0
                     (EventKind.WALL_UPPER, (0.0, 0.0, -1.0, 0.0), 0.0, self.h)])  # h - g > 0
        sigma = key[1]  # -1: held at gap 0, +1: at gap h
        return ([[0.0, 1.0, 0.0, 0.0], [0.0] * 4, [0.0] * 4, [0.0] * 4], [0.0] * 4,
                [0.0, 1.0 / (self.M1 + self.M2), 0.0, 0.0],
                [(EventKind.RELEASE, (0.0,) * 4, float(sigma), 0.0)])  # sigma f > 0: pressing

    def initial(self, X):
        if 0.0 < X[2] < self.h:
            return FREE, X, None
        return self._at_wall(-1 if X[2] <= 0.0 else 1, X)

    def _at_wall(self, sigma, X):
        """At a wall after any impact: contact, or a flight away from it."""
        X[2] = 0.0 if sigma < 0 else self.h
        w = X[3]
        press = self.after(("contact", sigma), 0, X)
        f = self.force(X)
        if (w == 0.0 and press >= 0) or (press > 0 and 0.5 * w * w * self.M2 <= self.tol_h * abs(f)):
            X[1] += self.r2 * w  # both move with the centre of mass
            X[3] = 0.0
            return ("contact", sigma), X, None
        return FREE, X, 0 if sigma < 0 else 1

    def _fire(self, t, kind, X):
        if kind is EventKind.RELEASE:
            X[3] = 0.0
            return FREE, X, 0 if self.key[1] < 0 else 1
        sigma = -1 if kind is EventKind.WALL_LOWER else 1
        w = X[3]
        if sigma * w > 0.0:  # closing: Newton's impact law, momentum kept
            new = -self.eps * w
            X[1] += self.r2 * (w - new)
            X[3] = new
            self.impacts += 1
        return self._at_wall(sigma, X)

    def counts(self):
        return {"impacts": self.impacts}


class StaticBacklashLoop(FeedbackLoop):
    """Mass + geometric backlash in feedback with -G(s); q = (x, v, y), y the backlash output."""

    coordinates = ("x", "v", "y")
    OUTPUT = 2
    initial_parameters = ("x0", "v0")
    plant = StaticBacklash
    KEYS = (FREE, ("engaged", 1), ("engaged", -1))
    SECTION = (((FREE, EventKind.ENGAGE_DOWN),), ((FREE, EventKind.ENGAGE_UP),))  # the lower edge, then the upper
    PIVOT = 0  # x = y/k + h/2: at the upper edge of the play

    def pivot(self, X):
        return X[2] / self.k + 0.5 * self.h

    def linear(self):
        return [self.k], [self.M, 0.0, 0.0]

    def nonlinearity(self):
        return "length", self.k * self.h

    def still(self, F, omega):
        return F <= 0.5 * self.h * self.M * omega * omega  # the mass swings inside the play: y never moves

    @staticmethod
    def coordinates_of(output):
        return [output.x, output.v, output.y]

    def translate(self, q, d):
        q = list(q)
        q[0] += d / self.k
        q[2] += d
        return q

    def __init__(self, b, a, M=_sb.M, k=_sb.k, h=_sb.h, x0=_sb.x0, v0=_sb.v0, z0=None, state=None, section=None,
                 modes=None, budget=None):
        check_static_backlash(M, k, h, x0, v0)
        self.M, self.k, self.h = M, k, h
        self.engagements = 0
        super().__init__(b, a, (x0, v0, k * x0), z0, state, section, modes, budget)

    def check_coordinates(self, q):
        play = q[0] - q[2] / self.k
        check("x - y/k", play, lambda: abs(play) <= 0.5 * self.h * (1.0 + 1e-9),
              f"the play x - y/k must be within +-h/2 = {0.5 * self.h!r} (m)")

    def plant_mode(self, key):
        M, k, half = self.M, self.k, 0.5 * self.h
        if key == FREE:
            return ([[0.0, 1.0, 0.0], [0.0] * 3, [0.0] * 3], [0.0] * 3, [0.0, 1.0 / M, 0.0],
                    [(EventKind.ENGAGE_UP, (-1.0, 0.0, 1.0 / k), 0.0, half),  # y/k + h/2 - x > 0
                     (EventKind.ENGAGE_DOWN, (1.0, 0.0, -1.0 / k), 0.0, half)])  # x - y/k + h/2 > 0
        s = key[1]
        return ([[0.0, 1.0, 0.0], [0.0] * 3, [0.0, k, 0.0]], [0.0] * 3, [0.0, 1.0 / M, 0.0],
                [(EventKind.REVERSE, (0.0, float(s), 0.0), 0.0, 0.0)])  # s v > 0

    def initial(self, X):
        play = X[0] - X[2] / self.k
        for s in (1, -1):  # on an edge: engaged if moving on
            if s * play >= 0.5 * self.h * (1.0 - 1e-12):
                X[0] = X[2] / self.k + s * 0.5 * self.h  # on the edge, the given output kept
                return self._engage(s, X, count=False)
        return FREE, X, None

    def _engage(self, s, X, count=True):
        if count:  # reached the edge: y takes up from x (within rounding of the edge already)
            X[2] = self.k * (X[0] - s * 0.5 * self.h)
        if self.after(("engaged", s), 0, X) > 0:
            self.engagements += count
            return ("engaged", s), X, None
        return FREE, X, 0 if s > 0 else 1

    def _fire(self, t, kind, X):
        if kind is EventKind.REVERSE:
            s = self.key[1]
            X[1] = 0.0
            return FREE, X, 0 if s > 0 else 1
        return self._engage(1 if kind is EventKind.ENGAGE_UP else -1, X)

    def counts(self):
        return {"engagements": self.engagements}
