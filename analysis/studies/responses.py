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

import html
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["DescribingFunctionResponse", "LimitCycleResponse", "ContinuationResponse", "HuntingMapResponse",
           "MarginResponse"]


class _Shown:
    """How a response shows itself: ``repr`` one line (its class and the summary's first line), ``str`` the
    summary with units (what the command line prints), and the summary in a notebook (``_repr_html_``)."""

    def __repr__(self):
        return f"<{type(self).__name__}: {self.summary().splitlines()[0]}>"

    def __str__(self):
        return self.summary()

    def _repr_html_(self):
        return f"<pre>{html.escape(self.summary())}</pre>"


@dataclass(eq=False, repr=False)
class DescribingFunctionResponse(_Shown):
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
        ``|X_k|`` [m], k = 0 .. harmonics, on a trailing axis: shape ``N.shape + (harmonics + 1,)``.
    periodic : ndarray of bool
        Whether the response at the point settled on a periodic orbit.
    N_error : ndarray of float
        The estimated absolute error of N [m/N] for a user's FMU (``inf`` where the
        point failed); NaN for dfwb's own plants, whose engine is exact (to its 1e-11
        section tolerance) and estimates nothing.
    points : list of dict
        The record of every point (:meth:`dfwb.engine.describing.DFResult.as_dict`), in C
        (row-major) order of the grid: ``points[i]`` belongs to ``N.flat[i]``. The same shape
        as a row of ``results.json`` (and, flattened, of ``results.csv``).

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.describing_function("friction", F=10.0, omega=[1.0, 2.0])
    >>> response
    <DescribingFunctionResponse: describing function of friction: 2 point(s), F 10 to 10 N, omega 1 to 2 rad/s>
    >>> print(response)  # doctest: +NORMALIZE_WHITESPACE
    describing function of friction: 2 point(s), F 10 to 10 N, omega 1 to 2 rad/s
           F [N]  omega [rad/s]                    N [m/N]                 -1/N [N/m]  periodic
              10              1          -0.23505-0.29799j             1.6318-2.0687j      True
              10              2        -0.082037-0.084764j             5.8956-6.0916j      True
    >>> response.shape, response.periodic.tolist(), response.points[1]["omega"]
    ((2,), [True, True], 2.0)
    """

    plant: str
    params: dict
    F: np.ndarray
    omega: np.ndarray
    N: Any
    harmonics: np.ndarray
    periodic: Any
    points: list = field(repr=False)
    N_error: Any = None

    ROWS = 20  # points listed by summary(), at most

    def summary(self) -> str:
        """The grid and a table of its points with units (the first ``ROWS``), as ``print(response)`` shows it."""
        F, omega = np.ravel(self.F), np.ravel(self.omega)
        N, inverse = np.ravel(np.asarray(self.N, dtype=complex)), np.ravel(self.minus_inverse)
        periodic = np.ravel(self.periodic)
        lines = [f"describing function of {self.plant}: {F.size} point(s), F {F.min():.4g} to {F.max():.4g} N, "
                 f"omega {omega.min():.4g} to {omega.max():.4g} rad/s"
                 + (f", {np.count_nonzero(~periodic)} not periodic" if not periodic.all() else ""),
                 f"{'F [N]':>12} {'omega [rad/s]':>14} {'N [m/N]':>26} {'-1/N [N/m]':>26} {'periodic':>9}"]
        for i in range(min(F.size, self.ROWS)):
            N_i, inverse_i = f"{N[i].real:.5g}{N[i].imag:+.5g}j", f"{inverse[i].real:.5g}{inverse[i].imag:+.5g}j"
            lines.append(f"{F[i]:12.6g} {omega[i]:14.6g} {N_i:>26} {inverse_i:>26} {str(bool(periodic[i])):>9}")
        if F.size > self.ROWS:
            lines.append(f"... {F.size - self.ROWS} more (response.points lists them all)")
        return "\n".join(lines)

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
        for index, (values, Fs, ws) in enumerate(zip(curves, forces, omegas)):
            label = f"{self.plant}: " + (f"F = {Fs[0]:g} N" if np.all(Fs == Fs[0]) else f"omega = {ws[0]:g} rad/s")
            kwargs = dict({"marker": "o", "ms": 4} if len(values) == 1 else {}, label=label)
            kwargs.update(style)
            line, = ax.plot(values.real, values.imag, **kwargs)
            lines.append(line)
            _mark_decades(ax, values, ws, line.get_color(), named=index == 0)
        ax.set_xlabel(RE_INVERSE)
        ax.set_ylabel(IM_INVERSE)
        ax.grid(alpha=0.3)
        return lines


def _mark_decades(ax, values, omegas, colour, named):
    """Dots where a -1/N curve passes each decade of omega (1, 10, 100 rad/s ...), named on the first curve:
    over log-spaced frequencies most points crowd near the origin, and the dots say which w is where."""
    finite = np.isfinite(values) & (omegas > 0)
    if np.all(omegas == omegas[0]) or not finite.any():
        return
    lo, hi = np.log10(omegas[finite].min()), np.log10(omegas[finite].max())
    for decade in range(int(np.ceil(lo)), int(np.floor(hi)) + 1):
        i = int(np.argmin(np.abs(np.log10(np.where(finite, omegas, np.inf)) - decade)))
        ax.plot(values[i].real, values[i].imag, "o", ms=3, color=colour)
        if named:
            ax.annotate(f"w = {10.0 ** decade:g}", (values[i].real, values[i].imag), xytext=(3, 3),
                        textcoords="offset points", fontsize="x-small", color=colour)


@dataclass(eq=False, repr=False)
class LimitCycleResponse(_Shown):
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
        ``amplitude_x``, ``F``, ``stable``, ``multipliers``, ``prediction``, ``df``, ``as_dict()``).
    links : list
        With ``exact=True``: for each prediction the index of its true cycle in ``cycles``, or
        None (no true cycle near it: a false alarm).
    coverage : dfwb.engine.cycles.Coverage or None
        With ``exact=True``: what the search of the true cycles covered (starts, amplitudes,
        horizon): no true cycle means none reached from there.
    verification : list of dict
        With ``verify=True``: the co-simulation judge of each prediction.
    runs : list of (Cycle, LoopRun)
        With ``verify=True``: each judged prediction and its run's last periods.
    F_range, omega_range : list of float
        The DF map's ranges [N], [rad/s] (derived from the plant and G unless given).
    values : dict
        G's parameters and the plant's as given.
    unit : str
        The plant output's unit.

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", F_range=(0.01, 100),
    ...                              omega_range=(0.1, 50), n_F=6, n_omega=12)
    >>> print(response)  # doctest: +ELLIPSIS
    1 limit cycle(s) of static-backlash predicted by the describing function in F 0.01 to 100 N, omega 0.1 to 50 rad/s
      [0] F = 0.248572... N, omega = 0.913731... rad/s, period 6.876... s, amplitude 0.11316... m, stable, ...
    >>> cycle = response.predictions[0]
    >>> cycle.stable, round(cycle.F, 6), response.N_grid.shape, response.exact
    (True, 0.248573, (6, 12), False)
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
    coverage: Any = None
    verification: list = field(default_factory=list, repr=False)
    runs: list = field(default_factory=list, repr=False)
    F_range: list = field(default_factory=list)
    omega_range: list = field(default_factory=list)
    values: dict = field(default_factory=dict)
    unit: str = "m"
    compensation: str = ""
    cost: Any = None
    equivalent: Any = None  # the plant parameters whose DF the compensated loop's is (Compensation.equivalent)
    df_described: Any = None  # what that DF is where it is the compensated plant's own (Compensation.df_text)
    responses: Any = None  # a dithered loop's own responses (period T_d), TrueCycles; None without a dither
    hunting: list = field(default_factory=list)  # a dithered loop's runs that hunt unlocked: {start, detail}

    @property
    def exact(self):
        """Whether the exact loop was searched."""
        return self.coverage is not None

    def as_dict(self) -> dict:
        """The answer as JSON types: what ``dfwb limit-cycle --json`` prints and a scene's results.json holds."""
        from dfwb.engine.closed_loop import judge_errors
        from dfwb.engine.cycles import relative_errors

        document = {"plant": self.plant, "G": {"num": [float(c) for c in self.G.num[0][0]],
                                               "den": [float(c) for c in self.G.den[0][0]]},
                    "params": self.params, "values": self.values, "F_range": list(self.F_range),
                    "omega_range": list(self.omega_range), "predictions": []}
        for i, prediction in enumerate(self.predictions):
            entry = prediction.as_dict()
            if self.exact:
                j = self.links[i]
                entry["true_cycle"] = j
                entry["error"] = None if j is None else relative_errors(prediction, self.cycles[j])
            document["predictions"].append(entry)
        if self.verification:
            document["verification"] = []
            for i, outcome in enumerate(self.verification):
                outcome = dict(outcome)
                if self.exact:
                    j = self.links[i]
                    outcome["error_vs_true"] = (judge_errors(outcome, self.cycles[j])
                                                if j is not None and outcome["settled"] else None)
                document["verification"].append(outcome)
        if self.exact:
            document["cycles"] = [cycle.as_dict() for cycle in self.cycles]
            document["coverage"] = self.coverage.as_dict()
        if self.compensation:
            document["compensation"] = self.compensation
            document["df_params"] = self.equivalent
        if self.cost is not None:
            document["cost"] = self.cost.as_dict()
        if self.responses is not None:
            document["responses"] = [response.as_dict() for response in self.responses]
            document["hunting"] = list(self.hunting)
        return document

    def summary(self) -> str:
        """What was found, in a few lines with units (what ``dfwb limit-cycle`` prints)."""
        from dfwb.engine.cycles import relative_errors

        u = self.unit
        equivalent = "" if not self.equivalent else ", ".join(
            f"{k} = {v:.6g}" for k, v in self.equivalent.items() if v != self.params.get(k))
        shown = self.df_described or f"as the plant with {equivalent}"
        lines = [f"{self.plant} compensated by {self.compensation}: judged by its exact loop (no DF of this "
                 "compensated loop)" if self.compensation and self.equivalent is None else
                 f"{len(self.predictions)} limit cycle(s) of {self.plant}"
                 + (f" compensated by {self.compensation} ({shown})" if self.compensation
                    else "")
                 + f" predicted by the describing function in F {self.F_range[0]:.4g} to {self.F_range[1]:.4g} N, "
                 f"omega {self.omega_range[0]:.4g} to {self.omega_range[1]:.4g} rad/s"]
        for i, c in enumerate(self.predictions):
            line = (f"  [{i}] F = {c.F:.8g} N, omega = {c.omega:.8g} rad/s, period {c.period:.6g} s, amplitude "
                    f"{c.amplitude_x:.6g} {u}, {'stable' if c.stable else 'unstable'}, distortion {c.distortion:.3g}")
            if self.verification:
                v = self.verification[i]
                line += ("\n    judge: settled at F = {F:.6g} N, omega = {omega:.6g} rad/s (off the prediction by "
                         "{rel_error_F:.2%}, {rel_error_omega:.2%})".format(**v) if v["settled"] else
                         f"\n    judge: not settled: {v['reason']}")
            if self.exact:
                j = self.links[i]
                line += (("\n    no true cycle found near it (the search reaches stable cycles only)"
                          if self.coverage.stable_only and not c.stable else
                          "\n    no locked cycle near it (a dithered loop's search finds the stable cycles "
                          "locked to its dither)" if self.responses is not None else
                          "\n    no true cycle near it: a false alarm") if j is None else
                         "\n    true cycle [{}]: DF error omega {omega:+.2%}, amplitude {amplitude_x:+.2%}, F {F:+.2%}"
                         .format(j, **relative_errors(c, self.cycles[j])))
            lines.append(line)
        if self.exact:
            how = ("co-simulated, refined and extrapolated" if any(c.errors for c in self.cycles) else
                   "shooting, Floquet multipliers")
            lines.append(f"{len(self.cycles)} true cycle(s) of the exact closed loop ({how}); "
                         + self.coverage.summary(u))
            for j, c in enumerate(self.cycles):
                which = "not predicted by the DF" if c.prediction is None else f"prediction [{c.prediction}]"
                per_period = ", ".join(f"{value} {name}" for name, value in c.counts.items())
                how = (f"(|multipliers| {', '.join(f'{m:.3g}' for m in c.multipliers)}), {per_period} per "
                       f"period, residual {c.residual:.1e}" if not c.errors else
                       f"(reached by the co-simulated loop; estimated errors: period {c.errors['period']:.2g} s, "
                       f"amplitude {c.errors['amplitude_x']:.2g} {u}, F {c.errors['F']:.2g} N, at "
                       f"{c.errors['steps_per_period']} steps per period)")
                lines.append(f"  [{j}] omega = {c.omega:.10g} rad/s, period {c.period:.10g} s, amplitude "
                             f"{c.amplitude_x:.10g} {u}, F = {c.F:.10g} N, {'stable' if c.stable else 'unstable'} "
                             f"{how}; {which}" + (f"\n      {c.df}" if c.df else ""))
        if self.responses is not None:
            lines += self._dithered(u)
        if self.cost is not None:
            lines.append("cost: " + self.cost.summary(u))
        return "\n".join(lines)

    def _dithered(self, u):
        """A dithered loop's own responses (period T_d) and its runs that hunt unlocked, as summary lines."""
        lines = [f"{len(self.responses)} response(s) at the dither's period (fixed points of the stroboscopic map)"]
        for j, c in enumerate(self.responses):
            lines.append(f"  [{j}] period {c.period:.6g} s, mean {c.harmonics[0]:.4g} {u}, residual oscillation "
                         f"{c.amplitude_x:.4g} {u} (first harmonic), {'stable' if c.stable else 'unstable'} "
                         f"(|multipliers| {', '.join(f'{m:.3g}' for m in c.multipliers)})")
        if self.hunting:
            lines.append(f"{len(self.hunting)} run(s) hunt, not locked to the dither within 8 of its periods; e.g. "
                         f"from {self.hunting[0]['start']}: {self.hunting[0]['detail']}")
        return lines

    def markdown(self) -> str:
        """Tables of the predictions (and judge), and of the true cycles with the DF's errors (a scene's
        summary.md)."""
        from dfwb.engine.closed_loop import judge_errors
        from dfwb.engine.cycles import relative_errors

        u = self.unit
        lines = [f"| F [N] | w [rad/s] | amplitude [{u}] | stable | distortion | judge F | judge w | settled |",
                 "|---|---|---|---|---|---|---|---|"]
        for i, c in enumerate(self.predictions):
            v = self.verification[i] if self.verification else None
            judged = ("- | - | not asked" if not v else f"{v['F']:.4g} | {v['omega']:.4g} | True" if v["settled"]
                      else f"- | - | no: {v['reason']}")
            lines.append(f"| {c.F:.6g} | {c.omega:.6g} | {c.amplitude_x:.4g} | {c.stable} | {c.distortion:.3g} "
                         f"| {judged} |")
        if not self.predictions:
            lines.append(f"| not computed: no DF of the loop compensated by {self.compensation} | | | | | | | |"
                         if self.compensation and self.equivalent is None else
                         f"| no cycle in F {self.F_range[0]:.4g} to {self.F_range[1]:.4g} N | | | | | | | |")
        if self.exact:
            lines += ["", "The exact closed loop's true cycles (shooting to a residual of 1e-10, Floquet "
                      "multipliers), and the DF's relative errors against them; " + self.coverage.summary(u) + ":", "",
                      f"| true w [rad/s] | amplitude [{u}] | F [N] | stable | max multiplier | per period "
                      "| DF prediction | DF error w | DF error amplitude | DF error F | judge error w "
                      "| judge error amplitude |", "|---" * 12 + "|"]
            for c in self.cycles:
                errors = ("not predicted" + (" (the DF cannot represent it)" if c.df else "")) + " | | | | | |"
                if c.prediction is not None:
                    e = relative_errors(self.predictions[c.prediction], c)
                    errors = f"{c.prediction} | {e['omega']:+.2%} | {e['amplitude_x']:+.2%} | {e['F']:+.2%} | "
                    v = self.verification[c.prediction] if self.verification else None
                    j = judge_errors(v, c) if v and v["settled"] else None
                    errors += (f"{j['omega']:+.2%} | {j['amplitude_x']:+.2%} |" if j else "- | - |")
                counts = ", ".join(f"{v} {k}" for k, v in c.counts.items())
                lines.append(f"| {c.omega:.8g} | {c.amplitude_x:.6g} | {c.F:.6g} | {c.stable} | "
                             f"{max(c.multipliers, default=math.nan):.3g} | {counts} | {errors}")
            missed = [i for i, j in enumerate(self.links) if j is None]
            if missed:
                lines.append(f"\nPrediction(s) {missed}: no true cycle near them ("
                             + ("the search reaches stable cycles only)." if self.coverage.stable_only
                                else "false alarms)."))
        if self.cost is not None:
            lines += ["", "Cost: " + self.cost.summary(u) + "."]
        return "\n".join(lines)

    def figure(self, path):
        """The Nyquist plane, the judge's runs and the true cycles over a period, written to ``path`` (PNG, SVG)."""
        from dfwb.plotting.plots import limit_cycle_figure

        return limit_cycle_figure(path, self.G, self.F_grid, self.omega_grid, self.N_grid, self.predictions,
                                  self.runs, self.cycles)

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


