"""dfwb bench: run time against error of every way to get a DF point, measured side by side.

For each registered plant with benchmark points (``Plant.bench``) and a
reference (``Plant.reference``), at each of its points, each method and setting computes N(F, w)
repeatedly, interleaved with the others (so all see the same machine load);
the median time and the relative error against a tight reference are
recorded. Methods:

- ``fmu-exact``: this project's FMU with its built-in excitation;
- ``fmu-input``: the same FMU driven by a sampled sine held over each step;
- ``fmu-karnopp``: the FMU at the plant's regularised variants (``Plant.variants``:
  the friction FMU with Karnopp's band Dv, the paper's way);
- ``fmu-fixedstep``: the plant's naive fixed-step twin FMU (``Plant.naive``:
  semi-implicit Euler inside doStep);
- ``scipy-<method>``: what a user would write with ``solve_ivp`` (``Plant.scipy``:
  event functions, ``dfwb.plants.reference``; for the static backlash the mass
  ODE on a dense grid and the play operator).

A plant without a naive twin or a scipy rival gets fewer methods. The
reference (``Plant.reference``): scipy DOP853 at rtol 1e-12 (friction,
backlash), the closed form (static backlash). Outputs: ``bench.csv`` (plant, method, setting, F,
omega, eps, error, seconds), ``pareto_<plant>.png`` and ``bench.md``, plus
how the cost grows with the periods to steady state and with a sweep's size
and processes.
"""

import csv
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from dfwb.engine.describing import DFEngine
from dfwb.plants import PLANTS
from dfwb.plotting import plots
from dfwb.studies.sweep import grid, run_sweep

SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau")
FIELDS = ["plant", "method", "setting", "F", "omega", "eps", "error", "seconds"]  # bench.csv's columns


def points(quick):
    """{plant: [(F, omega, params)]}: every registered plant with benchmark points and a reference."""
    which = "quick" if quick else "full"
    return {entry.name: list(entry.bench[which]) for entry in PLANTS.values()
            if entry.reference is not None and entry.bench.get(which)}


def _label(F, omega, params, sep=", ", eq=" = "):
    """'F = 50, w = 20, eps = 0.5': a point's label."""
    return sep.join([f"F{eq}{F:g}", f"w{eq}{omega:g}"] + [f"{k}{eq}{v:g}" for k, v in params.items()])


class Method:
    """One method at one setting: ``run(F, omega, params) -> N``."""

    def __init__(self, plant, name, setting, run):
        self.plant, self.name, self.setting, self.run = plant, name, setting, run


