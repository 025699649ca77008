"""Plot helpers for describing functions: Nyquist loci, Bode-like magnitudes, harmonic maps.

The helpers draw into the axes they are given (or a new figure's when ``ax``
is None) and return what they drew; only :func:`save` writes files. Importing
this module leaves matplotlib's backend alone: a program that writes figures
in batch (the ``dfwb`` command line) calls :func:`use_batch_backend` first,
a notebook keeps its own. The rows are DF records
(:meth:`dfwb.engine.describing.DFResult.as_dict`); the axes carry units
(N in m/N, so -1/N and G(jw) in N/m).
"""

import io
import json
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib import ticker

from dfwb.base.files import write_atomic
from dfwb.plotting.backend import use_batch_backend  # noqa: F401 (here too, for callers of plots)

RE_INVERSE = "Re{-1/N} [N/m]"
IM_INVERSE = "Im{-1/N} [N/m]"
OMEGA = "omega [rad/s]"
TITLE_SIZE = "medium"  # the tick labels' size (rc xtick.labelsize): a smaller title reads as a footnote
DPI = 120  # of the PNGs
LEGEND_SIZE = "small"  # a legend readable beside the ticks, not 7 points


class PlainLogFormatter(ticker.LogFormatter):
    """Log-axis tick labels as plain numbers (30, 0.1, not 3x10^1); matplotlib still picks which ticks get one."""

    def __call__(self, x, pos=None):
        return f"{x:g}" if super().__call__(x, pos) else ""


def get_axes(ax=None, **subplots):
    """``ax``, or the axes of a new figure (``plt.subplots(**subplots)``) when it is None."""
    if ax is None:
        _, ax = plt.subplots(**subplots)
    return ax


def minus_inverse(rows):
    """(omega, -1/N) arrays of DF records with N != 0, sorted by omega."""
    data = sorted((r["omega"], complex(r["minus_inv_N_re"], r["minus_inv_N_im"]))
                  for r in rows if r["minus_inv_N_re"] is not None)
    omega = np.array([w for w, _ in data], dtype=float)
    values = np.array([v for _, v in data], dtype=complex)
    return omega, values


def nyquist(ax, curves, marks=(), label_marks=True):
    """-1/N loci: ``curves`` is [(label, rows, style)], marks are omegas shown as dots; returns the lines.

    A mark's label that would overlap an earlier one is left out (where curves meet, e.g. at low w, one
    label says it; the dots stay), so set the axes' limits before calling. ``ax`` None draws into a new
    figure."""
    ax = get_axes(ax)
    lines, labels = [], []
    for label, rows, style in curves:
        omega, values = minus_inverse(rows)
        if len(values) == 0:
            continue
        line, = ax.plot(values.real, values.imag, label=label, **style)
        lines.append(line)
        for mark in marks:
            hits = np.flatnonzero(np.isclose(omega, mark, rtol=1e-9))
            if len(hits):
                point = values[hits[0]]
                ax.plot(point.real, point.imag, "o", ms=3, color=line.get_color())
                if label_marks:
                    labels.append(ax.annotate(f"{mark:g}", (point.real, point.imag), fontsize=6, xytext=(2, 2),
                                              textcoords="offset points", color=line.get_color()))
    ax.autoscale_view()  # the limits the labels land in
    placed = []
    for text in labels:
        box = text.get_window_extent()
        if any(box.overlaps(other) for other in placed):
            text.remove()
        else:
            placed.append(box)
    ax.set_xlabel(RE_INVERSE)
    ax.set_ylabel(IM_INVERSE)
    ax.grid(alpha=0.3)
    return lines


def re_im_loglog(axes, curves):
    """|Re{-1/N}| and |Im{-1/N}| against omega on two log-log axes; returns the lines."""
    lines = []
    for label, rows, style in curves:
        omega, values = minus_inverse(rows)
        lines += axes[0].loglog(omega, np.abs(values.real), label=label, **style)
        lines += axes[1].loglog(omega, np.abs(values.imag), label=label, **style)
    axes[0].set_ylabel("|Re{-1/N}| [N/m]")
    axes[1].set_ylabel("|Im{-1/N}| [N/m]")
    for ax in axes:
        ax.set_xlabel(OMEGA)
        ax.grid(alpha=0.3, which="both")
    return lines


