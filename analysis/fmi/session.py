"""One of dfwb's own FMUs, kept instantiated and reset between runs.

A describing-function point is a short run, so the cost of an FMU run
matters: instantiating a pythonfmu FMU takes ~30 ms, ``fmi2Reset`` and a new
initialisation ~0.2 ms (a native FMU: microseconds). :class:`FMUSession` keeps
one :class:`~dfwb.fmi.instance.Instance` and resets it. Every FMI call is
checked; a refused call raises :class:`~dfwb.fmi.simulation.FMUError` with
the FMU's name, the time and the FMU's own message. A call refused with
fmi2Error leaves the instance usable (the FMUs' shim keeps it in FMI's Error
state until ``fmi2Reset``), so the next run resets it; after anything worse
the instance is abandoned, never freed: pythonfmu 0.7.0 would release its
objects twice after a fatal error.
"""

from dfwb.base import stop
from dfwb.fmi.instance import Instance
from dfwb.fmi.simulation import FMUError, unpacked
from dfwb.fmi.status import ERROR

_ABANDONED = []  # failed instances stay referenced for the life of the process


class FMUSession:
    """A reusable co-simulation instance of one FMU."""

    def __init__(self, fmu_path):
        self.directory, self.description = unpacked(fmu_path)
        self.name = self.description.modelName
        self.variables = {v.name: v for v in self.description.modelVariables}
        self._instance = None
        self._time = 0.0

    @property
    def time(self):
        """The FMU's time: where the next step starts."""
        return self._time if self._instance is None else self._instance.time

    @time.setter
    def time(self, value):  # a master that keeps its own clock (libcosim's whole nanoseconds) sets it
        if self._instance is None:
            self._time = value
        else:
            self._instance.time = value

    def _live(self):
        if self._instance is None:
            self._instance = Instance(self.directory, "co-simulation", label=self.name, description=self.description)
        return self._instance

    def _fail(self, what, error):
        instance = self._instance
        self._time = instance.time
        if getattr(error, "status", None) != ERROR:  # worse than refused: abandoned; a refused one is reset
            _ABANDONED.append(instance)
            self._instance = None
        if stop.requested():  # a Ctrl-C or kill that landed inside the FMU's Python code
            raise KeyboardInterrupt
        raise (error if isinstance(error, FMUError) else instance.failed(what, error)) from None

    def start(self, values):
        """Reset (or instantiate) the FMU, set ``values`` and initialise it at t = 0."""
        instance = self._live()
        try:
            instance.start(values)
        except Exception as error:  # a refused call, or a value ctypes cannot convert
            self._fail("initialisation", error)

    def step(self, size, inputs=None):
        """One communication step of ``size`` from the current time, inputs held over it."""
        instance = self._instance
        try:
            instance.set(inputs)
            instance.do_step(size)
        except Exception as error:
            self._fail(f"the step of {float(size)!r} s", error)

    def reader(self, reals, integers):
        """``read() -> (list of reals, list of integers)``: these variables now, in two FMI calls.

        The value references and buffers are made once, for a run's repeated
        reads (the DF engine reads the same variables every period); a
        session's instance may be replaced after a fatal error, and the
        reader follows it.
        """
        made = {}

        def read():
            instance = self._instance
            try:
                fast = made.get(id(instance))
                if fast is None:
                    made.clear()
                    fast = made[id(instance)] = instance.reader(reals, integers)
                return fast()
            except Exception as error:
                self._fail("reading the outputs", error)

        return read

    def reals(self, names):
        return self._instance.read(names)

    def integers(self, names):
        return self._instance.integers(names)
