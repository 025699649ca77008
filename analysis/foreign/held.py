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

from dfwb.foreign.steady import Sections

__all__ = ["point", "richardson", "FIRST_STEPS", "MAX_STEPS"]

FIRST_STEPS = 32
MAX_STEPS = 1 << 14  # steps per period at the finest level


def richardson(values):
    """(extrapolated value, error estimate) of a sequence at steps h, h/2, h/4, ...

    The order is observed from the last three values (clipped to [0.5, 8]).
    The error estimate is the larger of twice the change of the extrapolated
    value from the previous level and the last raw change: the raw change
    bounds the finer value's error for any order of at least 1, and the
    extrapolated value is trusted no further than that when the extrapolations
    agree with each other yet not with the truth (measured: the two-mass
    backlash at 50 N, 20 rad/s, where the order falls to about 1 at the finest
    steps). Infinite with fewer than four levels.
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
    now, before = extrapolated(values), extrapolated(values[:-1])
    return now, max(2.0 * abs(now - before), abs(values[-1] - values[-2]))


class _Held:
    """Periods of a co-simulation FMU under a held (or interpolated) sine with n steps per period.

    ``interpolate``: the FMU takes input derivatives (FMI 2.0 ``canInterpolateInputs``): each step's
    input is the straight line closest to the sine over the step (its mean and its first moment exact),
    given as the value at the step's start and a slope.
    """

    def __init__(self, instance, F, omega, harmonics, interpolate=False):
        self.inst, self.F, self.omega, self.K = instance, F, omega, harmonics
        self.k = np.arange(harmonics + 1)
        self.y = None
        self.interpolate = interpolate

    def run(self, n):
        """One period of n steps from the current time: (section, X_k, the output's largest size)."""
        inst, omega = self.inst, self.omega
        T = 2 * math.pi / omega
        h = T / n
        t0 = inst.time
        a = omega * h / 2
        mean = math.sin(a) / a  # the step's mean of cos over its midpoint value
        moment = 24.0 * (math.sin(a) - a * math.cos(a)) / (omega ** 2 * h ** 3)  # the least-squares slope's factor
        samples = np.empty(n + 1)
        samples[0] = self.y if self.y is not None else inst.output()
        for i in range(n):
            middle = omega * (t0 + (i + 0.5) * h)
            if inst.intermediate:  # it asks for the force inside the step (input_law): the sine at the start
                inst.set_input(self.F * math.cos(omega * (t0 + i * h)))
            elif self.interpolate:
                slope = -self.F * moment * math.sin(middle)
                inst.set_input(self.F * mean * math.cos(middle) - slope * h / 2)
                inst.set_input_slope(slope)
            else:
                inst.set_input(self.F * mean * math.cos(middle))
            inst.do_step(h)
            samples[i + 1] = inst.output()
        if not np.all(np.isfinite(samples)):
            raise FloatingPointError(f"the output is not finite (NaN or overflow) before t = {inst.time!r}")
        self.y = samples[-1]
        times = t0 + h * np.arange(n + 1)
        weights = np.full(n + 1, h)
        weights[[0, -1]] = h / 2
        phase = np.outer(self.k, omega * times)
        integrals = (np.cos(phase) - 1j * np.sin(phase)) @ (weights * samples)
        X = integrals * (2.0 / T)
        X[0] = integrals[0] / T
        return np.array([samples[-1]]), X, np.array([np.max(np.abs(samples))])


def point(instance, F, omega, params, harmonics=10, rtol=1e-6, max_periods=150):
    """(X_k, N error, periodic, periods, orbit periods, note) of one DF point of a co-simulation FMU."""
    interpolate = instance.info.can_interpolate_inputs and instance.info.major == "2"
    held = _Held(instance, F, omega, harmonics, interpolate)
    instance.input_law = (lambda t: F * math.cos(omega * t)) if instance.intermediate else None
    n = FIRST_STEPS
    mean = math.sin(math.pi / n) / (math.pi / n)
    instance.start(params, F if instance.intermediate else F * mean * math.cos(math.pi / n))
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
    if not periodic:
        note = f"no periodic response within {max_periods} periods at some step: averaged; " + note
    return X, error + residual, periodic, periods, lag, note