def harmonic_map(ax, rows, title):
    """log10 |X_k| over (omega, k), k = 0..10: where the harmonics live."""
    rows = sorted(rows, key=lambda r: r["omega"])
    omega = np.array([r["omega"] for r in rows])
    amplitudes = np.array([r["harmonics"] for r in rows]).T
    with np.errstate(divide="ignore"):
        levels = np.log10(np.maximum(amplitudes, 1e-300))
    top = np.max(levels)
    mesh = ax.pcolormesh(omega, np.arange(amplitudes.shape[0]), levels, shading="nearest",
                         vmin=top - 8, vmax=top, cmap="viridis")
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(PlainLogFormatter())  # less than a decade shows 3x10^1 and 4x10^1 otherwise
    ax.xaxis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False))
    ax.set_xlabel(OMEGA)
    ax.set_ylabel("harmonic k")
    ax.set_title(title, fontsize=TITLE_SIZE)
    return mesh


def vertical_marks(ax, frequencies):
    """Dashed verticals at named frequencies (e.g. w_C, w_J, w_L) within the axes' x range (one outside
    would widen the axes into a blank band), each named right of its line, or left of it in the axes' last
    tenth (w_L, where the data end, would be cut at the edge)."""
    lo, hi = ax.get_xlim()
    to_axes = ax.transData + ax.transAxes.inverted()
    for name, value in frequencies.items():
        if lo <= value <= hi:
            left = to_axes.transform((value, 1.0))[0] > 0.9
            ax.axvline(value, ls=":", lw=0.8, color="gray")
            ax.annotate(name, (value, 1.0), xycoords=("data", "axes fraction"), fontsize=7, color="gray",
                        xytext=(-2 if left else 2, -10), textcoords="offset points", ha="right" if left else "left")


def save(figure, out_dir, name):
    """PNG and SVG of a figure; returns the PNG path."""
    figure.set_dpi(DPI)  # laid out at the PNG's resolution: the PNG reuses the text metrics of the layout
    if figure.get_layout_engine() is None:
        figure.tight_layout()
    for kind in ("png", "svg"):  # atomically: an interrupted run never leaves half a figure
        buffer = io.BytesIO()
        figure.savefig(buffer, dpi=DPI, format=kind)
        write_atomic(out_dir / f"{name}.{kind}", buffer.getvalue())
        figure.set_layout_engine("none")  # laid out by the first save: the second keeps that layout
    plt.close(figure)
    return out_dir / f"{name}.png"


def drawn(path, draw, **layout):
    """A new figure (``plt.subplots(**layout)``), ``draw(axes)`` on it, written to ``path`` (PNG and SVG)."""
    figure, axes = plt.subplots(**layout)
    draw(axes)
    path = Path(path)
    return save(figure, path.parent, path.stem)


def curves_of(data, names):
    """[(label, rows, style)]: one curve per series, force and parameter set (the frequency varies)."""
    curves = []
    for name in names:
        groups = {}
        for r in data[name]:
            groups.setdefault((r["F"], json.dumps(r["params"], sort_keys=True)), []).append(r)
        for (F, params), rows in groups.items():
            extra = ", ".join(f"{k} = {v:g}" for k, v in json.loads(params).items())
            label = f"{name}: F = {F:g} N" + (f", {extra}" if extra else "")
            curves.append((label, rows, {}))
    return curves


def nyquist_panel(ax, curves, title, marks=()):
    """A scene's nyquist figure, and a sweep's: the -1/N loci (:func:`nyquist`), their legend and the title;
    returns the lines. ``ax`` None draws into a new figure."""
    ax = get_axes(ax, figsize=(6.5, 5))
    lines = nyquist(ax, curves, marks)
    if lines:
        ax.legend(fontsize=LEGEND_SIZE)
    ax.set_title(title, fontsize=TITLE_SIZE)
    return lines


