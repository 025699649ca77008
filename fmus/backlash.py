"""Two masses with a clearance and impacts, integrated exactly.

M2 carries the force u = f + F cos(omega t + phi); M1 is free. The gap
g = x2 - x1 stays in [0, h]. The state is the centre of mass (x_cm, v_cm)
and the relative motion (g, w = g'): the centre of mass obeys
(M1 + M2) x_cm'' = u in every mode, a single closed form that impacts never
touch, so momentum is conserved exactly by construction; between impacts
g'' = u / M2, so impacts are first zeros of the closed-form gap at 0 and h.
An impact follows Newton's law with restitution eps: w -> -eps w. When u
presses the masses together and the next bounce would rise less than
``tol_h`` (a 1e-12 fraction of h), the accumulation of impacts is complete
for all purposes: the masses move together (w = 0) until u turns to pull
them apart (an analytic crossing of zero). Neither the gap nor the momentum
suffers the cancellation of x2 - x1 or M1 v1 + M2 v2 when the masses have
drifted far or their masses differ by orders of magnitude.
"""

from .contract import EventKind
from .exact import Motion
from .loops import FREE as FLIGHT  # the loop's mode key of free flight
from .loops import FeedbackLoop
from .piecewise import PiecewisePlant, PositionSearch, Search, VelocitySearch, check
from .table import MASS, POSITION, VELOCITY, Output, Parameter, PlantTable

MIN_CLEARANCE = 1e-290  # m: the Zeno tolerance 1e-12 h stays a normal float
FREE, LOWER, UPPER = 0, 1, 2  # the ``contact`` output: free, at gap 0, at gap h
SIDE = {LOWER: -1, UPPER: 1}  # sigma: pressing into the boundary means sigma * u > 0
WALL = {EventKind.WALL_LOWER: LOWER, EventKind.WALL_UPPER: UPPER}  # the event of reaching a wall -> contact


GAP0_FMU = ", or -1 in an FMU (h/2)"  # an FMU's start value -1 stands for h/2 (its facades map it)


TABLE = PlantTable(
    "backlash",
    model="TwoMassBacklash", summary="two masses with a clearance and impacts of restitution eps (the force on M2)",
    constants=(
        Parameter("M1", 1.0, "kg", "mass 1, the output side (> 0)", (0.0, None), MASS),
        Parameter("M2", 1.0, "kg", "mass 2, driven by the force (> 0)", (0.0, None), MASS),
        Parameter("h", 0.1, "m", "clearance (> 0)", (0.0, None), (1e-9, 1e3)),
        Parameter("eps", 0.5, None, "coefficient of restitution, in [0, 1]", (0.0, 1.0)),
    ),
    initial=(
        Parameter("x1_0", 0.0, "m", "initial position of M1", accepted=POSITION),
        Parameter("v1_0", 0.0, "m/s", "initial velocity of M1", accepted=VELOCITY),
        Parameter("v2_0", 0.0, "m/s", "initial velocity of M2", accepted=VELOCITY),
        Parameter("gap0", None, "m", "initial gap x2 - x1, in [0, h]; -1 (default): h/2", (-1.0, None), start=-1.0,
                  half_of="h"),
    ),
    outputs=(
        Output("x1", "m", "position of M1"),
        Output("v1", "m/s", "velocity of M1"),
        Output("x2", "m", "position of M2"),
        Output("v2", "m/s", "velocity of M2"),
        Output("gap", "m", "gap x2 - x1, in [0, h]"),
        Output("contact", None, "0 free, 1 in contact at gap 0, 2 in contact at gap h", integer=True, counter=True),
        Output("impacts", None, "number of impacts so far", integer=True, counter=True),
    ),
    section=("x1", "v1", "gap", "v2"), modes=("contact",), starts={"x1": "x1_0", "v1": "v1_0", "gap": "gap0",
                                                                      "v2": "v2_0"},
    shifts={"x1": 1.0}, position="x1_0", counter="impacts",
)
DEFAULT = TABLE.default  # the keyword defaults below


