"""The second solver family: a mode with no closed form, integrated by an embedded Runge-Kutta pair.

The exact family (:mod:`.exact`) needs every mode to be ``x'' = -lam x' + a +
b cos(omega t + phi)``. A friction law that varies with the velocity
(Stribeck's drop from breakaway to Coulomb friction) is not of that form; its
sliding phase

    x' = v,   v' = law(t, v)

is integrated here by the Dormand-Prince pair DOPRI5(4) (Dormand & Prince
1980; the continuous extension and the step control of Hairer, Norsett &
Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., II.4-II.6),
with local extrapolation (the 5th-order solution is kept) and dense output.

A :class:`Trajectory` is a piece's motion: it has the interface of
:class:`~.exact.Motion` that :class:`~.piecewise.PiecewisePlant` reads
(``state``, ``acceleration``, ``integrals`` and the error bounds), and it finds its
own event (the velocity falling to zero in the direction of motion) by
integrating to it: :class:`~.piecewise.PiecewisePlant` asks it through a
:class:`~.piecewise.Search` whose bound ``K`` is None.

What makes it a solver dfwb can stand behind:

- **Independent of the communication step.** Steps are chosen by the error
  control alone, from the piece's start, whole steps only; a time between
  two step ends is read from the dense output. Where an importer stops never
  changes a step, so the result is the same to the bit for any step.
- **Scale and translation invariant.** The displacement d = x - x0 is
  integrated, not x; each component's tolerance is ``rtol`` times the
  largest size it has had in the piece. Changing units or moving the plant
  changes no step.
- **Fourier integrals to the tolerance.** Each step's ``int x exp(-i k omega
  t) dt`` is a 9-point Gauss-Legendre rule on the dense output; a step spans
  at most 1/32 of the drive's period, so the rule's own error (phase span
  below 2 rad at k = 10) is far below rounding.
- **An honest error.** ``error`` bounds the error of the integral of x so
  far (its absolute error, m s): the local error estimates of each step,
  with the velocity's propagated into the position without credit for
  damping. The describing-function engine turns it into ``N_error``.
- **Stops that are motion, not rounding.** An event function is sampled
  EVENT_SAMPLES times a step and its zero refined by Illinois, but a fall to
  zero counts only once the function has risen above what the rounding of
  the step's rates moves it (:func:`_stop`). A mass at its breakaway
  threshold (a loop creeping to rest, the net force within rounding of zero)
  has a velocity of rounding: a stop there fired again and again, millions of
  events without motion.
- **Bounded.** At most MAX_REJECTIONS rejections in a row, MAX_STEPS steps
  in one call, and a step never below STEP_FLOOR ulp of the time: beyond,
  PlantError (the mode is too stiff for an explicit pair: a light mass with
  strong damping).

Plain Python (``math``, ``cmath``) only: this module runs inside the FMUs.
"""

import cmath
import math

from .exact import EPS, PlantError

TREND_ROUNDING = 64.0 * EPS  # as hybrid.TREND_ROUNDING: a coefficient within this of its scale is zero

__all__ = ["Trajectory", "IntegratedMode", "RTOL", "GAUSS_NODES", "GAUSS_WEIGHTS"]

RTOL = 1e-9  # the family's default relative tolerance
STEPS_PER_PERIOD = 32  # a step spans at most this fraction of the drive's period
MAX_REJECTIONS = 60  # in a row: 0.2^60 of a step is far below any resolvable step
MAX_STEPS = 1_000_000  # steps one call may take (an FMU's step costs seconds at most)
# Hairer's stiffness test (DOPRI5's): h |lambda| estimated from the last two stages beyond 3.25 (the pair's
# stability edge) on STIFF_STEPS accepted steps in a row means the step is held by stability, not accuracy;
# refused once that holds it below STIFF_FRACTION of the largest step (thousands of steps per drive period).
STIFF_STEPS, STIFF_FRACTION = 15, 1e-3
STEP_FLOOR = 64.0  # ulp of the time: a step below this is refused (the mode is stiff or singular)
SAFETY, GROW, SHRINK = 0.9, 5.0, 0.2  # step control: h_new = h * clip(0.9 err^(-1/5), 0.2, 5)
NEAR = 3.0  # |v| < NEAR law.scale: the law's feature (the Stribeck drop), crossed a quarter scale a step
ROUNDING = 64.0 * EPS  # the error control's floor: a step's rounding of its derivative's terms
EVENT_SAMPLES = 8  # an event function is sampled at this many points of each step before refinement
REFINE_ITERATIONS = 200  # Illinois steps on one bracket (each at least halves it within 2 steps)

