"""A foreign plant written with pythonfmu3 as FMI 3.0 model exchange: M x'' + c x' + k x = u, y = x."""

from pythonfmu3 import Float64, Fmi3Causality, Fmi3Initial, Fmi3SlaveBase, Fmi3Variability, ModelExchange


class PyMassSpringDamperME(Fmi3SlaveBase, ModelExchange):
    """dfwb integrates it: the states x and v, their derivatives from the parameters and the input u."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.time = 0.0
        self.M, self.c, self.k = 1.0, 0.2, 4.0
        self.u, self.x, self.v, self.y = 0.0, 0.0, 0.0, 0.0
        self.der_x, self.der_v = 0.0, 0.0
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous))
        for name in ("M", "c", "k"):
            self.register_variable(Float64(name, causality=Fmi3Causality.parameter,
                                           variability=Fmi3Variability.tunable))
        self.register_variable(Float64("u", causality=Fmi3Causality.input, start=0.0))
        self.register_variable(Float64("y", causality=Fmi3Causality.output, variability=Fmi3Variability.continuous,
                                       getter=lambda: self.x))
        self.register_variable(Float64("x", causality=Fmi3Causality.local, start=0.0,
                                       variability=Fmi3Variability.continuous, initial=Fmi3Initial.exact))
        self.register_variable(Float64("v", causality=Fmi3Causality.local, start=0.0,
                                       variability=Fmi3Variability.continuous, initial=Fmi3Initial.exact))
        self.register_variable(Float64("der_x", causality=Fmi3Causality.local,
                                       variability=Fmi3Variability.continuous, derivative=6))
        self.register_variable(Float64("der_v", causality=Fmi3Causality.local,
                                       variability=Fmi3Variability.continuous, derivative=7))

    def get_continuous_state_derivatives(self):
        self.der_x = self.v
        self.der_v = (self.u - self.c * self.v - self.k * self.x) / self.M
        return [self.der_x, self.der_v]
