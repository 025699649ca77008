"""Mass with Stribeck friction: the first plant of the integrated family.

    M x'' + Ff = u(t),   u = f + F cos(omega t + phi)

Sliding (v != 0): Ff = (Fc + (Fs - Fc) exp(-(|v| / vs)^delta)) sgn(v) + B v:
the friction falls from the breakaway force Fs at rest to the Coulomb force
Fc over the Stribeck velocity vs. Stuck (v = 0) while |u| <= Fs, breaking
away in the direction of u above it (Karnopp's stick, as the friction mass's
with Dv = 0; at v = 0 the law's friction is Fs, so the two meet).

The stick and the breakaway are exact (the friction mass's logic: analytic
crossings of the force); a slide has no closed form and is integrated by
:mod:`.integrated` to tolerance ``rtol``, its stop (v back to 0) found on
its dense output. With Fs = Fc it is the friction mass; as vs -> 0 it tends
to it.
"""

import math

from .contract import EventKind
from .friction import SLIDE, FrictionLoop, FrictionMass, check_forces
from .integrated import Trajectory
from .piecewise import Search, check
from .table import FORCE, MASS, START, Output, Parameter, PlantTable

TABLE = PlantTable(
    "stribeck",
    model="StribeckMass", summary="mass with Stribeck friction (breakaway Fs falling to Coulomb Fc over the "
                                  "Stribeck velocity vs; exact stick, integrated slides)",
    constants=(
        Parameter("M", 1.0, "kg", "mass (> 0)", (0.0, None), MASS),
        Parameter("B", 0.5, "N.s/m", "viscous friction coefficient (>= 0)", (0.0, None), (0.0, 1e9)),
        Parameter("Fc", 5.0, "N", "Coulomb friction force (>= 0)", (0.0, None), FORCE),
        Parameter("Fs", 7.0, "N", "static (breakaway) friction force (>= Fc)", (0.0, None), FORCE),
        Parameter("vs", 0.1, "m/s", "Stribeck velocity (> 0)", (0.0, None), (1e-4, 1e3)),
        Parameter("delta", 2.0, None, "Stribeck exponent (in [0.5, 10])", (0.5, 10.0), (1.0, 10.0)),
        Parameter("rtol", 1e-9, None, "relative tolerance of the integrated slides (in [1e-12, 1e-3])",
                  (1e-12, 1e-3), (1e-12, 1e-3)),
    ),
    initial=START,
    outputs=(
        Output("x", "m", "position"),
        Output("v", "m/s", "velocity"),
        Output("Ff", "N", "friction force", feedthrough=True),  # stuck: Ff = u
        Output("mode", None, "0 stick, +1/-1 sliding", integer=True, feedthrough=True),
    ),
    section=("x", "v"), modes=("mode",), starts={"x": "x0", "v": "v0"}, shifts={"x": 1.0}, position="x0",
    integrated=True,
)
DEFAULT = TABLE.default


def check_stribeck(M, B, Fc, Fs, vs, delta, rtol, x0, v0):
    """The Stribeck mass's parameter checks, in order (shared with its closed loop)."""
    check_forces(M, B, Fc, Fs)
    check("vs", vs, lambda: vs > 0.0, "vs must be > 0 (m/s)")
    check("delta", delta, lambda: 0.5 <= delta <= 10.0, "delta must be in [0.5, 10]")
    check("rtol", rtol, lambda: 1e-12 <= rtol <= 1e-3, "rtol must be in [1e-12, 1e-3]")
    check("x0", x0, True, "x0 must be a finite number (m)")
    check("v0", v0, True, "v0 must be a finite number (m/s)")


FAR = 1e6  # |v| / vs beyond which exp(-(|v|/vs)^delta) is 0.0 for every delta >= 0.5 (exp(-1000) underflows)


def stribeck_factor(v, vs, delta):
    """exp(-(|v|/vs)^delta), the share of the drop Fs - Fc left at speed |v| (0.0 far beyond vs, where the
    power would overflow)."""
    w = abs(v) / vs
    return 0.0 if w > FAR else math.exp(-_power(w, delta))


def _power(w, delta):
    """w ** delta, the default delta = 2 as w * w (a fifth of the integrated plant's time went to pow)."""
    return w * w if delta == 2.0 else w ** delta


class StribeckSlide:
    """The acceleration of a slide in direction s: (u - s (Fc + (Fs - Fc) exp(-(|v|/vs)^delta)) - B v) / M.

    Plain data (a plant's state is copied and serialised exactly); ``drive`` is the plant's :class:`Drive`.
    """

    __slots__ = ("M", "B", "Fc", "drop", "vs", "delta", "s", "drive")

    def __init__(self, M, B, Fc, Fs, vs, delta, s, drive):
        self.M, self.B, self.Fc, self.drop, self.vs, self.delta, self.s, self.drive = (
            M, B, Fc, Fs - Fc, vs, delta, s, drive)

    @property
    def scale(self):
        """The velocity over which the friction varies: vs (none without a drop)."""
        return self.vs if self.drop else math.inf

    def friction(self, v):
        return self.s * (self.Fc + self.drop * stribeck_factor(v, self.vs, self.delta)) + self.B * v

    def __call__(self, t, v):
        return (self.drive.u(t) - self.friction(v)) / self.M

    def size(self, t, v):
        """The magnitude of the acceleration's terms (the integrator's rounding floor)."""
        d = self.drive
        return (abs(d.f) + d.F + self.Fc + self.drop + self.B * abs(v)) / self.M


