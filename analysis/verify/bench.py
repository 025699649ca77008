"""dfwb bench: run time against error of every way to get a DF point, measured side by side.

For each registered plant with benchmark points (``Plant.bench``) and a
reference (``Plant.reference``), at each of its points, each method and setting computes N(F, w)
repeatedly, interleaved with the others (so all see the same machine load);
the median time and the relative error against a tight reference are
recorded (a run under :data:`WARM` is repeated at once and the repeat timed:
every method as a sweep runs it, caches warm). Methods:

- ``fmu-native``: this project's native FMU (the exact solver in C with an FMI
  wrapper, no Python: the default kind) with its built-in excitation;
- ``fmu-python-core``: the pythonfmu FMU of the same plant on the compiled core
  it carries (``DFWB_FMU_SOLVER=native``; left out, with the reason in
  ``bench.md``, if the core does not load);
- ``fmu-pure-python``: the pythonfmu FMU on its pure-Python solver
  (``DFWB_FMU_SOLVER=python``). The three exact FMUs give the same numbers bit
  for bit; they differ in cost only;
- ``fmu-input``: the native FMU driven by a sampled sine held over each step;
- ``fmu-karnopp``: the native FMU at the plant's regularised variants (``Plant.variants``:
  the friction FMU with Karnopp's band Dv, the paper's way);
- ``fmu-fixedstep``: the plant's naive fixed-step twin FMU (``Plant.naive``:
  semi-implicit Euler inside doStep, a pythonfmu FMU);
- ``scipy-<method>``: what a user would write with ``solve_ivp`` (``Plant.scipy``:
  event functions, ``dfwb.plants.reference``; for the static backlash the mass
  ODE on a dense grid and the play operator).

A plant without a naive twin or a scipy rival gets fewer methods. The
reference (``Plant.reference``): scipy DOP853 at rtol 1e-12 (friction,
backlash), the closed form (static backlash). Outputs: ``bench.csv`` (plant, method, setting, F,
omega, eps, error, seconds), ``pareto_<plant>.png`` and ``bench.md``, plus
the cost per event of each exact FMU kind (:func:`event_cost`), how the
cost grows with the periods to steady state and with a sweep's size and
processes, and the cost and error of a DF point of a user's FMU through the
generic driver (:mod:`dfwb.verify.foreign_bench`; rows in ``foreign.csv``).
"""

import contextlib
import csv
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from dfwb.engine.describing import DFEngine
from dfwb.fmi.location import fmu_path
from dfwb.fmi.simulation import FMUError
from dfwb.fmus.facade import SOLVER_VARIABLE  # read by a pythonfmu plant FMU at each exitInitializationMode
from dfwb.plants import PLANTS
from dfwb.plotting import plots
from dfwb.studies.sweep import grid, run_sweep
from dfwb.verify.foreign_bench import FIELDS as FOREIGN_FIELDS
from dfwb.verify.foreign_bench import foreign_markdown, foreign_rows

SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau")
FIELDS = ["plant", "method", "setting", "F", "omega", "eps", "error", "seconds"]  # bench.csv's columns
EXACT = (("fmu-native", "native", None), ("fmu-python-core", "python", "native"),
         ("fmu-pure-python", "python", "python"))
"""The exact FMU kinds: (method, kind of FMU for fmu_path, DFWB_FMU_SOLVER inside it, None: not set)."""
EVENT_PERIODS = 200  # periods of the long run that measures the cost per event
EVENT_REPEATS = 9  # its repeats (median)
WARM = 0.01
"""A run shorter than this (s) is repeated at once and the repeat timed: every method as in a sweep, caches warm
(a lone 0.1 ms DF point right after other work costs ~0.3 ms more, a cost that says nothing about the method)."""


def points(quick):
    """{plant: [(F, omega, params)]}: every registered plant with benchmark points and a reference."""
    which = "quick" if quick else "full"
    return {entry.name: list(entry.bench[which]) for entry in PLANTS.values()
            if entry.reference is not None and entry.bench.get(which)}


