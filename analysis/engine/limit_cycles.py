"""Limit cycles of a plant FMU under a controller G(s): G(jw) N(F, w) = -1.

The plant's DF depends on both the force amplitude F and the frequency w,
so the harmonic balance is two real equations in two unknowns,
``R(F, w) = 1 + G(jw) N(F, w) = 0`` (python-control's amplitude-only
``describing_function_response`` cannot solve it). A coarse map of R over
an F x w grid locates candidate cells (both Re R and Im R change sign);
each is refined by damped Newton steps in (ln F, ln w) on the plant's exact
DF to 1e-8 or better. Stability follows Loeb's criterion, valid for a DF that
depends on w: with R = U + jV, the cycle is stable when
``dU/dF dV/dw - dU/dw dV/dF > 0`` (a small increase of the amplitude must
move the loop back inside).

Examples
--------
>>> import control as ct
>>> from dfwb.engine.limit_cycles import predict
>>> lead = ct.tf([20.0, 40.0], [1.0, 20.0])  # 20 (s + 2) / (s + 20) around mass + backlash
>>> cycles = predict("static-backlash", lead, F_range=(0.01, 100), omega_range=(0.1, 50))
>>> [(round(c.F, 6), round(c.omega, 6), c.stable) for c in cycles]
[(0.248573, 0.913732, True)]
"""

import math
from dataclasses import dataclass

import numpy as np

from dfwb.base.defaults import DF_MAP_SIZE
from dfwb.engine.describing import F_RANGE, OMEGA_RANGE, DFEngine
from dfwb.engine.transfer import check_transfer_function
from dfwb.fmus.piecewise import PlantError

NEWTON_TOL = 1e-10  # on the steps in ln F and ln w
NOISE_MAX = 1e-4  # |R| (1 + G N, of order 1) below which an engine's error estimate may end Newton
ROUGH_TOL = 1e-4  # ... of the first Newton on an engine's looser twin: the precise one then needs a step or two
DIFF_STEP = 1e-6  # relative step of the finite-difference Jacobian


@dataclass
class Cycle:
    """A predicted limit cycle: the force amplitude F at the plant input, and w."""

    F: float
    omega: float
    N: complex
    amplitude_x: float  # |N| F: the plant output's first-harmonic amplitude
    distortion: float  # sqrt(sum_{k>=2} |X_k|^2) / |X_1|: how far to trust the prediction
    stable: bool
    loeb: float  # dU/dF dV/dw - dU/dw dV/dF at the cycle (> 0: stable)
    residual: float  # |1 + G(jw) N(F, w)| at the cycle
    periodic: bool  # whether the plant's response at (F, w) is periodic

    @property
    def period(self):
        return 2 * math.pi / self.omega

    def as_dict(self):
        return {"F": self.F, "omega": self.omega, "amplitude_x": self.amplitude_x, "period": self.period,
                "N_re": self.N.real, "N_im": self.N.imag, "stable": self.stable, "loeb": self.loeb,
                "distortion": self.distortion, "residual": self.residual, "periodic": self.periodic}


def check_range(name, values, limits):
    """(lo, hi) as floats, refused unless limits[0] <= lo < hi <= limits[1] (the engine's range)."""
    lo, hi = values
    if not (limits[0] <= lo < hi <= limits[1]):
        raise PlantError(f"{name} = [{lo!r}, {hi!r}] is not a range the engine accepts: "
                         f"{limits[0]:g} <= LO < HI <= {limits[1]:g}")
    return float(lo), float(hi)


