"""Closed-form pieces and event location shared by the plant solvers.

Every plant in dfwb is, between events, a set of coordinates obeying

    x'' = -lam x' + a + b cos(omega t + phi)        (lam >= 0)

with a constant input folded into ``a``. :class:`Motion` gives its exact
solution, written with the phi-functions of exponential integrators so that
it stays accurate for lam -> 0 and for short pieces. :class:`Drive` locates
the instants where the force crosses a level analytically, and
:func:`first_root` finds the first zero of a smooth function from a bound on
its second derivative, so that no zero is ever stepped over.

Every loop here is bounded by construction: a phase too large to resolve a
period and a zero search that would need more than ``MAX_EVALUATIONS``
evaluations raise :class:`PlantError` instead of running on.

Plain Python (``math``, ``cmath``) only: this module runs inside the FMUs.
"""

import cmath
import math

EPS = 2.220446049250313e-16
TWO_PI = 2.0 * math.pi
# |omega t + phi| at most 1e10 rad: there a phase still resolves 3e-7 of a period
# (ulp(1e10) = 1.9e-6 rad); beyond, the force and the crossings dissolve in rounding.
PHASE_LIMIT = 1e10
# Evaluations of g in one first_root call. dfwb stress needs at most 13,241 (the full set: a
# velocity touching zero at a chunk's end; the quick set 929); more means the event cannot be
# resolved at the plant's scale (a clearance of 1e-200 m, a motion 1e30 times the clearance).
MAX_EVALUATIONS = 100_000
# Events one step of a plant or loop may fire: 1 to 3 us each on the compiled core (a loop with an
# 8th-order controller the most), so an importer's step costs seconds, never hours; a longer motion
# is taken in several steps.
MAX_EVENTS_PER_STEP = 5_000_000


class DfwbError(Exception):
    """Base of every error dfwb raises for a reason the user can act on (a value, a file, a run)."""


class PlantError(DfwbError, ValueError):
    """A parameter, input or step the plant cannot accept."""


class Diverged(PlantError):
    """A motion that grew beyond the solvers' bound on the state (the hybrid loops' MAX_STATE)."""


def too_many_events(t, t_event, kind):
    """The PlantError of a step that fires more than MAX_EVENTS_PER_STEP events."""
    return PlantError(f"more than {MAX_EVENTS_PER_STEP} events in one step between t = {t!r} and t = {t_event!r} "
                      f"(last event: {kind}): take smaller steps")


def phi_real(k, y):
    """phi_k(-y) = sum_n (-y)^n / (n + k)!, for y >= 0 (k = 1, 2, 3)."""
    if k == 1 and y > 0.0:
        return -math.expm1(-y) / y  # expm1 keeps every digit
    if y < 0.5:
        term = 1.0 / math.factorial(k)
        total = term
        for n in range(1, 30):  # y < 0.5: the 30th term is below 1e-40 of the first
            term *= -y / (n + k)
            total += term
            if abs(term) <= 1e-18 * abs(total):
                break
        return total
    value = -math.expm1(-y) / y  # phi_1
    for j in range(1, k):
        value = (1.0 / math.factorial(j) - value) / y  # phi_{j+1}(-y)
    return value


def phi1_imaginary(y):
    """(exp(i y) - 1) / (i y) = sin(y)/y + i 2 sin(y/2)^2 / y: no cancellation, exact as y -> 0."""
    if y == 0.0:
        return 1.0 + 0j
    half = math.sin(0.5 * y)
    return complex(math.sin(y) / y, 2.0 * half * half / y)


