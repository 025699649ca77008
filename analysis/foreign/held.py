"""A co-simulation FMU driven by a held sine, refined until its DF converges, with Richardson extrapolation.

A generic master can only hold an input over each communication step. dfwb
holds the step's mean of ``F cos(w t)`` (the exact impulse of the force over
the step, so a free mass gains no spurious drift), reads the output at every
step and takes X_k by the trapezoidal rule over each period. Both errors
vanish as the step h does, so the DF is computed at n = 32, 64, 128, ...
steps per period, each run continued from the last (its state is close to
the finer run's steady state), and Richardson's extrapolation at the
observed order gives N; its error estimate is :func:`richardson`'s, with the
transient that remains. It stops when that estimate is below ``rtol |N|`` or
at :data:`MAX_STEPS` steps per period.

Better inputs where the FMU takes them: an FMI 2.0 FMU that can interpolate
inputs gets each step's line closest to the sine (its value and slope), and
an FMI 3.0 FMU whose force input has ``intermediateUpdate`` gets the sine
itself whenever it asks inside a step (its intermediate-update callback), so
only the output's sampling is left to refine.
"""

import math

import numpy as np

from dfwb.base.defaults import DF_PERIODS, HARMONICS
from dfwb.foreign.steady import Sections

__all__ = ["point", "richardson", "FIRST_STEPS", "MAX_STEPS"]

FIRST_STEPS = 32
MAX_STEPS = 1 << 14  # steps per period at the finest level
JUMP_TOL = 1e-10  # a located jump's time, in periods


def richardson(values):
    """(extrapolated value, error estimate) of a sequence at steps h, h/2, h/4, ...

    The order is observed from the last three values (clipped to [0.5, 8]).
    The error estimate is the last change of the extrapolated value (it bounds
    the error of the coarser of the two, and the finer one's is smaller where
    they converge), or, if larger, the change before scaled by its own rate of
    decrease: that covers a last change small by chance, two levels whose
    errors happen to agree (measured on the two-mass backlash, whose observed
    order wanders between 1 and 4). The finer raw value's change, the bound
    used before, was up to 4000 times the true error of the extrapolated value
    (a held saturation, of order 1). Infinite with fewer than four levels.
    """
    values = [complex(v) for v in values]

    def extrapolated(seq):
        if len(seq) < 3:
            return seq[-1]
        d1, d2 = abs(seq[-1] - seq[-2]), abs(seq[-2] - seq[-3])
        if d1 == 0.0:
            return seq[-1]
        p = min(max(math.log2(d2 / d1), 0.5), 8.0) if d2 > 0.0 else 8.0
        return seq[-1] + (seq[-1] - seq[-2]) / (2.0 ** p - 1.0)

    if len(values) < 4:
        return extrapolated(values), math.inf
    now, before, earlier, first = (extrapolated(values[:len(values) - i]) for i in range(4))
    last, previous, oldest = abs(now - before), abs(before - earlier), abs(earlier - first)
    return now, max(last, previous * min(previous / oldest, 1.0) if oldest > 0.0 else previous)


