"""A dithered loop's responses: the fixed points of its stroboscopic map, and the hunting that is none.

A dither ``a sin(w_d t)`` (:class:`~dfwb.fmus.compensation.Dither`) forces
the loop periodically, so it has no limit cycle of its own to find on an
event section: its periodic responses have periods ``p T_d`` (T_d = 2 pi /
w_d), and they are the fixed points of the *stroboscopic map* P, the loop's
state (plant and controller) taken from one instant of phase 0 of the dither
to the next, and of its powers P^p. The exact loop integrates the dither as
an oscillator, so P is exact, and its fixed points are found by Newton's
method to rounding, their stability by the eigenvalues of dP^p (finite
differences of the exact map, central at the end).

A run from each start (:func:`dfwb.engine.cycles.starts`) samples P, dither
period by dither period, until one of these fates:

- ``rest``: no event of the plant for the loop's horizon (a mass stuck that
  the dither no longer breaks away), as an undithered search decides it;
- ``dithered``: the samples converge to a stable fixed point of P, the
  dither's own response: the mass moves at the dither's frequency only (its
  residual oscillation, a cost) and does not hunt;
- ``cycle``: the samples repeat every p = 2..P_MAX periods and Newton finds
  the fixed point of P^p: a hunting cycle locked to the dither (a
  :class:`~dfwb.engine.periodic.TrueCycle` of period p T_d);
- ``hunting``: the samples' output swings through its target for
  SLOW_CYCLES slow cycles without decaying (the latest half of them at least
  DECAY of the earlier half), and never repeats within P_MAX periods: the
  loop hunts, not locked to the dither (quasi-periodic, or locked beyond
  P_MAX of its periods: no periodic orbit is reported; the swing and its
  mean period are measured);
- ``diverged``, ``failed`` as in :mod:`dfwb.engine.cycles`; and
  ``unsettled`` after MAX_PERIODS periods (or RUN_HORIZONS horizons) without
  one of those.

So a setting *hunts* when a run locks on a stable cycle or hunts unlocked;
*no cycle* needs every run at rest or on the dither's response (an unsettled
run leaves the search incomplete, never "no cycle").

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> from dfwb.fmus.compensation import Dither
>>> found = find_responses(LoopProblem("friction", "10 + 2/s", compensation=Dither(10.0, 5.0)),
...                        amplitudes=[0.7])
>>> found.coverage.outcomes, round(found.responses[0].amplitude_x, 4)
({'dithered': 4}, 0.4026)
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.errors import InputError
from dfwb.engine.cycles import DIVERGED, Coverage, CycleSearch, Fate, link, refused, starts, tally
from dfwb.engine.periodic import FD_STEP, FD_STEP_FINAL, MAX_NEWTON, RESIDUAL_TOL, TrueCycle, jacobian, newton_step
from dfwb.fmus.exact import PlantError

__all__ = ["DitherSearch", "find_responses", "check_dither", "OUTCOMES", "P_MAX", "MAX_PERIODS", "RUN_HORIZONS",
           "SLOW_CYCLES", "DECAY"]

OUTCOMES = ("cycle", "hunting", "dithered", "rest", "diverged", "unsettled", "failed")
P_MAX = 8  # a run recognises samples that repeat every 1..P_MAX dither periods
MAX_PERIODS = 1_000_000  # dither periods a run may take, at most (the budget bounds them too), ...
RUN_HORIZONS = 8  # ... and at most this many of the loop's horizons
NEAR = 3e-2  # samples p apart this close (relative to the window's size): Newton is tried on P^p
JOIN = 1e-2  # a run this close to a stable fixed point (relative): it has reached it
SAME = 1e-6  # two fixed points this close (relative) are one
SLOW_CYCLES = 12  # slow swings of the samples' output through the target that make a run "hunting" ...
DECAY = 0.95  # ... when the latest half of them are at least this part of the earlier half


@dataclass
class DitherSearch(CycleSearch):
    """The answer of :func:`find_responses`: a :class:`~dfwb.engine.cycles.CycleSearch` whose ``cycles`` are the
    hunting cycles locked to the dither (period p T_d, p >= 2), with ``responses``: the dither's own responses
    (fixed points of P, period T_d; ``amplitude_x`` their residual oscillation, ``harmonics[0]`` their mean)."""

    responses: list = field(default_factory=list)

    def hunting(self):
        """The runs that hunt, not locked to the dither (their Fates; ``detail`` has the swing measured)."""
        return [f for f in self.fates if f.outcome == "hunting"]


class _Runs:
    """The runs of one search: the fixed points found so far (each a TrueCycle, by p) and the fates."""

    def __init__(self, problem, horizon, max_periods, divergence):
        self.problem, self.horizon, self.max_periods, self.divergence = problem, horizon, max_periods, divergence
        self.T = 2.0 * math.pi / problem.dither.w_d
        self.found = []  # TrueCycles, any p (p = returns)
        self.fates = []

    # -- the stroboscopic map ---------------------------------------------------------------
    def _map(self, scale, p):
        """u -> (P^p(u) - u, (None, events fired)) in coordinates scaled by ``scale``; (None, None) where the loop
        refuses the state."""
        problem = self.problem

        def residual(u):
            try:
                solver = problem._make(list(u * scale))
                solver.advance(p * self.T)
            except PlantError:
                if problem.exhausted():
                    raise
                return None, None
            return np.array(solver.state()) / scale - u, (None, solver.events)

        return residual

    def newton(self, X, p, scale):
        """(the fixed point of P^p near X, residual, iterations, dP^p), or None."""
        residual = self._map(scale, p)
        u = np.array(X) / scale
        r, info = residual(u)
        if r is None:
            return None
        for iteration in range(MAX_NEWTON + 1):
            if np.abs(r).max() <= RESIDUAL_TOL:
                base = (r, info)
                M = jacobian(residual, u, base, FD_STEP_FINAL, central=True)
                M = jacobian(residual, u, base, FD_STEP) if M is None else M
                if M is None:
                    return None
                M = M + np.eye(len(u))  # dP^p in scaled coordinates: its eigenvalues are the multipliers
                return u * scale, float(np.abs(r).max()), iteration, M
            stepped = None if iteration == MAX_NEWTON else newton_step(residual, u, r, info)
            if stepped is None:
                return None
            u, r, info, _J = stepped
        return None

    def fixed_point(self, X, p, scale, origin):
        """The index among ``found`` of the fixed point of P^p Newton finds from X (added if new), or None (none,
        or one where the output does not move: a rest)."""
        solved = self.newton(X, p, scale)
        if solved is None:
            return None
        Xs, residual, iterations, M = solved
        problem, T = self.problem, p * self.T
        sections, solver = [[float(x) for x in Xs]], problem._make(list(Xs))
        for i in range(1, p):  # its other samples: a run may reach it at any of them
            solver.advance(i * self.T)
            sections.append(solver.state())
            if p % i == 0 and np.abs((np.array(sections[-1]) - Xs) / scale).max() <= SAME:
                return self.fixed_point(Xs, i, scale, origin)  # a fixed point of P^i: of the lower period
        harmonics, F, counts, trace = problem.period_trace(list(Xs), T)
        if np.ptp(trace["y"]) <= 1e-12 * max(np.abs(trace["y"]).max(), 1e-300):
            return None  # the output does not move: rest
        for j, known in enumerate(self.found):  # found before, from any of its samples (a symmetric partner,
            # -y half a dither period later, has the same amplitude but other samples: another orbit)
            if known.returns == p and _distance(known, Xs, scale) <= SAME:
                if origin not in known.started_from:
                    known.started_from.append(origin)
                return j
        spectrum = sorted((complex(m) for m in np.linalg.eigvals(M)), key=abs, reverse=True)
        multipliers = [float(abs(m)) for m in spectrum]
        swing = problem._swing(list(Xs), T)
        self.found.append(TrueCycle(
            omega=2.0 * math.pi / T, period=T, amplitude_x=harmonics[1], F=F,
            stable=all(m < 1.0 for m in multipliers), multipliers=multipliers, residual=residual,
            iterations=iterations, state=[float(x) for x in Xs], returns=p, harmonics=harmonics, counts=counts,
            signature=[str(k) for _t, k in trace["events"]], spectrum=[[m.real, m.imag] for m in spectrum],
            sections=sections, swing=[float(v) for v in swing], started_from=[origin],
            trace=trace))
        return len(self.found) - 1

    # -- one run ----------------------------------------------------------------------------
    def run(self, start):
        fate = self._run(start.state, start.label)
        fate.start = start.label
        self.fates.append(fate)
        return fate

    def _run(self, X0, label):
        problem, out, T = self.problem, self.problem.output, self.T
        try:
            solver = problem._make(X0)
        except PlantError as error:
            return Fate(label, "failed", detail=str(error))
        samples, tried = [np.array(solver.state())], {}
        events, quiet_since = solver.events, 0.0
        swings = _Swings()
        for k in range(1, self.max_periods + 1):
            try:
                solver.advance(k * T)
            except PlantError as error:
                return refused(problem, solver, label, k - 1, error)
            X = np.array(solver.state())
            if not abs(X[out]) <= self.divergence:
                return Fate(label, "diverged", hits=k, time=solver.t, detail=f"the output reached {X[out]:.3g}")
            if solver.events != events:
                events, quiet_since = solver.events, solver.t
            elif solver.t - quiet_since >= self.horizon:
                return Fate(label, "rest", hits=k, time=solver.t,
                            detail=f"no event of the plant for {self.horizon:.4g} s")
            samples.append(X)
            del samples[:-2 * P_MAX - 1]
            hunting = swings.add(solver.t, X[out])
            if hunting:
                return Fate(label, "hunting", hits=k, time=solver.t, detail=hunting)
            window = np.array(samples)
            scale = np.abs(window).max(axis=0)
            scale = np.maximum(scale, 1e-6 * scale.max() + 1e-300)
            for j, cycle in enumerate(self.found):  # a stable fixed point reached (at any of its p phases)
                if cycle.stable and _distance(cycle, X, scale) <= JOIN:
                    return self._reached(label, j, k, solver.t)
            # each earlier sample's distance from X: distances[p - 1] is p periods back
            distances = np.abs((window[-2::-1] - X) / scale).max(axis=1)
            for p, distance in enumerate(distances[:P_MAX].tolist(), start=1):
                if distance > NEAR:
                    continue
                if p not in tried or distance < 0.1 * tried[p]:
                    tried[p] = distance
                    j = self.fixed_point(X, p, scale, label)
                    if j is not None and self.found[j].stable and _distance(self.found[j], X, scale) <= JOIN:
                        return self._reached(label, j, k, solver.t)
                break
        return Fate(label, "unsettled", hits=self.max_periods, time=solver.t,
                    detail=f"neither at rest, on a periodic response nor hunting in {self.max_periods} dither periods")

    def _reached(self, label, j, k, t):
        return Fate(label, "dithered" if self.found[j].returns == 1 else "cycle", j, k, t)


def _distance(cycle, X, scale):
    """How far X is from the nearest of a fixed point's p samples (relative to ``scale``)."""
    return min(float(np.abs((X - np.array(S)) / scale).max()) for S in cycle.sections)


