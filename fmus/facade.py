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

The compiled core: a facade with ``native_solver`` (the three plants here
and their closed loops in :mod:`.loop_facade`, not the naive twins nor
LinearSystem) runs on the C port of its solver (:mod:`.native_core`) when
its FMU carries it, as
``resources/libdfwb_core.so`` (the builder puts it there). At
exitInitializationMode the facade opens that library (once per process and
path) and makes the C solver with the Python solver's keywords: same
variables, same outputs bit for bit, same refusals. The pure-Python solver
stays the oracle and the fallback: if the core cannot be used (missing,
another ABI, a load error) the FMU logs one warning naming the reason and
runs on Python. The environment variable ``DFWB_FMU_SOLVER`` decides when
set: ``python`` forces the pure-Python solver, ``native`` makes a core that
cannot be used an error; any other value is refused at exitInitializationMode.
"""

import cmath
import math
import os

from pythonfmu import DefaultExperiment, Fmi2Slave, Integer, Real
from pythonfmu.enums import Fmi2Causality, Fmi2Status, Fmi2Variability

from . import native_core as _native_core
from . import plants as _plants
from . import state as _state
from . import table as _table
from .contract import EventKind
from .exact import PHASE_LIMIT, Drive, Motion
from .integrated import Trajectory
from .linear_system import MAX_ORDER as _MAX_ORDER
from .linear_system import LinearSystem as _LinearSystem
from .piecewise import SEARCH_CLASSES, PlantError, check

MAX_HARMONIC = 10
STATE_BASE_CLASSES = (Drive, Motion, Trajectory, EventKind) + SEARCH_CLASSES
ERROR_OUTPUT = "I_error"  # an integrated plant's bound on its Fourier integrals' error (PlantTable.integrated)
"""Classes any solver's state may hold (with the solver's own classes): what a serialized state may name."""
EXCITATION = tuple((p.name, p.default, p.unit, p.description) for p in _table.EXCITATION)


NATIVE_CORE_FILE = "libdfwb_core.so"
"""The compiled core in the resources folder of an FMU whose facade has ``native_solver``."""
SOLVER_VARIABLE = "DFWB_FMU_SOLVER"
SOLVER_CHOICES = ("native", "python")
"""Values of ``DFWB_FMU_SOLVER`` (unset or empty: the compiled core if it can be used, else Python)."""
_CORES = {}
"""{core file: (NativeCore, None) or (None, why it cannot be used)}: each core is opened once per process."""


def core_in(resources):
    """(NativeCore, None) for the compiled core in an FMU's resources folder, or (None, why it cannot be used)."""
    if not resources:
        return None, "no resources folder (the facade does not run inside an FMU)"
    folder = str(resources)
    path = os.path.join(folder[len("file://"):] if folder.startswith("file://") else folder, NATIVE_CORE_FILE)
    known = _CORES.get(path)
    if known is None:
        if not os.path.isfile(path):
            known = (None, f"the FMU has no compiled core (no resources/{NATIVE_CORE_FILE})")
        else:
            try:
                known = (_native_core.load(path), None)
            except _native_core.CoreError as error:  # a library that does not load, another ABI
                known = (None, str(error))
            except Exception as error:  # noqa: BLE001 - whatever else stops the core is a reason too
                known = (None, f"cannot load the C core {path}: {type(error).__name__}: {error}")
        _CORES[path] = known
    return known


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
    """A refused call inside the FMU: caught by the callback's guard, logged as an error, never raised out."""


MAX_INPUT = 1e100
"""Largest magnitude of the input (N for the plants): beyond, a plant's motion can overflow a float within a step."""

INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, ERROR = (
    "instantiated", "initialization mode", "stepping", "terminated", "error")
PHASES = (INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED, ERROR)
PHASE_VR = 0x7FFFFFFF
"""A valueReference outside the model description: getInteger of it alone answers the phase's index in
PHASES (0 instantiated, 1 initialization mode, 2 stepping, 3 terminated, 4 error), for the FMU's C shim,
which must learn the phase a restored FMU state puts the instance in."""


def _guarded(call, fallback=None):
    """Wrap an Fmi2Slave callback: any exception becomes one logged error and a benign return.

    pythonfmu 0.7.0 treats an exception out of a callback as fatal and
    destroys the Python instance (later calls crash the host), so none ever
    leaves. ``fallback(self, *args)`` is what a refused call returns (getters:
    values of the right length; doStep: False).
    """

    def decorate(method):
        def guarded(self, *args):
            try:
                return method(self, *args)
            except Exception as error:  # noqa: BLE001 - every exception must become an FMI error
                message = str(error) if isinstance(error, (StepRefused, PlantError)) else \
                    f"{call} failed: {type(error).__name__}: {error}"
                self._refuse(call, message)
                return fallback(self, *args) if fallback else None

        guarded.__name__, guarded.__doc__ = method.__name__, method.__doc__
        return guarded

    return decorate


