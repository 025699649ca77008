"""The exact plant solvers in C (``fmus/native``), loaded with ctypes.

The C core ports :class:`~.friction.FrictionMass`, :class:`~.backlash.TwoMassBacklash` and
:class:`~.static_backlash.StaticBacklash` (with :mod:`.exact` and :mod:`.piecewise`), which stay the
oracles: same algorithms, same bounds, same operation order, so both agree to rounding - in practice bit
for bit (``tests/test_native_core.py`` and ``tests/test_native_backlash.py`` hold them to it). This module
is its binding: :func:`load` opens a compiled library (``dfwb.build_fmus.core.build_core`` makes one) and
:class:`NativeFrictionMass`, :class:`NativeTwoMassBacklash` and :class:`NativeStaticBacklash` implement
the :class:`~.contract.Solver` protocol on it, each with the constructor of its Python twin (same
keywords, same defaults) and its output named tuple::

    core = load(build_core(folder))
    plant = core.TwoMassBacklash(F=50.0, omega=20.0)   # or NativeTwoMassBacklash(..., core=core)
    plant.advance(6.28)
    x1, v1, x2, v2, gap = plant.output()
    plant.contact, plant.impacts                         # StaticBacklash: plant.engaged

The closed loops of :mod:`.loops` run on the core too (``dfwb_loop_*``, a port of :mod:`.loops` and
:mod:`.hybrid`): ``core.FrictionLoop``, ``core.BacklashLoop`` and ``core.StaticBacklashLoop`` take the
Python classes' keywords and defaults (``b, a, ..., z0, state, section, modes, budget``) and have their
attributes and methods (``t``, ``events``, ``key``, ``crossings``, ``event_log``, ``order``, ``Ac``, ``Bc``,
``C``, ``D``, the plant's constants and counter, ``advance(t_end, stop_at_section)``, ``state()``,
``output()``, ``force(X)``, ``counts()``, ``translate``, ``coordinates_of``), bit for bit
(``tests/test_native_loop.py``). ``modes`` (a dict shared by the loops of one study, here of
:data:`NativeMode`) and ``budget`` (a :class:`~.hybrid.Budget`) are shared as in Python; ``plant`` is the
open-loop solver on the same core. Not shared with the Python loops: a ``modes`` dict holds one kind.
``compensation`` takes the Python loop's compensators (:mod:`.compensation`): the Coulomb feedforward of the
velocity, the integrator reset, the deadband and the dither run in C, bit for bit
(``tests/test_native_compensation.py``;
the deadband's side keys the modes as in Python, and ``band`` reads it); the feedforward of the controller's
sign is refused in one line (the Python loop runs it). ``readings(times)`` gives the states and the forces on
the plant at many times in one call. Beyond Python: ``to_bytes()`` / ``from_bytes(data)`` (the loop's state,
checked as a plant's is; not in it: the crossings and the event log), ``same_parameters(other)``, ``copy()``,
pickling.

A value the C core refuses raises :class:`~.exact.PlantError` with the C message, which is the Python
solver's text (a non-float value, e.g. an int or None, is named as Python writes it). A power or a
modulus that overflows raises OverflowError, as in Python.

``event_log``: None, or a list; set to a list, every counted event of a step is appended to it as
``(t, EventKind)``, as the Python solvers do (recorded in C, moved to the list after each step; beyond
:data:`LOG_CAPACITY` events in one step the rest are counted in ``event_log_dropped`` and a
RuntimeWarning is issued).

State: :meth:`~_Native.to_bytes` gives the solver's state as bytes (a header - magic, ABI, plant
kind, length, CRC-32 - then the plain data) and the classmethod ``from_bytes(data)`` makes a solver from
them; the C core checks everything it reads and refuses anything else with
:class:`~.state.StateRefused` (one line). ``copy()``, :func:`copy.copy` and :func:`copy.deepcopy` give
an independent exact copy; :mod:`pickle` works through the state bytes (the unpickling process loads the
library from the same path). ``a.same_parameters(b)``: whether two solvers of one plant on one core hold
bit-identical fixed parameters (what a run never changes: not the input f, the time nor the motion), as
an importer restoring a state checks it against a solver made anew from the state's parameters.

Plain Python (stdlib ``ctypes``) only.
"""

import copy
import ctypes
import inspect
import warnings
from collections import namedtuple
from pathlib import Path

from .compensation import BacklashInverse, Coulomb, Dither, compensators, dither_of, follows_control, inverse_of
from .contract import EventKind
from .exact import DfwbError, Diverged, Drive, PlantError
from .plants import KINDS, MODULES, c_name
from .state import StateRefused

__all__ = ["load", "NativeCore", "SOLVERS", "LOOPS", "CoreError", "ABI", "LOG_CAPACITY", "EVENT_KINDS",
           "NativeMode"]  # and each plant's classes by name: NativeFrictionMass, NativeFrictionLoop, ...

ABI = 11  # DFWB_CORE_ABI of dfwb_core.h this binding speaks
ERRLEN = 1024
LOOP_KEYS = 9  # the mode keys a loop may have (DFWB_HY_KEYS); slot s of its modes is key s % 9 at deadband side s // 9
SIDES = (1, 0, -1)  # the integrator deadband's side of each variant of the modes (FeedbackLoop.band)
LOOP_CONSTANTS = 9  # what dfwb_loop_parameters writes (DFWB_LOOP_PAR): a plant's loop holds at most these
LOG_CAPACITY = 1 << 20  # events one step may record (16 bytes each in C, allocated as they come)

