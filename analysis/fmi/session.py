"""One FMU instance, driven through fmpy's FMI 2.0 API and reused across runs.

A describing-function point is a short run, so the cost of an FMU run
matters: instantiating a pythonfmu FMU takes ~30 ms, ``fmi2Reset`` and a new
initialisation ~0.2 ms (a native FMU: microseconds). :class:`FMUSession` keeps
one instance and resets it. The calls a DF point repeats (initialisation,
doStep, the per-period reads) go to the FMI functions fmpy has declared,
without its Python wrapper, with the same status checks: on the native FMUs
that wrapper was a third of a point's cost. Every FMI call is checked; a refused call raises
:class:`~dfwb.fmi.simulation.FMUError` with the FMU's name, the time and the
FMU's own message. A call refused with fmi2Error leaves the instance usable
(the FMUs' shim keeps it in FMI's Error state until ``fmi2Reset``), so the
next run resets it; after anything worse the instance is abandoned, never
freed: pythonfmu 0.7.0 would release its objects twice after a fatal error.
"""

import ctypes
import itertools

from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from dfwb.base import stop
from dfwb.fmi.simulation import FMUError, unpacked
from dfwb.fmi.status import ERROR, Messages, check

_ABANDONED = []  # failed instances stay referenced for the life of the process
_COUNTER = itertools.count()

class FMUSession:
    """A reusable co-simulation instance of one FMU."""

    def __init__(self, fmu_path):
        self.directory, description = unpacked(fmu_path)
        self.description = description
        self.name = description.modelName
        self.variables = {v.name: v for v in description.modelVariables}
        self.messages = Messages()
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self.messages.fmi2())
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._fmu = None
        self._needs_reset = False
        self._setter_cache = {}
        self.time = 0.0

    def _instance(self):
        if self._fmu is None:
            self._fmu = FMU2Slave(guid=self.description.guid, unzipDirectory=self.directory,
                                  modelIdentifier=self.description.coSimulation.modelIdentifier,
                                  instanceName=f"{self.name}_{next(_COUNTER)}")
            self._fmu.instantiate(loggingOn=True, callbacks=self._callbacks)
            self._needs_reset = False
        return self._fmu

    def _fail(self, what, error):
        if getattr(error, "status", None) == ERROR:  # refused: reset before the next run
            self._needs_reset = True
        else:
            _ABANDONED.append((self._fmu, self._callbacks))
            self._fmu = None
        if stop.requested():  # a Ctrl-C or kill that landed inside the FMU's Python code
            raise KeyboardInterrupt
        reason = self.messages.reasons(otherwise=str(error))
        raise FMUError(f"{self.name}: {what} failed at t = {self.time!r}: {reason}") from None

    def start(self, values):
        """Reset (or instantiate) the FMU, set ``values`` and initialise it at t = 0."""
        fmu = self._instance()
        self.time = 0.0
        dll, component = fmu.dll, fmu.component  # the FMI functions as fmpy declared them, without its wrapper
        try:
            if self._needs_reset:
                check("fmi2Reset", dll.fmi2Reset(component))
            self._needs_reset = True
            for name, refs, ctype, convert, names in self._setters(tuple(values)):
                numbers = (ctype * len(names))(*(convert(values[n]) for n in names))
                check(name, getattr(dll, name)(component, refs, len(names), numbers))
            check("fmi2SetupExperiment", dll.fmi2SetupExperiment(component, 0, 0.0, 0.0, 0, 0.0))
            check("fmi2EnterInitializationMode", dll.fmi2EnterInitializationMode(component))
            check("fmi2ExitInitializationMode", dll.fmi2ExitInitializationMode(component))
        except Exception as error:  # a refused call, or a value ctypes cannot convert
            self._fail("initialisation", error)

    def _setters(self, names):
        """[(FMI setter, value references, C type, conversion, names)] for values of these names (made once)."""
        found = self._setter_cache.get(names)
        if found is None:
            found = []
            for kind, setter, ctype, convert in (("Real", "fmi2SetReal", ctypes.c_double, float),
                                                 ("Integer", "fmi2SetInteger", ctypes.c_int, int)):
                chosen = [n for n in names if self.variables[n].type == kind]
                if chosen:
                    refs = (ctypes.c_uint * len(chosen))(*(self.variables[n].valueReference for n in chosen))
                    found.append((setter, refs, ctype, convert, chosen))
            if len(self._setter_cache) < 64:  # a run uses one or two sets of names
                self._setter_cache[names] = found
        return found

    def step(self, size, inputs=None):
        """One communication step of ``size`` from the current time, inputs held over it."""
        fmu = self._fmu
        try:
            if inputs:
                fmu.setReal([self.variables[n].valueReference for n in inputs], list(inputs.values()))
            check("fmi2DoStep", fmu.dll.fmi2DoStep(fmu.component, self.time, size, 1))
        except Exception as error:
            self._fail(f"the step of {float(size)!r} s", error)
        self.time += size

    def reader(self, reals, integers):
        """``read() -> (list of reals, list of integers)``: these variables now, in two FMI calls.

        The value references and buffers are made once, for a run's repeated
        reads (the DF engine reads the same variables every period).
        """
        real_refs = (ctypes.c_uint * len(reals))(*(self.variables[n].valueReference for n in reals))
        integer_refs = (ctypes.c_uint * len(integers))(*(self.variables[n].valueReference for n in integers))
        real_values, integer_values = (ctypes.c_double * len(reals))(), (ctypes.c_int * len(integers))()

        def read():
            fmu = self._fmu
            try:
                check("fmi2GetReal", fmu.dll.fmi2GetReal(fmu.component, real_refs, len(reals), real_values))
                check("fmi2GetInteger",
                       fmu.dll.fmi2GetInteger(fmu.component, integer_refs, len(integers), integer_values))
            except FMICallException as error:
                self._fail("reading the outputs", error)
            return real_values[:], integer_values[:]

        return read

    def reals(self, names):
        refs = [self.variables[n].valueReference for n in names]
        return self._fmu.getReal(refs)

    def integers(self, names):
        refs = [self.variables[n].valueReference for n in names]
        return self._fmu.getInteger(refs)
