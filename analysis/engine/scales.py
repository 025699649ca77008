"""A loop's own scales, and the ranges a search covers derived from them.

Nobody should have to guess where a limit cycle lies. A plant in feedback
with G(s) carries its scales: the linear loop (the plant with its
nonlinearity removed, under G) has a crossover frequency and poles, the
nonlinearity has a size (a force such as Fs, or a length such as the
clearance h), and a stuck plant waits for the controller's integrator to
build up the force that moves it. From these:

* the output amplitudes a search starts from: around the amplitude at which
  the controller's force at crossover equals the nonlinearity's force (a
  force-type nonlinearity), or around the nonlinearity's length;
* the longest time a search waits between two section events before it
  calls a motion at rest: many of the loop's slowest time constants, and
  several times what a stuck plant displaced by the smallest amplitude
  searched needs until the integrator's force moves it;
* the describing function's ranges: the force between what moves the plant
  at all (below it N = 0) and what the linear loop allows (where the
  nonlinearity is too small beside the force to balance 1 + G N = 0:
  ``F ~ size |T(jw)|`` with T the linear loop's complementary sensitivity),
  and frequencies around the crossover.

Examples
--------
>>> from dfwb.engine.periodic import LoopProblem
>>> scales = loop_scales(LoopProblem("friction", "10 + 2/s"))
>>> round(scales.omega_c, 4), round(scales.length, 4), scales.stable
(3.1458, 0.6986, True)
>>> [round(v, 3) for v in scales.F_range()], [round(v, 5) for v in scales.omega_range()]
([7.0, 7439.064], [0.00315, 314.5786])
"""

import math
from dataclasses import dataclass

import numpy as np

from dfwb.base.errors import InputError
from dfwb.base.values import real, short

OMEGA_SPAN = (1e-3, 1e2)  # the DF's frequencies, relative to the crossover
F_SAFETY = 100.0  # the DF's largest force: this many times what the linear loop allows
AMPLITUDE_SPAN = (1e-2, 1e2)  # the search's start amplitudes, relative to the length scale
AMPLITUDES = 9  # ... log-spaced
SLOW_TIMES = 50.0  # the horizon: this many of the loop's slowest time constants,
RAMP_TIMES = 4.0  # ... and this many times a stuck plant's wait at the smallest amplitude
MAX_HORIZON = 1e7  # s: no horizon beyond (a search's budget bounds its work anyway)
GRID = np.geomspace(1e-6, 1e6, 1201)  # relative frequencies scanned for the crossover and the peaks


def _poly(coefficients):
    return np.poly1d(np.asarray(coefficients, dtype=float))


@dataclass(frozen=True)
class LoopScales:
    """The scales of a plant in feedback with G(s) (:func:`loop_scales`).

    Attributes
    ----------
    omega_c : float
        The linear loop's crossover [rad/s] (|G P| = 1, the highest such frequency).
    length : float
        The output amplitude scale [output unit]: the nonlinearity's length, or the
        displacement at which the controller's force at crossover equals its force.
    size : (str, float)
        The nonlinearity's size: ``("force", F)`` [N] or ``("length", d)`` [output unit].
    stable : bool
        Whether the linear loop (the nonlinearity removed) is stable.
    poles : tuple of complex
        The linear loop's poles [rad/s].
    slow : float
        The slowest time constant of the linear loop and of the controller [s] (integrators aside).
    ramp : float
        How fast the controller's force grows per second under a held output of 1 [N/(unit s)]:
        the integrator's gain (0 without an integrator; inf for a double one).
    f_lo, f_hi : float
        The describing function's force range [N] (see the module's docstring).
    """

    omega_c: float
    length: float
    size: tuple
    stable: bool
    poles: tuple
    slow: float
    ramp: float
    f_lo: float
    f_hi: float

    def amplitudes(self, n=AMPLITUDES, span=AMPLITUDE_SPAN):
        """``n`` log-spaced output amplitudes over ``span`` times the length scale."""
        return [float(a) for a in np.geomspace(span[0] * self.length, span[1] * self.length, n)]

    def horizon(self, smallest):
        """The longest wait between two section events [s] of a motion of output amplitude ``smallest``."""
        kind, size = self.size
        wait = 0.0
        if kind == "force" and size > 0.0 and self.ramp > 0.0:
            wait = size / (self.ramp * smallest)
        cycle = 2.0 * math.pi / self.omega_c
        return float(min(MAX_HORIZON, max(SLOW_TIMES * self.slow, RAMP_TIMES * wait, SLOW_TIMES * cycle)))

    def omega_range(self):
        """[low, high] of the describing function's frequencies [rad/s]."""
        from dfwb.engine.describing import OMEGA_RANGE

        lo = min(max(OMEGA_SPAN[0] * self.omega_c, OMEGA_RANGE[0]), 0.1 * OMEGA_RANGE[1])
        hi = max(min(OMEGA_SPAN[1] * self.omega_c, OMEGA_RANGE[1]), 10.0 * lo)
        return [float(lo), float(min(hi, OMEGA_RANGE[1]))]

    def F_range(self):
        """[low, high] of the describing function's force amplitudes [N]."""
        return [self.f_lo, self.f_hi]


