"""One FMU instance, driven through fmpy's FMI 2.0 API and reused across runs.

A describing-function point is a short run, so the cost of an FMU run
matters: instantiating a pythonfmu FMU takes ~30 ms, ``fmi2Reset`` and a new
initialisation ~0.2 ms. :class:`FMUSession` keeps one instance and resets
it. Every FMI call is checked; a refused call raises
:class:`~dfwb.fmi.simulation.FMUError` with the FMU's name, the time and the
FMU's own message. A call refused with fmi2Error leaves the instance usable
(the FMUs' shim keeps it in FMI's Error state until ``fmi2Reset``), so the
next run resets it; after anything worse the instance is abandoned, never
freed: pythonfmu 0.7.0 would release its objects twice after a fatal error.
"""

import itertools

from fmpy.fmi1 import calloc, free
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from dfwb.base import stop
from dfwb.fmi.simulation import FMUError, unpacked

_ABANDONED = []  # failed instances stay referenced for the life of the process
_COUNTER = itertools.count()
ERROR = 3  # fmi2Error

class FMUSession:
    """A reusable co-simulation instance of one FMU."""

    def __init__(self, fmu_path):
        self.directory, description = unpacked(fmu_path)
        self.description = description
        self.name = description.modelName
        self.variables = {v.name: v for v in description.modelVariables}
        self.messages = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._fmu = None
        self._needs_reset = False
        self.time = 0.0

    def _log(self, _env, _instance, status, _category, message):
        if status >= 1 and b"Fatal py exception" not in message:
            self.messages.append(message.decode(errors="replace").strip())

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
        reason = "; ".join(self.messages) or str(error)
        self.messages = []
        raise FMUError(f"{self.name}: {what} failed at t = {self.time!r}: {reason}") from None

    def start(self, values):
        """Reset (or instantiate) the FMU, set ``values`` and initialise it at t = 0."""
        fmu = self._instance()
        self.time = 0.0
        try:
            if self._needs_reset:
                fmu.reset()
            self._needs_reset = True
            reals = [(self.variables[n].valueReference, float(v)) for n, v in values.items()
                     if self.variables[n].type == "Real"]
            integers = [(self.variables[n].valueReference, int(v)) for n, v in values.items()
                        if self.variables[n].type == "Integer"]
            if reals:
                fmu.setReal(*zip(*reals))
            if integers:
                fmu.setInteger(*zip(*integers))
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
        except Exception as error:  # fmpy raises a plain Exception for a refused call
            self._fail("initialisation", error)

    def step(self, size, inputs=None):
        """One communication step of ``size`` from the current time, inputs held over it."""
        fmu = self._fmu
        try:
            if inputs:
                fmu.setReal([self.variables[n].valueReference for n in inputs], list(inputs.values()))
            fmu.doStep(self.time, size)
        except Exception as error:
            self._fail(f"the step of {size!r} s", error)
        self.time += size

    def reals(self, names):
        refs = [self.variables[n].valueReference for n in names]
        return self._fmu.getReal(refs)

    def integers(self, names):
        refs = [self.variables[n].valueReference for n in names]
        return self._fmu.getInteger(refs)