class _Held:
    """Periods of a co-simulation FMU under a held (or interpolated) sine with n steps per period.

    ``interpolate``: the FMU takes input derivatives (FMI 2.0 ``canInterpolateInputs``): each step's
    input is the straight line closest to the sine over the step (its mean and its first moment exact),
    given as the value at the step's start and a slope.

    ``locate``: the FMU can save and restore its state: a step whose output jumps (a relay, a hard stop)
    is repeated around the jump (:meth:`_locate`) so that the trapezoidal rule integrates each side of
    the jump on its own, the jump's time known to :data:`JUMP_TOL` of the period instead of the step grid's.
    """

    def __init__(self, instance, F, omega, harmonics, interpolate=False, locate=False):
        self.inst, self.F, self.omega, self.K = instance, F, omega, harmonics
        self.k = np.arange(harmonics + 1)
        self.y = None
        self.interpolate = interpolate
        self.locate = locate and not instance.intermediate
        self.changes = [0.0, 0.0]  # the output's last two changes per step (a jump is far larger)
        self.y_scale = 0.0
        self.low, self.high = math.inf, -math.inf  # the output's range seen
        self.located = self.missed = 0
        self.saved = [None, None]  # the FMU's states at the last two steps' starts, overwritten

    def close(self):
        for state in self.saved:
            if state is not None:
                self.inst.free(state)
        self.saved = [None, None]

    def _input(self, t0, h, probe=False):
        """Set the input for a step of size h from t0: the step's mean of the sine (its line, if
        interpolated), or, for a probe, the sine at the step's end held."""
        inst, omega, F = self.inst, self.omega, self.F
        if inst.intermediate:  # it asks for the force inside the step (input_law): the sine at the start
            inst.set_input(F * math.cos(omega * t0))
            return
        if probe:
            inst.set_input(F * math.cos(omega * (t0 + h)))
            if self.interpolate:
                inst.set_input_slope(0.0)
            return
        a = omega * h / 2
        middle = omega * (t0 + h / 2)
        mean = math.sin(a) / a if a > 0.0 else 1.0  # the step's mean of cos over its midpoint value
        if self.interpolate:
            moment = 24.0 * (math.sin(a) - a * math.cos(a)) / (omega ** 2 * h ** 3) if a > 1e-4 else 1.0
            slope = -F * moment * math.sin(middle)
            inst.set_input(F * mean * math.cos(middle) - slope * h / 2)
            inst.set_input_slope(slope)
        else:
            inst.set_input(F * mean * math.cos(middle))

    def _step(self, t0, h, probe=False):
        self._input(t0, h, probe)
        self.inst.do_step(h)
        return self.inst.output()

    def _jumped(self, before, after, n):
        """True if the change is a jump: 8 times the last two steps' changes, and 8 / n of the output's
        swing (a sine's step changes by at most pi / n of it: a kink is no jump), and not rounding."""
        change = abs(after - before)
        return change > 8.0 * max(self.changes) and change > 8.0 * (self.high - self.low) / n and \
            change > 1e-6 * self.y_scale

    def _locate(self, start, grid, y0, size, saved):
        """The steps from ``start`` (state ``saved``, output y0) to grid[-1] again, the output's jump (of
        ``size``) located: [(time, output)] at grid[1:] and just before and after the jump, in order, or None.

        The window is the jump's step and the one before (a held mean crosses a threshold up to a step
        after the sine does). Probes from ``start`` with the sine at their end held (a relay then switches
        where the sine crosses its threshold) bisect the jump's time to JUMP_TOL of the period; the window is
        then run again with the sine's means, up to just before the jump, across it, and on. None if the
        probes do not show the jump or the run again jumps elsewhere, False if the output has no jump there
        (the caller runs the steps as they were).
        """
        inst, end = self.inst, grid[-1]

        def probe(t):
            inst.restore(saved, start)
            return self._step(start, t - start, probe=True)

        lo, hi = start, end
        y_lo, y_hi = y0, probe(hi)
        if abs(y_hi - y0) <= size / 2:
            return None
        tol = JUMP_TOL * 2 * math.pi / self.omega
        for _ in range(64):  # bounded: the window / tol < 2^64
            if hi - lo <= tol:
                break
            middle = 0.5 * (lo + hi)
            y = probe(middle)
            if abs(y - y0) > size / 2:
                hi, y_hi = middle, y
            else:
                lo, y_lo = middle, y
        if abs(y_hi - y_lo) <= size / 4:  # no jump across the bracket: a kink, a steep stretch
            inst.restore(saved, start)
            return False
        inst.restore(saved, start)
        times = sorted({lo, hi, *grid[1:]} - {start})
        nodes, t, y = [], start, y0
        for following in times:
            y = self._step(t, following - t, probe=(t == lo))
            if abs(y - y0) > size / 2 and following < hi:  # it jumped before the bracket
                return None
            nodes.append((following, y))
            t = following
        after = dict(nodes)[hi]
        if abs(after - y0) <= size / 2 or any(abs(v - after) > size / 2 for s, v in nodes if s > hi):
            return None
        return nodes

    def run(self, n):
        """One period of n steps from the current time: (section, X_k, the output's largest size)."""
        inst, omega = self.inst, self.omega
        T = 2 * math.pi / omega
        h = T / n
        t0 = inst.time
        samples = np.empty(n + 1)
        samples[0] = self.y if self.y is not None else inst.output()
        self.y_scale = max(self.y_scale, abs(samples[0]))
        inside = {}  # first step of a window -> the nodes of its located jump
        saved = self.saved
        held = None if inst.intermediate or self.interpolate else \
            (self.F * math.sin(omega * h / 2) / (omega * h / 2)) * np.cos(omega * (t0 + np.arange(n) * h + h / 2))
        for i in range(n):
            start = t0 + i * h
            if self.locate:
                saved[i % 2] = inst.save(saved[i % 2])
            if held is None:
                y = self._step(start, h)
            else:  # the step's mean of the sine, computed for the period at once (a held step is hot)
                inst.set_input(held[i])
                inst.do_step(h)
                y = inst.output()
            if self.locate and self._jumped(samples[i], y, n):
                back = 1 if i > 0 and i - 1 not in inside else 0  # the window: this step and the one before
                first = i - back
                grid = [t0 + j * h for j in range(first, i + 2)]
                nodes = self._locate(grid[0], grid, samples[first], abs(y - samples[first]), saved[first % 2])
                if not nodes:
                    self.missed += nodes is None
                    inst.restore(saved[i % 2], start)
                    y = self._step(start, h)
                else:
                    self.located += 1
                    values = dict(nodes)
                    if back:
                        samples[i] = values[grid[1]]
                    y = values[grid[-1]]
                    inside[first] = [grid[0]] + [node[0] for node in nodes], [samples[first]] + [v for _, v in nodes]
            inst.time = start + h  # the grid's time exactly (no sum of sub-steps' rounding)
            samples[i + 1] = y
            if i not in inside and i - 1 not in inside:
                self.changes = [self.changes[1], abs(y - samples[i])]
            self.y_scale = max(self.y_scale, abs(y))
            self.low, self.high = min(self.low, y), max(self.high, y)
        if not np.all(np.isfinite(samples)):
            raise FloatingPointError(f"the output is not finite (NaN or overflow) before t = {inst.time!r}")
        self.y = samples[-1]
        times = t0 + h * np.arange(n + 1)
        weights = np.full(n + 1, h)
        weights[[0, -1]] = h / 2
        phase = np.outer(self.k, omega * times)
        integrals = (np.cos(phase) - 1j * np.sin(phase)) @ (weights * samples)
        for first, (t, y) in inside.items():  # a located jump's window: the trapezoidal rule on each side
            t, y = np.array(t), np.array(y)
            grid = np.isin(t, times[first:first + 3])
            kernel = np.exp(-1j * np.outer(self.k, omega * t)) * y
            uniform = kernel[:, grid]
            integrals += (kernel[:, 1:] + kernel[:, :-1]) @ (np.diff(t) / 2) - \
                (uniform[:, 1:] + uniform[:, :-1]).sum(axis=1) * h / 2
        X = integrals * (2.0 / T)
        X[0] = integrals[0] / T
        return np.array([samples[-1]]), X, np.array([np.max(np.abs(samples))])