def _attribute(obj, dotted):
    """obj.a.b for "a.b" (a missing attribute: a private marker that equals nothing else)."""
    for name in dotted.split("."):
        obj = getattr(obj, name, _MISSING)
    return obj


_MISSING = object()


def _zeros(value):
    return lambda self, vrs, *rest: [value] * len(vrs)


class SolverFMU(Fmi2Slave):
    """What every dfwb FMU shares: metadata, errors through the FMI logger, a checked doStep, FMU state.

    FMI interface
    -------------
    * Time: ``fmi2SetupExperiment``'s start time t0 is honoured. The plant
      starts at t = t0 from its initial values (x0, v0, ...); the built-in
      excitation is ``F cos(omega t + phi)`` in absolute time t, and the
      Fourier outputs are ``I_k(t) = int_{t0}^{t} y(s) exp(-i k omega s) ds``
      (absolute phase; with t0 = 0 everything is as before, bit for bit).
      doStep's currentTime must be the FMU's absolute time.
    * Errors: no exception ever leaves a callback. A refused call logs one
      message with status error (naming the call and the value) and returns
      normally (doStep returns False, getters return values of the right
      length); the FMU is then in the Error state of the standard: only
      getters, fmi2SetFMUstate, fmi2Reset and fmi2FreeInstance make sense.
      Refused: a bad parameter (at exitInitializationMode), a fixed parameter
      set after initialisation (its value is kept), an input that is NaN,
      infinite or larger than MAX_INPUT, a step at the wrong time or of a bad
      length, doStep before initialisation or after terminate.
    * State: fmi2Get/Set/FreeFMUstate copy the solver exactly (time, pieces,
      Fourier integrals, event counters, modes) and the facade's values;
      fmi2SerializeFMUstate writes them as bytes that only this model of
      the same build accepts (see :mod:`.state`).
    * Solver: a facade with ``native_solver`` runs on the compiled core its FMU
      carries, else (one warning says why) on the pure-Python solver;
      ``DFWB_FMU_SOLVER=python`` forces Python, ``=native`` makes a missing
      core an error (see the module's docstring). A restored state keeps
      the kind of solver it holds (a serialized C solver is read back by
      this FMU's own core, which checks its bytes).

    A subclass creates ``self.solver`` at the end of initialisation; doStep
    hands it the input named ``input_name``, held over the step (``input_name``
    None: an FMU without input, a closed system the solver only advances).
    """

    input_name = "f"
    ranges = {}
    """{variable name: (min, max)} written into the model description (None: no bound on that side).

    Declarative only: the solvers' own checks decide what is accepted, with their messages
    (a bound that is strict, like M > 0, is written as min = 0 and said in the description)."""
    feedthrough = {}
    """{output name: dependenciesKind} of the outputs the input feeds directly (the others depend on no input)."""
    state_classes = ()
    """Extra classes a solver's state holds (beyond its own class, Drive, Motion and the searches)."""
    fixed_solver_attributes = ()
    """Solver attributes a run never changes (dotted: drive.F): a restored solver's must equal a new one's."""
    native_solver = None
    """The NativeCore attribute of the compiled twin of the solver ("FrictionMass"...), or None (Python only)."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "solver_class" in cls.__dict__ and "native_solver" not in cls.__dict__:
            cls.native_solver = None  # a subclass with a solver of its own (a naive twin) has no compiled twin

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.author = "dfwb"
        self.description = self.__class__.__doc__.strip().splitlines()[0]
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=10.0, step_size=0.01)
        self.solver = None
        self._phase = INSTANTIATED
        self._start_time = 0.0
        self._time = 0.0

    @classmethod
    def limits(cls):
        """{name: (min, max)} of the model description (:attr:`ranges`, the input's bound)."""
        return dict({name: (-MAX_INPUT, MAX_INPUT) for name in cls._input_names()}, **cls.ranges)

    @classmethod
    def _input_names(cls):
        """(input_name,), or () for an FMU without input."""
        return () if cls.input_name is None else (cls.input_name,)

    # -- errors ---------------------------------------------------------------
    def _refuse(self, call, message):
        """Log a refused call (status error) and enter the Error state."""
        self.log(f"{self.__class__.__name__}: {message}", status=Fmi2Status.error)
        self._phase = ERROR

    def _fail(self, message):
        raise StepRefused(message)

    def _expect(self, call, *phases):
        if self._phase not in phases:
            raise StepRefused(f"{call} is not allowed in the {self._phase} state"
                              + (" (after an error only getters, setFMUstate, reset and freeInstance)"
                                 if self._phase == ERROR else ""))

    # -- FMI callbacks ---------------------------------------------------------------
    @_guarded("setupExperiment")
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._expect("setupExperiment", INSTANTIATED)
        if not (isinstance(start_time, (int, float)) and math.isfinite(start_time)):
            self._fail(f"start time {start_time!r} refused: it must be a finite number")
        self._start_time = self._time = float(start_time)

    @_guarded("enterInitializationMode")
    def enter_initialization_mode(self):
        self._expect("enterInitializationMode", INSTANTIATED)
        self._phase = INITIALIZATION

    @_guarded("exitInitializationMode")
    def exit_initialization_mode(self):
        self._expect("exitInitializationMode", INITIALIZATION)
        for name in self._input_names():
            self._check_input(getattr(self, name))
        try:
            self.solver = self._make_solver()
        except PlantError as error:
            self._fail(f"invalid parameter: {error}")
        self._refresh()
        if not self._finite():
            self.solver = None
            self._fail("invalid parameters: the outputs at the start overflow a float (a force or a mass "
                       "out of scale)")
        self._phase = STEPPING

    @_guarded("doStep", fallback=lambda self, *args: False)
    def do_step(self, current_time, step_size):
        solver = self.solver
        if self._phase == TERMINATED:
            self._fail(f"doStep at t = {current_time!r} refused: the FMU is terminated")
        if solver is None or self._phase in (INSTANTIATED, INITIALIZATION):
            self._fail("doStep called before initialisation")
        self._expect("doStep", STEPPING)
        if not (math.isfinite(step_size) and step_size > 0.0):
            self._fail(f"communication step {step_size!r} at t = {current_time!r}: it must be > 0 and finite")
        now = self._time
        if not (abs(current_time - now) <= 1e-9 * max(1.0, abs(now))):  # NaN refused too
            self._fail(f"doStep at t = {current_time!r}, but the FMU is at t = {now!r}")
        end = max(current_time + step_size, now)
        try:
            if self.input_name is not None:
                solver.set_input(getattr(self, self.input_name))
            solver.advance(end - self._start_time)  # the solver's own time starts at 0
        except PlantError as error:
            self._broken()
            self._fail(f"step from t = {current_time!r} refused: {error}")
        self._time = end
        self._refresh()
        if not self._finite():
            self._broken()
            self._fail(f"step from t = {current_time!r} to {end!r} refused: the motion overflows a float "
                       f"(outputs are no longer finite)")
        return True

    @_guarded("terminate")
    def terminate(self):
        self._expect("terminate", STEPPING)
        self._phase = TERMINATED

    @_guarded("getReal", fallback=_zeros(0.0))
    def get_real(self, vrs):
        return self._get_real(vrs)

    @_guarded("getInteger", fallback=_zeros(0))
    def get_integer(self, vrs):
        if len(vrs) == 1 and vrs[0] == PHASE_VR:  # the host shim asks the phase (after fmi2SetFMUstate)
            return [PHASES.index(self._phase)]
        return self._get_integer(vrs)

    @_guarded("getBoolean", fallback=_zeros(False))
    def get_boolean(self, vrs):
        return super().get_boolean(vrs)

    @_guarded("getString", fallback=_zeros(""))
    def get_string(self, vrs):
        return super().get_string(vrs)

    @_guarded("setReal")
    def set_real(self, vrs, values):
        self._set_values("setReal", vrs, values, "Real")

    @_guarded("setInteger")
    def set_integer(self, vrs, values):
        self._set_values("setInteger", vrs, values, "Integer")

    @_guarded("setBoolean")
    def set_boolean(self, vrs, values):
        self._fail(f"valueReferences {list(vrs)!r}: this FMU has no Boolean variable")

    @_guarded("setString")
    def set_string(self, vrs, values):
        self._fail(f"valueReferences {list(vrs)!r}: this FMU has no String variable")

    # -- setting values ------------------------------------------------------------
    def _set_values(self, call, vrs, values, kind):
        names = self._names(vrs, kind)
        values = list(values)
        if len(values) != len(names):
            self._fail(f"{len(names)} valueReferences but {len(values)} values")
        if self._phase in (TERMINATED, ERROR):
            self._fail(f"{call} of {', '.join(names)} refused: not allowed in the {self._phase} state")
        for name, value in zip(names, values):
            if name == self.input_name:
                self._check_input(value)
            elif name not in self._parameter_names():
                self._fail(f"{call}: {name} is an output and cannot be set")
            elif self._phase == STEPPING:
                self._fail(f"{call} of {name} = {value!r} refused: {name} is a fixed parameter and cannot be set "
                           f"after initialisation ({name} stays {getattr(self, name)!r})")
        for name, value in zip(names, values):
            setattr(self, name, int(value) if kind == "Integer" else float(value))

    def _check_input(self, value):
        name = self.input_name
        if not (isinstance(value, (int, float)) and math.isfinite(value) and abs(value) <= MAX_INPUT):
            self._fail(f"at t = {self._time!r}: {name} = {value!r} is out of range: the input {name} must be "
                       f"a finite number of magnitude <= {MAX_INPUT:g}")

    # -- FMU state -------------------------------------------------------------------
    @classmethod
    def _state_table(cls):
        """{(module, qualname): class} of every class this FMU's state may hold (see :mod:`.state`)."""
        table = getattr(cls, "_state_table_cache", None)
        if table is None or table[0] is not cls:
            classes = set(STATE_BASE_CLASSES) | set(cls.state_classes)
            solver_class = getattr(cls, "solver_class", None) or _LinearSystem
            classes.update(klass for klass in solver_class.__mro__ if klass is not object)
            classes.update(getattr(solver_class, "STATE_CLASSES", ()))  # its own plain data (an integrated law)
            if cls.native_solver:  # a solver of the compiled core is serialized as its checked bytes
                classes.add(_state.NativeState)
            table = (cls, {(klass.__module__, klass.__qualname__): klass for klass in classes})
            cls._state_table_cache = table
        return table[1]

    @classmethod
    def _package(cls):
        return cls.__module__.rpartition(".")[0] or cls.__module__

    def _facade_values(self):
        values = {name: getattr(self, name) for name in self._parameter_names() + self._input_names()}
        values.update(_phase=self._phase, _start_time=self._start_time, _time=self._time)
        return values

    @_guarded("getFMUstate", fallback=lambda self: _state.RefusedState("the state could not be taken"))
    def _get_fmu_state(self):
        self._expect("getFMUstate", INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED)
        solver = None if self.solver is None else _state.copy_solver(self.solver)
        return _state.FMUState(type(self).__name__, self._package(), self._facade_values(), solver)

    @_guarded("setFMUstate")
    def _set_fmu_state(self, state):
        if isinstance(state, _state.RefusedState):
            self._fail(f"the state was refused when it was deserialized: {state.refused}")
        model, package = getattr(state, "model", None), getattr(state, "package", None)
        if not (isinstance(state, _state.FMUState) or type(state).__name__ == "FMUState"
                and type(model) is str and type(package) is str):  # another build's FMUState: named below
            self._fail(f"{type(state).__name__} is not a state of this FMU")
        if not isinstance(state, _state.FMUState) or model != type(self).__name__ or package != self._package():
            self._fail(f"the state is one of {package}.{model}, not of this FMU "
                       f"({self._package()}.{type(self).__name__})")
        values = state.values
        expected = set(self._facade_values())
        if set(values) != expected:
            self._fail("the state's facade values do not match this FMU's variables")
        solver = state.solver
        solver_class = self._solver_type()
        stored = isinstance(solver, _state.NativeState)
        if not (solver is None or type(solver) is solver_class or stored or self._is_native(solver)):
            self._fail(f"the state's solver is a {type(solver).__name__}, not a {solver_class.__name__}")
        phase = values["_phase"]
        if phase not in (INSTANTIATED, INITIALIZATION, STEPPING, TERMINATED) or \
                (solver is None) != (phase in (INSTANTIATED, INITIALIZATION)):
            self._fail("the state's phase does not match its solver")
        for name in self._parameter_names() + self._input_names():
            if type(values[name]) is not type(getattr(self, name)):
                self._fail(f"the state's {name} is a {type(values[name]).__name__}")
        for name in ("_start_time", "_time"):
            if not (type(values[name]) is float and math.isfinite(values[name])):
                self._fail(f"the state's {name} is not a finite float")
        if stored:
            solver = self._native_from(solver)
        if solver is not None:
            self._check_solver_state(values, solver)
        self.solver = None if solver is None else solver if stored else _state.copy_solver(solver)
        for name, value in values.items():
            if not name.startswith("_"):
                setattr(self, name, value)
        self._start_time, self._time = values["_start_time"], values["_time"]
        self._phase = phase
        self._restored()

    def _check_solver_state(self, values, solver):
        """StepRefused unless a restored solver is one these parameter values and this time can produce.

        Well-typed is not enough: a crafted solver with 10**9 harmonics, an order of 10**6 or a time
        of -1e308 would make the next step or getter run for hours or exhaust memory. A new solver is
        made from the state's parameters (their own checks apply) and the solver's
        ``fixed_solver_attributes`` must equal its, exactly; its time must be the state's time.
        A solver of the compiled core is compared with a new one on its core (``same_parameters``:
        its fixed parameters bit for bit); the core checked its piece times when it read them.
        """
        native = self._is_native(solver)
        try:
            fresh = self._solver_from(values, solver if self.native_solver else None)
        except PlantError as error:
            self._fail(f"the state's parameters are refused: {error}")
        if native:
            if not fresh.same_parameters(solver):
                self._fail("the state's solver does not match its parameters")
        else:
            for name in self.fixed_solver_attributes:
                mine, theirs = _attribute(fresh, name), _attribute(solver, name)
                if type(mine) is not type(theirs) or mine != theirs:
                    self._fail(f"the state's solver does not match its parameters ({name})")
        t = getattr(solver, "t", None)
        if not (type(t) is float and t == values["_time"] - values["_start_time"]):
            self._fail("the state's solver time does not match the state's time")
        if not native:
            self._check_solver_times(solver)

    def _solver_from(self, values, like=None):
        """A new solver from a state's parameter values (this instance's own values are kept);
        ``like``: a solver whose kind (Python, or the compiled core it runs on) the new one takes."""
        names = [name for name in values if not name.startswith("_")]
        saved = {name: getattr(self, name) for name in names}
        saved_start, saved_rotation = self._start_time, getattr(self, "_rotation", None)
        try:
            for name in names:
                setattr(self, name, values[name])
            self._start_time = values["_start_time"]
            return self._make_solver() if like is None else self._make_solver(like=like)
        finally:
            for name, value in saved.items():
                setattr(self, name, value)
            self._start_time = saved_start
            if hasattr(self, "_rotation"):
                self._rotation = saved_rotation

    def _check_solver_times(self, solver):
        """Further checks of a restored solver (a subclass's); StepRefused if one fails."""

    def _restored(self):
        """Recompute what the facade derives from the solver after a state is set."""
        if self.solver is not None:
            self._refresh()

    @classmethod
    def _native_base(cls):
        """The native_core class of this facade's compiled solver (NativeFrictionMass...), or None."""
        return getattr(_native_core, "Native" + cls.native_solver, None) if cls.native_solver else None

    @classmethod
    def _is_native(cls, solver):
        """Whether ``solver`` is this facade's compiled solver, bound to a loaded core."""
        if type(solver) is cls._solver_class() or not cls.native_solver:
            return False
        base = cls._native_base()
        return base is not None and isinstance(solver, base) and getattr(type(solver), "core", None) is not None

    @classmethod
    def _solver_class(cls):
        return getattr(cls, "solver_class", None) or _LinearSystem

    def _new_solver_class(self, like=None):
        """The class a facade with ``native_solver`` makes its solver of (with the Python solver's keywords):
        the compiled twin on the core :meth:`_solver_core` chooses, or the pure-Python ``solver_class``.
        ``like``: a solver whose kind (the core it runs on, or Python) the new one takes; nothing is logged."""
        if like is None:
            core = self._solver_core()
        else:
            core = type(like).core if self._is_native(like) else None
        return self._solver_class() if core is None else getattr(core, self.native_solver)

    def _solver_core(self):
        """The NativeCore this run's solver is made on, or None for the pure-Python solver; the choice is logged
        (status ok; a warning when the core cannot be used), StepRefused for a bad ``DFWB_FMU_SOLVER``."""
        if not self.native_solver:
            return None
        choice = os.environ.get(SOLVER_VARIABLE, "")
        if choice and choice not in SOLVER_CHOICES:
            self._fail(f"{SOLVER_VARIABLE} = {choice!r} is refused: it must be 'native' (the compiled core; an error "
                       f"if it cannot be used) or 'python' (the pure-Python solver), or unset")
        name = type(self).__name__
        if choice == "python":
            self.log(f"{name}: runs on the pure-Python solver ({SOLVER_VARIABLE}=python)")
            return None
        core, why = core_in(self.resources)
        if core is None:
            if choice == "native":
                self._fail(f"{SOLVER_VARIABLE}=native, but the compiled core cannot be used: {why}")
            if not self.resources:  # the facade used directly in Python, not an FMU: nothing to warn about
                self.log(f"{name}: runs on the pure-Python solver ({why})")
            else:
                self.log(f"{name}: the compiled core cannot be used ({why}); it runs on the pure-Python solver",
                         status=Fmi2Status.warning)
            return None
        self.log(f"{name}: runs on the compiled core ({core.path})")
        return core

    def _native_from(self, stored):
        """The solver of a serialized :class:`~.state.NativeState`, read by this FMU's own core (StepRefused)."""
        if not (type(stored.plant) is str and type(stored.data) is bytes):
            self._fail("the state's native solver is damaged (it must hold a plant name and bytes)")
        if not self.native_solver or stored.plant != self.native_solver:
            self._fail(f"the state's solver is a compiled {stored.plant[:64]!r}, not a "
                       f"{self.native_solver or self._solver_type().__name__}")
        core, why = core_in(self.resources)
        if core is None:
            self._fail(f"the state holds a solver of the compiled core, which this instance cannot use: {why}")
        try:
            return getattr(core, self.native_solver).from_bytes(stored.data)
        except _state.StateRefused as error:
            self._fail(f"the state was refused when it was deserialized: serialized state refused: {error}")

    @classmethod
    def _fmu_state_to_bytes(cls, state):
        try:
            if isinstance(state, _state.RefusedState):
                return _state.MAGIC + b"refused: " + state.refused.encode("utf-8", "replace")
            if isinstance(state, _state.FMUState) and state.solver is not None and cls._is_native(state.solver):
                state = _state.FMUState(state.model, state.package, state.values,
                                        _state.NativeState(cls.native_solver, state.solver.to_bytes()))
            return _state.encode(state, cls._state_table())
        except Exception as error:  # noqa: BLE001 - never out of a callback: bytes that deserialize as refused
            return _state.MAGIC + f"refused: the state could not be serialized ({error})".encode("utf-8", "replace")

    @classmethod
    def _fmu_state_from_bytes(cls, data):
        try:
            return _state.decode(data, cls.__name__, cls._package(), cls._state_table())
        except _state.StateRefused as error:
            return _state.RefusedState(f"serialized state refused: {error}")
        except Exception as error:  # noqa: BLE001
            return _state.RefusedState(f"serialized state refused: {type(error).__name__}: {error}")

    # -- hooks ---------------------------------------------------------------------
    def _solver_type(self):
        return self.solver_class

    def _make_solver(self):
        """The solver from the parameters (PlantError names a bad one). A facade with ``native_solver`` takes
        ``like=None`` too and picks its class with :meth:`_new_solver_class`."""
        raise NotImplementedError

    def _parameter_names(self):
        """Names of the parameters (fixed: settable only before exitInitializationMode)."""
        raise NotImplementedError

    def _names(self, vrs, kind):
        raise NotImplementedError

    def _get_real(self, vrs):
        return Fmi2Slave.get_real(self, vrs)

    def _get_integer(self, vrs):
        return Fmi2Slave.get_integer(self, vrs)

    def _broken(self):
        """A step failed half-way: keep the outputs of the last good point."""

    def _finite(self):
        """Whether the outputs after a step are finite."""
        return True

    def _refresh(self):
        """Update cached outputs after a step (nothing to cache by default)."""


class TableFMU(SolverFMU):
    """An FMU whose variables are a per-class table, :meth:`layout`, served by get_/set_real and get_/set_integer.

    fmi2Reset creates a new instance, so instances are cheap: pythonfmu's
    variable objects are made only when a model description is written.
    Subclasses give :meth:`layout` and :meth:`_value` (an output's value).
    """

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls._layout = cls.layout()
        cls._settable = frozenset(name for name, _kind, causality, *_ in cls._layout if causality != "output")
        cls._parameters = tuple(name for name, _kind, causality, *_ in cls._layout if causality == "parameter")

    @classmethod
    def layout(cls):
        """[(name, 'Real' or 'Integer', causality, variability, description)] in value-reference order."""
        raise NotImplementedError

    def to_xml(self, model_options=dict()):
        if not self.vars:
            for name, kind, causality, variability, description in self.layout():
                self.register_variable((Integer if kind == "Integer" else Real)(
                    name, causality=Fmi2Causality[causality], variability=Fmi2Variability[variability],
                    description=description, getter=lambda name=name: self._value(name)))
        return super().to_xml(model_options)

    def _value(self, name):
        raise NotImplementedError

    def _names(self, vrs, kind):
        table = self._layout
        names = []
        for vr in vrs:
            if not 0 <= vr < len(table) or table[vr][1] != kind:
                raise TypeError(f"Variable with valueReference={vr} is not of type {kind}!")
            names.append(table[vr][0])
        return names

    def _get_real(self, vrs):
        return [float(self._value(name)) for name in self._names(vrs, "Real")]

    def _get_integer(self, vrs):
        return [int(self._value(name)) for name in self._names(vrs, "Integer")]

    def _parameter_names(self):
        return self._parameters


class PlantFMU(TableFMU):
    """Common facade: parameters, the input f, outputs and Fourier integrals."""

    solver_class = None
    table = None
    """The plant's :class:`~.table.PlantTable`: ``parameters``, ``ranges``, ``outputs``, ``feedthrough`` and
    ``output_signal`` are read from it, and the outputs' values from the solver (None: all declared here)."""
    parameters = ()  # (name, default, unit, description)
    outputs = ()  # (name, unit, description, is_integer)
    output_signal = ("x", "m")  # the signal whose Fourier integrals are exposed
    fixed_solver_attributes = ("period", "harmonics", "event_log", "drive.F", "drive.omega", "drive.phi")
    piecewise_solver = True  # a PiecewisePlant: its piece start and searched time are checked too
    loop = None
    """The plant's exact closed loop (a :class:`~.loops.FeedbackLoop`), or None."""

    def __init_subclass__(cls, **kwargs):
        table = cls.__dict__.get("table")
        if table is not None:  # first: TableFMU lays the variables out from them
            cls.parameters, cls.ranges = table.fmu_parameters(), table.bounds()
            if table.outputs:
                cls.outputs, cls.feedthrough = table.fmu_outputs(), table.feedthrough()
                cls.output_signal = table.fmu_signal()
        super().__init_subclass__(**kwargs)
        if cls.solver_class is not None:
            FACADES.append(cls)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._values = {}
        self._overflow = False
        self._fourier = None
        self._rotation = None
        self._frozen = False
        for name, default, *_ in self.parameters + EXCITATION:
            setattr(self, name, float(default))
        self.harmonics = MAX_HARMONIC
        self.f = 0.0

    # -- variables -------------------------------------------------------------
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

    def _value(self, name):
        if name in self._settable:
            return getattr(self, name)
        if name[:2] in ("Ic", "Is"):
            if self._fourier is None and self.solver is not None:
                fourier = self._integrals()
                if not all(math.isfinite(value) for value in fourier.values()):
                    self._fail(f"the Fourier integrals at t = {self._time!r} overflow a float")
                self._fourier = fourier
            return (self._fourier or {}).get(name, 0.0)
        return self._values.get(name, 0)

    # -- declarations used by the builder ------------------------------------
    @classmethod
    def all_outputs(cls):
        signal, unit = cls.output_signal
        fourier = []
        for k in range(MAX_HARMONIC + 1):
            for part, wave in (("c", "cos"), ("s", "sin")):
                fourier.append((f"I{part}{k}", f"{unit}.s",
                                f"running integral of {signal}(t) {wave}({k} omega t) dt from the start time "
                                f"(absolute phase)", False))
        events = ("events", None, "number of events (mode changes, impacts) so far", True)
        table = getattr(cls, "table", None)
        error = ()
        if table is not None and table.integrated:
            error = ((ERROR_OUTPUT, f"{unit}.s", f"a bound on the error of every running Fourier integral of "
                                                 f"{signal} (its integrated modes' tolerance)", False),)
        return tuple(cls.outputs) + (events,) + tuple(fourier) + error

    @classmethod
    def units(cls):
        """Unit of every Real variable that has one."""
        table = {name: unit for name, _d, unit, _desc in cls.parameters + EXCITATION if unit}
        table["f"] = "N"
        table.update({name: unit for name, unit, _d, is_int in cls.all_outputs() if unit and not is_int})
        return table

    @classmethod
    def limits(cls):
        """{name: (min, max)}: the class's ``ranges`` plus the excitation's, harmonics' and the input's."""
        table = {"omega": (0.0, None), "phi": (-PHASE_LIMIT, PHASE_LIMIT), "harmonics": (0, MAX_HARMONIC),
                 "f": (-MAX_INPUT, MAX_INPUT)}
        table.update(cls.ranges)
        return table

    # -- FMI ------------------------------------------------------------------
    def _make_solver(self, like=None):
        """The solver from the parameters (PlantError names a bad one), on the compiled core or in Python as
        :meth:`_new_solver_class` chooses; ``like``: a solver whose kind the new one takes (nothing logged)."""
        kwargs = {name: getattr(self, name) for name, *_ in self.parameters + EXCITATION}
        t0 = self._start_time
        if t0 != 0.0:  # the solver's time starts at 0: F cos(omega t + phi) = F cos(omega (t - t0) + phi')
            kwargs["phi"] = kwargs["phi"] + kwargs["omega"] * t0
        self._rotation = None
        solver_class = self._new_solver_class(like)
        solver = solver_class(f=self.f, harmonics=self.harmonics, **self.solver_kwargs(kwargs))
        if t0 != 0.0:  # I_k from t0 in absolute phase: exp(-i k omega t0) times the solver's own
            self._rotation = [cmath.exp(-1j * k * self.omega * t0) for k in range(solver.harmonics + 1)]
        return solver

    def _integrals(self):
        """{Ick, Isk: value} from the solver's running integrals (rotated to absolute phase)."""
        fourier = {}
        integrals = self.solver.integrals()
        if self._rotation is not None:
            integrals = [value * rot for value, rot in zip(integrals, self._rotation)]
        for k, integral in enumerate(integrals):
            fourier[f"Ic{k}"] = integral.real
            fourier[f"Is{k}"] = -integral.imag
        return fourier

    def _restored(self):
        self._frozen = False
        self._rotation = None
        if self.solver is None:  # a state from before initialisation: outputs as a reset instance's
            self._values, self._fourier = {}, None
        t0 = self._start_time
        if self.solver is not None and t0 != 0.0:
            self._rotation = [cmath.exp(-1j * k * self.omega * t0) for k in range(self.solver.harmonics + 1)]
        super()._restored()

    def _check_solver_times(self, solver):
        # what bounds a step's work: the integrals' length, the piece's start and the searched time
        integrals, t = getattr(solver, "_integrals", None), solver.t
        t_piece, searched = getattr(solver, "_t_piece", None), getattr(solver, "_searched", None)
        if not (type(integrals) is list and len(integrals) == solver.harmonics + 1):
            self._fail("the state's Fourier integrals do not match its harmonics")
        if not self.piecewise_solver:  # a fixed-step twin (naive_facade): its t and dt bound a step's work
            return
        if not (type(t_piece) is float and type(searched) is float
                and 0.0 <= t_piece <= t and t_piece <= searched <= t + solver.period):
            self._fail("the state's piece times do not match its time")

    def _broken(self):
        # the solver stopped half-way: outputs stay at the last good point; the integrals too, if known
        if self._fourier is None:
            self._fourier = {}
        self._frozen = True  # the Error state, until a state is set (or the instance reset)

    def _finite(self):
        return not self._overflow

    @classmethod
    def solver_kwargs(cls, kwargs):
        """The solver's keyword arguments from the FMU's parameter values (a table's parameter whose FMU start
        value stands for a default that is not a number, gap0 = -1 for h/2, is given that default)."""
        for parameter in cls.table.parameters if cls.table is not None else ():
            if parameter.start is not None and kwargs.get(parameter.name) == parameter.start:
                kwargs[parameter.name] = parameter.default
        return kwargs

    def _refresh(self):
        if getattr(self, "_frozen", False):
            return
        new = dict(zip((name for name, *_ in self.outputs), self.output_values()))
        new["events"] = self.solver.events
        if self.table is not None and self.table.integrated:
            new[ERROR_OUTPUT] = self.solver.integrals_error()
        self._overflow = not all(math.isfinite(value) for value in new.values())
        if self._overflow:
            return  # never NaN: the outputs stay those of the last good point (none yet at the start: zeros)
        self._values.update(new)
        self._fourier = None

    def output_values(self):
        """The values of ``outputs``, in order: the solver's ``output()``, then its counters (a table's)."""
        if self.table is None:
            raise NotImplementedError
        return tuple(self.solver.output()) + tuple(getattr(self.solver, name) for name in self.table.counters)


def plant_facade(module):
    """The FMU facade of a plant's model module (:mod:`.plants`): its ``TABLE`` gives the variables, the name
    (``table.model``) and the description, its ``SOLVER`` the solver, which runs on its compiled twin when the
    FMU carries the core."""
    table, solver = module.TABLE, module.SOLVER
    summary = table.summary[:1].upper() + table.summary[1:]
    return type(table.model, (PlantFMU,), {
        "__doc__": f"{summary}, force input f.", "__module__": __name__, "solver_class": solver,
        "native_solver": table.model, "table": table, "loop": module.LOOP,
        "fixed_solver_attributes": PlantFMU.fixed_solver_attributes + solver.FIXED})


PLANTS = tuple(plant_facade(module) for module in _plants.MODULES)
"""The facades of dfwb's plants (FrictionMass, TwoMassBacklash, StaticBacklash, ...), one per model module."""
for _facade in PLANTS:  # importable by name (the FMUs' scripts do); never in place of a name of this module
    if _facade.__name__ in globals():
        raise ValueError(f"{__name__}: the FMU {_facade.__name__} would replace a name of the module")
    globals()[_facade.__name__] = _facade


class LinearSystem(SolverFMU):
    """Linear transfer function G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an), exact for a held input u."""

    input_name = "u"
    ranges = {"order": (1, _MAX_ORDER)}
    fixed_solver_attributes = ("order", "b", "a", "D", "C")
    feedthrough = {"y": "fixed"}  # y = C x + D u, D = b0 a fixed parameter

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

    def _solver_type(self):
        return _LinearSystem

    def _check_solver_times(self, solver):
        x = getattr(solver, "x", None)
        if not (type(x) is list and len(x) == solver.order):
            self._fail("the state's solver state vector does not match its order")

    def _parameter_names(self):
        return tuple(var.name for var in self.vars.values() if var.causality == Fmi2Causality.parameter)

    def _names(self, vrs, kind):
        names = []
        for vr in vrs:
            var = self.vars.get(vr)
            if var is None or type(var).__name__ != kind:
                raise TypeError(f"Variable with valueReference={vr} is not of type {kind}!")
            names.append(var.name)
        return names


PRODUCTION = PLANTS + (LinearSystem,)
"""The FMUs dfwb ships: the plants and the linear controller (what ``dfwb build`` builds)."""

FACADES.append(LinearSystem)