# Dormand-Prince 5(4): nodes, stages, the 5th-order weights (the 7th stage is the next step's first: FSAL),
# the difference to the 4th-order weights, and the dense output's coefficients (Hairer's DOPRI5).
C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)
D = (-12715105075 / 11282082432, 0.0, 87487479700 / 32700410799, -10690763975 / 1880347072,
     701980252875 / 199316789632, -1453857185 / 822651844, 69997945 / 29380423)


def _legendre(n, z):
    """P_n(z) and P_n'(z), by the three-term recurrence."""
    p0, p1 = 1.0, z
    for k in range(2, n + 1):
        p0, p1 = p1, ((2 * k - 1) * z * p1 - (k - 1) * p0) / k
    return p1, n * (z * p1 - p0) / (z * z - 1.0)


def _gauss_legendre(n):
    """The roots z of P_n in [-1, 1], descending, and the weights of the n-point Gauss-Legendre rule on [0, 1]
    (nodes (1 - z) / 2) by Newton on P_n, to rounding."""
    roots, weights = [], []
    for i in range(1, n + 1):
        z = math.cos(math.pi * (i - 0.25) / (n + 0.5))
        for _ in range(100):
            p, dp = _legendre(n, z)
            step = p / dp
            z -= step
            if abs(step) <= 4.0 * EPS:
                break
        dp = _legendre(n, z)[1]  # P_n' at the final node
        roots.append(z)
        weights.append(1.0 / ((1.0 - z * z) * dp * dp))  # 2 / ((1 - z^2) P_n'^2), halved for [0, 1]
    return tuple(roots), tuple(weights)


_ROOTS, GAUSS_WEIGHTS = _gauss_legendre(9)
GAUSS_NODES = tuple(0.5 * (1.0 - z) for z in _ROOTS)
# The rule as a centre node and 4 pairs mid -+ z half (z > 0, the pair's weight the lower node's): the pairs'
# exponentials are the centre's times exp(+-i omega z half), 5 of them a step instead of 9
GAUSS_PAIRS = tuple(zip(_ROOTS[:4], GAUSS_WEIGHTS[:4]))
GAUSS_CENTRE = GAUSS_WEIGHTS[4]


