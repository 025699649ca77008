"""A worked example with your own FMU: a two-mass drive train with a compliant shaft, backlash and friction.

The plant is written here as an FMI 3.0 model-exchange FMU (pythonfmu3) and
analysed end to end with dfwb:

    J1 x1'' = u - T                               the motor, driven by the torque u
    J2 x2'' = T - Bv x2' - friction               the load
    T = k (d - b sgn d) + c d',  d = x1 - x2      the shaft, once its twist d has taken up the play,
    T = 0 while |d| < b                           and no torque inside the backlash gap of half-width b

(the dead-zone model of backlash, Nordin and Gutman 2002). The load sticks
when its velocity reaches zero and stays stuck while |T| < Fs; sliding, it
feels the Coulomb friction Fc against its motion. Contact and stick are
discrete modes of the FMU, switched only at events: dfwb locates the zeros
of the event indicators (the twist reaching +-b; the load's velocity
reaching zero; |T| reaching Fs while it is stuck) and the FMU updates its
modes there. The FMU can save and restore its state: dfwb needs that to
shoot the closed loop's cycles. J1 = 1 kg m2, J2 = 2 kg m2, k = 100 N m/rad
and c = 10 N m s/rad put the shaft's resonance at 12 rad/s with a damping
ratio of 0.6, so transients die out in a few tens of periods; b = 0.05 rad,
Fc = 1 N m, Fs = 1.5 N m, Bv = 0.5 N m s/rad.

The output is the load position x2: it is what the machine must place, and
a controller that watches the load loses its grip on it while the motor
crosses the gap, which is what makes the loop hunt. The controller is a lead
on the load position, u = -G(s) x2 with G(s) = 400 (s + 4) / (s + 20), tuned
fast: 23 degrees of phase margin and a gain margin of 1.7 on the plant
without backlash and Coulomb friction. (Fed back from the motor position x1
instead, the same controller brings the loop to rest from first torques of
+-1 to +-30 N m.) The script prints the describing function on a small grid
with its error estimate, the limit cycles the DF predicts, the true cycle
of the closed loop (shot by Newton, its Floquet multipliers) and the DF's
errors against it. dfwb labels forces N and positions m: read N m and rad.

Run it as ``python examples/drive_train.py [OUT_DIR]`` (30 s inside the test
suite on two shared cores: each FMI call of a pythonfmu3 FMU runs Python; it
needs pythonfmu3, one of the test extras: ``pip install -e
'.[test]'``). It writes into OUT_DIR (default: the current folder) the FMU,
``DriveTrain.fmu`` (for ``dfwb info``, ``dfwb df``, ``dfwb limit-cycle``), and
``drive_train.png``: the Nyquist plane with the cycles, and the true cycle
over one period. Only the public API is used: ``import dfwb``.
"""

import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import dfwb

