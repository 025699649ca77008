"""Exact integration of a piecewise-affine hybrid system: X' = A X + c in each mode, events where g(X) = 0.

A plant in feedback with a linear controller is, between events, linear
time-invariant: the plant's mode fixes its equations, the controller is
linear, and nothing depends on time explicitly. So each *piece* of the motion
is X(t) = exp(A (t - t0)) X0 + (affine part), and every event (a velocity
reaching zero, a force reaching the break-away level, a gap closing) is the
first zero of a linear function g(X) = L.X + l0 along it.

Pieces are walked in *chunks* of length h anchored at the piece start, with
rho h <= 1 where rho is a balanced norm of A (a power-of-two diagonal
similarity, so every bound below is rigorous). On a chunk the state is its
Taylor series, truncated where the remainder is below 2^-60 of the first
term:

    X(a + tau) = X(a) + sum_k A^(k-1) X'(a) tau^k / k!

so each event function is a polynomial in tau whose coefficients are dot
products with the rows L A^(k-1) / k! (cached per mode). Its first zero is
found by :func:`~.exact.first_root` from a bound on its second derivative, so
no event is ever stepped over, and refined to machine precision. The chunk
grid depends only on the piece start, never on where an importer asks for
the state: results are bit-identical for any communication step. Where
A^2 = 0 term by term (a stuck mass whose controller integrates its
position) the series ends after two terms and is exact on a chunk of any
length: such a mode is walked in chunks of 2^20 s, so a minute-long stick
phase is one chunk, not sixty.

An event leaves the state on a boundary; the next mode's function for that
boundary is zero there. Such a *departing* function is searched, on the
first chunk, as g / tau^j with j its leading coefficients that vanish within
rounding, so the departure itself is not an event and an immediate return is.

Every loop is bounded: a chunk's search by MAX_EVALUATIONS, the events of a
step by EVENTS_PER_CHUNK per chunk it spans and by MAX_EVENTS_PER_STEP, a
step's chunks by MAX_CHUNKS_PER_STEP, and the time by TIME_LIMIT chunks of the
fastest mode. So one step (an FMU's doStep) costs seconds at most; a study's
own bound is its :class:`Budget`.

Plain Python (``math``) only: this module runs inside the FMUs.
"""

import math
from operator import mul

from .exact import EPS, MAX_EVENTS_PER_STEP, Diverged, PlantError, first_root, too_many_events
from .integrated import TREND_ROUNDING, IntegratedMode

TAYLOR_RADIUS = 1.0  # rho h: the Taylor terms decrease from the first
TAYLOR_TOLERANCE = 2.0 ** -60  # relative truncation of a chunk's series
MAX_TERMS = 40
EVENTS_PER_CHUNK = 10_000
TIME_LIMIT = 1e12  # chunks of the fastest mode in [0, t]: beyond, ulp(t) is a sizeable part of a chunk
MAX_CHUNKS_PER_STEP = 10_000_000  # the chunks one step may integrate (a study's Budget is at most this)
NILPOTENT_CHUNK = 2.0 ** 20  # s: the chunk of a mode whose series ends (see nilpotency)
MAX_STATE = 1e150  # a state beyond this diverges: long before floating point's end, where no event resolves
SECTION_UP, SECTION_DOWN = "section+", "section-"  # crossings of a watched function (re-anchor, not events)
SECTION = (SECTION_UP, SECTION_DOWN)


def _matvec(A, x):
    return [sum(map(mul, row, x)) for row in A]


def _dot(a, b):
    return sum(map(mul, a, b))  # the products summed in order, as a generator would (without its frames)


def nilpotency(A):
    """1 where A = 0, 2 where A != 0 and A^2 = 0 term by term (each product A_iq A_qj has a zero factor), else 0.

    Exact, not rounded: such a mode's motion is a polynomial of degree at most 2 in time, its Taylor series
    ends, and a chunk of any length (NILPOTENT_CHUNK) is exact; its event functions are at most quadratic,
    which the zero search resolves over any span. Higher indices keep the ordinary chunks (a long chunk of a
    cubic would cost the search many evaluations)."""
    n = len(A)
    if all(a == 0.0 for row in A for a in row):
        return 1
    if all(A[i][q] == 0.0 or A[q][j] == 0.0 for i in range(n) for q in range(n) for j in range(n)):
        return 2
    return 0


