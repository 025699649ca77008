"""Mass with Coulomb, viscous and static friction, integrated exactly.

    M x'' + Ff = u(t),   u = f + F cos(omega t + phi)

Sliding (|v| > Dv): Ff = Fc sgn(v) + B v. With Dv = 0 (the default, CVS
model) the mass sticks at v = 0 while |u| <= Fs and breaks away in the
direction of u when |u| > Fs. With Dv > 0 (Karnopp's model) the band
|v| <= Dv has Ff = sat(u, Fs): the velocity is held while |u| <= Fs and is
pushed through the band by u - Fs sgn(u) otherwise.

Modes: hold (v constant, |v| <= Dv), push +-1 (inside the band, |u| > Fs),
slide +-1. Break-away and release are analytic crossings of the force;
stops (v reaching the band) are first zeros of the closed-form velocity.
"""

from .contract import EventKind
from .exact import Motion
from .loops import STICK, FeedbackLoop
from .piecewise import CurvatureBound, PiecewisePlant, Search, VelocitySearch, check
from .table import FORCE, MASS, START, Output, Parameter, PlantTable

TABLE = PlantTable(
    "friction",
    model="FrictionMass", summary="mass with Coulomb, viscous and static friction (exact stick-slip)",
    constants=(
        Parameter("M", 1.0, "kg", "mass (> 0)", (0.0, None), MASS),
        Parameter("B", 0.5, "N.s/m", "viscous friction coefficient (>= 0)", (0.0, None), (0.0, 1e9)),
        Parameter("Fc", 5.0, "N", "Coulomb friction force (>= 0)", (0.0, None), FORCE),
        Parameter("Fs", 7.0, "N", "static friction force (>= Fc)", (0.0, None), FORCE),
        Parameter("Dv", 0.0, "m/s", "Karnopp velocity band (0: exact stick at v = 0)", (0.0, None), (0.0, 1e3)),
    ),
    initial=START,
    outputs=(
        Output("x", "m", "position"),
        Output("v", "m/s", "velocity"),
        Output("Ff", "N", "friction force", feedthrough=True),  # stuck: Ff = u
        Output("mode", None, "0 stick (or inside the Karnopp band), +1/-1 sliding", integer=True,
               feedthrough=True),  # a new f can break away at once
    ),
    section=("x", "v"), modes=("mode",), starts={"x": "x0", "v": "v0"}, shifts={"x": 1.0}, position="x0",
)
DEFAULT = TABLE.default  # the keyword defaults below

HOLD, SLIDE, PUSH = "hold", "slide", "push"


def check_forces(M, B, Fc, Fs):
    """The checks of the mass and its friction forces, in order (the friction mass's first, a plant built on it
    too)."""
    check("M", M, lambda: M > 0.0, "M must be > 0 (kg)")
    check("B", B, lambda: B >= 0.0, "B must be >= 0 (N.s/m)")
    check("Fc", Fc, lambda: Fc >= 0.0, "Fc must be >= 0 (N)")
    check("Fs", Fs, lambda: Fs >= Fc, f"Fs must be >= Fc = {Fc!r} (N)")


def check_friction(M, B, Fc, Fs, Dv, x0, v0, exact_stick=False):
    """The friction mass's parameter checks, in order (shared with its closed loop, where ``exact_stick``: Dv = 0)."""
    check_forces(M, B, Fc, Fs)
    if exact_stick:
        check("Dv", Dv, lambda: Dv == 0.0, "Dv must be 0 in the exact closed loop (the CVS model: exact stick)")
    else:
        check("Dv", Dv, lambda: Dv >= 0.0, "Dv must be >= 0 (m/s)")
    check("x0", x0, True, "x0 must be a finite number (m)")
    check("v0", v0, True, "v0 must be a finite number (m/s)")