def scene_figure(out_dir, figure, data, traces, scene):
    """A scene's figure of kind nyquist, re_im, harmonics or trace; returns the PNG path."""
    title = figure.title or f"{scene.title}: {figure.name}"
    if figure.kind == "trace":
        outputs = sorted({o for name in figure.series for o in traces[name] if o != "time"})
        fig, axes = plt.subplots(len(outputs), 1, figsize=(7, 2.6 * len(outputs)), sharex=True, squeeze=False)
        for ax, output in zip(axes[:, 0], outputs):
            for name in figure.series:
                if output in traces[name]:
                    ax.plot(traces[name]["time"], traces[name][output], lw=1, label=name)
            ax.set_ylabel(output)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=LEGEND_SIZE)
        axes[-1, 0].set_xlabel("t [s]")
        axes[0, 0].set_title(title, fontsize=TITLE_SIZE)
        ax = axes[0, 0]
    elif figure.kind == "harmonics":
        curves = curves_of(data, figure.series)
        fig, axes = plt.subplots(1, len(curves), figsize=(5 * len(curves), 4), squeeze=False, layout="constrained")
        for ax, (label, rows, _) in zip(axes[0], curves):
            mesh = harmonic_map(ax, rows, label)
        fig.colorbar(mesh, ax=axes[0].tolist(), label="log10 (|X_k| / 1 m)")
        fig.suptitle(title, fontsize=TITLE_SIZE)
        ax = axes[0, 0]
    elif figure.kind == "re_im":
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
        re_im_loglog(axes, curves_of(data, figure.series))
        axes[0].legend(fontsize=LEGEND_SIZE)
        axes[0].set_title(title, fontsize=TITLE_SIZE)
        ax = axes[0]
    else:
        fig, ax = plt.subplots(figsize=(6.5, 5))
        nyquist_panel(ax, curves_of(data, figure.series), title, figure.marks)
    if figure.xlim:
        ax.set_xlim(*figure.xlim)
    if figure.ylim:
        ax.set_ylim(*figure.ylim)
    return save(fig, Path(out_dir), figure.name)


def _frame(ax, points):
    """Square limits around the points that matter (the origin, where -1/N starts, and the cycles), with room
    around them: the plane shows where G(jw) and -1/N meet, not an empty half."""
    re, im = [z.real for z in points], [z.imag for z in points]
    centre = complex(0.5 * (min(re) + max(re)), 0.5 * (min(im) + max(im)))
    half = 0.8 * max(max(re) - min(re), max(im) - min(im), 1e-9) + 1.0
    ax.set_xlim(centre.real - half, centre.real + half)
    ax.set_ylim(centre.imag - half, centre.imag + half)


