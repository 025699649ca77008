"""Benchmark: the cost of one true limit cycle of the exact loop (shooting on the Poincare return map).

For each case (a plant in feedback with G(s), and a start): ``LoopProblem.shoot``
is timed over ``--repeats`` runs, interleaved across the cases, medians
reported. The target: one cycle in well under a second. Each run is
instrumented by wrapping methods on its own ``LoopProblem`` instance, and,
for the time of the run, the module function ``dfwb.engine.periodic.jacobian``
(the library's files are not touched):

* ``first_return`` (the ``returns``-th hit of the event section: one exact
  period of the loop, in C on the compiled core, or in Python with
  ``DFWB_FMU=python``): calls counted and timed, so the table gives the number
  of exact periods integrated and the mean cost of one;
* the phases of ``shoot`` = ``converge`` (Newton) + ``finish``: *setup* (the
  loop's scales and horizon, the first returns, the Newton scales: everything
  up to the end of the first ``_swing``), *Newton* (from there to the end of
  ``converge``: the forward-difference Jacobians and the damped line search),
  *multipliers* (``monodromy`` in ``finish``: a first return, the scales and
  the central-difference Jacobian) and *trace* (``period_trace``: the
  harmonics over one period); what ``finish`` does besides (the eigenvalues,
  the section states, the swing) is reported apart.

The time per Newton iteration is the Newton phase over the iterations (the
initial residual included, so a case that converges in 0 iterations has
none). Then, once per distinct loop: the DF prediction (``search`` on the
scene's ranges) and ``dfwb.engine.cycles.find_cycles`` from those
predictions, timed, with its coverage line (``CycleSearch.coverage.summary()``).
With ``--profile`` each case's ``shoot`` is also run once under cProfile and
the shares of the main functions are reported.

Usage: ``.venv/bin/python benchmarks/limit_cycle.py [--repeats 7] [--quick] [--profile] [--no-find-cycles]
[--out out/bench_limit_cycle]``. Writes ``limit_cycle.md`` and ``limit_cycle.json`` into ``--out``.
"""

import argparse
import cProfile
import json
import math
import os
import platform
import pstats
import statistics
import time
from pathlib import Path

from dfwb.engine import periodic
from dfwb.engine.cycles import find_cycles
from dfwb.engine.limit_cycles import search
from dfwb.engine.periodic import LoopProblem
from dfwb.engine.transfer import parse_transfer_function

PID = "20 + 100/s + 2*s/(0.1*s+1)"
LEAD = "200*(s+2)/(s+20)"
STATIC_LEAD = "20*(s+2)/(s+20)"
PI = "30 + 60/s"
FRICTION_RANGES = ((7.0001, 300.0), (0.05, 50.0))  # scenes/lc_friction_pid.toml
BACKLASH_RANGES = ((0.01, 100.0), (0.1, 60.0))  # scenes/lc_backlash_lead_eps0*.toml
STATIC_RANGES = ((0.01, 100.0), (0.1, 50.0))  # scenes/lc_static_backlash_lead.toml

# name, plant, G, params, start: ("rest", position) or ("df", index of the DF prediction), the DF search ranges
CASES = [
    ("friction PID, stable", "friction", PID, {}, ("rest", 0.3), FRICTION_RANGES),
    ("friction PID, unstable", "friction", PID, {}, ("df", 1), FRICTION_RANGES),
    ("backlash lead, eps 0.2", "backlash", LEAD, {"eps": 0.2}, ("rest", 0.03), BACKLASH_RANGES),
    ("backlash lead, eps 0.8", "backlash", LEAD, {"eps": 0.8}, ("rest", 0.03), BACKLASH_RANGES),
    ("static backlash lead", "static-backlash", STATIC_LEAD, {}, ("rest", 0.3), STATIC_RANGES),
    ("friction PI", "friction", PI, {}, ("rest", 0.3), FRICTION_RANGES),
]
QUICK = ("friction PID, stable", "static backlash lead")
PHASES = ("setup", "newton", "multipliers", "trace")


