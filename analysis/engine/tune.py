"""The fastest controller that does not hunt: a search over a controller family and its compensators.

Within the ranges of G's free parameters and of the compensators' (``Kp``, ``Ki`` and the deadband's ``d``),
the setting with the highest crossover frequency of the linear loop (|G P| = 1; a faster loop) subject to

- the exact loop has no stable cycle: the systematic search (:func:`dfwb.engine.cycles.find_cycles`) is
  complete and finds none, at the nominal plant and at every corner of the robustness box (the plant's
  parameters given relative errors, ``Fc`` +-20 %);
- its step response comes to rest with a standing error at most ``tolerance`` there
  (:func:`dfwb.engine.cost.step_cost`); with a dither, settles with its standing error and its residual
  oscillation together at most ``tolerance`` (the mass stays that close to its target);
- the linear loop is stable.

The candidates are a grid of ``count`` values per free parameter (log-spaced on a positive range). G's
settings are tried in decreasing crossover, for each the compensators' in increasing order (the least
compensation first), each at the nominal plant first, then at the corners; the first setting that passes is
the answer: the best on the grid. The chosen loop is then confirmed by the independent reference
(:mod:`dfwb.plants.loop_reference`) at every corner: from rest at the step and from displaced starts, it
comes to rest and stays there (not for a dithered loop, which never rests: said so, its confirmation None).
"""

import itertools
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from dfwb.base.errors import DfwbError, InputError

__all__ = ["Candidate", "tune", "corners", "MAX_CANDIDATES"]

MAX_CANDIDATES = 10_000  # settings on the grid, at most
CONFIRM_STARTS = (1.0, 3.0, -10.0)  # the reference's starts: displacements in the loop's length scale
ACCEPTED = ("none", "unstable")  # the truth's classes without a stable cycle (and never diverging)


@dataclass
class Candidate:
    """A setting tried: its values, the linear loop's crossover [rad/s], the verdict and why."""

    values: dict
    crossover: float
    verdict: str = "not tried"  # accepted, hunts, standing error, linear loop unstable, refused, not tried
    detail: str = ""
    cost: dict = field(default_factory=dict)

    def as_dict(self):
        return asdict(self)


def corners(family, robust):
    """The plant's parameters at the nominal values, then at each corner of the box ``robust`` ({name: relative
    error}): a list of {name: value} (the nominal first)."""
    nominal = family.params()
    for name, rel in robust.items():
        if name not in family.plant_names:
            raise InputError(f"robust {name}: not a parameter of the {family.spec.name} plant (allowed: "
                             f"{', '.join(family.plant_names)})")
        if not (isinstance(rel, (int, float)) and not isinstance(rel, bool) and 0.0 < rel < 1.0):
            raise InputError(f"robust {name} = {rel!r}: a relative error between 0 and 1 (0.2: +-20 %)")
    box = [nominal]
    names = sorted(robust)
    defaults = family.spec.defaults()
    base = {name: nominal.get(name, defaults[name]) for name in names}
    for signs in itertools.product((-1.0, 1.0), repeat=len(names)):
        box.append(dict(nominal, **{n: base[n] * (1.0 + s * robust[n]) for n, s in zip(names, signs)}))
    for corner in box[1:]:  # each corner a plant the plant accepts (Fc <= Fs at every corner...)
        try:
            family.spec.checked(corner)
        except DfwbError as error:
            raise InputError(f"robust: the corner {_text(corner, names)} is refused by the plant: {error}") from None
    return box


def _text(values, names=None):
    return ", ".join(f"{n} = {values[n]:.6g}" if not isinstance(values[n], str) else f"{n} = {values[n]}"
                     for n in (names or values))


def _axis(name, lo, hi, count):
    if lo > 0.0:
        return [float(v) for v in np.geomspace(lo, hi, count)]
    return [float(v) for v in np.linspace(lo, hi, count)]