def balance(A):
    """Powers of two d_i such that D^-1 A D (D = diag(d)) has rows and columns of like size (LAPACK's gebal).

    Exact (powers of two) and bounded: at most 60 sweeps, each scaling by at most 2^+-1 per entry.
    """
    n = len(A)
    d = [1.0] * n
    for _ in range(60):
        changed = False
        for i in range(n):
            col = sum(abs(A[j][i]) * d[i] / d[j] for j in range(n) if j != i)  # of D^-1 A D
            row = sum(abs(A[i][j]) * d[j] / d[i] for j in range(n) if j != i)
            if col == 0.0 or row == 0.0:
                continue
            f = 1.0
            while col < row / 2.0 and f < 2.0 ** 30:
                col, row, f = col * 2.0, row / 2.0, f * 2.0
            while col > row * 2.0 and f > 2.0 ** -30:
                col, row, f = col / 2.0, row * 2.0, f / 2.0
            if f != 1.0 and (col + row) < 0.95 * (col / f + row * f):
                d[i] *= f
                changed = True
        if not changed:
            break
    return d


def _taylor_rows(L, A, terms):
    """The rows L A^(k-1) / k!, k = 1..terms: a linear function's Taylor coefficients are their dot products
    with X'."""
    n, rows, r = len(A), [], list(L)
    for k in range(1, terms + 1):
        rows.append([v / math.factorial(k) for v in r])
        r = [_dot(r, [A[m][j] for m in range(n)]) for j in range(n)]
    return rows


