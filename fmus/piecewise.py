"""Event-driven exact integration: the machinery shared by the three plants.

A plant is a sequence of *pieces*. A piece holds the closed-form motion of
the plant's output (a :class:`~exact.Motion`) and knows its next event: an
analytic instant (the force crossing a level) or the first zero of a
function searched with :func:`~exact.first_root`. Searches run lazily in
chunks anchored at the start of the piece, never at the communication
points, so the events and the result do not depend on how an importer steps.

The running Fourier integrals of the output, ``I_k(t) = int_0^t y(s)
exp(-i k omega s) ds`` for k = 0..harmonics (k = 0: the plain integral), are
accumulated piece by piece in closed form; a describing function needs only
their values at two instants.

:class:`PiecewisePlant` implements the :class:`~.contract.Solver` protocol
(it does not define it); its events are :class:`~.contract.EventKind` members.

Every loop is bounded, and so is the work of one step: a step spans at most
MAX_PERIODS_PER_STEP drive periods (8 search chunks each) and fires at most
MAX_EVENTS_PER_STEP events, and EVENTS_PER_PERIOD_LIMIT per period it spans
(motion that chatters below resolution); each chunk's search takes at most
MAX_EVALUATIONS. Hitting a bound raises PlantError before the work, or as soon
as the events exceed it; a longer span is taken in several steps.
"""

import math

from .exact import EPS, MAX_EVENTS_PER_STEP, PHASE_LIMIT, TWO_PI, Drive, PlantError, first_root, too_many_events

EVENTS_PER_PERIOD_LIMIT = 100_000
# consecutive events each within STALL_ULPS ulp of the one before: time no longer resolves the motion (a state
# so large that its rounding fires events). A Zeno cascade ends at its 1e-12 tolerance long before.
STALL_EVENTS, STALL_ULPS = 1000, 64
MAX_PERIODS_PER_STEP = 1e6  # 10x the longest trace a scene may ask for: a step costs seconds, never hours


def check(name, value, ok, allowed):
    """Raise PlantError naming the value and the allowed range unless it is a finite number and ``ok``.

    ``ok`` is True or a function of no argument, called only once the value is
    known to be a finite number (so a condition never fails on None or text).
    ``allowed`` is the text, or a function of no argument that makes it: a
    check on a hot path (a step) formats its message only when it fails.
    """
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and _finite(value)
            and (ok() if callable(ok) else ok)):
        raise PlantError(f"{name} = {value!r} is out of range: {allowed() if callable(allowed) else allowed}")


