"""FMI 2.0 co-simulation facades of the plants in feedback with a linear controller (:mod:`.loops`).

    f = -G(s) y,   G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an),   n = order = 1..8

One FMU holds the whole loop, solved exactly and event by event by the
plant's ``LOOP`` (:class:`~.loops.FeedbackLoop`), one FMU per plant of
:mod:`.plants`, made by :func:`loop_facade`: the friction mass
(FrictionMassLoop), the two-mass backlash (TwoMassBacklashLoop) and the mass
with a static backlash (StaticBacklashLoop), each with its plant output y
(x, x1, y) fed back through -G(s). The FMU has no input. Its parameters are the plant FMU's
(same names, defaults, units and descriptions; no built-in excitation, no
harmonics) and the controller's, named as in LinearSystem.fmu (``order``,
``b0..b8``, ``a1..a8``; the coefficients above the order must be 0), plus
the controller's initial state ``z1_0..z8_0`` (controllable canonical
form, as LinearSystem realises G; those above the order must be 0). The
default controller is G(s) = 1 / (s + 1) (order 1, b0 = 0, b1 = 1,
a1 = 1), a weak low-pass feedback: with the plants' default initial
values nothing moves until a parameter says otherwise.

Outputs: the plant FMU's continuous outputs (same names), ``f`` (the force
-G(s) y into the plant), the plant's mode, ``events`` and the plant's
counter. The results are bit-identical for any communication steps (the
solver's chunks are anchored at its events, never at communication points).

Everything else is :class:`~.facade.SolverFMU`: refused parameters, steps
and non-finite motions are logged with status error and never raise out of
a callback; FMU states are exact copies of the solver, serialized for this
model and build only, restored after checks that bound the work of the
next step (:meth:`LoopFMU._check_solver_state`).

The compiled core: as the plant FMUs, each loop FMU carries the C core
(``resources/libdfwb_core.so``) and runs on its port of the loop
(``native_solver``: ``FrictionLoop``, ``BacklashLoop``,
``StaticBacklashLoop`` of :mod:`.native_core`), bit for bit the Python
solver's outputs and refusals; the pure-Python loop is
the fallback (one warning) and ``DFWB_FMU_SOLVER`` chooses as for the
plants (see :mod:`.facade`). A serialized state holds the C loop's checked
bytes, read back by the instance's own core.
"""

import math

from . import facade as _facade
from .hybrid import Mode
from .integrated import IntegratedMode
from .linear_system import MAX_ORDER
from .piecewise import PlantError, check
from .plants import MODULES

__all__ = ["LoopFMU", "loop_facade", "LOOPS"]


def _controller_layout():
    """(name, kind, causality, variability, description) of order, b0..b8, a1..a8 and z1_0..z8_0."""
    table = [("order", "Integer", "parameter", "fixed",
              f"order n of the controller G(s), the degree of its denominator (1..{MAX_ORDER}); "
              f"the force on the plant is f = -G(s) y")]
    for i in range(MAX_ORDER + 1):
        table.append((f"b{i}", "Real", "parameter", "fixed",
                      (f"numerator coefficient of s^(n-{i}) of G(s), n = order; must be 0 when order < {i}" if i
                       else "numerator coefficient of s^n of G(s), n = order")))
    for i in range(1, MAX_ORDER + 1):
        table.append((f"a{i}", "Real", "parameter", "fixed",
                      f"denominator coefficient of s^(n-{i}) of G(s), n = order (the coefficient of s^n is 1); "
                      f"must be 0 when order < {i}"))
    for i in range(1, MAX_ORDER + 1):
        table.append((f"z{i}_0", "Real", "parameter", "fixed",
                      f"initial value of the controller state z{i} (controllable canonical form, z{i} the "
                      f"{i - 1}-th derivative of z1, G(s) = C z + D y as in LinearSystem); must be 0 when "
                      f"order < {i}"))
    return table


CONTROLLER = _controller_layout()
CONTROLLER_DEFAULTS = {name: 1.0 if name in ("b1", "a1") else 0.0 for name, kind, *_ in CONTROLLER if kind == "Real"}
CONTROLLER_DEFAULTS["order"] = 1
"""G(s) = 1 / (s + 1) and z = 0: a harmless default (a weak low-pass feedback)."""
COMMON_FIXED = ("order", "Ac", "Bc", "C", "D", "event_log", "_section", "_watching", "crossings")
"""Solver attributes of every loop that a run never changes (a restored solver's must equal a new one's)."""


