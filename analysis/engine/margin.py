"""The limit-cycle margin of a controller: the gain factors k for which k G makes the machine hunt.

"How much more gain can I use before it hunts?" has a number: scan k over a
logarithmic range, classify each k by the truth (the exact loop's systematic
search: a stable cycle, :mod:`dfwb.engine.hunting`) and by the DF (a stable
prediction), then locate every boundary between hunting and not hunting. A
truth boundary is located by continuing the stable cycle from the hunting
side in k (:mod:`dfwb.engine.continuation`): the bifurcation that ends it (a
fold, a nonsmooth fold, a loss of stability, or the amplitude going to
infinity at the linear loop's stability boundary) is the boundary, to 1e-7
of the bracket; where no bifurcation explains it, the bracket is bisected
with the search itself (to 1e-3 relative). A DF boundary is bisected on the
DF's verdict.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dfwb.base.defaults import K_COUNT, K_RANGE
from dfwb.base.errors import DfwbError, InputError
from dfwb.engine.hunting import HUNTS, MAP_AMPLITUDES, TRACKED, classify, df_map_for, hunting

GAIN = "gain factor"  # the gain factor k's name inside: no name of G or of a plant (no identifier has a space)

K_LIMITS = (1e-6, 1e6)  # a gain scaled further is another controller: give it as G

BISECTIONS = 12  # halvings of a boundary's bracket in log k by the search, at most


@dataclass
class Boundary:
    """Where hunting starts or stops as k grows: ``k``, ``kind`` (why: a bifurcation's kind, or "bisected"),
    ``starts`` (True: hunting begins above k), ``accuracy`` (the bracket's width in k)."""

    k: float
    kind: str
    starts: bool
    accuracy: float
    detail: str = ""

    def as_dict(self):
        return {"k": self.k, "kind": self.kind, "starts": self.starts, "accuracy": self.accuracy,
                "detail": self.detail}


@dataclass
class Margin:
    """One source's verdict over k: the scan, the hunting intervals and their boundaries."""

    source: str
    scan: list  # [(k, class, amplitude or None, omega or None)]
    intervals: list  # [[k_lo, k_hi]] where k G hunts (the range's edges where it hunts up to them)
    boundaries: list = field(default_factory=list)

    def hunts_at(self, k):
        return any(lo <= k <= hi for lo, hi in self.intervals)

    def room(self):
        """(down, up): the factors by which the gain may fall or grow from k = 1 before the verdict changes
        (None: no change within the range)."""
        below = [b.k for b in self.boundaries if b.k < 1.0]
        above = [b.k for b in self.boundaries if b.k > 1.0]
        return (max(below) if below else None), (min(above) if above else None)

    def as_dict(self):
        down, up = self.room()
        return {"source": self.source, "hunts_at_1": self.hunts_at(1.0), "intervals": self.intervals,
                "boundaries": [b.as_dict() for b in self.boundaries], "down": down, "up": up,
                "scan": [{"k": k, "class": kind, "amplitude_x": a, "omega": w} for k, kind, a, w in self.scan]}


def margins(family, k_range=K_RANGE, count=K_COUNT, fmu_dir=None, engine=None, progress=None, classifier=None):
    """(truth Margin, DF Margin) of the family's G scaled by k over ``k_range`` (a LoopFamily without k).

    ``classifier(scaled, ks)``: makes ``classify_at(k, truth, df)``, a setting's cell as
    :func:`~dfwb.engine.hunting.classify` gives it (or None where the loop cannot be set up); default: the
    exact loop's (a user's FMU brings its own, :mod:`dfwb.foreign.hunting`). Only the exact loop's truth
    boundaries are located by continuation; the others are bisected.
    """
    lo, hi = _k_range(k_range)
    scaled = family.scaled(GAIN)
    ks = [float(k) for k in np.geomspace(lo, hi, count)]
    if 1.0 not in ks and lo < 1.0 < hi:
        ks = sorted(ks + [1.0])
    exact = classifier is None
    classify_at = (classifier or _exact_classifier(fmu_dir, engine))(scaled, ks)
    cells = {}
    for i, k in enumerate(ks):
        try:
            cells[k] = classify_at(k, True, engine is not None)
        except DfwbError as error:
            cells[k] = {"error": str(error)}
        if progress:
            progress(i + 1, len(ks))
    results = []
    for source in ("truth", "df"):
        if engine is None and source == "df":
            continue
        scan = []
        for k in ks:
            cell = cells[k]
            if cell is None or source not in cell:
                scan.append((k, "error", None, None))
                continue
            best = hunting(cell, source)
            scan.append((k, cell[source]["class"], best and best["amplitude_x"], best and best["omega"]))
        margin = Margin(source, scan, [])
        for (k_a, class_a, *_), (k_b, class_b, *_) in zip(scan, scan[1:]):
            if (class_a in HUNTS) != (class_b in HUNTS) and "error" not in (class_a, class_b):
                margin.boundaries.append(_boundary(scaled, source, k_a, k_b, class_a in HUNTS, fmu_dir,
                                                   classify_at, exact))
        margin.intervals = _intervals(scan, margin.boundaries)
        results.append(margin)
    return results


def _k_range(k_range):
    try:
        lo, hi = (float(v) for v in k_range)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"k range = {k_range!r:.60}: give (low, high) gain factors") from None
    if not (K_LIMITS[0] <= lo < 1.0 < hi <= K_LIMITS[1]):
        raise InputError(f"k range = [{lo:g}, {hi:g}]: expected {K_LIMITS[0]:g} <= low < 1 < high <= "
                         f"{K_LIMITS[1]:g} (the gain as given is 1)")
    return lo, hi


def _intervals(scan, boundaries):
    """The hunting intervals: runs of hunting scan points, stretched to their boundaries."""
    intervals, start, previous = [], None, None
    for k, kind, *_ in scan + [(math.inf, "end")]:
        if kind in HUNTS and start is None:
            start = k
        elif kind not in HUNTS and start is not None:
            intervals.append([start, previous])
            start = None
        previous = k
    for interval in intervals:
        below = [b.k for b in boundaries if b.k <= interval[0] and b.starts]
        above = [b.k for b in boundaries if b.k >= interval[1] and not b.starts]
        interval[0] = max(below) if below else interval[0]
        interval[1] = min(above) if above else interval[1]
    return intervals


def _exact_classifier(fmu_dir, engine):
    """The exact loop's ``classifier`` (see :func:`margins`): one DF map, shared, on the range's ends' ranges."""
    def make(scaled, ks):
        problems = {}
        for k in ks:
            try:
                problems[k] = scaled.problem({GAIN: k}, fmu_dir)
            except InputError:
                problems[k] = None
        ends = [p for p in (problems[ks[0]], problems[ks[-1]]) if p is not None]
        shared = df_map_for(ends, engine) if engine is not None and ends else None

        def classify_at(k, truth=True, df=True):
            problem = problems[k] if k in problems else scaled.problem({GAIN: k}, fmu_dir)
            return None if problem is None else classify(problem, engine, shared, truth=truth, df=df)

        return classify_at

    return make


def _boundary(scaled, source, k_a, k_b, hunts_a, fmu_dir, classify_at, exact):
    """The boundary between k_a and k_b (one hunts, the other not): by continuation (the exact loop's
    truth), else bisection."""
    if source == "truth" and exact:
        located = _by_continuation(scaled, k_a if hunts_a else k_b, k_b if hunts_a else k_a, fmu_dir)
        if located is not None:
            return Boundary(located.parameter, located.kind, starts=not hunts_a, accuracy=located.accuracy,
                            detail=located.detail)
    return _bisect(source, k_a, k_b, hunts_a, classify_at)


def _by_continuation(scaled, hunting_k, other_k, fmu_dir):
    """The bifurcation ending the stable cycle between hunting_k and other_k, or None."""
    from dfwb.engine.continuation import continue_cycles
    from dfwb.engine.cycles import find_cycles

    problem = scaled.problem({GAIN: hunting_k}, fmu_dir)
    if problem.dither is not None:  # a forced loop: continuation follows no fixed point of its stroboscopic map
        return None
    stable = find_cycles(problem, amplitudes=problem.scales.amplitudes(MAP_AMPLITUDES), boundaries=False).stable()
    if not stable:
        return None
    bounds = (min(hunting_k, other_k), max(hunting_k, other_k))
    _branches, found = continue_cycles(scaled, GAIN, bounds, [(hunting_k, stable[-1])], fmu_dir)
    ends = [b for b in found if b.kind in TRACKED + ("infinity",) and bounds[0] <= b.parameter <= bounds[1]]
    if not ends:
        return None
    return min(ends, key=lambda b: abs(b.parameter - hunting_k))


def _bisect(source, k_a, k_b, hunts_a, classify_at):
    """The boundary between k_a and k_b by bisection in log k on the verdict of ``source``."""
    lo, hi = math.log(k_a), math.log(k_b)
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        try:
            cell = classify_at(math.exp(mid), source == "truth", source == "df")
        except DfwbError:
            break
        if cell is None:
            break
        hunts = cell[source]["class"] in HUNTS
        if hunts == hunts_a:
            lo = mid
        else:
            hi = mid
    k = math.exp(0.5 * (lo + hi))
    return Boundary(k, "bisected", starts=not hunts_a, accuracy=abs(math.exp(hi) - math.exp(lo)),
                    detail=f"the {source}'s verdict changes here (bisected in k)")
