"""One instance of a user's FMU, FMI 2.0 or 3.0, model exchange or co-simulation, behind one small interface.

The drivers (:mod:`dfwb.foreign.model_exchange`, :mod:`dfwb.foreign.held`)
speak only to :class:`Instance`; the differences between the four FMI
flavours (fmpy's ``FMU2Model``, ``FMU2Slave``, ``FMU3Model``, ``FMU3Slave``)
stay here. Every FMI call is checked by fmpy; a refused call becomes
:class:`~dfwb.fmi.simulation.FMUError` with the FMU's own log lines. Runs
only inside a worker process (:mod:`dfwb.foreign.worker`): this is where the
FMU's native code is loaded.
"""

import ctypes
import itertools

import numpy as np

from dfwb.fmi.simulation import FMUError
from dfwb.fmi.status import Messages, check
from dfwb.foreign.description import MAX_EVENT_INDICATORS

__all__ = ["Instance"]

_COUNTER = itertools.count()
_DOUBLES = ctypes.POINTER(ctypes.c_double)


def _pointer(array):
    return array.ctypes.data_as(_DOUBLES)


class Instance:
    """A live FMU instance: start it with parameters and an input value, then step or evaluate it.

    Parameters
    ----------
    info : FMUInfo
    kind : {"model-exchange", "co-simulation"}
    input, output : str
        The force input and the position output.
    """

    def __init__(self, info, kind, input, output):
        from fmpy import read_model_description
        from fmpy.fmi2 import FMU2Model, FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.fmi3 import FMU3Model, FMU3Slave

        self.info, self.kind = info, kind
        self.v3 = info.major == "3"
        md = read_model_description(info.folder, validate=False)
        self.variables = {v.name: v for v in md.modelVariables}
        classes = {("2", "model-exchange"): FMU2Model, ("2", "co-simulation"): FMU2Slave,
                   ("3", "model-exchange"): FMU3Model, ("3", "co-simulation"): FMU3Slave}
        self.messages = Messages()
        token = md.instantiationToken if self.v3 else md.guid
        self.fmu = classes[info.major, kind](guid=token, unzipDirectory=info.folder,
                                             modelIdentifier=info.identifiers[kind],
                                             instanceName=f"dfwb{next(_COUNTER)}")
        # FMI 3.0 co-simulation that asks for the force inside its steps: given there, from the input law
        self.intermediate = self.v3 and kind == "co-simulation" and input in info.intermediate_inputs
        self.input_law, self.refused = None, None
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
        else:
            self._callbacks = fmi2CallbackFunctions()
            self._callbacks.logger = fmi2CallbackLoggerTYPE(self.messages.fmi2())
            from fmpy.fmi1 import calloc, free
            from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE

            self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self.fmu.instantiate(loggingOn=True, callbacks=self._callbacks)
        self._input = self._refs([input])
        self._output = self._refs([output])
        self._u, self._y = np.zeros(1), np.zeros(1)
        self._u_at, self._y_at = _pointer(self._u), _pointer(self._y)  # made once: a right-hand side is hot
        # the hot calls straight to the FMU's functions, their status checked here: fmpy's wrapper of each
        # call (a dictionary look-up, its logger, its check) was a third of a held step's time
        functions, self._component = getattr(self.fmu, "_functions", {}), self.fmu.component
        self._raw = {name: functions[name] for name in (
            "fmi2SetReal", "fmi2GetReal", "fmi2DoStep", "fmi2GetFMUstate", "fmi2SetTime", "fmi2SetContinuousStates",
            "fmi2GetDerivatives", "fmi2GetEventIndicators", "fmi3SetFloat64", "fmi3GetFloat64", "fmi3SetTime",
            "fmi3SetContinuousStates", "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators")
            if name in functions and getattr(functions[name], "argtypes", None) is not None}
        self._started = False
        self.nx = self.nz = 0
        self.time = 0.0

    # -- helpers ---------------------------------------------------------------------------------
    def _fast(self, name, *args):
        """fmpy's checked call ``name``, made straight to the FMU's function (fmpy's own check: a status
        above warning raises its FMICallException)."""
        function = self._raw.get(name)
        if function is None:
            return getattr(self.fmu, name)(*args)
        return check(name, function(*args))

    def _refs(self, names):
        return (ctypes.c_uint * len(names))(*(self.variables[n].valueReference for n in names))

    def failed(self, what, error):
        """The FMUError for a refused call, with the FMU's own messages."""
        reason = self.messages.reasons(otherwise=str(error))
        return FMUError(f"{self.info.path}: {what} failed at t = {self.time!r}: {' '.join(reason.split())[:400]}")

    def _set(self, name, value):
        variable = self.variables[name]
        kind = variable.type
        ref = [variable.valueReference]
        if self.v3:
            setter = "setFloat64" if kind == "Float64" else "setFloat32" if kind == "Float32" else \
                "setBoolean" if kind == "Boolean" else "setInt64" if kind == "Enumeration" else f"set{kind}"
            converted = bool(value) if kind == "Boolean" else value if kind.startswith("Float") else int(value)
            getattr(self.fmu, setter)(ref, [converted])
        elif kind == "Real":
            self.fmu.setReal(ref, [value])
        elif kind == "Boolean":
            self.fmu.setBoolean(ref, [bool(value)])
        else:
            self.fmu.setInteger(ref, [int(value)])

    # -- life cycle --------------------------------------------------------------------------------
    def start(self, params, u0):
        """Reset (after a first run), set the parameters and the input u0, initialise at t = 0."""
        fmu = self.fmu
        self.time = 0.0
        if self._started:
            fmu.reset()
        self._started = True
        for name, value in params.items():
            self._set(name, value)
        self.set_input(u0)
        if self.v3:
            fmu.enterInitializationMode(startTime=0.0)
        else:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
        self.set_input(u0)
        fmu.exitInitializationMode()
        if self.kind == "co-simulation":
            if self.v3:
                fmu.enterStepMode()
            return None
        if self.v3:  # an FMI 3.0 FMU tells its sizes at run time: checked as its description's would be
            self.nx, self.nz = fmu.getNumberOfContinuousStates(), fmu.getNumberOfEventIndicators()
            if not (0 <= self.nx <= MAX_EVENT_INDICATORS and 0 <= self.nz <= MAX_EVENT_INDICATORS):
                raise FMUError(f"the FMU reports {self.nx} continuous states and {self.nz} event indicators "
                               f"(each 0 to {MAX_EVENT_INDICATORS})")
        else:
            self.nx, self.nz = self.info.states, self.info.event_indicators
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
        """The Real outputs ``names`` now (a trace's)."""
        refs = [self.variables[n].valueReference for n in names]
        return self.fmu.getFloat64(refs) if self.v3 else self.fmu.getReal(refs)

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
            raise FMUError(f"{self.info.path}: the FMU asked to terminate at t = {self.time!r}")
        return bool(enter)

    def update_discrete(self):
        """The event iteration (in event mode); returns the next time event or None. Bounded."""
        update = self.fmu.updateDiscreteStates if self.v3 else self.fmu.newDiscreteStates
        for _ in range(1000):
            needed, terminate, _nominals, _values, time_defined, next_time = update()
            if terminate:
                raise FMUError(f"{self.info.path}: the FMU asked to terminate at t = {self.time!r}")
            if not needed:
                return float(next_time) if time_defined else None
        raise FMUError(f"{self.info.path}: the event iteration at t = {self.time!r} did not end in 1000 rounds")

    def event(self):
        """Handle an event at the current time and state; returns the next time event or None."""
        self.fmu.enterEventMode()
        next_time = self.update_discrete()
        self.fmu.enterContinuousTimeMode()
        return next_time

    # -- co-simulation ---------------------------------------------------------------------------------
    def do_step(self, size):
        fmu = self.fmu
        if self.v3:
            _event, terminate, early, reached = fmu.doStep(self.time, size)
            if self.refused is not None:
                raise self.failed("setting the force inside a step (intermediate update)", self.refused)
            if terminate or early:
                raise FMUError(f"{self.info.path}: the step from t = {self.time!r} ended early at {reached!r}")
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
