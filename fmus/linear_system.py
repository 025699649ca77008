"""A linear transfer function G(s) in state space, exact for a held input.

    G(s) = (b0 s^n + b1 s^(n-1) + ... + bn) / (s^n + a1 s^(n-1) + ... + an),   n = 1..8

The realisation is the controllable canonical form (x1 the lowest
derivative): x1' = x2, ..., xn' = -an x1 - ... - a1 xn + u, and
y = sum_i (b_(n+1-i) - b0 a_(n+1-i)) x_i + b0 u (D = b0: proper is allowed).

Over a step of length h with the input u held constant the state obeys
x(t + h) = Phi x(t) + Gamma u exactly, with Phi = exp(A h) and
Gamma = int_0^h exp(A s) ds B. Both come from one matrix exponential of the
augmented matrix [[A, B], [0, 0]] h (its upper blocks are Phi and Gamma),
so integrators (a pole at 0, A singular) need no inverse of A. The matrix
exponential is plain Python (this module runs inside the FMU with only a
Python runtime): scaling and squaring around a Taylor polynomial.
"""

import math

from .piecewise import PlantError, check, check_step_end

MAX_ORDER = 8
TAYLOR_RADIUS = 0.5  # the scaled matrix has a 1-norm <= this
TAYLOR_TOLERANCE = 2.0 ** -56  # bound on the Taylor remainder, relative to exp(-radius) <= |exp|
CACHE_SIZE = 64  # (Phi, Gamma) pairs kept, one per distinct step length


def _norm1(M):
    """1-norm (largest absolute column sum) of a square matrix."""
    return max(sum(abs(row[j]) for row in M) for j in range(len(M)))


def _matmul(X, Y):
    columns = list(zip(*Y))
    return [[sum(x * y for x, y in zip(row, column)) for column in columns] for row in X]


def expm(M):
    """exp(M) of a small square matrix (list of rows), in plain Python.

    Scaling and squaring: M / 2^s has a 1-norm <= 0.5, its exponential is
    the Taylor polynomial of the least degree m whose remainder is below
    2^-56 relative (Horner form, m <= 17), then it is squared s times. The
    scaling by a power of two is exact.
    """
    n = len(M)
    if any(len(row) != n for row in M):
        raise PlantError(f"expm needs a square matrix, not {n} rows of lengths {[len(row) for row in M]}")
    norm = _norm1(M)
    if not math.isfinite(norm):
        raise PlantError(f"expm of a matrix with a non-finite entry (1-norm {norm!r})")
    squarings = 0
    if norm > TAYLOR_RADIUS:
        squarings = max(0, math.frexp(norm / TAYLOR_RADIUS)[1])  # 2^s >= norm / radius
    scale = math.ldexp(1.0, -squarings)
    X = [[value * scale for value in row] for row in M]
    theta = norm * scale
    # least m with theta^(m+1) / (m+1)! * exp(theta) <= tolerance * exp(-theta)
    degree, remainder = 0, math.exp(2.0 * theta)
    while degree < 30:
        degree += 1
        remainder *= theta / degree
        if remainder * theta / (degree + 1) <= TAYLOR_TOLERANCE:
            break
    # Horner: E = I + X/1 (I + X/2 (I + ... (I + X/m)))
    E = [[X[i][j] / degree + (1.0 if i == j else 0.0) for j in range(n)] for i in range(n)]
    for k in range(degree - 1, 0, -1):
        E = _matmul(X, E)
        E = [[E[i][j] / k + (1.0 if i == j else 0.0) for j in range(n)] for i in range(n)]
    for _ in range(squarings):
        E = _matmul(E, E)
    return E


class LinearSystem:
    """G(s) = b(s) / a(s) driven by an input held constant over each step.

    ``b`` = (b0, ..., bn) and ``a`` = (a1, ..., an): the denominator's leading
    coefficient is 1 and is not given, so the order is n = len(a), 1..8, and
    b has n + 1 coefficients (b0 = 0 for a strictly proper G). The state
    starts at zero and at t = 0.
    """

    def __init__(self, b, a):
        a, b = list(a), list(b)
        n = len(a)
        check("order", n, lambda: 1 <= n <= MAX_ORDER,
              f"the order (the number of denominator coefficients a1..an) must be an integer in 1..{MAX_ORDER}")
        check("number of numerator coefficients", len(b), len(b) == n + 1,
              f"an order-{n} G(s) needs {n + 1} numerator coefficients b0..b{n}")
        for i, value in enumerate(a, start=1):
            check(f"a{i}", value, True, f"a{i} must be a finite number")
        for i, value in enumerate(b):
            check(f"b{i}", value, True, f"b{i} must be a finite number")
        self.order = n
        self.b = tuple(float(value) for value in b)
        self.a = tuple(float(value) for value in a)
        b0 = self.b[0]
        self.D = b0
        # C x = sum_i c_i x_i, x_i the (i-1)-th derivative: c_i = b_(n+1-i) - b0 a_(n+1-i)
        self.C = tuple(self.b[n + 1 - i] - b0 * self.a[n - i] for i in range(1, n + 1))
        self.t = 0.0
        self.x = [0.0] * n
        self.u = 0.0
        self._transitions = {}

    # -- matrices -------------------------------------------------------------
    def matrices(self):
        """(A, B, C, D) of the controllable canonical form, as lists."""
        n = self.order
        A = [[1.0 if j == i + 1 else 0.0 for j in range(n)] for i in range(n - 1)]
        A.append([-self.a[n - 1 - j] for j in range(n)])
        B = [0.0] * (n - 1) + [1.0]
        return A, B, list(self.C), self.D

    def transition(self, h):
        """(Phi, Gamma) for a step of length h: x(t + h) = Phi x(t) + Gamma u."""
        cached = self._transitions.get(h)
        if cached is not None:
            return cached
        n = self.order
        A, B, _C, _D = self.matrices()
        augmented = [[value * h for value in row] + [B[i] * h] for i, row in enumerate(A)]
        augmented.append([0.0] * (n + 1))
        E = expm(augmented)
        pair = (tuple(tuple(row[:n]) for row in E[:n]), tuple(row[n] for row in E[:n]))
        if len(self._transitions) >= CACHE_SIZE:
            del self._transitions[next(iter(self._transitions))]  # the oldest
        self._transitions[h] = pair
        return pair

    # -- stepping -------------------------------------------------------------
    def set_input(self, u):
        """Set the input, held constant until the next change."""
        check("u", u, True, "the input u must be a finite number")
        self.u = float(u)

    def advance(self, t_end):
        """Integrate exactly from self.t to t_end with the input held."""
        check_step_end(t_end, self.t)
        h = t_end - self.t
        if h > 0.0:
            Phi, Gamma = self.transition(h)
            x, u = self.x, self.u
            self.x = [sum(p * xj for p, xj in zip(row, x)) + g * u for row, g in zip(Phi, Gamma)]
        self.t = t_end

    def output(self, u=None):
        """y = C x + D u at self.t, with the held input (or the given u)."""
        u = self.u if u is None else u
        return sum(c * xi for c, xi in zip(self.C, self.x)) + self.D * u
