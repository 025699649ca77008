"""The true limit cycles of a user's co-simulation FMU under G(s): the loop co-simulated, refined, extrapolated.

An FMU that can only be stepped is run as a master runs it: over each
communication step h the plant's output y is held (its value at the step's
start) and the controller, ``force = -G(s) y``, is solved exactly for it (its
state-space form discretised by the matrix exponential); the force into the
FMU is the step's mean of that force. From first forces +-F0 (the
controller's state set as for model exchange, :mod:`dfwb.foreign.loop`) the
loop runs until its motion settles: to rest, or to a cycle, read on the
upward crossings of the middle of the output's swing (interpolated between
steps). The cycle's period and first harmonics are measured at n = 32, 64,
128, ... steps per period (of the cycle found first), each level continued from the last, and
extrapolated with :func:`dfwb.foreign.held.richardson`, whose estimate is the
reported error.

A cycle that forward runs settle on attracts what is near it: it is reported
stable, without multipliers (a stepped FMU gives no Jacobian). Unstable
cycles are out of reach here, and the search says so.
"""

import math

import numpy as np
from scipy.linalg import expm

from dfwb.base.defaults import HARMONICS
from dfwb.foreign.held import richardson

__all__ = ["settle_and_refine", "discretise"]

FIRST_STEPS = 32  # steps per reference period at the first level
MAX_STEPS = 4096  # ... and at the finest (about)
RESETTLE = 6  # periods a finer level runs before it is measured
MEASURE = 4  # periods measured at each level
MAX_CROSSINGS = 400  # quarter periods a level waits for its crossings before the run counts as not settled
TRACE = 200  # samples of the trace over one period


def discretise(A, B, C, D, h):
    """(Phi, Gamma, Cm, Dm) for a step h with y held: w' = Phi w + Gamma y, and the step's mean force
    -(Cm w + Dm y) (Van Loan's block exponential gives the integrals of e^{As})."""
    n = len(B)
    M = np.zeros((3 * n, 3 * n))
    M[:n, :n], M[:n, n:2 * n], M[n:2 * n, 2 * n:] = A, np.eye(n), np.eye(n)
    E = expm(M * h)
    Phi, E1, E2 = E[:n, :n], E[:n, n:2 * n], E[:n, 2 * n:]
    return Phi, E1 @ B, C @ E1 / h, float(C @ E2 @ B) / h + D


class _Master:
    """The closed loop of one co-simulation instance, stepped at h with the controller exact."""

    def __init__(self, instance, A, B, C, D, w):
        self.inst, self.A, self.B, self.C, self.D, self.w = instance, A, B, C, D, w
        self.y = instance.output()
        self.h = None

    def steps(self, h, count):
        """``count`` steps of h: (times, outputs, forces) with the output at each step's start and end."""
        if h != self.h:
            self.Phi, self.Gamma, self.Cm, self.Dm = discretise(self.A, self.B, self.C, self.D, h)
            self.h = h
        inst = self.inst
        times, ys, us = np.empty(count + 1), np.empty(count + 1), np.empty(count)
        times[0], ys[0] = inst.time, self.y
        for i in range(count):
            u = -(float(self.Cm @ self.w) + self.Dm * self.y)
            inst.set_input(u)
            inst.do_step(h)
            self.w = self.Phi @ self.w + self.Gamma * self.y
            self.y = inst.output()
            times[i + 1], ys[i + 1], us[i] = inst.time, self.y, u
        if not (np.all(np.isfinite(ys)) and np.all(np.isfinite(self.w))):
            raise FloatingPointError(f"the loop is not finite (NaN or overflow) before t = {inst.time!r}")
        return times, ys, us


def _upward(times, ys, middle):
    """Times where y crosses ``middle`` upwards, linearly interpolated between steps."""
    below, above = ys[:-1] < middle, ys[1:] >= middle
    i = np.nonzero(below & above)[0]
    return times[i] + (middle - ys[i]) / (ys[i + 1] - ys[i]) * (times[i + 1] - times[i])


def _measure(master, h, middle, periods, period):
    """Run until ``periods`` whole periods between upward crossings (``period``: about how long one is):
    (first crossing, period, samples), or None if they do not come within MAX_CROSSINGS quarter periods."""
    times, ys, us = [], [], []
    chunk = max(int(period / h / 4), 1)  # a quarter period a time
    for _ in range(MAX_CROSSINGS):
        t, y, u = master.steps(h, chunk)
        times.append(t if not times else t[1:])
        ys.append(y if not ys else y[1:])
        us.append(u)
        crossings = _upward(np.concatenate(times), np.concatenate(ys), middle)
        if len(crossings) > periods:
            break
    else:
        return None
    t, y, u = np.concatenate(times), np.concatenate(ys), np.concatenate(us)
    start, end = crossings[-periods - 1], crossings[-1]
    return start, (end - start) / periods, (t, y, u)