class Mode:
    """One mode: X' = A X + c, and its event functions ``(kind, L, l0)``: events where L.X + l0 falls to zero.

    Derived once: the chunk length h, the number of Taylor terms, the step
    matrix Psi = sum_k A^(k-1) h^k / k! (X(a + h) = X(a) + Psi X'(a)), and for
    each event function the rows L A^(k-1) / k! and their absolute values.
    """

    __slots__ = ("key", "A", "c", "events", "h", "resolution", "terms", "psi", "rows", "abs_rows", "absA", "scale",
                 "reach", "norms", "tail", "curvature_tail", "_series")
    integrated = False  # a closed-form mode (IntegratedMode: one integrated by .integrated)

    def __init__(self, key, A, c, events):
        self.key, self.A, self.c, self.events = key, A, c, tuple(events)
        self._series = {}  # {row L: its rows L A^(k-1) / k!} (series())
        n = len(A)
        d = balance(A)
        rho = max(sum(abs(A[i][j]) * d[j] / d[i] for j in range(n)) for i in range(n))
        self.scale = d
        # the time scale the mode resolves (A = 0: none; 1 s serves the time limits)
        self.resolution = TAYLOR_RADIUS / rho if rho > 0.0 else 1.0
        # a chunk of at most NILPOTENT_CHUNK: rho h <= 1 still, and h^k stays finite (a mass of 1e300 kg)
        h = min(self.resolution, NILPOTENT_CHUNK)
        terms, term = 1, 1.0
        while rho > 0.0 and terms < MAX_TERMS and term > TAYLOR_TOLERANCE:
            terms += 1
            term *= TAYLOR_RADIUS / terms
        index = nilpotency(A)
        if index:  # A^index = 0: the series ends after index terms, exact on any chunk (a stuck mass's integrator)
            h, terms = NILPOTENT_CHUNK, index
        self.h = h
        self.terms = terms
        self.absA = [[abs(a) for a in row] for row in A]
        # Psi by Horner: h (I + A h/2 (I + A h/3 (...)))
        P = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
        for k in range(self.terms, 1, -1):
            AP = [[_dot(A[i], [P[m][j] for m in range(n)]) for j in range(n)] for i in range(n)]
            P = [[(1.0 if i == j else 0.0) + AP[i][j] * h / k for j in range(n)] for i in range(n)]
        self.psi = [[value * h for value in row] for row in P]
        self.rows = [_taylor_rows(L, A, self.terms) for _kind, L, _l0 in self.events]
        self.abs_rows = [_taylor_rows([abs(v) for v in L], self.absA, self.terms) for _kind, L, _l0 in self.events]
        # What a chunk can change: |g(a + tau) - g(a)| <= reach . |X'(a)| + |L D|_1 |D^-1 X'(a)|_inf tail
        # (the series' truncated terms, bounded in the balanced norm, rho h <= 1)
        self.reach = [[sum(row[j] * h ** k for k, row in enumerate(abs_rows, start=1)) for j in range(n)]
                      for abs_rows in self.abs_rows]
        self.norms = [sum(abs(v) * dj for v, dj in zip(L, d)) for _kind, L, _l0 in self.events]
        self.tail = 0.0 if index else 2.0 * h / math.factorial(self.terms + 1)
        self.curvature_tail = 0.0 if index or self.terms == 1 else 2.0 * rho / math.factorial(self.terms - 1)

    def balanced_size(self, dX):
        """|D^-1 X'|_inf: the size of X' in the norm the Taylor bounds use."""
        return max(abs(v) / dj for v, dj in zip(dX, self.scale))

    def cannot_fire(self, index, X, dX, size):
        """Whether event function ``index`` provably stays positive over the chunk from X (X' = dX)."""
        _kind, L, l0 = self.events[index]
        g = _dot(L, X) + l0
        if g <= 0.0:
            return False
        change = _dot(self.reach[index], [abs(v) for v in dX]) + self.norms[index] * size * self.tail
        rounding = TREND_ROUNDING * (_dot([abs(v) for v in L], [abs(x) for x in X]) + abs(l0))
        return g > 1.001 * change + rounding

    def derivative(self, X):
        return [_dot(row, X) + ci for row, ci in zip(self.A, self.c)]

    def state(self, X, dX, tau):
        """X(a + tau) from X(a) and X'(a), 0 <= tau <= h, by the Taylor series (Horner)."""
        krylov = [dX]
        for _ in range(self.terms - 1):
            krylov.append(_matvec(self.A, krylov[-1]))
        acc = krylov[-1]
        for k in range(self.terms - 1, 0, -1):
            f = tau / (k + 1)
            acc = [kv + f * a for kv, a in zip(krylov[k - 1], acc)]
        return [x + tau * a for x, a in zip(X, acc)]

    def series(self, L, X, dX):
        """Taylor coefficients [L.X, (L.X)'/1!, (L.X)''/2!, ...] at X (X' = dX) of the linear function L.X, as
        :meth:`coefficients` gives an event function's (the rows L A^(k-1) / k! kept per row)."""
        rows = self._series.get(tuple(L))
        if rows is None:
            rows = self._series[tuple(L)] = _taylor_rows(L, self.A, self.terms)
        return [_dot(L, X)] + [_dot(row, dX) for row in rows]

    def step(self, X, dX):
        """X(a + h)."""
        return [x + _dot(row, dX) for x, row in zip(X, self.psi)]

    def coefficients(self, index, X, dX, dt=0.0):
        """Taylor coefficients [g, g'/1!, g''/2!, ...] of event function ``index`` at X, and their rounding scales.

        ``dt``: how far the instant of X is uncertain (an event located to the
        ulp of its time): a coefficient moves by (k + 1) c_(k+1) dt with it,
        which its scale includes (a force found zero at a release is zero
        within that, not a sign to act on).
        """
        _kind, L, l0 = self.events[index]
        coeffs = [_dot(L, X) + l0] + [_dot(row, dX) for row in self.rows[index]]
        size = [abs(a) for a in _matvec(self.absA, [abs(x) for x in X])]
        size = [s + abs(ci) for s, ci in zip(size, self.c)]
        scales = [_dot([abs(v) for v in L], [abs(x) for x in X]) + abs(l0)]
        scales += [_dot(row, size) for row in self.abs_rows[index]]
        if dt:
            shift = dt / TREND_ROUNDING
            for k in range(len(coeffs) - 1):
                scales[k] += (k + 1) * abs(coeffs[k + 1]) * shift
        return coeffs, scales


def trend(coeffs, scales):
    """The sign of a function just after a point, from its Taylor coefficients there (0: zero within rounding)."""
    for value, scale in zip(coeffs, scales):
        if abs(value) > TREND_ROUNDING * scale:
            return 1 if value > 0.0 else -1
    return 0


