"""Every limit cycle of the exact closed loop that a simulation reaches, within a stated range.

A search that starts from rest at a few amplitudes and gives up after a few
guessed periods misses the cycle that matters most: a friction mass that
sticks while the integrator winds up for a minute is never seen moving. This
search is systematic, and says what it covered:

* **Starts** over a logarithmic range of output amplitudes (by default
  around the loop's length scale, :mod:`dfwb.engine.scales`), each
  displacing one part of the state: the plant's output (at rest), its
  velocity, and each controller state in both directions with the output
  displaced (a stuck mass with a winding integrator is such a start); plus
  the describing function's predictions, each shot directly (which finds
  unstable cycles) and run.
* **Runs** counted in section hits, the plant's own events that every
  periodic orbit crosses (:class:`~dfwb.engine.periodic.LoopProblem`), never
  in periods guessed from the DF; the wait for one hit is bounded by the
  loop's own time scales (its slowest time constant, and how long a stuck
  plant at the smallest amplitude waits for the integrator). A run ends
  when it reaches a known stable cycle, when its hits repeat closely enough
  (every ``p`` hits, p = 1..8) for Newton's method to find the cycle it
  approaches, when it comes to rest (no hit in time), when it diverges, or
  after ``max_returns`` hits (unsettled: quasi-periodic or chaotic, or slow).
* **Basin boundaries**: where neighbouring starts end differently (two
  cycles, a cycle and rest, a cycle and divergence), bisection on the
  amplitude finds a start on the boundary; its run lingers near the
  unstable cycle that separates the basins, which is then shot.

The answer (:class:`CycleSearch`) holds the cycles, each run's fate and the
:class:`Coverage`, so that "no cycle" means "none reached from these starts
within this horizon".

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> found = find_cycles(LoopProblem("friction", "10 + 2/s"))
>>> [(round(c.omega, 6), round(c.amplitude_x, 6), c.stable) for c in found.cycles]
[(0.109725, 0.236652, True)]
>>> found.coverage.outcomes
{'cycle': 34, 'rest': 2}
"""

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from dfwb.fmus.exact import Diverged, PlantError

P_MAX = 8  # section hits per period a run recognises
MAX_RETURNS = 600  # section hits a run may take
NEAR = 3e-2  # hits p apart this close (relative): Newton is tried
JOIN = 1e-2  # a hit this close to a stable cycle's (relative to its swing), and closer than the one before: reached
LINEAR = 0.3  # ... or this close, its distance shrinking by the cycle's leading multiplier (within RATIO) 3 times
RATIO = 1.2
DIVERGED = 1e4  # an output beyond this many times the largest start amplitude: the run diverges
BISECTIONS = 40  # halvings of a basin boundary's amplitude interval, at most
MAX_BOUNDARIES = 4  # basin boundaries searched, at most
SAME_CYCLE = 1e-6  # two cycles with w and X this close (relative) are one
Z_CAP = 1e6  # a controller state is displaced at most this many times its size in a motion of the start amplitude
LINK_FACTOR = 2.0  # a prediction and a true cycle within this factor in w and X may be linked
OUTCOMES = ("cycle", "rest", "diverged", "unsettled", "moving", "failed")


@dataclass
class Start:
    """Where a run begins: a label, the part of the state displaced, the output amplitude, the loop state."""

    label: str
    part: str
    amplitude: float
    state: list


@dataclass
class Fate:
    """How a run ended: ``outcome`` (one of OUTCOMES), the cycle reached (index) or None, hits, time, detail."""

    start: str
    outcome: str
    cycle: object = None
    hits: int = 0
    time: float = 0.0
    detail: str = ""