class FrictionMass(PiecewisePlant):
    """Exact solver of the friction mass; the output is the position x."""

    # what a run never changes: a restored FMU state's solver is held to it
    FIXED = ("M", "B", "Fc", "Fs", "Dv", "edge_force")

    def __init__(self, M=DEFAULT.M, B=DEFAULT.B, Fc=DEFAULT.Fc, Fs=DEFAULT.Fs, Dv=DEFAULT.Dv, F=0.0, omega=1.0, phi=0.0,
                 x0=DEFAULT.x0, v0=DEFAULT.v0, f=0.0, harmonics=10):
        check_friction(M, B, Fc, Fs, Dv, x0, v0)
        super().__init__(F, omega, phi, f, harmonics)
        self.M, self.B, self.Fc, self.Fs, self.Dv = M, B, Fc, Fs, Dv
        self.edge_force = Fc + B * Dv  # friction just outside the band
        self.mode, self.direction = HOLD, 0
        self._start(0.0, x0, v0)

    # -- outputs ---------------------------------------------------------
    def output(self):
        """x, v, friction force Ff and mode (0 stick or band, +-1 sliding) at self.t."""
        x, v = self._output.state(self.t)
        acc = self._output.acceleration(self.t, v)
        ff = self.drive.u(self.t) - self.M * acc
        return TABLE.output_type(x, v, ff, self.direction if self.mode == SLIDE else 0)

    # -- pieces ------------------------------------------------------------
    def _motion(self, t, x, v, lam, force):
        d = self.drive
        return Motion(t, x, v, lam, force / self.M, d.F / self.M, d.omega, d.phi)

    def _start(self, t, x, v, at_edge=0):
        """Choose the mode from the state and the force at t.

        ``at_edge`` = s when v has just reached the band edge s * Dv (up to
        rounding). The state stays continuous across the switch: a slide
        leaving v = 0 (Dv = 0) keeps the computed v rather than a snapped 0.
        """
        Dv = self.Dv
        if not at_edge and abs(v) > Dv:
            self._slide(t, x, v, 1 if v > 0.0 else -1, departing=False)
            return
        d = self.drive
        point_band = Dv == 0.0 and at_edge != 0  # both edges are v = 0
        upper = at_edge == 1 or v >= Dv or point_band
        lower = at_edge == -1 or v <= -Dv or point_band
        breakaway = max(self.Fs, self.edge_force)
        if upper and d.above(t, breakaway):
            self._slide(t, x, v if Dv == 0.0 else Dv, 1, departing=True)
        elif lower and d.below(t, -breakaway):
            self._slide(t, x, v if Dv == 0.0 else -Dv, -1, departing=True)
        elif not upper and d.above(t, self.Fs):
            self._push(t, x, v, 1)
        elif not lower and d.below(t, -self.Fs):
            self._push(t, x, v, -1)
        else:
            self._hold(t, x, at_edge * Dv if at_edge else v)

    def _hold(self, t, x, v):
        """Velocity held inside the band (stick when Dv = 0) while |u| is small."""
        self.mode, self.direction = HOLD, 0
        up = max(self.Fs, self.edge_force) if v >= self.Dv else self.Fs
        down = max(self.Fs, self.edge_force) if v <= -self.Dv else self.Fs
        t_up = self.drive.crossing(t, up, rising=True)
        t_down = self.drive.crossing(t, -down, rising=False)
        kind, t_ev = (EventKind.BREAK_UP, t_up) if t_up <= t_down else (EventKind.BREAK_DOWN, t_down)
        self._begin(t, Motion(t, x, v, 0.0, 0.0, 0.0, self.drive.omega, self.drive.phi), t_ev, kind)

    def _push(self, t, x, v, s):
        """Inside the band with |u| > Fs: friction Fs opposes u, v moves towards s * Dv."""
        self.mode, self.direction = PUSH, s
        motion = self._motion(t, x, v, 0.0, self.drive.f - s * self.Fs)
        t_release = self.drive.crossing(t, s * self.Fs, rising=s < 0)
        gap_to_edge = VelocitySearch(motion, -s, self.Dv)  # Dv - s v, -s v'
        search = Search(gap_to_edge, motion.curvature_bound(), t, EventKind.EDGE)
        self._begin(t, motion, t_release, EventKind.RELEASE, [search])

    def _slide(self, t, x, v, s, departing):
        """Sliding in direction s until the velocity falls back to the band."""
        self.mode, self.direction = SLIDE, s
        motion = self._motion(t, x, v, self.B / self.M, self.drive.f - s * self.Fc)
        # Leaving the band edge, s*v - Dv > 0 is proven while s*u > Fc + B Dv.
        t_from = self.drive.crossing(t, s * self.edge_force, rising=s < 0) if departing else t
        speed_above_band = VelocitySearch(motion, s, -self.Dv)  # s v - Dv, s v'
        # with damping, K is a function of t: the initial velocity's part of v'' decays
        K = CurvatureBound(motion) if self.B else motion.curvature_bound()
        search = Search(speed_above_band, K, t_from, EventKind.BAND)
        self._begin(t, motion, searches=[search])

    # -- events --------------------------------------------------------------
    def _fire(self, t, kind):
        self._close_piece(t)
        x, v = self._output.state(t)
        s = self.direction
        if kind is EventKind.BREAK_UP or kind is EventKind.BREAK_DOWN:
            s = 1 if kind is EventKind.BREAK_UP else -1
            if s * v >= self.Dv:
                self._slide(t, x, s * self.Dv, s, departing=True)
            else:
                self._push(t, x, v, s)
        elif kind is EventKind.RELEASE:  # |u| falls to Fs: hold, or (Fs = 0) a push the other way
            self._start(t, x, v)
        elif kind is EventKind.EDGE:  # pushed through the band to its edge s * Dv (Dv > 0)
            edge = s * self.edge_force
            if self.drive.above(t, edge) if s > 0 else self.drive.below(t, edge):
                self._slide(t, x, s * self.Dv, s, departing=True)
            else:
                self._hold(t, x, s * self.Dv)
        else:  # EventKind.BAND: the sliding velocity reached the band edge
            self._start(t, x, v, at_edge=s)
        return True

    def _restart(self, t):
        x, v = self._output.state(t)
        at_edge = self.direction if self.mode == SLIDE and abs(v) <= self.Dv else 0
        self._start(t, x, v, at_edge)