class LoopFMU(_facade.TableFMU):
    """A plant in feedback with -G(s): no input, the plant's parameters and outputs, the controller's parameters."""

    input_name = None
    solver_class = None
    plant = None
    """The plant FMU facade whose parameters (minus the excitation) and outputs this loop keeps."""
    parameters = ()  # (name, default, unit, description): the plant's
    outputs = ()  # (name, unit, description, is_integer), in value-reference order after the parameters
    mode_keys = {}
    """{mode key of the solver: value of the mode output}: every mode the loop can be in."""
    fixed_solver_attributes = COMMON_FIXED
    state_classes = (Mode, IntegratedMode)  # the solver's modes (its own classes, EventKind, its STATE_CLASSES and
    # the base classes are added)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._values = {}
        self._frozen = False
        self._overflow = False
        for name, default, *_ in self.parameters:
            setattr(self, name, float(default))
        for name, value in CONTROLLER_DEFAULTS.items():
            setattr(self, name, value)

    # -- variables (TableFMU's per-class table) ------------------------------------
    @classmethod
    def layout(cls):
        """[(name, 'Real' or 'Integer', causality, variability, description)] in value-reference order."""
        table = [(name, "Real", "parameter", "fixed", description) for name, _d, _u, description in cls.parameters]
        table += CONTROLLER
        for name, _unit, description, is_integer in cls.outputs:
            table.append((name, "Integer" if is_integer else "Real", "output",
                          "discrete" if is_integer else "continuous", description))
        return table

    @classmethod
    def units(cls):
        """Unit of every Real variable that has one (the controller's coefficients and states have none)."""
        table = {name: unit for name, _d, unit, _desc in cls.parameters if unit}
        table.update({name: unit for name, unit, _d, is_int in cls.outputs if unit and not is_int})
        return table

    @classmethod
    def limits(cls):
        """{name: (min, max)}: the plant's ranges (those of its parameters kept) and the order's."""
        kept = {name for name, *_ in cls.parameters}
        table = {name: bounds for name, bounds in cls.plant.ranges.items() if name in kept}
        table["order"] = (1, MAX_ORDER)
        table.update(cls.ranges)
        return table

    def _value(self, name):
        if name in self._parameters:
            return getattr(self, name)
        return self._values.get(name, 0)

    # -- the solver --------------------------------------------------------------
    def _controller(self):
        """(b, a, z0) of G(s) from the parameters; PlantError names a bad one (as LinearSystem.fmu's checks)."""
        order = self.order
        check("order", order, lambda: order == int(order) and 1 <= order <= MAX_ORDER,
              f"the order must be an integer in 1..{MAX_ORDER}")
        for i in range(order + 1, MAX_ORDER + 1):
            for name in (f"b{i}", f"a{i}", f"z{i}_0"):
                value = getattr(self, name)
                check(name, value, lambda: value == 0.0, f"{name} is above the order {order} and must be 0")
        return ([getattr(self, f"b{i}") for i in range(order + 1)],
                [getattr(self, f"a{i}") for i in range(1, order + 1)],
                [getattr(self, f"z{i}_0") for i in range(1, order + 1)])

    def _make_solver(self, like=None):
        """The loop's solver at its time 0 (the FMU's start time); PlantError names a bad parameter.

        On the compiled core or in Python as :meth:`~.facade.SolverFMU._new_solver_class` chooses (the
        choice logged); ``like``: a solver whose kind the new one takes (nothing logged)."""
        solver_class = self._new_solver_class(like)
        b, a, z0 = self._controller()
        kwargs = self.solver_kwargs({name: getattr(self, name) for name, *_ in self.parameters})
        solver = solver_class(b, a, z0=z0, **kwargs)
        outputs = self._outputs_of(solver)
        if not _finite(outputs):
            bad = ", ".join(f"{name} = {value!r}" for name, value in outputs.items() if not math.isfinite(value))
            raise PlantError(f"the initial outputs overflow a float ({bad}): the gains or initial values are too large")
        return solver

    @classmethod
    def solver_kwargs(cls, kwargs):
        """The solver's keyword arguments (the plant's) from the FMU's parameter values."""
        return cls.plant.solver_kwargs(kwargs)

    def _outputs_of(self, solver):
        """{output name: value} at the solver's time."""
        X = solver.state()
        f = solver.force(X)
        loop = self.solver_class
        values = loop.fmu_values(solver, X, f)
        values["f"] = f
        values[loop.MODE_OUTPUT.name] = self.mode_keys[solver.key]
        values["events"] = solver.events
        values.update(solver.counts())
        return values

    def _refresh(self):
        if self._frozen:
            return
        values = self._outputs_of(self.solver)
        self._overflow = not _finite(values)
        if not self._overflow:  # a motion that overflows keeps the last good outputs (doStep then fails)
            self._values = values

    def _broken(self):
        self._frozen = True  # outputs stay at the last good point, until a state is set (or a reset)

    def _finite(self):
        return not self._overflow

    def _restored(self):
        self._frozen = self._overflow = False
        if self.solver is None:  # a state taken before initialisation: no outputs yet
            self._values = {}
        super()._restored()

    # -- FMU state ---------------------------------------------------------------------
    def _check_solver_state(self, values, solver):
        """StepRefused unless the restored solver is one these parameters and this time can produce.

        Beyond SolverFMU's checks (the parameters, the fixed attributes, the time): the
        modes must be modes of this loop, each identical to the one a new solver derives
        (their chunk length and Taylor terms bound a step's work), the current piece
        consistent (state and derivative of the loop's size and finite, the chunk
        around the time, a pending event inside the chunk) and the counters whole numbers.
        A loop of the compiled core checked all that when it read its bytes (``from_bytes``);
        SolverFMU compared its parameters with a new one's (``same_parameters``). Either
        way its outputs must be finite.
        """
        super()._check_solver_state(values, solver)
        if not self._is_native(solver):
            self._check_python_loop(values, solver)
        if not _finite(self._outputs_of(solver)):
            self._fail("the state's outputs overflow a float")

    def _check_python_loop(self, values, solver):
        """The checks of a restored Python loop's internals (:meth:`_check_solver_state`); StepRefused."""
        fresh = self._solver_from(values, solver)
        modes = getattr(solver, "_modes", None)
        if not (type(modes) is dict and modes and all(key in self.mode_keys for key in modes)):
            self._fail("the state's modes are not modes of this loop")
        for key, mode in modes.items():
            if not _same_mode(mode, fresh.mode(key)):
                self._fail(f"the state's mode {key!r} does not match its parameters")
        key = getattr(solver, "key", None)
        mode = modes.get(key) if type(key) is tuple and key in self.mode_keys else None
        if mode is None or getattr(solver, "_mode", None) is not mode:
            self._fail("the state's current mode is not one of its modes")
        size = len(fresh.coordinates) + fresh.order
        X, dX = getattr(solver, "_X", None), getattr(solver, "_dX", None)
        for vector in (X, dX):
            if not (type(vector) is list and len(vector) == size
                    and all(type(value) is float and math.isfinite(value) for value in vector)):
                self._fail("the state's loop state does not match the loop's size or is not finite")
        if mode.integrated and not _step_shape(getattr(solver, "_step", None), size):
            self._fail("the state's integrated step is not one of this loop")
        if dX != mode.derivative(X):
            self._fail("the state's derivative does not match its state")
        a, b, t = getattr(solver, "_a", None), getattr(solver, "_b", None), solver.t
        if not (type(a) is float and type(b) is float and 0.0 <= a <= t < b and b == a + mode.h):
            self._fail("the state's chunk does not match its time")
        first, searched = getattr(solver, "_first", None), getattr(solver, "_searched", None)
        departing, event = getattr(solver, "_departing", False), getattr(solver, "_event", False)
        kinds = [kind for kind, _L, _l0 in mode.events]
        if not (type(first) is bool and type(searched) is bool and _indices(departing, len(kinds))):
            self._fail("the state's search flags are damaged")
        if not (event is None or (searched and type(event) is tuple and len(event) == 2
                                  and type(event[0]) is float and 0.0 <= event[0] <= mode.h and event[1] in kinds
                                  and type(event[1]) is type(kinds[0]))):
            self._fail("the state's pending event is damaged")
        for name in ("events",) + tuple(fresh.counts()):
            count = getattr(solver, name, None)
            if not (type(count) is int and count >= 0):
                self._fail(f"the state's {name} is not a count")

    def _check_solver_times(self, solver):
        """(All checked in :meth:`_check_solver_state`.)"""


