"""The dual-input describing function: the plant's response to ``F cos(w t)`` with the dither ``a sin(w_d t)``.

A dithered loop (:class:`dfwb.fmus.compensation.Dither`) drives its plant with the controller's force and the
dither together. Its describing function is the plant's first harmonic at w under the sum of the two sines,
per unit F: the dual-input DF (Gelb and Vander Velde, *Multiple-Input Describing Functions and Nonlinear
System Design*, McGraw-Hill 1968, ch. 5). The two frequencies are in general incommensurate, so the response
is no periodic orbit: it lives on a torus of the two phases, and its harmonic at w is the torus average

    X_k = (1 / 2 pi) int_0^2pi [ (2 / T) int_0^T y(t; theta) exp(-j k w t) dt ] d theta,   T = 2 pi / w,

where ``y(t; theta)`` is the response over one forcing period that starts at the forcing's phase 0 and the
dither's phase theta (the segments from (0, theta) cover the torus once). That is Gelb and Vander Velde's
definition with the relative phase uniformly distributed; for a static nonlinearity it is their double
integral, and at a = 0 it is the plant's own DF.

How it is computed. The plant's exact loop (:mod:`dfwb.fmus.loops`) is driven by a generator in place of the
controller: two autonomous oscillators, so the forced plant is one more piecewise-affine system, integrated
exactly with every event located. Runs start from rest at dither phases spread over the circle; each forgets
its start (the friction mass's velocity is the forcing's alone after it sticks, and Coulomb friction contracts
two slides), and the run of pullback periods is taken long enough that a second run, started from rest one
period later at the first run's phase, agrees with it to TRANSIENT_TOL (that first run goes on as run 0; the
DF map's coarse twin asks less, COARSE). Then each run's next SEGMENTS periods
give segment harmonics, exactly (Gauss-Legendre sums of the motion's own Taylor series, chunk by chunk and event
by event). For each measured period the runs' dither phases are uniform, so the mean of the segment harmonics is
the trapezoidal rule of the phase integral; the runs double (RUNS) until that mean moves less than RTOL and
its last two moves less than ACCEPTED RTOL, and ``N_error`` is those two moves with the transient left. So N is
a quadrature, not a closed form: its error is estimated, not nil.

The response's mean is not reported (a free position drifts by the start's history: ``harmonics[0]`` is 0).
Its amplitude at the loop's dither is the dither's own at the plant: the loop's feedback of it, which the
controller adds, is left out, as in the classic use of the DIDF with a dither much faster than the loop
(documented in docs/guide/compensation.md). A point whose runs need more than MAX_CHUNKS of the exact loop's
chunks (seconds of Python) is not computed: its N is nan, which a DF map and Newton's steps pass over.

:class:`DitherDFEngine` serves it as a DF engine serves a plant (``point(F, omega, params)`` gives a
:class:`~dfwb.engine.describing.DFResult`), its parameters the plant's and the dither's ``a`` and ``w_d``.

Examples
--------
>>> from dfwb.plants import plant
>>> engine = DitherDFEngine(plant("friction"))
>>> plain = engine.point(10.0, 1.0, {"a": 0.0, "w_d": 5.0})  # no dither: the friction mass's own DF
>>> round(plain.N.real, 9), round(plain.N.imag, 9)
(-0.235053392, -0.297987542)
>>> dithered = engine.point(10.0, 1.0, {"a": 10.0, "w_d": 5.0})  # a 10 N dither, 5 times as fast
>>> round(dithered.N.real, 3), round(dithered.N.imag, 3), dithered.N_error < 1e-3 * abs(dithered.N)
(-0.252, -0.405, True)
"""

import functools
import math
import time
from collections.abc import Mapping

import numpy as np

from dfwb.base.errors import PlantError
from dfwb.engine.describing import DFResult, check_point
from dfwb.engine.periodic import GAUSS_NODES
from dfwb.fmus.compensation import Dither
from dfwb.fmus.hybrid import Budget

__all__ = ["DitherDFEngine", "forced_loop", "PLANTS", "R_MAX"]