class FrictionLoop(FeedbackLoop):
    """The friction mass (CVS friction, Dv = 0) in feedback with -G(s); q = (x, v), y = x.

    Slide +-1 (Ff = Fc sgn v + B v) until v reaches 0; stick (v = 0, x held)
    until |f| exceeds Fs, breaking away in the direction of f; at v = 0 the
    mass sticks while |f| <= Fs.
    """

    coordinates = ("x", "v")
    initial_parameters = ("x0", "v0")
    plant = FrictionMass
    KEYS = (STICK, ("slide", 1), ("slide", -1))
    REST_EVENTS = (EventKind.BAND,)  # v reaches 0
    MODE_VALUES = {STICK: 0, ("slide", 1): 1, ("slide", -1): -1}
    CONSTANTS = ("M", "B", "Fc", "Fs")
    FMU_OUTPUTS = (Output("x", "m", "position (the output y fed back to the controller)"),
                   Output("v", "m/s", "velocity"),
                   Output("Ff", "N", "friction force (stuck: it balances f)"))
    MODE_OUTPUT = Output("mode", None, "0 stick, +1/-1 sliding", integer=True)
    COUNTER = Output("sticks", None, "number of stick phases so far (one at the start time if the mass starts "
                     "stuck)", integer=True, counter=True)
    FMU_RANGES = {"Dv": (0.0, 0.0)}
    FMU_DESCRIPTIONS = {"Dv": "Karnopp velocity band: must be 0 (the loop is solved with exact stick at v = 0)"}
    SECTION = (((("slide", -1), EventKind.BAND),), ((("slide", 1), EventKind.BAND),))  # x at a minimum, a maximum
    PIVOT = 1  # v = 0

    def pivot(self, X):
        return 0.0

    @staticmethod
    def fmu_values(loop, X, f):
        s = FrictionLoop.MODE_VALUES[loop.key]
        return {"x": X[0], "v": X[1], "Ff": f if s == 0 else s * loop.Fc + loop.B * X[1]}

    def linear(self):
        return [1.0], [self.M, self.B, 0.0]

    def nonlinearity(self):
        return "force", max(self.Fs, self.Fc)

    def still(self, F, omega):
        return F <= self.Fs  # the mass never breaks away

    @staticmethod
    def coordinates_of(output):
        return [output.x, output.v]

    def __init__(self, b, a, M=DEFAULT.M, B=DEFAULT.B, Fc=DEFAULT.Fc, Fs=DEFAULT.Fs, Dv=DEFAULT.Dv, x0=DEFAULT.x0,
                 v0=DEFAULT.v0, z0=None, state=None, section=None, modes=None, budget=None, compensation=None):
        check_friction(M, B, Fc, Fs, Dv, x0, v0, exact_stick=True)
        self.M, self.B, self.Fc, self.Fs = M, B, Fc, Fs
        self.sticks = 0
        super().__init__(b, a, (x0, v0), z0, state, section, modes, budget, compensation)

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
        slide = self._breakaway(X)
        if slide is not None:
            return slide, X, 0
        self.sticks += 1
        return STICK, X, None

    def _breakaway(self, X):
        """The slide a mass at rest at X breaks into (the force on it beyond Fs), or None: it sticks."""
        if self.after(STICK, 0, X) < 0:
            return ("slide", 1)
        if self.after(STICK, 1, X) < 0:
            return ("slide", -1)
        return None

    def slip(self, key):
        return 0 if key == STICK else key[1]

    def settle(self, key, X):
        slide = self._breakaway(X) if key == STICK else None
        return (key, X, None) if slide is None else (slide, X, 0)

    def _fire(self, t, kind, X):
        if kind is EventKind.BAND:
            X[1] = 0.0
            return self._rest(X)
        return ("slide", 1 if kind is EventKind.BREAK_UP else -1), X, 0


SOLVER, LOOP = FrictionMass, FrictionLoop
