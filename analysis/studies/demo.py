"""The main job of ``make demo``: each plant FMU driven by fmpy with a sine, plotted.

Every plant is run twice through fmpy: with its built-in excitation
F cos(omega t) (integrated exactly inside the FMU) and with the same sine fed
into the input ``f`` (held over each communication step, as any FMI master
would drive it). The figure shows both, so the cost of the sampled input is
visible at a glance.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from dfwb.fmi.simulation import simulate, sine_input
from dfwb.plants import PLANTS


def run_case(fmu_path, start_values, stop_time, samples_per_period, outputs):
    """(exact, sampled) fmpy results of one plant."""
    F, omega = start_values["F"], start_values["omega"]
    step = 2 * np.pi / omega / samples_per_period
    names = [name for name, _ in outputs]
    exact = simulate(fmu_path, stop_time, step / 8, start_values, names)
    sampled_values = dict(start_values, F=0.0)
    table = sine_input(F, omega, stop_time, samples_per_period)
    sampled = simulate(fmu_path, stop_time, step, sampled_values, names, input=table)
    return exact, sampled


def plot_case(model, exact, sampled, start_values, samples_per_period, outputs, path, units=None):
    """The two runs of one plant, one panel per output; ``units`` ({name: unit}) puts units in the title."""
    figure, axes = plt.subplots(len(outputs), 1, sharex=True, figsize=(8, 2.2 * len(outputs) + 0.8))
    for ax, (name, label) in zip(np.atleast_1d(axes), outputs):
        ax.plot(exact["time"], exact[name], lw=1.6, label="built-in excitation (exact)")
        ax.plot(sampled["time"], sampled[name], lw=1.0, ls="--",
                label=f"input f from fmpy, {samples_per_period} samples/period")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    units = units or {}
    settings = ", ".join(f"{k} = {v:g}" + (f" {units[k]}" if units.get(k) else "") for k, v in start_values.items())
    figure.suptitle(f"{model}: force F cos(omega t), {settings}")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def run_demo(fmus, out_dir="out", report=print):
    """Simulate and plot every plant; return the written figure paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for plant in PLANTS.values():
        if plant.demo is None:
            continue
        model = plant.fmu_name
        start_values, stop_time, samples, outputs = dict(plant.demo.start), plant.demo.stop_time, \
            plant.demo.samples_per_period, plant.demo.outputs
        exact, sampled = run_case(fmus[model], start_values, stop_time, samples, outputs)
        path = out_dir / f"demo_{model}.png"
        units = plant.model.units()
        plot_case(model, exact, sampled, start_values, samples, outputs, path, units)
        first = outputs[0][0]
        gap = np.max(np.abs(np.interp(sampled["time"], exact["time"], exact[first]) - sampled[first]))
        unit = f" {units[first]}" if units.get(first) else ""
        report(f"{path}: {model}, max |{first} exact - {first} sampled input| = {gap:.3g}{unit}")
        written.append(path)
    return written