def limit_cycle_plane(ax, G, F_grid, omega_grid, N_grid, cycles, curves=6, true_cycles=()):
    """The Nyquist plane of a limit-cycle search: G(jw), -1/N(F, w) for ``curves`` forces of the map, the
    predicted cycles marked (circles, filled: stable) and the exact loop's true cycles (stars at G(jw) of
    their frequency, where the loop's first harmonics put them exactly, filled: stable; a grey line joins
    a prediction to its true cycle); returns the lines. ``ax`` None draws into a new figure."""
    ax = get_axes(ax, figsize=(6.5, 5))
    fine = np.geomspace(omega_grid[0], omega_grid[-1], 600)
    Gjw = np.array([complex(G(1j * w)) for w in fine])
    lines = ax.plot(Gjw.real, Gjw.imag, "k", lw=2, label="G(jw)")
    rows = np.unique(np.linspace(0, len(F_grid) - 1, curves).astype(int)) if len(F_grid) else []  # (none: no DF)
    for i in rows:
        N = np.asarray(N_grid[i])
        keep = N != 0
        inverse = -1.0 / N[keep]
        lines += ax.plot(inverse.real, inverse.imag, lw=1, label=f"-1/N, F = {F_grid[i]:.3g} N")
    for c in cycles:
        point = -1.0 / c.N
        lines += ax.plot(point.real, point.imag, "o", ms=8, mfc="r" if c.stable else "w", mec="r",
                         label=f"{'stable' if c.stable else 'unstable'}: F = {c.F:.4g} N, w = {c.omega:.4g} rad/s")
    for c in true_cycles:
        point = complex(G(1j * c.omega))
        lines += ax.plot(point.real, point.imag, "*", ms=13, mfc="b" if c.stable else "w", mec="b",
                         label=f"true, {'stable' if c.stable else 'unstable'}: F = {c.F:.4g} N, w = {c.omega:.4g} rad/s"
                               + ("" if c.prediction is not None else " (not predicted)"))
        if c.prediction is not None and c.prediction < len(cycles):
            predicted = -1.0 / cycles[c.prediction].N
            ax.plot([predicted.real, point.real], [predicted.imag, point.imag], color="0.5", lw=0.8)
    marks = [-1.0 / c.N for c in cycles] + [complex(G(1j * c.omega)) for c in true_cycles]
    _frame(ax, [0j] + marks if marks else [-3 + 3j, 3 - 3j])
    ax.set_xlabel("Re [N/m]")
    ax.set_ylabel("Im [N/m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=LEGEND_SIZE, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)  # below: never on a cycle
    ax.set_title("G(jw) and -1/N(F, w): limit cycles where they meet at the same w", fontsize=TITLE_SIZE)
    return lines


def true_cycle_response(ax, true_cycles):
    """Each true cycle over one period: the output y and the force f, each over its first-harmonic amplitude."""
    ax = get_axes(ax, figsize=(6.5, 5))
    lines = []
    for c in true_cycles:
        trace = c.trace
        t = trace["t"] / c.period
        kind = "stable" if c.stable else "unstable"
        middle = 0.5 * (np.max(trace["y"]) + np.min(trace["y"]))
        line, = ax.plot(t, (trace["y"] - middle) / c.amplitude_x, lw=1.2,
                        label=f"y / {c.amplitude_x:.4g} m ({kind}, w = {c.omega:.4g})")
        lines.append(line)
        lines += ax.plot(t, trace["f"] / c.F, lw=0.9, ls="--", color=line.get_color(), label=f"f / {c.F:.4g} N")
        for time, _kind in trace["events"]:
            if 0.0 < time < c.period:
                ax.axvline(time / c.period, ls=":", lw=0.6, color=line.get_color())
    ax.set_xlabel("t / period (dotted: events: stick, break-away, impacts, engagements)")
    ax.set_ylabel("over the first-harmonic amplitude")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=LEGEND_SIZE)
    ax.set_title("the truth: the exact closed loop's periodic orbits over one period", fontsize=TITLE_SIZE)
    return lines


def limit_cycle_figure(path, G, F_grid, omega_grid, N_grid, cycles, runs=(), true_cycles=()):
    """Nyquist plane (:func:`limit_cycle_plane`), the judge's runs and the true cycles over a period,
    written to ``path`` (PNG and SVG)."""
    panels = 1 + bool(runs) + bool(true_cycles)
    figure, axes = plt.subplots(1, panels, figsize=(6.5 * panels, 6), squeeze=False)
    limit_cycle_plane(axes[0][0], G, F_grid, omega_grid, N_grid, cycles, true_cycles=true_cycles)
    if true_cycles:
        true_cycle_response(axes[0][-1], true_cycles)
    if runs:
        ax = axes[0][1]
        for (cycle, run) in runs:
            tail = run.position[len(run.position) // 2:]
            centre = 0.5 * (tail.max() + tail.min()) if np.all(np.isfinite(tail)) else 0.0
            relative = (run.position - centre) / cycle.amplitude_x
            kind = "stable" if cycle.stable else "unstable"
            line, = ax.plot(run.time, relative, lw=0.8, label=f"from the {kind} cycle (w = {cycle.omega:.4g})")
            end = run.time[-1]
            for k in range(1, 4):
                ax.axvline(end - k * cycle.period, ls=":", lw=0.6, color=line.get_color())
        for sign in (1, -1):
            ax.axhline(sign, ls="--", lw=0.8, color="k")
        longest = max(cycle.period for cycle, _ in runs)
        ax.set_xlim(max(run.time[-1] for _, run in runs) - 6 * longest, max(run.time[-1] for _, run in runs))
        ax.set_ylim(-3, 3)
        ax.set_xlabel("t [s] (the last 6 periods)")
        ax.set_ylabel("plant output / predicted amplitude")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=LEGEND_SIZE)
        ax.set_title("the judge: co-simulation; dashed: predicted amplitude, dotted: predicted period\n"
                     "(a run that leaves its cycle, as from an unstable one, runs off the plot)", fontsize=TITLE_SIZE)
    return save(figure, path.parent, path.stem)