class Drive:
    """The force u(t) = f + F cos(omega t + phi) acting on a plant.

    ``f`` is the importer's input, held over a communication step; ``F``,
    ``omega``, ``phi`` describe the built-in harmonic excitation.
    """

    __slots__ = ("f", "F", "omega", "phi")

    def __init__(self, f, F, omega, phi):
        if F < 0.0:  # a negative amplitude is a phase shift of pi (towards 0: |phi| does not grow)
            F, phi = -F, (phi + math.pi if phi <= 0.0 else phi - math.pi)
        self.f, self.F, self.omega, self.phi = f, F, omega, phi

    def phase(self, t, name="t"):
        """omega t + phi; PlantError naming ``name`` beyond PHASE_LIMIT, where a period is no longer resolved."""
        theta = self.omega * t + self.phi
        if not abs(theta) <= PHASE_LIMIT:
            raise PlantError(f"{name} = {t!r} is out of range: the phase omega*t + phi = {theta!r} rad must stay "
                             f"within +-{PHASE_LIMIT:g} rad (t <= {(PHASE_LIMIT - self.phi) / self.omega!r} s), "
                             f"where a float still resolves a period")
        return theta

    def u(self, t):
        return self.f + self.F * math.cos(self.omega * t + self.phi)

    def du(self, t):
        return -self.F * self.omega * math.sin(self.omega * t + self.phi)

    def _rounding(self, theta, level):
        """Rounding of u - level at phase theta (a phase carries |theta| ulp).

        Scaled term by term: F (1 + |theta|) would overflow for F near the
        largest float, and an infinite rounding let the trend overrule u.
        """
        e = 8.0 * EPS
        return e * abs(self.f) + e * self.F * (1.0 + abs(theta)) + e * abs(level)

    def above(self, t, level):
        """Whether u > level just after t.

        Where u(t) equals the level within rounding (a mode switch found at
        the very instant u crosses it) the trend decides, not the rounding.
        """
        d, theta = self.u(t) - level, self.omega * t + self.phi
        if self.F == 0.0 or abs(d) > self._rounding(theta, level):
            return d > 0.0  # a constant force has no trend: equal is not above
        slope = -math.sin(theta)
        return slope > 0.0 if abs(slope) > 1e-12 else -math.cos(theta) > 0.0

    def below(self, t, level):
        """Whether u < level just after t (see :meth:`above`)."""
        d, theta = self.u(t) - level, self.omega * t + self.phi
        if self.F == 0.0 or abs(d) > self._rounding(theta, level):
            return d < 0.0
        slope = -math.sin(theta)
        return slope < 0.0 if abs(slope) > 1e-12 else -math.cos(theta) < 0.0

    def crossing(self, t0, level, rising):
        """First t > t0 where u crosses ``level`` upwards (or downwards).

        Tangency is no crossing. Returns inf when u never crosses the level.
        Within PHASE_LIMIT a period spans millions of ulp of the phase, so the
        first candidate is past t0, or the next one is (rounding).
        """
        if self.F == 0.0:
            return math.inf
        r = (level - self.f) / self.F
        if not -1.0 < r < 1.0:
            return math.inf
        theta_c = -math.acos(r) if rising else math.acos(r)
        n = math.ceil((self.phase(t0) - theta_c) / TWO_PI)
        for n in (n, n + 1, n + 2):
            t = (theta_c + TWO_PI * n - self.phi) / self.omega
            if t > t0:
                return t
        raise PlantError(f"t = {t0!r}: no crossing of {level!r} N found past it at omega = {self.omega!r} rad/s "
                         f"(the phase does not resolve a period)")


class Motion:
    """Exact solution of x'' = -lam x' + a + b cos(omega t + phi) from (t0, x0, v0).

    Used for a mass under a constant plus harmonic force (lam = 0), a mass
    with viscous damping (lam = B / M), a relative coordinate, or a body at
    rest (a = b = 0, v0 = 0).
    """

    __slots__ = ("t0", "x0", "v0", "lam", "a", "b", "omega", "phi", "_P")

    def __init__(self, t0, x0, v0, lam, a, b, omega, phi):
        self.t0, self.x0, self.v0 = t0, x0, v0
        self.lam, self.a, self.b, self.omega, self.phi = lam, a, b, omega, phi
        # particular harmonic response of the velocity: Re{P exp(i theta)}
        self._P = b / complex(lam, omega) * cmath.exp(1j * (omega * t0 + phi))

    def state(self, t):
        """Position and velocity at t >= t0."""
        tau = t - self.t0
        lam, w = self.lam, self.omega
        if lam == 0.0:  # undamped (free flight, contact, stick): phi_k(0) = 1/k!
            p1, p2, decay = 1.0, 0.5, 1.0
        else:
            p1, p2, decay = phi_real(1, lam * tau), phi_real(2, lam * tau), math.exp(-lam * tau)
        e = cmath.exp(1j * w * tau)
        v = self.v0 * decay + self.a * tau * p1 + (self._P * (e - decay)).real
        x = (self.x0 + self.v0 * tau * p1 + self.a * tau * tau * p2
             + (self._P * (tau * phi1_imaginary(w * tau) - tau * p1)).real)
        return x, v

    def acceleration(self, t, v):
        return -self.lam * v + self.a + self.b * math.cos(self.omega * t + self.phi)

    def curvature_bound(self, t=None):
        """Bound on |v''| over [t, inf) (t0 by default): ``K`` for velocity zero searches.

        v'' = lam^2 (v0 - a/lam - Re P) exp(-lam tau) - omega^2 Re(P exp(i omega tau)):
        the transient's part decays, so a search long after a fast initial
        decay is not held to the scale of the initial velocity.
        """
        lam, P = self.lam, abs(self._P)
        transient = lam * lam * (abs(self.v0) + P) + lam * abs(self.a)
        if t is not None and transient:
            transient *= math.exp(-lam * (t - self.t0))
        return transient + P * self.omega ** 2

    def integral_error(self, t):
        """A bound on the error of :meth:`integral` and :meth:`fourier` beyond rounding: none (closed form).

        With :meth:`position_error` and :meth:`velocity_error` (also none), what a piece of the integrated
        family (:class:`~.integrated.Trajectory`) reports, so a plant may mix the two."""
        return 0.0

    def position_error(self, t):
        return 0.0

    def velocity_error(self, t):
        return 0.0

    def integrals(self, t, harmonics):
        """[int x ds, then int x exp(-i k omega s) ds for k = 1..harmonics] from t0 to t (a piece's share)."""
        x, v = self.state(t)
        return [complex(self.integral(t))] + self.fourier(t, harmonics, x, v)

    def integral(self, t):
        """Integral of x from t0 to t."""
        tau = t - self.t0
        lam, w = self.lam, self.omega
        harmonic = (tau * phi1_imaginary(w * tau) - tau) / (1j * w) - tau * tau * phi_real(2, lam * tau)
        return (self.x0 * tau + self.v0 * tau * tau * phi_real(2, lam * tau)
                + self.a * tau ** 3 * phi_real(3, lam * tau) + (self._P * harmonic).real)

    def fourier(self, t, harmonics, x1, v1):
        """[int_{t0}^{t} x(s) exp(-i k omega s) ds for k = 1..harmonics], given x, v at t.

        Integration by parts through the equation of motion: exact, with an
        absolute error of a few ulp of the state's scale however short the
        piece. Every exponential is a power of exp(-i omega t0) or
        exp(-i omega t), so all harmonics cost a few complex products each.
        """
        w, t0 = self.omega, self.t0
        z0, z1 = cmath.exp(-1j * w * t0), cmath.exp(-1j * w * t)
        half_rot = 0.5 * cmath.exp(1j * self.phi)
        half_rot_c = half_rot.conjugate()
        a, b, lam, x0, v0 = self.a, self.b, self.lam, self.x0, self.v0
        below = t - t0  # int exp(-i (k - 1) w s) ds, for k = 1
        e0, e1 = z0, z1  # exp(-i k w t0), exp(-i k w t)
        out = []
        for k in range(1, harmonics + 1):
            nu = k * w
            n0, n1 = e0 * z0, e1 * z1  # power k + 1
            s0 = (e1 - e0) / (-1j * nu)  # int exp(-i k w s) ds
            above = (n1 - n0) / (-1j * (nu + w))  # int exp(-i (k + 1) w s) ds
            # int cos(w s + phi) exp(-i k w s) ds
            c = half_rot * below + half_rot_c * above
            j = (a * s0 + b * c - (v1 * e1 - v0 * e0)) / complex(lam, nu)
            out.append((j - (x1 * e1 - x0 * e0)) / (1j * nu))
            below, e0, e1 = s0, n0, n1
        return out


