"""FMI 2.0 co-simulation facades (pythonfmu) over the exact plant solvers.

Each facade declares its variables once (name, unit, description), hands
the parameters to its solver at the end of initialisation and advances the
solver in ``do_step``. Bad parameters, inputs or steps are reported through
the FMI logger with status error, and the call fails: an importer sees an
error status, never NaN outputs.

A solver is anything that implements :class:`~.contract.Solver`; a facade
names it in ``solver_class``. The FMU of a facade bundles only the modules
its own module imports (the builder follows the relative imports), so the
benchmark's fixed-step twins live in :mod:`.naive`, outside the closure of
the production FMUs, and a plant defined outside dfwb subclasses
:class:`PlantFMU` in its own module.
"""

import math

from pythonfmu import DefaultExperiment, Fmi2Slave, Integer, Real
from pythonfmu.enums import Fmi2Causality, Fmi2Status, Fmi2Variability

from .backlash import TwoMassBacklash as _TwoMassBacklash
from .friction import FrictionMass as _FrictionMass
from .linear_system import MAX_ORDER as _MAX_ORDER
from .linear_system import LinearSystem as _LinearSystem
from .piecewise import PlantError, check
from .static_backlash import StaticBacklash as _StaticBacklash

MAX_HARMONIC = 10
EXCITATION = (
    ("F", 0.0, "N", "amplitude of the built-in excitation F cos(omega t + phi)"),
    ("omega", 1.0, "rad/s", "angular frequency of the built-in excitation (> 0)"),
    ("phi", 0.0, "rad", "phase of the built-in excitation"),
)


_PINNED = []
FACADES = []
"""Every loaded facade class: :class:`PlantFMU` subclasses add themselves (the naive twins when
:mod:`.naive` is imported, a plant defined elsewhere when its module is); LinearSystem is added below."""


def pin(namespace):
    """Hold one more reference to an FMU script's globals.

    pythonfmu 0.7.0's C++ loader re-executes the script at each
    fmi2Instantiate with the module's dict as globals and then releases that
    borrowed dict once too often; without this extra reference the second
    instance in a process finds a freed module. The generated script calls
    ``pin(globals())`` on every execution, which balances the release.
    """
    _PINNED.append(namespace)


class StepRefused(RuntimeError):
    """Raised inside the FMU so that the importer gets an error status."""


class SolverFMU(Fmi2Slave):
    """What every dfwb FMU shares: metadata, errors through the FMI logger, a checked doStep.

    A subclass creates ``self.solver`` at the end of initialisation; doStep
    hands it the input named ``input_name``, held over the step.
    """

    input_name = "f"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.author = "dfwb"
        self.description = self.__class__.__doc__.strip().splitlines()[0]
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)
        self.solver = None

    def _fail(self, message):
        self.log(f"{self.__class__.__name__}: {message}", status=Fmi2Status.error)
        raise StepRefused(message)

    def do_step(self, current_time, step_size):
        solver = self.solver
        if solver is None:
            self._fail("doStep called before initialisation")
        if not (math.isfinite(step_size) and step_size > 0.0):
            self._fail(f"communication step {step_size!r} at t = {current_time!r}: it must be > 0 and finite")
        if not (abs(current_time - solver.t) <= 1e-9 * max(1.0, abs(solver.t))):  # NaN refused too
            self._fail(f"doStep at t = {current_time!r}, but the FMU is at t = {solver.t!r}")
        try:
            solver.set_input(getattr(self, self.input_name))
            solver.advance(max(current_time + step_size, solver.t))
        except PlantError as error:
            self._fail(f"step from t = {current_time!r} refused: {error}")
        self._refresh()
        return True

    def _refresh(self):
        """Update cached outputs after a step (nothing to cache by default)."""