@dataclass
class Coverage:
    """What a search covered: "no cycle" means none reached from these starts within this horizon.

    Attributes
    ----------
    amplitudes : list of float
        [lowest, highest] output amplitude of the starts [output unit].
    count : int
        Amplitudes, log-spaced.
    parts : list of str
        The parts of the state displaced (``x``, ``v``, ``z1+``, ``z1-``, ...).
    starts : int
        Runs made (predictions' and bisections' included).
    predictions : int
        DF predictions started from.
    horizon : float
        The longest wait for a section hit [s]: a run without one in that time has come to rest.
    max_returns : int
        Section hits a run may take.
    divergence : float
        An output beyond this [output unit] counts as divergence.
    outcomes : dict
        Runs per outcome.
    boundaries : int
        Basin boundaries bisected.
    complete : bool
        False when the work budget ran out before every start came to a verdict (or, for a user's FMU, a run
        did not settle within its returns).
    starts_text : str
        What the starts were, when they are not output amplitudes displacing parts of the state
        (a user's FMU's loop starts from first forces); "" otherwise.
    stable_only : bool
        The runs can only settle on cycles, never converge to an unstable one (a user's FMU's search):
        an unstable prediction without a true cycle near it is then no false alarm.
    runs_text : str
        How long a run may go, when it is not counted in section hits (a dithered loop's runs count its
        periods, :mod:`dfwb.engine.dither`); "" otherwise.
    """

    amplitudes: list
    count: int
    parts: list
    starts: int = 0
    predictions: int = 0
    horizon: float = 0.0
    max_returns: int = MAX_RETURNS
    divergence: float = 0.0
    outcomes: dict = field(default_factory=dict)
    boundaries: int = 0
    complete: bool = True
    starts_text: str = ""
    stable_only: bool = False
    runs_text: str = ""

    def as_dict(self):
        return asdict(self)

    @property
    def settled(self):
        """Whether every start came to a verdict: the budget lasted, no run failed, none moved on without crossing
        the section and none ran out of section hits unsettled (else absence is unproven)."""
        return self.complete and not any(self.outcomes.get(name) for name in ("failed", "moving", "unsettled"))

    def summary(self, unit="m"):
        """One line: what was searched."""
        lo, hi = self.amplitudes
        outcomes = ", ".join(f"{n} {name}" for name, n in self.outcomes.items())
        starts = self.starts_text or (f"{self.count} output amplitudes {lo:.3g} to {hi:.3g} {unit} "
                                      f"displacing {', '.join(self.parts)}")
        runs = self.runs_text or f"each up to {self.max_returns} section hits, at most {self.horizon:.4g} s apart"
        return (f"searched {self.starts} runs: {starts}" + (f", {self.predictions} DF predictions" if self.predictions
                                                         else "") +
                f"; {runs} ({outcomes})" + self._incomplete())

    def _incomplete(self):
        """Why the search proves no absence ("; INCOMPLETE: ..."), or "" where it does."""
        if self.complete and not self.outcomes.get("moving") and not self.outcomes.get("unsettled"):
            return ""
        if self.outcomes.get("moving"):
            why = "runs moved on without crossing the section (a motion it cannot see)"
        elif self.outcomes.get("unsettled"):
            why = "runs did not settle"
        else:
            why = "the work budget ran out"
        return "; INCOMPLETE: " + why


@dataclass
class CycleSearch:
    """The answer of :func:`find_cycles`.

    Attributes
    ----------
    cycles : list of TrueCycle
        Distinct cycles, sorted by amplitude.
    links : list
        For each DF prediction the index of its true cycle, or None (a false alarm).
    coverage : Coverage
    fates : list of Fate
        How every run ended.
    """

    cycles: list
    links: list
    coverage: Coverage
    fates: list

    def stable(self):
        """The stable cycles."""
        return [c for c in self.cycles if c.stable]


def starts(problem, amplitudes):
    """The runs' starts at each output amplitude: x, v, and each controller state displaced both ways."""
    probe, scales = problem.probe, problem.scales
    m, n = len(probe.coordinates), probe.order
    velocity = next(i for i, name in enumerate(probe.coordinates) if name.startswith("v"))
    per_output = probe.translate([0.0] * m, 1.0)[0]  # the first coordinate (a position) per unit of output
    G_c = abs(complex(problem.G(1j * scales.omega_c)))
    with np.errstate(all="ignore"):  # a controller state's size in a motion of unit output at omega_c
        natural = np.abs(np.linalg.solve(1j * scales.omega_c * np.eye(n) - np.array(probe.Ac, dtype=complex),
                                         np.array(probe.Bc, dtype=complex))) if n else np.zeros(0)
    out = []
    for a in amplitudes:
        out.append(Start(f"x = {a:.3g}", "x", a, problem.rest_start(a)))
        q = [0.0] * m
        q[velocity] = a * scales.omega_c * per_output
        out.append(Start(f"v = {q[velocity]:.3g}", "v", a, q + [0.0] * n))
        C = probe.C
        for i in range(n):
            size = abs(C[i]) if C[i] != 0.0 else max(max(abs(c) for c in C), 1e-300)
            # the controller's force moved by G_c a; no further than Z_CAP times the state's size in a motion
            # of amplitude a (a state that hardly moves the force, Ki = 1e-300, is not sent to 1e300)
            shift = min(G_c * a / size, Z_CAP * a * float(natural[i])) if np.isfinite(natural[i]) else G_c * a / size
            for sign, label in ((1.0, "+"), (-1.0, "-")):
                X = problem.rest_start(a)
                X[m + i] = sign * shift
                out.append(Start(f"x = {a:.3g}, z{i + 1} = {X[m + i]:.3g}", f"z{i + 1}{label}", a, X))
    return out