def first_root(fun, a, b, K):
    """First t in (a, b] where g(t) <= 0, given g(a) > 0 and |g''| <= K on [a, b].

    ``fun(t)`` returns (g, g'). ``K`` is a number, or a function of t that
    bounds |g''| on [t, b] (a decaying transient: each interval gets the
    bound from its own start). Intervals are cleared by rigorous bounds
    (positive lower bound, or g increasing) and split otherwise, so a zero
    can never hide between two samples; a strictly decreasing interval with
    a sign change is refined by safeguarded Newton to machine precision.
    Returns None when g stays positive (grazes below rounding are ignored).
    Bounded: each pass evaluates g once or pops an evaluated point, and more
    than MAX_EVALUATIONS evaluations (the search and the refinement
    together) raise PlantError.
    """
    bound = K if callable(K) else None
    ga, dga = fun(a)
    if ga <= 0.0:
        return a
    if bound is not None:
        K = bound(a)
    end = b
    pending = [(b,) + tuple(fun(b))]
    evaluations = 2
    while pending:
        b, gb, dgb = pending[-1]
        span = b - a
        mean_slope = 0.5 * (dga + dgb)
        if gb <= 0.0 and mean_slope + 0.5 * K * span < 0.0:
            return _refine(fun, a, b, ga, dga, MAX_EVALUATIONS - evaluations, K)
        cleared = gb > 0.0 and (min(ga, gb) - 0.125 * K * span * span > 0.0
                                or mean_slope - 0.5 * K * span >= 0.0)
        if not cleared:
            m = a + 0.5 * span
            if a < m < b:
                if evaluations >= MAX_EVALUATIONS:
                    raise _unresolved(a, end, K)
                evaluations += 1
                pending.append((m,) + tuple(fun(m)))
                continue
            if gb <= 0.0:  # interval at machine resolution
                return b
        pending.pop()
        a, ga, dga = b, gb, dgb
        if bound is not None:
            K = bound(a)
    return None


def _unresolved(a, b, K):
    return PlantError(f"an event search between t = {a!r} and t = {b!r} s needed more than {MAX_EVALUATIONS} "
                      f"evaluations (curvature bound {K!r}): the motion cannot be resolved at the plant's scale")


def _refine(fun, lo, hi, g_lo, dg_lo, budget, K):
    """Zero of a strictly decreasing g on [lo, hi], g(lo) > 0 >= g(hi), in at most ``budget`` evaluations."""
    start = lo
    t = lo - g_lo / dg_lo if dg_lo < 0.0 else 0.5 * (lo + hi)
    for _ in range(budget):
        if not lo < t < hi:
            t = 0.5 * (lo + hi)
            if not lo < t < hi:
                return hi  # bracket at machine resolution
        g, dg = fun(t)
        if g > 0.0:
            lo = t
        else:
            hi = t
        nxt = t - g / dg if dg < 0.0 else 0.5 * (lo + hi)
        if abs(nxt - t) <= 2.0 * EPS * abs(t):
            return min(max(nxt, lo), hi)
        t = nxt
    raise _unresolved(start, hi, K)