_NUMBER = (float, None)  # None: an infinity written to JSON
_CONTINUATION = {  # the shape of ContinuationResponse.as_dict()
    "plant": str, "G": str, "parameter": str, "range": [float], "values": {str: float}, "unit": str,
    "branches": [{"source": frozenset(("truth", "df")), "returns": int, "ends": [{"parameter": float, "reason": str}],
                  "points": [{"parameter": float, "omega": _NUMBER, "amplitude_x": _NUMBER, "F": _NUMBER,
                              "stable": bool, "multipliers": [_NUMBER], "period": _NUMBER, "events": [str]}]}],
    "bifurcations": [{"kind": str, "parameter": float, "omega": _NUMBER, "amplitude_x": _NUMBER, "source": str,
                      "detail": str, "accuracy": _NUMBER}],
    "searches": [{"parameter": float, "cycles": int, "coverage": {"complete": bool, ...: object}}], "notes": [str]}


@dataclass(eq=False, repr=False)
class ContinuationResponse(_Shown):
    """Limit cycles followed in one parameter: branches of true cycles and of DF predictions, and bifurcations.

    Made by :func:`dfwb.continuation`.

    Attributes
    ----------
    plant : str
        The plant's registry name.
    G : str
        The controller as given.
    parameter : str
        The parameter followed (of G or of the plant).
    range : list of float
        [low, high] of the parameter.
    values : dict
        The other parameters' values.
    branches : list of dfwb.engine.continuation.Branch
        Each with ``source`` ("truth" or "df"), ``points`` (``parameter``, ``omega`` [rad/s],
        ``amplitude_x`` [unit], ``F`` [N], ``stable``, ``multipliers``, ``period`` [s], ``signature``) and
        ``ends`` (why each end stops).
    bifurcations : list of dfwb.engine.continuation.Bifurcation
        ``kind`` (``fold``, ``nonsmooth-fold``, ``sliding``, ``grazing``, ``period-doubling``, ``torus``,
        ``branch-point``, ``infinity``), ``parameter``, ``omega``, ``amplitude_x``, ``source``, ``detail``
        and ``accuracy`` (the located bracket's width in the parameter).
    searches : list of dict
        At each parameter value searched for true cycles: how many were found and the search's coverage.
    notes : list of str
        Parameter values that could not be searched, and why.
    unit : str
        The plant output's unit.

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.continuation("friction", "Kp + Ki/s", "Ki", 1, 30, Kp=10, sources="truth")
    >>> response
    <ContinuationResponse: friction under G = Kp + Ki/s (Kp = 10), Ki from 1 to 30: 1 branch(es)>
    >>> print(response)  # doctest: +ELLIPSIS
    friction under G = Kp + Ki/s (Kp = 10), Ki from 1 to 30: 1 branch(es)
      [0] truth: ... points, Ki 1 to 24.773, ... stable; ends: at 1, the end of the range; at 5.07..., infinity
      truth infinity at Ki = 5 (+-0): ... the linear loop's stability boundary
      truth nonsmooth-fold at Ki = 24.773... (+-...): omega 2.8993... rad/s, amplitude 0.87549... m; ...
    >>> branch = response.branches[0]
    >>> branch.source, branch.ends[0], [(b.kind, round(b.parameter, 4)) for b in response.bifurcations]
    ('truth', (1.0, 'the end of the range'), [('infinity', 5.0), ('nonsmooth-fold', 24.773)])
    """

    plant: str
    G: str
    parameter: str
    range: list
    values: dict
    branches: list
    bifurcations: list
    searches: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    unit: str = "m"

    @classmethod
    def from_dict(cls, data):
        """The response :meth:`as_dict` wrote (a cached continuation; the section states are not kept).

        ValueError for a document of another shape (a crafted or damaged cache entry)."""
        from dfwb.base.values import conforms
        from dfwb.engine.continuation import Bifurcation, Branch, Point

        if not (conforms(data, _CONTINUATION) and len(data["range"]) == 2 and all(b["points"] for b in data["branches"])
                and all(b["returns"] >= 1 for b in data["branches"])):
            raise ValueError("not a continuation's record")
        branches = [Branch(b["source"], [Point(**{k: v for k, v in p.items() if k != "events"},
                                               signature=tuple(p["events"])) for p in b["points"]],
                           [(e["parameter"], e["reason"]) for e in b["ends"]], b["returns"])
                    for b in data["branches"]]
        return cls(plant=data["plant"], G=data["G"], parameter=data["parameter"], range=data["range"],
                   values=data["values"], branches=branches,
                   bifurcations=[Bifurcation(**b) for b in data["bifurcations"]], searches=data["searches"],
                   notes=data["notes"], unit=data.get("unit", "m"))

    def as_dict(self) -> dict:
        """JSON types: what ``dfwb continue --json`` prints."""
        return {"plant": self.plant, "G": self.G, "parameter": self.parameter, "range": self.range,
                "values": self.values, "branches": [b.as_dict() for b in self.branches],
                "bifurcations": [b.as_dict() for b in self.bifurcations], "searches": self.searches,
                "notes": self.notes, "unit": self.unit}

    def summary(self) -> str:
        """The branches and bifurcations in a few lines."""
        lo, hi = self.range
        lines = [f"{self.plant} under G = {self.G}" + (f" ({_values(self.values)})" if self.values else "")
                 + f", {self.parameter} from {lo:g} to {hi:g}: {len(self.branches)} branch(es)"]
        for i, branch in enumerate(self.branches):
            stable = sum(p.stable for p in branch.points)
            values = [p.parameter for p in branch.points]
            lines.append(f"  [{i}] {branch.source}: {len(branch.points)} points, {self.parameter} "
                         f"{min(values):.6g} to {max(values):.6g}, {stable} stable; ends: "
                         + "; ".join(f"at {v:.6g}, {why}" for v, why in branch.ends))
        for b in self.bifurcations:
            lines.append(f"  {b.source} {b.kind} at {self.parameter} = {b.parameter:.8g} (+-{b.accuracy:.1g}): "
                         f"omega {b.omega:.6g} rad/s, amplitude {b.amplitude_x:.6g} {self.unit}; {b.detail}")
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)

    def plot(self, ax=None) -> list:
        """The bifurcation diagram: amplitude against the parameter, truth and DF, stable solid, unstable dashed,
        each bifurcation marked and named. Returns the lines drawn.

        Examples
        --------
        >>> import dfwb
        >>> response = dfwb.continuation("friction", "Kp + Ki/s", "Ki", 1, 4, Kp=10, sources="truth",
        ...                              max_points=20)
        >>> lines = response.plot()
        >>> lines[0].axes.get_xlabel()
        'Ki'
        """
        from dfwb.plotting.plots import bifurcation_diagram, get_axes

        return bifurcation_diagram(get_axes(ax, figsize=(7, 5)), self)

    def figure(self, path):
        """The diagram written to ``path`` (PNG and SVG)."""
        from dfwb.plotting.plots import bifurcation_diagram, drawn

        return drawn(path, lambda ax: bifurcation_diagram(ax, self), figsize=(8, 5.5))


