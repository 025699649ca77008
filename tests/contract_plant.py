"""An extra plant defined outside dfwb: a mass-spring-damper, for the contract suite (tests/test_contract.py).

    M x'' + B x' + K x = u(t),   u = f + F cos(omega t + phi),   output x

Its whole definition is here: its parameters' table, the solver (its own
closed form, not ``dfwb.fmus.exact.Motion``), the FMU facade and the
registry entry (:func:`entry`). docs/plants/adding-a-plant.md walks through it.

The solver: between input changes x is a sum of exponentials, x(s) = Re sum_i
a_i exp(l_i (s - t0)) with l_i the roots of M l^2 + B l + K (the transient),
0 (the static part f / K) and +-j omega (the forced response), all anchored
at the last input change t0. Outputs and the running Fourier integrals are
evaluated from that anchor whatever the communication steps, so they do not
depend on how an importer steps.
"""

import cmath
import math
from typing import NamedTuple

from dfwb.fmus.facade import PlantFMU
from dfwb.fmus.piecewise import check
from dfwb.fmus.table import MASS, START, Output, Parameter, PlantTable

TABLE = PlantTable(
    "mass-spring-damper",
    constants=(
        Parameter("M", 1.0, "kg", "mass (> 0)", (0.0, None), MASS),
        Parameter("B", 0.5, "N.s/m", "viscous damping (> 0)", (0.0, None), (1e-6, 1e9)),
        Parameter("K", 4.0, "N/m", "spring stiffness (> 0, not critical damping)", (0.0, None), (1e-6, 1e9)),
    ),
    initial=START,
    outputs=(
        Output("x", "m", "position"),
        Output("v", "m/s", "velocity"),
    ),
    section=("x", "v"), starts={"x": "x0", "v": "v0"}, position="x0",  # shifts: none (the spring is fixed)
)
DEFAULT = TABLE.default


class Output(NamedTuple):
    """MassSpringDamperSolver.output(): position and velocity."""

    x: float
    v: float


def _integral(mu, tau):
    """int_0^tau exp(mu s) ds, accurate for small |mu tau| (e^z - 1 = 2 sinh(z/2) e^(z/2))."""
    if mu == 0:
        return complex(tau)
    half = 0.5 * mu * tau
    return 2.0 * cmath.sinh(half) * cmath.exp(half) / mu


class MassSpringDamperSolver:
    """Exact solver of M x'' + B x' + K x = u (B > 0, not critically damped); implements dfwb.fmus.Solver."""

    def __init__(self, M=DEFAULT.M, B=DEFAULT.B, K=DEFAULT.K, x0=DEFAULT.x0, v0=DEFAULT.v0, F=0.0, omega=1.0,
                 phi=0.0, f=0.0, harmonics=10):
        check("M", M, lambda: M > 0.0, "M must be > 0 (kg)")
        check("B", B, lambda: B > 0.0, "B must be > 0 (N.s/m)")
        check("K", K, lambda: K > 0.0 and abs(B * B - 4.0 * M * K) > 1e-9 * B * B,
              "K must be > 0 (N/m), and not the critical damping K = B^2 / (4 M)")
        for name, value in (("x0", x0), ("v0", v0), ("F", F), ("phi", phi), ("f", f)):
            check(name, value, True, f"{name} must be a finite number")
        check("omega", omega, lambda: omega > 0.0, "omega must be > 0 (rad/s)")
        check("harmonics", harmonics, lambda: harmonics == int(harmonics) and 0 <= harmonics <= 10,
              "harmonics must be an integer in 0..10")
        self.M, self.B, self.K, self.omega, self.f = M, B, K, omega, f
        root = cmath.sqrt(B * B - 4.0 * M * K)
        self.roots = ((-B + root) / (2.0 * M), (-B - root) / (2.0 * M))
        self.A = F * cmath.exp(1j * phi) / complex(K - M * omega * omega, B * omega)  # forced: Re A e^{j w t}
        self.harmonics = int(harmonics)
        self.t = 0.0
        self.events = 0  # a linear plant has no events
        self._done = [0j] * (self.harmonics + 1)  # the integrals of the pieces before the current one
        self._anchor(0.0, x0, v0)

    def _anchor(self, t0, x0, v0):
        """The current piece: x(s) = Re sum a exp(l (s - t0)) over self._terms = [(a, l)]."""
        forced = self.A * cmath.exp(1j * self.omega * t0)
        (s1, s2), jw = self.roots, 1j * self.omega
        xh, vh = x0 - self.f / self.K - forced.real, v0 - (jw * forced).real  # the transient's start
        c2 = (vh - s1 * xh) / (s2 - s1)
        self._t0 = t0
        self._terms = [(self.f / self.K, 0.0), (xh - c2, s1), (c2, s2), (0.5 * forced, jw),
                       (0.5 * forced.conjugate(), -jw)]

    def _state(self, t):
        tau = t - self._t0
        x = sum(a * cmath.exp(rate * tau) for a, rate in self._terms)
        v = sum(a * rate * cmath.exp(rate * tau) for a, rate in self._terms)
        return x.real, v.real

    def _piece_integrals(self, t):
        tau = t - self._t0
        out = []
        for k in range(self.harmonics + 1):
            shift = cmath.exp(-1j * k * self.omega * self._t0)
            out.append(shift * sum(a * _integral(rate - 1j * k * self.omega, tau) for a, rate in self._terms))
        out[0] = complex(out[0].real)
        return out

    # -- the Solver protocol ---------------------------------------------------------
    def set_input(self, f):
        check("f", f, True, "the input f must be a finite number (N)")
        if f != self.f:
            x, v = self._state(self.t)
            self._done = self.integrals()
            self.f = f
            self._anchor(self.t, x, v)

    def advance(self, t_end):
        check("t_end", t_end, lambda: t_end >= self.t, f"the end of a step must be >= the current time {self.t!r}")
        self.t = t_end  # the closed form needs no stepping

    def integrals(self):
        return [done + piece for done, piece in zip(self._done, self._piece_integrals(self.t))]

    def output(self):
        return Output(*self._state(self.t))


class MassSpringDamper(PlantFMU):
    """Mass on a spring with viscous damping (exact closed form), force input f."""

    solver_class = MassSpringDamperSolver
    table = TABLE


def linear_df(omega, params):
    """The exact DF: the transfer function 1 / (K - M w^2 + j B w) (the plant is linear)."""
    p = dict(TABLE.defaults, **params)
    return 1.0 / complex(p["K"] - p["M"] * omega * omega, p["B"] * omega)


def entry():
    """The registry entry (the registry is imported here, not at module level: the FMU runs without dfwb)."""
    from dfwb.plants.registry import Demo, Plant

    return Plant(
        "mass-spring-damper", MassSpringDamper,
        summary="mass on a spring with viscous damping (linear, exact closed form)",
        linear=({}, linear_df),
        demo=Demo({"F": 10.0, "omega": 1.0}, 4 * math.pi, 64, (("x", "position x [m]"),)),
    )
