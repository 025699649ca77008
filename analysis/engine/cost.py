"""What a loop costs: its step response (standing error, settling time, overshoot) and the force it takes.

A compensator that removes hunting may leave the mass short of its target or
spend force; this is the price reported beside each verdict. The loop
regulates the output to 0 (force = -G(s) y), so a step of the target by S is
the exact loop started at rest with the output at -S and the controller's
states at 0 (dfwb's plants do not depend on where the motion is). It runs for
``horizon`` seconds and is read at every event and at evenly spaced times, at
least :data:`SAMPLES` and :data:`PER_RADIAN` per radian of the linear loop's
crossover, the largest force and output read again between their neighbours:

- ``standing_error``: ``|y|`` where the loop came to rest, or None when it did not
  within the horizon (it hunts, or still moves). At rest means that over the
  last quarter of the horizon no event occurred and y stayed within
  :data:`STILL` of S, the force within :data:`STILL` of its peak: a measured
  rest, not the set of every rest position;
- ``settling_time``: from then on |y - y_end| stays within :data:`BAND` of S
  (None without rest);
- ``overshoot``: how far y passed the target, as a fraction of S (0: never);
- ``peak_force``, ``rms_force``: the force on the plant (the controller's and
  the compensator's) over the horizon [N];
- ``note``: why the step response could not be computed (the loop refused
  it, e.g. a feedforward that chatters), its other fields then None;
- ``residual_oscillation``: with a dither, the first harmonic of the output
  at the dither's frequency over the last dither period [output unit] (None
  without a dither, or where it does not settle). A dithered loop never
  rests: it *settles* when its output at the dither's phase 0 varies less
  than :data:`DITHER_STILL` of S over the last quarter; the standing error
  is then the output's mean over the last dither period (both exact to
  rounding), and the settling time counts the band from that mean widened
  by half the output's swing over that period.

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> from dfwb.fmus.compensation import Deadband
>>> cost = step_cost(LoopProblem("friction", "10 + 2/s", compensation=Deadband(0.2)))
>>> round(cost.standing_error, 4), round(cost.settling_time, 2), round(cost.overshoot, 3)
(0.1415, 10.17, 0.203)
>>> step_cost(LoopProblem("friction", "10 + 2/s")).standing_error is None  # it hunts
True
"""

import math
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

from dfwb.base.errors import InputError, PlantError

__all__ = ["Cost", "step_cost", "SAMPLES", "BAND", "STILL", "DITHER_STILL"]

SAMPLES = 2000  # evenly spaced readings of the step response, besides its events, at least,
PER_RADIAN = 8  # ... and this many per radian of the linear loop's crossover,
MAX_SAMPLES = 100_000  # ... up to this many
REFINE = 200  # the largest force and output read again at this many steps between their neighbours
BAND = 0.02  # settled: within 2 % of the step of where it rests
STILL = 1e-9  # at rest: y and the force vary less than this (relative) over the last quarter
DITHER_STILL = 1e-3  # settled on a dither's response: y at its phase 0 varies less than this (relative to S)


@dataclass(frozen=True)
class Cost:
    """The cost of a loop (see the module docstring); lengths in the output's unit, forces in N, times in s."""

    step: float
    horizon: float
    standing_error: Optional[float]
    settling_time: Optional[float]
    overshoot: Optional[float]
    peak_force: Optional[float]
    rms_force: Optional[float]
    note: str = ""
    residual_oscillation: Optional[float] = None

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self, unit="m") -> str:
        """One line: ``standing error 0.15 m, settles in 32 s, overshoot 0 %, force peak 7.0 N, rms 2.1 N``."""
        if self.note:
            return f"step of {self.step:.4g} {unit}: not computed: {self.note}"
        rest = ("does not come to rest in {:.4g} s".format(self.horizon) if self.standing_error is None else
                f"standing error {self.standing_error:.4g} {unit}, settles in {self.settling_time:.4g} s")
        if self.residual_oscillation is not None:
            rest += f", residual oscillation {self.residual_oscillation:.4g} {unit}"
        return (f"step of {self.step:.4g} {unit}: {rest}, overshoot {self.overshoot:.1%}, force peak "
                f"{self.peak_force:.4g} N, rms {self.rms_force:.4g} N")