class _Swings:
    """The slow swings of the stroboscopic samples' output through the target (0): their sizes and times, and
    whether they show hunting (SLOW_CYCLES of them, the later half not decaying below DECAY of the earlier)."""

    def __init__(self):
        self.last, self.low, self.high, self.ups, self.sizes = None, math.inf, -math.inf, [], []

    def add(self, t, y):
        """Record a sample; the detail of a hunting verdict, or ""."""
        self.low, self.high = min(self.low, y), max(self.high, y)
        up = self.last is not None and self.last < 0.0 <= y
        self.last = y
        if not up:
            return ""
        if self.ups:  # a whole slow cycle since the last upward crossing
            self.sizes.append(self.high - self.low)
        self.ups.append(t)
        self.low = self.high = y
        if len(self.sizes) < SLOW_CYCLES:
            return ""
        recent = self.sizes[-SLOW_CYCLES:]
        half = SLOW_CYCLES // 2
        earlier, later = sum(recent[:half]), sum(recent[half:])
        if later < DECAY * earlier:
            return ""
        period = (self.ups[-1] - self.ups[-1 - SLOW_CYCLES]) / SLOW_CYCLES
        return (f"hunts, not locked to the dither within {P_MAX} of its periods: over {SLOW_CYCLES} slow cycles "
                f"(about {period:.4g} s each) the "
                f"output swings {later / half / 2.0:.4g} about its target at the dither's phase 0, not decaying "
                f"(the later half {later / earlier:.3f} of the earlier)")