HARMONICS = 10  # |X_k|, k = 0..10, as the DF engine gives them
PLANTS = ("friction",)  # plants whose forced response forgets its start (a free mass drifts by its start's)
R_MAX = 100.0  # dither periods per forcing period, at most: a point's runs cost that many dither periods each
RTOL = 1e-4  # the phase integral's last move, relative to |X_1|, that ends the doubling of the runs
ACCEPTED = 10.0  # ... if its last two moves (the error claimed) are within ACCEPTED RTOL: else it is not converged
RUNS = (4, 64)  # runs at dither phases 2 pi i / n + OFFSET: first, and at most (doubling)
SEGMENTS = 4  # forcing periods a run measures after its pullback
TRANSIENT_TOL = 1e-10  # two runs' states at one torus point, relative to the motion's size: both forgot
# the looser twin's runs (one level), segments, the accuracy it is taken to have, and its transient tolerance
# (far below that accuracy: where the mass never sticks, its damping alone forgets, e^(-B t / M))
COARSE = (2, 2, 1e-2, 1e-6)
MAX_PULLBACK = 512  # forcing periods a run may wait before it measures (the difference left enters N_error)
# Taylor chunks a point may integrate, all its runs: beyond, N is nan. A chunk costs 30 to 250 us with its events
# and integrals, so a point at most about 20 s; the slowest converged points measured need 30,000
MAX_CHUNKS = 100_000
# The runs' dither phases are 2 pi i / n + OFFSET: uniform at every n, and a start where the two sines cancel
# (F = a at the phase 3 pi / 2, a stuck start on a boundary of the stick band) improbable
OFFSET = 0.5 * (3.0 - math.sqrt(5.0))
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(GAUSS_NODES)  # on [-1, 1], for every segment
_K = np.arange(HARMONICS + 1)


def _generator(F, omega, a, w_d):
    """(Ac, Bc, C, D) of the autonomous drive F cos(phi) + a sin(psi): z = (cos phi, sin phi, sin psi, cos psi)."""
    Ac = [[0.0, -omega, 0.0, 0.0], [omega, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, w_d], [0.0, 0.0, -w_d, 0.0]]
    return Ac, [0.0] * 4, [F, 0.0, a, 0.0], 0.0


@functools.lru_cache(maxsize=None)
def forced_loop(loop):
    """The plant's exact loop ``loop`` with a generator in place of the controller: ``forced(F, omega, a, w_d,
    state=..., **plant parameters)``, its state the plant's coordinates and the generator's four."""

    class Forced(loop):
        def __init__(self, F, omega, a, w_d, **kwargs):
            self._drive = (F, omega, a, w_d)
            super().__init__([0.0, 0.0], [1.0, 1.0], **kwargs)

        def controller(self, b, a):
            return _generator(*self._drive)

    Forced.__name__ = Forced.__qualname__ = f"Forced{loop.__name__}"
    return Forced


class _Plant:
    """The plant with a dither, as a DF engine's plant: its parameters and the dither's ``a`` and ``w_d``."""

    def __init__(self, spec):
        self.spec, self.name = spec, spec.name

    def check(self, params):
        if not isinstance(params, Mapping):
            self.spec.check(params)  # refused as the plant refuses it
        missing = [name for name in ("a", "w_d") if name not in params]
        if missing:
            raise PlantError(f"{', '.join(missing)}: the dither's DF needs its amplitude a [N] and frequency w_d "
                             "[rad/s]")
        params = dict(params)
        dither = Dither(params.pop("a"), params.pop("w_d"))  # its checks, their messages
        return dict(self.spec.check(params), a=dither.a, w_d=dither.w_d)

    checked = check