class Budget:
    """Chunks a study may still integrate: the bound on its work where the importer does not set one.

    A loop whose controller is much faster than its motion (a pole at -1e6
    around a 1 s cycle) needs millions of chunks per period; a study refuses
    it in one line instead of running for hours.
    """

    __slots__ = ("left", "total")

    def __init__(self, chunks):
        self.left = self.total = int(chunks)

    def spend(self, t, h):
        self.left -= 1
        if self.left < 0:
            raise PlantError(f"the exact loop needed more than {self.total} chunks of integration (at t = {t:.6g} s "
                             f"a chunk is {h:.3g} s): this study's motions are too long for its work budget, or the "
                             f"fastest time scale too far below the motion's")


class Polynomial:
    """``tau -> (p, p')`` of sum c_i tau^i (Horner): an event function on a chunk, as plain data."""

    __slots__ = ("c",)

    def __init__(self, c):
        self.c = c

    def __call__(self, tau):
        p, dp = 0.0, 0.0
        for value in reversed(self.c):
            dp = dp * tau + p
            p = p * tau + value
        return p, dp

    def curvature_bound(self, h, tail=0.0):
        """A bound on |p''| over [0, h], plus ``tail`` (the bound on the truncated series' part)."""
        c = self.c
        total = sum(i * (i - 1) * abs(c[i]) * h ** (i - 2) for i in range(2, len(c)))
        return 1.0001 * total + tail + 1e-300


