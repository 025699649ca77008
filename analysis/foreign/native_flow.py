"""The steps of a user's model-exchange FMU in C (``flow.c``): scipy's DOP853 without Python in its stages.

:class:`dfwb.foreign.flow.Flow` steps an FMU with an input law and states of
dfwb's own. With scipy's DOP853 every stage of every step runs Python: the
solver's arithmetic, the law, the rates and six FMU calls through ctypes,
some 85 % of a loop's time for a C FMU. Here a step is one call into C,
which calls the FMU's functions itself; the run's decisions (events,
sections, aiming) stay in Python, per step. The method is scipy's, step for
step (its step-size control, error norm and dense output, its coefficient
tables handed to C), so scipy's DOP853 is the oracle (the tests hold the two
to rounding) and the fallback: where the library cannot be built, where the
law is not one C knows, or with ``DFWB_FOREIGN_FLOW=python``.

Built on first use, with the C core's compiler and flags, into the FMU
folder's ``native/`` (:func:`dfwb.build_fmus.core.build_library`).
"""

import ctypes
import math
import os
import warnings
from pathlib import Path

import numpy as np

from dfwb.base.errors import DfwbError, InputError
from dfwb.fmi.simulation import FMUError
from dfwb.fmi.status import check

__all__ = ["Drive", "Stepper", "choice", "library", "not_finite", "unsolved", "CHOICES", "MAX_ALGEBRAIC",
           "ALGEBRAIC_ULPS", "ALGEBRAIC_TOLERANCE"]

SOURCE = Path(__file__).with_name("flow.c")
MAX_ALGEBRAIC = 50  # rounds of an algebraic loop through a feedthrough (dfwb.foreign.flow.Flow._algebraic)
ALGEBRAIC_ULPS = 4.0  # ... solved when the law's force and the one the output came from differ by this much
ALGEBRAIC_TOLERANCE = ALGEBRAIC_ULPS * np.finfo(float).eps  # (relative)
CHOICES = ("native", "python")  # DFWB_FOREIGN_FLOW
OK, FMI, NOT_FINITE, ALGEBRAIC, TOO_SMALL = range(5)
_CALLS = {False: ("fmi2SetTime", "fmi2SetContinuousStates", "fmi2SetReal", "fmi2GetReal", "fmi2GetDerivatives"),
          True: ("fmi3SetTime", "fmi3SetContinuousStates", "fmi3SetFloat64", "fmi3GetFloat64",
                 "fmi3GetContinuousStateDerivatives")}  # flow.c's calls[], in its order
_P = ctypes.POINTER(ctypes.c_double)
_int, _double = ctypes.c_int, ctypes.c_double


class _Model(ctypes.Structure):
    _fields_ = [("component", ctypes.c_void_p), ("calls", ctypes.c_void_p * 5),
                *((name, _int) for name in ("v3", "nx", "n", "K", "u_integrals", "reads_output",
                                            "max_algebraic")),
                ("input", ctypes.c_uint), ("output", ctypes.c_uint),
                *((name, _double) for name in ("F", "omega_f", "D", "omega", "algebraic_tolerance")),
                ("A", _P), ("B", _P), ("C", _P), ("y", _double), ("u", _double), ("at", _double),
                ("evaluations", ctypes.c_longlong), ("failed_call", _int), ("fmi_status", _int)]


class _Stepper(ctypes.Structure):
    _fields_ = [("n", _int), *((name, _double) for name in ("t", "t_bound", "t_old", "h_abs", "h_previous", "rtol")),
                *((name, _P) for name in ("atol", "y", "y_old", "f", "K", "work", "A", "B", "C", "E3", "E5", "D"))]


