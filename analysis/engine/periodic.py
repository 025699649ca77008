"""The true limit cycles of the exact closed loop: periodic orbits by shooting on an event section, and their
Floquet multipliers.

The loop (plant + controller, :mod:`dfwb.fmus.loops`) is integrated exactly,
so its periodic orbits can be computed to rounding. The Poincare section is
made of the plant's own events, which every periodic orbit must have
whatever its period: for the friction mass, a velocity reaching zero at a
minimum of x and then at a maximum (the start of a stick phase or a
reversal); for the two-mass backlash, an impact at the gap's lower wall and
then at its upper wall; for the static backlash, an engagement at the lower
edge of the play and then at the upper one (``FeedbackLoop.SECTION``). A
point of the section is the state the last such event leaves; one of its
coordinates (``PIVOT``: v = 0, gap = h, x at the upper edge) is fixed by
the others, which are the section's coordinates u.

The return map P takes u to the section's next hit; an orbit that hits the
section ``returns`` times per period is a fixed point of P^returns, found by
Newton's method (damped, on coordinates scaled by the orbit's swing) to a
residual of 1e-10 relative. Newton does not care whether the cycle is
stable, so unstable cycles are found too. The Jacobian of P comes from
finite differences of the exact map (central at the end); its eigenvalues
are the cycle's Floquet multipliers with the trivial one (along the flow)
removed by the section: stable when all lie inside the unit circle. Stick
phases and plastic impacts collapse directions, so some multipliers are 0.

A return is waited for at most ``horizon`` seconds (the loop's own scales,
:mod:`dfwb.engine.scales`): longer, and the motion has come to rest.
Finding every cycle (starts, coverage) is :mod:`dfwb.engine.cycles`;
following them in a parameter is :mod:`dfwb.engine.continuation`.

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> problem = LoopProblem("backlash", "200*(s+2)/(s+20)", {"eps": 0.2})
>>> cycle = problem.shoot(problem.rest_start(0.03))
>>> round(cycle.omega, 6), round(cycle.amplitude_x, 7), cycle.stable, cycle.returns
(7.92883, 0.028911, True, 1)
"""

import copy
import functools
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from dfwb.base.defaults import HARMONICS
from dfwb.base.errors import InputError
from dfwb.engine.transfer import check_transfer_function
from dfwb.fmus.compensation import dither_of, follows_control
from dfwb.fmus.exact import PlantError
from dfwb.fmus.hybrid import MAX_CHUNKS_PER_STEP, Budget
from dfwb.plants import plant as find_plant

