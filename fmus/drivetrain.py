"""A gear with play driving a load that sticks, integrated exactly.

M2 (the motor side) carries the force u = f + F cos(omega t + phi); a
clearance h separates it from the load M1 (gap g = x2 - x1 in [0, h]), with
impacts of restitution eps as in :mod:`.backlash`; the load has viscous B,
Coulomb Fc and static Fs friction, stuck exactly at v1 = 0 as the friction
mass (:mod:`.friction`, Dv = 0). Every mode is linear with constant and
sine forcing, so every piece is closed-form:

- flight: M2 driven alone (g'' = u / M2 - x1''), the load sliding (damped,
  decelerating until v1 = 0, where it sticks: nothing pushes it) or stuck.
  The gap is the difference of two closed forms (the gap were the load to
  keep its velocity, and the load's deviation from that velocity), so
  without load friction it is the two-mass backlash's gap to the bit;
- contact at a wall: the masses move together, (M1 + M2) v' = u - Fc s - B v,
  until v = 0 or the force one mass presses on the other,
  N / (M1 + M2) = (M1 u + M2 (Fc s + B v)) / (M1 + M2), stops pressing
  (sigma N <= 0, sigma = -1 at gap 0, +1 at gap h): a zero of a function
  affine in u and v. Stuck together (v = 0) until |u| rises through Fs (they
  slide) or u stops pressing (M2 leaves, the load stays stuck): analytic
  crossings of the force.

At a wall the masses stay together when N presses them into it and the next
bounce would rise less than 1e-12 h (0.5 w^2 <= 1e-12 h |g''|: the
accumulation of impacts is over), as the two-mass backlash does. With h = 0
the coupling is rigid: the plant is the friction mass of mass M1 + M2 (the
masses take their common velocity at once if they start apart in speed).
"""

import math

from . import backlash
from .backlash import BacklashLoop
from .contract import EventKind
from .exact import Motion
from .loops import FeedbackLoop
from .piecewise import (
    CurvatureBound,
    DecayingBound,
    DifferenceSearch,
    ForceSearch,
    MotionBound,
    PiecewisePlant,
    Search,
    VelocitySearch,
    check,
)
from .table import FORCE, MASS, Output, Parameter, PlantTable

MIN_CLEARANCE = 1e-290  # m: h = 0 (rigid) or at least this: the Zeno tolerance 1e-12 h stays a normal float
FREE, LOWER, UPPER = 0, 1, 2  # the ``contact`` output: free, at gap 0, at gap h
SIDE = {LOWER: -1, UPPER: 1}  # sigma: pressing into the boundary means sigma N > 0
WALL = {EventKind.WALL_LOWER: LOWER, EventKind.WALL_UPPER: UPPER}  # the event of reaching a wall -> contact

TABLE = PlantTable(
    "drivetrain",
    model="Drivetrain", summary="a gear with play (impacts of restitution eps) driving a load with stick-slip "
                                "friction (the force on M2, the output the load's x1)",
    constants=(
        Parameter("M1", 1.0, "kg", "the load's mass (> 0)", (0.0, None), MASS),
        Parameter("M2", 1.0, "kg", "the motor side's mass, driven by the force (> 0)", (0.0, None), MASS),
        Parameter("h", 0.1, "m", "clearance (0: a rigid coupling, or >= 1e-290)", (0.0, None), (1e-9, 1e3)),
        Parameter("eps", 0.5, None, "coefficient of restitution, in [0, 1]", (0.0, 1.0)),
        Parameter("B", 0.5, "N.s/m", "the load's viscous friction coefficient (>= 0)", (0.0, None), (0.0, 1e9)),
        Parameter("Fc", 5.0, "N", "the load's Coulomb friction force (>= 0)", (0.0, None), FORCE),
        Parameter("Fs", 7.0, "N", "the load's static friction force (>= Fc)", (0.0, None), FORCE),
    ),
    initial=backlash.TABLE.initial,  # x1_0, v1_0, v2_0, gap0 (h/2 by default)
    outputs=backlash.TABLE.outputs[:6]  # x1, v1, x2, v2, gap, contact
    + (Output("slip", None, "the load: 0 stuck, +1/-1 sliding", integer=True, counter=True),)
    + backlash.TABLE.outputs[6:],  # impacts
    section=("x1", "v1", "gap", "v2"), modes=("contact", "slip"), starts={"x1": "x1_0", "v1": "v1_0", "gap": "gap0",
                                                                         "v2": "v2_0"},
    shifts={"x1": 1.0}, position="x1_0", counter="impacts",
)
DEFAULT = TABLE.default  # the keyword defaults below