# status codes of dfwb_core.h
OK, E_VALUE, E_LIMIT, E_MATH, E_MEMORY, E_ARGUMENT, E_STATE, E_DIVERGED = range(8)

# DFWB_EVENT_* -> EventKind (0: none)
EVENT_KINDS = (None, EventKind.BREAK_UP, EventKind.BREAK_DOWN, EventKind.RELEASE, EventKind.EDGE, EventKind.BAND,
               EventKind.WALL_LOWER, EventKind.WALL_UPPER, EventKind.APEX, EventKind.ENGAGE_UP,
               EventKind.ENGAGE_DOWN, EventKind.REVERSE, EventKind.COULOMB, EventKind.DEADBAND)

# plant -> (DFWB_PLANT_*, NativeCore attribute, its table: the C order of its parameters, outputs and counters)
_PLANTS = {c_name(m.TABLE): (KINDS[m.TABLE.name], m.TABLE.model, m.TABLE) for m in MODULES}


class CoreError(DfwbError, RuntimeError):
    """The C core cannot be used: a library that does not load, another ABI, no core given."""


_LOADED = {}  # resolved path -> NativeCore: a library is opened once per process


def load(path):
    """The :class:`NativeCore` of the compiled library at ``path`` (opened once per process)."""
    path = Path(path).resolve()
    core = _LOADED.get(path)
    if core is None:
        core = _LOADED[path] = NativeCore(path)
    return core


def _signatures():
    """The C signatures a plant's functions and the loop's share (the same names after the prefix)."""
    c_int, c_void_p, c_char_p, c_size_t = ctypes.c_int, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t
    return {
        "time": (ctypes.c_double, [c_void_p]),
        "events": (ctypes.c_longlong, [c_void_p]),
        "same_parameters": (c_int, [c_void_p, c_void_p]),
        "copy": (c_void_p, [c_void_p]),
        "free": (None, [c_void_p]),
        "log": (None, [c_void_p, c_size_t]),
        "log_read": (c_size_t, [c_void_p, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(c_int), c_size_t]),
        "log_dropped": (ctypes.c_ulonglong, [c_void_p]),
        "to_bytes": (c_int, [c_void_p, c_char_p, c_size_t, ctypes.POINTER(c_size_t), c_char_p, c_size_t]),
    }


class _Functions:
    """The C functions of one prefix (``new``, ``advance``, ... without it), typed: a core missing one is refused
    when loaded, not at the first call."""

    def __init__(self, lib, prefix, path, table):
        self.prefix = prefix
        for name, (restype, argtypes) in {**_signatures(), **table}.items():
            try:
                function = getattr(lib, f"{prefix}_{name}")
            except AttributeError:
                raise CoreError(f"the C core {path} has no function {prefix}_{name}") from None
            function.restype, function.argtypes = restype, argtypes
            setattr(self, name, function)