BRANCH_COLOURS = {"truth": "tab:blue", "df": "tab:orange"}
BIFURCATION_MARKERS = {"fold": "o", "nonsmooth-fold": "D", "sliding": "s", "grazing": "^", "period-doubling": "v",
                       "torus": "P", "branch-point": "X", "infinity": "|"}


def bifurcation_diagram(ax, response):
    """Amplitude against the parameter: each branch (truth blue, DF orange; stable solid, unstable dashed) and
    each bifurcation marked and named; returns the branch lines."""
    lines, labelled = [], set()
    for branch in response.branches:
        colour = BRANCH_COLOURS.get(branch.source, "k")
        points = branch.points
        start = 0
        for i in range(1, len(points) + 1):  # runs of equal stability, each one line
            if i < len(points) and points[i].stable == points[start].stable:
                continue
            run = points[max(start - 1, 0):i]
            stable = points[start].stable
            label = f"{'truth' if branch.source == 'truth' else 'DF'}, {'stable' if stable else 'unstable'}"
            line, = ax.plot([p.parameter for p in run], [p.amplitude_x for p in run], color=colour,
                            ls="-" if stable else "--", lw=1.8 if stable else 1.2,
                            label=None if label in labelled else label)
            labelled.add(label)
            lines.append(line)
            start = i
    for b in response.bifurcations:
        colour = BRANCH_COLOURS.get(b.source, "k")
        if b.kind == "infinity":
            ax.axvline(b.parameter, color=colour, ls=":", lw=1.0)
            ax.annotate(f"{b.kind} ({b.source})\n{response.parameter} = {b.parameter:.4g}", (b.parameter, 1.0),
                        xycoords=("data", "axes fraction"), xytext=(3, -4), textcoords="offset points",
                        va="top", fontsize=8, color=colour)
            continue
        ax.plot([b.parameter], [b.amplitude_x], BIFURCATION_MARKERS.get(b.kind, "o"), ms=8, mfc="w", mec=colour,
                mew=1.5)
        ax.annotate(f"{b.kind}\n{response.parameter} = {b.parameter:.6g}", (b.parameter, b.amplitude_x),
                    xytext=(6, 6), textcoords="offset points", fontsize=8, color=colour)
    ax.set_yscale("log")
    ax.set_xlabel(response.parameter)
    ax.set_ylabel(f"first-harmonic amplitude of the output [{response.unit}]")
    ax.set_title(f"{response.plant} under G = {response.G}: limit cycles against {response.parameter}", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    if lines:
        ax.legend(fontsize=8)
    return lines


CLASS_COLOURS = {"hunts": "#7b2cbf", "unstable": "#f4a261", "diverges": "#3a3a3a", "none": "#f2f2f2",
                 "incomplete": "#bdbdbd", "uncomputed": "#d8e2dc", "error": "#e63946"}
CURVE_STYLES = {"truth": "-", "df": "--"}
NO_REST = "#f4b6c2"  # a compensated map's cost panel: a cell whose step response does not come to rest


def hunting_map(response, axes=None):
    """Truth and DF side by side, and a compensated loop's cost (a :class:`dfwb.studies.responses.
    HuntingMapResponse`); returns the axes."""
    from matplotlib import colors
    from matplotlib.patches import Patch

    from dfwb.engine.hunting import LABELS, hunting

    compensated, has_df = response.compensated, response.has_df
    panels = [("truth", "the truth: the exact loop's cycles")] + (
        [("df", "the describing function's predictions")] if has_df else []) + (
        [("cost", "the cost: the standing error after a step")] if compensated else [])
    if axes is None:
        _, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels), 6.2), sharey=True, layout="constrained")
    xs, ys = np.asarray(response.xs), np.asarray(response.ys)
    dx, dy = (xs[-1] - xs[0]) / max(len(xs) - 1, 1), (ys[-1] - ys[0]) / max(len(ys) - 1, 1)
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    amplitudes = [c["amplitude_x"] for row in response.cells for cell in row for source in ("truth", "df")
                  if source in cell for c in [hunting(cell, source)] if c is not None]
    norm = colors.LogNorm(min(amplitudes), max(amplitudes) * (1.0 + 1e-9)) if amplitudes else None
    cmap = plt.get_cmap("viridis")
    image = None
    for ax, (source, title) in zip(axes, panels):
        if source == "cost":  # a dither's price is its residual oscillation, the others' their standing error
            residual = response.costs("residual_oscillation")
            dithered = bool(np.isfinite(residual).any())
            error = residual if dithered else response.costs("standing_error")
            what = "residual oscillation" if dithered else "standing error"
            shown = ax.imshow(np.ma.masked_invalid(error), origin="lower", extent=extent, aspect="auto",
                              interpolation="nearest", cmap="cividis")
            ax.set_facecolor(NO_REST)  # (cells whose step response never rests)
            if np.isfinite(error).any():
                title = f"the cost: the {what} after a step"
                ax.figure.colorbar(shown, ax=ax, fraction=0.05, pad=0.02).set_label(
                    f"{what} [{response.unit}] (pink: never at rest" + (", or never settles)" if dithered else ")"))
            else:
                title = "the cost: no cell comes to rest after a step (pink)"
        else:
            rgba = np.zeros((len(ys), len(xs), 4))
            for j, row in enumerate(response.cells):
                for i, cell in enumerate(row):
                    kind = cell[source]["class"] if source in cell else "error"
                    best = hunting(cell, source) if kind == "stable" else None
                    rgba[j, i] = cmap(norm(best["amplitude_x"])) if best is not None else colors.to_rgba(
                        CLASS_COLOURS.get(kind, "w"))
            ax.imshow(rgba, origin="lower", extent=extent, aspect="auto", interpolation="nearest")
        linear = response.linear
        growth = np.array([[np.nan if v is None else float(v) for v in row] for row in linear["growth"]], dtype=float)
        if np.isfinite(growth).any() and np.nanmin(growth) < 0.0 < np.nanmax(growth):
            ax.contour(linear["x"], linear["y"], growth, levels=[0.0], colors="crimson", linewidths=1.6)
        for curve in response.curves:
            points = np.array(curve.points)
            ax.plot(points[:, 0], points[:, 1], CURVE_STYLES.get(curve.source, "-"), color="white", lw=2.6)
            ax.plot(points[:, 0], points[:, 1], CURVE_STYLES.get(curve.source, "-"), color="k", lw=1.3)
        ax.set_title(title, fontsize=11)
        ax.set_xlabel(response.x)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        image = image or plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    axes[0].set_ylabel(response.y)
    shown = set(response.classes("truth").ravel()) | (set(response.classes("df").ravel()) if has_df else set())
    handles = [Patch(color=CLASS_COLOURS[k], label=LABELS.get(k, "the plant or G refuses the values"))
               for k in ("hunts", "unstable", "diverges", "none", "incomplete", "uncomputed", "error")
               if k in shown or k == "none"]
    if response.linear["growth"]:  # (a user's FMU has no linear loop dfwb knows)
        handles.append(plt.Line2D([], [], color="crimson", lw=1.6, label="linear loop's stability boundary"))
    for source in sorted({c.source for c in response.curves}):
        kinds = ", ".join(sorted({c.kind for c in response.curves if c.source == source}))
        handles.append(plt.Line2D([], [], color="k", ls=CURVE_STYLES.get(source, "-"),
                                  label=f"{'truth' if source == 'truth' else 'DF'}: {kinds}"))
    figure = axes[0].figure
    figure.legend(handles=handles, fontsize=9, loc="outside lower center", ncol=min(len(handles), 3))
    if norm is not None:
        bar = figure.colorbar(image, ax=list(axes[:1 + has_df]), fraction=0.04, pad=0.02)
        bar.set_label(f"hunts: first-harmonic amplitude of the output [{response.unit}]")
    axes[0].figure.suptitle(f"{response.plant} under G = {response.G}: where it hunts", fontsize=12)
    return axes


