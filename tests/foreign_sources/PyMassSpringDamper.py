"""A foreign plant written with pythonfmu3 (FMI 3.0 co-simulation): M x'' + c x' + k x = u, y = x."""

import math

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Slave, Fmi3Variability


class PyMassSpringDamper(Fmi3Slave):
    """Stepped by RK4 with substeps of 1 ms or less: exact to rounding for a held u at the test's frequencies."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.M, self.c, self.k = 1.0, 0.2, 4.0
        self.u, self.y, self.v = 0.0, 0.0, 0.0
        for name in ("M", "c", "k"):
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter,
                                           variability=Fmi3Variability.tunable))
        self.register_variable(Float64("u", causality=Fmi3Causality.input))
        self.register_variable(Float64("y", causality=Fmi3Causality.output))

    def _rate(self, x, v):
        return v, (self.u - self.c * v - self.k * x) / self.M

    def do_step(self, current_time, step_size):
        n = max(1, int(math.ceil(step_size / 1e-3)))
        h = step_size / n
        x, v = self.y, self.v
        for _ in range(n):
            a1 = self._rate(x, v)
            a2 = self._rate(x + h / 2 * a1[0], v + h / 2 * a1[1])
            a3 = self._rate(x + h / 2 * a2[0], v + h / 2 * a2[1])
            a4 = self._rate(x + h * a3[0], v + h * a3[1])
            x += h / 6 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0])
            v += h / 6 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
        self.y, self.v = x, v
        return True
