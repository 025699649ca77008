"""The shipped limit-cycle examples: the DF's prediction, the co-simulation judge, and the exact truth.

1. PID position control of the friction mass: integral action and static
   friction make the mass hunt (a stable cycle, and an unstable one above it).
2. A lead compensator around the static backlash: the amplitude-only case,
   cross-checked against python-control in the tests.
3. The same kind of lead around the two-mass backlash with impacts, for
   eps = 0.2 and eps = 0.8.

Each example is a scene, ``scenes/lc_<name>.toml`` (``dfwb run`` runs one with
the cache). ``dfwb examples [--out DIR]`` runs them all: the harmonic balance
on the exact DF (:mod:`dfwb.engine.limit_cycles`), the judge (plant FMU and
LinearSystem.fmu co-simulated at a fixed step, :mod:`dfwb.engine.closed_loop`)
and the true cycles of the exact closed loop (:mod:`dfwb.engine.cycles`), all by
:func:`dfwb.studies.limit_cycles.analyse`,
then the judge's step study against the truth with Richardson's
extrapolation; it writes ``example_<name>.png``, ``examples.md`` and
``examples.json``.
"""

import json
from pathlib import Path

from dfwb.base.defaults import JUDGE_SAMPLES
from dfwb.engine.closed_loop import judge_errors, step_study
from dfwb.engine.cycles import relative_errors
from dfwb.studies.limit_cycles import analyse
from dfwb.studies.scene import load_scene, shipped_scenes

STEP_STUDY = (256, 512, 1024, 2048)  # steps per true period


def examples():
    """The [[limit_cycle]] of every shipped scene ``lc_*.toml``, by name."""
    return [cycle for path in shipped_scenes("lc_") for cycle in load_scene(path).limit_cycle]


def _percent(value):
    return "-" if value is None else f"{value:+.2%}"


def run_examples(out_dir="out/examples", samples_per_period=JUDGE_SAMPLES, report=print, fmu_dir=None):
    """Predict, judge, find the truth, study the judge's step and plot every example; return examples.md's path.

    ``fmu_dir``: the FMU folder (default: :func:`dfwb.fmi.location.default_fmu_dir`)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ["# Limit-cycle examples: the DF, the judge and the truth", "",
             "**DF**: harmonic balance on the exact describing function (Newton, Loeb's criterion). **Judge**: "
             f"plant FMU + LinearSystem.fmu co-simulated at {samples_per_period} steps per predicted period from the "
             "predicted amplitude. **Truth**: the exact closed loop's periodic orbits (shooting to a residual of "
             "1e-10, Floquet multipliers). Errors are relative to the true cycle.", "",
             "| example | G(s) | params | DF w | DF X | DF stable | judge w | judge X | settled | true w | true X "
             "| true stable | max multiplier | DF error w | DF error X | DF error F | judge error w | judge error X |",
             "|---" * 18 + "|"]
    results, studies = {}, []
    for example in examples():
        name, plant, text, params = example.name, example.plant, example.G, example.params
        response = analyse(plant, example.controller(), params, F_range=example.F_range,
                           omega_range=example.omega_range, n_F=example.n_F, n_omega=example.n_omega, exact=True,
                           verify=True, samples_per_period=samples_per_period, fmu_dir=fmu_dir)
        G, predictions, checks = response.G, response.predictions, response.verification
        truths, links = response.cycles, response.links
        for i, (cycle, check) in enumerate(zip(predictions, checks)):
            j = links[i]
            judged = (f"{check['omega']:.5g} | {check['amplitude_x']:.4g} | {check['settled']}" if check["omega"]
                      else "- | - | no")
            if j is None:
                truth = "no true cycle near it (a false alarm) | | | |"
                errors = "| | | |"
            else:
                true = truths[j]
                e, judge = relative_errors(cycle, true), judge_errors(check, true) if check["omega"] else {}
                truth = f"{true.omega:.7g} | {true.amplitude_x:.6g} | {true.stable} | {max(true.multipliers):.3g}"
                errors = (f"{_percent(e['omega'])} | {_percent(e['amplitude_x'])} | {_percent(e['F'])} | "
                          f"{_percent(judge.get('omega'))} | {_percent(judge.get('amplitude_x'))}")
            lines.append(f"| {name} | {text} | {json.dumps(params)} | {cycle.omega:.5g} | {cycle.amplitude_x:.4g} | "
                         f"{cycle.stable} | {judged} | {truth} | {errors} |")
        for true in truths:
            if true.prediction is None:
                lines.append(f"| {name} | {text} | {json.dumps(params)} | not predicted | | | | | | "
                             f"{true.omega:.7g} | {true.amplitude_x:.6g} | {true.stable} | "
                             f"{max(true.multipliers):.3g} | | | | | |")
        if not predictions and not truths:
            lines.append(f"| {name} | {text} | {json.dumps(params)} | no cycle | | | | | | none found | | | | | | | "
                         "| |")
        for true in (t for t in truths if t.stable):
            study = step_study(plant, G, true, params, STEP_STUDY, fmu_dir=fmu_dir)
            studies.append((name, true, study))
        png = response.figure(out_dir / f"example_{name}.png")
        results[name] = response.as_dict()
        report(f"{png}: {len(predictions)} prediction(s), {len(truths)} true cycle(s)")
    lines += ["", "## The judge's step against the truth", "",
              "The co-simulation holds each signal over a step, a first-order error in the step; Richardson's "
              "extrapolation (first order, from the three finest settled steps, where the sequence is monotone "
              "and its observed order near 1) removes it. Stable true cycles, runs from rest at the true "
              "amplitude:", "",
              "| example | steps per period | judge w | judge X | settled | error w | error X | error F |",
              "|---|---|---|---|---|---|---|---|"]
    for name, true, study in studies:
        for run in study.runs:
            e = judge_errors(run, true) if run.settled else {}
            lines.append(f"| {name} | {run.samples} | {run.omega:.6g} | {run.amplitude_x:.5g} | {run.settled} | "
                         f"{_percent(e.get('omega'))} | {_percent(e.get('amplitude_x'))} | {_percent(e.get('F'))} |")
        r = study.richardson
        if r is not None:
            e = judge_errors(r, true)
            orders = ", ".join(f"{q} {p:.2f}" for q, p in r.orders.items() if q != "samples" and p is not None)
            w, x = ("-" if v is None else f"{v:.7g}" for v in (r.omega, r.amplitude_x))
            lines.append(f"| {name} | Richardson (orders {orders}) | {w} | {x} | | "
                         f"{_percent(e['omega'])} | {_percent(e['amplitude_x'])} | {_percent(e['F'])} |")
        else:
            lines.append(f"| {name} | Richardson: {study.reason} | | | | | | |")
        lines.append(f"| {name} | truth | {true.omega:.8g} | {true.amplitude_x:.7g} | | | | |")
        results[name]["step_study"] = study.as_dict()
    lines += ["", "An unstable cycle is not reproduced by a simulation (the judge's runs leave it): only shooting "
              "finds it. A true cycle marked 'not predicted' is one the DF misses.", ""]
    lines += [f"![{example.name}](example_{example.name}.png)" for example in examples()]
    (out_dir / "examples.json").write_text(json.dumps(results, indent=1, default=str))
    path = out_dir / "examples.md"
    path.write_text("\n".join(lines) + "\n")
    return path
