"""One live FMU instance, FMI 2.0 or 3.0, co-simulation or model exchange: the one place dfwb calls an FMU.

Every FMU dfwb runs call by call goes through :class:`Instance`: its own
plants' sessions (:mod:`dfwb.fmi.session`) and a user's FMU in a worker
process (:mod:`dfwb.foreign`). The differences between fmpy's four classes
(``FMU2Model``, ``FMU2Slave``, ``FMU3Model``, ``FMU3Slave``) stay here. The
calls a run repeats (setting values, a step, a read, a model-exchange
evaluation) go straight to the FMI functions fmpy has declared, without its
Python wrapper (a dictionary look-up, its logger and its check were a third
of a step's time), their status checked by :func:`dfwb.fmi.status.check`,
fmpy's own rule. The FMU's log lines are kept by a
:class:`~dfwb.fmi.status.Messages` and named in the
:class:`~dfwb.fmi.simulation.FMUError` of a refused call (:meth:`failed`).
"""

import ctypes
import itertools

import numpy as np

from dfwb.fmi.simulation import FMUError
from dfwb.fmi.status import Messages, check

__all__ = ["Instance"]

_COUNTER = itertools.count()
_DOUBLES = ctypes.POINTER(ctypes.c_double)
_RAW = ("fmi2Reset", "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean", "fmi2GetReal", "fmi2GetInteger",
        "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2DoStep",
        "fmi2GetFMUstate", "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives", "fmi2GetEventIndicators",
        "fmi3SetFloat64", "fmi3GetFloat64", "fmi3SetTime", "fmi3SetContinuousStates",
        "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators")
# FMI 2.0's setters of a batch of values, by variable type: (function, C type, conversion)
_SETTERS2 = {"Real": ("fmi2SetReal", ctypes.c_double, float), "Integer": ("fmi2SetInteger", ctypes.c_int, int),
             "Enumeration": ("fmi2SetInteger", ctypes.c_int, int), "Boolean": ("fmi2SetBoolean", ctypes.c_int, bool)}


def _pointer(array):
    return array.ctypes.data_as(_DOUBLES)