def check_dither(problem, amplitudes=None, horizon=None):
    """The horizon of a dithered loop's runs [s] (default: the loop's, for the smallest start amplitude), once
    its dither is checked against it: InputError where the dither's period is longer than the horizon, or one
    run over the horizon would take more steps of the exact loop (at most 1/w_d s each) than the problem's
    budget. A study calls it before anything runs."""
    scales = problem.scales
    amplitudes = scales.amplitudes() if amplitudes is None else amplitudes
    horizon = scales.horizon(min(amplitudes)) if horizon is None else float(horizon)
    w_d = problem.dither.w_d
    T = 2.0 * math.pi / w_d
    if T > horizon:
        raise InputError(f"w_d = {w_d:.6g} rad/s is out of range for this loop: its period {T:.4g} s is longer than "
                         f"the loop's horizon {horizon:.4g} s (a dither is faster than the motion it smooths)")
    if w_d * horizon > problem.budget.total:
        raise InputError(f"w_d = {w_d:.6g} rad/s is out of range for this loop: the exact loop's steps are at most "
                         f"1/w_d long, so one run over its horizon ({horizon:.4g} s) would take more than the "
                         f"study's {problem.budget.total} of them (at most {problem.budget.total / horizon:.4g} "
                         "rad/s)")
    return horizon