class Probe:
    """Wraps one LoopProblem's methods (on the instance) to count exact periods and time the phases of shoot."""

    def __init__(self, problem):
        self.problem = problem
        self.phase = "setup"
        self.periods = dict.fromkeys(PHASES, 0)  # first_return calls per phase
        self.period_seconds = 0.0
        self.marks = {}  # end of the first _swing (Newton begins), end of converge
        self.seconds = {"multipliers": 0.0, "trace": 0.0}
        self.jacobian_seconds = {"newton": 0.0, "multipliers": 0.0}
        first_return, swing, converge = problem.first_return, problem._swing, problem.converge
        monodromy, trace = problem.monodromy, problem.period_trace

        def counted_first_return(*args, **kwargs):
            started = time.perf_counter()
            try:
                return first_return(*args, **kwargs)
            finally:
                self.period_seconds += time.perf_counter() - started
                self.periods[self.phase] = self.periods.get(self.phase, 0) + 1

        def marked_swing(*args, **kwargs):
            value = swing(*args, **kwargs)
            if self.phase == "setup":  # the Newton scales: setup ends, Newton begins
                self.marks["newton"] = time.perf_counter()
                self.phase = "newton"
            return value

        def marked_converge(*args, **kwargs):
            try:
                return converge(*args, **kwargs)
            finally:
                self.marks["converged"] = time.perf_counter()
                self.phase = "finish"

        def timed_monodromy(*args, **kwargs):
            self.phase = "multipliers"
            started = time.perf_counter()
            try:
                return monodromy(*args, **kwargs)
            finally:
                self.seconds["multipliers"] += time.perf_counter() - started
                self.phase = "finish"

        def timed_trace(*args, **kwargs):
            self.phase = "trace"
            started = time.perf_counter()
            try:
                return trace(*args, **kwargs)
            finally:
                self.seconds["trace"] += time.perf_counter() - started
                self.phase = "finish"

        problem.first_return = counted_first_return
        problem._swing = marked_swing
        problem.converge = marked_converge
        problem.monodromy = timed_monodromy
        problem.period_trace = timed_trace

    def _timed_jacobian(self, jacobian):
        def timed(*args, **kwargs):
            started = time.perf_counter()
            try:
                return jacobian(*args, **kwargs)
            finally:
                if self.phase in self.jacobian_seconds:
                    self.jacobian_seconds[self.phase] += time.perf_counter() - started
        return timed

    def shoot(self, X):
        jacobian = periodic.jacobian  # a module function (converge and monodromy call it): wrapped for this run
        periodic.jacobian = self._timed_jacobian(jacobian)
        try:
            started, cpu = time.perf_counter(), time.process_time()
            cycle = self.problem.shoot(X)
            ended, cpu = time.perf_counter(), time.process_time() - cpu
        finally:
            periodic.jacobian = jacobian
        phases = {}
        if "newton" in self.marks and "converged" in self.marks:
            phases = {"setup": self.marks["newton"] - started, "newton": self.marks["converged"] - self.marks["newton"],
                      "multipliers": self.seconds["multipliers"], "trace": self.seconds["trace"],
                      "newton jacobians": self.jacobian_seconds["newton"]}
            phases["finish, other"] = ended - self.marks["converged"] - phases["multipliers"] - phases["trace"]
        return {"seconds": ended - started, "cpu_seconds": cpu, "cycle": cycle, "phases": phases,
                "periods": {phase: self.periods.get(phase, 0) for phase in PHASES},
                "period_seconds": self.period_seconds}


def make_start(problem, start, predictions):
    """The loop state LoopProblem.shoot starts from (its first hit of the section is the first Newton iterate)."""
    kind, value = start
    if kind == "rest":
        return problem.rest_start(value)
    found = problem.df_start(predictions[value])  # (state, period) or None
    if found is None:
        raise SystemExit(f"df_start found no start on DF prediction {value} ({predictions[value]})")
    return found[0]


def cycle_summary(cycle):
    if cycle is None:
        return None
    return {"omega": float(cycle.omega), "period": float(cycle.period), "amplitude_x": cycle.amplitude_x,
            "F": cycle.F, "stable": cycle.stable, "multipliers": cycle.multipliers, "residual": cycle.residual,
            "iterations": cycle.iterations, "returns": cycle.returns, "counts": cycle.counts}