class HybridSolver:
    """Walk a hybrid system through its events exactly.

    Subclasses give the modes (:meth:`system`, returning A, c and the event
    functions of a mode key) and the switching logic (:meth:`_fire`, called
    at an event with the state; it returns the next mode key, the state and
    the index of the departing event function or None), and call
    :meth:`start`.
    """

    def __init__(self, section=None, modes=None, budget=None):
        self.t = 0.0
        self.events = 0
        self.event_log = None  # a list to record (time, kind) of every event
        self._modes = {} if modes is None else modes  # shared by solvers of one system and section
        self._budget = budget  # a Budget of chunks shared by the solvers of one study (None: unbounded)
        self._section = section  # (L, l0): watch the upward zero crossings of L.X + l0
        self._watching = None  # the kind of the section function searched (the other is negative)
        self._time_rounding = 0.0  # how far the current instant is uncertain (4 ulp of the last event's time)
        self.crossings = []  # (t, X) at every upward crossing of the section
        self.stopped = None  # the event kind the last advance stopped at (its ``stop_at``), else None

    def start(self, t0, X0, key, departing=None):
        """Begin at t0 in mode ``key`` (``departing``: the index of an event function that is zero at X0).

        Started on the section, the section's function leaves zero as a departing one (no crossing at t0).
        """
        self.t = t0
        self._time_rounding = 4.0 * EPS * abs(t0)
        departing = () if departing is None else (departing,)
        if self._section is not None:
            mode = self.mode(key)
            up = len(mode.events) - 2
            coeffs, scales = mode.coefficients(up, X0, mode.derivative(X0))
            self._watching = SECTION_UP if trend(coeffs, scales) > 0 else SECTION_DOWN
            if abs(coeffs[0]) <= TREND_ROUNDING * scales[0]:
                departing += (up if self._watching is SECTION_UP else up + 1,)
        self._begin(t0, list(X0), key, departing)

    # -- modes ----------------------------------------------------------------
    def mode(self, key):
        mode = self._modes.get(key)
        if mode is None:
            A, c, events, *nonlinear = self.system(key)
            if self._section is not None:
                L, l0 = self._section
                events = list(events) + [(SECTION_UP, [-v for v in L], -l0), (SECTION_DOWN, list(L), l0)]
            if nonlinear and nonlinear[0] is not None:  # (row, col, law): X'[row] += law(X[col])
                mode = IntegratedMode(key, A, c, events, nonlinear[0], self.rtol)
            else:
                mode = Mode(key, A, c, events)
            self._modes[key] = mode
        return mode

    rtol = None  # the relative tolerance of integrated modes (a system with any sets it)

    def system(self, key):
        """(A, c, events) of mode ``key``, or (A, c, events, (row, col, law)) for a mode with the nonlinear
        term law(X[col]) added to X'[row] (integrated, :class:`~.integrated.IntegratedMode`)."""
        raise NotImplementedError

    def _fire(self, t, kind, X):
        raise NotImplementedError

    def _switch(self, t, kind, X):
        """(key, X, departing) after an event of ``kind`` at X: the system's switching logic, :meth:`_fire`."""
        return self._fire(t, kind, X)

    def after(self, key, index, X):
        """Sign of event function ``index`` of mode ``key`` just after X (its trend where it is zero).

        Called at an event (or the start): X's instant is known to the ulp of the time.
        """
        mode = self.mode(key)
        return trend(*mode.coefficients(index, X, mode.derivative(X), self._time_rounding))

    def function_index(self, key, kind):
        return next(i for i, event in enumerate(self.mode(key).events) if event[0] == kind)

    # -- pieces and chunks --------------------------------------------------------
    def _begin(self, t, X, key, departing):
        self.key = key
        self._mode = self.mode(key)
        self._departing = departing
        self._chunk_start(t, X, first=True)

    def _chunk_start(self, t, X, first=False):
        for x in X:
            if not abs(x) <= MAX_STATE:
                raise Diverged(f"the state is beyond [-{MAX_STATE:g}, {MAX_STATE:g}] at t = {t!r} s ({X}): the "
                               "loop diverges (or its initial values are too large)")
        self._a, self._X = t, X
        mode = self._mode
        self._dX = mode.derivative(X)
        if mode.integrated:  # the chunk is one accepted step, sized by the error control from the piece's start
            last = None if first else self._step
            h, peak = (mode.first_step(), [abs(x) for x in X]) if last is None else (last[8], last[9])
            self._step = mode.take(t, X, self._dX, h, peak)
            self._b = t + self._step[1]
        else:
            self._step = None
            self._b = t + mode.h
        self._first = first
        self._event = None
        self._searched = False

    def _search(self):
        """The first event in the current chunk: (tau, kind) or None."""
        mode, X, dX = self._mode, self._X, self._dX
        if mode.integrated:
            skip = {i for i, event in enumerate(mode.events) if event[0] in SECTION and event[0] != self._watching}
            return mode.search(self._step, skip, lambda index: not (self._first and index in self._departing))
        h = mode.h
        size = mode.balanced_size(dX)
        best = None
        dt = self._time_rounding if self._first else 0.0
        for index, (kind, _L, _l0) in enumerate(mode.events):
            if kind in SECTION and kind != self._watching:
                continue
            departing = self._first and index in self._departing
            if not departing and mode.cannot_fire(index, X, dX, size):
                continue
            coeffs, scales = mode.coefficients(index, X, dX, dt)
            j = 0
            if departing or abs(coeffs[0]) <= TREND_ROUNDING * scales[0]:
                # on the boundary (left by the last event, or reached at the chunk's start): its trend decides
                j = 1
                while j < len(coeffs) and abs(coeffs[j]) <= TREND_ROUNDING * scales[j]:
                    j += 1
                if j == len(coeffs):
                    continue  # identically zero within rounding: it stays on the boundary, not an event
                coeffs = coeffs[j:]
            poly = Polynomial(coeffs)
            limit = h if best is None else best[0]
            tail = mode.norms[index] * size * mode.curvature_tail / h ** j  # g / tau^j: its tail is no larger
            try:
                tau = first_root(poly, 0.0, limit, poly.curvature_bound(limit, tail))
            except PlantError:
                raise PlantError(f"the search for the event {kind} on [{self._a!r}, {self._a + limit!r}] s needed "
                                 f"more than the bounded number of evaluations: the motion cannot be resolved at "
                                 f"the loop's scale") from None
            if tau is not None and (best is None or tau < best[0]):
                best = (tau, kind)
        return best

    def advance(self, t_end, stop_at_section=False, stop_at=()):
        """Integrate exactly from self.t to t_end, firing every event on the way.

        With ``stop_at_section``, stop early at the next upward crossing of the
        section (then ``self.crossings[-1]`` holds it). ``stop_at``: pairs
        ``(mode key, event kind)``; stop just after the first event of such a
        kind fired from such a mode (then ``self.stopped`` is its kind and the
        state is the one the event left, on its boundary).
        """
        self.stopped = None
        if not (isinstance(t_end, (int, float)) and not isinstance(t_end, bool) and math.isfinite(t_end)
                and t_end >= self.t):
            raise PlantError(f"t_end = {t_end!r} is out of range: the end of a step must be a finite number >= "
                             f"the current time {self.t!r}")
        fastest = min(mode.resolution for mode in self._modes.values())
        if t_end > TIME_LIMIT * fastest:
            raise PlantError(f"t_end = {t_end!r} s is out of range: at most {TIME_LIMIT * fastest:.6g} s "
                             f"({TIME_LIMIT:g} chunks of the fastest mode, where a float still resolves them)")
        limit = EVENTS_PER_CHUNK * (1.0 + (t_end - self.t) / fastest)
        fired = chunks = 0
        while True:
            if not self._searched:
                self._event = self._search()
                self._searched = True
            if self._event is not None and self._a + self._event[0] <= t_end:
                tau, kind = self._event
                fired += 1
                if fired > limit:
                    raise PlantError(f"more than {EVENTS_PER_CHUNK} events per chunk between t = {self.t!r} and "
                                     f"{self._a + tau!r} s (last event: {kind}): the motion chatters below the "
                                     f"solver's resolution")
                if fired > MAX_EVENTS_PER_STEP:
                    raise too_many_events(self.t, self._a + tau, kind)
                t = self._a + tau
                X = self._state_at(tau)
                self._time_rounding = 4.0 * EPS * abs(t)
                if kind in SECTION:  # not an event of the system: watch the other direction from here
                    if kind is SECTION_UP:
                        self.crossings.append((t, self.visible(X)))
                    self._watching = SECTION_DOWN if kind is SECTION_UP else SECTION_UP
                    self._begin(t, X, self.key, (self.function_index(self.key, self._watching),))
                    if stop_at_section and kind is SECTION_UP:
                        t_end = t
                        break
                    continue
                fired_from = self.key
                key, X, departing = self._switch(t, kind, X)
                departing = () if departing is None else (departing,)
                self.events += 1
                if self.event_log is not None:
                    self.event_log.append((t, kind))
                self._begin(t, X, key, departing)
                if stop_at and (fired_from, kind) in stop_at:
                    self.stopped = kind
                    t_end = t
                    break
                continue
            if self._b > t_end:
                break
            chunks += 1
            if chunks > MAX_CHUNKS_PER_STEP:
                raise PlantError(f"more than {MAX_CHUNKS_PER_STEP} chunks of integration in one step from "
                                 f"t = {self.t!r} (at t = {self._b:.6g} s a chunk is {self._chunk_length():.3g} s): "
                                 f"take smaller steps")
            if self._budget is not None:
                self._budget.spend(self._b, self._chunk_length())
            end = list(self._step[3]) if self._mode.integrated else self._mode.step(self._X, self._dX)
            self._chunk_start(self._b, end)
        self.t = t_end

    def expansion(self, L):
        """(t_end, coefficients): ``L.X(self.t + tau) = sum_k c_k tau^k`` for 0 <= tau <= t_end - self.t, t_end
        the current chunk's end or its next event, whichever comes first: the exact motion's Taylor series
        (remainder below 2^-60 of its first term), for integrals over the motion with no sampling error."""
        if self._mode.integrated:
            raise PlantError("an integrated mode has no Taylor series of its motion (expansion)")
        if not self._searched:
            self._event = self._search()
            self._searched = True
        end = self._b if self._event is None else min(self._b, self._a + self._event[0])
        X = self._integrated()
        return end, self._mode.series(L, X, self._mode.derivative(X))

    def sample(self, times):
        """The states at each of ``times`` (non-decreasing, from self.t), advancing to them in turn."""
        states = []
        for t in times:
            self.advance(t)
            states.append(self.state())
        return states

    def state(self):
        """The state X at self.t (as :meth:`visible` shows it)."""
        return self.visible(self._integrated())

    def _integrated(self):
        """The whole integrated state at self.t (a system's own coordinates included)."""
        tau = self.t - self._a
        return list(self._X) if tau == 0.0 else self._state_at(tau)

    @staticmethod
    def visible(X):
        """What a caller sees of the integrated state X: all of it (a system may keep coordinates of its own)."""
        return X

    def _chunk_length(self):
        """The current chunk's length: the mode's (closed form), or the step's (integrated)."""
        return self._step[1] if self._mode.integrated else self._mode.h

    def _state_at(self, tau):
        """X at self._a + tau within the chunk."""
        if self._mode.integrated:
            return self._mode.state(self._step, tau)
        return self._mode.state(self._X, self._dX, tau)
