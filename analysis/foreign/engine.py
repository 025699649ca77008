"""DF points of a user's FMU: the built-in engine's interface, each point computed in a worker process.

:func:`engine_for` is the one place that chooses the engine of a plant: the
exact built-in :class:`dfwb.engine.describing.DFEngine`, or :class:`FMUEngine`
for a user's FMU. :class:`FMUEngine` has the built-in engine's ``point`` and
``harmonics``, so every study that takes an engine takes this one, and
``points`` to spread a row of a map over several workers. Each
point carries its estimated error ``N_error``; a point the FMU could not
give (refused, crashed, hung, NaN) comes back with N = NaN, ``periodic``
False and the reason in its note, and a warning, so a sweep loses one point,
not the run.
"""

import math
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor

from dfwb.base.defaults import DF_PERIODS, HARMONICS, SAMPLES_PER_PERIOD
from dfwb.base.errors import InputError, PlantError, fmu_only
from dfwb.engine.describing import MAX_PERIODS, DFEngine, DFResult, check_point
from dfwb.foreign import native_flow
from dfwb.foreign.worker import TIMEOUT, PointFailed, PointTimedOut, borrowed

__all__ = ["FMUEngine", "RTOL", "engine_for"]

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
    timeout : float, optional
        Seconds a point may take before its worker is killed. Default: fitted to the work (:meth:`limit`).
        A point cut by the limit is tried once more with twice the limit, with a warning saying so.
    jobs : int, optional
        Worker processes :meth:`points` may use at once (default: the machine's cores).
    """

    def __init__(self, plant, harmonics=HARMONICS, max_periods=DF_PERIODS, rtol=None, timeout=None, jobs=None):
        if not (isinstance(harmonics, int) and 1 <= harmonics <= HARMONICS):
            raise PlantError(f"harmonics = {harmonics!r} is out of range: an integer from 1 to {HARMONICS}")
        if not (isinstance(max_periods, int) and 1 <= max_periods <= MAX_PERIODS):
            raise PlantError(f"max_periods = {max_periods!r} is out of range: an integer from 1 to {MAX_PERIODS}")
        rtol = RTOL[plant.kind] if rtol is None else rtol
        if not (isinstance(rtol, (int, float)) and 1e-13 <= rtol <= 1e-2):
            raise PlantError(f"rtol = {rtol!r} is out of range: a number from 1e-13 to 0.01")
        if timeout is not None and not (isinstance(timeout, (int, float)) and 0.1 <= timeout <= 86400):
            raise PlantError(f"timeout = {timeout!r} is out of range: seconds from 0.1 to 86400")
        jobs = (os.cpu_count() or 1) if jobs is None else jobs
        if not (isinstance(jobs, int) and 1 <= jobs <= 256):
            raise PlantError(f"jobs = {jobs!r} is out of range: an integer from 1 to 256")
        native_flow.choice()  # a DFWB_FOREIGN_FLOW its workers would refuse at every point: refused here, once
        self.plant, self.harmonics, self.max_periods, self.jobs = plant, harmonics, max_periods, jobs
        self.rtol, self.drive = float(rtol), plant.kind
        self.fitted = timeout is None
        self.timeout = TIMEOUT * max(1.0, max_periods / 150) if timeout is None else float(timeout)
        self.slowest = 0.0  # seconds of the slowest point computed so far

    def limit(self):
        """Seconds the next point may take: the timeout given, or TIMEOUT scaled by the periods allowed and
        at least 10 times the slowest point so far (a busy machine slows every point alike)."""
        return self.timeout if not self.fitted else max(self.timeout, 10.0 * self.slowest)

    def _call(self, request, what):
        """The worker's answer; a point cut by the time limit is tried once more with twice the limit."""
        limit = self.limit()
        for attempt in range(2):
            try:
                with borrowed() as worker:
                    started = time.perf_counter()
                    answer = worker.call(request, what, limit)
                self.slowest = max(self.slowest, time.perf_counter() - started)
                return answer
            except PointTimedOut as cut:
                if attempt:
                    raise PointFailed(f"{cut}, also when tried again; the point is skipped") from None
                warnings.warn(f"{cut}; tried again with {2 * limit:g} s", RuntimeWarning, stacklevel=3)
                limit *= 2

    def point(self, F, omega, params=None):
        """The DFResult at force amplitude F and frequency omega (N NaN and a note if the FMU failed)."""
        started = time.perf_counter()
        F, omega = check_point(F, omega)
        params = self.plant.check(params or {})
        request = {"info": self.plant.info, "kind": self.plant.kind, "input": self.plant.input,
                   "output": self.plant.output, "F": float(F), "omega": float(omega), "params": params,
                   "harmonics": self.harmonics, "rtol": self.rtol, "max_periods": self.max_periods}
        try:
            answer = self._call(request, f"{self.plant.name} at F = {F:g}, omega = {omega:g}")
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

    def true_cycles(self, num, den, params, starts, omega_ref, seeds=()):
        """(cycles as dicts, outcome per start, then per seed) of the closed loop under G = num/den, from each
        start force, and by Newton from each DF prediction (F, omega) in ``seeds`` (model exchange).

        The starts and seeds are shared out among up to ``jobs`` workers, each a call with the engine's time
        limit per start; the cycles they find are merged. PointFailed if the FMU crashes, hangs or refuses.
        """
        from dfwb.foreign.loop import merge

        request = {"task": "cycles", "info": self.plant.info, "kind": self.plant.kind, "input": self.plant.input,
                   "output": self.plant.output, "params": self.plant.check(params or {}), "num": list(num),
                   "den": list(den), "omega_ref": float(omega_ref),
                   "rtol": min(self.rtol, 1e-9) if self.plant.kind == "model-exchange" else self.rtol}
        starts = [float(F) for F in starts]
        seeds = [(float(F), float(omega)) for F, omega in seeds]
        shares = max(1, min(self.jobs, len(starts) + len(seeds)))
        groups = [(starts[i::shares], seeds[i::shares]) for i in range(shares)]

        def call(group):
            with borrowed() as worker:
                return worker.call(dict(request, starts=group[0], seeds=group[1]),
                                   f"{self.plant.name}: the closed loop's cycles",
                                   timeout=self.limit() * max(len(group[0]) + len(group[1]), 1))

        answers = self._spread(call, groups)
        found, by_start, by_seed = [], [None] * len(starts), [None] * len(seeds)
        for i, ((group_starts, _), answer) in enumerate(zip(groups, answers)):
            for cycle in answer["cycles"]:
                merge(found, cycle)
            by_start[i::shares] = answer["outcomes"][:len(group_starts)]
            by_seed[i::shares] = answer["outcomes"][len(group_starts):]
        return found, by_start + by_seed

    def trace(self, F, omega, params, stop, step, outputs):
        """{"time": [...], output: [...]}: the response to F cos(omega t) from rest, sampled every ``step`` up
        to ``stop`` (:mod:`dfwb.foreign.trace`); one worker call under the engine's time limit."""
        F, omega = check_point(F, omega)
        request = {"task": "trace", "info": self.plant.info, "kind": self.plant.kind, "input": self.plant.input,
                   "output": self.plant.output, "params": self.plant.check(params or {}), "F": float(F),
                   "omega": float(omega), "stop": float(stop), "step": float(step), "outputs": list(outputs)}
        with borrowed() as worker:
            return worker.call(request, f"{self.plant.name}: a trace at F = {F:g}, omega = {omega:g}", self.limit())

    def coarse(self):
        """A looser twin for the work that only locates (a map, Newton's first steps): N alone, rtol 1000
        times looser (at most 1e-4), the same FMU, limits and workers' count."""
        return FMUEngine(self.plant, harmonics=1, max_periods=self.max_periods, rtol=min(self.rtol * 1e3, 1e-4),
                         timeout=None if self.fitted else self.timeout, jobs=self.jobs)

    def points(self, pairs, params=None):
        """DFResults of several (F, omega) pairs at the same parameters, in order (see :meth:`batch`)."""
        return self.batch([(F, omega, params) for F, omega in pairs])

    def batch(self, points):
        """DFResults of several (F, omega, params) points, in order, computed by up to ``jobs`` workers at once."""
        return self._spread(lambda point: self.point(*point), list(points))

    def _spread(self, call, items):
        """[call(item) for item in items], up to ``jobs`` at once (each call borrows its own worker)."""
        threads = min(self.jobs, len(items))
        if threads < 2:
            return [call(item) for item in items]
        with ThreadPoolExecutor(threads, thread_name_prefix="dfwb-fmu") as pool:
            return list(pool.map(call, items))


def engine_for(plant, *, fmu_dir=None, drive="internal", samples_per_period=SAMPLES_PER_PERIOD, max_periods=DF_PERIODS,
               harmonics=HARMONICS, rtol=None, timeout=None):
    """The engine of DF points for a plant: the exact built-in engine, or a user's FMU's (in worker processes).

    ``rtol`` and ``timeout`` are for a user's FMU only, ``drive`` and
    ``samples_per_period`` for dfwb's own plants only: given to the other, they are refused.
    """
    if getattr(plant, "foreign", False):
        if drive != "internal" or samples_per_period != 64:
            raise InputError("drive and samples_per_period are for dfwb's own plants: a user's FMU is driven as "
                             "its kind allows (model exchange: the exact sine; co-simulation: held and refined)")
        return FMUEngine(plant, harmonics=harmonics, max_periods=max_periods, rtol=rtol,
                         timeout=timeout)
    fmu_only({"rtol": (rtol, None), "timeout": (timeout, None)}, "dfwb's own plants are computed exactly")
    return DFEngine(plant, fmu_dir=fmu_dir, drive=drive, samples_per_period=samples_per_period,
                    max_periods=max_periods, harmonics=harmonics)

