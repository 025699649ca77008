"""A plant in feedback with a controller, both with named parameters: where their values meet and are checked.

A continuation follows a cycle in one parameter and a hunting map covers
two; either may belong to the controller (``Kp`` of ``"Kp + Ki/s"``, or an
argument of a function that builds a python-control system) or to the plant
(``Fs``, ``eps``). A :class:`LoopFamily` holds the plant, the controller
and the values given, refuses what cannot work before anything runs (a
parameter of G given no value, a name that is both G's and the plant's, a
parameter named ``s``, an unknown name), and makes the loop at any values.

Examples
--------
>>> family = LoopFamily("friction", "Kp + Ki/s", {"Kp": 10, "Ki": 2, "Fs": 8})
>>> family.names
('Kp', 'Ki', 'M', 'B', 'Fc', 'Fs', 'Dv')
>>> family.G({"Ki": 3}).num[0][0].tolist(), family.params({"Ki": 3})
([10.0, 3.0], {'Fs': 8.0})
"""

import copy
import inspect
import math

from dfwb.base.errors import InputError, PlantError
from dfwb.base.values import NUMBER_FORMS, real, short
from dfwb.engine.compensators import CHOICES, Compensation, choice
from dfwb.plants import plant as find_plant


def number(name, value, finite="give a finite number"):
    """A finite float of a value given for a parameter (text from the command line too); ``finite`` says
    what is allowed when it is not."""
    value_ = real(value)
    if value_ is None:
        raise InputError(f"{name} = {short(value, 60)} is not a number ({NUMBER_FORMS}, or a real number)")
    if not math.isfinite(value_):
        raise InputError(f"{name} = {short(value, 60)}: {finite}")
    return value_


class _Built:
    """A controller built by a function of its parameters (``lambda Kp, Ki: control.tf(...)``)."""

    def __init__(self, function):
        try:
            signature = inspect.signature(function)
        except (TypeError, ValueError):
            raise InputError(f"G = {function!r:.60}: cannot read the parameters of this function") from None
        kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
        if any(p.kind not in kinds for p in signature.parameters.values()):
            raise InputError(f"G = {function!r:.60}: a function of named parameters only (no *args, **kwargs)")
        self.function, self.names = function, tuple(signature.parameters)
        self.text = getattr(function, "__name__", "G")

    def transfer_function(self, values):
        from dfwb.engine.transfer import to_transfer_function

        arguments = {name: values[name] for name in self.names}
        try:
            system = self.function(**arguments)
        except Exception as error:  # the user's function: its failure is the user's to read, in one line
            raise InputError(f"G = {self.text}({', '.join(f'{k}={v:g}' for k, v in arguments.items())}) raised "
                             f"{type(error).__name__}: {error}") from None
        return to_transfer_function(system)


class _Fixed:
    """A controller without parameters. Given as (num, den), it is checked now and built when first used."""

    names = ()

    def __init__(self, G):
        from dfwb.engine.transfer import is_pair, pair_of, to_transfer_function

        self.pair, self.G = (pair_of(G), None) if is_pair(G) else (None, to_transfer_function(G))
        self.text = "G(s)" if self.pair is None else "({})/({})".format(*self.pair)

    def checked(self, values):
        if self.G is None:
            return self.pair
        from dfwb.engine.transfer import num_den

        return num_den(self.G)

    def transfer_function(self, values):
        if self.G is None:
            from dfwb.engine.transfer import system

            self.G = system(*self.pair)
        return self.G


class _Scaled:
    """k G: a controller times a gain factor named ``name`` (a margin's parameter)."""

    def __init__(self, inner, name):
        self.inner, self.name = inner, name
        self.names = tuple(inner.names) + (name,)
        self.text = f"{name} * ({inner.text})"

    def transfer_function(self, values):
        from dfwb.engine.transfer import check_transfer_function

        return check_transfer_function(values[self.name] * self.inner.transfer_function(values), self.text)

    def coefficients(self, values):
        from dfwb.engine.transfer import num_den

        return num_den(self.transfer_function(values))