def profile_shoot(plant, G, params, X, top=8):
    """cProfile of one shoot: the top functions by own time and the shares of the main ones (cumulative)."""
    from dfwb.fmus import hybrid

    problem = LoopProblem(plant, G, params)
    profiler = cProfile.Profile()
    profiler.enable()
    problem.shoot(X)
    profiler.disable()
    stats = pstats.Stats(profiler).stats  # (file, line, name) -> (cc, nc, tottime, cumtime, callers)
    shoot = LoopProblem.shoot.__code__
    total = stats[(shoot.co_filename, shoot.co_firstlineno, shoot.co_name)][3]

    def where(function):
        code = getattr(function, "__code__", None)
        return None if code is None else (code.co_filename, code.co_firstlineno, code.co_name)

    loop = problem.cls  # the compiled core's loop (ctypes calls into C) or the Python one (dfwb.fmus.loops)
    watched = {"loop.advance (integration, events)": loop.advance,
               "loop.sample (dense output)": loop.sample,
               "first_return": LoopProblem.first_return,
               "converge (Newton)": LoopProblem.converge,
               "jacobian (differences)": periodic.jacobian,
               "monodromy (multipliers)": LoopProblem.monodromy,
               "_swing (64 samples)": LoopProblem._swing,
               "period_trace": LoopProblem.period_trace}
    if issubclass(loop, hybrid.HybridSolver):  # the Python loop: its Taylor modes and event search
        watched.update({"Mode.__init__ (a mode's Taylor data)": hybrid.Mode.__init__,
                        "Mode.coefficients (event polynomials)": hybrid.Mode.coefficients,
                        "HybridSolver._search (event search)": hybrid.HybridSolver._search})
    shares = {}
    for label, function in watched.items():
        value = stats.get(where(function))
        shares[label] = {"calls": value[1] if value else 0, "share": value[3] / total if value else 0.0}
    own = sorted(stats.items(), key=lambda item: -item[1][2])[:top]
    tops = [{"function": key[2] if key[0] == "~" else f"{Path(key[0]).name}:{key[1]}({key[2]})", "calls": value[1],
             "share": value[2] / total} for key, value in own]
    return {"seconds": total, "loop": f"{loop.__module__}.{loop.__name__}", "cumulative": shares, "own_time": tops}


def main():
    options = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    options.add_argument("--repeats", type=int, default=7)
    options.add_argument("--quick", action="store_true", help=f"one repeat, two cases ({', '.join(QUICK)})")
    options.add_argument("--profile", action="store_true", help="one cProfile run of each case's shoot")
    options.add_argument("--no-find-cycles", action="store_true", help="skip the DF search and find_cycles timing")
    options.add_argument("--out", type=Path, default=Path("out/bench_limit_cycle"))
    args = options.parse_args()
    repeats = 1 if args.quick else args.repeats
    cases = [case for case in CASES if not args.quick or case[0] in QUICK]

    # the DF predictions, once per distinct loop (a DF start needs them; find_cycles starts from them)
    loops = {}
    for name, plant, G, params, start, ranges in cases:
        key = (plant, G, json.dumps(params, sort_keys=True))
        if key in loops or (args.no_find_cycles and start[0] != "df"):
            continue
        started = time.perf_counter()
        found = search(plant, parse_transfer_function(G), params, *ranges)
        loops[key] = {"name": name, "search_seconds": time.perf_counter() - started, "predictions": found.cycles}
        print(f"DF search, {plant} under {G} {params or ''}: {loops[key]['search_seconds']:.2f} s, "
              f"{len(found.cycles)} prediction(s)", flush=True)

    starts, start_seconds = {}, {}
    for name, plant, G, params, start, _ranges in cases:
        problem = LoopProblem(plant, G, params)
        predictions = loops.get((plant, G, json.dumps(params, sort_keys=True)), {}).get("predictions", [])
        started = time.perf_counter()
        starts[name] = make_start(problem, start, predictions)
        start_seconds[name] = time.perf_counter() - started

    warm = cases[0]  # imports and first calls out of the measurements
    Probe(LoopProblem(*warm[1:4])).shoot(starts[warm[0]])

    runs = {case[0]: [] for case in cases}
    for repeat in range(repeats):  # interleaved: every case sees the same machine load
        for name, plant, G, params, _start, _ranges in cases:
            run = Probe(LoopProblem(plant, G, params)).shoot(starts[name])
            runs[name].append(run)
            cycle = run["cycle"]
            print(f"[{repeat + 1}/{repeats}] {name}: {1e3 * run['seconds']:.3g} ms, "
                  f"{sum(run['periods'].values())} periods, "
                  + (f"{cycle.iterations} Newton iterations" if cycle else "no cycle"), flush=True)

    results = []
    for name, plant, G, params, start, _ranges in cases:
        median = {key: statistics.median(run[key] for run in runs[name])
                  for key in ("seconds", "cpu_seconds", "period_seconds")}
        phases = {}
        for phase in runs[name][0]["phases"]:
            phases[phase] = statistics.median(run["phases"].get(phase, math.nan) for run in runs[name])
        last = runs[name][-1]
        cycle = cycle_summary(last["cycle"])
        periods = last["periods"]
        total_periods = sum(periods.values())
        iterations = cycle["iterations"] if cycle else None
        results.append({
            "case": name, "plant": plant, "G": G, "params": params,
            "start": f"rest_start({start[1]})" if start[0] == "rest" else f"df_start(prediction {start[1]})",
            "start_seconds": start_seconds[name], "seconds": [run["seconds"] for run in runs[name]],
            "median_seconds": median["seconds"], "cpu_seconds": [run["cpu_seconds"] for run in runs[name]],
            "median_cpu_seconds": median["cpu_seconds"], "periods": periods, "total_periods": total_periods,
            "median_seconds_per_period": median["period_seconds"] / total_periods if total_periods else None,
            "median_period_share": median["period_seconds"] / median["seconds"],
            "phases": phases,
            "seconds_per_newton_iteration": phases["newton"] / iterations if iterations and phases else None,
            "cycle": cycle})

    if args.profile:
        for result, (name, plant, G, params, _start, _ranges) in zip(results, cases):
            result["profile"] = profile_shoot(plant, G, params, starts[name])
            print(f"profiled {name}: {1e3 * result['profile']['seconds']:.3g} ms under cProfile", flush=True)

    discovery = []
    if not args.no_find_cycles:
        for (plant, G, params_key), loop in loops.items():
            problem = LoopProblem(plant, G, json.loads(params_key))
            started = time.perf_counter()
            found = find_cycles(problem, loop["predictions"])
            seconds = time.perf_counter() - started
            coverage = found.coverage.summary(problem.spec.unit)
            discovery.append({
                "plant": plant, "G": G, "params": json.loads(params_key), "search_seconds": loop["search_seconds"],
                "find_cycles_seconds": seconds,
                "predictions": [{"omega": p.omega, "amplitude_x": p.amplitude_x, "stable": p.stable}
                                for p in loop["predictions"]],
                "cycles": [dict(cycle_summary(c), started_from=c.started_from) for c in found.cycles],
                "links": found.links, "coverage": found.coverage.as_dict(), "coverage_summary": coverage})
            print(f"find_cycles, {plant} under {G} {json.loads(params_key) or ''}: {seconds:.2f} s, "
                  f"{len(found.cycles)} true cycle(s); {coverage}", flush=True)

    machine = {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count(),
               "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None}
    text = markdown(results, discovery, repeats, machine)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "limit_cycle.md").write_text(text)
    (args.out / "limit_cycle.json").write_text(json.dumps(
        {"repeats": repeats, "quick": args.quick, "machine": machine, "cases": results, "find_cycles": discovery},
        indent=1, default=float) + "\n")
    print(text)


