"""A worked study: what stops the hunting of a friction mass under PI control, and what it costs.

The friction mass (M = 1 kg, B = 0.5 N s/m, Coulomb 5 N, static 7 N) under
G(s) = 10 + 2/s hunts: the integrator winds up while the mass sticks, breaks
it away, and the mass overshoots and sticks on the other side (a stable cycle
of 57 s that the describing function cannot see; Olsson and Astrom, 2001).
The script judges the classic remedies on the exact loop, each with its cost
(the step response's standing error, settling time, overshoot and force):

1. each compensator at one setting: Coulomb feedforward of the velocity's
   sign and of the controller's (F_hat = 3 N), the integrator reset at rest,
   an integrator deadband of 0.2 m, and two dithers: 1 N at 5 rad/s (it
   still hunts, not locked to the dither) and 10 N at 5 rad/s (no hunting,
   but the mass shakes: its residual oscillation);
2. the deadband followed in d: where the hunting ends (a fold of the cycle);
3. two compensation maps: the deadband (Kp x d) and the feedforward of the
   controller's sign (Kp x F_hat), the truth beside the standing error;
4. the tuned controller: the fastest Kp + Ki/s with a deadband that does not
   hunt with Fc and Fs off by up to 20 % and 10 %, and stops within 0.1 m;
5. and beside it the other nonlinearity, the play: the static backlash under
   20 (s + 2)/(s + 20) with a backlash inverse of h_hat = 0, h/2, h and 2h
   (it shrinks the hunting, never stops it).

Run it as ``python examples/compensation_study.py [OUT_DIR]`` (about half a
minute: the two dithers' dual-input DFs take most of it). It writes
``compensation_study.png`` into OUT_DIR (default: the current folder).
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import dfwb  # noqa: E402

PI = {"Kp": 10, "Ki": 2}
SIDE = 4  # cells per side of the maps (a quick look; 30 for the figure of a report)


def one_line(response):
    hunting = [c for c in response.cycles if c.stable]
    verdict = (f"hunts: period {hunting[0].period:.4g} s, amplitude {hunting[0].amplitude_x:.4g} m" if hunting
               else "hunts, not locked to the dither" if response.hunting
               else "no cycle in the range searched")
    return f"{verdict}; {response.cost.summary()}"


def main(out_dir="."):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    print("1. One setting each, under G = 10 + 2/s")
    settings = [("none", None, {}), ("coulomb (velocity)", "coulomb", {"F_hat": 3}),
                ("coulomb (control)", "coulomb", {"F_hat": 3, "signal": "control"}), ("reset", "reset", {}),
                ("deadband", "deadband", {"d": 0.2}), ("dither 1 N, 5 rad/s", "dither", {"a": 1, "w_d": 5}),
                ("dither 10 N, 5 rad/s", "dither", {"a": 10, "w_d": 5})]
    for label, name, values in settings:
        response = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, compensate=name, **PI, **values)
        print(f"  {label:20s} {one_line(response)}")

    print("2. The deadband followed in d")
    branch = dfwb.continuation("friction", "Kp + Ki/s", "d", 0.01, 0.3, compensate="deadband", sources="truth", **PI)
    for b in branch.bifurcations:
        print(f"  {b.kind} at d = {b.parameter:.6g} m")

    print("3. Two compensation maps")
    deadband = dfwb.hunting_map("friction", "Kp + 2/s", ("Kp", 5, 20, SIDE), ("d", 0.01, 0.3, SIDE),
                                compensate="deadband", curves=False)
    feedforward = dfwb.hunting_map("friction", "Kp + 2/s", ("Kp", 5, 20, SIDE), ("F_hat", 0, 6, SIDE),
                                   compensate="coulomb", signal="control", curves=False)
    for response in (deadband, feedforward):
        print("  " + response.summary().replace("\n", "\n  "))

    print("4. The tuned controller")
    tuned = dfwb.tune("friction", "Kp + Ki/s", compensate="deadband",
                      free={"Kp": (2, 50), "Ki": (0.2, 10), "d": (0.01, 0.5)}, tolerance=0.1,
                      robust={"Fc": 0.2, "Fs": 0.1})
    print("  " + tuned.summary().replace("\n", "\n  "))

    print("5. The static backlash's play (h = 0.1 m) under 20 (s + 2)/(s + 20), with a backlash inverse")
    for h_hat in (0.0, 0.05, 0.1, 0.2):
        response = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", exact=True, compensate="backlash-inverse",
                                     h_hat=h_hat)
        print(f"  h_hat = {h_hat:<5g} {one_line(response)}")

    figure, axes = plt.subplots(3, 2, figsize=(13, 16), layout="constrained")
    deadband.plot(axes[0])
    feedforward.plot(axes[1])
    branch.plot(axes[2][0])
    tuned.plot(axes[2][1])
    figure.suptitle("The friction mass under PI: what stops the hunting, and at what cost", fontsize=13)
    path = out / "compensation_study.png"
    figure.savefig(path, dpi=90)
    print(f"written {path}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