# The FMU's source. pythonfmu3 embeds it in the FMU, whose binary runs it in the importer's Python.
MODEL = '''
from pythonfmu3 import Float64, Fmi3Causality, Fmi3Initial, Fmi3SlaveBase, Fmi3Variability, Int32, ModelExchange
from pythonfmu3 import Fmi3UpdateDiscreteStatesResult, Unit

PARAMETERS = {"J1": 1.0, "J2": 2.0, "k": 100.0, "c": 10.0, "b": 0.05, "Fc": 1.0, "Fs": 1.5, "Bv": 0.5}
STATES = ("x1", "v1", "x2", "v2")


class DriveTrain(Fmi3SlaveBase, ModelExchange):
    """Motor J1, a shaft (k, c) through a backlash gap +-b, a load J2 with stiction Fs, Coulomb Fc, viscous Bv."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.description = "Two-mass drive train: a compliant shaft with backlash, a load with stick-slip friction"
        self.time, self.u = 0.0, 0.0
        for name, value in PARAMETERS.items():
            setattr(self, name, value)
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter,
                                           variability=Fmi3Variability.tunable))
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        self.register_variable(Float64("u", causality=Fmi3Causality.input, start=0.0))
        self.register_units([Unit("rad", rad=1)])
        self.x1 = self.v1 = self.x2 = self.v2 = 0.0  # at rest, the shaft in the middle of its play
        for name in STATES:  # the positions are the outputs
            position = name.startswith("x")
            self.register_variable(Float64(name, causality=Fmi3Causality.output if position else Fmi3Causality.local,
                                           start=0.0, initial=Fmi3Initial.exact, unit="rad" if position else None,
                                           variability=Fmi3Variability.continuous))
        for name in STATES:
            setattr(self, "der_" + name, 0.0)
            self.register_variable(Float64("der_" + name, causality=Fmi3Causality.local,
                                           variability=Fmi3Variability.continuous,
                                           derivative=self.reference(name)))
        # the discrete modes, registered so that a saved FMU state holds them:
        # contact -1/0/+1: the shaft engaged at -b / free in the gap / engaged at +b;
        # slip -1/0/+1: the load sliding backwards / stuck / sliding forwards
        self.contact, self.slip = 0, 0
        for name in ("contact", "slip"):
            self.register_variable(Int32(name, causality=Fmi3Causality.local, variability=Fmi3Variability.discrete))
        self.z_upper = self.z_lower = self.z_slip = self.z_break = 0.0
        for name in ("z_upper", "z_lower", "z_slip", "z_break"):
            self.register_variable(Float64(name, causality=Fmi3Causality.local,
                                           variability=Fmi3Variability.continuous), has_event_indicator=True)

    def reference(self, name):
        return next(r for r, v in self.vars.items() if v.name == name)

    # pythonfmu3 finds the states by scanning every variable on each call, the hot path: done directly here
    def get_continuous_states(self):
        return [self.x1, self.v1, self.x2, self.v2]

    def set_continuous_states(self, values):
        self.x1, self.v1, self.x2, self.v2 = values

    def get_number_of_continuous_states(self):
        return 4

    def torque(self):
        """The shaft's torque in the current contact mode: none inside the gap."""
        if self.contact == 0:
            return 0.0
        return self.k * (self.x1 - self.x2 - self.contact * self.b) + self.c * (self.v1 - self.v2)

    def get_continuous_state_derivatives(self):
        T = self.torque()
        self.der_x1, self.der_v1 = self.v1, (self.u - T) / self.J1
        if self.slip == 0:
            self.der_x2 = self.der_v2 = 0.0
        else:
            self.der_x2, self.der_v2 = self.v2, (T - self.slip * self.Fc - self.Bv * self.v2) / self.J2
        return [self.der_x1, self.der_v1, self.der_x2, self.der_v2]

    def get_event_indicators(self):
        d, T = self.x1 - self.x2, self.torque()
        self.z_upper, self.z_lower = d - self.b, d + self.b
        if self.slip == 0:  # stuck: breaks away when |T| reaches Fs
            self.z_slip, self.z_break = self.Fs - T, self.Fs + T
        else:  # sliding: stops when its velocity reaches 0. Just broken away (v2 = 0 exactly) the sign of
            # its acceleration stands in, so that the start of the slide is not taken for its end.
            self.z_slip = self.slip * (self.v2 if self.v2 != 0.0 else T - self.slip * self.Fc)
            self.z_break = 1.0
        return [self.z_upper, self.z_lower, self.z_slip, self.z_break]

    def update_discrete_states(self):
        # Each mode follows its indicator's domain as FMI defines it, z > 0 or z <= 0: the importer may put
        # the FMU exactly on z = 0, and a mode that took that for "not yet" would miss the crossing for good.
        d = self.x1 - self.x2
        self.contact = 1 if d - self.b > 0.0 else -1 if d + self.b <= 0.0 else 0
        stopped = self.slip != 0 and self.slip * self.v2 <= 0.0
        if stopped:
            self.slip, self.v2 = 0, 0.0
        if self.slip == 0:  # stuck (or just stopped): stays so while |T| < Fs
            T = self.torque()
            self.slip = 1 if self.Fs - T <= 0.0 else -1 if self.Fs + T <= 0.0 else 0
        return Fmi3UpdateDiscreteStatesResult(valuesOfContinuousStatesChanged=stopped)

    def exit_initialization_mode(self):
        self.update_discrete_states()
'''

G = "400*(s + 4)/(s + 20)"  # a lead on the load position [N m/rad]: torque u = -G(s) x2
# The map only locates: each cell where both parts of 1 + G N change sign is then refined by Newton on the
# precise DF, some 10 to 30 points of the FMU at 0.3 to 1 s each, so a small map is the quick one here.
RANGES = {"F_range": (1.0, 40.0), "omega_range": (2.0, 20.0), "n_F": 3, "n_omega": 4}


def build(out_dir):
    """Write the model's source to a temporary folder and build ``DriveTrain.fmu`` from it into ``out_dir``."""
    try:
        from pythonfmu3 import FmuBuilder
    except ImportError:
        sys.exit("this example builds its FMU with pythonfmu3: pip install pythonfmu3==0.3.4")
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "DriveTrain.py"
        source.write_text(MODEL)
        # canGetAndSetFMUState: dfwb saves the FMU's state on the cycle's section to shoot the cycle from there
        return FmuBuilder.build_FMU(source, dest=out_dir, canGetAndSetFMUState=True)