class _Balance:
    """R(ln F, ln w) = 1 + G(jw) N(F, w) through the plant's exact DF."""

    def __init__(self, engine, G, params, tol=NEWTON_TOL):
        self.engine, self.G, self.params, self.tol = engine, G, params, tol
        self.evaluations = 0
        rtol = getattr(engine, "rtol", None)  # an engine with an accuracy (a user's FMU's): differences above it
        self.step = DIFF_STEP if rtol is None else max(DIFF_STEP, math.sqrt(rtol))

    def noise(self, result):
        """How much of |R| the DF's own error estimate may explain: 0 for the exact engine, and for a point
        that is not periodic or whose estimate is too large to say that R is near 0 at all."""
        error = getattr(result, "N_error", None)
        if error is None or not math.isfinite(error) or not result.periodic:
            return 0.0
        noise = 2.0 * abs(complex(self.G(1j * result.omega))) * error
        return noise if noise < NOISE_MAX else 0.0

    def point(self, u, v):
        self.evaluations += 1
        return self.engine.point(math.exp(u), math.exp(v), self.params)

    def residual(self, result):
        return 1.0 + complex(self.G(1j * result.omega)) * result.N

    def jacobian(self, u, v, R):
        """d(Re R, Im R)/d(ln F, ln w) by forward differences (the two points at once on an engine that can)."""
        pairs = [(math.exp(u + du), math.exp(v + dv)) for du, dv in ((self.step, 0.0), (0.0, self.step))]
        many = getattr(self.engine, "points", None)
        results = many(pairs, self.params) if many is not None else \
            [self.engine.point(F, w, self.params) for F, w in pairs]
        self.evaluations += len(pairs)
        columns = []
        for result in results:
            d = (self.residual(result) - R) / self.step
            columns.append((d.real, d.imag))
        return np.array(columns).T

    def newton(self, u, v, bounds, max_iterations=40, jacobian=True):
        """Refined (u, v, result, R, J) or None when it leaves the range or does not converge: steps below
        ``tol``, or |R| within what the DF's error estimate explains (an engine that is not exact).

        A differenced J serves every step taken within one differencing step of where it was made (the
        last steps of a refinement: a chord; it differs from the J there by no more than the differences'
        own error), and is made afresh farther away or where a damped step with it fails. J at the answer
        decides stability (Loeb); ``jacobian=False``: not wanted (None), as for a start refined again."""
        result = self.point(u, v)
        R = self.residual(result)
        J = at = None
        for _ in range(max_iterations):
            if abs(R) <= self.noise(result):  # as close as the DF's accuracy can tell
                return u, v, result, R, self._answer(u, v, R, J, at, jacobian)
            if J is None or self._far(u, v, at):
                J, at = self.jacobian(u, v, R), (u, v)
            try:
                step = np.linalg.solve(J, [-R.real, -R.imag])
            except np.linalg.LinAlgError:
                return None
            scale = 1.0
            while scale >= 1e-3:  # damped: the first step that reduces |R| (at most 10 halvings)
                nu, nv = u + scale * step[0], v + scale * step[1]
                if bounds[0] <= nu <= bounds[1] and bounds[2] <= nv <= bounds[3]:
                    trial = self.point(nu, nv)
                    trial_R = self.residual(trial)
                    if abs(trial_R) < abs(R):
                        break
                scale *= 0.5
            if scale < 1e-3:  # no step: with a J made here, none at all; with an older one, make it here
                if at == (u, v):
                    return None
                J = None
                continue
            u, v, result, R = nu, nv, trial, trial_R
            if max(abs(scale * step[0]), abs(scale * step[1])) < self.tol:
                return u, v, result, R, self._answer(u, v, R, J, at, jacobian)
        return None

    def _far(self, u, v, at):
        return max(abs(u - at[0]), abs(v - at[1])) > self.step

    def _answer(self, u, v, R, J, at, wanted):
        """J at the answer (u, v): None if not ``wanted``; the last one if made within one differencing step
        from here, else differenced afresh."""
        if not wanted:
            return None
        return J if J is not None and not self._far(u, v, at) else self.jacobian(u, v, R)


def df_map(engine, params, F_grid, omega_grid, progress=None):
    """N on the grid: an array [len(F_grid), len(omega_grid)] of complex; ``progress(done, total)`` per row."""
    N = np.empty((len(F_grid), len(omega_grid)), dtype=complex)
    many = getattr(engine, "points", None)  # an engine that spreads a row over workers (a user's FMU's)
    for i in range(len(F_grid)):
        if many is not None:
            N[i] = [result.N for result in many([(F_grid[i], w) for w in omega_grid], params)]
            if progress:
                progress((i + 1) * len(omega_grid), N.size)
            continue
        for j in range(len(omega_grid)):
            N[i, j] = engine.point(F_grid[i], omega_grid[j], params).N
        if progress:
            progress((i + 1) * len(omega_grid), N.size)
    return N


def candidates(R):
    """Grid cells (i, j) where both Re R and Im R change sign among the four corners."""
    cells = []
    for i in range(R.shape[0] - 1):
        for j in range(R.shape[1] - 1):
            corners = R[i:i + 2, j:j + 2]
            if corners.real.min() < 0 < corners.real.max() and corners.imag.min() < 0 < corners.imag.max():
                cells.append((i, j))
    return cells


@dataclass
class Search:
    """What :func:`search` found: the limit cycles, and the DF map they were found on.

    Attributes
    ----------
    cycles : list of Cycle
        Sorted by F; empty when there is none in the ranges (a valid answer).
    F_grid : ndarray
        The map's force amplitudes [N], geometrically spaced.
    omega_grid : ndarray
        The map's frequencies [rad/s], geometrically spaced.
    N_grid : ndarray of complex
        N(F_grid[i], omega_grid[j]) [m/N], shape ``(len(F_grid), len(omega_grid))``.
    """

    cycles: list
    F_grid: np.ndarray
    omega_grid: np.ndarray
    N_grid: np.ndarray


def predict(plant, G, params=None, F_range=(1.0, 100.0), omega_range=(0.1, 100.0), n_F=DF_MAP_SIZE[0],
            n_omega=DF_MAP_SIZE[1],
            engine=None, progress=None):
    """Every limit cycle of ``plant`` under the controller ``G`` in the given ranges.

    See :func:`search`, which also returns the DF map."""
    return search(plant, G, params, F_range, omega_range, n_F, n_omega, engine, progress).cycles