class Trajectory:
    """The motion ``x' = v, v' = law(t, v)`` from ``(t0, x0, v0)``, integrated to its stop.

    ``law`` is plain data with ``__call__(t, v)`` (the acceleration),
    ``size(t, v)`` (the sum of its terms' magnitudes: its rounding) and
    ``scale`` (the velocity over which it varies, near zero: a step there
    crosses a quarter of it at most; inf for none); the
    stop is the first time after t0 where ``sign * v`` falls to zero (the
    direction of motion, sign +-1), the start's own zero excepted. ``omega``
    is the drive's (a step spans at most 1/32 of its period), ``harmonics``
    how many Fourier integrals a piece keeps.

    It keeps only its last step: :meth:`first_zero` integrates no further
    than the step containing ``hi``, and every time asked of it (the plant's,
    which only increases) lies in that step. So its state has a fixed size.
    """

    __slots__ = ("law", "t0", "x0", "v0", "sign", "omega", "harmonics", "rtol", "max_step", "h", "k_last", "peak",
                 "error", "stopped", "taken", "stiff", "step")

    def __init__(self, law, t0, x0, v0, sign, omega, harmonics, rtol=RTOL, v_error=0.0):
        self.law, self.t0, self.x0, self.v0, self.sign = law, t0, x0, v0, sign
        self.omega, self.harmonics, self.rtol = omega, harmonics, rtol
        self.max_step = 2.0 * math.pi / omega / STEPS_PER_PERIOD
        self.h = self.max_step / 64.0  # the next step's trial size (grown by the control within a few steps)
        self.k_last = law(t0, v0)  # v' at the end of the last step (first same as last)
        self.peak = [0.0, abs(v0)]  # the largest |d|, |v| so far: the tolerance's scale
        # bounds on |error| of d and of v at the last step's end (v0's own error: ``v_error``, the plant's
        # velocity_error where its last piece ended)
        self.error = [0.0, v_error]
        self.stopped = None  # the stop's time once found
        self.taken = 0  # steps taken (accepted)
        self.stiff = [0, 0]  # steps held by the pair's stability (Hairer's test), and calm steps since
        # The last step: [a, h, d0, v0, the dense coefficients of d (5) and of v (4), the integrals
        # [0..harmonics] of x from t0 to a, the error bound of int d dt from t0 to a, the bound on |err d|
        # within the step]. At first a step of zero length at t0.
        self.step = [t0, 0.0, 0.0, v0, (0.0,) * 5, (0.0,) * 4, (0j,) * (harmonics + 1), 0.0, 0.0]

    # -- the motion's interface (as exact.Motion) ------------------------------------------------
    def state(self, t):
        """Position and velocity at t (within the last step)."""
        d, v = _dense(self._step_at(t), t)
        return self.x0 + d, v

    def acceleration(self, t, v):
        return self.law(t, v)

    def integrals(self, t, harmonics):
        """[int x ds, then int x exp(-i k omega s) ds for k = 1..harmonics] from t0 to t: one Gauss pass."""
        total = self._step_integrals(self._step_at(t), harmonics, t)
        return [complex(total[0].real)] + total[1:]

    def position_error(self, t):
        """A bound on the error of the displacement at t (m)."""
        return self._step_at(t)[8]

    def velocity_error(self, t):
        """A bound on the error of the velocity at t (m/s); 0 once stopped (the plant then sets it to zero)."""
        return 0.0 if self.stopped is not None and t >= self.stopped else self.error[1]

    def integral_error(self, t):
        """A bound on the error of int_{t0}^{t} x ds (m s): each Fourier integral's error is at most this."""
        step = self._step_at(t)
        return step[7] + step[8] * (t - step[0])

    # -- integration ---------------------------------------------------------------------------------
    @property
    def end(self):
        """The time integrated to."""
        return self.step[0] + self.step[1]

    def first_zero(self, lo, hi):
        """The stop's time if it is at most ``hi``, integrating on to the step containing ``hi``; else None.

        A ``Search`` with K None calls this (see :class:`~.piecewise.PiecewisePlant`, which asks up to its
        step's end at most); a stop found beyond an earlier ``hi`` is returned now, whatever ``lo``.
        """
        if self.stopped is not None:
            return self.stopped if self.stopped <= hi else None
        taken = 0
        while self.end < hi:
            taken += 1
            if taken > MAX_STEPS:
                raise PlantError(f"more than {MAX_STEPS} integration steps between t = {lo!r} and t = {hi!r} s: "
                                 f"the sliding motion is too slow to integrate (take smaller steps)")
            self._take_step()
            if self.stopped is not None:
                return self.stopped if self.stopped <= hi else None
        return None

    def _take_step(self):
        """One accepted step past the end (or the stop within it: then ``stopped`` is set)."""
        last = self.step
        a, d0, v0 = last[0] + last[1], last[2] + last[4][0], last[3] + last[5][0]  # its end
        law, rtol, sign = self.law, self.rtol, self.sign
        k1 = self.k_last
        h = min(self.h, self.max_step, _feature_step(law.scale, v0, k1))
        size = law.size(a, v0)

        def attempt(h):
            kv = [k1]  # the stages of v' (the stages of d' are the stages' velocities)
            vs = [v0]
            for i in range(1, 7):
                vi = v0 + h * sum(aij * kj for aij, kj in zip(A[i], kv))
                vs.append(vi)
                kv.append(law(a + C[i] * h, vi))
            v1 = vs[6]  # the 7th stage is at the 5th-order solution
            d1 = d0 + h * sum(b * vi for b, vi in zip(A[6], vs))
            err_d = h * sum(e * vi for e, vi in zip(E, vs))
            err_v = h * sum(e * ki for e, ki in zip(E, kv))
            # relative to the largest size so far, and never below what the rounding of the forces' sum moves
            # (a breakaway starts from u - Fs = 0, the net acceleration all cancellation; a force a few ulp
            # above Fs moves the mass by rounding alone)
            scale_d = rtol * max(self.peak[0], abs(d1), abs(d0)) + ROUNDING * h * (abs(v0) + h * size)
            scale_v = rtol * max(self.peak[1], abs(v1), abs(v0)) + ROUNDING * h * size
            return max(_ratio(err_d, scale_d), _ratio(err_v, scale_v)), (kv, vs, v1, d1, err_d, err_v)

        h, factor, (kv, vs, v1, d1, err_d, err_v) = _controlled(attempt, a, h, "solver cannot resolve the motion",
                                                                  "a stiff or singular sliding law")
        self.taken += 1
        # Hairer's stiffness test: h |lambda| ~ h |k7 - k6| / |v7 - v6|; 6 calm steps in a row reset the count
        spread = abs(vs[6] - vs[5])
        if spread and h * abs(kv[6] - kv[5]) > 3.25 * spread:
            self.stiff[0] += 1
            self.stiff[1] = 0
            if self.stiff[0] >= STIFF_STEPS and h < STIFF_FRACTION * self.max_step:
                raise PlantError(f"the sliding motion at t = {a!r} s is too stiff for the integrated solver: its "
                                 f"step ({h:.3g} s) is held by the explicit pair's stability, below "
                                 f"{STIFF_FRACTION:g} of a drive period's 1/{STEPS_PER_PERIOD} (a light mass with "
                                 f"strong damping)")
        else:
            self.stiff[1] += 1
            if self.stiff[1] >= 6:
                self.stiff = [0, 0]
        # Dense output. v: Hairer's contd5, 4th order:
        #   v(a + theta h) = v0 + theta (r1 + (1 - theta) (r2 + theta (r3 + (1 - theta) r4)));
        # d: the quintic Hermite of d, d' = v and d'' = v' at both ends, 5th order like the step (contd5's
        # quartic for d is one order short: at rtol 1e-7 its error mid-step is 50 times the step's own).
        dv = v1 - v0
        r2v = h * k1 - dv
        r3v = dv - h * kv[6] - r2v
        r4v = h * sum(c * k for c, k in zip(D, kv))
        dd = d1 - d0
        quintic = (dd, h * v0, h * h * k1, h * v1, h * h * kv[6])
        # the interpolation's error, bounded by the quintic's distance to contd5's quartic for d (the cruder)
        r2d = h * v0 - dd
        quartic = (dd, r2d, dd - h * v1 - r2d, h * sum(c * vi for c, vi in zip(D, vs)))
        dense_error = max(abs(_quintic(0.0, quintic, theta) - _poly(0.0, quartic, theta))
                          for theta in (0.25, 0.5, 0.75))
        integrals = self._step_integrals(last, self.harmonics, a)
        integral_error = last[7] + last[8] * last[1]  # the bound on int |err d| from t0 to a
        # the error bounds at the step's end: the velocity's error moves the position by at most itself times h
        self.error = [self.error[0] + self.error[1] * h + abs(err_d), self.error[1] + abs(err_v)]
        step = [a, h, d0, v0, quintic, (dv, r2v, r3v, r4v), integrals, integral_error,
                self.error[0] + 1.5 * dense_error]  # |err d| anywhere in the step
        self.peak = [max(self.peak[0], abs(d1)), max(self.peak[1], abs(v1))]
        self.k_last = kv[6]
        self.h = h * factor
        self.step = step
        # The stop (see _stop): the velocity against the slide's direction, from the start's own zero on.
        self.stopped = _stop(lambda theta: sign * _poly(v0, step[5], theta), sign * v0, ROUNDING * h * size,
                             left=self.taken > 1)
        if self.stopped is not None:
            self.stopped = a + h * self.stopped

    # -- reading the step -------------------------------------------------------------------------------
    def _step_at(self, t):
        """The last step, which must contain t (PlantError otherwise: a time the piece no longer holds)."""
        step = self.step
        if not step[0] <= t <= step[0] + step[1]:
            raise PlantError(f"t = {t!r} is out of range: this integrated piece holds [{step[0]!r}, "
                             f"{step[0] + step[1]!r}] s")
        return step

    def _step_integrals(self, step, harmonics, t):
        """The integrals of x from t0 to t (t within ``step``): the step's start's, plus Gauss on [a, t]."""
        a, h = step[0], step[1]
        total = list(step[6][:harmonics + 1])
        span = t - a
        if not span > 0.0 or not h:
            return total
        x0, omega, half = self.x0, self.omega, 0.5 * span
        mid = a + half
        centre = (x0 + _dense(step, mid)[0]) * GAUSS_CENTRE * span
        total[0] += centre
        sums, differences = [], []
        for z, weight in GAUSS_PAIRS:
            low = (x0 + _dense(step, mid - half * z)[0]) * weight * span
            high = (x0 + _dense(step, mid + half * z)[0]) * weight * span
            total[0] += low + high
            sums.append(low + high)
            differences.append(low - high)
        if harmonics:
            # low exp(-i k omega (mid - z half)) + high exp(-i k omega (mid + z half))
            #   = exp(-i k omega mid) ((low + high) cos(k theta) + i (low - high) sin(k theta)),  theta = omega z half
            turns = [cmath.exp(complex(0.0, omega * (half * z))) for z, _weight in GAUSS_PAIRS]
            centre_turn = cmath.exp(-1j * omega * mid)
            turn_k, powers = centre_turn, list(turns)
            for k in range(1, harmonics + 1):
                acc = complex(centre, 0.0)
                for total_pair, difference, power in zip(sums, differences, powers):
                    acc += complex(total_pair * power.real, difference * power.imag)
                total[k] += turn_k * acc
                turn_k *= centre_turn
                powers = [power * turn for power, turn in zip(powers, turns)]
        return total