class Instance:
    """A live FMU instance: start it with values (and an input), then step, read or evaluate it.

    Parameters
    ----------
    folder : path
        The unpacked FMU.
    kind : {"co-simulation", "model-exchange"}
    label : str
        What names the FMU in errors (its path, or its model's name).
    description : fmpy ModelDescription, optional
        Read from ``folder`` when not given.
    identifier : str, optional
        The interface's modelIdentifier (default: the description's).
    input, output : str, optional
        A force input and a position output, set and read by :meth:`set_input` and :meth:`output`.
    intermediate : bool
        FMI 3.0 co-simulation: the FMU asks for ``input`` inside its steps (intermediate update); it is
        given there from :attr:`input_law`.
    sizes : (int, int), optional
        FMI 2.0 model exchange: the continuous states and event indicators (FMI 3.0 tells them at run time).
    max_size : int, optional
        FMI 3.0 model exchange: the most states or event indicators accepted when the FMU tells them.
    """

    def __init__(self, folder, kind="co-simulation", *, label, description=None, identifier=None, input=None,
                 output=None, intermediate=False, sizes=(0, 0), max_size=None):
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Model, FMU2Slave
        from fmpy.fmi3 import FMU3Model, FMU3Slave

        md = description if description is not None else read_model_description(folder, validate=False)
        self.kind, self.label = kind, label
        self.v3 = md.fmiVersion.startswith("3")
        self.variables = {v.name: v for v in md.modelVariables}
        if identifier is None:
            identifier = (md.coSimulation if kind == "co-simulation" else md.modelExchange).modelIdentifier
        classes = {(False, "model-exchange"): FMU2Model, (False, "co-simulation"): FMU2Slave,
                   (True, "model-exchange"): FMU3Model, (True, "co-simulation"): FMU3Slave}
        self.messages = Messages()
        self.fmu = classes[self.v3, kind](guid=md.instantiationToken if self.v3 else md.guid, unzipDirectory=folder,
                                          modelIdentifier=identifier, instanceName=f"dfwb{next(_COUNTER)}")
        self.intermediate = bool(intermediate)
        self.input_law, self.refused = None, None
        self._instantiate()
        self._input = self._refs([input]) if input is not None else None
        self._output = self._refs([output]) if output is not None else None
        self._u, self._y = np.zeros(1), np.zeros(1)
        self._u_at, self._y_at = _pointer(self._u), _pointer(self._y)  # made once: a right-hand side is hot
        functions, self._component = getattr(self.fmu, "_functions", {}), self.fmu.component
        self._raw = {name: functions[name] for name in _RAW
                     if name in functions and getattr(functions[name], "argtypes", None) is not None}
        self._setters = {}
        self._started = False
        self.nx, self.nz = sizes if kind == "model-exchange" and not self.v3 else (0, 0)
        self.max_size = max_size
        self.time = 0.0

    def _instantiate(self):
        if self.v3:
            log = self.messages.fmi3()
            if self.intermediate:
                def update(_env, time, set_requested, _get_allowed, _finished, _can_return, early, _early_time):
                    early[0] = False
                    if set_requested and self.input_law is not None:
                        try:  # (an exception cannot cross the FMU's C frames: kept for do_step to raise)
                            self.set_input(self.input_law(time))
                        except Exception as error:  # noqa: BLE001
                            self.refused = self.refused or error

                self.fmu.instantiate(loggingOn=True, logMessage=log, intermediateUpdate=update)
            else:
                self.fmu.instantiate(loggingOn=True, logMessage=log)
            return
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self._callbacks = fmi2CallbackFunctions()  # kept alive as long as the instance
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self.messages.fmi2())
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu.instantiate(loggingOn=True, callbacks=self._callbacks)

    # -- helpers ---------------------------------------------------------------------------------
    def _fast(self, name, *args):
        """fmpy's checked call ``name``, made straight to the FMU's function (a status above warning raises
        fmpy's FMICallException)."""
        function = self._raw.get(name)
        if function is None:
            return getattr(self.fmu, name)(*args)
        return check(name, function(*args))

    def _refs(self, names):
        return (ctypes.c_uint * len(names))(*(self.variables[n].valueReference for n in names))

    def failed(self, what, error):
        """The FMUError for a refused call, with the FMU's own messages."""
        reason = self.messages.reasons(otherwise=str(error))
        return FMUError(f"{self.label}: {what} failed at t = {self.time!r}: {' '.join(reason.split())[:400]}")

    def set(self, values):
        """Set variables by name, each as its type wants (FMI 2.0: one call per type, made once per set of names)."""
        if not values:
            return
        names = tuple(values)
        if self.v3:
            for name in names:
                self._set3(name, values[name])
            return
        batches = self._setters.get(names)
        if batches is None:
            batches = []
            for setter, ctype, convert in dict.fromkeys(_SETTERS2.values()):
                chosen = [n for n in names if _SETTERS2.get(self.variables[n].type, _SETTERS2["Integer"])[0] == setter]
                if chosen:
                    batches.append((setter, self._refs(chosen), ctype, convert, chosen))
            if len(self._setters) < 64:  # a run uses one or two sets of names
                self._setters[names] = batches
        for setter, refs, ctype, convert, chosen in batches:
            numbers = (ctype * len(chosen))(*(convert(values[n]) for n in chosen))
            self._fast(setter, self._component, refs, len(chosen), numbers)

    def _set3(self, name, value):
        variable = self.variables[name]
        kind = variable.type
        setter = "setFloat64" if kind == "Float64" else "setFloat32" if kind == "Float32" else \
            "setBoolean" if kind == "Boolean" else "setInt64" if kind == "Enumeration" else f"set{kind}"
        converted = bool(value) if kind == "Boolean" else value if kind.startswith("Float") else int(value)
        getattr(self.fmu, setter)([variable.valueReference], [converted])

    # -- life cycle --------------------------------------------------------------------------------
    def start(self, params, u0=None):
        """Reset (after a first run), set the parameters and the input u0, initialise at t = 0.

        Returns the next time event of a model-exchange FMU (or None).
        """
        fmu = self.fmu
        self.time = 0.0
        if self._started:
            if self.v3:
                fmu.reset()
            else:
                self._fast("fmi2Reset", self._component)
        self._started = True
        self.set(params)
        if u0 is not None:
            self.set_input(u0)
        if self.v3:
            fmu.enterInitializationMode(startTime=0.0)
        else:
            self._fast("fmi2SetupExperiment", self._component, 0, 0.0, 0.0, 0, 0.0)
            self._fast("fmi2EnterInitializationMode", self._component)
        if u0 is not None:
            self.set_input(u0)
        if self.v3:
            fmu.exitInitializationMode()
        else:
            self._fast("fmi2ExitInitializationMode", self._component)
        if self.kind == "co-simulation":
            if self.v3:
                fmu.enterStepMode()
            return None
        if self.v3:  # an FMI 3.0 FMU tells its sizes at run time: checked as its description's would be
            self.nx, self.nz = fmu.getNumberOfContinuousStates(), fmu.getNumberOfEventIndicators()
            most = self.max_size if self.max_size is not None else max(self.nx, self.nz)
            if not (0 <= self.nx <= most and 0 <= self.nz <= most):
                raise FMUError(f"the FMU reports {self.nx} continuous states and {self.nz} event indicators "
                               f"(each 0 to {most})")
        self._x, self._dx, self._z = np.zeros(self.nx), np.zeros(self.nx), np.zeros(self.nz)
        self._x_at, self._dx_at, self._z_at = _pointer(self._x), _pointer(self._dx), _pointer(self._z)
        next_time = self.update_discrete()
        fmu.enterContinuousTimeMode()
        return next_time

    # -- signals ----------------------------------------------------------------------------------
    def set_input(self, u):
        self._u[0] = u
        if self.v3:
            self._fast("fmi3SetFloat64", self._component, self._input, 1, self._u_at, 1)
        else:
            self._fast("fmi2SetReal", self._component, self._input, 1, self._u_at)

    def set_input_slope(self, slope):
        """The input's first derivative over the next step (FMI 2.0 co-simulation that can interpolate inputs)."""
        self.fmu.setRealInputDerivatives(list(self._input), [1], [slope])

    def output(self):
        if self.v3:
            self._fast("fmi3GetFloat64", self._component, self._output, 1, self._y_at, 1)
        else:
            self._fast("fmi2GetReal", self._component, self._output, 1, self._y_at)
        return float(self._y[0])

    def read(self, names):
        """The Real variables ``names`` now."""
        refs = [self.variables[n].valueReference for n in names]
        return self.fmu.getFloat64(refs) if self.v3 else self.fmu.getReal(refs)

    def integers(self, names):
        """The Integer variables ``names`` now."""
        refs = [self.variables[n].valueReference for n in names]
        return self.fmu.getInt32(refs) if self.v3 else self.fmu.getInteger(refs)

    def reader(self, reals, integers):
        """``read() -> (list of reals, list of integers)``: these variables now; the value references and
        buffers are made once, for a run's repeated reads (the DF engine reads the same ones every period)."""
        if self.v3:
            return lambda: (self.read(reals), self.integers(integers))
        real_refs, integer_refs = self._refs(reals), self._refs(integers)
        real_values, integer_values = (ctypes.c_double * len(reals))(), (ctypes.c_int * len(integers))()
        get_real, get_integer, component = self._raw["fmi2GetReal"], self._raw["fmi2GetInteger"], self._component

        def read():
            check("fmi2GetReal", get_real(component, real_refs, len(reals), real_values))
            check("fmi2GetInteger", get_integer(component, integer_refs, len(integers), integer_values))
            return real_values[:], integer_values[:]

        return read

    # -- model exchange -------------------------------------------------------------------------------
    def set_continuous(self, t, x, u):
        """Time, states and input for the next evaluation."""
        self.time = t
        v3 = self.v3
        self._fast("fmi3SetTime" if v3 else "fmi2SetTime", self._component, t)
        if self.nx:
            self._x[:] = x
            self._fast("fmi3SetContinuousStates" if v3 else "fmi2SetContinuousStates", self._component, self._x_at,
                       self.nx)
        self.set_input(u)

    def derivatives(self):
        if not self.nx:
            return self._dx
        if self.v3:
            self._fast("fmi3GetContinuousStateDerivatives", self._component, self._dx_at, self.nx)
        else:
            self._fast("fmi2GetDerivatives", self._component, self._dx_at, self.nx)
        return self._dx

    def indicators(self):
        if self.nz:
            self._fast("fmi3GetEventIndicators" if self.v3 else "fmi2GetEventIndicators", self._component,
                       self._z_at, self.nz)
        return self._z

    def states(self):
        if self.nx:
            self.fmu.getContinuousStates(self._x_at, self.nx)
        return self._x.copy()

    def completed_step(self):
        """True if the FMU asks for event mode after an accepted integrator step."""
        enter, terminate = self.fmu.completedIntegratorStep()
        if terminate:
            raise FMUError(f"{self.label}: the FMU asked to terminate at t = {self.time!r}")
        return bool(enter)

    def update_discrete(self):
        """The event iteration (in event mode); returns the next time event or None. Bounded."""
        update = self.fmu.updateDiscreteStates if self.v3 else self.fmu.newDiscreteStates
        for _ in range(1000):
            needed, terminate, _nominals, _values, time_defined, next_time = update()
            if terminate:
                raise FMUError(f"{self.label}: the FMU asked to terminate at t = {self.time!r}")
            if not needed:
                return float(next_time) if time_defined else None
        raise FMUError(f"{self.label}: the event iteration at t = {self.time!r} did not end in 1000 rounds")

    def event(self):
        """Handle an event at the current time and state; returns the next time event or None."""
        self.fmu.enterEventMode()
        next_time = self.update_discrete()
        self.fmu.enterContinuousTimeMode()
        return next_time

    # -- co-simulation ---------------------------------------------------------------------------------
    def do_step(self, size):
        if self.v3:
            _event, terminate, early, reached = self.fmu.doStep(self.time, size)
            if self.refused is not None:
                raise self.failed("setting the force inside a step (intermediate update)", self.refused)
            if terminate or early:
                raise FMUError(f"{self.label}: the step from t = {self.time!r} ended early at {reached!r}")
        else:
            self._fast("fmi2DoStep", self._component, self.time, size, 1)
        self.time += size

    def save(self, into=None):
        """The FMU's state; ``into``: a state from an earlier save, overwritten (no allocation per call)."""
        if into is None:
            return self.fmu.getFMUState() if self.v3 else self.fmu.getFMUstate()
        if self.v3:
            self.fmu.fmi3GetFMUState(self.fmu.component, ctypes.byref(into))
        else:
            self._fast("fmi2GetFMUstate", self._component, ctypes.byref(into))
        return into

    def free(self, state):
        """Release a state from :meth:`save`."""
        if self.v3:
            self.fmu.freeFMUState(state)
        else:
            self.fmu.freeFMUstate(state)

    def restore(self, state, time):
        if self.v3:
            self.fmu.setFMUState(state)
        else:
            self.fmu.setFMUstate(state)
        self.time = time
