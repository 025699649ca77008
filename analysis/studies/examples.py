"""The shipped limit-cycle examples: predicted, judged by co-simulation, plotted.

1. PID position control of the friction mass: integral action and static
   friction make the mass hunt (a stable cycle, and an unstable one above it).
2. A lead compensator around the static backlash: the amplitude-only case,
   cross-checked against python-control in the tests.
3. The same kind of lead around the two-mass backlash with impacts, for
   eps = 0.2 and eps = 0.8.

Each example is a scene, ``scenes/lc_<name>.toml`` (``dfwb run`` runs one with
the cache); ``dfwb examples [--out DIR]`` runs them all and adds a convergence
study of the judge, writing ``example_<name>.png`` and ``examples.md``.
"""

import json
from pathlib import Path

from dfwb.engine.closed_loop import measure, run_loop, verify
from dfwb.engine.describing import DFEngine
from dfwb.engine.limit_cycles import search
from dfwb.plants import plant as find_plant
from dfwb.plotting.plots import limit_cycle_figure
from dfwb.studies.scene import load_scene, shipped_scenes

CONVERGENCE = (128, 256, 512, 1024, 2048)  # steps per predicted period


def examples():
    """The [[limit_cycle]] of every shipped scene ``lc_*.toml``, by name."""
    return [cycle for path in shipped_scenes("lc_") for cycle in load_scene(path).limit_cycle]


def run_examples(out_dir="out/examples", samples_per_period=512, report=print):
    """Predict, verify and plot every example; return the path of examples.md."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ["# Limit-cycle examples", "",
             "Predicted by harmonic balance on the exact DF (Newton, Loeb's criterion for stability), judged by "
             f"co-simulating plant FMU + LinearSystem.fmu at {samples_per_period} steps per predicted period, from "
             "the predicted amplitude and from 1.5 times it.", "",
             "| example | G(s) | params | F [N] | w [rad/s] | amplitude | stable | distortion | judge F | judge w "
             "| error F | error w | settled (near, perturbed) |", "|---" * 13 + "|"]
    results = {}
    for example in examples():
        name, plant, text, params = example.name, example.plant, example.G, example.params
        F_range, omega_range = example.F_range, example.omega_range
        G = example.transfer_function()
        found = search(plant, G, params, F_range, omega_range, engine=DFEngine(plant))
        cycles = found.cycles
        runs, checks = [], []
        for cycle in cycles:
            outcome, run = verify(plant, G, cycle, params, samples_per_period)
            runs.append((cycle, run))
            checks.append(outcome)
            lines.append(f"| {name} | {text} | {json.dumps(params)} | {cycle.F:.6g} | {cycle.omega:.6g} | "
                         f"{cycle.amplitude_x:.4g} | {cycle.stable} | {cycle.distortion:.3g} | {outcome['F']:.4g} | "
                         f"{outcome['omega']:.4g} | {outcome['rel_error_F']:.1%} | {outcome['rel_error_omega']:.1%} | "
                         f"{outcome['settled']}, {outcome['perturbed']['settled']} |")
        if not cycles:
            lines.append(f"| {name} | {text} | {json.dumps(params)} | no cycle | | | | | | | | | |")
        png = limit_cycle_figure(out_dir / f"example_{name}.png", G, found.F_grid, found.omega_grid, found.N_grid,
                                 cycles, runs)
        results[name] = {"predictions": [c.as_dict() for c in cycles], "verification": checks, "cycles": cycles}
        report(f"{png}: {len(cycles)} cycle(s)")
    lines += ["", "## Convergence of the judge as the communication step shrinks", "",
              "The co-simulation holds each signal over a step (a delay of half a step on average); its error "
              "vanishes with the step. Stable cycles, near start, measured F and w:", "",
              "| example | steps per period | F [N] | w [rad/s] | settled |", "|---|---|---|---|---|"]
    for example in examples():
        name, plant, params = example.name, example.plant, example.params
        for cycle in (c for c in results[name]["cycles"] if c.stable):
            for samples in CONVERGENCE:
                run = run_loop(plant, example.transfer_function(), params, cycle.period / samples,
                               40 * cycle.period, {find_plant(plant).loop_start: cycle.amplitude_x})
                found = measure(run, rtol=5e-3)
                lines.append(f"| {name} | {samples} | {found.F:.5g} | {found.omega:.5g} | {found.settled} |")
            lines.append(f"| {name} | prediction | {cycle.F:.5g} | {cycle.omega:.5g} | |")
    lines += ["", "An unstable cycle is not expected to be reproduced: the judge's runs leave it (to the stable "
              "cycle or to rest). Where no cycle is listed, none was found in the ranges; for eps = 0.8 the "
              "only sign change of 1 + G N lies where the plant's response is not periodic.", ""]
    lines += [f"![{example.name}](example_{example.name}.png)" for example in examples()]
    for entry in results.values():
        entry.pop("cycles")
    (out_dir / "examples.json").write_text(json.dumps(results, indent=1))
    path = out_dir / "examples.md"
    path.write_text("\n".join(lines) + "\n")
    return path