def _ratio(error, scale):
    """|error| / scale, the step's error against its tolerance (0 for no error, inf for no tolerance)."""
    return abs(error) / scale if scale else (0.0 if error == 0.0 else math.inf)


def _controlled(attempt, a, h, what, why):
    """(h, the next step's factor, the values) of the first step from a, from trial size h, whose
    ``attempt(h) -> (error ratio, values)`` is at most 1: Hairer's control, h times 0.9 ratio^(-1/5) within
    [0.2, 5], at most MAX_REJECTIONS times; a step below STEP_FLOOR ulp of the time is refused (PlantError)."""
    ratio = factor = math.inf  # a step below the floor from the start is refused as any other
    values = None
    for _ in range(MAX_REJECTIONS):
        if not h > STEP_FLOOR * EPS * max(abs(a), 1.0) or not a + h > a:
            break
        ratio, values = attempt(h)
        factor = GROW if ratio == 0.0 else min(GROW, max(SHRINK, SAFETY * ratio ** -0.2))
        if ratio <= 1.0:
            break
        h *= factor
    else:
        ratio = math.inf
    if not ratio <= 1.0:
        raise PlantError(f"the integrated {what} at t = {a!r} s: its step fell below {STEP_FLOOR:g} ulp of the time "
                         f"({why})")
    return h, factor, values


