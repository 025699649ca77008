"""The exact friction-mass solver in C (``fmus/native``), loaded with ctypes.

The C core is a port of :class:`~.friction.FrictionMass` (with
:mod:`.exact` and :mod:`.piecewise`), which stays the oracle: same
algorithms, same bounds, same operation order, so both agree to rounding
(``tests/test_native_core.py`` holds them to it). This module is its
binding: :func:`load` opens a compiled library (``dfwb.build_fmus.core.
build_core`` makes one) and :class:`NativeFrictionMass` implements the
:class:`~.contract.Solver` protocol on it, with the constructor of
``FrictionMass`` (same keywords, same defaults)::

    core = load(build_core(folder))
    plant = core.FrictionMass(F=10.0, omega=1.0)   # or NativeFrictionMass(F=10.0, omega=1.0, core=core)
    plant.advance(6.28)
    x, v, Ff, mode = plant.output()

A value the C core refuses raises :class:`~.exact.PlantError` with the C
message, which is the Python solver's text (a non-float value, e.g. an int
or None, is named as Python writes it). A power or a modulus that overflows
raises OverflowError, as in Python.

Not (yet) offered by the C core: ``event_log`` (always None), pickling.
``copy.copy`` / ``copy.deepcopy`` / :meth:`NativeFrictionMass.copy` give an
independent exact copy (``dfwb_friction_copy``).

Plain Python (stdlib ``ctypes``) only.
"""

import ctypes
from pathlib import Path

from .contract import FrictionOutput
from .exact import DfwbError, PlantError

__all__ = ["load", "NativeCore", "NativeFrictionMass", "CoreError", "PARAMETERS", "ABI"]

ABI = 1  # DFWB_CORE_ABI of dfwb_core.h this binding speaks
PARAMETERS = ("M", "B", "Fc", "Fs", "Dv", "F", "omega", "phi", "x0", "v0", "f", "harmonics")
ERRLEN = 1024

# status codes of dfwb_core.h
OK, E_VALUE, E_LIMIT, E_MATH, E_MEMORY, E_ARGUMENT = range(6)


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