class PlantFMU(SolverFMU):
    """Common facade: parameters, the input f, outputs and Fourier integrals."""

    solver_class = None
    parameters = ()  # (name, default, unit, description)
    outputs = ()  # (name, unit, description, is_integer)
    output_signal = ("x", "m")  # the signal whose Fourier integrals are exposed

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.solver_class is not None:
            FACADES.append(cls)
        cls._layout = cls.layout()
        cls._settable = frozenset(name for name, _kind, causality, *_ in cls._layout if causality != "output")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._values = {}
        self._fourier = None
        for name, default, *_ in self.parameters + EXCITATION:
            setattr(self, name, float(default))
        self.harmonics = MAX_HARMONIC
        self.f = 0.0

    # -- variables -------------------------------------------------------------
    # fmi2Reset creates a new instance, so instances are cheap: the variables are
    # a per-class table served by get_/set_real and get_/set_integer, and pythonfmu's
    # variable objects are made only when a model description is written.
    @classmethod
    def layout(cls):
        """[(name, 'Real' or 'Integer', causality, variability, description)] in value-reference order."""
        table = [(name, "Real", "parameter", "fixed", description)
                 for name, _default, _unit, description in cls.parameters + EXCITATION]
        table.append(("harmonics", "Integer", "parameter", "fixed",
                      "number of harmonics k whose running Fourier integrals are computed (0..10)"))
        table.append(("f", "Real", "input", "continuous", "input force, added to the built-in excitation"))
        for name, _unit, description, is_integer in cls.all_outputs():
            table.append((name, "Integer" if is_integer else "Real", "output",
                          "discrete" if is_integer else "continuous", description))
        return table

    def to_xml(self, model_options=dict()):
        if not self.vars:
            for name, kind, causality, variability, description in self.layout():
                self.register_variable((Integer if kind == "Integer" else Real)(
                    name, causality=Fmi2Causality[causality], variability=Fmi2Variability[variability],
                    description=description, getter=lambda name=name: self._value(name)))
        return super().to_xml(model_options)

    def _value(self, name):
        if name in self._settable:
            return getattr(self, name)
        if name[:2] in ("Ic", "Is"):
            if self._fourier is None and self.solver is not None:
                self._fourier = {}
                for k, integral in enumerate(self.solver.integrals()):
                    self._fourier[f"Ic{k}"] = integral.real
                    self._fourier[f"Is{k}"] = -integral.imag
            return (self._fourier or {}).get(name, 0.0)
        return self._values.get(name, 0)

    def _names(self, vrs, kind):
        table = self._layout
        names = []
        for vr in vrs:
            if not 0 <= vr < len(table) or table[vr][1] != kind:
                raise TypeError(f"Variable with valueReference={vr} is not of type {kind}!")
            names.append(table[vr][0])
        return names

    def get_real(self, vrs):
        return [float(self._value(name)) for name in self._names(vrs, "Real")]

    def get_integer(self, vrs):
        return [int(self._value(name)) for name in self._names(vrs, "Integer")]

    def _set(self, vrs, values, kind, convert):
        for name, value in zip(self._names(vrs, kind), values):
            if name not in self._settable:
                raise TypeError(f"{name} is an output and cannot be set")
            setattr(self, name, convert(value))

    def set_real(self, vrs, values):
        self._set(vrs, values, "Real", float)

    def set_integer(self, vrs, values):
        self._set(vrs, values, "Integer", int)

    # -- declarations used by the builder ------------------------------------
    @classmethod
    def all_outputs(cls):
        signal, unit = cls.output_signal
        fourier = []
        for k in range(MAX_HARMONIC + 1):
            for part, wave in (("c", "cos"), ("s", "sin")):
                fourier.append((f"I{part}{k}", f"{unit}.s",
                                f"running integral of {signal}(t) {wave}({k} omega t) dt from 0", False))
        events = ("events", None, "number of events (mode changes, impacts) so far", True)
        return tuple(cls.outputs) + (events,) + tuple(fourier)

    @classmethod
    def units(cls):
        """Unit of every Real variable that has one."""
        table = {name: unit for name, _d, unit, _desc in cls.parameters + EXCITATION if unit}
        table["f"] = "N"
        table.update({name: unit for name, unit, _d, is_int in cls.all_outputs() if unit and not is_int})
        return table

    # -- FMI ------------------------------------------------------------------
    def exit_initialization_mode(self):
        kwargs = {name: getattr(self, name) for name, *_ in self.parameters + EXCITATION}
        try:
            self.solver = self.solver_class(f=self.f, harmonics=self.harmonics, **self.solver_kwargs(kwargs))
        except PlantError as error:
            self._fail(f"invalid parameter: {error}")
        self._refresh()

    @classmethod
    def solver_kwargs(cls, kwargs):
        """The solver's keyword arguments from the FMU's parameter values."""
        return kwargs

    def _refresh(self):
        values = self._values
        values.update(zip((name for name, *_ in self.outputs), self.output_values()))
        values["events"] = self.solver.events
        self._fourier = None

    def output_values(self):
        raise NotImplementedError


class FrictionMass(PlantFMU):
    """Mass with Coulomb, viscous and static friction (exact stick-slip), force input f."""

    solver_class = _FrictionMass
    parameters = (
        ("M", 1.0, "kg", "mass (> 0)"),
        ("B", 0.5, "N.s/m", "viscous friction coefficient (>= 0)"),
        ("Fc", 5.0, "N", "Coulomb friction force (>= 0)"),
        ("Fs", 7.0, "N", "static friction force (>= Fc)"),
        ("Dv", 0.0, "m/s", "Karnopp velocity band (0: exact stick at v = 0)"),
        ("x0", 0.0, "m", "initial position"),
        ("v0", 0.0, "m/s", "initial velocity"),
    )
    outputs = (
        ("x", "m", "position", False),
        ("v", "m/s", "velocity", False),
        ("Ff", "N", "friction force", False),
        ("mode", None, "0 stick (or inside the Karnopp band), +1/-1 sliding", True),
    )

    def output_values(self):
        return self.solver.output()