def _indices(departing, count):
    """Whether ``departing`` names event functions of a mode with ``count`` of them (None, an index or a tuple)."""
    if departing is None:
        return True
    if type(departing) is not tuple:
        departing = (departing,)
    return len(departing) <= count and all(type(i) is int and 0 <= i < count for i in departing)


def _finite(values):
    return all(math.isfinite(value) for value in values.values())


def _same(mine, theirs):
    """Equal values of the same types, all the way down (EventKind is not its str, 1 is not 1.0; plain data
    with slots, an integrated mode's law, slot by slot)."""
    if type(mine) is not type(theirs):
        return False
    if type(mine) in (list, tuple):
        return len(mine) == len(theirs) and all(_same(x, y) for x, y in zip(mine, theirs))
    slots = getattr(type(mine), "__slots__", None)
    if slots:
        return all(_same(getattr(mine, slot, None), getattr(theirs, slot, None)) for slot in slots)
    return mine == theirs


def _same_mode(mode, fresh):
    return type(mode) in (Mode, IntegratedMode) and _same(mode, fresh)


def _step_shape(step, size):
    """Whether an integrated chunk's step is [a, h, X0, X1, dX0, dX1, X0'', X1'', next h, peaks] of finite
    floats, its vectors of the loop's size (IntegratedMode.take)."""
    if not (type(step) is list and len(step) == 10):
        return False
    scalars, vectors = (step[0], step[1], step[8]), step[2:8] + [step[9]]
    return (all(type(v) is float and math.isfinite(v) for v in scalars) and step[1] > 0.0
            and all(type(vector) is list and len(vector) == size
                    and all(type(v) is float and math.isfinite(v) for v in vector) for vector in vectors))