def step_cost(problem, step=None, horizon=None):
    """The :class:`Cost` of ``problem`` (a :class:`~dfwb.engine.periodic.LoopProblem`, compensated or not) for a
    step of ``step`` (default: the loop's length scale) over ``horizon`` s (default: the loop's horizon for
    motions of that size, :meth:`~dfwb.engine.scales.LoopScales.horizon`)."""
    S = float(problem.scales.length if step is None else step)
    if not (math.isfinite(S) and S > 0.0):
        raise InputError(f"step = {step!r}: a positive, finite length")
    T = float(problem.scales.horizon(S) if horizon is None else horizon)
    if not (math.isfinite(T) and T > 0.0):
        raise InputError(f"horizon = {horizon!r}: a positive, finite time [s]")
    try:
        return _step(problem, S, T)
    except PlantError as error:  # the loop refuses the run: the cost says why
        return Cost(step=S, horizon=T, standing_error=None, settling_time=None, overshoot=None, peak_force=None,
                    rms_force=None, note=" ".join(str(error).split()))


def _read(problem, start, times):
    """(y, the force on the plant) of the loop from ``start`` at each of ``times`` (increasing)."""
    states, forces = problem.solver(start).readings(np.ascontiguousarray(times, dtype=float))
    return np.array(states)[:, problem.output], np.array(forces)


def _step(problem, S, T):
    start = problem.rest_start(-S)
    first = problem.solver(start)  # where the events are: read there too (a force jumps at a reset)
    first.event_log = []
    first.advance(T)
    events = [t for t, _kind in first.event_log]
    fastest = problem.scales.omega_c if problem.dither is None else max(problem.scales.omega_c, problem.dither.w_d)
    count = min(MAX_SAMPLES, max(SAMPLES, math.ceil(PER_RADIAN * T * fastest)))
    times = np.union1d(np.linspace(0.0, T, count + 1), events)
    y, f = _read(problem, start, times)
    peaks = []
    for values in (np.abs(f), y):  # the largest force and output, read again between their neighbours
        index = int(np.argmax(values))
        near = np.linspace(times[max(index - 1, 0)], times[min(index + 1, len(times) - 1)], REFINE + 1)
        again = _read(problem, start, near)
        peaks.append(float(max(values[index], np.max(np.abs(again[1]) if values is not y else again[0]))))
    peak, highest = peaks
    quiet = np.searchsorted(times, 0.75 * T)  # the last quarter
    standing = settling = residual = None
    if problem.dither is not None:
        end = _dithered_end(problem, start, S, T)
        if end is not None:
            mean, residual, swing = end
            standing = abs(mean)
            outside = np.nonzero(np.abs(y - mean) > BAND * S + swing)[0]
            settling = 0.0 if outside.size == 0 else float(times[min(outside[-1] + 1, len(times) - 1)])
    elif (not any(t > 0.75 * T for t in events)
          and np.ptp(y[quiet:]) <= STILL * S and np.ptp(f[quiet:]) <= STILL * max(peak, 1.0)):  # at rest
        standing = float(abs(y[-1]))
        outside = np.nonzero(np.abs(y - y[-1]) > BAND * S)[0]
        settling = 0.0 if outside.size == 0 else float(times[min(outside[-1] + 1, len(times) - 1)])
    return Cost(step=S, horizon=T, standing_error=standing, settling_time=settling,
                overshoot=max(0.0, highest) / S, peak_force=peak,
                rms_force=float(math.sqrt(np.trapezoid(f * f, times) / T)), residual_oscillation=residual)


def _dithered_end(problem, start, S, T):
    """(the output's mean, the first harmonic of its oscillation at the dither's frequency, half its swing) over
    the last dither period, where the output at the dither's phase 0 varies less than DITHER_STILL S over the last
    quarter of the horizon T; None where it does not. The mean and the harmonic are exact to rounding
    (:meth:`~dfwb.engine.periodic.LoopProblem.period_trace`: Gauss-Legendre on the smooth pieces)."""
    period = 2.0 * math.pi / problem.dither.w_d
    phases = np.arange(math.ceil(0.75 * T / period), math.floor(T / period) + 1) * period
    if len(phases) < 3:
        return None  # fewer than two dither periods in the last quarter: nothing to judge
    states, _ = problem.solver(start).readings(phases)
    if np.ptp(np.array(states)[:, problem.output]) > DITHER_STILL * S:
        return None
    harmonics, _F, _counts, trace = problem.period_trace(states[-2], period)
    signed = math.copysign(harmonics[0], float(np.mean(trace["y"])))
    return signed, harmonics[1], float(0.5 * np.ptp(trace["y"]))