class TwoMassBacklash(PlantFMU):
    """Two masses with a clearance h and impacts of restitution eps, force input f on M2."""

    solver_class = _TwoMassBacklash
    output_signal = ("x1", "m")
    parameters = (
        ("M1", 1.0, "kg", "mass 1, the output side (> 0)"),
        ("M2", 1.0, "kg", "mass 2, driven by the force (> 0)"),
        ("h", 0.1, "m", "clearance (> 0)"),
        ("eps", 0.5, None, "coefficient of restitution, in [0, 1]"),
        ("x1_0", 0.0, "m", "initial position of M1"),
        ("v1_0", 0.0, "m/s", "initial velocity of M1"),
        ("v2_0", 0.0, "m/s", "initial velocity of M2"),
        ("gap0", -1.0, "m", "initial gap x2 - x1, in [0, h]; -1 (default): h/2"),
    )
    outputs = (
        ("x1", "m", "position of M1", False),
        ("v1", "m/s", "velocity of M1", False),
        ("x2", "m", "position of M2", False),
        ("v2", "m/s", "velocity of M2", False),
        ("gap", "m", "gap x2 - x1, in [0, h]", False),
        ("contact", None, "0 free, 1 in contact at gap 0, 2 in contact at gap h", True),
        ("impacts", None, "number of impacts so far", True),
    )

    @classmethod
    def solver_kwargs(cls, kwargs):
        if kwargs["gap0"] == -1.0:  # the start value: centred, whatever h is
            kwargs["gap0"] = None
        return kwargs

    def output_values(self):
        return self.solver.output() + (self.solver.contact, self.solver.impacts)


class StaticBacklash(PlantFMU):
    """Mass M driven by the force, followed by a backlash element of slope k and width h."""

    solver_class = _StaticBacklash
    output_signal = ("y", "m")
    parameters = (
        ("M", 2.0, "kg", "mass (> 0)"),
        ("k", 1.0, None, "slope of the backlash element (> 0)"),
        ("h", 0.1, "m", "total width of the dead band (> 0)"),
        ("x0", 0.0, "m", "initial position"),
        ("v0", 0.0, "m/s", "initial velocity"),
    )
    outputs = (
        ("x", "m", "position of the mass (backlash input)", False),
        ("v", "m/s", "velocity of the mass", False),
        ("y", "m", "backlash output", False),
        ("engaged", None, "0 inside the play, +1/-1 engaged and dragging y", True),
    )

    def output_values(self):
        return self.solver.output() + (self.solver.engaged,)


class LinearSystem(SolverFMU):
    """Linear transfer function G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an), exact for a held input u."""

    input_name = "u"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.order = 1  # defaults: G(s) = 1 / (s + 1)
        for i in range(_MAX_ORDER + 1):
            setattr(self, f"b{i}", 1.0 if i == 1 else 0.0)
        for i in range(1, _MAX_ORDER + 1):
            setattr(self, f"a{i}", 1.0 if i == 1 else 0.0)
        self.u = 0.0
        fixed = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        self.register_variable(Integer(
            "order", description=f"order n of G(s), the degree of its denominator (1..{_MAX_ORDER})", **fixed))
        for i in range(_MAX_ORDER + 1):
            self.register_variable(Real(f"b{i}", description=(
                f"numerator coefficient of s^(n-{i}), n = order" if i else "numerator coefficient of s^n, n = order")
                + ("" if i == 0 else f"; must be 0 when order < {i}"), **fixed))
        for i in range(1, _MAX_ORDER + 1):
            self.register_variable(Real(f"a{i}", description=(
                f"denominator coefficient of s^(n-{i}), n = order (the coefficient of s^n is 1); "
                f"must be 0 when order < {i}"), **fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                    description="input u, held constant over each communication step"))
        self.register_variable(Real("y", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    description="output y = C x + D u of G(s) at the current time",
                                    getter=self._output))

    @classmethod
    def units(cls):
        """Every variable is dimensionless (the builder's unit pass)."""
        return {}

    def _make_solver(self):
        """The solver from the parameters; PlantError names a bad one."""
        order = self.order
        check("order", order, lambda: order == int(order) and 1 <= order <= _MAX_ORDER,
              f"the order must be an integer in 1..{_MAX_ORDER}")
        for i in range(order + 1, _MAX_ORDER + 1):
            for name in (f"b{i}", f"a{i}"):
                value = getattr(self, name)
                check(name, value, lambda: value == 0.0, f"{name} is above the order {order} and must be 0")
        return _LinearSystem([getattr(self, f"b{i}") for i in range(order + 1)],
                             [getattr(self, f"a{i}") for i in range(1, order + 1)])

    def _output(self):
        """y with the input as it is now (D u is a direct feedthrough); never NaN."""
        solver = self.solver
        if solver is None:  # initialisation mode: zero state, the parameters as set so far
            try:
                solver = self._make_solver()
            except PlantError:
                return 0.0
        return solver.output(self.u if math.isfinite(self.u) else None)

    def exit_initialization_mode(self):
        try:
            self.solver = self._make_solver()
        except PlantError as error:
            self._fail(f"invalid parameter: {error}")


PRODUCTION = (FrictionMass, TwoMassBacklash, StaticBacklash, LinearSystem)
"""The FMUs dfwb ships: the three plants and the linear controller (what ``dfwb build`` builds)."""

FACADES.append(LinearSystem)