def relative_error(value, truth):
    """|value - truth| / |truth| (|value| where the truth is 0)."""
    return abs(value - truth) / abs(truth) if truth != 0 else abs(value)


def label(F, omega, params, sep=", ", eq=" = "):
    """'F = 50, w = 20, eps = 0.5': a point's label."""
    return sep.join([f"F{eq}{F:g}", f"w{eq}{omega:g}"] + [f"{k}{eq}{v:g}" for k, v in params.items()])


@contextlib.contextmanager
def solver_variable(value):
    """``DFWB_FMU_SOLVER`` set to ``value`` (None: left as it is) inside the block, restored after.

    A pythonfmu plant FMU reads the variable at every exitInitializationMode,
    that is at every run from rest (each DF point, each shooting run), so it
    must be set around every point of an engine, not only its first.
    """
    if value is None:
        yield
        return
    before = os.environ.get(SOLVER_VARIABLE)
    os.environ[SOLVER_VARIABLE] = value
    try:
        yield
    finally:
        if before is None:
            del os.environ[SOLVER_VARIABLE]
        else:
            os.environ[SOLVER_VARIABLE] = before


class ExactFMU:
    """The DF engine of one exact FMU kind of a plant (:data:`EXACT`): ``point(F, omega, params)``.

    ``path`` is the FMU, ``solver`` the ``DFWB_FMU_SOLVER`` set around each of
    its points. ``why`` is None, or why this kind cannot run here (its core
    does not load): the first point, at ``warm``, is run at creation.
    """

    def __init__(self, plant, method, kind, solver, warm, fmu_dir=None):
        self.plant, self.method, self.kind, self.solver = plant, method, kind, solver
        self.path = fmu_path(PLANTS[plant], fmu_dir, kind=kind)
        self.engine = DFEngine(plant, fmu=self.path)
        self.why = None
        try:
            self.point(*warm)  # instantiates the FMU; with DFWB_FMU_SOLVER=native, fails if the core cannot load
        except FMUError as error:
            self.why = str(error)

    def point(self, F, omega, params=None):
        with solver_variable(self.solver):
            return self.engine.point(F, omega, dict(params or {}))

    def events(self, F, omega, params=None):
        """(DFResult, events): the point and the events its runs simulated, read from the FMU's ``events``.

        The engine's runs (from rest, shooting) each start at 0 events; their
        last ``events`` read (after each period) is summed. Untimed: the extra
        reads cost a little.
        """
        engine, counts = self.engine, []
        run = engine._run

        def counted(session, *args):
            counts.append(0)
            index = len(counts) - 1
            for item in run(session, *args):
                counts[index] = session.integers(["events"])[0]
                yield item

        engine._run = counted
        try:
            result = self.point(F, omega, params)
        finally:
            del engine._run
        return result, sum(counts)


def exact_fmus(plant, warm, fmu_dir=None):
    """[ExactFMU] of a plant, one per :data:`EXACT` kind (check ``why`` before use)."""
    return [ExactFMU(plant, method, kind, solver, warm, fmu_dir) for method, kind, solver in EXACT]


def event_cost(exact, F, omega, params=None, periods=EVENT_PERIODS, repeats=EVENT_REPEATS):
    """The cost per event of an exact FMU: {"events", "one_step", "per_period"} (seconds per event).

    The FMU runs ``periods`` forcing periods from rest at (F, omega, params):
    once in a single doStep (``one_step``: the solver's own cost per event)
    and once in one doStep per period (``per_period``: as the DF engine drives
    it, the FMI calls included); medians of ``repeats``.
    """
    from dfwb.fmi.session import FMUSession

    session = FMUSession(exact.path)
    values = dict(exact.engine.plant.at_origin(dict(params or {}))[0], F=F, omega=omega, phi=0.0)
    period = 2 * math.pi / omega
    times = {"one_step": [], "per_period": []}
    events = None
    for _ in range(repeats):
        for way in times:
            with solver_variable(exact.solver):
                session.start(values)
            t0 = time.perf_counter()
            if way == "one_step":
                session.step(periods * period)
            else:
                for _ in range(periods):
                    session.step(period)
            times[way].append(time.perf_counter() - t0)
            events = session.integers(["events"])[0]
    return dict({way: statistics.median(t) / max(events, 1) for way, t in times.items()}, events=events)