class DitherDFEngine:
    """DF points of a plant driven with a dither: the dual-input DF, averaged over the dither's phase.

    Parameters
    ----------
    spec : PlantSpec
        The plant's (one of :data:`PLANTS`, ``dfwb.plants.plant("friction")``).
    rtol : float, optional
        The phase integral's accuracy asked, relative to |X_1| (the runs double until their last move is below, and the
        last two below ten times it).
    runs : (int, int), optional
        The runs at the first level, and at most.
    segments : int, optional
        Forcing periods each run measures.
    transient : float, optional
        How close two runs from rest must come at one torus point, relative to the motion's size, before the
        runs measure (the difference left enters ``N_error``).

    Examples
    --------
    >>> from dfwb.plants import plant
    >>> point = DitherDFEngine(plant("friction")).point(4.0, 0.5, {"a": 10.0, "w_d": 5.0})
    >>> point.periodic, round(abs(point.N), 3), point.N_error < 1e-3 * abs(point.N)
    (True, 0.604, True)
    """

    drive = "dither average"
    described = "its dual-input DF, averaged over the dither's phase"
    map_size = (4, 12)  # the DF map a study makes by default: it only locates (its points cost 0.01 to 1 s each)
    mapped = False  # a map of settings leaves its DF out (a DF map per cell would cost minutes)

    def __init__(self, spec, rtol=RTOL, runs=RUNS, segments=SEGMENTS, transient=TRANSIENT_TOL):
        if spec.name not in PLANTS or spec.loop is None:
            raise PlantError(f"the dither's DF is computed for {', '.join(PLANTS)}, whose response forgets its "
                             f"start; {spec.name} has none (a free mass drifts under a dither)")
        self.plant, self.rtol, self.runs, self.segments, self.transient = _Plant(spec), rtol, runs, segments, transient
        self.cls = forced_loop(spec.loop)

    def coarse(self):
        """A looser twin for the DF map, which only locates cycles (COARSE: a few runs, no doubling, no error
        claimed: N_error is inf); Newton then refines on this engine. Its ``rtol`` sizes the differences taken
        on it."""
        runs, segments, rtol, transient = COARSE
        return DitherDFEngine(self.plant.spec, rtol, (runs, runs), segments, transient)

    def domain(self, F_range, omega_range, params):
        """(F range, omega range) of a DF map: forces from max(0.01, 1 - a / Fs) of the range's lower end (a
        dither moves the mass under forces the plant alone would stick at), frequencies where a forcing period
        spans at most R_MAX dither periods (omega >= w_d / R_MAX); None where no frequency is left."""
        Fs = dict(self.plant.spec.defaults(), **params)["Fs"]
        scale = max(0.01, 1.0 - params["a"] / Fs) if Fs > 0.0 else 1.0
        lo, hi = max(omega_range[0], params["w_d"] / R_MAX), omega_range[1]
        return ((F_range[0] * scale, F_range[1]), (lo, hi)) if lo < hi else None

    def point(self, F, omega, params=None):
        """The :class:`~dfwb.engine.describing.DFResult` at force amplitude F [N] and frequency omega [rad/s]."""
        started = time.perf_counter()
        F, omega = check_point(F, omega)
        params = self.plant.checked(params or {})
        plant = {k: v for k, v in params.items() if k not in ("a", "w_d")
                 and k not in self.cls.initial_parameters}
        a, w_d = params["a"], params["w_d"]
        if w_d > R_MAX * omega:
            raise PlantError(f"omega = {omega!r} rad/s: the dither's DF is computed where a forcing period spans at "
                             f"most {R_MAX:g} dither periods, omega >= w_d / {R_MAX:g} = {w_d / R_MAX:.6g} rad/s")
        measure = _Measure(self.cls, plant, F, omega, a, w_d, self.segments, self.transient)
        try:
            pullback, transient = measure.pullback()
            if a == 0.0:  # no dither: every phase is the same, the plain DF's orbit
                values, moves = measure.runs(range(1), 1, pullback), [0.0]
            else:
                values, moves = self._average(measure, pullback)
        except PlantError as error:  # its work ran out: this point is lost (N is nan), not the study
            if measure.budget.left >= 0:
                raise
            nan = complex(math.nan, math.nan)
            return DFResult(plant=self.plant.name, F=F, omega=omega, params=params, N=nan,
                            harmonics=[math.nan] * (HARMONICS + 1), periodic=False, periods=measure.periods,
                            seconds=time.perf_counter() - started, drive=self.drive, X=[nan] * (HARMONICS + 1),
                            N_error=math.inf, note=f"not computed: more than {MAX_CHUNKS} chunks of the exact "
                                                   f"loop ({' '.join(str(error).split())[:80]})")
        X = np.mean(values, axis=0)
        moved = max(moves[-2:]) if moves else math.inf
        X = [0j] + [complex(x) for x in X[1:]]  # the mean: a free position's, not the response's (see module)
        error = float(moved + transient * abs(X[1]))
        converged = bool(self._accepted(error, X[1]) or abs(X[1]) == 0.0)
        note = "" if converged else (f"the phase average did not converge within {self.runs[1]} runs "
                                     f"({error:.3g} m of |X1| = {abs(X[1]):.3g} m)")
        return DFResult(plant=self.plant.name, F=F, omega=omega, params=params, N=X[1] / F,
                        harmonics=[float(abs(x)) for x in X], periodic=converged, periods=measure.periods,
                        seconds=time.perf_counter() - started, drive=self.drive, note=note, X=X,
                        N_error=error / F)

    def _accepted(self, error, X1):
        """Whether an error estimate of X_1 is within what a converged point may claim (ACCEPTED rtol)."""
        return error <= ACCEPTED * self.rtol * abs(X1)

    def _average(self, measure, pullback):
        """(segment harmonics, the moves of X_1's mean): runs at n uniform phases, then the odd ones of 2n (so
        uniform again), until the mean's last move is less than rtol of itself and the last two (the error it
        then claims) less than ACCEPTED rtol, or the runs reach their most."""
        values, moves, runs = [], [], 0
        while runs < self.runs[1]:
            more = range(self.runs[0]) if runs == 0 else range(1, 2 * runs, 2)
            runs = self.runs[0] if runs == 0 else 2 * runs
            before = np.mean(values, axis=0)[1] if values else None
            values += measure.runs(more, runs, pullback)
            X1 = np.mean(values, axis=0)[1]
            if before is not None:
                moves.append(abs(X1 - before))
                if moves[-1] <= self.rtol * abs(X1) and self._accepted(max(moves[-2:]), X1):
                    break
        return values, moves