def linear_poles(problem):
    """The poles of the linear loop: the plant with its nonlinearity removed, under G (1 + G P = 0)."""
    return closed_loop_poles(problem.b, [1.0] + list(problem.a), *problem.probe.linear())


def closed_loop_poles(num_g, den_g, num_p, den_p):
    """The roots of den_G den_P + num_G num_P (coefficients highest power first).

    On plain arrays, not poly1d: a hunting map's boundary asks this at 10^4 points, and poly1d's
    construction cost 5 times the roots themselves."""
    num_g, den_g, num_p, den_p = (np.asarray(c, dtype=float) for c in (num_g, den_g, num_p, den_p))
    return tuple(complex(p) for p in np.roots(np.polyadd(np.convolve(den_g, den_p), np.convolve(num_g, num_p))))


def characteristic(num_g, den_g, num_p, den_p):
    """den_G den_P + num_G num_P (coefficients highest power first): the linear loop's poles are its roots."""
    num_g, den_g, num_p, den_p = (np.asarray(c, dtype=float) for c in (num_g, den_g, num_p, den_p))
    return np.polyadd(np.convolve(den_g, den_p), np.convolve(num_g, num_p))


def largest_real_parts(polynomials):
    """The largest real part of each polynomial's roots (inf where it has none, or a coefficient is not finite).

    The roots of polynomials of one degree come from one stacked eigenvalue call on their companion
    matrices (as np.roots builds them): a map's boundary asks for 6400, one call each cost ten times more."""
    growth = np.full(len(polynomials), -np.inf)
    degrees = {}
    for i, coefficients in enumerate(polynomials):
        leading = np.trim_zeros(np.asarray(coefficients, dtype=float), "f")
        core = np.trim_zeros(leading, "b")
        if not np.isfinite(core).all():
            growth[i] = np.inf
            continue
        if len(core) < len(leading):
            growth[i] = 0.0  # roots at 0
        if len(core) > 1:
            degrees.setdefault(len(core) - 1, []).append((i, core))
        elif len(core) == len(leading):
            growth[i] = np.inf  # a constant: no roots
    for n, members in degrees.items():
        rows = np.array([core for _i, core in members])
        companion = np.zeros((len(rows), n, n))
        companion[:, 0, :] = -rows[:, 1:] / rows[:, :1]
        companion[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        where = [i for i, _core in members]
        growth[where] = np.maximum(growth[where], np.linalg.eigvals(companion).real.max(axis=1))
    return growth


def loop_scales(problem):
    """The :class:`LoopScales` of a :class:`~dfwb.engine.periodic.LoopProblem` (its plant, parameters and G).

    InputError where they leave the floats (a gain of 1e300: its crossover's powers overflow)."""
    with np.errstate(all="ignore"):
        scales = _loop_scales(problem)
    numbers = (scales.omega_c, scales.length, scales.slow, scales.f_lo, scales.f_hi)
    if not all(math.isfinite(v) and v > 0.0 for v in numbers) or not scales.horizon(scales.length) > 0.0:
        raise InputError(f"the loop's scales (crossover {scales.omega_c:.3g} rad/s, length {scales.length:.3g}) "
                         "leave the floating-point range at these values: give G's and the plant's parameters "
                         "within a few hundred orders of magnitude of each other")
    return scales


def _loop_scales(problem):
    from dfwb.engine.describing import F_RANGE

    probe = problem.probe
    num_p, den_p = (_poly(c) for c in probe.linear())
    num_g, den_g = _poly(problem.b), _poly([1.0] + list(problem.a))
    poles = linear_poles(problem)
    stable = bool(poles) and all(p.real < 0.0 for p in poles)

    def loop(omega):
        s = 1j * np.asarray(omega, dtype=float)
        return num_g(s) / den_g(s) * num_p(s) / den_p(s)

    magnitudes = np.array([abs(p) for p in poles if abs(p) > 0.0] + [abs(p) for p in np.roots(den_g.coeffs)
                                                                     if abs(p) > 0.0])
    centre = float(np.exp(np.mean(np.log(magnitudes)))) if magnitudes.size else 1.0
    omega_c = _crossover(loop, centre)
    kind, size = probe.nonlinearity()
    G_c = abs(num_g(1j * omega_c) / den_g(1j * omega_c))
    length = size / G_c if kind == "force" else size
    if size == 0.0 or G_c == 0.0:
        length = 1.0  # a linear plant (no nonlinearity), or no force: any scale serves, no cycle is expected
    rates = [abs(p.real) for p in poles + tuple(complex(r) for r in np.roots(den_g.coeffs))
             if abs(p.real) > 1e-9 * max(abs(p), 1e-300)]
    slow = 1.0 / min(rates) if rates else 1.0 / omega_c
    ramp = _ramp(problem.b, problem.a)
    omegas = omega_c * GRID[(GRID >= OMEGA_SPAN[0]) & (GRID <= OMEGA_SPAN[1])]
    L = loop(omegas)
    T = np.abs(L / (1.0 + L))
    if kind != "force":
        T = T / np.abs(num_p(1j * omegas) / den_p(1j * omegas))
    T = T[np.isfinite(T)]
    allowed = size * T.max() if T.size else math.nan
    f_lo = _moving_force(probe, omega_c * OMEGA_SPAN[0], F_RANGE)
    f_hi = F_SAFETY * allowed if math.isfinite(allowed) and allowed > 0.0 else F_RANGE[1]
    f_hi = float(min(max(f_hi, 100.0 * f_lo), F_RANGE[1]))
    return LoopScales(omega_c=float(omega_c), length=float(length), size=(kind, float(size)), stable=stable,
                      poles=poles, slow=float(slow), ramp=ramp, f_lo=float(f_lo), f_hi=f_hi)


def _crossover(loop, centre):
    """The highest frequency where |loop(jw)| falls through 1 (refined by bisection), else ``centre``."""
    omegas = centre * GRID
    above = np.abs(loop(omegas)) >= 1.0
    falls = np.flatnonzero(above[:-1] & ~above[1:])
    if not falls.size:
        return centre
    lo, hi = math.log(omegas[falls[-1]]), math.log(omegas[falls[-1] + 1])
    for _ in range(60):  # bounded: the bracket halves each time
        mid = 0.5 * (lo + hi)
        if abs(loop(math.exp(mid))) >= 1.0:
            lo = mid
        else:
            hi = mid
    return math.exp(0.5 * (lo + hi))


def _ramp(b, a):
    """lim s G(s) as s -> 0 in magnitude: the integrator's gain (0: none; inf: a double integrator)."""
    a = [1.0] + list(a)
    if a[-1] != 0.0:
        return 0.0
    if a[-2] != 0.0:
        return abs(b[-1] / a[-2])
    return math.inf if b[-1] != 0.0 else 0.0


def _moving_force(probe, omega, limits):
    """The least force amplitude F at ``omega`` for which F cos(wt) moves the plant's output (bisection in log F)."""
    lo, hi = math.log(limits[0]), math.log(limits[1])
    if not probe.still(math.exp(lo), omega):
        return limits[0]
    if probe.still(math.exp(hi), omega):
        raise InputError(f"no force up to {limits[1]:g} N moves the plant at {omega:g} rad/s")
    for _ in range(80):  # bounded: the bracket halves each time
        mid = 0.5 * (lo + hi)
        if probe.still(math.exp(mid), omega):
            lo = mid
        else:
            hi = mid
    return math.exp(hi)


def search_ranges(problem, F_range=None, omega_range=None):
    """(F_range, omega_range): those given, checked, else the loop's own (:meth:`LoopScales.F_range`).

    A force range in which no force moves the plant (at any of the frequencies) is refused: no cycle
    can balance there."""
    from dfwb.engine.describing import F_RANGE, OMEGA_RANGE
    from dfwb.engine.limit_cycles import check_range

    scales = problem.scales if problem is not None else None
    if (F_range is None or omega_range is None) and scales is None:
        raise InputError("give F_range and omega_range: this plant has no exact loop to derive them from")
    omega = check_range("omega range", _pair("omega_range", omega_range), OMEGA_RANGE) \
        if omega_range is not None else tuple(scales.omega_range())
    F = check_range("F range", _pair("F_range", F_range), F_RANGE) if F_range is not None \
        else tuple(scales.F_range())
    if problem is not None and problem.probe.still(F[1], omega[0]):
        raise InputError(f"F range [{F[0]:g}, {F[1]:g}] N: no force in it moves the {problem.spec.name} plant at "
                         f"any frequency of [{omega[0]:g}, {omega[1]:g}] rad/s (N = 0 throughout), so no cycle "
                         "can balance there; give larger forces, or none to have them derived")
    return F, omega


def _pair(name, value):
    try:
        lo, hi = (real(v) for v in value)
    except (TypeError, ValueError):
        lo = hi = None
    if lo is None or hi is None:
        raise InputError(f"{name} = {short(value, 60)} must be a (low, high) pair of numbers")
    return lo, hi
