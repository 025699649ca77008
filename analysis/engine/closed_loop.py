"""The judge: a plant FMU in a loop with the controller FMU, co-simulated by fmpy.

The loop is force = -G(s) position: the controller is ``LinearSystem.fmu``
loaded with -G, its input the plant output, its output the plant input
``f``. The master is the fixed-step Jacobi scheme that libcosim uses too: at
every communication point read all outputs, then set all inputs, then step
every FMU; both FMUs are exact for inputs held over a step, so the only
co-simulation error is the hold (a delay of about a step), and it vanishes
as the step shrinks (:func:`convergence`). The measured cycle is the first
harmonic of the plant input force and of the plant output over whole
periods of the settled oscillation.
"""

import math
from dataclasses import dataclass

import numpy as np

from dfwb.base.errors import InputError
from dfwb.fmi.location import fmu_path
from dfwb.fmi.session import FMUSession
from dfwb.plants import plant as find_plant

CONTROLLER = "LinearSystem"
MAX_ORDER = 8


def controller_values(G, sign=-1.0):
    """LinearSystem.fmu parameters (order, b0.., a1..) of ``sign * G`` (den normalised)."""
    num = np.trim_zeros(np.atleast_1d(np.asarray(G.num[0][0], dtype=float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(G.den[0][0], dtype=float)), "f")
    order = len(den) - 1
    if not 1 <= order <= MAX_ORDER:
        raise InputError(f"G(s) of order {order}: the controller FMU takes orders 1..{MAX_ORDER}")
    num = np.concatenate([np.zeros(order + 1 - len(num)), num]) * sign / den[0]
    den = den / den[0]
    values = {"order": order}
    values.update({f"b{i}": float(num[i]) for i in range(order + 1)})
    values.update({f"a{i}": float(den[i]) for i in range(1, order + 1)})
    return values


@dataclass
class LoopRun:
    """Samples of one closed-loop run at every communication point."""

    time: np.ndarray
    position: np.ndarray  # plant output
    force: np.ndarray  # plant input f, held over [t_k, t_k + step]
    step: float


@dataclass
class Oscillation:
    """What the judge measured."""

    settled: bool
    omega: float
    F: float  # first-harmonic amplitude of the force
    amplitude_x: float  # first-harmonic amplitude of the plant output
    periods: int  # whole periods measured at the end


def run_loop(plant, G, params=None, step=1e-3, stop_time=10.0, initial=None, fmu_dir=None,
             sessions=None):
    """Co-simulate plant + controller from ``initial`` plant parameters (e.g. x0, v0)."""
    spec = find_plant(plant)
    values = spec.check(dict(params or {}, **(initial or {})))
    plant_session, controller_session = sessions or (
        FMUSession(fmu_path(spec, fmu_dir)), FMUSession(fmu_path(CONTROLLER, fmu_dir)))
    plant_session.start(dict(values, F=0.0))
    controller_session.start(controller_values(G))
    n = int(round(stop_time / step))
    time = np.arange(n + 1) * step
    position, force = np.empty(n + 1), np.empty(n + 1)
    output = spec.output
    for k in range(n + 1):
        position[k] = plant_session.reals([output])[0]  # read every output first,
        force[k] = controller_session.reals(["y"])[0]
        if k == n:
            break
        plant_session.step(step, {"f": force[k]})  # then set the inputs and step both
        controller_session.step(step, {"u": position[k]})
    return LoopRun(time, position, force, step)


def measure(run, periods=10, rtol=1e-3):
    """The settled oscillation at the end of a run: frequency and first harmonics.

    The period comes from the upward crossings of the force through its mean
    in the second half of the run; the first harmonics are taken over exactly
    ``periods`` of those periods: the held force integrated exactly, the
    position by the trapezoidal rule. ``settled`` when the last cycles agree
    to ``rtol`` in period and swing.
    """
    t, f, x, h = run.time, run.force, run.position, run.step
    half = len(t) // 2
    mean = f[half:].mean()
    above = f - mean > 0
    ups = np.flatnonzero(~above[:-1] & above[1:])
    ups = ups[ups >= half]
    if len(ups) < periods + 2 or np.ptp(f[half:]) <= 1e-12 * (1.0 + np.abs(f[half:]).max()):
        return Oscillation(False, 0.0, 0.0, 0.0, 0)
    crossings = t[ups] + (mean - f[ups]) / (f[ups + 1] - f[ups]) * h
    cycles = np.diff(crossings)[-periods:]
    swings = [np.ptp(f[a:b + 1]) for a, b in zip(ups[-periods - 1:-1], ups[-periods:])]
    settled = bool(np.ptp(cycles) <= rtol * cycles.mean() and np.ptp(swings) <= rtol * np.mean(swings))
    omega = 2 * math.pi / cycles.mean()
    t0, t1 = crossings[-periods - 1], crossings[-1]
    return Oscillation(settled, omega, abs(_held_harmonic(t, f, h, t0, t1, omega)),
                       abs(_sampled_harmonic(t, x, t0, t1, omega)), periods)


def _held_harmonic(t, f, h, t0, t1, omega):
    """(2 / (t1 - t0)) int_t0^t1 f exp(-j w t) dt for f held over each step: exact."""
    k = np.arange(int(t0 // h), int(math.ceil(t1 / h)))
    a, b = np.clip(t[k], t0, t1), np.clip(t[k] + h, t0, t1)
    integral = np.sum(f[k] * (np.exp(-1j * omega * b) - np.exp(-1j * omega * a)) / (-1j * omega))
    return 2.0 / (t1 - t0) * integral


def _sampled_harmonic(t, x, t0, t1, omega):
    """The same for a sampled signal, trapezoidal between samples (linear at the window's ends)."""
    inside = (t > t0) & (t < t1)
    grid = np.concatenate([[t0], t[inside], [t1]])
    values = np.interp(grid, t, x)
    return 2.0 / (t1 - t0) * np.trapezoid(values * np.exp(-1j * omega * grid), grid)


def verify(plant, G, cycle, params=None, samples_per_period=512, periods=60, perturbation=0.5,
           fmu_dir=None):
    """Co-simulate from near a predicted cycle and from a perturbed start; compare.

    The plant starts at rest at the predicted output amplitude (and at
    ``1 + perturbation`` times it); after ``periods`` predicted periods the
    settled oscillation is measured (:func:`measure`).

    Returns
    -------
    (dict, LoopRun): ``F``, ``omega``, ``amplitude_x``, ``settled``,
    ``rel_error_F``, ``rel_error_omega`` of the near start, ``step``, and
    ``perturbed`` (the same for the perturbed start); the near start's run.
    """
    step = cycle.period / samples_per_period
    spec = find_plant(plant)
    sessions = (FMUSession(fmu_path(spec, fmu_dir)), FMUSession(fmu_path(CONTROLLER, fmu_dir)))
    runs, trajectories = [], []
    for scale in (1.0, 1.0 + perturbation):
        run = run_loop(plant, G, params, step, periods * cycle.period,
                       {spec.loop_start: scale * cycle.amplitude_x}, fmu_dir, sessions)
        trajectories.append(run)
        found = measure(run, rtol=5e-3)
        runs.append({
            "F": found.F, "omega": found.omega, "amplitude_x": found.amplitude_x, "settled": found.settled,
            "rel_error_F": abs(found.F - cycle.F) / cycle.F,
            "rel_error_omega": abs(found.omega - cycle.omega) / cycle.omega,
            "start": {spec.loop_start: scale * cycle.amplitude_x}, "step": step})
    near, perturbed = runs
    near["perturbed"] = perturbed
    return near, trajectories[0]
