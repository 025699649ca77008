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

A value the C core refuses raises :class:`~.exact.PlantError` with the C message, which is the Python
solver's text (a non-float value, e.g. an int or None, is named as Python writes it). A power or a
modulus that overflows raises OverflowError, as in Python.

``event_log``: None, or a list; set to a list, every counted event of a step is appended to it as
``(t, EventKind)``, as the Python solvers do (recorded in C, moved to the list after each step; beyond
:data:`LOG_CAPACITY` events in one step the rest are counted in ``event_log_dropped`` and a
RuntimeWarning is issued).

State: :meth:`~_NativeSolver.to_bytes` gives the solver's state as bytes (a header - magic, ABI, plant
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
import warnings
from pathlib import Path

from .contract import BacklashOutput, EventKind, FrictionOutput, StaticBacklashOutput
from .exact import DfwbError, Drive, PlantError
from .state import StateRefused

__all__ = ["load", "NativeCore", "NativeFrictionMass", "NativeTwoMassBacklash", "NativeStaticBacklash",
           "CoreError", "PARAMETERS", "BACKLASH_PARAMETERS", "STATIC_BACKLASH_PARAMETERS", "ABI", "LOG_CAPACITY",
           "EVENT_KINDS"]

ABI = 3  # DFWB_CORE_ABI of dfwb_core.h this binding speaks
PARAMETERS = ("M", "B", "Fc", "Fs", "Dv", "F", "omega", "phi", "x0", "v0", "f", "harmonics")
BACKLASH_PARAMETERS = ("M1", "M2", "h", "eps", "F", "omega", "phi", "x1_0", "v1_0", "v2_0", "gap0", "f",
                       "harmonics")
STATIC_BACKLASH_PARAMETERS = ("M", "k", "h", "F", "omega", "phi", "x0", "v0", "f", "harmonics")
ERRLEN = 1024
LOG_CAPACITY = 1 << 20  # events one step may record (16 bytes each in C, allocated as they come)

# status codes of dfwb_core.h
OK, E_VALUE, E_LIMIT, E_MATH, E_MEMORY, E_ARGUMENT, E_STATE = range(7)

# DFWB_EVENT_* -> EventKind (0: none)
EVENT_KINDS = (None, EventKind.BREAK_UP, EventKind.BREAK_DOWN, EventKind.RELEASE, EventKind.EDGE, EventKind.BAND,
               EventKind.WALL_LOWER, EventKind.WALL_UPPER, EventKind.APEX, EventKind.ENGAGE_UP,
               EventKind.ENGAGE_DOWN, EventKind.REVERSE)

# plant -> (C prefix, NativeCore attribute, output length, extra counters {name: restype})
_PLANTS = {
    "friction": ("dfwb_friction", "FrictionMass", 4, {}),
    "backlash": ("dfwb_backlash", "TwoMassBacklash", 5, {"contact": ctypes.c_int, "impacts": ctypes.c_longlong}),
    "static_backlash": ("dfwb_static_backlash", "StaticBacklash", 3, {"engaged": ctypes.c_int}),
}


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