def markdown(results, discovery, repeats, machine):
    lines = [f"# One true limit cycle of the exact loop: the cost of `LoopProblem.shoot` (medians of {repeats})", "",
             "Wall time of `shoot` from the start shown (the start itself not included), and the process's CPU time "
             "(on shared cores the wall time can be twice the CPU time), repeats interleaved across the cases. "
             "*Periods*: calls of `first_return` (one exact period of the loop each: the section's hits, "
             "`returns` of them), as setup + Newton + multipliers. *Per period*: the mean wall time of one "
             "`first_return`. *Per Newton iteration*: the Newton phase of `converge` (forward-difference Jacobian "
             "and damped line search, the initial residual included) over the iterations. Split: setup (the "
             "loop's scales and horizon, the first returns, the Newton scales) / Newton (`converge` after the "
             "scales) / multipliers (`monodromy` in `finish`: central differences) / `period_trace` / the rest of "
             "`finish` (eigenvalues, section states, swing).", "",
             "| case | start | shoot [ms] | CPU [ms] | Newton its | periods | per Newton it [ms] | per period [ms] | "
             "split setup / Newton / mult. / trace / other [ms] | omega [rad/s] | X | stable | residual |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        c, p, ph = r["cycle"], r["periods"], r["phases"]
        per_it = f"{1e3 * r['seconds_per_newton_iteration']:.3g}" if r["seconds_per_newton_iteration"] else "-"
        per_period = f"{1e3 * r['median_seconds_per_period']:.3g}" if r["median_seconds_per_period"] else "-"
        split = (" / ".join(f"{1e3 * ph[k]:.3g}" for k in PHASES + ("finish, other",)) if ph else "-")
        counted = f"{r['total_periods']} ({p['setup']} + {p['newton']} + {p['multipliers']})"
        if c is None:
            found = "no cycle | " + " | ".join(["-"] * 8)
        else:
            found = (f"{c['iterations']} | {counted} | {per_it} | {per_period} | {split} | {c['omega']:.6f} | "
                     f"{c['amplitude_x']:.6g} | {'yes' if c['stable'] else 'no'} | {c['residual']:.1e}")
        lines.append(f"| {r['case']} | {r['start']} | {1e3 * r['median_seconds']:.3g} | "
                     f"{1e3 * r['median_cpu_seconds']:.3g} | {found} |")
    worst = max(results, key=lambda r: r["median_seconds"])
    under = sum(r["median_seconds"] < 1.0 for r in results)
    under_cpu = sum(r["median_cpu_seconds"] < 1.0 for r in results)
    lines += ["", f"{under} of {len(results)} cases under 1 s of wall time ({under_cpu} in CPU time); the slowest, "
              f"{worst['case']}, {worst['median_seconds']:.3g} s ({worst['median_cpu_seconds']:.3g} s CPU). "
              "`first_return` takes "
              f"{min(r['median_period_share'] for r in results):.0%} to "
              f"{max(r['median_period_share'] for r in results):.0%} of `shoot`; the rest is the loop's scales, the "
              "Newton scales (`_swing`: sampled integrations), `period_trace` and the linear algebra."]
    df = [r for r in results if r["start"].startswith("df_start")]
    for r in df:
        lines.append(f"The DF start of {r['case']} (`df_start`: the plant's open-loop orbit, 60 periods) took "
                     f"{r['start_seconds']:.2f} s more, not counted above.")
    profiled = [r for r in results if "profile" in r]
    if profiled:
        labels = list(dict.fromkeys(k for r in profiled for k in r["profile"]["cumulative"]))
        lines += ["", "## Where the time goes (one cProfile run of `shoot` each; cumulative shares)", "",
                  "*loop*: each case's exact loop class, "
                  + ", ".join(sorted({f"`{r['profile']['loop']}`" for r in profiled})) + ".", "",
                  "| case | under cProfile [ms] | " + " | ".join(labels) + " |",
                  "|---|---|" + "---|" * len(labels)]
        for r in profiled:
            cumulative = r["profile"]["cumulative"]
            lines.append(f"| {r['case']} | {1e3 * r['profile']['seconds']:.3g} | "
                         + " | ".join(f"{cumulative[k]['share']:.0%} ({cumulative[k]['calls']})" if k in cumulative
                                      else "-" for k in labels)
                         + " |")
        lines += ["", "Own time, top functions:", ""]
        for r in profiled:
            tops = ", ".join(f"{t['function']} {t['share']:.0%}" for t in r["profile"]["own_time"][:5])
            lines.append(f"- {r['case']}: {tops}")
    if discovery:
        lines += ["", "## The whole discovery, once per loop", "",
                  "`search` (the DF map and harmonic balance on the scene's ranges, default 16 x 48 map), then "
                  "`dfwb.engine.cycles.find_cycles` from its predictions (each shot directly and run; runs from "
                  "starts at the loop's default output amplitudes displacing the output, the velocity and each "
                  "controller state both ways, each until it settles; basin boundaries bisected), timed once. "
                  "Below the table, each search's coverage (`CycleSearch.coverage.summary()`).", "",
                  "| loop | DF search [s] | predictions (omega, X, stable) | find_cycles [s] | true cycles "
                  "(omega, X, stable, from) |", "|---|---|---|---|---|"]
        for d in discovery:
            loop = f"{d['plant']}, G = {d['G']}" + (f", {d['params']}" if d["params"] else "")
            predictions = "; ".join(f"{p['omega']:.4g}, {p['amplitude_x']:.4g}, {'s' if p['stable'] else 'u'}"
                                    for p in d["predictions"]) or "none"
            cycles = "; ".join(f"{c['omega']:.6g}, {c['amplitude_x']:.6g}, {'s' if c['stable'] else 'u'}, "
                               f"{len(c['started_from'])} start(s)" for c in d["cycles"]) or "none"
            lines.append(f"| {loop} | {d['search_seconds']:.2f} | {predictions} | {d['find_cycles_seconds']:.2f} | "
                         f"{cycles} |")
        lines.append("")
        for d in discovery:
            lines.append(f"- {d['plant']}, G = {d['G']}" + (f", {d['params']}" if d["params"] else "")
                         + f": {d['coverage_summary']}")
    load = machine["load_average"]
    lines += ["", f"Machine: {machine['cpus']} shared, noisy cores ({machine['platform']}, Python {machine['python']}"
              + (f", load average {load[0]:.2f} at the end" if load else "") + "); single-process timings."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
