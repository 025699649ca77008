"""FMI facades of the naive fixed-step baselines (:mod:`.naive`): a benchmark baseline, not for analysis.

The same plants integrated the way typical pythonfmu examples do: semi-implicit
Euler with a fixed internal step dt inside doStep. They exist as the
``fmu-fixedstep`` method of the benchmark, to measure what exactness buys;
their results carry a first-order error in dt and are not for analysis. Same
variables as the exact FMUs plus the parameter dt, so any importer (and the DF
engine) can use either.

They live here, not in :mod:`.facade`, so that the production FMUs' sources
(the modules :mod:`.facade` imports) do not include them: editing
:mod:`.naive` or this module rebuilds only the naive FMUs.
"""

from .facade import FrictionMass, StaticBacklash, TwoMassBacklash
from .naive import NaiveFrictionMass as _NaiveFrictionMass
from .naive import NaiveStaticBacklash as _NaiveStaticBacklash
from .naive import NaiveTwoMassBacklash as _NaiveTwoMassBacklash

DT_PARAMETER = ("dt", 1e-3, "s", "internal fixed step of the naive integrator (> 0)")
NAIVE_FIXED = ("harmonics", "dt", "omega", "drive.F", "drive.omega", "drive.phi")
"""Attributes of a fixed-step solver that a run never changes (see facade.SolverFMU._check_solver_state)."""


class NaiveFrictionMass(FrictionMass):
    """Friction mass by naive fixed-step semi-implicit Euler (Karnopp band): a benchmark baseline, not for analysis.

    The ``fmu-fixedstep`` comparison method: the exact FrictionMass's
    variables plus ``dt``; Karnopp's stick band is max(Dv, Fs dt / M).
    """

    solver_class = _NaiveFrictionMass
    fixed_solver_attributes = NAIVE_FIXED + ("M", "B", "Fc", "Fs", "Dv", "band")
    piecewise_solver = False
    ranges = dict(FrictionMass.ranges, dt=(0.0, None))
    parameters = FrictionMass.parameters + (DT_PARAMETER,)


class NaiveTwoMassBacklash(TwoMassBacklash):
    """Two-mass backlash by naive fixed-step semi-implicit Euler (clamped gap): a benchmark baseline, not for analysis.

    The ``fmu-fixedstep`` comparison method: the exact TwoMassBacklash's
    variables plus ``dt``; impacts are detected after the step that crosses
    a wall.
    """

    solver_class = _NaiveTwoMassBacklash
    fixed_solver_attributes = NAIVE_FIXED + ("M1", "M2", "h", "eps")
    piecewise_solver = False
    ranges = dict(TwoMassBacklash.ranges, dt=(0.0, None))
    parameters = TwoMassBacklash.parameters + (DT_PARAMETER,)


class NaiveStaticBacklash(StaticBacklash):
    """Mass and backlash by naive fixed-step semi-implicit Euler: a benchmark baseline, not for analysis.

    The ``fmu-fixedstep`` comparison method: the exact StaticBacklash's
    variables plus ``dt``; the play operator acts once per internal step.
    """

    solver_class = _NaiveStaticBacklash
    fixed_solver_attributes = NAIVE_FIXED + ("M", "k", "h")
    piecewise_solver = False
    ranges = dict(StaticBacklash.ranges, dt=(0.0, None))
    parameters = StaticBacklash.parameters + (DT_PARAMETER,)


NAIVE = (NaiveFrictionMass, NaiveTwoMassBacklash, NaiveStaticBacklash)
"""The benchmark's fixed-step twins of the three plants."""
