"""A mass followed by the geometric backlash element, integrated exactly.

M x'' = u(t) gives the input x of a backlash (play) element of slope k and
total width h: y / k stays within [x - h/2, x + h/2] and moves only when x
drags it. Engagement (x reaching y/k +- h/2) is a first zero of the
closed-form position; disengagement is the velocity reversal, a first zero
of the closed-form velocity. The output is y; it starts centred, y = k x0.
"""

from .contract import EventKind
from .exact import Motion
from .loops import FREE, FeedbackLoop
from .piecewise import EdgeSearch, PiecewisePlant, Search, VelocitySearch, check
from .table import MASS, START, Output, Parameter, PlantTable

ENGAGE = {1: EventKind.ENGAGE_UP, -1: EventKind.ENGAGE_DOWN}  # the edge x reaches -> the event
EDGE = {kind: s for s, kind in ENGAGE.items()}


TABLE = PlantTable(
    "static-backlash",
    model="StaticBacklash", summary="mass driven by the force, followed by a static backlash (dead band h, slope k)",
    constants=(
        Parameter("M", 2.0, "kg", "mass (> 0)", (0.0, None), MASS),
        Parameter("k", 1.0, None, "slope of the backlash element (> 0)", (0.0, None), (1e-6, 1e6)),
        Parameter("h", 0.1, "m", "total width of the dead band (> 0)", (0.0, None), (1e-9, 1e3)),
    ),
    initial=START,
    outputs=(
        Output("x", "m", "position of the mass (backlash input)"),
        Output("v", "m/s", "velocity of the mass"),
        Output("y", "m", "backlash output"),
        Output("engaged", None, "0 inside the play, +1/-1 engaged and dragging y", integer=True, counter=True),
    ),
    signal="y", section=("x", "v", "y"), modes=("engaged",), shifts={"x": 1.0, "y": "k"}, position="x0",
)
DEFAULT = TABLE.default  # the keyword defaults below


def check_static_backlash(M, k, h, x0, v0):
    """The static backlash's parameter checks, in order (shared with its closed loop)."""
    check("M", M, lambda: M > 0.0, "M must be > 0 (kg)")
    check("k", k, lambda: k > 0.0, "k must be > 0")
    check("h", h, lambda: h > 0.0, "h must be > 0 (m)")
    check("x0", x0, True, "x0 must be a finite number (m)")
    check("v0", v0, True, "v0 must be a finite number (m/s)")


class StaticBacklash(PiecewisePlant):
    """Exact solver of mass + backlash; the output is the backlash output y."""

    # what a run never changes: a restored FMU state's solver is held to it
    FIXED = ("M", "k", "h")

    def __init__(self, M=DEFAULT.M, k=DEFAULT.k, h=DEFAULT.h, F=0.0, omega=1.0, phi=0.0, x0=DEFAULT.x0, v0=DEFAULT.v0,
                 f=0.0, harmonics=10):
        check_static_backlash(M, k, h, x0, v0)
        super().__init__(F, omega, phi, f, harmonics)
        self.M, self.k, self.h = M, k, h
        self.engaged = 0
        self._free(0.0, x0, v0, k * x0, leaving=0)

    def output(self):
        """x, v, y at self.t."""
        x, v = self._mass.state(self.t)
        y, _ = self._output.state(self.t)
        return TABLE.output_type(x, v, y)

    def _mass_motion(self, t, x, v):
        d = self.drive
        return Motion(t, x, v, 0.0, d.f / self.M, d.F / self.M, d.omega, d.phi)

    def _free(self, t, x, v, y, leaving):
        """y held; x moves inside the play. ``leaving``: the edge just left (+-1)."""
        self.engaged = 0
        self._leaving = leaving
        self._y = y
        self._mass = mass = self._mass_motion(t, x, v)
        output = Motion(t, y, 0.0, 0.0, 0.0, 0.0, self.drive.omega, self.drive.phi)
        self._begin(t, output, searches=self._edge_searches(t, skip=leaving))
        if leaving:
            # x cannot return to the edge it left before -s*v falls back to zero.
            away = VelocitySearch(mass, -leaving)  # -s v, -s v'
            t_from = t if -leaving * v > 0.0 else self.drive.crossing(t, 0.0, rising=leaving > 0)
            self._searches.append(Search(away, mass.curvature_bound(), t_from, EventKind.APEX))

    def _edge_searches(self, t, skip=0):
        mass, y = self._mass, self._y
        K = abs(mass.a) + abs(mass.b)
        searches = []
        for s in (1, -1):
            if s == skip:
                continue
            edge = y / self.k + s * 0.5 * self.h
            searches.append(Search(EdgeSearch(mass, s, edge), K, t, ENGAGE[s]))  # s (edge - x), -s v
        return searches

    def _engage(self, t, x, v, s):
        """x drags y: y = k (x - s h/2) until the velocity reverses."""
        self.engaged = s
        self._mass = mass = self._mass_motion(t, x, v)
        shift = s * 0.5 * self.h
        k = self.k
        output = Motion(t, k * (x - shift), k * v, 0.0, k * mass.a, k * mass.b, mass.omega, mass.phi)
        speed = VelocitySearch(mass, s)  # s v, s v'
        t_from = t if s * v > 0.0 else self.drive.crossing(t, 0.0, rising=s < 0)
        self._begin(t, output, searches=[Search(speed, mass.curvature_bound(), t_from, EventKind.REVERSE)])

    def _fire(self, t, kind):
        if kind is EventKind.APEX:
            self._leaving = 0
            self._set_searches(t, self._edge_searches(t))
            return False
        x, v = self._mass.state(t)
        self._close_piece(t)
        # x and v stay as computed (no snapping): the mass's motion is continuous
        if kind is EventKind.REVERSE:
            s = self.engaged
            self._free(t, x, v, self.k * (x - s * 0.5 * self.h), leaving=s)
        else:
            self._engage(t, x, v, EDGE[kind])
        return True

    def _restart(self, t):
        x, v = self._mass.state(t)
        s = self.engaged
        d = self.drive
        def pushing(edge):  # the new force drives x into that edge just after t
            return d.above(t, 0.0) if edge > 0 else d.below(t, 0.0)

        if s and s * v <= 0.0 and not pushing(s):
            # at rest on the edge with the new force not pushing on: it lets go of y
            self._free(t, x, v, self._output.state(t)[0], leaving=s)
        elif s:
            self._engage(t, x, v, s)
        elif self._leaving and -self._leaving * v <= 0.0 and pushing(self._leaving):
            # still on the edge it was leaving, and the new force pushes back: it drags y again
            self._engage(t, x, v, self._leaving)
        else:
            self._free(t, x, v, self._y, leaving=self._leaving)