def loop_facade(module):
    """The closed-loop FMU facade of a plant's model module (:mod:`.plants`), ``table.model + "Loop"``: the
    plant FMU's parameters (the loop's descriptions where it has its own), the loop's outputs (its plant's
    continuous outputs, the force, its mode, the events, its counter), its ``LOOP`` as the solver."""
    table, loop = module.TABLE, module.LOOP
    plant = getattr(_facade, table.model)
    summary = table.summary[:1].upper() + table.summary[1:]
    outputs = tuple((o.name, o.unit, o.description, o.integer) for o in loop.FMU_OUTPUTS) + (
        ("f", "N", f"force on the plant, f = -G(s) {table.signal}", False),
        (loop.MODE_OUTPUT.name, None, loop.MODE_OUTPUT.description, True),
        ("events", None, "number of events (the loop's mode changes) so far", True),
        (loop.COUNTER.name, None, loop.COUNTER.description, True))
    return type(table.model + "Loop", (LoopFMU,), {
        "__doc__": f"{summary}, in feedback f = -G(s) {table.signal}.", "__module__": __name__,
        "solver_class": loop, "native_solver": loop.__name__, "plant": plant,
        "fixed_solver_attributes": COMMON_FIXED + loop.CONSTANTS, "ranges": dict(loop.FMU_RANGES),
        "mode_keys": loop.MODE_VALUES, "outputs": outputs,
        "parameters": tuple((name, start, unit, loop.FMU_DESCRIPTIONS.get(name, description))
                            for name, start, unit, description in plant.parameters)})


LOOPS = tuple(loop_facade(module) for module in MODULES)
"""The closed-loop FMUs (``dfwb build`` builds them with the plants and LinearSystem)."""
for _loop in LOOPS:  # importable by name (the FMUs' scripts do); never in place of a name of this module
    if _loop.__name__ in globals():
        raise ValueError(f"{__name__}: the FMU {_loop.__name__} would replace a name of the module")
    globals()[_loop.__name__] = _loop
