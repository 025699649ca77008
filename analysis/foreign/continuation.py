"""The true cycles of a user's model-exchange FMU followed in a parameter, by sampling it.

dfwb's own loops are continued by pseudo-arclength (:mod:`dfwb.engine.continuation`): their exact
section maps give Jacobians fine enough to pass folds. A user's FMU is searched instead at
``count`` evenly spaced values of the parameter (:func:`dfwb.foreign.hunting.cells`: the runs from
their starts, and Newton from the DF's unstable predictions), and the cycles found at consecutive
values are joined where they are near (frequency and amplitude within :data:`NEAR`). Where a branch
begins or ends, or changes its stability, between two values, the change is bracketed by them: a
``bracketed`` bifurcation whose accuracy is the spacing.
"""

import math

import numpy as np

from dfwb.engine.continuation import Bifurcation, Branch, Point
from dfwb.foreign.hunting import cells

__all__ = ["sampled_branches", "NEAR"]

NEAR = math.log(1.2)  # |ln(omega ratio)| + |ln(amplitude ratio)| of one branch's consecutive cycles, at most


def sampled_branches(engine, family, name, bounds, count, F_range, omega_range, size, progress=None):
    """(branches, bifurcations) of the true cycles over ``name`` in ``bounds`` (see the module docstring)."""
    values = [float(v) for v in np.linspace(bounds[0], bounds[1], count)]
    spacing = values[1] - values[0]
    classify_at = cells(engine, family, F_range, omega_range, size)
    open_branches, closed, found = [], [], []
    for k, value in enumerate(values):
        cycles = classify_at({name: value}, truth=True, df=False)["truth"]["cycles"]
        continued = []
        for cycle in sorted(cycles, key=lambda c: c["amplitude_x"]):
            point = Point(parameter=value, omega=cycle["omega"], amplitude_x=cycle["amplitude_x"], F=cycle["F"],
                          stable=cycle["stable"], multipliers=cycle["multipliers"], period=cycle["period"],
                          signature=tuple(cycle["events"]))
            near = [(_distance(branch.points[-1], point), i) for i, branch in enumerate(open_branches)
                    if i not in continued and branch.points[-1].parameter == values[k - 1]]
            near = [(d, i) for d, i in near if d < NEAR]
            if near:
                i = min(near)[1]
                branch = open_branches[i]
                last = branch.points[-1]
                if last.stable != point.stable:
                    found.append(_bracketed(f"its stability changes ({_kind(last)} to {_kind(point)})",
                                            value - spacing / 2, point, spacing))
                branch.points.append(point)
                continued.append(i)
            else:
                branch = Branch("truth", [point])
                branch.ends.append((value, "the end of the range" if k == 0 else
                                    f"it begins between {values[k - 1]:g} and {value:g}"))
                if k:
                    found.append(_bracketed("a branch of cycles begins", value - spacing / 2, point, spacing))
                open_branches.append(branch)
                continued.append(len(open_branches) - 1)
        for i, branch in enumerate(open_branches):
            if i not in continued and branch.points[-1].parameter == values[k - 1] and len(branch.ends) == 1:
                last = branch.points[-1]
                branch.ends.append((last.parameter, f"it ends between {last.parameter:g} and {value:g}"))
                found.append(_bracketed("the branch of cycles ends", value - spacing / 2, last, spacing))
        if progress:
            progress("samples", k + 1, count)
    for branch in open_branches:
        if len(branch.ends) == 1:
            branch.ends.append((branch.points[-1].parameter, "the end of the range"))
        closed.append(branch)
    return closed, found


def _distance(a, b):
    return abs(math.log(a.omega / b.omega)) + abs(math.log(max(a.amplitude_x, 1e-300) / max(b.amplitude_x, 1e-300)))


def _kind(point):
    return "stable" if point.stable else "unstable"


def _bracketed(what, parameter, point, spacing):
    """A change between two samples, ``parameter`` their middle: located only to their spacing."""
    return Bifurcation(kind="bracketed", parameter=parameter, omega=point.omega, amplitude_x=point.amplitude_x,
                       source="truth", detail=f"{what} between the samples", accuracy=spacing)