class StaticBacklashLoop(FeedbackLoop):
    """Mass + geometric backlash in feedback with -G(s); q = (x, v, y), y the backlash output.

    y held while x moves in the play; engaged (y = k (x -+ h/2)) from x
    reaching an edge until its velocity reverses.
    """

    coordinates = ("x", "v", "y")
    OUTPUT = 2
    initial_parameters = ("x0", "v0")
    plant = StaticBacklash
    KEYS = (FREE, ("engaged", 1), ("engaged", -1))
    MODE_VALUES = {FREE: 0, ("engaged", 1): 1, ("engaged", -1): -1}
    CONSTANTS = ("M", "k", "h")
    FMU_OUTPUTS = TABLE.outputs[:2] + (Output("y", "m", "backlash output (fed back to the controller)"),)
    MODE_OUTPUT = TABLE.outputs[3]  # engaged
    CONTACTS = {EventKind.ENGAGE_UP: 1, EventKind.ENGAGE_DOWN: -1}  # x reaches the play's upper / lower edge
    COUNTER = Output("engagements", None, "number of engagements so far (an edge reached and the output dragged)",
                     integer=True, counter=True)
    SECTION = (((FREE, EventKind.ENGAGE_DOWN),), ((FREE, EventKind.ENGAGE_UP),))  # the lower edge, then the upper
    PIVOT = 0  # x = y/k + h/2: at the upper edge of the play

    def pivot(self, X):
        return X[2] / self.k + 0.5 * self.h

    @staticmethod
    def fmu_values(loop, X, f):
        return {"x": X[0], "v": X[1], "y": X[2]}

    def linear(self):
        return [self.k], [self.M, 0.0, 0.0]

    def nonlinearity(self):
        return "length", self.k * self.h

    def half_play(self):
        return 0.5 * self.k

    def wall(self, X):
        play = X[0] - X[2] / self.k  # on an edge to rounding (initial() snaps it there)
        return next((s for s in (1, -1) if s * play >= 0.5 * self.h * (1.0 - 1e-12)), 0)

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

    def __init__(self, b, a, M=DEFAULT.M, k=DEFAULT.k, h=DEFAULT.h, x0=DEFAULT.x0, v0=DEFAULT.v0, z0=None, state=None,
                 section=None, modes=None, budget=None, compensation=None):
        check_static_backlash(M, k, h, x0, v0)
        self.M, self.k, self.h = M, k, h
        self.engagements = 0
        super().__init__(b, a, (x0, v0, k * x0), z0, state, section, modes, budget, compensation)

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
        s = self.wall(X)  # on an edge: engaged if moving on
        if not s:
            return FREE, X, None
        X[0] = X[2] / self.k + s * 0.5 * self.h  # on the edge, the given output kept
        return self._engage(s, X, count=False)

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


SOLVER, LOOP = StaticBacklash, StaticBacklashLoop