def _values(values):
    return ", ".join(f"{name} = {value:g}" if not isinstance(value, str) else f"{name} = {value}"
                     for name, value in values.items())


@dataclass(eq=False, repr=False)
class HuntingMapResponse(_Shown):
    """Which settings of two parameters make the loop hunt: every cell classified by the truth and the DF.

    Made by :func:`dfwb.hunting_map`.

    Attributes
    ----------
    plant, G : str
        The plant and the controller as given.
    x, y : str
        The two parameters (of G or of the plant).
    xs, ys : list of float
        Their values, the cells' columns and rows.
    values : dict
        The other parameters' values.
    cells : list of list of dict
        ``cells[j][i]`` at (xs[i], ys[j]): ``truth`` (``class``: ``stable`` = hunts, ``unstable``: only
        unstable cycles, ``diverges``, ``none``: no cycle in the range searched, ``incomplete``; ``cycles``;
        ``coverage``), ``df`` (``class``, ``predictions``) and ``linear`` (``stable``); or ``error``.
    linear : dict
        The linear loop on a fine grid: ``x``, ``y``, ``growth`` (rows of the largest real part of its poles
        [1/s]; negative: stable; its zero contour is the stability boundary).
    curves : list of dfwb.engine.hunting.Curve
        Bifurcations continued across the map (``kind``, ``source``, ``points``).
    counts : dict
        Cells computed, from the cache, resumed from the folder.
    seconds : float
    out_dir : path or None
        Where the map was written (``cells.csv``, ``cells.json``, ``map.json``, ``hunting_map.png``).

    Examples
    --------
    The smallest map, 2 x 2 cells, in this process and without the bifurcation curves:

    >>> import dfwb
    >>> response = dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 5, 20, 2), ("Ki", 1, 4, 2), jobs=1,
    ...                             curves=False)
    >>> print(response)  # doctest: +ELLIPSIS
    friction under G = Kp + Ki/s: 4 cells, Kp 5 to 20, Ki 1 to 4 (4 computed, 0 cached, 0 resumed; ... s)
      truth: 4 hunts (a stable cycle)
      DF: 3 no cycle in the range searched, 1 diverges (from some starts)
      the DF misses 4 of the 4 cells that hunt and predicts hunting in 0 that do not
    >>> response.classes("df").tolist()
    [['none', 'none'], ['diverges', 'none']]
    >>> cell = response.cells[0][0]
    >>> cell["x"], cell["y"], cell["truth"]["class"], round(cell["truth"]["cycles"][0]["period"], 2)
    (5.0, 1.0, 'stable', 60.3)
    """

    plant: str
    G: str
    x: str
    xs: list
    y: str
    ys: list
    values: dict
    cells: list = field(repr=False)
    linear: dict = field(repr=False)
    curves: list = field(default_factory=list)
    unit: str = "m"
    counts: dict = field(default_factory=dict)
    seconds: float = 0.0
    out_dir: Any = None

    def classes(self, source="truth") -> np.ndarray:
        """The class of every cell as an array of text, shape (len(ys), len(xs)) ("error" where it failed)."""
        return np.array([[cell[source]["class"] if source in cell else "error" for cell in row] for row in self.cells])

    @property
    def compensated(self) -> bool:
        """Whether the loop has compensators: its cells carry their ``cost``."""
        return any("cost" in cell for row in self.cells for cell in row)

    @property
    def has_df(self) -> bool:
        """Whether the cells have a DF verdict (a compensated loop's only where its plant is a plant)."""
        return any(cell.get("df", {}).get("class", "uncomputed") != "uncomputed" for row in self.cells
                   for cell in row)

    def costs(self, name="standing_error") -> np.ndarray:
        """One quantity of every cell's cost (:class:`dfwb.engine.cost.Cost`), shape (len(ys), len(xs)); NaN
        where the cell has none (it failed, or its loop never came to rest for a standing error)."""
        return np.array([[np.nan if cell.get("cost", {}).get(name) is None else cell["cost"][name]
                          for cell in row] for row in self.cells], dtype=float)

    def as_dict(self) -> dict:
        """JSON types: what ``dfwb map --json`` prints and cells.json holds."""
        cells = [dict(cell) for row in self.cells for cell in row]
        return {"plant": self.plant, "G": self.G, "x": {"name": self.x, "values": self.xs},
                "y": {"name": self.y, "values": self.ys}, "values": self.values, "cells": cells,
                "linear": self.linear, "curves": [c.as_dict() for c in self.curves], "counts": self.counts,
                "seconds": self.seconds}

    def summary(self) -> str:
        """Counts of each class, truth and DF, and where they disagree."""
        from collections import Counter

        from dfwb.engine.hunting import HUNTS, LABELS

        truth, df = self.classes("truth"), self.classes("df")
        lines = [f"{self.plant} under G = {self.G}" + (f" ({_values(self.values)})" if self.values else "")
                 + f": {truth.size} cells, {self.x} {self.xs[0]:g} to {self.xs[-1]:g}, {self.y} {self.ys[0]:g} to "
                 f"{self.ys[-1]:g} ({self.counts.get('computed', 0)} computed, {self.counts.get('cached', 0)} "
                 f"cached, {self.counts.get('resumed', 0)} resumed; {self.seconds:.1f} s)"]
        for source, classes in (("truth", truth), ("DF", df))[:2 if self.has_df else 1]:
            counted = Counter(classes.ravel().tolist())
            lines.append(f"  {source}: " + ", ".join(f"{n} {LABELS.get(k, k)}" for k, n in counted.most_common()))
        if self.has_df:
            hunts = np.isin(truth, HUNTS)
            missed = int(np.sum(hunts & (df != "stable")))
            false = int(np.sum(~hunts & (df == "stable")))
            lines.append(f"  the DF misses {missed} of the {int(hunts.sum())} cells that hunt and predicts hunting "
                         f"in {false} that do not")
        if self.compensated:  # the price of the cells at rest
            error, settling = self.costs("standing_error"), self.costs("settling_time")
            failed = np.array([[bool(cell.get("cost", {}).get("note")) for cell in row] for row in self.cells])
            rest = np.isfinite(error)
            lines.append(f"  cost: {int(rest.sum())} cells come to rest after a step" + (
                f", standing error {np.min(error[rest]):.4g} to {np.max(error[rest]):.4g} {self.unit}, settling in "
                f"{np.min(settling[rest]):.4g} to {np.max(settling[rest]):.4g} s" if rest.any() else "")
                + (f"; force peak up to {np.nanmax(self.costs('peak_force')):.4g} N"
                   if np.isfinite(self.costs("peak_force")).any() else "")
                + (f"; {int(np.sum(failed))} cells' step response not computed" if failed.any() else ""))
        for curve in self.curves:
            lines.append(f"  {curve.source} {curve.kind} curve through {len(curve.points)} columns")
        if self.out_dir is not None:
            lines.append(f"  written to {self.out_dir}: cells.csv (as the cells finished), cells.json, map.json, "
                         "hunting_map.png and .svg")
        return "\n".join(lines)

    def plot(self, axes=None) -> list:
        """Truth and DF side by side: hunting cells coloured by the cycle's amplitude, the other classes in
        flat colours, the linear loop's stability boundary and the bifurcation curves drawn over both. A
        compensated loop's map has its cost beside them: the standing error of the cells that rest (and no DF
        panel where its plant is no plant).

        Returns the axes (two, or three for a compensated loop with its DF)."""
        from dfwb.plotting.plots import hunting_map

        return hunting_map(self, axes)

    def write(self, out_dir):
        """cells.json and hunting_map.png (and .svg) into ``out_dir`` (its cells.csv and map.json are written
        as the map runs)."""
        import json

        from dfwb.base.files import write_atomic
        from dfwb.studies.cache import finite

        out_dir = Path(out_dir)
        write_atomic(out_dir / "cells.json", json.dumps(finite(self.as_dict()), indent=1).encode())
        return self.figure(out_dir / "hunting_map.png")

    def figure(self, path):
        """The map written to ``path`` (PNG and SVG)."""
        from dfwb.plotting.plots import drawn

        panels = 1 + self.has_df + self.compensated  # the truth, the DF, the cost
        return drawn(path, self.plot, ncols=panels, figsize=(6.5 * panels, 6.2), sharey=True, layout="constrained")


