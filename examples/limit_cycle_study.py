"""A limit-cycle study: a mass with backlash (the static dead-zone model) under a lead compensator.

The controller G(s) = K (s + 2) / (s + 20) feeds the position back as a force,
force = -G(s) x. Harmonic balance G(jw) N(F, w) = -1 on the plant's exact
describing function predicts a limit cycle for each gain K; the study prints
how its amplitude and frequency move with K and draws the Nyquist plane of
the nominal loop. The controller is given three ways (an expression, num/den
and a python-control transfer function) to show they are the same. Last, the
truth: the exact closed loop's periodic orbit (``exact=True``), with the DF's
errors against it.

Run it as ``python examples/limit_cycle_study.py [OUT_DIR]``; it writes
``limit_cycle_nyquist.png`` into OUT_DIR (default: the current folder).
Only the public API is used: ``import dfwb``.
"""

import sys
from pathlib import Path

import control as ct
import matplotlib.pyplot as plt

import dfwb

RANGES = {"F_range": (0.01, 100.0), "omega_range": (0.1, 50.0), "n_F": 10, "n_omega": 24}


def main(out_dir="."):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    # The nominal loop, K = 20, with the controller given three ways.
    nominal = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", **RANGES)
    for G in (([20.0, 40.0], [1.0, 20.0]), ct.tf([20.0, 40.0], [1.0, 20.0])):
        assert dfwb.limit_cycles("static-backlash", G, **RANGES).predictions == nominal.predictions
    for cycle in nominal.predictions:
        print(f"K = 20: F = {cycle.F:.6g} N, omega = {cycle.omega:.6g} rad/s, amplitude {cycle.amplitude_x:.4g} m, "
              f"{'stable' if cycle.stable else 'unstable'}, distortion {cycle.distortion:.3g}")

    # How the cycle moves with the gain.
    print("   K | F [N]    | omega [rad/s] | amplitude [m] | stable")
    for K in (10.0, 20.0, 40.0):
        response = dfwb.limit_cycles("static-backlash", ([K, 2.0 * K], [1.0, 20.0]), **RANGES)
        for cycle in response.predictions:
            print(f"{K:4g} | {cycle.F:8.4g} | {cycle.omega:13.4g} | {cycle.amplitude_x:13.4g} | {cycle.stable}")
        if not response.predictions:
            print(f"{K:4g} | no limit cycle in the ranges")

    # The truth behind the prediction: the exact closed loop's periodic orbits, and the DF's errors.
    truth = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", exact=True, **RANGES)
    for i, j in enumerate(truth.links):
        if j is None:
            print(f"prediction {i}: no true cycle near it (a false alarm)")
            continue
        true, predicted = truth.cycles[j], truth.predictions[i]
        print(f"prediction {i}: true cycle omega = {true.omega:.8g} rad/s, amplitude {true.amplitude_x:.6g} m, "
              f"{'stable' if true.stable else 'unstable'} (Floquet |multipliers| "
              f"{', '.join(f'{m:.3g}' for m in true.multipliers)}); DF error in omega "
              f"{predicted.omega / true.omega - 1:+.2%}, "
              f"in amplitude {predicted.amplitude_x / true.amplitude_x - 1:+.2%}")

    figure, ax = plt.subplots(figsize=(6.5, 5))
    truth.plot(ax=ax)  # the predictions (circles) and the true cycles (stars)
    figure.savefig(out_dir / "limit_cycle_nyquist.png", dpi=100)
    plt.close(figure)
    return nominal


if __name__ == "__main__":
    main(*sys.argv[1:2])