RESIDUAL_TOL = 1e-10  # |P(X) - X| / swing, at convergence
MAX_NEWTON = 40
FD_STEP = 1e-7  # relative to each coordinate's swing (forward differences during Newton)
FD_STEP_FINAL = 1e-5  # central differences for the multipliers
GAUSS_NODES = 16
QUIET = 0.25  # a wait for the section without a hit is rest unless the output turns in this last part of it
QUIET_SAMPLES = 8  # ... read at this many instants (a turn: changes of both signs, each beyond STILL)
STILL = 1e-9  # of the loop's length scale: an output that moves less is still (a rest chattering at rounding)
MAX_CHUNKS = 10_000_000  # a problem's work (seconds in C): a search of a slow hunting loop needs 1e5 to 2e6


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
        |first harmonic| of the force into the plant [N].
    stable : bool
        All Floquet multipliers (the trivial one removed) inside the unit circle.
    multipliers : list of float
        Their moduli, largest first.
    residual : float
        |P^returns(u) - u| relative to the orbit's swing, at the solution.
    iterations : int
        Newton iterations.
    state : list of float
        The loop state on the section (just after the section's event).
    returns : int
        Hits of the section per period.
    harmonics : list of float
        |Y_k| of the output, k = 0..10 (k = 0: the mean).
    counts : dict
        Per period: events, and the plant's counter (stick phases, impacts, engagements).
    signature : list of str
        The event kinds of one period in order, from the section: what changes at a
        discontinuity-induced bifurcation (a stick phase or an impact appearing or vanishing).
    spectrum : list of [float, float]
        The multipliers as (re, im) pairs, largest modulus first.
    sections : list of list of float
        The ``returns`` states where the orbit hits the section, ``state`` first.
    swing : list of float
        Each coordinate's swing over the orbit (the Newton scales).
    prediction : int or None
        The DF prediction this cycle corresponds to (index), or None: the DF missed it.
    started_from : list of str
        The starts that reached it.
    df : str
        Why no describing function can represent it ("" when one can): its first-harmonic
        force lies where a sine leaves the plant still (N = 0).
    errors : dict
        Where the cycle comes from a co-simulated loop refined and extrapolated (a user's co-simulation
        FMU): the estimated absolute errors of ``period``, ``amplitude_x`` and ``F``, and the finest
        ``steps_per_period``; empty for an exact cycle.
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
    returns: int
    harmonics: list
    counts: dict
    signature: list
    spectrum: list
    sections: list
    swing: list
    prediction: object = None
    started_from: list = field(default_factory=list)
    df: str = ""
    errors: dict = field(default_factory=dict)  # estimated errors where the cycle is extrapolated (co-simulation)
    trace: dict = field(default=None, repr=False)  # one period: times, outputs, forces, events (plots)
    section: int = 0  # the loop's section it is shot on: 0 its SECTION, 1 its ALTERNATE

    def as_dict(self):
        """Every field but the trace (JSON types; ``TrueCycle(**as_dict())`` rebuilds it)."""
        return {name: getattr(self, name) for name in self.__dataclass_fields__ if name != "trace"}


def trace_arrays(trace):
    """A true cycle's trace from its JSON form (lists): arrays of t, y and f, and (time, kind) events."""
    return {"t": np.array(trace["t"]), "y": np.array(trace["y"]), "f": np.array(trace["f"]),
            "events": [tuple(e) for e in trace["events"]]}


def same_events(a, b):
    """Whether two returns (time, events fired) fire as many events: the map is smooth between them."""
    return a[1] == b[1]


def jacobian(residual, u, base, step, central=False, same_kind=same_events, scale=None):
    """d(residual)/du by differences of an exact map, or None where a perturbed orbit does not return.

    ``residual(u)`` gives (r, info) or (None, None); ``base`` is its value at u. Forward differences
    (central with ``central``), each side taken only where ``same_kind(info, base's info)`` (by default: its
    orbit fires as many events): next to a switching (a stick phase about to vanish, an impact about to
    graze) the difference stays on the base's side, where the map is smooth. A side that leaves the state
    space is not used. ``scale``: coordinate j is moved by ``step * scale[j]`` (the columns are then
    d/d(u_j / scale_j)).
    """
    r0, info0 = base
    if r0 is None:
        return None
    columns = []
    for j in range(len(u)):
        du = np.zeros(len(u))
        du[j] = step if scale is None else step * scale[j]
        ahead, ahead_info = residual(u + du)
        good_ahead = ahead is not None and same_kind(ahead_info, info0)
        behind, behind_info = residual(u - du) if central or not good_ahead else (None, None)
        good_behind = behind is not None and same_kind(behind_info, info0)
        if central and good_ahead and good_behind:
            columns.append((ahead - behind) / (2.0 * step))
        elif good_ahead or (ahead is not None and not good_behind):
            columns.append((ahead - r0) / step)
        elif behind is not None:
            columns.append((r0 - behind) / step)
        else:
            return None
    return np.array(columns).T


def newton_step(residual, u, r, info):
    """One damped Newton step on ``residual`` (as :func:`jacobian` takes it) from u, where it is (r, info): (u, r,
    info, the Jacobian) after it, or None where the Jacobian or the step fails or no halving of the step (down to
    1e-4 of it) lowers the largest residual."""
    J = jacobian(residual, u, (r, info), FD_STEP)
    if J is None:
        return None
    try:
        step = np.linalg.solve(J, -r)
    except np.linalg.LinAlgError:
        return None
    damping = 1.0
    while damping > 1e-4:
        trial = u + damping * step
        r_trial, info_trial = residual(trial)
        if r_trial is not None and np.abs(r_trial).max() < np.abs(r).max():
            return trial, r_trial, info_trial, J
        damping *= 0.5
    return None


@functools.lru_cache(maxsize=4)
def _gauss(n):
    """Gauss-Legendre nodes and weights on [-1, 1]."""
    return np.polynomial.legendre.leggauss(n)


def _loop_class(spec, fmu_dir):
    """The plant's exact loop class: the compiled core's twin where it can be used, else the Python one."""
    from dfwb.fmi.location import native_core

    core = native_core(fmu_dir)
    return spec.loop if core is None else getattr(core, spec.loop.__name__)


def _turns(values, still):
    """Whether ``values`` rise and fall (changes of both signs, each larger than ``still``)."""
    changes = [b - a for a, b in zip(values, values[1:]) if abs(b - a) > still]
    return any(c > 0.0 for c in changes) and any(c < 0.0 for c in changes)


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
        faster per event; with ``DFWB_FMU=python`` (``--fmu-kind python``), or where
        the core cannot be built, the Python loop (``dfwb.fmus.loops``) runs.
    budget : dfwb.fmus.hybrid.Budget, optional
        A budget shared with other problems (a continuation's), instead of one of ``max_chunks``.
    compensation : compensator or list of them, optional
        ``Coulomb``, ``Reset``, ``Deadband``, ``Dither``, ``BacklashInverse`` of :mod:`dfwb.fmus.compensation`,
        between the controller and the plant. The compiled core runs them, bit for bit, but for the Coulomb
        feedforward of the controller's sign: with it, the Python loop runs. With a dither the loop is forced
        (``dither``): its truth is :mod:`dfwb.engine.dither`'s.
    """

    def __init__(self, plant, G, params=None, max_chunks=MAX_CHUNKS, fmu_dir=None, budget=None, compensation=None):
        spec = find_plant(plant)
        if spec.loop is None:
            raise InputError(f"plant {spec.name!r} has no exact closed loop (--exact): it is available for "
                             "friction, backlash and static-backlash")
        if isinstance(G, str):
            from dfwb.engine.transfer import parse_transfer_function

            G = parse_transfer_function(G)
        self.G = check_transfer_function(G)
        self.spec, self.fmu_dir, self.compensation = spec, fmu_dir, compensation
        # the compiled core runs every compensator but the feedforward of the controller's sign
        self.cls = spec.loop if follows_control(compensation) else _loop_class(spec, fmu_dir)
        self.dither = dither_of(compensation)  # the loop is then forced: its responses are dfwb.engine.dither's
        self.b, self.a = _coefficients(self.G)
        checked = spec.check(dict(params or {}))
        self.params = {k: v for k, v in checked.items() if k not in self.cls.initial_parameters}
        self.output = self.cls.OUTPUT
        self.legs = tuple(frozenset(leg) for leg in self.cls.SECTION)
        self.pivot = self.cls.PIVOT
        self.section = 0  # SECTION; 1: ALTERNATE (alternate())
        self._modes = {}  # the modes every solver of this problem shares (built once, not per run)
        if budget is None:
            whole = isinstance(max_chunks, int) and not isinstance(max_chunks, bool)
            if not (whole and 1 <= max_chunks <= MAX_CHUNKS_PER_STEP):
                raise InputError(f"max_chunks = {max_chunks!r} is out of range: an integer from 1 to "
                                 f"{MAX_CHUNKS_PER_STEP}")
            budget = Budget(max_chunks)
        self.budget = budget  # every solver of this problem draws on it: the study's work is bounded
        self.probe = self.solver(None)  # refuses the controller (order, coefficients) and the parameters now

    @cached_property
    def scales(self):
        """The loop's scales (:func:`dfwb.engine.scales.loop_scales`)."""
        from dfwb.engine.scales import loop_scales

        return loop_scales(self)

    @cached_property
    def horizon(self):
        """The default longest wait between two section hits [s]: for motions from the smallest default start."""
        return self.scales.horizon(self.scales.amplitudes()[0])

    # -- solvers ----------------------------------------------------------------------
    def solver(self, state):
        """A loop solver from ``state`` (None: the plant's default start); InputError for a state it refuses."""
        try:
            return self._make(state)
        except PlantError as error:
            raise InputError(str(error)) from None

    def _make(self, state):
        state = None if state is None else [float(x) for x in state]  # numpy scalars would slow the solver
        more = {} if self.compensation is None else {"compensation": self.compensation}
        return self.cls(self.b, self.a, **self.params, state=state, modes=self._modes, budget=self.budget, **more)

    def exhausted(self):
        """Whether the problem's budget of work is spent (every later run would be refused)."""
        return self.budget.left < 0

    def rest_start(self, position):
        """The state with the plant displaced by ``position`` (its output coordinate), all else at rest."""
        m = len(self.probe.coordinates)
        return self.probe.translate([0.0] * m, position) + [0.0] * self.probe.order

    # -- the section ------------------------------------------------------------------------
    def hit(self, solver, horizon):
        """Advance ``solver`` to its next hit of the section within ``horizon`` s: True, or False (none in time)."""
        return self.wait(solver, horizon) == "hit"

    def wait(self, solver, horizon):
        """Advance ``solver`` to its next hit of the section within ``horizon`` s: ``"hit"``; else ``"moving"``
        where, in the last :data:`QUIET` of the wait, events fired and the output turned (a motion that never
        crosses the section, as an oscillation by impacts alone: no wait turns it into rest), ``"rest"``
        otherwise (at rest, or creeping one way towards it, stick after stick)."""
        deadline = solver.t + horizon
        quiet_from = deadline - QUIET * horizon
        for leg in self.legs:
            if solver.t < quiet_from:
                solver.advance(quiet_from, stop_at=leg)
                if solver.stopped is not None:
                    continue
            events, outputs = solver.events, [solver.output()]
            for i in range(1, QUIET_SAMPLES + 1):
                solver.advance(max(solver.t, quiet_from + (deadline - quiet_from) * i / QUIET_SAMPLES), stop_at=leg)
                if solver.stopped is not None:
                    break
                outputs.append(solver.output())
            else:
                moved = solver.events > events and _turns(outputs, STILL * self.scales.length)
                return "moving" if moved else "rest"
        return "hit"

    def alternate(self):
        """The same problem on the loop's second section (``ALTERNATE``: for motions that never cross the first,
        as a hunt of the drivetrain by impacts alone), sharing its modes and budget; None without one."""
        if self.section or self.cls.ALTERNATE is None:
            return None
        other = copy.copy(self)
        legs, other.pivot = self.cls.ALTERNATE
        other.legs, other.section = tuple(frozenset(leg) for leg in legs), 1
        return other

    def reduced(self, X):
        """The section's coordinates u of a state on it (the pivot left out)."""
        return [x for i, x in enumerate(X) if i != self.pivot]

    def on_section(self, u):
        """The state on the section with coordinates u."""
        X = list(u)
        X.insert(self.pivot, 0.0)
        X[self.pivot] = self.probe.alternate_pivot(X) if self.section else self.probe.pivot(X)
        return X

    def first_return(self, X, returns=1, horizon=None):
        """(state, time, events fired) at the ``returns``-th hit of the section from X, or None.

        None too where X is not a state of the loop (a perturbation beyond a
        play's edge) or a run is refused (it leaves floating point); a spent
        budget is raised.
        """
        horizon = self.horizon if horizon is None else horizon
        try:
            solver = self._make(X)
            for _ in range(returns):
                if not self.hit(solver, horizon):
                    return None
        except PlantError:
            if self.exhausted():
                raise
            return None
        return solver.state(), solver.t, solver.events

    # -- shooting ---------------------------------------------------------------------------
    def _swing(self, X, period):
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

    def shoot(self, X, returns=1, horizon=None, on_section=False, tol=RESIDUAL_TOL, max_iterations=MAX_NEWTON):
        """The periodic orbit near the loop state X that hits the section ``returns`` times, or None.

        X need not lie on the section (unless ``on_section``): its first hit
        is the starting point. None when Newton does not converge or a return
        takes longer than ``horizon`` s (default: :attr:`horizon`).
        """
        horizon = self.horizon if horizon is None else horizon
        fixed = self.converge(X, returns, horizon, on_section, tol, max_iterations)
        return None if fixed is None else self.finish(*fixed[:2], returns, horizon, *fixed[2:])

    def converge(self, X, returns=1, horizon=None, on_section=False, tol=RESIDUAL_TOL, max_iterations=MAX_NEWTON):
        """Newton's method on P^returns from X: (section state, period, residual, iterations), or None (see shoot)."""
        horizon = self.horizon if horizon is None else horizon
        if not on_section:
            first = self.first_return(X, 1, horizon)
            if first is None:
                return None
            X = first[0]
        scaled = self._scaled_at(X, returns, horizon)
        if scaled is None:
            return None
        scale, residual, u = scaled
        r, T = residual(u)
        if r is None:
            return None
        J = None
        for iteration in range(1, max_iterations + 1):
            if np.abs(r).max() <= tol:
                if J is not None:  # one more chord step (the last Jacobian, one period) polishes to rounding
                    step = np.linalg.solve(J, -r)
                    polished, T_polished = residual(u + step)
                    if polished is not None and np.abs(polished).max() < np.abs(r).max():
                        u, r, T = u + step, polished, T_polished
                return self.on_section(u * scale), T[0], float(np.abs(r).max()), iteration - 1
            stepped = newton_step(residual, u, r, T)
            if stepped is None:
                return None
            u, r, T, J = stepped
        return None

    def _scaled_at(self, X, returns, horizon):
        """(scale, scaled map, u) around the section state X: the scale the orbit's swing; None where X does not
        return."""
        back = self.first_return(X, returns, horizon)
        if back is None:
            return None
        scale = self._swing(X, back[1])[[i for i in range(len(X)) if i != self.pivot]]
        return scale, self.scaled_map(scale, returns, horizon), np.array(self.reduced(X)) / scale

    def scaled_map(self, scale, returns, horizon):
        """u -> (P^returns(u) - u, (return time, events fired)) in coordinates scaled by ``scale``; (None, None)
        where the orbit does not return."""
        def residual(u):
            result = self.first_return(self.on_section(u * scale), returns, horizon)
            if result is None:
                return None, None
            return np.array(self.reduced(result[0])) / scale - u, result[1:]

        return residual

    def monodromy(self, X, returns, horizon=None, step=FD_STEP_FINAL):
        """d P^returns / du at the section state X (central differences), or None."""
        horizon = self.horizon if horizon is None else horizon
        scaled = self._scaled_at(X, returns, horizon)
        if scaled is None:
            return None
        _scale, residual, u = scaled
        base = residual(u)
        J = jacobian(residual, u, base, step, central=True)
        if J is None:
            J = jacobian(residual, u, base, FD_STEP)
        return None if J is None else J + np.eye(len(u))

    def finish(self, X, T, returns=1, horizon=None, residual=0.0, iterations=0, monodromy=None):
        """The :class:`TrueCycle` through the section state X (a fixed point of P^returns, return time T).

        ``monodromy``: d P^returns / du if known (a continuation's corrector has it), else by central
        differences. None where the output does not move (rest, not a cycle).
        """
        horizon = self.horizon if horizon is None else horizon
        M = self.monodromy(X, returns, horizon) if monodromy is None else monodromy
        if M is None:
            spectrum = []
        else:
            spectrum = sorted((complex(m) for m in np.linalg.eigvals(M)), key=abs, reverse=True)
        multipliers = [float(abs(m)) for m in spectrum] or [math.nan]
        harmonics, F, counts, trace = self.period_trace(X, T)
        if np.ptp(trace["y"]) <= 1e-12 * max(np.abs(trace["y"]).max(), 1e-300):
            return None  # the output does not move: rest, not a cycle
        sections, solver = [list(X)], self._make(X)
        for _ in range(returns - 1):
            self.hit(solver, horizon)
            sections.append(solver.state())
        return TrueCycle(omega=2.0 * math.pi / T, period=T, amplitude_x=harmonics[1], F=F,
                         stable=bool(spectrum) and all(m < 1.0 for m in multipliers), multipliers=multipliers,
                         residual=float(residual), iterations=iterations, state=list(X), returns=returns,
                         harmonics=harmonics, counts=counts, signature=[str(k) for _t, k in trace["events"]],
                         spectrum=[[m.real, m.imag] for m in spectrum], sections=sections,
                         swing=[float(v) for v in self._swing(X, T)], df=self.df_note(F, 2.0 * math.pi / T),
                         trace=trace, section=self.section)

    def df_note(self, F, omega):
        """Why no describing function represents a cycle of first-harmonic force F at omega ("" if one can; a
        compensated loop has no DF to speak of)."""
        if self.compensation is not None or not self.probe.still(F, omega):
            return ""
        kind, size = self.probe.nonlinearity()
        what = (f"the threshold {size:.6g} N" if kind == "force" and F < size  # (a play's stillness is no threshold)
                else "the size at which the plant's output moves")
        return (f"its first-harmonic force {F:.6g} N lies below {what}: there a sine leaves the plant still and "
                "N(F, w) = 0, so no describing-function prediction can represent this cycle")

    # -- one period, exactly --------------------------------------------------------------------
    def period_trace(self, X, T):
        """(|Y_k| for k = 0..10, |F_1|, counts per period, trace) over one period from X.

        The integrals are Gauss-Legendre sums on the smooth pieces between
        events, each cut to a few chunks of the fastest mode (where the motion
        is analytic), so they are exact to rounding. ``trace`` holds the nodes'
        times, outputs and forces and the period's events (for plots).
        """
        probe = self._make(X)
        probe.event_log = []
        before = dict(probe.counts())
        probe.advance(T)
        counts = {key: value - before.get(key, 0) for key, value in probe.counts().items()}
        counts["events"] = len(probe.event_log)
        breaks = sorted({0.0, T, *(t for t, _kind in probe.event_log if 0.0 < t < T)})
        walker = self._make(X)  # each piece is cut to its own mode's chunks (a stick phase is one long piece)
        widths = []
        for a in breaks[:-1]:
            walker.advance(a)
            widths.append(min(T / 32.0, 2.0 * walker.mode(walker.key).h))
        nodes, weights = _gauss(GAUSS_NODES)
        edges = np.concatenate([np.linspace(a, b, max(1, math.ceil((b - a) / width)) + 1)[:-1]
                                for a, b, width in zip(breaks[:-1], breaks[1:], widths)] + [[T]])
        half = 0.5 * np.diff(edges)
        times = (edges[:-1, None] + half[:, None] * (nodes + 1.0)).ravel()
        wsum = (half[:, None] * weights).ravel()
        m = len(self.probe.coordinates)
        if self.compensation is None:
            states = np.array(self._make(X).sample(times))
            fs = self.probe.D * states[:, self.output] + states[:, m:] @ np.array(self.probe.C)  # f = D y + C z
        else:  # the force on the plant, the compensators' included (a backlash inverse's correction, a dither)
            states, forces = self._make(X).readings(times)
            states, fs = np.array(states), np.array(forces)
        ys = states[:, self.output]
        omega = 2.0 * math.pi / T
        harmonics = []
        for k in range(HARMONICS + 1):
            value = np.sum(wsum * ys * np.exp(-1j * k * omega * times)) * (1.0 if k == 0 else 2.0) / T
            harmonics.append(float(abs(value)))
        F = float(abs(np.sum(wsum * fs * np.exp(-1j * omega * times)) * 2.0 / T))
        return harmonics, F, counts, {"t": times, "y": ys, "f": fs, "events": probe.event_log}

    # -- a start from a DF prediction ----------------------------------------------------------------
    def df_start(self, prediction, periods=60):
        """A loop state on the DF's predicted cycle: (state, period), or None.

        The plant's own periodic orbit under the predicted F cos(wt) (centred:
        the open-loop orbit drifts), where its output rises through its mean,
        with the controller in its harmonic steady state driven by that orbit.
        """
        F, omega = prediction.F, prediction.omega
        T = 2.0 * math.pi / omega
        plant = self.cls.plant(**dict(self.params), F=F, omega=omega, harmonics=HARMONICS)
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
        q = self.probe.translate(self.cls.coordinates_of(plant.output()), -mean)
        z = self._controller_state(Y, 0.0, omega, t_start)
        return q + z, T

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