def check_backlash(M1, M2, h, eps, x1_0, v1_0, v2_0, gap0=None):
    """The two-mass backlash's parameter checks, in order (shared with its closed loop); gap0 (None: h/2)."""
    check("M1", M1, lambda: M1 > 0.0, "M1 must be > 0 (kg)")
    check("M2", M2, lambda: M2 > 0.0, "M2 must be > 0 (kg)")
    # below, tol_h underflows and a pressed bounce never comes to rest: impacts without end
    check("h", h, lambda: h >= MIN_CLEARANCE, f"h must be >= {MIN_CLEARANCE:g} (m)")
    check("eps", eps, lambda: 0.0 <= eps <= 1.0, "eps must be in [0, 1]")
    gap0 = 0.5 * h if gap0 is None else gap0
    check("gap0", gap0, lambda: 0.0 <= gap0 <= h, f"gap0 must be in [0, h] = [0, {h!r}] (m){GAP0_FMU}")
    for name, value in (("x1_0", x1_0), ("v1_0", v1_0), ("v2_0", v2_0)):
        check(name, value, True, f"{name} must be a finite number")
    return gap0


class TwoMassBacklash(PiecewisePlant):
    """Exact solver of the two-mass backlash; the output is x1."""

    # what a run never changes: a restored FMU state's solver is held to it
    FIXED = ("M1", "M2", "h", "eps", "total", "r1", "r2", "tol_h")

    def __init__(self, M1=DEFAULT.M1, M2=DEFAULT.M2, h=DEFAULT.h, eps=DEFAULT.eps, F=0.0, omega=1.0, phi=0.0,
                 x1_0=DEFAULT.x1_0, v1_0=DEFAULT.v1_0, v2_0=DEFAULT.v2_0, gap0=DEFAULT.gap0, f=0.0, harmonics=10):
        gap0 = check_backlash(M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)
        super().__init__(F, omega, phi, f, harmonics)
        self.M1, self.M2, self.h, self.eps = M1, M2, h, eps
        self.total = M1 + M2
        self.r1, self.r2 = M1 / self.total, M2 / self.total  # x1 = x_cm - r2 g, x2 = x_cm + r1 g
        self.tol_h = 1e-12 * h
        self.impacts = 0
        self.contact = FREE
        self._departing = 0
        self._centre(0.0, x1_0 + self.r2 * gap0, self.r1 * v1_0 + self.r2 * v2_0)
        self._start(0.0, gap0, v2_0 - v1_0)

    # -- state -------------------------------------------------------------
    def _centre(self, t, x_cm, v_cm):
        d = self.drive
        self._cm = Motion(t, x_cm, v_cm, 0.0, d.f / self.total, d.F / self.total, d.omega, d.phi)

    def relative(self, t):
        """(g, w) at t."""
        if self.contact == FREE:
            return self._gap.state(t)
        return (0.0 if self.contact == LOWER else self.h), 0.0

    def output(self):
        """x1, v1, x2, v2, gap at self.t (x1, v1 as integrated into the Fourier outputs)."""
        x1, v1 = self._output.state(self.t)
        g, w = self.relative(self.t)
        if self.contact != FREE:  # riding together: one closed form for both
            return TABLE.output_type(x1, v1, x1 + g, v1, g)
        x_cm, v_cm = self._cm.state(self.t)
        return TABLE.output_type(x1, v1, x_cm + self.r1 * g, v_cm + self.r1 * w, g)

    # -- pieces -------------------------------------------------------------
    def _start(self, t, g, w):
        if g <= 0.0:
            self._at_boundary(t, LOWER, w)
        elif g >= self.h:
            self._at_boundary(t, UPPER, w)
        else:
            self._free(t, g, w, departing=0)

    def _at_boundary(self, t, side, w):
        """Impact (if closing), then contact or a flight away from the boundary."""
        sigma = SIDE[side]
        if sigma * w > 0.0:
            w = -self.eps * w
            self.impacts += 1
        u = self.drive.u(t)
        pressing = self.drive.above(t, 0.0) if sigma > 0 else self.drive.below(t, 0.0)
        pulling = self.drive.below(t, 0.0) if sigma > 0 else self.drive.above(t, 0.0)
        if (w == 0.0 and not pulling) or (pressing and 0.5 * w * w * self.M2 <= self.tol_h * abs(u)):
            self._contact(t, side)
        else:
            self._free(t, 0.0 if side == LOWER else self.h, w, departing=sigma)

    def _output_motion(self, t, g, w, a, b):
        """x1's closed form from t: free (a = b = 0) or riding with the centre of mass."""
        x_cm, v_cm = self._cm.state(t)
        d = self.drive
        return Motion(t, x_cm - self.r2 * g, v_cm - self.r2 * w, 0.0, a, b, d.omega, d.phi)

    def _free(self, t, g, w, departing):
        """Flight; ``departing`` = sigma of the boundary just left (0: none)."""
        d = self.drive
        self.contact = FREE
        self._departing = departing
        self._gap = gap = Motion(t, g, w, 0.0, d.f / self.M2, d.F / self.M2, d.omega, d.phi)
        self._begin(t, self._output_motion(t, g, w, 0.0, 0.0), searches=self._boundary_searches(t, skip=departing))
        if departing:
            # The gap cannot return to the boundary it left before the
            # separation speed -sigma*w falls to zero: search that apex first.
            separation = VelocitySearch(gap, -departing)  # -sigma w, -sigma w'
            sep = -departing * w
            t_from = t if sep > 0.0 else d.crossing(t, 0.0, rising=departing > 0)
            self._searches.append(Search(separation, gap.curvature_bound(), t_from, EventKind.APEX))

    def _boundary_searches(self, t, skip=0):
        gap, h = self._gap, self.h
        K = abs(gap.a) + abs(gap.b)
        above_lower = PositionSearch(gap)  # g, w
        below_upper = PositionSearch(gap, h)  # h - g, -w

        searches = []
        if skip != SIDE[LOWER]:
            searches.append(Search(above_lower, K, t, EventKind.WALL_LOWER))
        if skip != SIDE[UPPER]:
            searches.append(Search(below_upper, K, t, EventKind.WALL_UPPER))
        return searches

    def _contact(self, t, side):
        """The masses move together until u stops pressing them into the boundary."""
        d = self.drive
        self.contact = side
        self._departing = 0
        wall = 0.0 if side == LOWER else self.h
        output = self._output_motion(t, wall, 0.0, d.f / self.total, d.F / self.total)
        t_release = d.crossing(t, 0.0, rising=SIDE[side] < 0)
        self._begin(t, output, t_release, EventKind.RELEASE)

    # -- events ---------------------------------------------------------------
    def _fire(self, t, kind):
        if kind is EventKind.APEX:
            self._departing = 0
            self._set_searches(t, self._boundary_searches(t))
            return False
        g, w = self.relative(t)
        self._close_piece(t)
        if kind is EventKind.RELEASE:
            side = self.contact
            self._free(t, 0.0 if side == LOWER else self.h, 0.0, departing=SIDE[side])
        else:
            self._at_boundary(t, WALL[kind], w)
        return True

    def _restart(self, t):
        g, w = self.relative(t)
        self._centre(t, *self._cm.state(t))  # the new input changes the centre's closed form
        if self.contact != FREE:
            self._at_boundary(t, self.contact, 0.0)
        elif self._departing and -self._departing * w <= 0.0:
            # still at the wall it was leaving (no separation speed yet): the new force decides
            self._at_boundary(t, LOWER if self._departing < 0 else UPPER, w)
        elif self._departing:
            self._free(t, g, w, departing=self._departing)
        else:
            self._start(t, g, w)