class StribeckMass(FrictionMass):
    """Solver of the Stribeck mass (the friction mass's stick and breakaway, integrated slides); output x."""

    FIXED = ("M", "B", "Fc", "Fs", "vs", "delta", "rtol", "Dv", "edge_force")
    STATE_CLASSES = (StribeckSlide,)  # what its FMU state may hold beyond the common classes

    def __init__(self, M=DEFAULT.M, B=DEFAULT.B, Fc=DEFAULT.Fc, Fs=DEFAULT.Fs, vs=DEFAULT.vs, delta=DEFAULT.delta,
                 rtol=DEFAULT.rtol, F=0.0, omega=1.0, phi=0.0, x0=DEFAULT.x0, v0=DEFAULT.v0, f=0.0, harmonics=10):
        check_stribeck(M, B, Fc, Fs, vs, delta, rtol, x0, v0)
        self.vs, self.delta, self.rtol = vs, delta, rtol
        super().__init__(M, B, Fc, Fs, 0.0, F, omega, phi, x0, v0, f, harmonics)

    def output(self):
        """x, v, friction force Ff and mode (0 stick, +-1 sliding) at self.t."""
        return TABLE.output_type(*super().output())

    def _slide(self, t, x, v, s, departing):
        """Sliding in direction s until the velocity falls back to 0: integrated (the stop is on its way)."""
        self.mode, self.direction = SLIDE, s
        d = self.drive
        law = StribeckSlide(self.M, self.B, self.Fc, self.Fs, self.vs, self.delta, s, d)
        trajectory = Trajectory(law, t, x, v, s, d.omega, self.harmonics, self.rtol, self._velocity_error)
        self._begin(t, trajectory, searches=[Search(trajectory, None, t, EventKind.BAND)])


class StribeckDrop:
    """The Stribeck part of a slide's acceleration in direction s, -s (Fs - Fc) exp(-(|v|/vs)^delta) / M, and
    its slope in v: the nonlinear term of the closed loop's slide (plain data)."""

    __slots__ = ("factor", "vs", "delta", "s")

    def __init__(self, M, Fc, Fs, vs, delta, s):
        self.factor, self.vs, self.delta, self.s = -s * (Fs - Fc) / M, vs, delta, s

    @property
    def scale(self):
        """The velocity over which the term varies: vs (none without a drop)."""
        return self.vs if self.factor else math.inf

    def __call__(self, v):
        return self.factor * stribeck_factor(v, self.vs, self.delta)

    def slope(self, v):
        """d/dv of the term (at v = 0 the one-sided slope in the slide's direction; 0 far beyond vs)."""
        w = abs(v) / self.vs
        if w > FAR:
            return 0.0
        if w == 0.0:  # delta > 1: flat; delta = 1: -scale/vs towards the slide; below: unbounded, held at 0 here
            return -self.s * self.factor / self.vs if self.delta == 1.0 else 0.0
        sign = 1.0 if v > 0.0 else -1.0
        return (-self.factor * self.delta * w ** (self.delta - 1.0) / self.vs * sign
                * math.exp(-_power(w, self.delta)))


class StribeckLoop(FrictionLoop):
    """The Stribeck mass in feedback with -G(s); q = (x, v), y = x.

    The friction mass's loop (stick until |f| exceeds Fs, slides until v
    returns to 0) with each slide's Stribeck drop as the nonlinear term of an
    integrated mode (:class:`~.integrated.IntegratedMode`, tolerance rtol).
    """

    plant = StribeckMass
    STATE_CLASSES = (StribeckDrop,)
    CONSTANTS = ("M", "B", "Fc", "Fs", "vs", "delta", "rtol")
    FMU_RANGES = {}
    FMU_DESCRIPTIONS = {}

    def __init__(self, b, a, M=DEFAULT.M, B=DEFAULT.B, Fc=DEFAULT.Fc, Fs=DEFAULT.Fs, vs=DEFAULT.vs,
                 delta=DEFAULT.delta, rtol=DEFAULT.rtol, x0=DEFAULT.x0, v0=DEFAULT.v0, z0=None, state=None,
                 section=None, modes=None, budget=None, compensation=None):
        check_stribeck(M, B, Fc, Fs, vs, delta, rtol, x0, v0)
        self.vs, self.delta, self.rtol = vs, delta, rtol
        super().__init__(b, a, M, B, Fc, Fs, 0.0, x0, v0, z0, state, section, modes, budget, compensation)

    def plant_mode(self, key):
        mode = super().plant_mode(key)
        if key[0] != "slide":
            return mode
        return mode + ((1, 1, StribeckDrop(self.M, self.Fc, self.Fs, self.vs, self.delta, key[1])),)

    def linear(self):
        return [1.0], [self.M, self.B, 0.0]


SOLVER, LOOP = StribeckMass, StribeckLoop