class _Api:
    """One plant's C functions (``new``, ``advance``, ... without the prefix)."""

    def __init__(self, lib, prefix, path, counters):
        c_double, c_int, c_void_p, c_char_p, c_size_t = (ctypes.c_double, ctypes.c_int, ctypes.c_void_p,
                                                         ctypes.c_char_p, ctypes.c_size_t)
        p_double, p_int = ctypes.POINTER(c_double), ctypes.POINTER(c_int)
        table = {
            "new": (c_int, [p_double, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
            "set_input": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "advance": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "output": (None, [c_void_p, p_double]),
            "integrals": (c_int, [c_void_p, p_double, p_double, c_char_p, c_size_t]),
            "time": (c_double, [c_void_p]),
            "events": (ctypes.c_longlong, [c_void_p]),
            "harmonics": (c_int, [c_void_p]),
            "period": (c_double, [c_void_p]),
            "drive": (None, [c_void_p, p_double]),
            "same_parameters": (c_int, [c_void_p, c_void_p]),
            "copy": (c_void_p, [c_void_p]),
            "free": (None, [c_void_p]),
            "log": (None, [c_void_p, c_size_t]),
            "log_read": (c_size_t, [c_void_p, p_double, p_int, c_size_t]),
            "log_dropped": (ctypes.c_ulonglong, [c_void_p]),
            "to_bytes": (c_int, [c_void_p, c_char_p, c_size_t, ctypes.POINTER(c_size_t), c_char_p, c_size_t]),
            "from_bytes": (c_int, [c_char_p, c_size_t, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
        }
        table.update({name: (restype, [c_void_p]) for name, restype in counters.items()})
        for name, (restype, argtypes) in table.items():
            try:
                function = getattr(lib, f"{prefix}_{name}")
            except AttributeError:
                raise CoreError(f"the C core {path} has no function {prefix}_{name}") from None
            function.restype, function.argtypes = restype, argtypes
            setattr(self, name, function)
        size = c_size_t()
        self.to_bytes(None, None, 0, ctypes.byref(size), None, 0)
        self.state_size = size.value


class NativeCore:
    """An opened C core: its ctypes functions and the solver classes bound to it
    (``FrictionMass``, ``TwoMassBacklash``, ``StaticBacklash``)."""

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
        self.api = {plant: _Api(lib, prefix, self.path, counters)
                    for plant, (prefix, _attr, _n, counters) in _PLANTS.items()}
        for cls in (NativeFrictionMass, NativeTwoMassBacklash, NativeStaticBacklash):
            attr = _PLANTS[cls._plant][1]
            setattr(self, attr, type(cls.__name__, (cls,), {"core": self, "__module__": __name__}))

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


def _raise(code, buffer, originals=None, tails=()):
    """Raise the exception of a C status, its message the C text (values named as Python writes them).

    ``tails``: (C text, Python text) pairs replaced at the end of a value's message (an allowed range
    that quotes another parameter, e.g. ``Fs must be >= Fc = 5 (N)``)."""
    message = buffer.value.decode("utf-8", "replace")
    if code in (E_VALUE, E_LIMIT):
        for name, value in (originals or {}).items():
            if type(value) is not float:  # the C text wrote float(value) (or NaN): write it as Python does
                head = f"{name} = {_c_repr(value)} is out of range"
                if message.startswith(head):
                    message = f"{name} = {value!r} is out of range" + message[len(head):]
        for c_text, py_text in tails:
            if message.endswith(c_text):
                message = message[:-len(c_text)] + py_text
        raise PlantError(message)
    if code == E_MATH:
        raise OverflowError(message)
    if code == E_MEMORY:
        raise MemoryError(message)
    if code == E_STATE:
        raise StateRefused(message)
    raise CoreError(f"C core status {code}: {message}")


def _restore(path, plant, data, event_log=None):
    """Unpickle a native solver: the library at ``path``, the solver from its state bytes."""
    cls = getattr(load(path), _PLANTS[plant][1])
    solver = cls.from_bytes(data)
    if event_log is not None:
        solver.event_log = event_log
    return solver


class _NativeSolver:
    """What the three native solvers share: the Solver protocol on a C instance, the event log, copies,
    the state as bytes."""

    core = None  # the NativeCore of a bound subclass (NativeCore.FrictionMass, ...)
    _plant = None  # key of _PLANTS
    _output_type = None

    def _create(self, core, values, originals, tails=()):
        self._handle = None
        core = core if core is not None else type(self).core
        if core is None:
            attr = _PLANTS[self._plant][1]
            raise CoreError(f"{type(self).__name__} needs a C core: pass core=load(path), or use load(path).{attr}")
        api = core.api[self._plant]
        params = (ctypes.c_double * len(values))(*(_as_double(v) for v in values))
        handle = ctypes.c_void_p()
        err = ctypes.create_string_buffer(ERRLEN)
        code = api.new(params, ctypes.byref(handle), err, ERRLEN)
        if code != OK:
            _raise(code, err, originals, tails)
        self._setup(core, handle)

    def _setup(self, core, handle):
        api = core.api[self._plant]
        self._core, self._api, self._handle = core, api, handle
        self.harmonics = api.harmonics(handle)
        self._event_log = None
        self.event_log_dropped = 0
        self._err = ctypes.create_string_buffer(ERRLEN)
        self._out = (ctypes.c_double * _PLANTS[self._plant][2])()
        self._re = (ctypes.c_double * (self.harmonics + 1))()
        self._im = (ctypes.c_double * (self.harmonics + 1))()

    # -- the Solver protocol ---------------------------------------------------------------
    @property
    def t(self):
        """The current time (s)."""
        return self._api.time(self._handle)

    @property
    def events(self):
        """Events counted so far."""
        return self._api.events(self._handle)

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
        """The outputs at self.t, as the Python solver's named tuple."""
        out = self._out
        self._api.output(self._handle, out)
        return self._output_type._make(out[:])

    def integrals(self):
        """Running integrals I_k(t) = int_0^t y exp(-i k omega s) ds, k = 0..harmonics."""
        re, im = self._re, self._im
        code = self._api.integrals(self._handle, re, im, self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err)
        return list(map(complex, re[:], im[:]))

    # -- the event log ------------------------------------------------------------------------
    @property
    def event_log(self):
        """None, or the list every counted event is appended to as (t, EventKind)."""
        return self._event_log

    @event_log.setter
    def event_log(self, value):
        self._api.log(self._handle, 0 if value is None else LOG_CAPACITY)
        self._event_log = value
        self.event_log_dropped = 0

    def _drain(self):
        api, handle = self._api, self._handle
        n = api.log_read(handle, None, None, 0)
        if n:
            times, kinds = (ctypes.c_double * n)(), (ctypes.c_int * n)()
            n = api.log_read(handle, times, kinds, n)
            self._event_log.extend(zip(times[:n], map(EVENT_KINDS.__getitem__, kinds[:n])))
        dropped = api.log_dropped(handle)
        if dropped != self.event_log_dropped:
            warnings.warn(f"{type(self).__name__}.event_log: {dropped - self.event_log_dropped} events of one step "
                          f"beyond LOG_CAPACITY = {LOG_CAPACITY} were not recorded", RuntimeWarning, stacklevel=3)
            self.event_log_dropped = dropped

    # -- copies and state ----------------------------------------------------------------------
    def same_parameters(self, other):
        """Whether ``other`` holds bit-identical fixed parameters: the plant's constants and what is derived
        from them, the drive's F, omega and phi, the period, the harmonics (-0.0 differs from 0.0; the
        input f, the time and the motion are not compared). False unless ``other`` is a native solver of
        the same plant on the same core."""
        if not (isinstance(other, _NativeSolver) and other._plant == self._plant
                and getattr(other, "_core", None) is self._core):
            return False
        if not (self._handle and other._handle):
            return False
        return bool(self._api.same_parameters(self._handle, other._handle))

    def copy(self):
        """An independent exact copy (the C instance copied; the event log list copied too)."""
        handle = self._api.copy(self._handle)
        if not handle:
            raise MemoryError(f"out of memory (a copy of a {_PLANTS[self._plant][0]})")
        clone = object.__new__(type(self))
        clone._setup(self._core, ctypes.c_void_p(handle))
        if self._event_log is not None:
            clone.event_log = list(self._event_log)
        return clone

    __copy__ = copy

    def __deepcopy__(self, memo):
        clone = self.copy()
        if self._event_log is not None:
            clone.event_log = copy.deepcopy(self._event_log, memo)
        return clone

    def to_bytes(self):
        """The solver's state as bytes (the event log is not part of it): see :meth:`from_bytes`."""
        api = self._api
        size = ctypes.c_size_t(api.state_size)
        buf = ctypes.create_string_buffer(api.state_size)
        code = api.to_bytes(self._handle, buf, api.state_size, ctypes.byref(size), self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err)
        return buf.raw[:size.value]

    @classmethod
    def from_bytes(cls, data, *, core=None):
        """A solver from the bytes of :meth:`to_bytes` (StateRefused, one line, for anything else)."""
        core = core if core is not None else cls.core
        if core is None:
            raise CoreError(f"{cls.__name__}.from_bytes needs a C core: pass core=load(path)")
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise StateRefused(f"a solver state must be bytes, not {type(data).__name__}")
        data = bytes(data)
        api = core.api[cls._plant]
        handle = ctypes.c_void_p()
        err = ctypes.create_string_buffer(ERRLEN)
        code = api.from_bytes(data, len(data), ctypes.byref(handle), err, ERRLEN)
        if code != OK:
            _raise(code, err)
        solver = object.__new__(cls)
        solver._setup(core, handle)
        return solver

    def __reduce__(self):
        return (_restore, (str(self._core.path), self._plant, self.to_bytes(), self._event_log))

    def __del__(self):
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            try:
                self._api.free(handle)
            except Exception:  # noqa: BLE001 - interpreter shutdown: the library may be gone
                pass


class NativeFrictionMass(_NativeSolver):
    """The friction mass solved by the C core: the :class:`~.contract.Solver` protocol of FrictionMass.

    Same keywords and defaults as :class:`~.friction.FrictionMass`; ``core``
    (keyword only) is the :class:`NativeCore` to run on, by default the class's
    own (``load(path).FrictionMass`` is this class bound to that core).
    """

    _plant = "friction"
    _output_type = FrictionOutput

    def __init__(self, M=1.0, B=0.5, Fc=5.0, Fs=7.0, Dv=0.0, F=0.0, omega=1.0, phi=0.0,
                 x0=0.0, v0=0.0, f=0.0, harmonics=10, *, core=None):
        values = (M, B, Fc, Fs, Dv, F, omega, phi, x0, v0, f, harmonics)
        tails = () if type(Fc) is float else ((f"Fc = {_c_repr(Fc)} (N)", f"Fc = {Fc!r} (N)"),)
        self._create(core, values, dict(zip(PARAMETERS, values)), tails)

    def output(self):
        """x, v, friction force Ff and mode (0 stick or band, +-1 sliding) at self.t."""
        out = self._out
        self._api.output(self._handle, out)
        x, v, ff, mode = out[:]
        return FrictionOutput(x, v, ff, int(mode))


class NativeTwoMassBacklash(_NativeSolver):
    """The two-mass backlash solved by the C core: keywords, defaults (gap0=None: h/2) and outputs of
    :class:`~.backlash.TwoMassBacklash`, with its counters ``contact`` (0 free, 1 gap 0, 2 gap h) and
    ``impacts``."""

    _plant = "backlash"
    _output_type = BacklashOutput

    def __init__(self, M1=1.0, M2=1.0, h=0.1, eps=0.5, F=0.0, omega=1.0, phi=0.0,
                 x1_0=0.0, v1_0=0.0, v2_0=0.0, gap0=None, f=0.0, harmonics=10, *, core=None):
        originals = dict(M1=M1, M2=M2, h=h, eps=eps, F=F, omega=omega, phi=phi, x1_0=x1_0, v1_0=v1_0,
                         v2_0=v2_0, gap0=gap0, f=f, harmonics=harmonics)
        if gap0 is None:
            gap0 = originals["gap0"] = 0.5 * _as_double(h)  # as Python: 0.5 * h (h is checked first)
        values = (M1, M2, h, eps, F, omega, phi, x1_0, v1_0, v2_0, gap0, f, harmonics)
        tails = () if type(h) is float else ((f"= [0, {_c_repr(h)}] (m)", f"= [0, {h!r}] (m)"),)
        self._create(core, values, originals, tails)

    @property
    def contact(self):
        """0 free, 1 riding at gap 0, 2 riding at gap h."""
        return self._api.contact(self._handle)

    @property
    def impacts(self):
        """Impacts so far."""
        return self._api.impacts(self._handle)


class NativeStaticBacklash(_NativeSolver):
    """Mass + backlash solved by the C core: keywords, defaults and outputs of
    :class:`~.static_backlash.StaticBacklash`, with its counter ``engaged`` (0, +1, -1)."""

    _plant = "static_backlash"
    _output_type = StaticBacklashOutput

    def __init__(self, M=2.0, k=1.0, h=0.1, F=0.0, omega=1.0, phi=0.0, x0=0.0, v0=0.0, f=0.0, harmonics=10,
                 *, core=None):
        values = (M, k, h, F, omega, phi, x0, v0, f, harmonics)
        self._create(core, values, dict(zip(STATIC_BACKLASH_PARAMETERS, values)))

    @property
    def engaged(self):
        """0 free, +1/-1 dragging y at the upper/lower edge of the play."""
        return self._api.engaged(self._handle)