class _Search:
    """The runs of one search: the cycles found so far and each run's fate."""

    def __init__(self, problem, horizon, max_returns, divergence):
        self.problem, self.horizon, self.max_returns, self.divergence = problem, horizon, max_returns, divergence
        self.cycles, self.fates = [], []

    def add(self, cycle, origin):
        """The index of ``cycle`` among the known ones (added if new)."""
        for j, known in enumerate(self.cycles):
            if (abs(known.omega - cycle.omega) <= SAME_CYCLE * known.omega
                    and abs(known.amplitude_x - cycle.amplitude_x) <= SAME_CYCLE * max(known.amplitude_x, 1e-300)):
                if origin not in known.started_from:
                    known.started_from.append(origin)
                return j
        cycle.started_from.append(origin)
        self.cycles.append(cycle)
        return len(self.cycles) - 1

    def shoot(self, X, returns, origin, on_section=True):
        """The index of the cycle Newton's method finds from X (added if new), or None."""
        fixed = self.problem.converge(X, returns, self.horizon, on_section)
        if fixed is None:
            return None
        j = self.known(np.array(fixed[0]))
        if j is not None:  # a cycle found before: no need to describe it again
            if origin not in self.cycles[j].started_from:
                self.cycles[j].started_from.append(origin)
            return j
        cycle = self.problem.finish(*fixed[:2], returns, self.horizon, *fixed[2:])
        return None if cycle is None else self.add(cycle, origin)

    def known(self, X, tolerance=1e-6):
        """The cycle (stable or not) whose section passes through X, or None."""
        for j, cycle in enumerate(self.cycles):
            swing = np.array(cycle.swing)
            if cycle.section == self.problem.section and any(np.abs((X - np.array(S)) / swing).max() <= tolerance
                                                              for S in cycle.sections):
                return j
        return None

    def joined(self, hits):
        """The stable cycle a run's hits (the last one new) have reached, or None.

        Reached: the last hit lies within JOIN of the cycle's section and closer than the one before; or
        within LINEAR, the distance having shrunk three times in a row by the cycle's leading multiplier
        (a real one, within a factor RATIO): the run is in the cycle's linear neighbourhood.
        """
        for j, cycle in enumerate(self.cycles):
            if not cycle.stable or cycle.section != self.problem.section:
                continue
            recent = [self.distance(cycle, X) for X in hits[-4:]]
            if recent[-1] <= JOIN and (len(recent) == 1 or recent[-1] < recent[-2]):
                return j
            leading = cycle.spectrum[0] if cycle.spectrum else None
            if (len(recent) == 4 and recent[-1] <= LINEAR and leading is not None and leading[1] == 0.0
                    and abs(leading[0]) >= 0.5):
                rho = abs(leading[0])
                if all(rho / RATIO <= b / a <= min(1.0, rho * RATIO) for a, b in zip(recent, recent[1:]) if a > 0):
                    return j
        return None

    @staticmethod
    def distance(cycle, X):
        """How far a state is from the cycle's section states, relative to its swing."""
        swing = np.array(cycle.swing)
        return min(float(np.abs((X - np.array(S)) / swing).max()) for S in cycle.sections)

    def run(self, start):
        """Run from ``start`` until it reaches a cycle, rests, diverges or runs out of hits: its Fate. A run that
        moves on without crossing the loop's section runs again on its second section, where it has one."""
        problem, label = self.problem, start.label
        fate = self._run(problem, start.state, label)
        alternate = problem.alternate() if fate.outcome == "moving" else None
        if alternate is not None:
            self.problem = alternate  # its shooting and its cycles' distances are on that section
            try:
                fate = self._run(alternate, start.state, label)
            finally:
                self.problem = problem
        fate.start = label
        self.fates.append(fate)
        return fate

    def _run(self, problem, X0, label):
        try:
            solver = problem._make(X0)
        except PlantError as error:
            return Fate(label, "failed", detail=str(error))
        hits, tried = [], {}
        for count in range(1, self.max_returns + 1):
            try:
                waited = problem.wait(solver, self.horizon)
            except PlantError as error:
                return refused(problem, solver, label, count - 1, error)
            hit = waited == "hit"
            X = np.array(solver.state())
            if not abs(X[problem.output]) <= self.divergence:  # at a hit, or drifting away without one
                return Fate(label, "diverged", hits=count - int(not hit), time=solver.t,
                            detail=f"the output reached {X[problem.output]:.3g}")
            if waited == "moving":  # never "rest" (nor "no cycle") while it moves: the search is incomplete
                return Fate(label, "moving", hits=count - 1, time=solver.t,
                            detail=f"no section hit within {self.horizon:.4g} s, yet events still fire: it moves "
                                   "without crossing the section")
            if not hit:
                return Fate(label, "rest", hits=count - 1, time=solver.t,
                            detail=f"no section hit within {self.horizon:.4g} s")
            hits.append(X)
            j = self.joined(hits)
            if j is not None:
                return Fate(label, "cycle", j, count, solver.t)
            window = np.array(hits[-2 * P_MAX - 1:])
            scale = np.abs(window).max(axis=0)
            scale = np.maximum(scale, 1e-6 * scale.max() + 1e-300)
            for p in range(1, min(P_MAX, len(hits) - 1) + 1):
                distance = float(np.abs((hits[-1] - hits[-1 - p]) / scale).max())
                if distance > NEAR:
                    continue
                if p not in tried or distance < 0.1 * tried[p]:
                    tried[p] = distance
                    found = self.shoot(list(X), p, label)
                    if found is not None and self.joined(hits) == found:
                        return Fate(label, "cycle", found, count, solver.t)
                break
        return Fate(label, "unsettled", hits=self.max_returns, time=solver.t,
                    detail=f"no cycle reached in {self.max_returns} section hits")