class NativeCore:
    """An opened C core: its ctypes functions and ``FrictionMass``, the solver class bound to it."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            lib = ctypes.CDLL(str(self.path))
        except OSError as error:
            raise CoreError(f"cannot load the C core {self.path}: {error}") from None
        c_double, c_int, c_void_p, c_char_p, c_size_t = (ctypes.c_double, ctypes.c_int, ctypes.c_void_p,
                                                         ctypes.c_char_p, ctypes.c_size_t)
        p_double = ctypes.POINTER(c_double)
        table = {
            "dfwb_core_abi_version": (c_int, []),
            "dfwb_friction_new": (c_int, [p_double, ctypes.POINTER(c_void_p), c_char_p, c_size_t]),
            "dfwb_friction_set_input": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "dfwb_friction_advance": (c_int, [c_void_p, c_double, c_char_p, c_size_t]),
            "dfwb_friction_output": (None, [c_void_p, p_double]),
            "dfwb_friction_integrals": (c_int, [c_void_p, p_double, p_double, c_char_p, c_size_t]),
            "dfwb_friction_time": (c_double, [c_void_p]),
            "dfwb_friction_events": (ctypes.c_longlong, [c_void_p]),
            "dfwb_friction_harmonics": (c_int, [c_void_p]),
            "dfwb_friction_copy": (c_void_p, [c_void_p]),
            "dfwb_friction_free": (None, [c_void_p]),
        }
        for name, (restype, argtypes) in table.items():
            try:
                function = getattr(lib, name)
            except AttributeError:
                raise CoreError(f"the C core {self.path} has no function {name}") from None
            function.restype, function.argtypes = restype, argtypes
        abi = lib.dfwb_core_abi_version()
        if abi != ABI:
            raise CoreError(f"the C core {self.path} speaks ABI {abi}, this binding {ABI}: rebuild it")
        self.lib = lib
        self.FrictionMass = type("NativeFrictionMass", (NativeFrictionMass,), {"core": self, "__module__": __name__})

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


def _raise(code, buffer, originals=None):
    """Raise the exception of a C status, its message the C text (values named as Python writes them)."""
    message = buffer.value.decode("utf-8", "replace")
    if code in (E_VALUE, E_LIMIT):
        for name, value in (originals or {}).items():
            if type(value) is not float:  # the C text wrote float(value) (or NaN): write it as Python does
                head = f"{name} = {_c_repr(value)} is out of range"
                if message.startswith(head):
                    message = f"{name} = {value!r} is out of range" + message[len(head):]
                tail = f"Fc = {_c_repr(value)} (N)"
                if name == "Fc" and message.endswith(tail):
                    message = message[:-len(tail)] + f"Fc = {value!r} (N)"
        raise PlantError(message)
    if code == E_MATH:
        raise OverflowError(message)
    if code == E_MEMORY:
        raise MemoryError(message)
    raise CoreError(f"C core status {code}: {message}")


def _c_repr(value):
    return repr(_as_double(value))


class NativeFrictionMass:
    """The friction mass solved by the C core: the :class:`~.contract.Solver` protocol of FrictionMass.

    Same keywords and defaults as :class:`~.friction.FrictionMass`; ``core``
    (keyword only) is the :class:`NativeCore` to run on, by default the class's
    own (``load(path).FrictionMass`` is this class bound to that core).
    """

    core = None  # the NativeCore of a bound subclass (NativeCore.FrictionMass)

    def __init__(self, M=1.0, B=0.5, Fc=5.0, Fs=7.0, Dv=0.0, F=0.0, omega=1.0, phi=0.0,
                 x0=0.0, v0=0.0, f=0.0, harmonics=10, *, core=None):
        self._handle = None
        core = core if core is not None else type(self).core
        if core is None:
            raise CoreError("NativeFrictionMass needs a C core: pass core=load(path), or use load(path).FrictionMass")
        values = (M, B, Fc, Fs, Dv, F, omega, phi, x0, v0, f, harmonics)
        params = (ctypes.c_double * len(PARAMETERS))(*(_as_double(v) for v in values))
        handle = ctypes.c_void_p()
        err = ctypes.create_string_buffer(ERRLEN)
        code = core.lib.dfwb_friction_new(params, ctypes.byref(handle), err, ERRLEN)
        if code != OK:
            _raise(code, err, dict(zip(PARAMETERS, values)))
        self._setup(core, handle)

    def _setup(self, core, handle):
        lib = core.lib
        self._core, self._lib, self._handle = core, lib, handle
        self.harmonics = lib.dfwb_friction_harmonics(handle)
        self.event_log = None  # not recorded by the C core
        self._err = ctypes.create_string_buffer(ERRLEN)
        self._out = (ctypes.c_double * 4)()
        self._re = (ctypes.c_double * (self.harmonics + 1))()
        self._im = (ctypes.c_double * (self.harmonics + 1))()

    # -- the Solver protocol ---------------------------------------------------------------
    @property
    def t(self):
        """The current time (s)."""
        return self._lib.dfwb_friction_time(self._handle)

    @property
    def events(self):
        """Events counted so far."""
        return self._lib.dfwb_friction_events(self._handle)

    def set_input(self, f):
        """Set the input force, held constant until the next change (PlantError unless finite)."""
        code = self._lib.dfwb_friction_set_input(self._handle, _as_double(f), self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err, {"f": f})

    def advance(self, t_end):
        """Integrate exactly from self.t to t_end, firing every event on the way."""
        code = self._lib.dfwb_friction_advance(self._handle, _as_double(t_end), self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err, {"t_end": t_end})

    def output(self):
        """x, v, friction force Ff and mode (0 stick or band, +-1 sliding) at self.t."""
        out = self._out
        self._lib.dfwb_friction_output(self._handle, out)
        x, v, ff, mode = out[:]
        return FrictionOutput(x, v, ff, int(mode))

    def integrals(self):
        """Running integrals I_k(t) = int_0^t x exp(-i k omega s) ds, k = 0..harmonics."""
        re, im = self._re, self._im
        code = self._lib.dfwb_friction_integrals(self._handle, re, im, self._err, ERRLEN)
        if code != OK:
            _raise(code, self._err)
        return list(map(complex, re[:], im[:]))

    # -- copies ------------------------------------------------------------------------------
    def copy(self):
        """An independent exact copy (the C instance copied)."""
        handle = self._lib.dfwb_friction_copy(self._handle)
        if not handle:
            raise MemoryError("out of memory (a copy of a dfwb_friction)")
        clone = object.__new__(type(self))
        clone._setup(self._core, ctypes.c_void_p(handle))
        return clone

    __copy__ = copy

    def __deepcopy__(self, memo):
        return self.copy()

    def __reduce__(self):
        raise TypeError("a NativeFrictionMass cannot be pickled (its state lives in the C core)")

    def __del__(self):
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            try:
                self._lib.dfwb_friction_free(handle)
            except Exception:  # noqa: BLE001 - interpreter shutdown: the library may be gone
                pass