class Method:
    """One method at one setting: ``run(F, omega, params) -> N``."""

    def __init__(self, plant, name, setting, run):
        self.plant, self.name, self.setting, self.run = plant, name, setting, run


def methods(plant, quick, exact=None, fmu_dir=None):
    """Every (method, setting) of a plant, fastest engines created once; what the plant's entry offers.

    ``exact``: the plant's :func:`exact_fmus` (made here if None); a kind that cannot run is left out.
    ``fmu_dir``: the FMU folder (default: dfwb's own).
    """
    entry = PLANTS[plant]
    exact = exact if exact is not None else exact_fmus(plant, entry.bench["quick"][0], fmu_dir)
    out = [Method(plant, e.method, "", lambda F, w, p, e=e: e.point(F, w, p).N) for e in exact if e.why is None]
    native = exact[0]  # fmu-native: the other ways of driving the plant use the default kind too
    for n in ((8, 32, 128, 512) if quick else (8, 16, 32, 64, 128, 256, 512, 1024)):
        engine = DFEngine(plant, drive="input", samples_per_period=n, fmu=native.path)
        out.append(Method(plant, "fmu-input", f"{n}/period",
                          lambda F, w, p, engine=engine: engine.point(F, w, p).N))
    for label, extra in entry.variants:
        out.append(Method(plant, "fmu-karnopp", label,
                          lambda F, w, p, extra=extra: native.point(F, w, dict(p, **extra)).N))
    if entry.naive is not None:
        naive = DFEngine(plant, fmu_dir, model=entry.naive.__name__, max_periods=60)
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