def tally(coverage, fates, outcomes):
    """Count the runs into ``coverage`` (``starts``, and ``outcomes``: those of ``outcomes`` that occurred, in
    that order); the counts of every one of ``outcomes``."""
    coverage.starts = len(fates)
    counts = {name: sum(f.outcome == name for f in fates) for name in outcomes}
    coverage.outcomes = {name: n for name, n in counts.items() if n}
    return counts


def refused(problem, solver, label, done, error):
    """The Fate of a run the loop refused (``error``, a PlantError) after ``done`` hits or periods: diverged, or
    failed; a spent budget is raised (every later run would be refused too)."""
    if isinstance(error, Diverged):
        return Fate(label, "diverged", hits=done, time=solver.t, detail=str(error))
    if problem.exhausted():
        raise error
    return Fate(label, "failed", hits=done, time=solver.t, detail=str(error))


def _outcome(fate, rests=True):
    """What a basin boundary separates: the cycle reached, rest or divergence (None: nothing settled).

    ``rests``: whether rest is an attractor (not under an integrator, which moves any stuck plant in the end).
    """
    if fate.outcome == "cycle":
        return ("cycle", fate.cycle)
    if fate.outcome == "rest":
        return "rest" if rests else None
    return "diverged" if fate.outcome == "diverged" else None