def main(out_dir="."):
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    plant = dfwb.fmu_plant(build(out_dir), input="u", output="x2")
    print(plant.summary)

    # The describing function on a small grid, 3 torques (a column) x 3 frequencies (a row), each point with
    # its estimated error. dfwb's tables say N and m: read N m and rad for this rotational plant.
    table = dfwb.describing_function(plant, [[2.0], [5.0], [20.0]], [3.0, 5.0, 9.0])
    print(" F [N m] | omega [rad/s] | N [rad/(N m)]             | N_error  | periodic")
    for record, error in zip(table.points, table.N_error.flat):
        print(f"{record['F']:8g} | {record['omega']:13g} | {record['N_re']:+.5e} {record['N_im']:+.5e}j | "
              f"{error:.1e}  | {record['periodic']}")
    for record in table.points:
        if record["N_re"] == record["N_im"] == 0.0:
            print(f"(N = 0 at {record['F']:g} N m, {record['omega']:g} rad/s: the motor's swing stays inside the gap, "
                  "the load never moves)")

    # The limit cycles under G: the DF's predictions, then the truth, the closed loop integrated and shot.
    truth = dfwb.limit_cycles(plant, G, exact=True, **RANGES)
    for i, cycle in enumerate(truth.predictions):
        print(f"DF prediction {i}: F = {cycle.F:.6g} N m, omega = {cycle.omega:.6g} rad/s (period {cycle.period:.4g} "
              f"s), load amplitude {cycle.amplitude_x:.4g} rad, {'stable' if cycle.stable else 'unstable'} (Loeb), "
              f"distortion {cycle.distortion:.3g}")
    for j, cycle in enumerate(truth.cycles):
        print(f"true cycle {j}: F = {cycle.F:.8g} N m, omega = {cycle.omega:.8g} rad/s (period {cycle.period:.6g} s), "
              f"load amplitude {cycle.amplitude_x:.6g} rad, {'stable' if cycle.stable else 'unstable'} "
              f"(Floquet |multipliers| {', '.join(f'{m:.3g}' for m in cycle.multipliers)}), "
              f"|X_3|/|X_1| = {cycle.harmonics[3] / cycle.harmonics[1]:.2%}, Newton residual {cycle.residual:.1e}, "
              f"reached from {len(cycle.started_from)} starts")
    for i, j in enumerate(truth.links):
        if j is None:  # the runs settle on stable cycles; Newton from an unstable prediction may find its cycle
            print(f"prediction {i}: no true cycle near it: neither the runs nor Newton from its harmonic balance "
                  f"found one (the starts ended: {truth.coverage.outcomes})")
            continue
        predicted, true = truth.predictions[i], truth.cycles[j]
        print(f"prediction {i} against true cycle {j}: DF error in omega {predicted.omega / true.omega - 1:+.2%}, "
              f"in load amplitude {predicted.amplitude_x / true.amplitude_x - 1:+.2%}, "
              f"in F {predicted.F / true.F - 1:+.2%}")

    # The figure: the Nyquist plane near the cycles, and the true cycle over one period.
    # A picture needs no 1e-10 (a point 4 times quicker), nor 150 periods before a response that never repeats
    # (the motor grazing the load) is averaged.
    curves = dfwb.describing_function(plant, [[2.0], [5.0], [10.0], [20.0]], np.geomspace(3.0, 12.0, 8),
                                      rtol=1e-6, max_periods=40)
    figure, (left, right) = plt.subplots(1, 2, figsize=(12, 5))
    inverse = np.where(curves.periodic, curves.minus_inverse, np.nan)  # a response that never repeats: no N
    for F, row in zip(curves.F[:, 0], inverse):
        left.plot(row.real, row.imag, lw=1, label=f"-1/N, F = {F:g} N m")
    truth.plot(ax=left, curves=0)  # G(jw), the predictions (circles, filled: stable), the true cycle (star)
    left.set_xlim(0.0, 260.0)
    left.set_ylim(-60.0, 260.0)
    left.set_xlabel("Re [N m/rad]")
    left.set_ylabel("Im [N m/rad]")
    left.legend(fontsize=7, loc="upper left")
    twin = right.twinx()
    for j, cycle in enumerate(truth.cycles):  # the truth over one period, against the DF's sine
        t, y, f = (np.asarray(cycle.trace[key]) for key in ("t", "y", "f"))
        line, = right.plot(t / cycle.period, y - 0.5 * (y.max() + y.min()), lw=1.5,
                           label=f"true cycle {j}: load position x2 [rad]")
        twin.plot(t / cycle.period, f, "--", lw=1, color=line.get_color(), label=f"true cycle {j}: torque u [N m]")
        if cycle.prediction is not None:
            predicted = truth.predictions[cycle.prediction]
            for sign in (1.0, -1.0):
                right.axhline(sign * predicted.amplitude_x, ls=":", color="k",
                              label=f"the DF's amplitude, {predicted.amplitude_x:.4g} rad" if sign > 0 else None)
    right.set_xlabel("t / period")
    right.set_ylabel("load position about its middle [rad]")
    twin.set_ylabel("torque [N m]")
    right.set_title("the true cycle over one period (dotted: the DF's amplitude)", fontsize=9)
    right.grid(alpha=0.3)
    lines = right.get_legend_handles_labels()
    twin_lines = twin.get_legend_handles_labels()
    right.legend(lines[0] + twin_lines[0], lines[1] + twin_lines[1], fontsize=7, loc="upper center",
                 bbox_to_anchor=(0.5, -0.12), ncol=2)
    figure.tight_layout()
    figure.savefig(out_dir / "drive_train.png", dpi=100)
    plt.close(figure)
    return truth


if __name__ == "__main__":
    main(*sys.argv[1:2])
