"""The true limit cycles of the exact closed loop: periodic orbits by shooting, and their Floquet multipliers.

The loop (plant + controller, :mod:`dfwb.fmus.loops`) is integrated exactly,
so its periodic orbits can be computed to rounding. The Poincare section is
the plant output y rising through a level c (the middle of its swing); the
first-return map P takes a state on the section (the output's coordinate
fixed at c, the others free) to the next upward crossing. A limit cycle is a
fixed point of P, found by Newton's method (damped, on coordinates scaled by
the orbit's swing) to a residual of 1e-10 relative; Newton does not care
whether the cycle is stable, so unstable cycles are found too. The Jacobian
of P comes from finite differences of the exact map (central at the end);
its eigenvalues are the cycle's Floquet multipliers with the trivial one
(along the flow) removed by the section: stable when all lie inside the unit
circle. Stick phases and plastic impacts collapse directions, so some
multipliers are 0.

Starts: the describing function's own prediction (the plant's periodic
orbit under the predicted F cos(wt), with the controller in its harmonic
steady state; see :meth:`LoopProblem.df_start`), simulations from small and
large amplitudes that are run until their section crossings settle
(:meth:`LoopProblem.settle`), and a known cycle continued in the
controller's gain (:func:`follow_gain`). :func:`find_cycles` collects every
distinct cycle and links each to the prediction it corresponds to.

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> problem = LoopProblem("backlash", "200*(s+2)/(s+20)", {"eps": 0.2})
>>> cycle = problem.shoot(problem.rest_start(0.03))
>>> round(cycle.omega, 6), round(cycle.amplitude_x, 7), cycle.stable
(7.92883, 0.028911, True)
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.errors import InputError
from dfwb.engine.transfer import check_transfer_function
from dfwb.fmus.exact import PlantError
from dfwb.fmus.hybrid import MAX_CHUNKS_PER_STEP, Budget
from dfwb.plants import plant as find_plant

RESIDUAL_TOL = 1e-10  # |P(X) - X| / swing, at convergence
MAX_NEWTON = 40
FD_STEP = 1e-7  # relative to each coordinate's swing (forward differences during Newton)
FD_STEP_FINAL = 1e-5  # central differences for the multipliers
HARMONICS = 10
GAUSS_NODES = 16
MAX_RETURN_PERIODS = 20.0  # a return to the section later than this many periods: none
SETTLE_RTOL = 1e-3  # successive section crossings this close (scaled): settled enough to shoot
SAME_CYCLE = 1e-6  # two cycles with w and X this close (relative) are one
LINK_FACTOR = 2.0  # a prediction and a true cycle within this factor in w and X may be linked
MAX_CHUNKS = 2_000_000  # a problem's work (under a minute): the examples' loops need 2e4 to 2e5


def _coefficients(G):
    """(b, a) of a proper G(s), the denominator made monic: b = [b0..bn], a = [a1..an]."""
    num = np.trim_zeros(np.atleast_1d(np.asarray(G.num[0][0], dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(G.den[0][0], dtype=float)), "f")
    order = len(den) - 1
    num = np.concatenate([np.zeros(order + 1 - len(num)), num]) / den[0]
    return [float(v) for v in num], [float(v) for v in den[1:] / den[0]]


@dataclass
class TrueCycle:
    """A periodic orbit of the exact closed loop.

    Attributes
    ----------
    omega, period : float
        Its angular frequency [rad/s] and period [s].
    amplitude_x : float
        |first harmonic| of the plant output y.
    F : float
        |first harmonic| of the force into the plant.
    stable : bool
        All Floquet multipliers (the trivial one removed) inside the unit circle.
    multipliers : list of float
        Their moduli, largest first.
    residual : float
        |P(X) - X| relative to the orbit's swing, at the solution.
    iterations : int
        Newton iterations.
    state : list of float
        The loop state where the output rises through ``level`` (on the section).
    level : float
        The section's output level (the middle of the swing).
    harmonics : list of float
        |Y_k| of the output, k = 0..10 (k = 0: the mean).
    counts : dict
        Per period: events, and the plant's counter (stick phases, impacts, engagements).
    prediction : int or None
        The DF prediction this cycle corresponds to (index), or None: the DF missed it.
    started_from : list of str
        The starts that reached it (a prediction shot or settled, a rest start).
    trace : dict
        One period sampled at the quadrature nodes: ``t``, ``y``, ``f`` and the ``events``.
    """

    omega: float
    period: float
    amplitude_x: float
    F: float
    stable: bool
    multipliers: list
    residual: float
    iterations: int
    state: list
    level: float
    harmonics: list
    counts: dict
    prediction: object = None
    started_from: list = field(default_factory=list)
    trace: dict = field(default=None, repr=False)  # one period: times, outputs, forces, events (plots)

    def as_dict(self):
        return {"omega": self.omega, "period": self.period, "amplitude_x": self.amplitude_x, "F": self.F,
                "stable": self.stable, "multipliers": self.multipliers, "residual": self.residual,
                "iterations": self.iterations, "harmonics": self.harmonics, "counts": self.counts,
                "state": self.state, "level": self.level, "prediction": self.prediction,
                "started_from": self.started_from}


def _loop_class(spec, fmu_dir):
    """The plant's exact loop class: the compiled core's twin where it can be used, else the Python one."""
    from dfwb.fmi.location import native_core

    core = native_core(fmu_dir)
    return spec.loop if core is None else getattr(core, spec.loop.__name__)


class LoopProblem:
    """A plant in feedback with G(s), f = -G(s) y: the exact loop's solvers, its return map and its cycles.

    Parameters
    ----------
    plant : str
        A registered plant with an exact loop (``friction``, ``backlash``, ``static-backlash``).
    G : str or control.TransferFunction
        The controller (negative feedback), proper, order 1..8.
    params : dict, optional
        Plant parameters (initial-value parameters are ignored: starts are states).
    max_chunks : int, optional
        The work the problem may do, in Taylor chunks of the exact loop over
        all its runs (about 10 to 30 us each in Python, well under 1 us in
        C); beyond, PlantError. An integer from 1 to 10,000,000 (what one
        step of the loop may integrate).
    fmu_dir : str or Path, optional
        Where the compiled core is built (the FMU folder's ``native/``): the
        loop runs in C, bit for bit the Python loop's numbers, 15 to 160 times
        faster per event; with ``DFWB_FMU=python`` (``--fmu python``), or where
        the core cannot be built, the Python loop (``dfwb.fmus.loops``) runs.
    """

    def __init__(self, plant, G, params=None, max_chunks=MAX_CHUNKS, fmu_dir=None):
        spec = find_plant(plant)
        if spec.loop is None:
            raise InputError(f"plant {spec.name!r} has no exact closed loop (--exact): it is available for "
                             "friction, backlash and static-backlash")
        if isinstance(G, str):
            from dfwb.engine.transfer import parse_transfer_function

            G = parse_transfer_function(G)
        self.G = check_transfer_function(G)
        self.spec, self.cls, self.fmu_dir = spec, _loop_class(spec, fmu_dir), fmu_dir
        self.b, self.a = _coefficients(self.G)
        checked = spec.check(dict(params or {}))
        self.params = {k: v for k, v in checked.items() if k not in self.cls.initial_parameters}
        self.output = self.cls.OUTPUT
        self._modes = {}  # section level -> the modes its solvers share (built once, not per period)
        whole = isinstance(max_chunks, int) and not isinstance(max_chunks, bool)
        if not (whole and 1 <= max_chunks <= MAX_CHUNKS_PER_STEP):
            raise InputError(f"max_chunks = {max_chunks!r} is out of range: an integer from 1 to {MAX_CHUNKS_PER_STEP}")
        self.budget = Budget(max_chunks)  # every solver of this problem draws on it: the study's work is bounded
        self.solver(None)  # refuses the controller (order, coefficients) and the parameters now

    # -- solvers ----------------------------------------------------------------------
    def solver(self, state, level=None):
        """A loop solver from ``state`` (None: the plant's default start), watching y rise through ``level``."""
        try:
            return self._make(state, level)
        except PlantError as error:
            raise InputError(str(error)) from None

    def _make(self, state, level):
        level = None if level is None else float(level)
        state = None if state is None else [float(x) for x in state]  # numpy scalars would slow the solver
        modes = self._modes.setdefault(level, {})
        return self.cls(self.b, self.a, **self.params, state=state, section=level, modes=modes, budget=self.budget)

    def rest_start(self, position):
        """The state with the plant displaced by ``position`` (its output coordinate), all else at rest."""
        solver = self.solver(None)
        m = len(solver.coordinates)
        return solver.translate([0.0] * m, position) + [0.0] * solver.order

    def first_return(self, X, level, max_time, min_time=None):
        """(state, time) at the first upward crossing of y through ``level`` from X in [min_time, max_time], or None.

        ``min_time`` (half the period, once it is known; by default 1e-12 of
        max_time) passes over a crossing that merely grazes the level at the
        start. None too where X is not a state of the loop (a perturbation
        beyond a play's edge).
        """
        if min_time is None:
            min_time = 1e-12 * max_time
        try:
            solver = self._make(X, level)
        except PlantError:
            return None
        while solver.t < max_time:
            solver.advance(max_time, stop_at_section=True)
            if solver.crossings and solver.crossings[-1][0] >= min_time:
                t, Y = solver.crossings[-1]
                return list(Y), t
        return None

    # -- shooting ---------------------------------------------------------------------------
    def _reduced(self, X):
        return [x for i, x in enumerate(X) if i != self.output]

    def _full(self, u, level):
        X = list(u)
        X.insert(self.output, level)
        return X

    def _swing(self, X, level, period):
        """Each coordinate's swing over one orbit from X (sampled), floored: the Newton scales."""
        solver = self.solver(X)
        samples = [X]
        for t in np.linspace(0.0, period, 65)[1:]:
            solver.advance(float(t))
            samples.append(solver.state())
        samples = np.array(samples)
        swing = samples.max(axis=0) - samples.min(axis=0)
        size = np.abs(samples).max(axis=0)
        floor = 1e-9 * max(float(size.max()), 1e-300)
        return np.maximum(np.maximum(swing, 1e-6 * size), floor)

    def shoot(self, X, level=None, period=None, tol=RESIDUAL_TOL, max_iterations=MAX_NEWTON):
        """The periodic orbit near the loop state X, or None when Newton does not converge.

        X need not lie on the section: the first upward crossing of ``level``
        (default: the middle of the output's swing over the first orbit) is the
        starting point. ``period``: a guess that bounds the return time.
        """
        horizon = MAX_RETURN_PERIODS * (period or 1.0)
        if level is None:  # the transient's middle, then the middle of the orbit it reaches
            level = self.level(X, period)
            first = level is not None and self.first_return(X, level, horizon if period else 1e3)
            if not first:
                return None
            back = self.first_return(first[0], level, horizon if period else 1e3)
            level = back and self.level(back[0], back[1])
            if level is None:
                return None
            X = back[0]
        first = self.first_return(X, level, horizon if period else 1e3)
        if first is None:
            return None
        X, _t = first
        back = self.first_return(X, level, horizon if period else 1e3)
        if back is None:
            return None
        period = back[1]
        horizon = MAX_RETURN_PERIODS * period
        scale = self._swing(X, level, period)[[i for i in range(len(X)) if i != self.output]]

        def residual(u):
            result = self.first_return(self._full(u * scale, level), level, horizon, 0.5 * period)
            if result is None:
                return None, None
            Y, T = result
            return np.array(self._reduced(Y)) / scale - u, T

        u = np.array(self._reduced(X)) / scale
        r, T = residual(u)
        if r is None:
            return None
        J = None
        for iteration in range(1, max_iterations + 1):
            if np.abs(r).max() <= tol:
                if J is not None:  # one more chord step (the last Jacobian, one period) polishes to rounding
                    polished, T_polished = residual(u + np.linalg.solve(J, -r))
                    if polished is not None and np.abs(polished).max() < np.abs(r).max():
                        u, r, T = u + np.linalg.solve(J, -r), polished, T_polished
                return self._finish(u * scale, level, T, scale, np.abs(r).max(), iteration - 1)
            J = self._jacobian(residual, u, r, FD_STEP)
            if J is None:
                return None
            try:
                step = np.linalg.solve(J, -r)
            except np.linalg.LinAlgError:
                return None
            damping = 1.0
            while damping > 1e-4:
                trial = u + damping * step
                r_trial, T_trial = residual(trial)
                if r_trial is not None and np.abs(r_trial).max() < np.abs(r).max():
                    break
                damping *= 0.5
            else:
                return None
            u, r, T = trial, r_trial, T_trial
        return None

    @staticmethod
    def _jacobian(residual, u, r, step, central=False):
        """d(residual)/du by differences of the exact map (None where a perturbed orbit does not return).

        Forward differences (central with ``central``); one-sided where one side is not a state of the loop.
        """
        centre = r if r is not None else residual(u)[0]
        columns = []
        for j in range(len(u)):
            du = np.zeros(len(u))
            du[j] = step
            ahead = residual(u + du)[0]
            behind = residual(u - du)[0] if central or ahead is None else None
            if ahead is not None and behind is not None:
                columns.append((ahead - behind) / (2.0 * step))
            elif ahead is not None or behind is not None:  # one side only (the other leaves the state space)
                columns.append((ahead - centre) / step if ahead is not None else (centre - behind) / step)
            else:
                return None
        return np.array(columns).T

    def _finish(self, X_reduced, level, T, scale, res, iterations):
        X = self._full(list(X_reduced), level)
        u = np.array(X_reduced) / scale

        def residual(v):
            result = self.first_return(self._full(v * scale, level), level, MAX_RETURN_PERIODS * T, 0.5 * T)
            if result is None:
                return None, None
            return np.array(self._reduced(result[0])) / scale - v, result[1]

        J = self._jacobian(residual, u, None, FD_STEP_FINAL, central=True)
        if J is None:
            J = self._jacobian(residual, u, residual(u)[0], FD_STEP)
        if J is None:
            multipliers = [math.nan]
        else:
            monodromy = J + np.eye(len(u))  # d P / d u
            multipliers = sorted((float(abs(m)) for m in np.linalg.eigvals(monodromy)), reverse=True)
        harmonics, F, counts, trace = self.period_trace(X, T, level)
        if np.ptp(trace["y"]) <= 1e-12 * max(np.abs(trace["y"]).max(), 1e-300):
            return None  # the output does not move: rest, not a cycle
        omega = 2.0 * math.pi / T
        return TrueCycle(omega=omega, period=T, amplitude_x=harmonics[1], F=F,
                         stable=bool(multipliers and all(m < 1.0 for m in multipliers)),
                         multipliers=multipliers, residual=float(res), iterations=iterations, state=X, level=level,
                         harmonics=harmonics, counts=counts, trace=trace)

    def level(self, X, period=None, samples=64):
        """The middle of the output's swing over [0, period] (default: up to 4 returns found by sampling)."""
        solver = self.solver(X)
        span = period or 10.0
        values = []
        for t in np.linspace(0.0, span, samples + 1)[1:]:
            solver.advance(float(t))
            values.append(solver.state()[self.output])
        lo, hi = min(values), max(values)
        return 0.5 * (lo + hi) if hi > lo else None

    # -- one period, exactly --------------------------------------------------------------------
    def period_trace(self, X, T, level=None):
        """(|Y_k| for k = 0..10, |F_1|, counts per period, trace) over one period from X.

        The integrals are Gauss-Legendre sums on the smooth pieces between
        events, each cut to a few chunks of the fastest mode (where the motion
        is analytic), so they are exact to rounding. ``trace`` holds the nodes'
        times, outputs and forces (for plots).
        """
        probe = self.solver(X, level)
        probe.event_log = []
        before = dict(probe.counts())
        probe.advance(T)
        counts = {key: value - before.get(key, 0) for key, value in probe.counts().items()}
        counts["events"] = probe.events
        h = min(mode.h for mode in probe._modes.values())
        width = min(T / 32.0, 2.0 * h)
        breaks = sorted({0.0, T, *(t for t, _kind in probe.event_log if 0.0 < t < T)})
        nodes, weights = np.polynomial.legendre.leggauss(GAUSS_NODES)
        times, wsum = [], []
        for a, b in zip(breaks[:-1], breaks[1:]):
            pieces = max(1, math.ceil((b - a) / width))
            edges = np.linspace(a, b, pieces + 1)
            for lo, hi in zip(edges[:-1], edges[1:]):
                half = 0.5 * (hi - lo)
                times.extend(lo + half * (nodes + 1.0))
                wsum.extend(half * weights)
        solver = self.solver(X, level)
        ys, fs = [], []
        for t in times:
            solver.advance(float(t))
            state = solver.state()
            ys.append(state[self.output])
            fs.append(solver.force(state))
        times, wsum, ys, fs = map(np.array, (times, wsum, ys, fs))
        omega = 2.0 * math.pi / T
        harmonics = []
        for k in range(HARMONICS + 1):
            value = np.sum(wsum * ys * np.exp(-1j * k * omega * times)) * (1.0 if k == 0 else 2.0) / T
            harmonics.append(float(abs(value)))
        F = float(abs(np.sum(wsum * fs * np.exp(-1j * omega * times)) * 2.0 / T))
        return harmonics, F, counts, {"t": times, "y": ys, "f": fs, "events": probe.event_log}

    # -- starts ------------------------------------------------------------------------------------
    def df_start(self, prediction, periods=60):
        """A loop state on the DF's predicted cycle: (state, period, level), or None.

        The plant's own periodic orbit under the predicted F cos(wt) (centred:
        the open-loop orbit drifts), where its output rises through its mean,
        with the controller in its harmonic steady state driven by that orbit.
        """
        F, omega = prediction.F, prediction.omega
        T = 2.0 * math.pi / omega
        plant = self.cls.plant(**{k: v for k, v in self.params.items()}, F=F, omega=omega, harmonics=HARMONICS)
        plant.advance(periods * T)
        start = plant.integrals()
        plant.advance((periods + 1) * T)
        end = plant.integrals()
        Y = [(e - s) * (1.0 if k == 0 else 2.0) / T for k, (s, e) in enumerate(zip(start, end))]
        mean = Y[0].real
        # the first sample after the output rises through its mean
        grid = np.linspace(0.0, T, 257)[1:]
        output = self.spec.output  # a field of the open-loop solver's output() (named as the FMU's)
        before = getattr(plant.output(), output) - mean
        t_start = None
        for t in grid:
            plant.advance((periods + 1) * T + float(t))
            value = getattr(plant.output(), output) - mean
            if before < 0.0 <= value:
                t_start = plant.t
                break
            before = value
        if t_start is None:
            return None
        # the open-loop orbit drifts (a mass under F cos(wt) from rest); the DF's cycle is centred
        q = self.solver(None).translate(self.cls.coordinates_of(plant.output()), -mean)
        z = self._controller_state(Y, 0.0, omega, t_start)
        return q + z, T, 0.0

    def _controller_state(self, Y, mean, omega, t):
        """z(t) of the controller driven by y = mean + Re sum_k Y_k exp(jkwt) in its periodic steady state."""
        from dfwb.fmus.linear_system import LinearSystem

        Ac, Bc, C, D = (np.array(m, dtype=float) for m in LinearSystem(self.b, self.a).matrices())
        n = len(Ac)
        z = np.zeros(n)
        for k in range(1, len(Y)):
            try:
                z += (np.linalg.solve(1j * k * omega * np.eye(n) - Ac, Bc) * Y[k] * np.exp(1j * k * omega * t)).real
            except np.linalg.LinAlgError:
                continue
        # the mean: Ac z + Bc mean = 0 with a zero mean force C z + D mean = 0 (least squares: integrators)
        stacked = np.vstack([Ac, C[None, :]])
        rhs = -np.concatenate([Bc * mean, [D * mean]])
        z += np.linalg.lstsq(stacked, rhs, rcond=None)[0]
        return [float(v) for v in z]

    def settle(self, X, period, max_periods=200, level=None):
        """Simulate from X until its section crossings settle: (a state on the orbit, the middle of its swing) or None.

        None: the loop comes to rest or leaves every bound (no crossing in
        MAX_RETURN_PERIODS periods, or none that settles in max_periods).
        """
        if level is None:
            level = self.level(X, 4.0 * period)
            if level is None:
                return None
        solver = self.solver(X, level)
        previous, scale = None, None
        for _ in range(max_periods):
            solver.advance(solver.t + MAX_RETURN_PERIODS * period, stop_at_section=True)
            if not solver.crossings or (previous is not None and solver.crossings[-1][1] is previous):
                return None
            state = np.array(solver.crossings[-1][1])
            if scale is None:
                scale = np.maximum(np.abs(state), 1e-12 * max(np.abs(state).max(), 1e-300))
            if previous is not None and np.abs((state - np.array(previous)) / scale).max() <= SETTLE_RTOL:
                returned = solver.crossings[-1][0] - solver.crossings[-2][0]
                middle = self.level(list(state), returned)  # centre the section on the settled orbit
                return list(state), (level if middle is None else middle)
            if not np.all(np.isfinite(state)) or np.abs(state / scale).max() > 1e8:
                return None
            previous = solver.crossings[-1][1]
        return None


def find_cycles(problem, predictions=(), amplitudes=None, settle_periods=200, progress=None):
    """Every distinct true cycle reached from the DF predictions and from simulations; each linked to a prediction.

    Starts: each prediction's DF state, shot directly (finds unstable cycles)
    and simulated until it settles; and simulations from the plant displaced
    by ``amplitudes`` (default: 0.3 times the smallest and 3 times the largest
    predicted amplitude; without predictions 0.01, 0.1 and 1).

    Returns (cycles, links): the cycles sorted by amplitude, and for each
    prediction the index of its cycle or None (a false alarm).
    """
    cycles = []
    period_guess = 2.0 * math.pi / min((p.omega for p in predictions), default=1.0)

    def add(cycle, origin):
        if cycle is None:
            return
        for known in cycles:
            if (abs(known.omega - cycle.omega) <= SAME_CYCLE * known.omega
                    and abs(known.amplitude_x - cycle.amplitude_x) <= SAME_CYCLE * max(known.amplitude_x, 1e-300)):
                known.started_from.append(origin)
                return
        cycle.started_from.append(origin)
        cycles.append(cycle)

    starts = []
    for i, prediction in enumerate(predictions):
        start = problem.df_start(prediction)
        if start is not None:
            starts.append((f"prediction {i}", start))
    if amplitudes is None:
        sizes = [p.amplitude_x for p in predictions]
        amplitudes = [0.3 * min(sizes), 3.0 * max(sizes)] if sizes else [0.01, 0.1, 1.0]
    for amplitude in amplitudes:
        starts.append((f"rest at {amplitude:g}", (problem.rest_start(amplitude), period_guess, None)))
    for origin, (X, period, level) in starts:
        if progress:
            progress(origin)
        if origin.startswith("prediction"):
            add(problem.shoot(X, level, period), origin + " (shot)")
        settled = problem.settle(X, period, settle_periods, level)
        if settled is not None:
            add(problem.shoot(settled[0], settled[1], period), origin + " (settled)")
    cycles.sort(key=lambda c: c.amplitude_x)
    links = link(predictions, cycles)
    for i, j in enumerate(links):
        if j is not None:
            cycles[j].prediction = i
    return cycles, links


def follow_gain(problem, cycle, gains):
    """The cycle continued in the controller's gain: [(k, the cycle of k G or None)] for each k in ``gains``.

    Each gain's loop is shot from the previous gain's cycle (natural
    parameter continuation), so a branch is followed whether it is stable or
    not, up to where it ends (a fold, or a cycle that stops engaging): there,
    and beyond, None. The gains are taken in the order given; start next to 1
    for the first step to begin on ``cycle``.
    """
    branch, previous = [], cycle
    for k in gains:
        if previous is None:
            branch.append((k, None))
            continue
        scaled = LoopProblem(problem.spec.name, k * problem.G, problem.params, problem.budget.total, problem.fmu_dir)
        previous = scaled.shoot(previous.state, previous.level, previous.period)
        branch.append((k, previous))
    return branch


def link(predictions, cycles):
    """For each prediction the index of its nearest true cycle (within LINK_FACTOR in w and X, each used once)."""
    pairs = []
    for i, p in enumerate(predictions):
        for j, c in enumerate(cycles):
            distance = max(abs(math.log(c.omega / p.omega)), abs(math.log(c.amplitude_x / p.amplitude_x)))
            if distance <= math.log(LINK_FACTOR):
                pairs.append((distance, i, j))
    links, taken = [None] * len(predictions), set()
    for _distance, i, j in sorted(pairs):
        if links[i] is None and j not in taken:
            links[i] = j
            taken.add(j)
    return links


def relative_errors(prediction, cycle):
    """The DF's relative errors against the true cycle: omega, amplitude_x, F."""
    return {"omega": (prediction.omega - cycle.omega) / cycle.omega,
            "amplitude_x": (prediction.amplitude_x - cycle.amplitude_x) / cycle.amplitude_x,
            "F": (prediction.F - cycle.F) / cycle.F}


def report(predictions, cycles, links):
    """The JSON entries: each prediction's dict with ``true_cycle`` and ``error``, and the cycles' dicts."""
    entries = []
    for prediction, j in zip(predictions, links):
        entry = prediction.as_dict()
        entry["true_cycle"] = j
        entry["error"] = None if j is None else relative_errors(prediction, cycles[j])
        entries.append(entry)
    return entries, [cycle.as_dict() for cycle in cycles]