def find_responses(problem, amplitudes=None, horizon=None, max_periods=MAX_PERIODS, progress=None, predictions=()):
    """Every periodic response of a dithered loop that a run reaches, and the runs that hunt unlocked.

    Parameters
    ----------
    problem : LoopProblem
        A loop with a dither (``problem.dither``).
    amplitudes : list of float, optional
        The start amplitudes of the output (default: :meth:`LoopScales.amplitudes`).
    horizon : float, optional
        A run with no event of the plant for this long is at rest [s] (default: the loop's, for the smallest
        amplitude).
    max_periods : int
        Dither periods a run may take (and no more than RUN_HORIZONS horizons' worth).
    progress : callable, optional
        ``progress(done, total, label)`` after each run.
    predictions : list of dfwb.engine.limit_cycles.Cycle, optional
        The dither's DF predictions (:mod:`dfwb.engine.dither_df`), each linked to its nearest locked cycle
        (``links``, as :func:`~dfwb.engine.cycles.find_cycles` links them; they start no run).

    Returns
    -------
    DitherSearch

    Raises
    ------
    InputError
        Where the dither's period is longer than the horizon, or one run over the horizon would take more steps
        of the exact loop (at most 1/w_d s each) than the problem's budget.
    """
    if getattr(problem, "dither", None) is None:
        raise ValueError("find_responses needs a loop with a dither (compensation=Dither(a, w_d))")
    scales = problem.scales
    amplitudes = scales.amplitudes() if amplitudes is None else [float(a) for a in amplitudes]
    horizon = check_dither(problem, amplitudes, horizon)
    T = 2.0 * math.pi / problem.dither.w_d
    max_periods = max(1, min(int(max_periods), math.ceil(RUN_HORIZONS * horizon / T)))
    runs = _Runs(problem, horizon, max_periods, DIVERGED * max(amplitudes))
    plan = starts(problem, amplitudes)
    coverage = Coverage(amplitudes=[min(amplitudes), max(amplitudes)], count=len(amplitudes),
                        parts=list(dict.fromkeys(s.part for s in plan)), horizon=horizon, max_returns=max_periods,
                        divergence=runs.divergence)
    coverage.runs_text = (f"each up to {max_periods} dither periods of {T:.4g} s, at rest after {horizon:.4g} s "
                          "without an event")
    try:
        for k, start in enumerate(plan):
            runs.run(start)
            if progress:
                progress(k + 1, len(plan), start.label)
    except PlantError:  # the budget is spent: report what was covered
        if not problem.exhausted():
            raise
        coverage.complete = False
    if tally(coverage, runs.fates, OUTCOMES)["unsettled"]:
        coverage.complete = False  # a run that neither settled nor hunted proves nothing
    cycles = sorted((c for c in runs.found if c.returns > 1), key=lambda c: c.amplitude_x)
    responses = [c for c in runs.found if c.returns == 1]
    order = {id(c): j for j, c in enumerate(cycles)}
    order.update({id(c): j for j, c in enumerate(responses)})
    for fate in runs.fates:
        if fate.cycle is not None:
            fate.cycle = order[id(runs.found[fate.cycle])]
    links = link(predictions, cycles)
    for i, j in enumerate(links):
        if j is not None:
            cycles[j].prediction = i
    return DitherSearch(cycles, links, coverage, runs.fates, responses=responses)