def run_bench(out_dir="out/bench", quick=False, repeats=None, report=print, fmu_dir=None):
    """Measure every method at every point; write bench.csv, pareto_*.png, bench.md (FMUs from ``fmu_dir``)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    repeats = repeats or (3 if quick else 5)
    rows, failures, costs = [], [], {}
    started = time.perf_counter()
    measured = points(quick)
    for plant, plant_points in measured.items():
        exact = exact_fmus(plant, plant_points[0], fmu_dir)
        failures += [f"{plant}: {e.method} cannot run ({e.why})" for e in exact if e.why is not None]
        costs[plant] = {e.method: event_cost(e, *plant_points[0]) for e in exact if e.why is None}
        # events per DF point, at each point in order (untimed; the same for every exact kind, bit for bit)
        costs[plant]["events"] = [exact[0].events(F, omega, params)[1] for F, omega, params in plant_points]
        candidates = methods(plant, quick, exact, fmu_dir)
        for F, omega, params in plant_points:
            truth = reference(plant, F, omega, params)
            times = {id(m): [] for m in candidates}
            values, failed = {}, {}
            for _ in range(repeats):  # interleaved: every method once per round
                for m in candidates:
                    if id(m) in failed or (times[id(m)] and sum(times[id(m)]) > 2.0):
                        continue  # failed, or slow: one or two runs are a fair median already
                    for attempt in range(2):  # a quick run is repeated at once, the repeat timed (caches warm)
                        t0 = time.perf_counter()
                        try:
                            values[id(m)] = m.run(F, omega, dict(params))
                        except (RuntimeError, ValueError, ArithmeticError) as error:  # the method gave up
                            failed[id(m)] = f"{type(error).__name__}: {error}"
                        seconds = time.perf_counter() - t0
                        if id(m) in failed or seconds >= WARM:
                            break
                    times[id(m)].append(seconds)
            for m in candidates:
                if id(m) in failed:
                    error = math.inf
                    failures.append(f"{plant} {label(F, omega, params)}: {m.name} {m.setting} failed "
                                    f"({failed[id(m)]})")
                else:
                    error = relative_error(values[id(m)], truth)
                rows.append({"plant": plant, "method": m.name, "setting": m.setting, "F": F, "omega": omega,
                             "eps": params.get("eps", ""), "error": error,
                             "seconds": statistics.median(times[id(m)]), "params": dict(params)})
            report(f"{plant} {label(F, omega, params, ' ', '=')}: "
                   f"{len(candidates)} methods ({time.perf_counter() - started:.0f} s so far)")
    with open(out_dir / "bench.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS, extrasaction="ignore")  # params: eps has a column
        writer.writeheader()
        writer.writerows(rows)
    for plant in measured:
        pareto(out_dir, plant, [r for r in rows if r["plant"] == plant])
    growth = cost_growth(quick, fmu_dir)
    foreign = foreign_rows(quick, repeats, fmu_dir, report)
    with open(out_dir / "foreign.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=FOREIGN_FIELDS + ["why"])
        writer.writeheader()
        writer.writerows(foreign)
    (out_dir / "bench.md").write_text(summary(rows, growth, quick, time.perf_counter() - started, failures, costs,
                                              foreign))
    return out_dir / "bench.md"


def _point(row):
    """(F, omega, sorted params): which point a row measured."""
    return row["F"], row["omega"], tuple(sorted(row["params"].items()))


STYLES = {  # the exact FMUs: stars (the same error, bit for bit; their costs differ)
    "fmu-native": {"lw": 2.5, "marker": "*", "ms": 14, "color": "k", "zorder": 5},
    "fmu-python-core": {"lw": 2, "marker": "*", "ms": 11, "color": "tab:cyan", "zorder": 4},
    "fmu-pure-python": {"lw": 2, "marker": "*", "ms": 11, "color": "tab:gray", "zorder": 4},
}


def pareto(out_dir, plant, rows):
    keys = sorted({_point(r) for r in rows})
    figure, axes = plots.plt.subplots(1, len(keys), figsize=(5.5 * len(keys), 4.5), squeeze=False)
    for ax, key in zip(axes[0], keys):
        here = [r for r in rows if _point(r) == key]
        F, omega, params = key
        for method in dict.fromkeys(r["method"] for r in here):
            mine = sorted((r for r in here if r["method"] == method and math.isfinite(r["error"])),
                          key=lambda r: r["seconds"])
            style = STYLES.get(method, {"marker": "o"})
            ax.loglog([r["seconds"] for r in mine], [max(r["error"], 1e-17) for r in mine], label=method, **style)
        ax.set_xlabel("seconds per DF point (median)")
        ax.set_ylabel("relative error of N")
        ax.set_title(f"{plant}: {label(F, omega, dict(params))}", fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].legend(fontsize=7)
    plots.save(figure, out_dir, f"pareto_{plant}")


def speed_ratios(rows):
    """Per point: fmu-native (and the pythonfmu kinds) against the fastest other method at equal or better error."""
    exact_kinds = [method for method, _kind, _solver in EXACT]
    lines = []
    for key in dict.fromkeys((r["plant"],) + _point(r) for r in rows):
        here = [r for r in rows if (r["plant"],) + _point(r) == key]
        kinds = {r["method"]: r for r in here if r["method"] in exact_kinds}
        native = kinds["fmu-native"]
        others = " | ".join(f"{kinds[m]['seconds'] * 1e3:.3g} ms ({kinds[m]['seconds'] / native['seconds']:.1f}x)"
                            if m in kinds else "-" for m in exact_kinds[1:])
        rivals = [r for r in here if r["method"] not in exact_kinds and r["error"] <= max(native["error"], 1e-14)]
        where = f"{key[0]} {label(key[1], key[2], dict(key[3]))}"
        head = f"| {where} | {native['seconds'] * 1e3:.3g} ms, {native['error']:.1e} | {others} | "
        if rivals:
            best = min(rivals, key=lambda r: r["seconds"])
            lines.append(head + f"{best['method']} {best['setting']}: {best['seconds'] * 1e3:.3g} ms, "
                         f"{best['error']:.1e} | {best['seconds'] / native['seconds']:.0f}x |")
        else:
            closest = min((r for r in here if r["method"] not in exact_kinds), key=lambda r: r["error"])
            lines.append(head + f"none reaches it; the most accurate, {closest['method']} {closest['setting']}: "
                         f"{closest['seconds'] * 1e3:.3g} ms, {closest['error']:.1e} | "
                         f"> {closest['seconds'] / native['seconds']:.0f}x |")
    return lines


def event_costs(rows, costs):
    """The cost-per-event table: per plant and exact kind, the long runs' cost and a DF point's cost per event."""
    lines = []
    for plant, table in costs.items():
        events = table.get("events", [])
        for method, _kind, _solver in EXACT:
            if method not in table:
                continue
            cost = table[method]
            seconds = [r["seconds"] for r in rows if r["plant"] == plant and r["method"] == method]
            per_point = (f"{1e6 * statistics.median(s / e for s, e in zip(seconds, events) if e):.1f} us"
                         if seconds and any(events) else "-")
            lines.append(f"| {plant} | {method} | {1e6 * cost['one_step']:.2f} us | {1e6 * cost['per_period']:.2f} us "
                         f"| {cost['events']} | {', '.join(map(str, events))} | {per_point} |")
    return lines


def cost_growth(quick, fmu_dir=None):
    """DF time against the periods to steady state; sweep time against grid size and processes."""
    engine = DFEngine("backlash", fmu_dir)
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
                run_sweep("friction", points, tmp, jobs=jobs, fmu_dir=fmu_dir, progress=False)
                sweeps.append((size, jobs, time.perf_counter() - t0))
    return {"per_period": slope, "fixed": intercept, "points": by_periods, "sweeps": sweeps}


def summary(rows, growth, quick, seconds, failures=(), costs=None, foreign=()):
    text = ["# Run time against error", "",
            f"{'Quick' if quick else 'Full'} set, measured in {seconds:.0f} s on this machine (2 shared cores): every "
            "method timed interleaved with the others, medians of repeats (a run under 10 ms is repeated at once "
            "and the repeat timed: caches warm, as in a sweep); errors of N against scipy DOP853 at rtol "
            "1e-12 (friction, backlash; itself good to ~1e-10) or the closed form (static backlash). "
            "fmu-native: the native FMU (C, no Python); fmu-python-core: the pythonfmu FMU on its compiled core; "
            "fmu-pure-python: the pythonfmu FMU on its pure-Python solver (DFWB_FMU_SOLVER=python). The three "
            "give the same N bit for bit.", "",
            "## fmu-native against the fastest method at equal or better error", "",
            "| point | fmu-native | fmu-python-core (/ native) | fmu-pure-python (/ native) | "
            "fastest non-exact method at equal or better error | ratio to fmu-native |", "|---|---|---|---|---|---|"]
    text += speed_ratios(rows)
    plants = dict.fromkeys(r["plant"] for r in rows)
    text += ["", "Pareto plots: " + ", ".join(f"![{p}](pareto_{p}.png)" for p in plants)]
    if costs:
        text += ["", "## Cost per event", "",
                 f"Each exact FMU run {EVENT_PERIODS} forcing periods from rest at the plant's first point, medians "
                 f"of {EVENT_REPEATS}: in one doStep (the solver's own cost per event) and in one doStep per period "
                 "(as the DF engine drives it, FMI calls included); then a DF point's median time over the events it "
                 "simulated (events from the FMU's `events` output, summed over the point's runs; fixed costs "
                 "of reset, initialisation and reads included).", "",
                 "| plant | FMU | per event, one doStep | per event, a doStep per period | events in the run | "
                 "events per DF point | DF point time per event (median) |", "|---|---|---|---|---|---|---|"]
        text += event_costs(rows, costs)
    text += ["", "## How the cost grows", "",
             f"DF time against periods to steady state (backlash, F = 50 N, 10 points): "
             f"{growth['per_period'] * 1e3:.3f} ms per period + {growth['fixed'] * 1e3:.2f} ms "
             f"(periods: {sorted(int(p) for p, _ in growth['points'])}).", "",
             "| sweep points | processes | seconds |", "|---|---|---|"]
    text += [f"| {size} | {jobs} | {t:.2f} |" for size, jobs, t in growth["sweeps"]]
    if foreign:
        text += [""] + foreign_markdown(foreign)
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