def _harmonics(start, period, periods, samples):
    """Y_k of the output (linear between steps) and the force's first harmonic (held over each step) over
    ``periods`` periods from ``start``: the output's by the trapezoidal rule on the steps inside, its ends
    interpolated; the force's exactly."""
    t, y, u = samples
    end = start + periods * period
    inside = (t > start) & (t < end)
    nodes = np.concatenate(([start], t[inside], [end]))
    values = np.interp(nodes, t, y)
    omega = 2 * math.pi / period
    k = np.arange(HARMONICS + 1)
    weights = np.diff(nodes)
    w = np.zeros(len(nodes))
    w[:-1] += weights / 2
    w[1:] += weights / 2
    Y = (np.exp(-1j * np.outer(k, omega * (nodes - start))) @ (w * values)) * (2.0 / (end - start))
    Y[0] /= 2
    left = np.clip(t[:-1], start, end)
    right = np.clip(t[1:], start, end)
    pieces = (np.exp(-1j * omega * (left - start)) - np.exp(-1j * omega * (right - start))) / (1j * omega)
    force = complex(np.sum(u * pieces)) * (2.0 / (end - start))
    return Y, force


def settle_and_refine(instance, A, B, C, D, w0, T_ref, rtol, settle):
    """(outcome, cycle dict or None) of the loop from the controller state w0 (the instance started), run
    ``settle`` reference periods T_ref before its swing is read."""
    master = _Master(instance, A, B, C, D, w0)
    n = FIRST_STEPS
    h = T_ref / n
    master.steps(h, int(settle * n * 2 / 3))
    _t, ys, _u = master.steps(h, int(settle * n / 3))
    low, high = float(np.min(ys)), float(np.max(ys))
    if not high - low > 1e-9 * max(abs(high), abs(low), 1e-300):
        return "rest", None
    middle = 0.5 * (low + high)
    found = _measure(master, h, middle, MEASURE, T_ref)  # the cycle's own period sets the levels' steps
    if found is None:
        return "not settled", None
    period = found[1]
    h = period / FIRST_STEPS
    master.steps(h, int(RESETTLE * period / h))
    levels = []
    while True:
        measured = _measure(master, h, middle, MEASURE, period)
        if measured is None:
            return "lost at finer steps", None
        start, period, samples = measured
        Y, force = _harmonics(start, period, MEASURE, samples)
        levels.append((period, Y, force))
        estimates = [richardson([level[0] for level in levels]), richardson([abs(lv[1][1]) for lv in levels]),
                     richardson([abs(lv[2]) for lv in levels])]
        if all(error <= rtol * abs(value) for value, error in estimates) or period / h >= MAX_STEPS / 2:
            break
        h /= 2
        master.steps(h, int(RESETTLE * period / h))
        _t, ys, _u = master.steps(h, int(period / h) + 1)
        middle = 0.5 * (float(np.min(ys)) + float(np.max(ys)))
    (period, period_error), (amplitude, amplitude_error), (F, F_error) = estimates
    period, amplitude, F = float(abs(period)), float(abs(amplitude)), float(abs(F))
    t, y, u = samples
    one = (t >= start) & (t <= start + period)
    trace_t = start + period * np.arange(TRACE + 1) / TRACE
    forces = u[np.clip(np.searchsorted(t, trace_t, side="right") - 1, 0, len(u) - 1)]
    return "cycle", {
        "omega": 2 * math.pi / period, "period": period, "amplitude_x": amplitude, "F": F, "stable": True,
        "multipliers": [], "residual": 0.0, "iterations": len(levels), "state": [float(v) for v in master.w],
        "returns": 1, "harmonics": [abs(v) for v in Y], "counts": {"events": 0}, "signature": [], "spectrum": [],
        "sections": [], "swing": [float(np.ptp(y[one])) if np.any(one) else 0.0],
        "errors": {"period": float(period_error), "amplitude_x": float(amplitude_error), "F": float(F_error),
                   "steps_per_period": int(round(period / h))},
        "trace": {"t": (trace_t - start).tolist(), "y": np.interp(trace_t, t, y).tolist(), "f": forces.tolist(),
                  "events": []},
    }