class _PlantApi(_Functions):
    """The plants' C functions (``dfwb_plant_*``: one API, the instance knows its kind), and each kind's state
    size; a core whose plants have other parameters, outputs or counters than this binding's is refused."""

    def __init__(self, lib, path):
        c_double, c_int, c_void_p, c_char_p, c_size_t = (ctypes.c_double, ctypes.c_int, ctypes.c_void_p,
                                                         ctypes.c_char_p, ctypes.c_size_t)
        p_double, p_size = ctypes.POINTER(c_double), ctypes.POINTER(c_size_t)
        table = {
            "new": (c_int, [c_int, p_double, c_size_t, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
            "shape": (c_int, [c_int, p_size, p_size, p_size]),
            "state_size": (c_size_t, [c_int]),
            "set_input": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "advance": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "output": (None, [c_void_p, p_double]),
            "integrals": (c_int, [c_void_p, p_double, p_double, c_char_p, c_size_t]),
            "integrals_error": (c_double, [c_void_p]),
            "harmonics": (c_int, [c_void_p]),
            "period": (c_double, [c_void_p]),
            "drive": (None, [c_void_p, p_double]),
            "counter": (ctypes.c_longlong, [c_void_p, c_size_t]),
            "from_bytes": (c_int, [c_int, c_char_p, c_size_t, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
        }
        super().__init__(lib, "dfwb_plant", path, table)
        self.state_sizes = {}
        for plant, (kind, _attr, plant_table) in _PLANTS.items():
            shape = [c_size_t() for _ in range(3)]
            if self.shape(kind, *map(ctypes.byref, shape)) != OK:
                raise CoreError(f"the C core {path} has no plant of kind {kind} ({plant}): rebuild it")
            expected = (len(plant_table.core_order), len(plant_table.solver_outputs), len(plant_table.counters))
            if tuple(n.value for n in shape) != expected:
                raise CoreError(f"the C core {path}'s {plant} has (parameters, outputs, counters) = "
                                f"{tuple(n.value for n in shape)}, this binding's {expected}: rebuild it")
            self.state_sizes[kind] = self.state_size(kind)


class NativeCore:
    """An opened C core: its ctypes functions and the solver classes bound to it, each plant's under its
    model's name (``FrictionMass``, ``TwoMassBacklash``, ``StaticBacklash``) and its closed loop's under the
    Python loop's (``FrictionLoop``, ``BacklashLoop``, ``StaticBacklashLoop``)."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            lib = ctypes.CDLL(str(self.path))
        except OSError as error:
            raise CoreError(f"cannot load the C core {self.path}: {error}") from None
        try:
            abi_version = lib.dfwb_core_abi_version
        except AttributeError:
            raise CoreError(f"the C core {self.path} has no function dfwb_core_abi_version") from None
        abi_version.restype, abi_version.argtypes = ctypes.c_int, []
        abi = abi_version()
        if abi != ABI:
            raise CoreError(f"the C core {self.path} speaks ABI {abi}, this binding {ABI}: rebuild it")
        self.lib = lib
        self.api = _PlantApi(lib, self.path)
        for cls in SOLVERS:
            attr = _PLANTS[cls._plant][1]
            setattr(self, attr, type(cls.__name__, (cls,), {"core": self, "__module__": __name__}))
        self.loop_api = _LoopApi(lib, self.path)
        for cls in LOOPS:
            _kind, attr, _python, _names = _LOOPS[cls._plant]
            plant = getattr(self, _PLANTS[cls._plant][1])  # the open-loop solver on this core (a shooting's start)
            setattr(self, attr, type(cls.__name__, (cls,), {"core": self, "plant": plant, "__module__": __name__}))

    def __repr__(self):
        return f"NativeCore({str(self.path)!r})"


def _as_double(value):
    """What the C core receives for a value: the float of a number (as PiecewisePlant's ``check``
    accepts them: int or float, not bool), NaN for anything else (refused, then named as Python writes it)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:  # an int beyond the floats
            return float("inf") if value > 0 else float("-inf")
    return float("nan")


def _c_repr(value):
    return repr(_as_double(value))


def _raise(code, buffer, originals=None):
    """Raise the exception of a C status, its message the C text (values named as Python writes them).

    ``originals``: {name: value as given}; a value that is not a float, which the C text writes as the
    float it became (or NaN), is written as Python does: where the message names it (``Fs must be >= Fc
    = 5 (N)``) and where it bounds a range (``gap0 must be in [0, h] = [0, 1] (m)``)."""
    message = buffer.value.decode("utf-8", "replace")
    if code in (E_VALUE, E_LIMIT):
        for name, value in (originals or {}).items():
            if type(value) is not float:  # the C text wrote float(value) (or NaN): write it as Python does
                c_text, py_text = _c_repr(value), repr(value)
                head = f"{name} = {c_text} is out of range"
                if message.startswith(head):
                    message = f"{name} = {py_text} is out of range" + message[len(head):]
                head, sep, tail = message.partition(" is out of range")
                tail = tail.replace(f"{name} = {c_text}", f"{name} = {py_text}")
                message = head + sep + tail.replace(f"{name}] = [0, {c_text}]", f"{name}] = [0, {py_text}]")
        raise PlantError(message)
    if code == E_MATH:
        raise OverflowError(message)
    if code == E_MEMORY:
        raise MemoryError(message)
    if code == E_STATE:
        raise StateRefused(message)
    if code == E_DIVERGED:
        raise Diverged(message)
    raise CoreError(f"C core status {code}: {message}")


def _restore(path, attr, data, event_log=None, crossings=None):
    """Unpickle a native solver or loop: the class ``attr`` of the library at ``path``, the instance from its
    state bytes."""
    native = getattr(load(path), attr).from_bytes(data)
    if event_log is not None:
        native.event_log = event_log
    if crossings is not None:
        native.crossings = list(crossings)
    return native


def _new(function, *args, originals=None):
    """The handle ``function(*args, &handle, err, ERRLEN)`` makes (a ``new`` or a ``from_bytes``), else its
    error raised (``originals`` as :func:`_raise`'s)."""
    handle = ctypes.c_void_p()
    err = ctypes.create_string_buffer(ERRLEN)
    code = function(*args, ctypes.byref(handle), err, ERRLEN)
    if code != OK:
        _raise(code, err, originals)
    return handle


class _Native:
    """What the native solvers and loops share: a C instance freed with its object, the event log, exact
    copies, the state as bytes, pickling. A subclass names its ``_table``, its C functions (``_functions``),
    completes ``_setup`` and gives what a copy shares (``_shared``)."""

    core = None  # the NativeCore of a bound subclass (NativeCore.FrictionMass, ...)
    _plant = None  # key of _table
    _table = None  # _PLANTS or _LOOPS: the NativeCore attribute of a plant's class is its entry's [1]

    @classmethod
    def _functions(cls, core):
        """The :class:`_Functions` of this class on ``core``."""
        raise NotImplementedError

    @classmethod
    def _bound_core(cls, core, method=""):
        """``core``, else the class's own (CoreError if neither): an unbound class needs one passed."""
        core = core if core is not None else cls.core
        if core is None:
            hint = "" if method else f", or use load(path).{cls._table[cls._plant][1]}"
            raise CoreError(f"{cls.__name__}{method} needs a C core: pass core=load(path){hint}")
        return core

    def _setup(self, core, handle):
        self._core, self._api, self._handle = core, self._functions(core), handle
        self._err = ctypes.create_string_buffer(ERRLEN)
        self._event_log = None
        self.event_log_dropped = 0

    def _shared(self):
        """The arguments of ``_setup`` after the handle that a copy takes from its original."""
        return ()

    def _state_size(self):
        """The bytes of this instance's state."""
        raise NotImplementedError

    @property
    def t(self):
        """The current time (s)."""
        return self._api.time(self._handle)

    @property
    def events(self):
        """Events counted so far."""
        return self._api.events(self._handle)

    # -- the event log --------------------------------------------------------------------------
    @property
    def event_log(self):
        """None, or the list every counted event is appended to as (t, EventKind)."""
        return self._event_log

    @event_log.setter
    def event_log(self, value):
        self._api.log(self._handle, 0 if value is None else LOG_CAPACITY)
        self._event_log = value
        self.event_log_dropped = 0

    def _drain(self, stacklevel=3):
        """Move the events C recorded in the last step to the event log (``stacklevel``: the user's frame)."""
        api, handle = self._api, self._handle
        n = api.log_read(handle, None, None, 0)
        if n:
            times, kinds = (ctypes.c_double * n)(), (ctypes.c_int * n)()
            n = api.log_read(handle, times, kinds, n)
            self._event_log.extend(zip(times[:n], map(EVENT_KINDS.__getitem__, kinds[:n])))
        dropped = api.log_dropped(handle)
        if dropped != self.event_log_dropped:
            warnings.warn(f"{type(self).__name__}.event_log: {dropped - self.event_log_dropped} events of one step "
                          f"beyond LOG_CAPACITY = {LOG_CAPACITY} were not recorded", RuntimeWarning,
                          stacklevel=stacklevel)
            self.event_log_dropped = dropped

    # -- copies and state ----------------------------------------------------------------------
    def same_parameters(self, other):
        """Whether ``other`` holds bit-identical fixed parameters: what a run never changes (a plant's
        constants and what is derived from them, the drive's F, omega and phi, the period, the harmonics; a
        loop's G and section), not the input f, the time nor the motion; -0.0 differs from 0.0. False
        unless ``other`` is the same kind (solver or loop) of the same plant on the same core."""
        if not (isinstance(other, _Native) and other._table is self._table and other._plant == self._plant
                and getattr(other, "_core", None) is self._core and self._handle and other._handle):
            return False
        return bool(self._api.same_parameters(self._handle, other._handle))

    def copy(self):
        """An independent exact copy (the C instance copied; the event log list copied too)."""
        handle = self._api.copy(self._handle)
        if not handle:
            raise MemoryError(f"out of memory (a copy of a {self._api.prefix})")
        clone = object.__new__(type(self))
        clone.__dict__.update({k: v for k, v in self.__dict__.items() if not k.startswith("_")})
        clone._setup(self._core, ctypes.c_void_p(handle), *self._shared())
        if self._event_log is not None:
            clone.event_log = list(self._event_log)
        return clone

    def __copy__(self):
        return self.copy()

    def __deepcopy__(self, memo):
        clone = self.copy()
        if self._event_log is not None:
            clone._event_log = copy.deepcopy(self._event_log, memo)
        return clone

    def to_bytes(self):
        """The state as bytes (not in it: the event log, a loop's crossings): see ``from_bytes``."""
        needed = self._state_size()
        size = ctypes.c_size_t(needed)
        buf = ctypes.create_string_buffer(needed)
        code = self._api.to_bytes(self._handle, buf, needed, ctypes.byref(size), self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err)
        return buf.raw[:size.value]

    @classmethod
    def _from_state(cls, data, core, *head):
        """The core and the C handle of the state bytes ``data`` (``head``: the C from_bytes's leading
        arguments); StateRefused, one line, for anything but a valid state."""
        core = cls._bound_core(core, ".from_bytes")
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise StateRefused(f"a solver state must be bytes, not {type(data).__name__}")
        data = bytes(data)
        return core, _new(cls._functions(core).from_bytes, *head, data, len(data))

    def __reduce__(self):
        return (_restore, (str(self._core.path), self._table[self._plant][1], self.to_bytes(), self._event_log))

    def __del__(self):
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            try:
                self._api.free(handle)
            except Exception:  # noqa: BLE001 - interpreter shutdown: the library may be gone
                pass


class _NativeSolver(_Native):
    """What the three native solvers share: the Solver protocol on a C instance."""

    _table = _PLANTS
    _output_type = None  # the table's output_type
    _integer_fields = ()  # the indices of its integer fields

    @classmethod
    def _functions(cls, core):
        return core.api

    def _state_size(self):
        return self._api.state_sizes[_PLANTS[self._plant][0]]

    def _counter(self, name):
        """The C solver's counter ``name``, one of its table's counters (dfwb_plant_counter's order)."""
        return self._api.counter(self._handle, _PLANTS[self._plant][2].counters.index(name))

    def __init__(self, *args, core=None, **kwargs):
        table = _PLANTS[self._plant][2]
        originals = _numbers(table, _bind(type(self), args, kwargs))
        self._create(core, tuple(originals[name] for name in table.core_order), originals)

    def _create(self, core, values, originals):
        self._handle = None
        core = self._bound_core(core)
        params = (ctypes.c_double * len(values))(*(_as_double(v) for v in values))
        kind = _PLANTS[self._plant][0]
        self._setup(core, _new(self._functions(core).new, kind, params, len(values), originals=originals))

    def _setup(self, core, handle):
        super()._setup(core, handle)
        self.harmonics = self._api.harmonics(handle)
        self._out = (ctypes.c_double * len(_PLANTS[self._plant][2].solver_outputs))()
        self._re = (ctypes.c_double * (self.harmonics + 1))()
        self._im = (ctypes.c_double * (self.harmonics + 1))()

    # -- the Solver protocol ---------------------------------------------------------------
    @property
    def period(self):
        """The drive's period 2 pi / omega (s)."""
        return self._api.period(self._handle)

    @property
    def drive(self):
        """A copy of the force u = f + F cos(omega t + phi) (a :class:`~.exact.Drive`)."""
        out = (ctypes.c_double * 4)()
        self._api.drive(self._handle, out)
        return Drive(*out[:])

    def set_input(self, f):
        """Set the input force, held constant until the next change (PlantError unless finite)."""
        code = self._api.set_input(self._handle, _as_double(f), self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err, {"f": f})

    def advance(self, t_end):
        """Integrate exactly from self.t to t_end, firing every event on the way."""
        code = self._api.advance(self._handle, _as_double(t_end), self._err, ERRLEN)
        if self._event_log is not None:
            self._drain()
        if code != OK:
            _raise(code, self._err, {"t_end": t_end})

    def output(self):
        """The outputs at self.t, as the Python solver's named tuple (its integer fields ints)."""
        out = self._out
        self._api.output(self._handle, out)
        values = out[:]
        for i in self._integer_fields:
            values[i] = int(values[i])
        return self._output_type._make(values)

    def integrals(self):
        """Running integrals I_k(t) = int_0^t y exp(-i k omega s) ds, k = 0..harmonics."""
        re, im = self._re, self._im
        code = self._api.integrals(self._handle, re, im, self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err)
        return list(map(complex, re[:], im[:]))

    def integrals_error(self):
        """A bound on the error of every running integral (0.0 for closed forms; see the Python solver's)."""
        return self._api.integrals_error(self._handle)

    @classmethod
    def from_bytes(cls, data, *, core=None):
        """A solver from the bytes of :meth:`to_bytes` (StateRefused, one line, for anything else)."""
        core, handle = cls._from_state(data, core, _PLANTS[cls._plant][0])
        solver = object.__new__(cls)
        solver._setup(core, handle)
        return solver


def _bind(cls, args, kwargs):
    """{name: value as given} of a call of ``cls`` with its Python twin's signature, defaults applied; a call
    that does not fit raises TypeError naming the class, as Python does."""
    try:
        bound = cls._signature.bind(*args, **kwargs)
    except TypeError as error:
        raise TypeError(f"{cls.__name__}(): {error}") from None
    bound.apply_defaults()
    return dict(bound.arguments)


def _numbers(table, originals):
    """``originals`` with each default that is not a number (gap0=None) made the number it stands for, as
    Python makes it (h/2; a bad h is refused first)."""
    for parameter in table.parameters:
        if parameter.half_of and originals.get(parameter.name) is None:
            originals[parameter.name] = 0.5 * _as_double(originals[parameter.half_of])
    return originals


def _with_core(signature):
    """A Python twin's signature with the keyword-only ``core=None`` last."""
    core = inspect.Parameter("core", inspect.Parameter.KEYWORD_ONLY, default=None)
    return signature.replace(parameters=[*signature.parameters.values(), core])


def _native_solver(module):
    """The class of a plant's solver on the C core: its Python twin's constructor (same keywords and
    defaults; ``core`` keyword only) and outputs, its table's counters as attributes."""
    table, python = module.TABLE, module.SOLVER
    signature = inspect.signature(python)
    namespace = {"__module__": __name__, "_plant": c_name(table), "_signature": signature,
                 "__signature__": _with_core(signature),
                 "_output_type": table.output_type, "_integer_fields": tuple(
                     i for i, output in enumerate(o for o in table.outputs if not o.counter) if output.integer),
                 "__doc__": f"{python.__name__} solved by the C core: the :class:`~.contract.Solver` protocol with "
                            f"its Python twin's keywords, defaults and outputs; ``core`` (keyword only) is the "
                            f":class:`NativeCore` to run on, by default the class's own "
                            f"(``load(path).{table.model}`` is this class bound to that core)."}
    for output in table.outputs:
        if output.counter:
            namespace[output.name] = property(lambda self, name=output.name: self._counter(name),
                                              doc=output.description)
    return type("Native" + table.model, (_NativeSolver,), namespace)


SOLVERS = tuple(_native_solver(module) for module in MODULES)
"""The native solvers' classes, one per plant (NativeFrictionMass, NativeTwoMassBacklash, ...)."""


# -- the exact closed loops (each plant's LOOP) ---------------------------------------------------------------
# plant -> (DFWB_PLANT_*, NativeCore attribute, the Python class, parameters in the C order)
_LOOPS = {c_name(m.TABLE): (KINDS[m.TABLE.name], m.LOOP.__name__, m.LOOP, m.TABLE.loop_order) for m in MODULES}

NativeMode = namedtuple("NativeMode", "key h terms")
NativeMode.__doc__ = """A mode of a native loop as its ``_modes`` dict holds it: key, chunk length h, Taylor terms."""


class _LoopApi(_Functions):
    """The C functions of the closed loops (``dfwb_loop_*``)."""

    def __init__(self, lib, path):
        c_double, c_int, c_void_p, c_char_p, c_size_t = (ctypes.c_double, ctypes.c_int, ctypes.c_void_p,
                                                         ctypes.c_char_p, ctypes.c_size_t)
        c_longlong = ctypes.c_longlong
        p_double, p_int = ctypes.POINTER(c_double), ctypes.POINTER(c_int)
        table = {
            "new": (c_int, [c_int, p_double, c_size_t, p_double, c_size_t, p_double, c_size_t, p_double, c_size_t,
                            p_double, c_size_t, p_double, p_double, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
            "band": (c_int, [c_void_p]),
            "compensation": (None, [c_void_p, p_double]),
            "advance": (c_int, [c_void_p, c_double, c_int, ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(c_longlong),
                                c_longlong, c_char_p, c_size_t]),
            "stopped": (c_int, [c_void_p]),
            "sample": (c_int, [c_void_p, p_double, c_size_t, p_double, p_int, p_double, ctypes.POINTER(c_longlong),
                               c_longlong, c_char_p, c_size_t]),
            "plant": (c_int, [c_void_p]),
            "order": (c_int, [c_void_p]),
            "size": (c_int, [c_void_p]),
            "mode": (c_int, [c_void_p]),
            "counter": (c_longlong, [c_void_p]),
            "state": (None, [c_void_p, p_double]),
            "output": (c_double, [c_void_p]),
            "force": (c_double, [c_void_p, p_double]),
            "parameters": (None, [c_void_p, p_double]),
            "controller": (None, [c_void_p, p_double, p_double, p_double, p_double]),
            "crossings_read": (c_size_t, [c_void_p, p_double, p_double, c_size_t]),
            "crossings_dropped": (ctypes.c_ulonglong, [c_void_p]),
            "modes_built": (c_int, [c_void_p]),
            "build_modes": (c_int, [c_void_p, c_int, c_char_p, c_size_t]),
            "mode_info": (c_int, [c_void_p, c_int, p_double, p_int]),
            "section": (c_int, [c_void_p, p_double]),
            "from_bytes": (c_int, [c_int, c_char_p, c_size_t, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
        }
        super().__init__(lib, "dfwb_loop", path, table)
        size = ctypes.c_size_t()
        self.to_bytes(None, None, 0, ctypes.byref(size), None, 0)
        self.state_size = size.value


def _doubles(values):
    values = [_as_double(v) for v in values]
    return (ctypes.c_double * max(1, len(values)))(*values), len(values)


class _NativeLoop(_Native):
    """What the three native loops share: :class:`~.loops.FeedbackLoop`'s attributes and methods on a C instance."""

    _table = _LOOPS
    _keys = ()  # mode key index of the C core -> the Python key tuple
    plant = None  # the open-loop solver class (the bound subclass: the native one of its core)

    def __init_subclass__(cls, **kwargs):
        """Take the Python loop's coordinates and its methods that need no solver, so both share one source."""
        super().__init_subclass__(**kwargs)
        python = _LOOPS[cls._plant][2]
        for name in ("coordinates", "OUTPUT", "initial_parameters", "translate", "check_coordinates", "force",
                     "applied", "feedforward", "slip", "KEYS", "SECTION", "PIVOT", "pivot", "ALTERNATE",
                     "alternate_pivot", "linear", "nonlinearity",
                     "still", "CONSTANTS", "COUNTER", "MODE_VALUES"):
            setattr(cls, name, getattr(python, name))
        cls.coordinates_of = staticmethod(python.coordinates_of)
        cls._keys = python.KEYS

    def __init__(self, *args, core=None, **kwargs):
        originals = _numbers(_PLANTS[self._plant][2], _bind(type(self), args, kwargs))
        names = _LOOPS[self._plant][3]
        self._create(core, originals["b"], originals["a"], tuple(originals[name] for name in names), *(
            originals[name] for name in ("z0", "state", "section", "modes", "budget", "compensation")))
        self._set_constants()
        for name in self.CONSTANTS:  # the parameters as given (an int stays an int), as the Python loop keeps them
            if name in originals:
                setattr(self, name, originals[name])

    @classmethod
    def _functions(cls, core):
        return core.loop_api

    def _state_size(self):
        return self._api.state_size

    def _create(self, core, b, a, values, z0, state, section, modes, budget, compensation):
        self._handle = None
        core = self._bound_core(core)
        coulomb, reset, band = compensators(compensation)
        if follows_control(coulomb):
            raise PlantError("the compiled loop has no Coulomb feedforward of the controller's sign (the Python loop, "
                             "dfwb.fmus.loops, runs it)")
        dither, inverse = dither_of(compensation), inverse_of(compensation)
        ccompensation = None if compensation is None else (ctypes.c_double * 7)(
            float(coulomb is not None), 0.0 if coulomb is None else coulomb.F_hat, float(reset),
            0.0 if band is None else band, 0.0 if dither is None else dither.a, 0.0 if dither is None else dither.w_d,
            0.0 if inverse is None else inverse.h_hat)
        kind, _attr, _cls, names = _LOOPS[self._plant]
        b, a = list(b), list(a)
        originals = dict(zip(names, values))
        originals.update({f"a{i}": value for i, value in enumerate(a, start=1)})
        originals.update({f"b{i}": value for i, value in enumerate(b)})
        if state is not None:
            state = list(state)
            m = len(self.coordinates)
            originals.update(zip(self.coordinates, state[:m]))
            originals.update({f"z{i}_0": value for i, value in enumerate(state[m:], start=1)})
        elif z0 is not None:
            z0 = list(z0)
            originals.update({f"z{i}_0": value for i, value in enumerate(z0, start=1)})
        params, nparams = _doubles(values)
        cb, nb = _doubles(b)
        ca, na = _doubles(a)
        cz, nz = _doubles(z0) if z0 is not None and state is None else (None, 0)
        cs, ns = _doubles(state) if state is not None else (None, 0)
        if section is not None:
            originals["section"] = section
            csec = ctypes.byref(ctypes.c_double(_as_double(section)))
        else:
            csec = None
        handle = _new(core.loop_api.new, kind, params, nparams, cb, nb, ca, na, cz, nz, cs, ns, csec, ccompensation,
                      originals=originals)
        self._setup(core, handle, modes, budget, section)

    def _setup(self, core, handle, modes, budget, level):
        super()._setup(core, handle)
        api = self._api
        self.order = n = api.order(handle)
        self._size = size = api.size(handle)
        Ac, Bc, C = (ctypes.c_double * (n * n))(), (ctypes.c_double * n)(), (ctypes.c_double * n)()
        D = ctypes.c_double()
        api.controller(handle, Ac, Bc, C, ctypes.byref(D))
        self.Ac = [Ac[i * n:(i + 1) * n] for i in range(n)]
        self.Bc, self.C, self.D = Bc[:], C[:], D.value
        held = (ctypes.c_double * 7)()
        api.compensation(handle, held)
        has_coulomb, F_hat, self._reset_at_rest, d, a, w_d, h_hat = held[:]
        self.coulomb = Coulomb(F_hat) if has_coulomb else None  # the compensators, as the Python loop holds them
        self.deadband = d if d > 0.0 else None
        self.dither = Dither(a, w_d) if a > 0.0 else None
        self.inverse = BacklashInverse(h_hat) if h_hat > 0.0 else None
        self.sigma, self._on_control = 0, False  # the feedforward of the controller's sign: Python's alone
        # slot s of the C modes -> the key the Python loop's modes dict holds it by: with a deadband (key, 0, side)
        self._slots = {k + LOOP_KEYS * v: (key, 0, side) if self.deadband is not None else key
                       for v, side in enumerate(SIDES if self.deadband is not None else (1,))
                       for k, key in enumerate(self._keys)}
        self._slot_of = {key: slot for slot, key in self._slots.items()}
        self._modes = {} if modes is None else modes
        self._budget = budget
        self._level = level  # the section's level, or None (Python's _section is (L, l0))
        self._left = ctypes.c_longlong()
        self._mask = 0
        self._X = (ctypes.c_double * size)()
        self.crossings = []  # (t, X) at every upward crossing of the section
        self.stopped = None  # the event kind the last advance stopped at (``stop_at``), else None
        self._collect()

    def _shared(self):
        return self._modes, self._budget, self._level

    # -- the solver ---------------------------------------------------------------------------
    @property
    def key(self):
        """The current mode key (as the Python loop's: ``("slide", 1)``, ...)."""
        return self._keys[self._api.mode(self._handle)]

    @property
    def band(self):
        """The integrator deadband's side: -1 below -d, 0 within (the integrator holds), +1 above d (or none)."""
        return self._api.band(self._handle)

    def _compound(self, key):
        """The key the modes dict holds plant mode ``key`` by at the current side of the deadband."""
        return (key, 0, self.band) if self.deadband is not None else key

    def advance(self, t_end, stop_at_section=False, stop_at=()):
        """Integrate exactly from self.t to t_end, firing every event on the way (HybridSolver.advance).

        With ``stop_at_section``, stop early at the next upward crossing of the section (then
        ``self.crossings[-1]`` holds it); ``stop_at``: pairs ``(mode key, event kind)``, stop just after the
        first such event (then ``self.stopped`` is its kind)."""
        self._share_modes()
        api, budget = self._api, self._budget
        section = int(bool(stop_at_section))
        events = None
        if stop_at:  # a mask of event kinds per mode key
            events = (ctypes.c_uint * LOOP_KEYS)()
            for key, kind in stop_at:
                events[self._keys.index(key)] |= 1 << EVENT_KINDS.index(kind)
        if budget is None:
            code = api.advance(self._handle, _as_double(t_end), section, events, None, 0, self._err, ERRLEN)
        else:
            left = self._left
            left.value = budget.left
            code = api.advance(self._handle, _as_double(t_end), section, events, ctypes.byref(left), budget.total,
                               self._err, ERRLEN)
            budget.left = left.value
        kind = api.stopped(self._handle)
        self.stopped = EVENT_KINDS[kind] if kind else None
        self._collect()
        if code != OK:
            if type(t_end) is not float:  # the value as Python writes it
                message = self._err.value.decode("utf-8", "replace")
                head = f"t_end = {_c_repr(t_end)} s is out of range"
                if message.startswith(head):
                    self._err.value = (f"t_end = {t_end!r} s is out of range" + message[len(head):]).encode()
            _raise(code, self._err, {"t_end": t_end})

    def state(self):
        """The state X at self.t."""
        X = self._X
        self._api.state(self._handle, X)
        return X[:]

    def sample(self, times):
        """The states at each of ``times`` (non-decreasing, from self.t), advancing to them in turn
        (HybridSolver.sample): one call into the core. ``times`` may be a float64 array (read in place)."""
        return self._sample(times)

    def readings(self, times):
        """(states, forces on the plant) at each of ``times`` (FeedbackLoop.readings): one call into the core."""
        forces = (ctypes.c_double * max(1, len(times)))()
        states = self._sample(times, forces)
        return states, forces[:len(times)]

    def _sample(self, times, forces=None):
        self._share_modes()
        api, budget, n = self._api, self._budget, len(times)
        if getattr(times, "dtype", None) == "float64" and times.flags["C_CONTIGUOUS"]:
            ctimes = times.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        else:
            ctimes = (ctypes.c_double * max(1, n))(*[_as_double(t) for t in times])
        states = (ctypes.c_double * max(1, n * self._size))()
        if budget is None:
            code = api.sample(self._handle, ctimes, n, states, None, forces, None, 0, self._err, ERRLEN)
        else:
            left = self._left
            left.value = budget.left
            code = api.sample(self._handle, ctimes, n, states, None, forces, ctypes.byref(left), budget.total,
                              self._err, ERRLEN)
            budget.left = left.value
        self.stopped = None
        self._collect()
        if code != OK:
            _raise(code, self._err)
        size = self._size
        return [states[i * size:(i + 1) * size] for i in range(n)]

    def output(self):
        """The plant's output y at self.t."""
        return self._api.output(self._handle)

    def counts(self):
        """{COUNTER's name: what the loop counted} (stick phases, impacts, engagements)."""
        return {self.COUNTER.name: self._api.counter(self._handle)}

    def mode(self, key):
        """The mode ``key`` (a :data:`NativeMode`), built if new (HybridSolver.mode)."""
        key = self._compound(key)
        self._share_modes(1 << self._slot_of[key])
        return self._modes[key]

    # -- what the C instance reports after a step --------------------------------------------------
    def _share_modes(self, extra=0):
        """Build the modes the shared ``modes`` dict holds and this instance lacks (they bound a step)."""
        wanted = extra
        if len(self._modes) > bin(self._mask).count("1") or extra:
            for key in self._modes:
                if key in self._slot_of:
                    wanted |= 1 << self._slot_of[key]
        if wanted & ~self._mask:
            code = self._api.build_modes(self._handle, wanted, self._err, ERRLEN)
            self._collect()
            if code != OK:
                _raise(code, self._err)

    def _collect(self):
        api, handle = self._api, self._handle
        mask = api.modes_built(handle)
        if mask != self._mask:
            h, terms = ctypes.c_double(), ctypes.c_int()
            for i, key in self._slots.items():
                if (mask >> i) & 1 and key not in self._modes and api.mode_info(handle, i, ctypes.byref(h),
                                                                                ctypes.byref(terms)):
                    self._modes[key] = NativeMode(key, h.value, terms.value)
            self._mask = mask
        if self._level is not None:
            n = api.crossings_read(handle, None, None, 0)
            if n:
                size = self._size
                times, states = (ctypes.c_double * n)(), (ctypes.c_double * (n * size))()
                n = api.crossings_read(handle, times, states, n)
                self.crossings.extend((times[i], states[i * size:(i + 1) * size]) for i in range(n))
        if self._event_log is not None:
            self._drain(stacklevel=4)  # the user's frame: _drain, _collect, advance or mode, the user

    # -- copies -------------------------------------------------------------------------------------
    def copy(self):
        """An independent exact copy (the C instance copied; crossings and the event log list copied; the
        ``modes`` dict and the budget shared, as the solvers of one study share them)."""
        clone = super().copy()
        clone.crossings = list(self.crossings)
        return clone

    def __deepcopy__(self, memo):
        """A copy with its own ``modes`` dict, budget, crossings and event log (as deepcopy of a Python loop)."""
        clone = super().__deepcopy__(memo)
        clone._modes = copy.deepcopy(self._modes, memo)
        clone._budget = copy.deepcopy(self._budget, memo)
        clone.crossings = copy.deepcopy(self.crossings, memo)
        return clone

    # -- the state as bytes ------------------------------------------------------------------------------
    def _set_constants(self):
        """The plant's constants (M, B, ...: CONSTANTS) as attributes, from the C instance."""
        out = (ctypes.c_double * LOOP_CONSTANTS)()
        self._api.parameters(self._handle, out)
        for name, value in zip(self.CONSTANTS, out):
            setattr(self, name, value)

    @classmethod
    def from_bytes(cls, data, *, core=None, modes=None, budget=None):
        """A loop from the bytes of :meth:`to_bytes` (StateRefused, one line, for anything else); ``modes`` and
        ``budget`` as the constructor's."""
        core, handle = cls._from_state(data, core, _LOOPS[cls._plant][0])
        level = ctypes.c_double()
        section = level.value if core.loop_api.section(handle, ctypes.byref(level)) else None
        loop = object.__new__(cls)
        loop._setup(core, handle, modes, budget, section)
        loop._set_constants()
        return loop

    def __reduce__(self):
        function, args = super().__reduce__()
        return function, args + (self.crossings,)


def _native_loop(module):
    """The class of a plant's closed loop on the C core: its Python twin's constructor (same keywords and
    defaults; ``core`` keyword only), attributes and methods; its counter as an attribute."""
    python = module.LOOP
    signature = inspect.signature(python)
    counter = python.COUNTER.name
    return type("Native" + python.__name__, (_NativeLoop,), {
        "__module__": __name__, "_plant": c_name(module.TABLE), "_signature": signature,
        "__signature__": _with_core(signature),
        counter: property(lambda self: self._api.counter(self._handle), doc=python.COUNTER.description),
        "__doc__": f":class:`~.{module.__name__.rsplit('.', 1)[-1]}.{python.__name__}` solved by the C core: "
                   f"same keywords, defaults, attributes and methods."})


LOOPS = tuple(_native_loop(module) for module in MODULES)
"""The native loops' classes, one per plant (NativeFrictionLoop, NativeBacklashLoop, ...)."""
for _cls in SOLVERS + LOOPS:  # NativeFrictionMass, ... by name; never in place of a name of this module
    if _cls.__name__ in globals():
        raise ValueError(f"dfwb.fmus.native_core: a plant's class {_cls.__name__} would replace a name of the module")
    globals()[_cls.__name__] = _cls
