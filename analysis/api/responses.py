"""The response objects of the public API: results with a ``.plot()``, in python-control's style.

:class:`DescribingFunctionResponse` holds N(F, omega) over a broadcast grid of
force amplitudes and frequencies, :class:`LimitCycleResponse` the predicted
limit cycles of a plant under a controller G(s) with the DF map they were
found on. Both keep the per-point data in the one record shape of a DF point
(:meth:`dfwb.engine.describing.DFResult.as_dict`) or the engine's
:class:`~dfwb.engine.limit_cycles.Cycle`, and draw a Nyquist plot of -1/N
with units on the axes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DescribingFunctionResponse", "LimitCycleResponse"]


@dataclass(eq=False)
class DescribingFunctionResponse:
    """The describing function N(F, omega) of a plant over a grid of points.

    Made by :func:`dfwb.describing_function`. Arrays are shaped like
    ``np.broadcast(F, omega)``; for scalar F and omega (shape ``()``) ``N`` is
    a complex scalar and ``periodic`` a bool scalar.

    Attributes
    ----------
    plant : str
        The plant's registry name.
    params : dict
        The plant parameters given (checked, as floats; defaults not filled in).
    F : ndarray of float
        Force amplitude [N] of every point (broadcast).
    omega : ndarray of float
        Frequency [rad/s] of every point (broadcast).
    N : ndarray of complex
        The describing function X_1 / F [m/N].
    harmonics : ndarray of float
        |X_k| [m], k = 0 .. harmonics, on a trailing axis: shape ``N.shape + (harmonics + 1,)``.
    periodic : ndarray of bool
        Whether the response at the point settled on a periodic orbit.
    points : list of dict
        The record of every point (:meth:`dfwb.engine.describing.DFResult.as_dict`), in C
        (row-major) order of the grid: ``points[i]`` belongs to ``N.flat[i]``. The same shape
        as a row of ``results.json`` (and, flattened, of ``results.csv``).
    """

    plant: str
    params: dict
    F: np.ndarray
    omega: np.ndarray
    N: Any
    harmonics: np.ndarray
    periodic: Any
    points: list = field(repr=False)

    @property
    def shape(self) -> tuple:
        """The grid's shape, ``np.broadcast(F, omega).shape``."""
        return np.shape(self.F)

    @property
    def minus_inverse(self) -> np.ndarray:
        """-1/N [N/m], NaN where N = 0 (a plant that does not engage)."""
        N = np.asarray(self.N, dtype=complex)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(N == 0, np.nan + 0j, -1.0 / np.where(N == 0, 1.0, N))

    def plot(self, ax=None, **style) -> list:
        """Nyquist plot of -1/N: one line along the last axis of the grid per leading index.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw; a new figure's axes when None.
        **style
            Passed to ``ax.plot`` (e.g. ``marker="o"``).

        Returns
        -------
        list of matplotlib.lines.Line2D
            The lines drawn, one per curve.

        Examples
        --------
        >>> import dfwb
        >>> response = dfwb.describing_function("friction", F=[[10.0], [20.0]], omega=[0.5, 1.0, 2.0])
        >>> lines = response.plot()
        >>> len(lines), lines[0].axes.get_xlabel()
        (2, 'Re{-1/N} [N/m]')
        """
        from dfwb.plotting.plots import IM_INVERSE, RE_INVERSE, get_axes

        ax = get_axes(ax)
        inverse = np.atleast_1d(self.minus_inverse)
        F = np.atleast_1d(self.F)
        omega = np.atleast_1d(self.omega)
        curves = inverse.reshape(-1, inverse.shape[-1])
        forces = F.reshape(curves.shape)
        omegas = omega.reshape(curves.shape)
        lines = []
        for values, Fs, ws in zip(curves, forces, omegas):
            label = f"{self.plant}: " + (f"F = {Fs[0]:g} N" if np.all(Fs == Fs[0]) else f"omega = {ws[0]:g} rad/s")
            kwargs = dict({"marker": "o", "ms": 4} if len(values) == 1 else {}, label=label)
            kwargs.update(style)
            line, = ax.plot(values.real, values.imag, **kwargs)
            lines.append(line)
        ax.set_xlabel(RE_INVERSE)
        ax.set_ylabel(IM_INVERSE)
        ax.grid(alpha=0.3)
        return lines


@dataclass(eq=False)
class LimitCycleResponse:
    """Limit cycles of a plant under a controller G(s), predicted by harmonic balance G(jw) N(F, w) = -1.

    Made by :func:`dfwb.limit_cycles`.

    Attributes
    ----------
    plant : str
        The plant's registry name.
    params : dict
        The plant parameters given (checked, as floats).
    G : control.TransferFunction
        The controller, force = -G(s) position.
    predictions : list of dfwb.engine.limit_cycles.Cycle
        Sorted by F; empty when there is none in the ranges. Each has ``F`` [N], ``omega``
        [rad/s], ``N`` [m/N], ``amplitude_x`` [m], ``period`` [s], ``stable`` (Loeb's
        criterion), ``loeb``, ``distortion``, ``residual``, ``periodic`` and ``as_dict()``.
    F_grid : ndarray of float
        The DF map's force amplitudes [N].
    omega_grid : ndarray of float
        The DF map's frequencies [rad/s].
    N_grid : ndarray of complex
        N on the map [m/N], shape ``(len(F_grid), len(omega_grid))``.
    cycles : list of dfwb.engine.periodic.TrueCycle
        With ``exact=True``: the exact closed loop's periodic orbits (``omega``, ``period``,
        ``amplitude_x``, ``F``, ``stable``, ``multipliers``, ``prediction``, ``as_dict()``).
    links : list
        With ``exact=True``: for each prediction the index of its true cycle in ``cycles``, or
        None (no true cycle near it: a false alarm).
    """

    plant: str
    params: dict
    G: Any
    predictions: list
    F_grid: np.ndarray = field(repr=False)
    omega_grid: np.ndarray = field(repr=False)
    N_grid: np.ndarray = field(repr=False)
    cycles: list = field(default_factory=list)
    links: list = field(default_factory=list)

    def plot(self, ax=None, curves: int = 6) -> list:
        """Nyquist plot: G(jw), -1/N(F, w) for ``curves`` forces of the map, the predictions marked.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw; a new figure's axes when None.
        curves : int
            How many -1/N curves (forces of the map) to draw.

        Returns
        -------
        list of matplotlib.lines.Line2D
            G(jw) first, then the -1/N curves, then one marker per prediction (filled: stable),
            then one star per true cycle (``exact=True``).

        Examples
        --------
        >>> import dfwb
        >>> response = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", F_range=(0.01, 100),
        ...                              omega_range=(0.1, 50), n_F=6, n_omega=12)
        >>> lines = response.plot()
        >>> len(lines), lines[0].get_label(), lines[0].axes.get_xlabel()
        (8, 'G(jw)', 'Re [N/m]')
        """
        from dfwb.plotting.plots import get_axes, limit_cycle_plane

        return limit_cycle_plane(get_axes(ax, figsize=(6.5, 5)), self.G, self.F_grid, self.omega_grid,
                                 self.N_grid, self.predictions, curves, true_cycles=self.cycles)