def point(instance, F, omega, params, harmonics=HARMONICS, rtol=1e-6, max_periods=DF_PERIODS):
    """(X_k, N error, periodic, periods, orbit periods, note) of one DF point of a co-simulation FMU."""
    interpolate = instance.info.can_interpolate_inputs and instance.info.major == "2"
    held = _Held(instance, F, omega, harmonics, interpolate, instance.info.can_save_state.get("co-simulation", False))
    instance.input_law = (lambda t: F * math.cos(omega * t)) if instance.intermediate else None
    mean = math.sin(math.pi / FIRST_STEPS) / (math.pi / FIRST_STEPS)
    instance.start(params, F if instance.intermediate else F * mean * math.cos(math.pi / FIRST_STEPS))
    try:
        return _refined(held, instance, F, omega, harmonics, rtol, max_periods, interpolate)
    finally:
        held.close()


def _refined(held, instance, F, omega, harmonics, rtol, max_periods, interpolate):
    n = FIRST_STEPS
    levels, periods, periodic, residual, lag = [], 0, True, 0.0, 1
    while True:
        sections = Sections(tol=min(1e-3 * rtol, 1e-9), output=0)
        steady = None
        for _ in range(max_periods):
            section, X, scale = held.run(n)
            periods += 1
            steady = sections.add(section, X, scale)
            if steady is not None:
                break
        if steady is None:
            steady = sections.average()
        periodic = periodic and steady.periodic
        residual = max(residual, steady.residual)
        lag = max(lag, steady.lag)
        levels.append(steady.X)
        N, error = richardson([X[1] for X in levels])
        if error + residual <= rtol * abs(N) or n >= MAX_STEPS:
            break
        n *= 2
    X = levels[-1].copy()
    X[1] = N  # the extrapolated first harmonic; the others at the finest step
    how = "the sine inside each step (intermediate update)" if instance.intermediate else \
        "interpolated input" if interpolate else "held input"
    note = f"{how}, {n} steps per period, Richardson over {len(levels)} levels"
    if held.located:
        note += f", {held.located} output jumps located inside steps" + (f" ({held.missed} not)" if held.missed else "")
    if not periodic:
        note = f"no periodic response within {max_periods} periods at some step: averaged; " + note
    return X, error + residual, periodic, periods, lag, note