def _finite(value):
    """math.isfinite, False for an int beyond the floats (instead of OverflowError)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def check_step_end(t_end, now):
    """PlantError unless ``t_end`` is a finite time >= ``now``, the solver's current time (a step's end)."""
    check("t_end", t_end, lambda: t_end >= now, lambda: f"the end of a step must be >= the current time {now!r}")


class Search:
    """A pending zero search: ``fun(t) -> (g, g')`` with |g''| <= K, from t_from; ``kind``: its EventKind.

    ``K`` is a number, or a function of t bounding |g''| on [t, inf) (a
    decaying transient's bound tightens as the search advances), or None:
    ``fun`` is an integrated motion (:class:`~.integrated.Trajectory`) that
    finds its own event, ``fun.first_zero(lo, hi)``.
    """

    __slots__ = ("fun", "K", "t_from", "kind")

    def __init__(self, fun, K, t_from, kind):
        self.fun, self.K, self.t_from, self.kind = fun, K, t_from, kind


class VelocitySearch:
    """Search function ``t -> (offset + sign v, sign v')`` of a motion's velocity (``offset`` None: no offset).

    A small class rather than a closure, so that a solver's state is plain data
    (copied and serialised exactly, see :mod:`.state`).
    """

    __slots__ = ("motion", "sign", "offset")

    def __init__(self, motion, sign, offset=None):
        self.motion, self.sign, self.offset = motion, sign, offset

    def __call__(self, t):
        motion, sign = self.motion, self.sign
        _, v = motion.state(t)
        g = sign * v if self.offset is None else self.offset + sign * v
        return g, sign * motion.acceleration(t, v)


class PositionSearch:
    """Search function ``t -> (x, v)`` (``wall`` None) or ``(wall - x, -v)`` of a motion's position."""

    __slots__ = ("motion", "wall")

    def __init__(self, motion, wall=None):
        self.motion, self.wall = motion, wall

    def __call__(self, t):
        x, v = self.motion.state(t)
        return (x, v) if self.wall is None else (self.wall - x, -v)


class EdgeSearch:
    """Search function ``t -> (s (edge - x), -s v)``: the distance of a motion's position to an edge."""

    __slots__ = ("motion", "s", "edge")

    def __init__(self, motion, s, edge):
        self.motion, self.s, self.edge = motion, s, edge

    def __call__(self, t):
        x, v = self.motion.state(t)
        return self.s * (self.edge - x), -self.s * v


class DifferenceSearch:
    """Search function ``t -> level + sign (x_a - x_b)`` with its derivative: the distance between two motions.

    With ``velocity``, of their velocities instead: ``level + sign (v_a - v_b)``, ``sign (v_a' - v_b')``.
    A gap between two masses whose laws differ (one damped, one driven) is no single :class:`~.exact.Motion`.
    """

    __slots__ = ("first", "second", "sign", "level", "velocity")

    def __init__(self, first, second, sign, level=0.0, velocity=False):
        self.first, self.second, self.sign, self.level, self.velocity = first, second, sign, level, velocity

    def __call__(self, t):
        (xa, va), (xb, vb) = self.first.state(t), self.second.state(t)
        if self.velocity:
            dg = self.first.acceleration(t, va) - self.second.acceleration(t, vb)
            return self.level + self.sign * (va - vb), self.sign * dg
        return self.level + self.sign * (xa - xb), self.sign * (va - vb)


class ForceSearch:
    """Search function ``t -> (c0 + cu u + cv v, cu u' + cv v')``: a force affine in the drive u and a motion's v.

    The contact force between two masses moving together is one: it changes sign where they part.
    """

    __slots__ = ("motion", "drive", "cu", "cv", "c0")

    def __init__(self, motion, drive, cu, cv, c0):
        self.motion, self.drive, self.cu, self.cv, self.c0 = motion, drive, cu, cv, c0

    def __call__(self, t):
        _, v = self.motion.state(t)
        d = self.drive
        return (self.c0 + self.cu * d.u(t) + self.cv * v,
                self.cu * d.du(t) + self.cv * self.motion.acceleration(t, v))


class DecayingBound:
    """``t -> constant + transient exp(-lam (t - t0))``: a search's bound K as plain data, for a curvature
    with a decaying part (the deceleration of a load braked by viscous friction). No argument: at t0."""

    __slots__ = ("constant", "transient", "lam", "t0")

    def __init__(self, constant, transient, lam, t0):
        self.constant, self.transient, self.lam, self.t0 = constant, transient, lam, t0

    def __call__(self, t=None):
        if t is None:
            return self.constant + self.transient
        return self.constant + self.transient * math.exp(-self.lam * (t - self.t0))


class MotionBound:
    """``t -> constant + scale * motion.curvature_bound(t)``: a search's bound K as plain data, for a function
    whose curvature is a constant plus a multiple of a decaying motion's |v''|. No argument: at the motion's t0."""

    __slots__ = ("constant", "scale", "motion")

    def __init__(self, constant, scale, motion):
        self.constant, self.scale, self.motion = constant, scale, motion

    def __call__(self, t=None):
        return self.constant + self.scale * self.motion.curvature_bound(t)


class CurvatureBound:
    """``t -> motion.curvature_bound(t)``: a search's bound K as plain data (not a bound method)."""

    __slots__ = ("motion",)

    def __init__(self, motion):
        self.motion = motion

    def __call__(self, t=None):
        return self.motion.curvature_bound(t)


SEARCH_CLASSES = (Search, VelocitySearch, PositionSearch, EdgeSearch, DifferenceSearch, ForceSearch, DecayingBound,
                  MotionBound, CurvatureBound)
"""The classes a pending search is made of (what a solver's state may hold besides Drive and Motion)."""


class PiecewisePlant:
    """Base class: advance through events exactly and keep the Fourier integrals."""

    def __init__(self, F, omega, phi, f, harmonics):
        check("F", F, True, "F must be a finite number (N)")
        check("omega", omega, lambda: omega > 0.0, "omega must be > 0 (rad/s)")
        check("phi", phi, lambda: abs(phi) <= PHASE_LIMIT,
              f"phi must be in [-{PHASE_LIMIT:g}, {PHASE_LIMIT:g}] rad (beyond, a float does not resolve a period)")
        check("f", f, True, "the input f must be a finite number (N)")
        check("harmonics", harmonics, lambda: harmonics == int(harmonics) and 0 <= harmonics <= 10,
              "harmonics must be an integer in 0..10")
        self.drive = Drive(f, F, omega, phi)
        self.period = TWO_PI / omega
        self.harmonics = int(harmonics)
        self.t = 0.0
        self.events = 0
        self.event_log = None  # set to a list to record (time, EventKind) of every counted event
        self._integrals = [0j] * (self.harmonics + 1)
        # Bounds on the errors of integrated pieces (.integrated; closed forms add none): the integrals' from
        # the closed pieces, the position's carried into the current piece (it moves every later position),
        # and the velocity's where the last piece ended (an integrated piece started there takes it over)
        self._integral_error = self._position_error = self._velocity_error = 0.0

    # -- pieces ---------------------------------------------------------
    def _begin(self, t, output, analytic=math.inf, analytic_kind=None, searches=()):
        """Start a piece at t with the output's motion and its event sources."""
        self._t_piece = t
        self._output = output
        self._analytic = analytic
        self._analytic_kind = analytic_kind
        self._set_searches(t, searches)

    def _set_searches(self, t, searches):
        self._searches = list(searches)
        self._searched = t
        self._found = None

    def _chunk_end(self, t):
        """End of the search chunk containing t: a grid anchored at the piece start."""
        width = self.period / 8.0
        n = math.floor((t - self._t_piece) / width) + 1
        end = self._t_piece + n * width
        if not end > t:
            end = t + width
            if not end > t:  # the search would not advance
                raise PlantError(f"t = {t!r} is out of range: a search chunk of {width!r} s does not advance past it")
        return end

    def _next_event(self, t_end):
        """(time, kind) of the piece's next event if it is <= t_end, else None."""
        while self._found is None and self._searched < min(self._analytic, t_end):
            a = self._searched
            b = min(self._chunk_end(a), self._analytic)
            for s in self._searches:
                lo = max(a, s.t_from)
                # past an event already found the piece has ended: its functions need not (and, past a
                # stop, may not: a force tending to zero) be resolved there
                hi = b if self._found is None else self._found[0]
                if s.K is None:  # an integrated motion (.integrated) locates its own event; it keeps one step,
                    hi = min(hi, t_end)  # so it goes no further than asked (its steps never depend on it)
                if lo < hi:
                    root = first_root(s.fun, lo, hi, s.K) if s.K is not None else s.fun.first_zero(lo, hi)
                    if root is not None and (self._found is None or root < self._found[0]):
                        self._found = (root, s.kind)
            # an integrated motion was asked up to t_end at most: searched to there, the grid unchanged
            self._searched = min(b, t_end) if any(s.K is None for s in self._searches) else b
        event = self._found
        if event is None or self._analytic <= event[0]:
            event = (self._analytic, self._analytic_kind)
        return event if event[0] <= t_end else None

    def _close_piece(self, t):
        """Add the piece's Fourier integrals from its start to t."""
        for k, value in enumerate(self._piece_integrals(t)):
            self._integrals[k] += value
        out = self._output
        self._integral_error += out.integral_error(t) + self._position_error * (t - self._t_piece)
        self._position_error += out.position_error(t)
        self._velocity_error = out.velocity_error(t)

    def _piece_integrals(self, t):
        out = self._output
        if t <= out.t0:
            return [0j] * (self.harmonics + 1)
        return out.integrals(t, self.harmonics)

    # -- stepping ---------------------------------------------------------
    def advance(self, t_end):
        """Integrate exactly from self.t to t_end, firing every event on the way."""
        check_step_end(t_end, self.t)
        self.drive.phase(t_end, "t_end")  # bounds the search chunks (and every phase on the way)
        span = (t_end - self.t) / self.period
        check("t_end", t_end, lambda: span <= MAX_PERIODS_PER_STEP,
              lambda: f"a step spans at most {MAX_PERIODS_PER_STEP:g} periods of the drive (2 pi/omega = "
                      f"{self.period!r} s), this one {span!r} from t = {self.t!r}: take smaller steps")
        limit = EVENTS_PER_PERIOD_LIMIT * (1.0 + span)
        fired = stalled = 0
        last = None
        while True:
            event = self._next_event(t_end)
            if event is None:
                break
            t_event, kind = event
            fired += 1
            stalled = stalled + 1 if last is not None and t_event - last <= STALL_ULPS * EPS * abs(t_event) else 0
            last = t_event
            if stalled > STALL_EVENTS:
                raise PlantError(f"more than {STALL_EVENTS} events within {STALL_ULPS} ulp of each other at t = "
                                 f"{t_event!r} (last event: {kind}): the motion chatters below the resolution of time")
            if fired > limit:
                raise PlantError(
                    f"more than {EVENTS_PER_PERIOD_LIMIT} events per period between t = {self.t!r} "
                    f"and t = {t_event!r} (last event: {kind}); the motion chatters below the "
                    f"plant's resolution")
            if fired > MAX_EVENTS_PER_STEP:
                raise too_many_events(self.t, t_event, kind)
            if self._fire(t_event, kind):
                self.events += 1
                if self.event_log is not None:
                    self.event_log.append((t_event, kind))
        self.t = t_end

    def _fire(self, t, kind):
        """Apply an event; a piece that ends must call _close_piece first.

        Returns True when the event changes the motion (it is counted)."""
        raise NotImplementedError

    def _restart(self, t):
        """Start a new piece at t from the current state (input change)."""
        raise NotImplementedError

    def set_input(self, f):
        """Set the input force, held constant until the next change."""
        check("f", f, True, "the input f must be a finite number (N)")
        if f != self.drive.f:
            self._close_piece(self.t)
            self.drive = Drive(f, self.drive.F, self.drive.omega, self.drive.phi)
            self._restart(self.t)

    def integrals(self):
        """Running integrals I_k(t) = int_0^t y exp(-i k omega s) ds, k = 0..harmonics."""
        return [acc + piece for acc, piece in zip(self._integrals, self._piece_integrals(self.t))]

    def integrals_error(self):
        """A bound on the error of every integral I_k(t) (y's unit times s): 0 for closed-form pieces (exact to
        rounding), the integrated pieces' own bound (:meth:`~.integrated.Trajectory.integral_error`) for the rest."""
        return (self._integral_error + self._output.integral_error(self.t)
                + self._position_error * (self.t - self._t_piece))