class LoopFamily:
    """A plant in feedback with G(s), their parameters named, the values given checked.

    Parameters
    ----------
    plant : str
        A registered plant with an exact loop.
    G : str, callable, (num, den), control.TransferFunction or control.StateSpace
        An expression in ``s`` whose other names are parameters (``"Kp + Ki/s"``); a
        function of named parameters returning a python-control system; or a fixed system.
    values : dict, optional
        Values of G's parameters and of the plant's (``{"Kp": 10, "Fs": 8}``).
    free : iterable of str
        Parameters that take their values later (a continuation's, a map's axes): they need none now.
    compensate : str or list of str, optional
        Compensators between the controller and the plant (:mod:`dfwb.engine.compensators`), whose
        parameters (``F_hat``, ``d``, the choice ``signal``) are named and valued like G's.
    """

    def __init__(self, plant, G, values=None, free=(), compensate=None):
        from dfwb.engine.transfer import TransferFamily

        self.spec = spec = find_plant(plant)
        if isinstance(G, str):
            self.controller = TransferFamily(G)
        elif callable(G) and not hasattr(G, "num") and not hasattr(G, "A"):
            self.controller = _Built(G)
        else:
            self.controller = _Fixed(G)
        starts = spec.loop.initial_parameters if spec.loop is not None else ()
        self.plant_names = tuple(name for name in spec.defaults() if name not in starts)  # not where it starts
        clash = [name for name in self.controller.names if name in self.plant_names]
        if clash:
            raise InputError(f"{clash[0]} is both a parameter of G(s) and of the {spec.name} plant: rename it in G")
        self.compensation = Compensation(compensate)
        if self.compensation and spec.loop is None:
            raise InputError(f"compensate: plant {spec.name!r} has no exact closed loop, where compensators act")
        self.compensation.fit(spec)
        clash = [name for name in self.compensation.names if name in self.controller.names + self.plant_names]
        if clash:
            raise InputError(f"{clash[0]} is both a parameter of a compensator and of G(s) or the {spec.name} "
                             "plant: rename it in G")
        self.names = tuple(self.controller.names) + self.plant_names + self.compensation.names
        self.built = isinstance(self.controller, _Built)  # G is a Python function (it stays in this process)
        values = dict(values or {})
        self.values = {}
        for name, value in values.items():
            self.check_name(name)
            self.values[name] = self._value(name, value)
        self.free = free = tuple(free)
        for name in free:
            self.check_name(name)
            if name in CHOICES:
                raise InputError(f"{name} is a choice ({', '.join(CHOICES[name])}), not a number: set it, it "
                                 "cannot be followed or mapped")
        missing = [name for name in self.controller.names if name not in self.values and name not in free]
        if missing:
            raise InputError(f"G(s) = {self.controller.text}: the parameter {missing[0]} is given no value "
                             f"(set it, e.g. {missing[0]}=1)")
        missing = [name for name in self.compensation.names
                   if self.compensation.numeric(name) and name not in self.values and name not in free]
        if missing:
            raise InputError(f"compensate: the parameter {missing[0]} is given no value (set it, e.g. "
                             f"{missing[0]}=1)")
        spec.check({k: v for k, v in self.values.items() if k in self.plant_names})
        self._linear = {}  # plant parameters -> the linear plant's (num, den) polynomials
        if not any(name in free for name in self.controller.names + self.compensation.names):
            self.check()  # every value given: refuse an improper or degenerate G now, before anything runs

    @staticmethod
    def _value(name, value):
        """A value given for ``name``: a choice's among its allowed, else a finite number."""
        return choice(name, value) if name in CHOICES else number(name, value)

    def check_name(self, name):
        """Refuse a name that is no parameter of G or of the plant (or is s)."""
        if name == "s":
            raise InputError("s is the variable of G(s), not a parameter: name the parameter otherwise")
        if name not in self.names:
            allowed = ", ".join(self.names)
            whose = f"G's, the {self.spec.name} plant's and the compensators'" if self.compensation else \
                f"G's and the {self.spec.name} plant's"
            raise InputError(f"unknown parameter {name!r}: {whose} are {allowed}")

    def merged(self, values=None):
        """The values given, updated by ``values`` (checked as numbers)."""
        merged = dict(self.values)
        for name, value in (values or {}).items():
            self.check_name(name)
            merged[name] = self._value(name, value)
        return merged

    def _complete(self, values):
        merged = self.merged(values)
        missing = [name for name in self.controller.names if name not in merged]
        if missing:
            raise InputError(f"G(s) = {self.controller.text}: the parameter {missing[0]} is given no value")
        return merged

    def G(self, values=None):
        """The controller at the values (a python-control TransferFunction, checked)."""
        return self.controller.transfer_function(self._complete(values))

    def check(self, values=None):
        """Refuse an improper or degenerate G at the values; an expression's or a (num, den)'s is checked
        without building a system (python-control is not imported)."""
        from dfwb.engine.transfer import check_loop_controller, num_den

        checked = getattr(self.controller, "checked", None)
        merged = self._complete(values)
        if checked is None:
            num, den = num_den(self.controller.transfer_function(merged))
        else:
            num, den = checked(merged)
        if self.spec.loop is not None:  # the exact closed loop is built of it
            check_loop_controller(num, den, self.controller.text)
        if self.compensation:  # the compensators' values, and whether they fit this plant and controller
            self.problem(values)

    def coefficients(self, values=None):
        """(num, den) of G at the values, highest power first: an expression's without building a checked
        system (a DF continuation asks at every step), else the checked G's."""
        from dfwb.engine.transfer import num_den

        if isinstance(self.controller, _Fixed) or self.built:
            return num_den(self.G(values))
        return self.controller.coefficients(self.merged(values))

    def params(self, values=None):
        """The plant's parameters at the values (checked, as the plant checks them)."""
        merged = self.merged(values)
        return self.spec.checked({k: v for k, v in merged.items() if k in self.plant_names})

    def df_params(self, values=None):
        """The plant parameters the loop's DF is computed with at the values: the plant's; a compensated loop's
        equivalent plant's (:meth:`~dfwb.engine.compensators.Compensation.equivalent`), None where it has none."""
        params = self.params(values)
        if not self.compensation:
            return params
        return self.compensation.equivalent(self.spec, params, self.merged(values))

    def df_engine(self, engine):
        """The engine of the loop's DF: ``engine`` (the plant's), or a compensated plant's own where its DF is a
        closed form (the static backlash seen through its inverse, :mod:`dfwb.engine.inverse_df`)."""
        return self.compensation.df_engine(self.spec, engine)

    def problem(self, values=None, fmu_dir=None, budget=None):
        """The :class:`~dfwb.engine.periodic.LoopProblem` at the values."""
        from dfwb.engine.periodic import LoopProblem

        return LoopProblem(self.spec.name, self.G(values), self.params(values), fmu_dir=fmu_dir, budget=budget,
                           compensation=self.compensators(values))

    def compensators(self, values=None):
        """The loop's compensators at the values (:mod:`dfwb.fmus.compensation`), or None without any; a value
        a compensator refuses, alone or against the plant's (a backlash inverse's estimate), in one line."""
        merged = self.merged(values)
        try:
            built = self.compensation.build(merged)
        except PlantError as error:
            raise InputError(str(error)) from None
        if built is not None:
            self.compensation.check_estimate(self.spec, self.params(values), merged)
        return built

    def check_compensator(self, values):
        """Refuse a value of a compensator's parameter outside the compensator's range (whatever its other
        parameters: a map may have two of one compensator's on its axes), and a backlash inverse's estimate
        beyond the plant's play allows where that play is fixed."""
        for name, value in values.items():
            self.compensation.check(name, number(name, value))
        if "h_hat" in values and "h" not in self.free:
            self.compensation.check_estimate(self.spec, self.params(), self.merged(values))

    def scaled(self, name):
        """The family of ``name`` * G: the gain factor a free parameter (refused if G or the plant has it)."""
        if name in self.names:
            raise InputError(f"{name} names a parameter of G or of the plant already: it cannot be the gain factor")
        scaled = copy.copy(self)
        scaled.controller = _Scaled(self.controller, name)
        scaled.names = (name,) + self.names
        scaled._linear = {}
        return scaled

    def at(self, values):
        """The family with more values fixed (a map's column: its x given)."""
        fixed = copy.copy(self)
        fixed.values = self.merged(values)
        fixed._linear = {}
        return fixed

    def linear_stable(self, values=None):
        """Whether the linear loop (the nonlinearity removed) is stable at the values."""
        return self.linear_growth(values) < 0.0

    def linear_growth(self, values=None):
        """The largest real part of the linear loop's poles at the values (< 0: stable; inf: none)."""
        from dfwb.engine.scales import largest_real_parts

        return float(largest_real_parts([self.characteristic(values)])[0])

    def characteristic(self, values=None):
        """The linear loop's characteristic polynomial at the values, den_G den_P + num_G num_P, without
        building the exact loop (a map's boundary asks it at 6400 points)."""
        from dfwb.engine.scales import characteristic

        num_g, den_g = self.coefficients(values)
        params = self.params(values)
        key = tuple(sorted(params.items()))
        if key not in self._linear:
            probe = self.spec.loop([0.0, 0.0], [1.0], **params)  # a trivial controller: only the plant is read
            self._linear[key] = probe.linear()
        return characteristic(num_g, den_g, *self._linear[key])

    def describe(self, values=None):
        """The values as one short text: ``Kp = 10, Ki = 2, Fs = 8``."""
        merged = self.merged(values)
        return ", ".join(f"{name} = {merged[name]:.6g}" if name not in CHOICES else f"{name} = {merged[name]}"
                         for name in self.names if name in merged)
