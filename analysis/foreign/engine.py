"""DF points of a user's FMU: the built-in engine's interface, each point computed in the worker process.

:class:`FMUEngine` has :class:`dfwb.engine.describing.DFEngine`'s ``point``
and ``harmonics``, so every study that takes an engine takes this one. Each
point carries its estimated error ``N_error``; a point the FMU could not
give (refused, crashed, hung, NaN) comes back with N = NaN, ``periodic``
False and the reason in its note, and a warning, so a sweep loses one point,
not the run.
"""

import math
import time
import warnings

from dfwb.base.errors import PlantError
from dfwb.engine.describing import HARMONICS, MAX_PERIODS, DFResult, check_point
from dfwb.foreign.worker import TIMEOUT, PointFailed, Worker

__all__ = ["FMUEngine", "RTOL"]

RTOL = {"model-exchange": 1e-10, "co-simulation": 1e-6}  # the drivers' default tolerances


class FMUEngine:
    """DF points of an :class:`~dfwb.foreign.plant.FMUPlant`.

    Parameters
    ----------
    plant : FMUPlant
    harmonics : int
        Harmonics X_0..X_harmonics recorded (1 to 10).
    max_periods : int
        Periods per run (per refinement level for co-simulation) before a response counts as not periodic.
    rtol : float, optional
        The relative accuracy aimed at: the integrator's tolerance (model exchange, default 1e-10),
        or the extrapolated DF's (co-simulation, default 1e-6).
    timeout : float
        Seconds a point may take before its worker is killed and the point skipped.
    """

    def __init__(self, plant, harmonics=HARMONICS, max_periods=150, rtol=None, timeout=TIMEOUT):
        if not (isinstance(harmonics, int) and 1 <= harmonics <= HARMONICS):
            raise PlantError(f"harmonics = {harmonics!r} is out of range: an integer from 1 to {HARMONICS}")
        if not (isinstance(max_periods, int) and 1 <= max_periods <= MAX_PERIODS):
            raise PlantError(f"max_periods = {max_periods!r} is out of range: an integer from 1 to {MAX_PERIODS}")
        rtol = RTOL[plant.kind] if rtol is None else rtol
        if not (isinstance(rtol, (int, float)) and 1e-13 <= rtol <= 1e-2):
            raise PlantError(f"rtol = {rtol!r} is out of range: a number from 1e-13 to 0.01")
        if not (isinstance(timeout, (int, float)) and 0.1 <= timeout <= 86400):
            raise PlantError(f"timeout = {timeout!r} is out of range: seconds from 0.1 to 86400")
        self.plant, self.harmonics, self.max_periods = plant, harmonics, max_periods
        self.rtol, self.drive = float(rtol), plant.kind
        self._worker = Worker(float(timeout))

    def point(self, F, omega, params=None):
        """The DFResult at force amplitude F and frequency omega (N NaN and a note if the FMU failed)."""
        started = time.perf_counter()
        check_point(F, omega)
        params = self.plant.check(params or {})
        request = {"info": self.plant.info, "kind": self.plant.kind, "input": self.plant.input,
                   "output": self.plant.output, "F": float(F), "omega": float(omega), "params": params,
                   "harmonics": self.harmonics, "rtol": self.rtol, "max_periods": self.max_periods}
        try:
            answer = self._worker.call(request, f"{self.plant.name} at F = {F:g}, omega = {omega:g}")
        except PointFailed as failure:
            warnings.warn(str(failure), RuntimeWarning, stacklevel=2)
            nan = complex(math.nan, math.nan)
            return DFResult(plant=self.plant.name, F=F, omega=omega, params=params, N=nan,
                            harmonics=[math.nan] * (self.harmonics + 1), periodic=False, periods=0,
                            seconds=time.perf_counter() - started, drive=self.drive,
                            note=f"failed: {failure}", X=[nan] * (self.harmonics + 1), N_error=math.inf)
        X = answer["X"]
        return DFResult(plant=self.plant.name, F=F, omega=omega, params=params, N=X[1] / F,
                        harmonics=[abs(x) for x in X], periodic=answer["periodic"], periods=answer["periods"],
                        seconds=time.perf_counter() - started, drive=self.drive, note=answer["note"],
                        orbit_periods=answer["lag"], X=X, N_error=answer["error"] / F)

    def close(self):
        self._worker.close()