def methods(plant, quick):
    """Every (method, setting) of a plant, fastest engines created once; what the plant's entry offers."""
    entry = PLANTS[plant]
    out = []
    exact = DFEngine(plant)
    out.append(Method(plant, "fmu-exact", "", lambda F, w, p: exact.point(F, w, p).N))
    for n in ((8, 32, 128, 512) if quick else (8, 16, 32, 64, 128, 256, 512, 1024)):
        engine = DFEngine(plant, drive="input", samples_per_period=n)
        out.append(Method(plant, "fmu-input", f"{n}/period",
                          lambda F, w, p, engine=engine: engine.point(F, w, p).N))
    for label, extra in entry.variants:
        out.append(Method(plant, "fmu-karnopp", label,
                          lambda F, w, p, extra=extra: exact.point(F, w, dict(p, **extra)).N))
    if entry.naive is not None:
        naive = DFEngine(plant, model=entry.naive.__name__, max_periods=60)
        for per in ((100, 1000) if quick else (100, 300, 1000, 3000)):
            out.append(Method(plant, "fmu-fixedstep", f"{per} steps/period",
                              lambda F, w, p, per=per: naive.point(F, w, dict(p, dt=2 * math.pi / w / per)).N))
    if entry.scipy is not None:
        rtols = (1e-3, 1e-6, 1e-9) if quick else (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
        for method in SCIPY_METHODS:
            for rtol in rtols:
                if method == "Radau" and rtol < 1e-8:
                    continue  # minutes per point: a user would not go there either
                out.append(Method(plant, f"scipy-{method}", f"rtol={rtol:g}",
                                  lambda F, w, p, m=method, r=rtol: entry.scipy(F, w, p, m, r)))
    return out


def reference(plant, F, omega, params):
    """N by the plant's independent reference (scipy at tight tolerance, or a closed form)."""
    return PLANTS[plant].reference(F, omega, dict(params))


def run_bench(out_dir="out/bench", quick=False, repeats=None, report=print):
    """Measure every method at every point; write bench.csv, pareto_*.png, bench.md."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    repeats = repeats or (3 if quick else 5)
    rows, failures = [], []
    started = time.perf_counter()
    measured = points(quick)
    for plant, plant_points in measured.items():
        candidates = methods(plant, quick)
        for F, omega, params in plant_points:
            truth = reference(plant, F, omega, params)
            times = {id(m): [] for m in candidates}
            values, failed = {}, {}
            for _ in range(repeats):  # interleaved: every method once per round
                for m in candidates:
                    if id(m) in failed or (times[id(m)] and sum(times[id(m)]) > 2.0):
                        continue  # failed, or slow: one or two runs are a fair median already
                    t0 = time.perf_counter()
                    try:
                        values[id(m)] = m.run(F, omega, dict(params))
                    except (RuntimeError, ValueError, ArithmeticError) as error:  # the method gave up
                        failed[id(m)] = f"{type(error).__name__}: {error}"
                    times[id(m)].append(time.perf_counter() - t0)
            for m in candidates:
                if id(m) in failed:
                    error = math.inf
                    failures.append(f"{plant} {_label(F, omega, params)}: {m.name} {m.setting} failed "
                                    f"({failed[id(m)]})")
                else:
                    error = abs(values[id(m)] - truth) / abs(truth) if truth != 0 else abs(values[id(m)])
                rows.append({"plant": plant, "method": m.name, "setting": m.setting, "F": F, "omega": omega,
                             "eps": params.get("eps", ""), "error": error,
                             "seconds": statistics.median(times[id(m)]), "params": dict(params)})
            report(f"{plant} {_label(F, omega, params, ' ', '=')}: "
                   f"{len(candidates)} methods ({time.perf_counter() - started:.0f} s so far)")
    with open(out_dir / "bench.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS, extrasaction="ignore")  # params: eps has a column
        writer.writeheader()
        writer.writerows(rows)
    for plant in measured:
        pareto(out_dir, plant, [r for r in rows if r["plant"] == plant])
    growth = cost_growth(quick)
    (out_dir / "bench.md").write_text(summary(rows, growth, quick, time.perf_counter() - started, failures))
    return out_dir / "bench.md"


def _point(row):
    """(F, omega, sorted params): which point a row measured."""
    return row["F"], row["omega"], tuple(sorted(row["params"].items()))


def pareto(out_dir, plant, rows):
    keys = sorted({_point(r) for r in rows})
    figure, axes = plots.plt.subplots(1, len(keys), figsize=(5.5 * len(keys), 4.5), squeeze=False)
    for ax, key in zip(axes[0], keys):
        here = [r for r in rows if _point(r) == key]
        F, omega, params = key
        for method in dict.fromkeys(r["method"] for r in here):
            mine = sorted((r for r in here if r["method"] == method and math.isfinite(r["error"])),
                          key=lambda r: r["seconds"])
            style = {"lw": 2.5, "marker": "*", "ms": 12, "color": "k"} if method == "fmu-exact" else {"marker": "o"}
            ax.loglog([r["seconds"] for r in mine], [max(r["error"], 1e-17) for r in mine], label=method, **style)
        ax.set_xlabel("seconds per DF point (median)")
        ax.set_ylabel("relative error of N")
        ax.set_title(f"{plant}: {_label(F, omega, dict(params))}", fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].legend(fontsize=7)
    plots.save(figure, out_dir, f"pareto_{plant}")


def speed_ratios(rows):
    """Per point: fmu-exact against the fastest other method at equal or better error."""
    lines = []
    for key in dict.fromkeys((r["plant"],) + _point(r) for r in rows):
        here = [r for r in rows if (r["plant"],) + _point(r) == key]
        exact = next(r for r in here if r["method"] == "fmu-exact")
        rivals = [r for r in here if r["method"] != "fmu-exact" and r["error"] <= max(exact["error"], 1e-14)]
        label = f"{key[0]} {_label(key[1], key[2], dict(key[3]))}"
        if rivals:
            best = min(rivals, key=lambda r: r["seconds"])
            lines.append(f"| {label} | {exact['seconds'] * 1e3:.3g} ms, {exact['error']:.1e} | {best['method']} "
                         f"{best['setting']}: {best['seconds'] * 1e3:.3g} ms, {best['error']:.1e} | "
                         f"{best['seconds'] / exact['seconds']:.0f}x |")
        else:
            closest = min((r for r in here if r["method"] != "fmu-exact"), key=lambda r: r["error"])
            lines.append(f"| {label} | {exact['seconds'] * 1e3:.3g} ms, {exact['error']:.1e} | none reaches it; "
                         f"the most accurate, {closest['method']} {closest['setting']}: "
                         f"{closest['seconds'] * 1e3:.3g} ms, {closest['error']:.1e} | "
                         f"> {closest['seconds'] / exact['seconds']:.0f}x |")
    return lines


def cost_growth(quick):
    """DF time against the periods to steady state; sweep time against grid size and processes."""
    engine = DFEngine("backlash")
    by_periods = []
    for eps in (0.1, 0.3, 0.5, 0.7, 0.9):
        for omega in (20.0, 30.0):
            r = engine.point(50.0, omega, {"eps": eps})
            by_periods.append((r.periods, r.seconds))
    periods, seconds = np.array(by_periods, dtype=float).T
    slope, intercept = np.polyfit(periods, seconds, 1)
    sweeps = []
    sizes = (16, 64) if quick else (16, 64, 256)
    for size in sizes:
        points = grid([10.0, 30.0], list(np.geomspace(0.2, 5.0, size // 2)))
        for jobs in (1, 2):
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                run_sweep("friction", points, tmp, jobs=jobs, progress=False)
                sweeps.append((size, jobs, time.perf_counter() - t0))
    return {"per_period": slope, "fixed": intercept, "points": by_periods, "sweeps": sweeps}


def summary(rows, growth, quick, seconds, failures=()):
    text = ["# Run time against error", "",
            f"{'Quick' if quick else 'Full'} set, measured in {seconds:.0f} s on this machine (2 shared cores): every "
            "method timed interleaved with the others, medians of repeats; errors of N against scipy DOP853 at rtol "
            "1e-12 (friction, backlash; itself good to ~1e-10) or the closed form (static backlash).", "",
            "## fmu-exact against the fastest method at equal or better error", "",
            "| point | fmu-exact | fastest other at equal or better error | ratio |", "|---|---|---|---|"]
    text += speed_ratios(rows)
    plants = dict.fromkeys(r["plant"] for r in rows)
    text += ["", "Pareto plots: " + ", ".join(f"![{p}](pareto_{p}.png)" for p in plants),
             "", "## How the cost grows", "",
             f"DF time against periods to steady state (backlash, F = 50 N, 10 points): "
             f"{growth['per_period'] * 1e3:.3f} ms per period + {growth['fixed'] * 1e3:.2f} ms "
             f"(periods: {sorted(int(p) for p, _ in growth['points'])}).", "",
             "| sweep points | processes | seconds |", "|---|---|---|"]
    text += [f"| {size} | {jobs} | {t:.2f} |" for size, jobs, t in growth["sweeps"]]
    if failures:
        text += ["", "## Methods that gave up", "", "Recorded with an infinite error:", ""]
        text += [f"- {f}" for f in failures]
    text += ["", "Process start-up (a spawned worker imports numpy and fmpy and loads the FMU) costs about a "
             "second, so two processes pay off only from a few hundred milliseconds of work on.", "",
             "## Every measurement", "", "| plant | method | setting | F | w | eps | error | seconds |",
             "|---|---|---|---|---|---|---|---|"]
    text += [f"| {r['plant']} | {r['method']} | {r['setting']} | {r['F']:g} | {r['omega']:g} | {r['eps']} | "
             f"{r['error']:.2e} | {r['seconds']:.3g} |" for r in rows]
    return "\n".join(text) + "\n"