def _feature_step(scale, v, rate):
    """The largest step that resolves the law's feature at velocity ``scale`` (the Stribeck velocity) from
    velocity v at the current ``rate`` (an error estimate can step over a feature much narrower than the step:
    a stop mislocated by 1e-3 s at rtol 1e-9): within NEAR scales of zero, a step changes v by a quarter scale
    at most; farther, by half the distance to that region (so it is approached, never jumped over)."""
    return max(0.5 * (abs(v) - NEAR * scale), 0.25 * scale) / abs(rate) if rate else math.inf


def _dense(step, t):
    """(d, v) of a step at t, by its dense output."""
    a, h = step[0], step[1]
    if not h:
        return step[2], step[3]
    theta = (t - a) / h
    return _quintic(step[2], step[4], theta), _poly(step[3], step[5], theta)


def _quintic(y0, c, theta):
    """y0 plus the quintic Hermite of a step: c = (y1 - y0, h y0', h^2 y0'', h y1', h^2 y1'')."""
    t2 = theta * theta
    t3 = t2 * theta
    one = 1.0 - theta
    return y0 + (c[0] * t3 * (10.0 - 15.0 * theta + 6.0 * t2)
                 + c[1] * theta * one * one * (1.0 + 2.0 * theta - 3.0 * t2)
                 + c[2] * 0.5 * t2 * one * one * one
                 + c[3] * t3 * (-4.0 + 7.0 * theta - 3.0 * t2)
                 + c[4] * 0.5 * t3 * one * one)


def _poly(y0, r, theta):
    one = 1.0 - theta
    return y0 + theta * (r[0] + one * (r[1] + theta * (r[2] + one * r[3])))