def search(plant, G, params=None, F_range=(1.0, 100.0), omega_range=(0.1, 100.0), n_F=DF_MAP_SIZE[0],
           n_omega=DF_MAP_SIZE[1],
           engine=None, progress=None):
    """The limit cycles and the DF map they were found on.

    Parameters
    ----------
    plant : {"friction", "backlash", "static-backlash"}
    G : control.TransferFunction or control.StateSpace
        Maps the plant output (position) to the plant input force, with negative
        feedback: force = -G(s) position.
    params : dict, optional
        Plant parameters.
    F_range, omega_range : (float, float)
        Search ranges of the force amplitude [N] and the frequency [rad/s].

    n_F, n_omega : int
        The DF map's size (2 to 1000 each).
    engine : DFEngine, optional
        The engine to use (default: a new one of ``plant``). One with a ``coarse()`` method (a
        user's FMU's, :class:`dfwb.foreign.engine.FMUEngine`) computes the map on that looser
        engine and refines on itself; one with a ``domain(F_range, omega_range, params)`` method (the
        dither's, :class:`dfwb.engine.dither_df.DitherDFEngine`) maps the ranges it gives.
    progress : callable, optional
        ``progress(done, total)`` as the map's points are computed.

    Returns
    -------
    Search
        ``.cycles``: list of Cycle, sorted by F (empty when there is none: a valid answer);
        ``.F_grid``, ``.omega_grid``, ``.N_grid``: the map.
    """
    G = check_transfer_function(G)
    F_lo, F_hi = check_range("F range", F_range, F_RANGE)
    w_lo, w_hi = check_range("omega range", omega_range, OMEGA_RANGE)
    if not (2 <= n_F <= 1000 and 2 <= n_omega <= 1000):
        raise PlantError(f"a DF map of {n_F} x {n_omega} points: each side must have 2 to 1000")
    engine = engine or DFEngine(plant)
    params = engine.plant.check(params or {})
    domain = getattr(engine, "domain", None)  # an engine with ranges of its own (the dither's DF)
    if domain is not None:
        ranges = domain((F_lo, F_hi), (w_lo, w_hi), params)
        if ranges is None:
            return Search([], np.geomspace(F_lo, F_hi, n_F), np.zeros(0), np.zeros((n_F, 0), complex))
        (F_lo, F_hi), (w_lo, w_hi) = ranges
    F_grid, omega_grid = np.geomspace(F_lo, F_hi, n_F), np.geomspace(w_lo, w_hi, n_omega)
    coarse = getattr(engine, "coarse", None)  # an engine whose points cost: the map only locates, looser
    N_grid = df_map(coarse() if coarse is not None else engine, params, F_grid, omega_grid, progress)
    return balance(engine, G, params, F_grid, omega_grid, N_grid)


def balance(engine, G, params, F_grid, omega_grid, N_grid):
    """The limit cycles of G on a DF map already computed (one map serves every controller of a plant):
    candidates where both parts of 1 + G N change sign, refined by Newton on the exact DF (first on the
    engine's looser twin, when it has one: a user's FMU's points cost, and Newton's early steps need
    no precision)."""
    R = 1.0 + np.array([complex(G(1j * w)) for w in omega_grid]) * N_grid
    balance = _Balance(engine, G, params)
    coarse = getattr(engine, "coarse", None)
    rough = _Balance(coarse(), G, params, tol=ROUGH_TOL) if coarse is not None else None
    bounds = (math.log(F_grid[0]), math.log(F_grid[-1]), math.log(omega_grid[0]), math.log(omega_grid[-1]))
    cycles = []
    for i, j in candidates(R):
        u = 0.5 * (math.log(F_grid[i]) + math.log(F_grid[i + 1]))
        v = 0.5 * (math.log(omega_grid[j]) + math.log(omega_grid[j + 1]))
        first = rough.newton(u, v, bounds, jacobian=False) if rough is not None else None
        if first is not None:
            u, v = first[0], first[1]
            if any(abs(u - math.log(c.F)) < ROUGH_TOL * 10 and abs(v - math.log(c.omega)) < ROUGH_TOL * 10
                   for c in cycles):
                continue  # another cell's cycle, refined already
        refined = balance.newton(u, v, bounds)
        if refined is None:
            continue
        u, v, result, residual, J = refined
        if any(abs(u - math.log(c.F)) < 1e-6 and abs(v - math.log(c.omega)) < 1e-6 for c in cycles):
            continue
        X = result.harmonics
        loeb = float(J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0])  # same sign in (ln F, ln w) as in (F, w)
        cycles.append(Cycle(F=result.F, omega=result.omega, N=result.N, amplitude_x=result.amplitude_x,
                            distortion=math.sqrt(sum(x * x for x in X[2:])) / X[1] if X[1] else math.inf,
                            stable=loeb > 0, loeb=loeb, residual=abs(residual), periodic=result.periodic))
    return Search(sorted(cycles, key=lambda c: c.F), F_grid, omega_grid, N_grid)