def check_drivetrain(M1, M2, h, eps, B, Fc, Fs, x1_0, v1_0, v2_0, gap0=None):
    """The drivetrain's parameter checks, in order (shared with its closed loop); gap0 (None: h/2)."""
    check("M1", M1, lambda: M1 > 0.0, "M1 must be > 0 (kg)")
    check("M2", M2, lambda: M2 > 0.0, "M2 must be > 0 (kg)")
    check("h", h, lambda: h == 0.0 or h >= MIN_CLEARANCE, f"h must be 0 (rigid) or >= {MIN_CLEARANCE:g} (m)")
    check("eps", eps, lambda: 0.0 <= eps <= 1.0, "eps must be in [0, 1]")
    check("B", B, lambda: B >= 0.0, "B must be >= 0 (N.s/m)")
    check("Fc", Fc, lambda: Fc >= 0.0, "Fc must be >= 0 (N)")
    check("Fs", Fs, lambda: Fs >= Fc, f"Fs must be >= Fc = {Fc!r} (N)")
    gap0 = 0.5 * h if gap0 is None else gap0
    check("gap0", gap0, lambda: 0.0 <= gap0 <= h, f"gap0 must be in [0, h] = [0, {h!r}] (m), or -1 in an FMU (h/2)")
    for name, value in (("x1_0", x1_0), ("v1_0", v1_0), ("v2_0", v2_0)):
        check(name, value, True, f"{name} must be a finite number")
    return gap0


def _sign(v):
    return 1 if v > 0.0 else (-1 if v < 0.0 else 0)