def _stop(fun, g0, floor, limit=1.0, left=True):
    """The first stop of an event function over a step, as theta in [0, limit], or None.

    ``fun(theta)``: the function along the step, ``g0`` at its start, ``floor`` what the rounding of the
    step's rates moves it. A fall to zero or below counts once the function is *resolved*: above its floor
    at the step's start or at a sample since (EVENT_SAMPLES a step). Within the floor its sign is rounding:
    a mass at its breakaway threshold creeps with the net force within rounding of zero, and a stop there
    would fire at once and again, events without motion. A fall below -floor always counts: refined from
    the last positive sample; if there is none, at the step's start, or where the step may not stop at its
    start (``left`` False: the first step of a departure), at that sample (it never left; time goes on).
    """
    if g0 < -floor and left:
        return 0.0
    armed = g0 > floor
    positive = (0.0, g0) if g0 > 0.0 else None
    for j in range(1, EVENT_SAMPLES + 1):
        if (j - 1) / EVENT_SAMPLES >= limit:
            return None
        theta = j / EVENT_SAMPLES
        g = fun(theta)
        if g <= 0.0 and (armed or g < -floor):
            if positive is not None:
                return _illinois_fn(fun, positive[0], positive[1], theta, g)
            return 0.0 if left else theta
        if g > 0.0:
            positive = (theta, g)
            armed = armed or g > floor
    return None


def _illinois_fn(fun, lo, g_lo, hi, g_hi):
    """The zero of fun in (lo, hi], fun(lo) = g_lo > 0 >= fun(hi) = g_hi: Illinois, at most REFINE_ITERATIONS."""
    if g_hi == 0.0:
        return hi
    side = 0
    for _ in range(REFINE_ITERATIONS):
        mid = hi - g_hi * (hi - lo) / (g_hi - g_lo)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
        g = fun(mid)
        if g > 0.0:
            lo, g_lo = mid, g
            if side == 1:
                g_hi *= 0.5
            side = 1
        else:
            hi, g_hi = mid, g
            if side == -1:
                g_lo *= 0.5
            side = -1
            if g == 0.0:
                break
        if hi - lo <= 2.0 * EPS * max(hi, 1.0):
            break
    return hi