@dataclass(eq=False, repr=False)
class MarginResponse(_Shown):
    """The gain factors k for which k G makes the machine hunt, by the truth and by the DF.

    Made by :func:`dfwb.limit_cycle_margin`.

    Attributes
    ----------
    plant, G : str
        The plant and the controller as given (k = 1).
    values : dict
        The parameters of G and of the plant.
    k_range : list of float
        The gain factors searched.
    truth, df : dfwb.engine.margin.Margin
        Each: ``intervals`` ([k_lo, k_hi] where k G hunts), ``boundaries`` (``k``, ``kind`` of what ends
        or starts the hunting: a bifurcation's kind or "bisected", ``starts``, ``accuracy``), ``scan``
        (k, class, amplitude, omega), ``hunts_at(k)`` and ``room()``: the factors by which the gain may fall
        or grow from 1 before the verdict changes.

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.limit_cycle_margin("friction", "20 + 100/s + 2*s/(0.1*s+1)", count=9)
    >>> print(response)  # doctest: +ELLIPSIS
    friction under k G, G = 20 + 100/s + 2*s/(0.1*s+1), k from 0.01 to 100:
      truth: hunts as it is (k = 1); stops below k = 0.83005... Hunts for k in [0.83005..., 100]
        at k = 0.830053... (+-...) hunting starts: nonsmooth-fold (...)
      DF: hunts as it is (k = 1); stops below k = 0.79...; stops above k = 4.1... Hunts for k in [0.79..., 4.1...]
        at k = 0.79... (+-...) hunting starts: bisected (...)
        at k = 4.1... (+-...) hunting stops: bisected (...)
    >>> [round(k, 4) for k in response.truth.intervals[0]], response.truth.room()[1]
    ([0.8301, 100.0], None)
    """

    plant: str
    G: str
    values: dict
    k_range: list
    truth: Any
    df: Any = None
    unit: str = "m"

    def as_dict(self) -> dict:
        """JSON types: what ``dfwb margin --json`` prints."""
        return {"plant": self.plant, "G": self.G, "values": self.values, "k_range": self.k_range,
                "truth": self.truth.as_dict(), "df": None if self.df is None else self.df.as_dict()}

    def summary(self) -> str:
        """The answer to "how much more gain before it hunts?", truth and DF."""
        lo, hi = self.k_range
        lines = [f"{self.plant} under k G, G = {self.G}" + (f" ({_values(self.values)})" if self.values else "")
                 + f", k from {lo:g} to {hi:g}:"]
        for margin in (self.truth, self.df):
            if margin is None:
                continue
            name = "truth" if margin.source == "truth" else "DF"
            ranges = ", ".join(f"[{a:.6g}, {b:.6g}]" for a, b in margin.intervals) or "nowhere in the range"
            down, up = margin.room()
            if margin.hunts_at(1.0):
                verdict = "hunts as it is (k = 1)"
                change = [f"stops below k = {down:.6g}" if down else "", f"stops above k = {up:.6g}" if up else ""]
            else:
                verdict = "does not hunt as it is (k = 1)"
                change = [f"hunts once the gain grows {up:.6g} times" if up else "",
                          f"hunts once it falls to {down:.6g} times" if down else ""]
            change = "; ".join(c for c in change if c) or "no change within the range"
            lines.append(f"  {name}: {verdict}; {change}. Hunts for k in {ranges}")
            for b in margin.boundaries:
                lines.append(f"    at k = {b.k:.8g} (+-{b.accuracy:.1g}) hunting {'starts' if b.starts else 'stops'}: "
                             f"{b.kind}" + (f" ({b.detail})" if b.detail else ""))
        return "\n".join(lines)

    def plot(self, ax=None) -> list:
        """Hunting amplitude against k (log-log), truth and DF; the hunting ranges shaded, k = 1 marked."""
        from dfwb.plotting.plots import get_axes, margin_plot

        return margin_plot(get_axes(ax, figsize=(7, 4.5)), self)

    def figure(self, path):
        """The plot written to ``path`` (PNG and SVG)."""
        from dfwb.plotting.plots import drawn, margin_plot

        return drawn(path, lambda ax: margin_plot(ax, self), figsize=(7.5, 4.8))