def margin_plot(ax, response):
    """The hunting cycle's amplitude against the gain factor k, truth and DF; returns the lines."""
    lines = []
    for margin, offset in ((response.truth, 0), (response.df, 1)):
        if margin is None:
            continue
        colour = BRANCH_COLOURS.get(margin.source, "k")
        name = "truth" if margin.source == "truth" else "DF"
        ks = [k for k, _kind, a, _w in margin.scan if a]
        amplitudes = [a for _k, _kind, a, _w in margin.scan if a]
        line, = ax.plot(ks, amplitudes, "o-" if margin.source == "truth" else "s--", color=colour, ms=4,
                        label=f"{name}: hunting amplitude")
        lines.append(line)
        for lo, hi in margin.intervals:
            ax.axvspan(lo, hi, ymin=0.0 + 0.5 * offset, ymax=0.5 + 0.5 * offset, color=colour, alpha=0.12)
        for i, b in enumerate(margin.boundaries):
            ax.axvline(b.k, color=colour, ls=":", lw=1.0)
            ax.annotate(f"{name}: {b.kind}\nk = {b.k:.4g}", (b.k, 0.04 + 0.5 * offset + 0.12 * (i % 2)),
                        xycoords=("data", "axes fraction"), xytext=(4, 0), textcoords="offset points", fontsize=8,
                        color=colour)
    ax.axvline(1.0, color="k", lw=1.2)
    ax.annotate("k = 1: G as given", (1.0, 0.5), xycoords=("data", "axes fraction"), xytext=(-4, 0),
                textcoords="offset points", ha="right", rotation=90, va="center", fontsize=8)
    ax.set_xscale("log")
    if lines and any(len(line.get_xdata()) for line in lines):
        ax.set_yscale("log")
    ax.set_xlabel("gain factor k (the controller is k G)")
    ax.set_ylabel(f"first-harmonic amplitude [{response.unit}]")
    ax.set_title(f"{response.plant} under k ({response.G}): where it hunts\n(shaded: truth in the lower half, "
                 "the DF in the upper)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    if lines:
        ax.legend(fontsize=8)
    return lines


TUNE_COLOURS = {"accepted": "#2a9d8f", "standing error": "#e9c46a", "hunts": "#e76f51",
                "linear loop unstable": "#3a3a3a", "refused": "#e63946", "not tried": "#d9d9d9"}


def tune_plot(ax, response):
    """:class:`dfwb.studies.responses.TuneResponse`: G's settings over its first two free parameters (or the
    first against the crossover), each coloured by its best verdict over the compensators' settings; the
    chosen one starred. Returns the lines."""
    controller = response.controller or list(response.free)
    x = controller[0]
    y = controller[1] if len(controller) > 1 else None
    order = list(TUNE_COLOURS)
    best = {}
    for c in response.candidates:
        key = (c["values"][x], c["values"][y] if y else c["crossover"])
        if key not in best or order.index(c["verdict"]) < order.index(best[key]):
            best[key] = c["verdict"]
    lines = []
    for verdict in order:
        points = [key for key, v in best.items() if v == verdict]
        if points:
            xs, ys = zip(*points)
            lines += ax.plot(xs, ys, "s", ms=9, color=TUNE_COLOURS[verdict], label=verdict, ls="none")
    if y is not None:  # each of G's settings: its linear loop's crossover, what the search ranks them by
        for c in {(c["values"][x], c["values"][y]): c for c in response.candidates}.values():
            if math.isfinite(c["crossover"]):
                ax.annotate(f"{c['crossover']:.3g}", (c["values"][x], c["values"][y]), xytext=(0, 7),
                            textcoords="offset points", ha="center", fontsize=6, color="0.35")
    if response.settings is not None:
        lines += ax.plot(response.settings[x], response.settings[y] if y else response.crossover, "*", ms=20,
                         mfc="none", mec="k", mew=1.6,
                         label="chosen: " + ", ".join(f"{k} = {v:.4g}" for k, v in response.settings.items()))
    if response.free[x][0] > 0:
        ax.set_xscale("log")
    if y is not None and response.free[y][0] > 0:
        ax.set_yscale("log")
    ax.set_xlabel(x)
    ax.set_ylabel(y if y else "crossover [rad/s]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{response.plant} under {response.G}: the fastest setting that does not hunt\n(grey numbers: "
                 "the linear loop's crossover [rad/s], the search's order)", fontsize=10)
    return lines