class IntegratedMode:
    """A mode of a hybrid loop with no closed form: X' = A X + c + e_row law(X[col]), integrated by DOPRI5(4).

    What :class:`~.hybrid.HybridSolver` needs of a mode (its ``Mode``'s
    interface: the derivative, the first Taylor coefficients of an event
    function for its trend, a time scale), plus :meth:`take`, one accepted
    step from a state (a chunk of the loop's walk), and :meth:`search`, the
    first event function falling to zero within it. The steps are chosen by
    the error control from the piece's start, as the plant's
    :class:`Trajectory`; the dense output is the quintic Hermite of each
    component (its second derivative A X' + e_row law'(X[col]) X'[col] at both
    ends). ``law`` is plain data with ``__call__(v)``, ``slope(v)`` and ``scale``
    (as the Trajectory's law's).
    """

    __slots__ = ("key", "A", "c", "events", "row", "col", "law", "rtol", "n", "resolution", "max_step")
    integrated = True

    def __init__(self, key, A, c, events, nonlinear, rtol):
        self.key, self.A, self.c, self.events = key, A, c, tuple(events)
        self.row, self.col, self.law = nonlinear
        self.rtol = rtol
        self.n = len(A)
        rho = max(sum(abs(a) for a in row) for row in A)
        self.resolution = 1.0 / rho if rho > 0.0 else 1.0  # the time scale of the linear part
        self.max_step = 4.0 * self.resolution  # a step spans a few of the linear part's time constants at most

    def derivative(self, X):
        dX = [sum(a * x for a, x in zip(row, X)) + ci for row, ci in zip(self.A, self.c)]
        dX[self.row] += self.law(X[self.col])
        return dX

    def second(self, X, dX):
        """X'' at X (X' = dX)."""
        d2 = [sum(a * x for a, x in zip(row, dX)) for row in self.A]
        d2[self.row] += self.law.slope(X[self.col]) * dX[self.col]
        return d2

    def coefficients(self, index, X, dX, dt=0.0):
        """[g, g', g''/2] of event function ``index`` at X and their rounding scales (as ``Mode.coefficients``)."""
        _kind, L, l0 = self.events[index]
        d2 = self.second(X, dX)
        coeffs = [sum(v * x for v, x in zip(L, X)) + l0, sum(v * x for v, x in zip(L, dX)),
                  0.5 * sum(v * x for v, x in zip(L, d2))]
        absL = [abs(v) for v in L]
        scales = [sum(v * abs(x) for v, x in zip(absL, X)) + abs(l0), sum(v * abs(x) for v, x in zip(absL, dX)),
                  0.5 * sum(v * abs(x) for v, x in zip(absL, d2))]
        if dt:
            shift = dt / TREND_ROUNDING
            for k in range(len(coeffs) - 1):
                scales[k] += (k + 1) * abs(coeffs[k + 1]) * shift
        return coeffs, scales

    def gross(self, X):
        """The size of the terms summed into X' (the rounding of a cancelling sum, as the plant's law.size)."""
        gross = [sum(abs(a * x) for a, x in zip(row, X)) + abs(ci) for row, ci in zip(self.A, self.c)]
        gross[self.row] += abs(self.law(X[self.col]))
        return gross

    def first_step(self):
        """The trial size of a piece's first step."""
        return self.max_step / 64.0

    def take(self, a, X0, dX0, h, peak):
        """One accepted step from (a, X0) with trial size h: the step [a, h, X0, X1, dX0, dX1, X0'', X1'', the
        next trial size, the peaks] (``peak``: the largest |X_i| of the piece so far, the tolerance's scale)."""
        n, rtol = self.n, self.rtol
        h = min(h, self.max_step, _feature_step(self.law.scale, X0[self.col], dX0[self.col]))
        gross = self.gross(X0)
        # and what that rounding moves in a step through the coupling (a position, through its velocity's)
        moved = [sum(abs(a) * g for a, g in zip(row, gross)) for row in self.A]

        def attempt(h):
            stages, ks = [X0], [dX0]
            for i in range(1, 7):
                Xi = [X0[j] + h * sum(aij * k[j] for aij, k in zip(A[i], ks)) for j in range(n)]
                stages.append(Xi)
                ks.append(self.derivative(Xi))
            X1 = stages[6]
            ratio = 0.0
            for j in range(n):
                err = h * sum(e * k[j] for e, k in zip(E, ks))
                scale = rtol * max(peak[j], abs(X0[j]), abs(X1[j])) + ROUNDING * h * (gross[j] + h * moved[j])
                ratio = max(ratio, _ratio(err, scale))
            return ratio, (X1, ks)

        h, factor, (X1, ks) = _controlled(attempt, a, h, "loop cannot resolve its motion", "a stiff or singular mode")
        dX1 = ks[6]
        return [a, h, X0, X1, dX0, dX1, self.second(X0, dX0), self.second(X1, dX1), h * factor,
                [max(p, abs(x)) for p, x in zip(peak, X1)]]

    @staticmethod
    def state(step, tau):
        """X at a + tau within the step (its quintic Hermite)."""
        a, h, X0, X1, dX0, dX1, d20, d21 = step[:8]
        if tau == h:
            return list(X1)
        theta = tau / h
        return [_quintic(x0, (x1 - x0, h * v0, h * h * w0, h * v1, h * h * w1), theta)
                for x0, x1, v0, v1, w0, w1 in zip(X0, X1, dX0, dX1, d20, d21)]

    def search(self, step, skip, armed_zero):
        """(tau, kind) of the first event within the step, or None.

        ``skip``: indices of functions not searched (the section's unwatched side). ``armed_zero(index)``:
        whether a function at zero at the step's start may fire at once (False for a departing one: it must
        be positive first, and fires where it is negative beyond the rounding of the step's rates).
        """
        best = None
        h = step[1]
        gross = self.gross(step[2])
        for index, (kind, L, l0) in enumerate(self.events):
            if index in skip:
                continue
            # a departing function that goes negative beyond the rounding of the step's rates never left
            floor = ROUNDING * h * sum(abs(v) * g for v, g in zip(L, gross))

            def g(theta):
                return sum(v * x for v, x in zip(L, self.state(step, theta * h))) + l0

            theta = _stop(g, g(0.0), floor, 1.0 if best is None else best[0] / h, armed_zero(index))
            if theta is not None and (best is None or h * theta < best[0]):
                best = (h * theta, kind)
        return best