class Drivetrain(PiecewisePlant):
    """Exact solver of the drivetrain; the output is the load's position x1."""

    # what a run never changes: a restored FMU state's solver is held to it
    FIXED = ("M1", "M2", "h", "eps", "B", "Fc", "Fs", "total", "r2", "tol_h", "rigid")

    def __init__(self, M1=DEFAULT.M1, M2=DEFAULT.M2, h=DEFAULT.h, eps=DEFAULT.eps, B=DEFAULT.B, Fc=DEFAULT.Fc,
                 Fs=DEFAULT.Fs, F=0.0, omega=1.0, phi=0.0, x1_0=DEFAULT.x1_0, v1_0=DEFAULT.v1_0, v2_0=DEFAULT.v2_0,
                 gap0=DEFAULT.gap0, f=0.0, harmonics=10):
        gap0 = check_drivetrain(M1, M2, h, eps, B, Fc, Fs, x1_0, v1_0, v2_0, gap0)
        super().__init__(F, omega, phi, f, harmonics)
        self.M1, self.M2, self.h, self.eps, self.B, self.Fc, self.Fs = M1, M2, h, eps, B, Fc, Fs
        self.total = M1 + M2
        self.r2 = M2 / self.total  # an impulse changing w by dw changes v1 by -r2 dw (momentum kept)
        self.tol_h = 1e-12 * h
        self.rigid = h == 0.0
        self.impacts = 0
        self.contact, self.slip, self._departing = FREE, 0, 0
        self._rel = self._dev = None
        self._start(0.0, x1_0, v1_0, gap0, v2_0 - v1_0)

    # -- state -------------------------------------------------------------
    def relative(self, t):
        """(g, w) at t."""
        if self.contact == FREE:
            (xr, vr), (xd, vd) = self._rel.state(t), self._dev.state(t)
            return xr - xd, vr - vd
        return (0.0 if self.contact == LOWER else self.h), 0.0

    def output(self):
        """x1, v1, x2, v2, gap at self.t."""
        x1, v1 = self._output.state(self.t)
        g, w = self.relative(self.t)
        return TABLE.output_type(x1, v1, x1 + g, v1 + w, g)

    def _wall(self, side):
        return 0.0 if side == LOWER else self.h

    # -- pieces -------------------------------------------------------------
    def _start(self, t, x1, v1, g, w):
        if self.rigid or g <= 0.0:
            self._at_boundary(t, LOWER, x1, v1, w)
        elif g >= self.h:
            self._at_boundary(t, UPPER, x1, v1, w)
        else:
            self._flight(t, x1, v1, g, w, departing=0)

    def _at_boundary(self, t, side, x1, v1, w):
        """Impact (if closing), then the masses together or a flight away from the wall."""
        sigma = SIDE[side]
        if self.rigid:  # plastic at once: the common velocity
            v1, w = v1 + self.r2 * w, 0.0
        elif sigma * w > 0.0:  # closing: Newton's impact law, momentum kept
            new = -self.eps * w
            v1 += self.r2 * (w - new)
            w = new
            self.impacts += 1
        v = v1 + self.r2 * w  # the common velocity, were they to move together
        if v == 0.0 and w == 0.0:
            self._rest(t, side, x1)
            return
        if v != 0.0:
            s = _sign(v)
            N = self._pressing(t, s, v)
            if self.rigid or (sigma * N > 0.0 and (w == 0.0 or 0.5 * w * w * self.M1 * self.M2 <= self.tol_h * abs(N))):
                self._together(t, side, x1, v, s, departing=False)
                return
        self._flight(t, x1, v1, self._wall(side), w, departing=sigma)

    def _pressing(self, t, s, v):
        """N = M1 u + M2 (Fc s + B v): (M1 + M2) times the force M2 presses on the load, sliding together at v."""
        return self.M1 * self.drive.u(t) + self.M2 * (self.Fc * s + self.B * v)

    def _rest(self, t, side, x1):
        """Together at the wall, v = 0: M2 leaves if u pulls it off; they slide if |u| > Fs; else stuck."""
        d, Fs = self.drive, self.Fs
        if self.rigid:
            s = 1 if d.above(t, Fs) else (-1 if d.below(t, -Fs) else 0)
        else:
            sigma = SIDE[side]
            if d.below(t, 0.0) if sigma > 0 else d.above(t, 0.0):
                self._flight(t, x1, 0.0, self._wall(side), 0.0, departing=sigma)
                return
            s = sigma if (d.above(t, Fs) if sigma > 0 else d.below(t, -Fs)) else 0
        if s:
            self._together(t, side, x1, 0.0, s, departing=True)
        else:
            self._stuck(t, side, x1)

    def _stuck(self, t, side, x1):
        """Stuck together until |u| rises through Fs or (h > 0) u stops pressing."""
        d = self.drive
        self.contact, self.slip, self._departing = side, 0, 0
        if self.rigid:
            events = [(d.crossing(t, self.Fs, rising=True), EventKind.BREAK_UP),
                      (d.crossing(t, -self.Fs, rising=False), EventKind.BREAK_DOWN)]
        else:
            sigma = SIDE[side]
            events = [(d.crossing(t, sigma * self.Fs, rising=sigma > 0),
                       EventKind.BREAK_UP if sigma > 0 else EventKind.BREAK_DOWN),
                      (d.crossing(t, 0.0, rising=sigma < 0), EventKind.RELEASE)]
        t_event, kind = min(events, key=lambda event: event[0])
        self._begin(t, Motion(t, x1, 0.0, 0.0, 0.0, 0.0, d.omega, d.phi), t_event, kind)

    def _together(self, t, side, x1, v, s, departing):
        """Sliding together in direction s until v = 0 or (h > 0) they part; ``departing`` from v = 0."""
        d, M = self.drive, self.total
        self.contact, self.slip, self._departing = side, s, 0
        motion = Motion(t, x1, v, self.B / M, (d.f - s * self.Fc) / M, d.F / M, d.omega, d.phi)
        # leaving v = 0, s v > 0 is proven while s u > Fc (as the friction mass's break-away)
        t_from = d.crossing(t, s * self.Fc, rising=s < 0) if departing else t
        K = CurvatureBound(motion) if motion.lam else motion.curvature_bound()
        searches = [Search(VelocitySearch(motion, s), K, t_from, EventKind.BAND)]
        if not self.rigid:
            sigma = SIDE[side]
            M1, M2 = self.M1, self.M2
            pressing = ForceSearch(motion, d, sigma * M1, sigma * M2 * self.B, sigma * M2 * self.Fc * s)
            # |N''| <= M1 F omega^2 + M2 B |v''|, the latter decaying
            K_force = MotionBound(M1 * d.F * d.omega * d.omega, M2 * self.B, motion) if motion.lam else \
                M1 * d.F * d.omega * d.omega
            searches.append(Search(pressing, K_force, t, EventKind.RELEASE))
        self._begin(t, motion, searches=searches)

    def _flight(self, t, x1, v1, g, w, departing):
        """M2 free, the load sliding or stuck; ``departing`` = sigma of the wall just left (0: none)."""
        d = self.drive
        s = _sign(v1)
        self.contact, self.slip, self._departing = FREE, s, departing
        lam = self.B / self.M1 if s else 0.0
        a = -s * self.Fc / self.M1
        # the gap were the load to keep its velocity, and the load's deviation from that velocity
        self._rel = Motion(t, g, w, 0.0, d.f / self.M2, d.F / self.M2, d.omega, d.phi)
        self._dev = Motion(t, 0.0, 0.0, lam, a - lam * v1, 0.0, d.omega, d.phi)
        load = Motion(t, x1, v1, lam, a, 0.0, d.omega, d.phi)
        self._begin(t, load, searches=self._flight_searches(t, load, skip=departing))
        if departing:
            # the gap cannot return to the wall it left before the separation speed -sigma w falls to zero
            apex = DifferenceSearch(self._rel, self._dev, -departing, velocity=True)
            rel, dev = self._rel, self._dev  # |w''| <= |v2''| + |v1''|, the latter decaying
            K = MotionBound(rel.curvature_bound(), 1.0, dev) if dev.lam else rel.curvature_bound()
            self._searches.append(Search(apex, K, self._apex_from(t, w, v1, departing), EventKind.APEX))

    def _flight_searches(self, t, load, skip=0):
        """The walls (but the one just left) and the load's stop (``load``: its motion)."""
        rel, dev = self._rel, self._dev
        # |g''| <= |u| / M2 + |x1''|, and x1'' = (a - lam v1) exp(-lam tau) (the load's force has no sine)
        constant, transient = abs(rel.a) + abs(rel.b), abs(load.a - load.lam * load.v0)
        K = DecayingBound(constant, transient, load.lam, load.t0) if load.lam else constant + transient
        searches = []
        if skip != SIDE[LOWER]:
            searches.append(Search(DifferenceSearch(rel, dev, 1.0), K, t, EventKind.WALL_LOWER))  # g
        if skip != SIDE[UPPER]:
            searches.append(Search(DifferenceSearch(rel, dev, -1.0, self.h), K, t, EventKind.WALL_UPPER))  # h - g
        if self.slip:
            K_stop = CurvatureBound(load) if load.lam else load.curvature_bound()
            searches.append(Search(VelocitySearch(load, self.slip), K_stop, t, EventKind.BAND))
        return searches

    def _apex_from(self, t, w, v1, sigma):
        """From when the separation speed -sigma w is proven positive (it is 0 when the masses part)."""
        d = self.drive
        if -sigma * w > 0.0:
            return t
        if not self.slip:  # w' = u / M2: positive until u presses again
            return d.crossing(t, 0.0, rising=sigma > 0)
        # w' = N / (M1 M2), N = M1 u + M2 (Fc s + B v1); x1'' = accel exp(-lam tau), so |N''| <= K below and
        # -sigma N >= n0 + n1 tau - K tau^2 / 2, positive (and so -sigma w, its integral) up to the root tau*
        load = self._output
        accel = load.a - load.lam * v1
        n0 = max(-sigma * self._pressing(t, self.slip, v1), 0.0)  # 0 (to rounding) where they part at a release
        n1 = -sigma * (self.M1 * d.du(t) + self.M2 * self.B * accel)
        K = self.M1 * d.F * d.omega * d.omega + self.M2 * self.B * load.lam * abs(accel)
        if not (n0 > 0.0 or n1 > 0.0):
            return t  # tangent: an immediate apex, then the wall decides
        if not K:  # N is linear in t
            return float("inf") if n1 >= 0.0 else t + 0.5 * n0 / -n1
        return t + 0.5 * (n1 + math.sqrt(n1 * n1 + 2.0 * K * n0)) / K  # the apex is searched from tau* / 2

    # -- events ---------------------------------------------------------------
    def _fire(self, t, kind):
        if kind is EventKind.APEX:
            self._departing = 0
            self._set_searches(t, self._flight_searches(t, self._output))
            return False
        x1, v1 = self._output.state(t)
        g, w = self.relative(t)
        self._close_piece(t)
        side = self.contact
        if side == FREE:
            if kind is EventKind.BAND:  # the load stops, and sticks: nothing pushes it
                self._flight(t, x1, 0.0, g, w, self._departing)
            else:
                self._at_boundary(t, WALL[kind], x1, v1, w)
        elif kind is EventKind.BAND:
            self._rest(t, side, x1)
        elif kind is EventKind.RELEASE:
            self._flight(t, x1, v1 if self.slip else 0.0, self._wall(side), 0.0, departing=SIDE[side])
        else:  # BREAK_UP, BREAK_DOWN
            self._together(t, side, x1, 0.0, 1 if kind is EventKind.BREAK_UP else -1, departing=True)
        return True

    def _restart(self, t):
        x1, v1 = self._output.state(t)
        g, w = self.relative(t)
        side, departing = self.contact, self._departing
        if side == FREE:
            if departing and -departing * w <= 0.0:  # still at the wall it was leaving: the new force decides
                self._at_boundary(t, LOWER if departing < 0 else UPPER, x1, v1, w)
            else:
                self._flight(t, x1, v1, g, w, departing)
        elif self.slip:
            self._at_boundary(t, side, x1, v1, 0.0)  # together while the new force presses
        else:
            self._rest(t, side, x1)