class Drive:
    """An input law and extra states C can evaluate: ``u = F cos(omega_f t) - (C w + D y)``, and w' = [A w + B y
    (the controller's n states), y cos(k omega t), y sin(k omega t) for k = 0..K (K = -1: none), u cos(omega t),
    u sin(omega t) (``u_integrals``)]. Its Python methods :meth:`law` and :meth:`rate` are the same formulas,
    for scipy's DOP853 and for the evaluations of a run's decisions."""

    def __init__(self, F=0.0, omega_f=0.0, A=None, B=None, C=None, D=0.0, K=-1, omega=0.0, u_integrals=False):
        self.F, self.omega_f, self.D, self.K, self.omega = float(F), float(omega_f), float(D), int(K), float(omega)
        self.A = np.ascontiguousarray(np.zeros((0, 0)) if A is None else A, dtype=float)
        self.B = np.ascontiguousarray(np.zeros(0) if B is None else B, dtype=float)
        self.C = np.ascontiguousarray(np.zeros(0) if C is None else C, dtype=float)
        self.n = len(self.B)
        self.u_integrals = bool(u_integrals) and self.K >= 1
        self.extra = self.n + (2 * (self.K + 1) + 2 * self.u_integrals if self.K >= 0 else 0)
        self.reads_output = self.D != 0.0
        self._k = np.arange(self.K + 1)

    def law(self, t, w, y):  # (C w is 0.0 without a controller: flow.c's sum, no empty product made here)
        return self.F * math.cos(self.omega_f * t) - ((float(self.C @ w[:self.n]) if self.n else 0.0) + self.D * y)

    def rate(self, t, w, y, u):
        parts = [self.A @ w[:self.n] + self.B * y] if self.n else []
        if self.K >= 0:
            phase = self._k * (self.omega * t)
            parts += [y * np.cos(phase), y * np.sin(phase)]
            if self.u_integrals:
                parts.append([u * np.cos(phase[1]), u * np.sin(phase[1])])
        return np.concatenate(parts) if parts else np.zeros(0)


def not_finite(path, t):
    """The error of a right-hand side that is not finite at t."""
    return FloatingPointError(f"{path}: the output, the input or a derivative is not finite (NaN or overflow) at "
                              f"t = {float(t)!r}")


def unsolved(path, t):
    """The error of an algebraic loop not solved in :data:`MAX_ALGEBRAIC` rounds at t."""
    return FMUError(f"{path}: the algebraic loop through the output at t = {float(t)!r} does not converge in "
                    f"{MAX_ALGEBRAIC} rounds (the output depends on the input directly)")


_LIBRARY = {}


def choice():
    """``DFWB_FOREIGN_FLOW``: "native" (the default) or "python"; InputError otherwise."""
    chosen = os.environ.get("DFWB_FOREIGN_FLOW") or "native"
    if chosen not in CHOICES:
        raise InputError(f"DFWB_FOREIGN_FLOW = {chosen!r} is not allowed: {' or '.join(CHOICES)}")
    return chosen


def library():
    """The compiled ``flow.c`` (a ctypes library), or None: ``DFWB_FOREIGN_FLOW=python``, or it cannot be built
    or loaded (a warning; scipy's DOP853 then runs). Once per process."""
    if choice() == "python":
        return None
    if "lib" not in _LIBRARY:
        from dfwb.build_fmus.core import build_library
        from dfwb.fmi.location import NATIVE_FOLDER, fmu_folder

        try:
            lib = ctypes.CDLL(str(build_library(fmu_folder() / NATIVE_FOLDER, [SOURCE], "libdfwb_flow-",
                                                what="the model-exchange stepper")))
            for name in ("dfwb_flow_rhs", "dfwb_flow_step", "dfwb_flow_dense"):
                getattr(lib, name).restype = _int
            lib.dfwb_flow_rhs.argtypes = [ctypes.POINTER(_Model), _double, _P, _P]
            lib.dfwb_flow_step.argtypes = [ctypes.POINTER(_Model), ctypes.POINTER(_Stepper)]
            lib.dfwb_flow_dense.argtypes = [ctypes.POINTER(_Model), ctypes.POINTER(_Stepper), _P]
        except (DfwbError, OSError) as error:
            warnings.warn(f"the model-exchange stepper in C cannot be used ({error}): scipy's DOP853 runs instead",
                          RuntimeWarning, stacklevel=2)
            lib = None
        _LIBRARY["lib"] = lib
    return _LIBRARY["lib"]


def _tables():
    from scipy.integrate._ivp import dop853_coefficients as c

    return {name: np.ascontiguousarray(value, dtype=float) for name, value in
            dict(A=c.A, B=c.B, C=c.C, E3=c.E3, E5=c.E5, D=c.D).items()}