def find_cycles(problem, predictions=(), amplitudes=None, horizon=None, max_returns=MAX_RETURNS, boundaries=True,
                progress=None):
    """Every distinct true cycle the search reaches, each linked to a DF prediction; what it covered.

    Parameters
    ----------
    problem : LoopProblem
    predictions : list of dfwb.engine.limit_cycles.Cycle
        DF predictions: each is shot from its DF state and run.
    amplitudes : list of float, optional
        The start amplitudes of the output (default: :meth:`LoopScales.amplitudes`).
    horizon : float, optional
        The longest wait for a section hit [s] (default: the loop's, for the smallest amplitude).
    max_returns : int
        Section hits a run may take.
    boundaries : bool or "unless-stable"
        Bisect basin boundaries for the unstable cycles between basins ("unless-stable": only when no
        stable cycle was found, as a map needs: a stable one settles its verdict).
    progress : callable, optional
        ``progress(done, total, label)`` after each run.

    Returns
    -------
    CycleSearch
    """
    if getattr(problem, "dither", None) is not None:
        raise ValueError("a dithered loop is forced: its truth is dfwb.engine.dither.find_responses "
                         "(dfwb.engine.truth.search picks it)")
    scales = problem.scales
    amplitudes = scales.amplitudes() if amplitudes is None else [float(a) for a in amplitudes]
    horizon = scales.horizon(min(amplitudes)) if horizon is None else float(horizon)
    search = _Search(problem, horizon, max_returns, DIVERGED * max(amplitudes))
    plan = starts(problem, amplitudes)
    coverage = Coverage(amplitudes=[min(amplitudes), max(amplitudes)], count=len(amplitudes),
                        parts=list(dict.fromkeys(s.part for s in plan)), horizon=horizon, max_returns=max_returns,
                        divergence=search.divergence, predictions=len(predictions))
    total = len(plan) + len(predictions)
    try:
        for i, prediction in enumerate(predictions):
            start = problem.df_start(prediction)
            if start is not None:
                search.shoot(start[0], 1, f"prediction {i} (shot)", on_section=False)
                search.run(Start(f"prediction {i}", "prediction", prediction.amplitude_x, start[0]))
            if progress:
                progress(i + 1, total, f"prediction {i}")
        ends = {}
        for k, start in enumerate(plan):
            ends.setdefault(start.part, []).append((start, search.run(start)))
            if progress:
                progress(len(predictions) + k + 1, total, start.label)
        if boundaries is True or (boundaries == "unless-stable" and not any(c.stable for c in search.cycles)):
            coverage.boundaries = _bisect(search, ends, plan, progress)
    except PlantError:  # the budget is spent: report what was covered
        if not problem.exhausted():
            raise
        coverage.complete = False
    tally(coverage, search.fates, OUTCOMES)
    cycles = sorted(search.cycles, key=lambda c: c.amplitude_x)
    order = {id(c): j for j, c in enumerate(cycles)}
    for fate in search.fates:
        if fate.cycle is not None:
            fate.cycle = order[id(search.cycles[fate.cycle])]
    links = link(predictions, cycles)
    for i, j in enumerate(links):
        if j is not None:
            cycles[j].prediction = i
    return CycleSearch(cycles, links, coverage, search.fates)


def _bisect(search, ends, plan, progress):
    """Bisect the amplitude between neighbouring starts of one part that end differently; the boundaries searched."""
    problem = search.problem
    rests = problem.scales.ramp == 0.0
    by_label = {s.label: s for s in plan}
    pairs = []
    for part, runs in ends.items():
        for (low, low_fate), (high, high_fate) in zip(runs, runs[1:]):
            a, b = _outcome(low_fate, rests), _outcome(high_fate, rests)
            if a is not None and b is not None and a != b:
                pairs.append((part, by_label[low.label], a, by_label[high.label], b))
    seen, done = set(), 0
    for part, low, a, high, b in pairs:
        if (a, b) in seen or done >= MAX_BOUNDARIES:
            continue
        seen.add((a, b))
        done += 1
        lo, hi = math.log(low.amplitude), math.log(high.amplitude)
        known = len(search.cycles)
        for step in range(BISECTIONS):
            if hi - lo <= 1e-9 or len(search.cycles) > known:
                break
            amplitude = math.exp(0.5 * (lo + hi))
            start = next(s for s in starts(problem, [amplitude]) if s.part == part)
            start.label = f"boundary {done}, {start.label}"
            outcome = _outcome(search.run(start), rests)
            if outcome == a:
                lo = math.log(amplitude)
            elif outcome == b:
                hi = math.log(amplitude)
            else:
                break
            if progress:
                progress(None, None, start.label)
    return done


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


def report(predictions, search):
    """The JSON entries: each prediction's dict with ``true_cycle`` and ``error``, the cycles' dicts, the coverage."""
    entries = []
    for prediction, j in zip(predictions, search.links):
        entry = prediction.as_dict()
        entry["true_cycle"] = j
        entry["error"] = None if j is None else relative_errors(prediction, search.cycles[j])
        entries.append(entry)
    return entries, [cycle.as_dict() for cycle in search.cycles], search.coverage.as_dict()