@dataclass(eq=False, repr=False)
class TuneResponse(_Shown):
    """The fastest controller of a family, with its compensators, that does not hunt.

    Made by :func:`dfwb.tune` (:mod:`dfwb.engine.tune`).

    Attributes
    ----------
    plant, G : str
        The plant and the controller family, with its compensators.
    free : dict
        The ranges searched, ``{name: [lo, hi]}``, ``count`` values each.
    tolerance : float or None
        The largest standing error allowed [the output's unit].
    robust : dict
        The relative errors of the plant's parameters; ``corners`` the plants checked (the nominal first).
    settings : dict or None
        The chosen values of the free parameters (None: no setting on the grid passes).
    crossover : float or None
        Its linear loop's crossover [rad/s].
    cost : dict
        Its cost at the nominal plant (:class:`dfwb.engine.cost.Cost`).
    confirmed : bool or None
        Whether the independent reference confirms it comes to rest at every corner (None: no reference for
        this plant's compensated loop); ``confirmation`` the runs.
    candidates : list of dict
        Every setting: its values, crossover, verdict (accepted, hunts, standing error, linear loop unstable,
        refused, not tried: ranked below the answer) and why.

    Examples
    --------
    >>> import dfwb
    >>> r = dfwb.tune("friction", "Kp + Ki/s", compensate="deadband", free={"Kp": (2, 50), "Ki": (0.2, 10),
    ...               "d": (0.01, 0.5)}, tolerance=0.1, robust={"Fc": 0.2, "Fs": 0.1}, count=3)
    >>> {k: round(v, 4) for k, v in r.settings.items()}, round(r.crossover, 3), r.confirmed
    ({'Kp': 50.0, 'Ki': 10.0, 'd': 0.0707}, 7.064, True)
    """

    plant: str
    G: str
    free: dict
    count: int
    tolerance: Any
    robust: dict
    corners: list
    settings: Any
    crossover: Any
    cost: dict
    confirmed: Any
    confirmation: Any
    candidates: list = field(repr=False)
    controller: list = field(default_factory=list)  # the free parameters that are G's
    values: dict = field(default_factory=dict)
    unit: str = "m"
    seconds: float = 0.0

    def as_dict(self) -> dict:
        """JSON types: what ``dfwb tune --json`` prints."""
        return {"plant": self.plant, "G": self.G, "free": self.free, "count": self.count, "values": self.values,
                "tolerance": self.tolerance, "robust": self.robust, "corners": self.corners,
                "settings": self.settings, "crossover": self.crossover, "cost": self.cost,
                "confirmed": self.confirmed, "confirmation": self.confirmation, "candidates": self.candidates,
                "seconds": self.seconds}

    def summary(self) -> str:
        """The chosen setting, its speed, its cost and what confirms it."""
        from collections import Counter

        ranges = ", ".join(f"{name} {lo:g} to {hi:g}" for name, (lo, hi) in self.free.items())
        box = ", ".join(f"{name} +-{rel:.0%}" for name, rel in self.robust.items()) or "the nominal plant only"
        lines = [f"{self.plant} under G = {self.G}" + (f" ({_values(self.values)})" if self.values else "")
                 + f": {ranges}, {self.count} values each; robust to {box}"
                 + ("" if self.tolerance is None else f"; standing error at most {self.tolerance:g} {self.unit}")]
        if self.settings is None:
            lines.append("  no setting on the grid passes (see the candidates' verdicts)")
        else:
            lines.append(f"  chosen: {_values(self.settings)}; crossover {self.crossover:.6g} rad/s")
            edges = [name for name, (lo, hi) in self.free.items() if self.settings[name] in (lo, hi)]
            if edges:
                lines.append(f"  ({', '.join(edges)} at the end of the range searched: a wider range may do better)")
            if self.cost:
                error = self.cost["standing_error"]
                lines.append("  cost (nominal): " + (f"standing error {error:.4g} {self.unit}, settles in "
                                                     f"{self.cost['settling_time']:.4g} s" if error is not None
                                                     else "does not come to rest")
                             + f", overshoot {self.cost['overshoot']:.1%}, force peak {self.cost['peak_force']:.4g}"
                               f" N, rms {self.cost['rms_force']:.4g} N")
            lines.append("  confirmed by the independent reference at every corner, from rest and displaced starts"
                         if self.confirmed else "  NOT confirmed by the independent reference: see confirmation"
                         if self.confirmed is False else f"  not confirmed: {self.confirmation}")
        counted = Counter(c["verdict"] for c in self.candidates)
        lines.append("  candidates: " + ", ".join(f"{n} {verdict}" for verdict, n in counted.most_common())
                     + f" ({self.seconds:.1f} s)")
        return "\n".join(lines)

    def plot(self, ax=None) -> list:
        """G's settings, each coloured by its best verdict over the compensators, the chosen starred."""
        from dfwb.plotting.plots import get_axes, tune_plot

        return tune_plot(get_axes(ax, figsize=(7, 5)), self)

    def figure(self, path):
        """The figure written to ``path`` (PNG and SVG)."""
        from dfwb.plotting.plots import drawn, tune_plot

        return drawn(path, lambda ax: tune_plot(ax, self), figsize=(7.5, 5.2))