def tune(family, free, tolerance=None, robust=None, count=5, progress=None, fmu_dir=None):
    """(the chosen Candidate or None, every Candidate tried or ranked, the corners) of ``family`` (a
    :class:`~dfwb.engine.family.LoopFamily` with its free parameters) over ``free`` ({name: (lo, hi)}); see the
    module docstring. ``progress(done, total)``."""
    from dfwb.engine.cost import step_cost
    from dfwb.engine.hunting import classify

    robust = dict(robust or {})
    box = corners(family, robust)
    controller = [n for n in free if n in family.controller.names]
    compensating = [n for n in free if family.compensation.numeric(n)]
    axes = {name: _axis(name, lo, hi, count) for name, (lo, hi) in free.items()}
    total = math.prod(len(v) for v in axes.values())
    if total > MAX_CANDIDATES:
        raise InputError(f"{total} settings on the grid: at most {MAX_CANDIDATES} (fewer free parameters or a "
                         "smaller count)")
    ranked = []
    for values in itertools.product(*(axes[n] for n in controller)):
        setting = dict(zip(controller, values))
        try:  # (the compensators at their first values: the linear loop does not see them)
            scales = family.problem(dict(setting, **{n: axes[n][0] for n in compensating}), fmu_dir).scales
        except DfwbError as error:
            ranked.append((Candidate(setting, math.nan, "refused", " ".join(str(error).split())), None))
            continue
        ranked.append((Candidate(setting, float(scales.omega_c)), scales.stable))
    ranked.sort(key=lambda entry: -entry[0].crossover if math.isfinite(entry[0].crossover) else math.inf)
    tried, done = [], 0
    chosen = None
    for base, stable in ranked:
        compensations = list(itertools.product(*(axes[n] for n in compensating))) or [()]
        for values in compensations:
            candidate = Candidate(dict(base.values, **dict(zip(compensating, values))), base.crossover,
                                  base.verdict, base.detail)
            tried.append(candidate)
            done += 1
            if progress:
                progress(done, total)
            if chosen is not None:
                continue  # (ranked below the answer: not tried)
            if candidate.verdict == "refused":
                continue
            if not stable:
                candidate.verdict, candidate.detail = "linear loop unstable", "the linear loop's poles"
                continue
            candidate.verdict = "accepted"
            for corner in box:  # the nominal first: most settings fail there
                where = "nominal" if corner is box[0] else _text(corner, sorted(robust))
                try:
                    problem = family.problem(dict(candidate.values, **corner), fmu_dir)
                    truth = classify(problem, df=False)["truth"]
                    if truth["class"] not in ACCEPTED or not truth["coverage"]["complete"]:
                        candidate.verdict, candidate.detail = "hunts", f"{truth['class']} at {where}"
                        break
                    cost = step_cost(problem)
                except DfwbError as error:
                    candidate.verdict, candidate.detail = "refused", f"{' '.join(str(error).split())} at {where}"
                    break
                if corner is box[0]:
                    candidate.cost = cost.as_dict()
                off = None if cost.standing_error is None else cost.standing_error + (cost.residual_oscillation or 0.0)
                if tolerance is not None and (off is None or off > tolerance):
                    shown = "no rest" if off is None else f"{off:.4g}"
                    candidate.verdict, candidate.detail = "standing error", f"{shown} at {where}"
                    break
            if candidate.verdict == "accepted":
                chosen = candidate
    return chosen, tried, box


def confirm(family, chosen, box, fmu_dir=None):
    """Whether the independent reference confirms that the chosen loop comes to rest and stays there at every
    corner, from rest at the step and from displaced starts (:data:`CONFIRM_STARTS`): (True or False, what was
    run); (None, why) for a plant or parameters the reference does not take (its friction mass sticks exactly:
    Dv = 0)."""
    from dfwb.plants.loop_reference import closed_loop_reference

    if family.spec.name != "friction":
        return None, f"the reference has the compensators of the friction mass only, not of {family.spec.name}"
    if "dither" in family.compensation.kinds:
        return None, ("a dithered loop settles on the dither's response, never at rest: this confirmation (at rest "
                      "for good) does not apply; its verdicts are held to the reference in tests/test_dither.py")
    runs = []
    for corner in box:
        problem = family.problem(dict(chosen.values, **corner), fmu_dir)
        kwargs = {}
        for compensator in problem.compensation or []:
            if compensator.name == "coulomb":
                kwargs["coulomb"] = (compensator.F_hat, compensator.signal)
            elif compensator.name == "reset":
                kwargs["reset"] = True
            elif compensator.name == "deadband":
                kwargs["deadband"] = compensator.d
        T = problem.horizon
        for scale in CONFIRM_STARTS:
            start = problem.rest_start(scale * problem.scales.length)
            try:  # the corner's plant as it is: a parameter the reference does not take is said, never dropped
                ref = closed_loop_reference("friction", problem.b, problem.a, T, corner, state=start,
                                            max_events=100_000, **kwargs)
            except DfwbError as error:
                return None, f"the reference cannot run this plant: {' '.join(str(error).split())}"
            later = closed_loop_reference("friction", problem.b, problem.a, T / 4, corner, state=ref["state"],
                                          **kwargs)
            rests = ref["mode"] == "stick" and later["events"] == [] and later["state"] == ref["state"]
            runs.append({"corner": corner, "start": start, "t": T, "rests": rests, "y": ref["state"][0]})
            if not rests:
                return False, runs
    return True, runs