class _Measure:
    """The forced plant at one point: its runs, their pullback and their segments' harmonics."""

    def __init__(self, cls, plant, F, omega, a, w_d, segments, transient):
        self.cls, self.plant, self.drive, self.segments = cls, plant, (F, omega, a, w_d), segments
        self.transient, self._first = transient, None  # (pullback: its tolerance, and its run kept for run 0)
        self.T = 2.0 * math.pi / omega
        self.ratio = w_d / omega  # the dither's phase turns by 2 pi ratio per forcing period
        self.periods = 0
        self.modes, self.budget = {}, Budget(MAX_CHUNKS)
        self.probe = self._solver(0.0, None)
        self.row = [1.0 if i == cls.OUTPUT else 0.0 for i in range(len(cls.coordinates) + 4)]  # y = row . X

    def _solver(self, theta, q):
        """A run from the plant's state q (None: at rest at the origin), forcing at phase 0, dither at theta."""
        m = len(self.cls.coordinates)
        q = [0.0] * m if q is None else list(q)
        z = [1.0, 0.0, math.sin(theta), math.cos(theta)]
        return self.cls(*self.drive, **self.plant, state=q + z, modes=self.modes, budget=self.budget)

    @staticmethod
    def phase(i, n):
        """The dither's phase at the start of run i of n."""
        return 2.0 * math.pi * i / n + OFFSET

    def _turned(self, theta, periods):
        """The dither's phase ``periods`` forcing periods after it was theta."""
        return (theta + 2.0 * math.pi * math.fmod(self.ratio * periods, 1.0)) % (2.0 * math.pi)

    def _plant_state(self, solver):
        return solver.state()[:len(self.cls.coordinates)]

    def _difference(self, qa, qb, previous):
        """Two plant states' difference, the second translated onto the first, relative to the motion's size."""
        out = self.cls.OUTPUT
        moved = self.probe.translate(qb, qa[out] - qb[out])
        size = max([abs(x) for i, x in enumerate(qa) if i != out] + [abs(qa[out] - previous[out])])
        difference = max(abs(x - y) for x, y in zip(qa, moved))
        return 0.0 if difference == 0.0 else difference / size if size > 0.0 else math.inf

    def pullback(self):
        """(forcing periods a run waits before it measures, the relative difference left): two runs from rest
        that meet at one torus point, one a period later, agree there. The first is run 0 of every level (its
        phase is :meth:`phase` (0, n)), kept at the end of its pullback for :meth:`runs`."""
        theta = self.phase(0, 1)
        a = self._solver(theta, None)
        b = self._solver(self._turned(theta, 1), None)
        a.advance(self.T)
        k, difference = 1, math.inf
        previous = self._plant_state(a)
        while True:
            a.advance((k + 1) * self.T)
            b.advance(k * self.T)
            qa = self._plant_state(a)
            difference = self._difference(qa, self._plant_state(b), previous)
            previous = qa
            k += 1
            self.periods += 2
            if difference <= self.transient or k >= MAX_PULLBACK:
                self._first = a
                return k, difference

    def runs(self, indices, n, pullback):
        """[segment harmonics X_0..X_10] of the runs ``indices`` of n, from the dither's phases :meth:`phase`: for
        each segment j, phases spread uniformly (their mean the trapezoidal rule of the phase integral)."""
        values = []
        for i in indices:
            if i == 0 and self._first is not None:  # the pullback's first run, at phase(0, n) and its end already
                solver, self._first = self._first, None
            else:
                solver = self._solver(self.phase(i, n), None)
                solver.advance(pullback * self.T)
                self.periods += pullback
            for j in range(self.segments):
                start = (pullback + j) * self.T
                values.append(self._segment(solver, start))
            self.periods += self.segments
        return values

    def _segment(self, solver, start):
        """X_0..X_10 of the output over [start, start + T] (``solver`` at start, left at its end): exact, from
        Gauss-Legendre sums of the motion's own Taylor series, chunk by chunk and event by event."""
        T, omega, end = self.T, 2.0 * math.pi / self.T, start + self.T
        total = np.zeros(HARMONICS + 1, dtype=complex)
        while solver.t < end:
            a = solver.t
            b, coefficients = solver.expansion(self.row)
            b = min(b, end)
            half = 0.5 * (b - a)
            tau = half * (_NODES + 1.0)
            ys = np.polynomial.polynomial.polyval(tau, coefficients)
            total += np.exp(-1j * omega * np.outer(_K, a - start + tau)) @ (half * _WEIGHTS * ys)
            solver.advance(b)
        return total * np.where(_K == 0, 1.0, 2.0) / T
