"""The periodic steady state of a driven FMU, read on the section t = kT.

Each forcing period gives a section vector (the continuous states of a model
exchange FMU, or the Real outputs of a co-simulation FMU) and the period's
Fourier coefficients X_k of the output. :class:`Sections` says when they
repeat: with an orbit of 1 to :data:`MAX_LAG` periods, or repeating up to a
constant drift per period (a free mass whose position creeps under a held
sine), whose ramp it removes from the harmonics. The same test for every
driver, so that "periodic" means the same thing whatever the FMU's kind.
"""

import math

import numpy as np

__all__ = ["Sections", "Steady", "MAX_LAG", "AVERAGE_PERIODS", "ramp"]

MAX_LAG = 4
AVERAGE_PERIODS = 20  # the window a response that never repeats is averaged over


def ramp(drift, harmonics):
    """X_k of the ramp ``drift * t / T`` over one period (k = 0 excluded: the mean is the caller's)."""
    return np.array([0.0] + [1j * drift / (k * math.pi) for k in range(1, harmonics + 1)])


class Steady:
    """A found steady state: X_k averaged over its orbit, the orbit's periods, the drift per period."""

    def __init__(self, X, lag, drift, residual, periodic=True):
        self.X, self.lag, self.drift, self.residual, self.periodic = X, lag, drift, residual, periodic


class Sections:
    """Section vectors and harmonics, period after period; :meth:`add` returns a :class:`Steady` once they repeat.

    Parameters
    ----------
    tol : float
        Relative tolerance on the section and on X_1.
    output : int or None
        The index of the output in the section vector (for the drift of its
        position), or None if the output is not in it.
    """

    def __init__(self, tol, output=None):
        self.tol, self.output = tol, output
        self.sections, self.spectra = [], []
        self.scale = None

    def add(self, section, X, scale=None):
        """Record one period; ``scale``: each section component's largest size over the period (default: now)."""
        section = np.asarray(section, dtype=float)
        X = np.asarray(X, dtype=complex)
        if not (np.all(np.isfinite(section)) and np.all(np.isfinite(X))):
            raise FloatingPointError("the response is not finite (NaN or overflow)")
        self.sections.append(section)
        self.spectra.append(X)
        scale = np.abs(section) if scale is None else np.asarray(scale, dtype=float)
        self.scale = scale if self.scale is None else np.maximum(self.scale, scale)
        if len(self.sections) > 4 * MAX_LAG + 4:  # only the recent periods matter
            del self.sections[0], self.spectra[0]
        return self._repeating()

    def _floor(self):
        """Each component's scale, at least 1e-6 of the largest (a component that stays near 0)."""
        return np.maximum(self.scale, 1e-6 * float(np.max(self.scale, initial=0.0)))

    def _close(self, a, b):
        """Equal to tol of each component's scale."""
        return bool(np.all(np.abs(a - b) <= self.tol * self._floor()))

    def change(self, back=0):
        """The largest change of a component, relative to its scale, over the period ``back`` periods before
        the last (0: the last period's)."""
        a, b = self.sections[-1 - back], self.sections[-2 - back]
        return float(np.max(np.abs(a - b) / np.maximum(self._floor(), 1e-300)))

    def _repeating(self):
        s, X = self.sections, self.spectra
        amplitude = max(abs(X[-1][1]), 1e-300) if len(X[-1]) > 1 else 1e-300
        for lag in range(1, MAX_LAG + 1):
            if len(s) < 2 * lag + 1:
                break
            window = np.mean(X[-lag:], axis=0)
            previous = np.mean(X[-2 * lag:-lag], axis=0)
            if not abs(window[1] - previous[1]) <= self.tol * amplitude * 10:
                continue
            residual = self._remaining(lag)
            if self._close(s[-1], s[-1 - lag]):  # repeats
                return Steady(window, lag, 0.0, residual)
            step, before = s[-1] - s[-1 - lag], s[-1 - lag] - s[-1 - 2 * lag]
            if self._close(step, before):  # repeats up to a constant drift per orbit
                drift = float(step[self.output]) / lag if self.output is not None else 0.0
                corrected = window - ramp(drift, len(window) - 1)
                corrected[0] = window[0]  # the mean of the last orbit, drift included
                return Steady(corrected, lag, drift, residual)
        return None

    def _remaining(self, lag):
        """What the transient may still change in X_1: the last change times rho / (1 - rho), rho its ratio.

        A transient that decays geometrically by rho per orbit has that much
        left; rho is the ratio of the last two changes, at most 0.99 (a ratio
        of 1 or more, or too few orbits to tell, counts as 0.99: 99 changes).
        """
        X = [np.mean(self.spectra[len(self.spectra) - (i + 1) * lag:len(self.spectra) - i * lag], axis=0)[1]
             for i in range(min(3, len(self.spectra) // lag))]
        if len(X) < 2:
            return math.inf
        last = abs(X[0] - X[1])
        rho = abs(X[1] - X[2]) and last / abs(X[1] - X[2]) if len(X) == 3 else 0.99
        rho = min(rho, 0.99)
        return last * rho / (1.0 - rho) + 0.0

    def average(self):
        """The steady state of a response that never repeated: X_k over the last periods, not periodic."""
        count = min(AVERAGE_PERIODS, len(self.spectra))
        window = np.mean(self.spectra[-count:], axis=0)
        spread = float(np.max([abs(x[1] - window[1]) for x in self.spectra[-count:]], initial=0.0))
        return Steady(window, 1, 0.0, spread, periodic=False)