def _key(side, s):
    return (("flight", "lower", "upper")[side], s)


class DrivetrainLoop(FeedbackLoop):
    """The drivetrain in feedback with -G(s); q = (x1, v1, g, w), y = x1 (the load), f on M2.

    Flight (the load sliding until v1 = 0, or stuck) until the gap reaches 0
    or h: an impact (w -> -eps w, momentum kept). Together at a wall while
    sigma (M1 f + M2 (Fc s + B v)) > 0 (pressing) and the next bounce would
    rise less than 1e-12 h; sliding until v = 0, stuck while |f| <= Fs.
    """

    # the two-mass geometry is the backlash loop's: its coordinates, FMU values, check of the gap and stillness
    coordinates, initial_parameters = BacklashLoop.coordinates, BacklashLoop.initial_parameters
    fmu_values = staticmethod(BacklashLoop.fmu_values)
    coordinates_of = staticmethod(BacklashLoop.coordinates_of)
    check_coordinates, still = BacklashLoop.check_coordinates, BacklashLoop.still
    CONTACTS, wall, half_play = BacklashLoop.CONTACTS, BacklashLoop.wall, BacklashLoop.half_play  # the inverse's
    plant = Drivetrain
    KEYS = tuple(_key(side, s) for side in (FREE, LOWER, UPPER) for s in (-1, 0, 1))
    MODE_VALUES = {_key(side, s): 10 * side + s for side in (FREE, LOWER, UPPER) for s in (-1, 0, 1)}
    CONSTANTS = ("M1", "M2", "h", "eps", "B", "Fc", "Fs", "r2", "tol_h")
    FMU_OUTPUTS = (Output("x1", "m", "position of the load M1 (the output y fed back to the controller)"),) \
        + TABLE.outputs[1:5]
    MODE_OUTPUT = Output("mode", None, "10 contact + slip: contact 0 free, 1 at gap 0, 2 at gap h; slip the "
                         "load's 0 stuck, +1/-1 sliding", integer=True)
    COUNTER = TABLE.outputs[7]  # impacts
    # the load at a minimum, then at a maximum: its velocity reaches 0, in flight or together at a wall
    SECTION = (tuple((_key(side, -1), EventKind.BAND) for side in (FREE, LOWER, UPPER)),
               tuple((_key(side, 1), EventKind.BAND) for side in (FREE, LOWER, UPPER)))
    PIVOT = 1  # v1 = 0
    # a load that never stops (a hunt by impacts alone): M2 at the lower wall, then at the upper (gap = h)
    ALTERNATE = ((tuple((_key(FREE, s), EventKind.WALL_LOWER) for s in (-1, 0, 1)),
                  tuple((_key(FREE, s), EventKind.WALL_UPPER) for s in (-1, 0, 1))), 2)

    def pivot(self, X):
        return 0.0

    def alternate_pivot(self, X):
        return self.h

    def linear(self):
        return [1.0], [self.M1 + self.M2, self.B, 0.0]

    def nonlinearity(self):
        return "force", max(self.Fs, self.Fc)

    def __init__(self, b, a, M1=DEFAULT.M1, M2=DEFAULT.M2, h=DEFAULT.h, eps=DEFAULT.eps, B=DEFAULT.B, Fc=DEFAULT.Fc,
                 Fs=DEFAULT.Fs, x1_0=DEFAULT.x1_0, v1_0=DEFAULT.v1_0, v2_0=DEFAULT.v2_0, gap0=DEFAULT.gap0, z0=None,
                 state=None, section=None, modes=None, budget=None, compensation=None):
        gap0 = check_drivetrain(M1, M2, h, eps, B, Fc, Fs, x1_0, v1_0, v2_0, gap0)
        self.M1, self.M2, self.h, self.eps, self.B, self.Fc, self.Fs = M1, M2, h, eps, B, Fc, Fs
        self.r2 = M2 / (M1 + M2)
        self.tol_h = 1e-12 * h
        self.impacts = 0
        super().__init__(b, a, (x1_0, v1_0, gap0, v2_0 - v1_0), z0, state, section, modes, budget, compensation)

    def plant_mode(self, key):
        M1, M2, B, Fc = self.M1, self.M2, self.B, self.Fc
        zero = [0.0] * 4
        s = key[1]
        if key[0] == "flight":  # x1' = v1, v1' = -(B v1 + Fc s) / M1 (sliding), g' = w, w' = f / M2 - v1'
            lam = B / M1 if s else 0.0
            a = -s * Fc / M1
            events = [(EventKind.WALL_LOWER, (0.0, 0.0, 1.0, 0.0), 0.0, 0.0),  # g > 0
                      (EventKind.WALL_UPPER, (0.0, 0.0, -1.0, 0.0), 0.0, self.h)]  # h - g > 0
            if s:
                events.append((EventKind.BAND, (0.0, float(s), 0.0, 0.0), 0.0, 0.0))  # s v1 > 0
            return ([[0.0, 1.0, 0.0, 0.0], [0.0, -lam, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, lam, 0.0, 0.0]],
                    [0.0, a, 0.0, -a], [0.0, 0.0, 0.0, 1.0 / M2], events)
        sigma = -1.0 if key[0] == "lower" else 1.0
        M = M1 + M2
        if s:  # together: M v' = f - Fc s - B v; pressing: sigma (M1 f + M2 (Fc s + B v)) > 0
            events = [(EventKind.BAND, (0.0, float(s), 0.0, 0.0), 0.0, 0.0)]  # s v > 0
            if self.h:
                events.append((EventKind.RELEASE, (0.0, sigma * M2 * B, 0.0, 0.0), sigma * M1, sigma * M2 * Fc * s))
            return ([[0.0, 1.0, 0.0, 0.0], [0.0, -B / M, 0.0, 0.0], zero, zero], [0.0, -s * Fc / M, 0.0, 0.0],
                    [0.0, 1.0 / M, 0.0, 0.0], events)
        if self.h:  # stuck together while sigma f > 0 (pressing) and sigma f < Fs
            events = [(EventKind.RELEASE, (0.0,) * 4, sigma, 0.0),
                      (EventKind.BREAK_UP if sigma > 0 else EventKind.BREAK_DOWN, (0.0,) * 4, -sigma, self.Fs)]
        else:  # rigid: stuck while |f| <= Fs
            events = [(EventKind.BREAK_UP, (0.0,) * 4, -1.0, self.Fs), (EventKind.BREAK_DOWN, (0.0,) * 4, 1.0, self.Fs)]
        return [zero, zero, zero, zero], zero, zero, events

    def initial(self, X):
        if self.h == 0.0 or not 0.0 < X[2] < self.h:
            return self._at_wall(LOWER if self.h == 0.0 or X[2] <= 0.0 else UPPER, X)
        return _key(FREE, _sign(X[1])), X, None

    def _at_wall(self, side, X):
        """At a wall: the impact (if closing), then together or a flight away from it."""
        sigma = SIDE[side]
        X[2] = 0.0 if side == LOWER else self.h
        w = X[3]
        if self.h == 0.0:  # rigid: plastic at once, the common velocity
            X[1] += self.r2 * w
            X[3] = w = 0.0
        elif sigma * w > 0.0:  # closing: Newton's impact law, momentum kept
            new = -self.eps * w
            X[1] += self.r2 * (w - new)
            X[3] = w = new
            self.impacts += 1
        v = X[1] + self.r2 * w  # the common velocity, were they to move together
        departing = 0 if side == LOWER else 1  # the index of the wall's function in flight
        if v == 0.0 and w == 0.0:
            return self._rest(side, X)
        if v != 0.0:
            s = _sign(v)
            key = _key(side, s)
            Y = list(X)
            Y[1], Y[3] = v, 0.0
            if self.h == 0.0:
                return key, Y, None
            press = self.after(key, 1, Y)  # the RELEASE function just after, at the common velocity
            N = self.M1 * self.force(X) + self.M2 * (self.Fc * s + self.B * v)
            if press > 0 and (w == 0.0 or 0.5 * w * w * self.M1 * self.M2 <= self.tol_h * abs(N)):
                X[1], X[3] = v, 0.0
                return key, X, None
        return _key(FREE, _sign(X[1])), X, departing

    def _rest(self, side, X):
        """Together at the wall at v = 0: M2 leaves if f pulls it off, they slide if |f| > Fs, else stuck."""
        X[1] = X[3] = 0.0
        stuck = _key(side, 0)
        if self.h == 0.0:
            for index, s in ((0, 1), (1, -1)):
                if self.after(stuck, index, X) < 0:
                    return _key(side, s), X, 0
            return stuck, X, None
        if self.after(stuck, 0, X) < 0:  # pulling
            return _key(FREE, 0), X, 0 if side == LOWER else 1
        if self.after(stuck, 1, X) < 0:  # breaking away, in the direction that presses
            return _key(side, SIDE[side]), X, 0
        return stuck, X, None

    def _fire(self, t, kind, X):
        name, s = self.key
        if kind is EventKind.BAND:
            X[1] = 0.0
            if name == "flight":  # the load stops, and sticks: nothing pushes it
                return _key(FREE, 0), X, None
            return self._rest(LOWER if name == "lower" else UPPER, X)
        if kind is EventKind.WALL_LOWER or kind is EventKind.WALL_UPPER:
            return self._at_wall(WALL[kind], X)
        if kind is EventKind.RELEASE:
            X[3] = 0.0
            return _key(FREE, s), X, 0 if name == "lower" else 1
        return (name, 1 if kind is EventKind.BREAK_UP else -1), X, 0  # BREAK_UP, BREAK_DOWN


SOLVER, LOOP = Drivetrain, DrivetrainLoop