class Stepper:
    """scipy's DOP853 as :class:`~dfwb.foreign.flow.Flow` uses it (``t``, ``y``, ``h_abs``, ``status``,
    ``step()``, ``dense_output()``), stepped in C. Made by :meth:`for_flow`, which says None where it cannot
    stand in."""

    _TABLES = None

    def __init__(self, lib, flow, model, t0, z, t_bound, rtol, atol, first_step):
        n = len(z)
        self._lib, self._flow, self._model = lib, flow, model
        tables = Stepper._TABLES = Stepper._TABLES or _tables()
        self._arrays = dict(tables, atol=np.ascontiguousarray(np.broadcast_to(atol, (n,)), dtype=float),
                            y=np.array(z, dtype=float), y_old=np.zeros(n), f=np.zeros(n), K=np.zeros(16 * n),
                            work=np.zeros(2 * n))
        rtol = max(float(rtol), 100 * np.finfo(float).eps)  # scipy's floor
        s = self._s = _Stepper(n=n, t=t0, t_bound=t_bound, t_old=t0, h_abs=float(first_step or 0.0),
                               h_previous=0.0, rtol=rtol)
        for name, array in self._arrays.items():
            setattr(s, name, array.ctypes.data_as(_P))
        self._call(lib.dfwb_flow_rhs, ctypes.byref(model), t0, s.y, s.f)
        self.status = "running"
        self.y = self._arrays["y"].copy()

    @classmethod
    def for_flow(cls, flow, t0, z, t_bound, rtol, atol, first_step):
        """A stepper for ``flow`` (its ``drive`` a :class:`Drive`, its instance's hot calls at hand), or None."""
        drive, inst = flow.drive, flow.inst
        if drive is None or not len(z) or first_step is None:
            return None
        lib = library()
        calls = [inst._raw.get(name) for name in _CALLS[inst.v3]]
        if lib is None or any(call is None for call in calls):
            return None
        model = flow.native
        if model is None:
            model = _Model(component=inst._component.value if hasattr(inst._component, "value")
                           else inst._component, v3=int(inst.v3), nx=inst.nx, n=drive.n, K=drive.K,
                           u_integrals=int(drive.u_integrals), reads_output=int(flow.reads_output),
                           max_algebraic=MAX_ALGEBRAIC, input=inst._input[0], output=inst._output[0],
                           F=drive.F, omega_f=drive.omega_f, D=drive.D, omega=drive.omega,
                           algebraic_tolerance=ALGEBRAIC_TOLERANCE,
                           A=drive.A.ctypes.data_as(_P), B=drive.B.ctypes.data_as(_P), C=drive.C.ctypes.data_as(_P))
            for i, call in enumerate(calls):
                model.calls[i] = ctypes.cast(call, ctypes.c_void_p).value
            flow.native = model
        return cls(lib, flow, model, t0, z, t_bound, rtol, atol, first_step)

    @property
    def t(self):
        return self._s.t

    @property
    def h_abs(self):
        return self._s.h_abs

    @h_abs.setter
    def h_abs(self, value):
        self._s.h_abs = value

    def _call(self, function, *args):
        flow, model = self._flow, self._model
        model.y, before = flow._y, model.evaluations
        code = function(*args)
        flow.evaluations += model.evaluations - before
        flow._y = model.y
        flow.inst.time = model.at
        if code in (OK, TOO_SMALL):
            return code
        path = flow.inst.info.path
        if code == FMI:
            check(_CALLS[flow.inst.v3][model.failed_call], model.fmi_status)
        if code == NOT_FINITE:
            raise not_finite(path, model.at)
        if code == ALGEBRAIC:
            raise unsolved(path, model.at)
        raise FMUError(f"{path}: the model-exchange stepper returned {code}")

    def step(self):
        s = self._s
        if s.t == s.t_bound:
            s.t_old = s.t
            self.status = "finished"
            return None
        code = self._call(self._lib.dfwb_flow_step, ctypes.byref(self._model), ctypes.byref(s))
        if code == TOO_SMALL:
            self.status = "failed"
            return "Required step size is less than spacing between numbers."
        self.y = self._arrays["y"].copy()
        self._flow._at = (s.t, self.y)  # the step's last stage was its end: the FMU is there
        if s.t - s.t_bound >= 0:
            self.status = "finished"
        return None

    def dense_output(self):
        s, n = self._s, self._s.n
        F = np.empty((7, n))
        self._call(self._lib.dfwb_flow_dense, ctypes.byref(self._model), ctypes.byref(s), F.ctypes.data_as(_P))
        self._flow._at = None  # the extra stages moved the FMU
        return _Dense(s.t_old, s.t, self._arrays["y_old"].copy(), F)


class _Dense:
    """scipy's DOP853 dense output between t_old and t (its 7 coefficient rows F)."""

    def __init__(self, t_old, t, y_old, F):
        self.t_old, self.h, self.y_old, self.F = t_old, t - t_old, y_old, F

    def __call__(self, t):
        x = (t - self.t_old) / self.h
        y = np.zeros_like(self.y_old)
        for i, f in enumerate(reversed(self.F)):
            y += f
            y *= x if i % 2 == 0 else 1 - x
        return y + self.y_old