class BacklashLoop(FeedbackLoop):
    """The two-mass backlash in feedback with -G(s); q = (x1, v1, g, w), y = x1, f on M2.

    Flight until the gap g reaches 0 or h, an impact (w -> -eps w, momentum
    kept); contact (the masses move together) while f presses them into the
    wall and the next bounce would rise less than 1e-12 h (the accumulation
    of impacts is over), released when f turns.
    """

    coordinates = ("x1", "v1", "gap", "w")
    initial_parameters = ("x1_0", "v1_0", "v2_0", "gap0")
    plant = TwoMassBacklash
    KEYS = (FLIGHT, ("contact", -1), ("contact", 1))
    MODE_VALUES = {FLIGHT: 0, ("contact", -1): 1, ("contact", 1): 2}
    CONSTANTS = ("M1", "M2", "h", "eps", "r2", "tol_h")
    FMU_OUTPUTS = (Output("x1", "m", "position of M1 (the output y fed back to the controller)"),) + TABLE.outputs[1:5]
    MODE_OUTPUT = TABLE.outputs[5]  # contact
    COUNTER = TABLE.outputs[6]  # impacts
    SECTION = (((FLIGHT, EventKind.WALL_LOWER),), ((FLIGHT, EventKind.WALL_UPPER),))  # an impact at 0, then at h
    CONTACTS = {EventKind.WALL_UPPER: 1, EventKind.WALL_LOWER: -1}  # M2 reaches the upper wall (drags M1 up) / lower
    PIVOT = 2  # gap = h

    def pivot(self, X):
        return self.h

    @staticmethod
    def fmu_values(loop, X, f):
        x1, v1, g, w = X[0], X[1], X[2], X[3]
        return {"x1": x1, "v1": v1, "x2": x1 + g, "v2": v1 + w, "gap": g}

    def linear(self):
        return [1.0], [self.M1 + self.M2, 0.0, 0.0]

    def nonlinearity(self):
        return "length", self.h

    def still(self, F, omega):
        return F <= 0.25 * self.h * self.M2 * omega * omega  # M2 from rest at the centre never reaches a wall

    @staticmethod
    def coordinates_of(output):
        return [output.x1, output.v1, output.gap, output.v2 - output.v1]

    def __init__(self, b, a, M1=DEFAULT.M1, M2=DEFAULT.M2, h=DEFAULT.h, eps=DEFAULT.eps, x1_0=DEFAULT.x1_0,
                 v1_0=DEFAULT.v1_0, v2_0=DEFAULT.v2_0, gap0=DEFAULT.gap0, z0=None, state=None, section=None,
                 modes=None, budget=None, compensation=None):
        gap0 = check_backlash(M1, M2, h, eps, x1_0, v1_0, v2_0, gap0)
        self.M1, self.M2, self.h, self.eps = M1, M2, h, eps
        self.r2 = M2 / (M1 + M2)
        self.tol_h = 1e-12 * h
        self.impacts = 0
        super().__init__(b, a, (x1_0, v1_0, gap0, v2_0 - v1_0), z0, state, section, modes, budget, compensation)

    def check_coordinates(self, q):
        check("gap", q[2], lambda: 0.0 <= q[2] <= self.h, f"the gap must be in [0, h] = [0, {self.h!r}] (m)")

    def plant_mode(self, key):
        if key == FLIGHT:
            return ([[0.0, 1.0, 0.0, 0.0], [0.0] * 4, [0.0, 0.0, 0.0, 1.0], [0.0] * 4], [0.0] * 4,
                    [0.0, 0.0, 0.0, 1.0 / self.M2],
                    [(EventKind.WALL_LOWER, (0.0, 0.0, 1.0, 0.0), 0.0, 0.0),  # g > 0
                     (EventKind.WALL_UPPER, (0.0, 0.0, -1.0, 0.0), 0.0, self.h)])  # h - g > 0
        sigma = key[1]  # -1: held at gap 0, +1: at gap h
        return ([[0.0, 1.0, 0.0, 0.0], [0.0] * 4, [0.0] * 4, [0.0] * 4], [0.0] * 4,
                [0.0, 1.0 / (self.M1 + self.M2), 0.0, 0.0],
                [(EventKind.RELEASE, (0.0,) * 4, float(sigma), 0.0)])  # sigma f > 0: pressing

    def half_play(self):
        return 0.5

    def wall(self, X):
        return 0 if 0.0 < X[2] < self.h else -1 if X[2] <= 0.0 else 1

    def initial(self, X):
        side = self.wall(X)
        return (FLIGHT, X, None) if not side else self._at_wall(side, X)

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
        return FLIGHT, X, 0 if sigma < 0 else 1

    def _fire(self, t, kind, X):
        if kind is EventKind.RELEASE:
            X[3] = 0.0
            return FLIGHT, X, 0 if self.key[1] < 0 else 1
        sigma = -1 if kind is EventKind.WALL_LOWER else 1
        w = X[3]
        if sigma * w > 0.0:  # closing: Newton's impact law, momentum kept
            new = -self.eps * w
            X[1] += self.r2 * (w - new)
            X[3] = new
            self.impacts += 1
        return self._at_wall(sigma, X)


SOLVER, LOOP = TwoMassBacklash, BacklashLoop
