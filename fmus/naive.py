"""Naive fixed-step solvers of the three plants: a benchmark baseline, not for analysis.

The way a typical pythonfmu example integrates: a fixed internal step ``dt``
inside ``doStep`` with semi-implicit (symplectic) Euler,

    v <- v + dt a(t_i, x, v),   x <- x + dt v      (the new v moves x),

the force ``u = f + F cos(omega t_i + phi)`` taken at the start ``t_i`` of
each internal step. ``advance(t_end)`` takes whole steps of ``dt`` from the
current time and shortens the last one to land exactly on ``t_end``, so every
communication point is honoured (the grid restarts at each call). The running
Fourier integrals ``I_k(t) = int_0^t y exp(-i k omega s) ds`` are accumulated
by the same naive rule: the left rectangle ``dt * y(t_i) exp(-i k omega t_i)``
(explicit Euler of ``I_k' = y exp(-i k omega t)``). Nothing is located:
events happen at grid instants and the error is first order in ``dt``.

Their FMI facades are in :mod:`.naive_facade` (outside the production FMUs' sources).

The public interface is the exact solvers' (:mod:`.friction`,
:mod:`.backlash`, :mod:`.static_backlash`): the same keyword arguments plus
``dt``, ``advance``, ``set_input``, ``output``, ``integrals``, ``events``,
``t`` and the plant's discrete outputs, so the facades and the DF engine use
either one. The parameters are validated by the exact solver itself (same
ranges, same messages).

Plain Python (``math``, ``cmath``) only: this module runs inside the FMUs.
"""

import cmath
import math

from . import backlash as _backlash
from . import friction as _friction
from . import static_backlash as _static_backlash
from .backlash import TwoMassBacklash as _ExactTwoMassBacklash
from .exact import Drive
from .friction import FrictionMass as _ExactFrictionMass
from .piecewise import PlantError, check, check_step_end
from .static_backlash import StaticBacklash as _ExactStaticBacklash

_fr, _bl, _sb = _friction.TABLE.default, _backlash.TABLE.default, _static_backlash.TABLE.default  # the defaults

DEFAULT_DT = 1e-3
MAX_STEPS_PER_ADVANCE = 100_000_000  # a step that would take longer than hours is refused, not run

FREE, LOWER, UPPER = 0, 1, 2  # the backlash ``contact`` output, as in .backlash


def check_dt(dt):
    check("dt", dt, lambda: dt > 0.0, "dt must be > 0 (s), the internal fixed step")


class NaivePlant:
    """Base class: the fixed-step loop, the input and the naive Fourier integrals."""

    def __init__(self, F, omega, phi, f, harmonics, dt):
        self.drive = Drive(f, F, omega, phi)
        self.omega = omega
        self.dt = dt
        self.harmonics = int(harmonics)
        self.t = 0.0
        self.events = 0
        self._integrals = [0j] * (self.harmonics + 1)

    def _y(self):
        """The output whose Fourier integrals are kept, at the current state."""
        raise NotImplementedError

    def _step(self, t, h):
        """One semi-implicit Euler step of length h from t (the force taken at t)."""
        raise NotImplementedError

    def advance(self, t_end):
        """Whole steps of dt from self.t, the last one shortened to end exactly at t_end."""
        check_step_end(t_end, self.t)
        t0, dt = self.t, self.dt
        span = t_end - t0
        n = math.ceil(span / dt - 1e-9) if span > 0.0 else 0  # a rounding excess is no extra step
        if n > MAX_STEPS_PER_ADVANCE:
            raise PlantError(f"a step from t = {t0!r} to {t_end!r} would take {n} internal steps of "
                             f"dt = {dt!r} (more than {MAX_STEPS_PER_ADVANCE})")
        acc = self._integrals
        kmax = self.harmonics + 1
        w = self.omega
        for i in range(n):
            t = t0 + i * dt
            h = dt if i < n - 1 else t_end - t
            # left rectangle: I_k += h y(t) exp(-i k omega t)
            term = h * self._y()
            rot = cmath.exp(-1j * w * t)
            for k in range(kmax):
                acc[k] += term
                term *= rot
            self._step(t, h)
        self.t = t_end

    def set_input(self, f):
        """Set the input force, held constant until the next change."""
        check("f", f, True, "the input f must be a finite number (N)")
        d = self.drive
        if f != d.f:
            self.drive = Drive(f, d.F, d.omega, d.phi)

    def integrals(self):
        """Running integrals I_k(t) = int_0^t y exp(-i k omega s) ds, k = 0..harmonics (left rectangles)."""
        return list(self._integrals)


class NaiveFrictionMass(NaivePlant):
    """Friction mass by semi-implicit Euler with Karnopp's stick band; the output is x.

    Inside the band ``|v| <= Dv_naive = max(Dv, Fs dt / M)`` the friction is
    ``sat(u, Fs)`` (the velocity is held while ``|u| <= Fs``); outside it is
    ``Fc sgn(v) + B v``. The band must be at least one step's worth of
    velocity, or a fixed step would jump across v = 0 and never stick.
    """

    def __init__(self, M=_fr.M, B=_fr.B, Fc=_fr.Fc, Fs=_fr.Fs, Dv=_fr.Dv, F=0.0, omega=1.0, phi=0.0,
                 x0=_fr.x0, v0=_fr.v0, f=0.0, harmonics=10, dt=DEFAULT_DT):
        _ExactFrictionMass(M=M, B=B, Fc=Fc, Fs=Fs, Dv=Dv, F=F, omega=omega, phi=phi,
                           x0=x0, v0=v0, f=f, harmonics=harmonics)  # its own validation
        check_dt(dt)
        super().__init__(F, omega, phi, f, harmonics, dt)
        self.M, self.B, self.Fc, self.Fs, self.Dv = M, B, Fc, Fs, Dv
        self.band = max(Dv, Fs * dt / M)
        self.x, self.v = float(x0), float(v0)
        self.mode = self._mode(self.v)

    def _mode(self, v):
        return 0 if abs(v) <= self.band else (1 if v > 0.0 else -1)

    def _friction(self, v, u):
        if abs(v) <= self.band:
            return max(-self.Fs, min(self.Fs, u))
        return (self.Fc if v > 0.0 else -self.Fc) + self.B * v

    def _y(self):
        return self.x

    def _step(self, t, h):
        u = self.drive.u(t)
        v = self.v + h * (u - self._friction(self.v, u)) / self.M
        self.x += h * v
        self.v = v
        mode = self._mode(v)
        if mode != self.mode:
            self.mode = mode
            self.events += 1

    def output(self):
        """x, v, friction force Ff (at the current state and force) and mode (0 band, +-1 sliding)."""
        return _friction.TABLE.output_type(self.x, self.v, self._friction(self.v, self.drive.u(self.t)), self.mode)


class NaiveTwoMassBacklash(NaivePlant):
    """Two-mass backlash by semi-implicit Euler with clamped gap; the output is x1.

    State (x1, v1, g, w) with g = x2 - x1, w = v2 - v1, as in the exact
    solver. After each step a gap outside [0, h] is clamped back to the wall
    (both masses moved so that their centre of mass stays put) and, if the
    masses were closing, Newton's restitution law is applied to the
    velocities. An impact is counted when the closing speed exceeds two
    steps' worth of the force's relative velocity ``2 dt |u| / M2``; below
    that the clamp is resting contact (a pressing force makes a fixed step
    re-enter the wall at every step), reported as ``contact`` 1 or 2 while
    the gap sits at the wall with |w| under the same threshold. ``events``
    counts the impacts and the changes of ``contact``.
    """

    def __init__(self, M1=_bl.M1, M2=_bl.M2, h=_bl.h, eps=_bl.eps, F=0.0, omega=1.0, phi=0.0,
                 x1_0=_bl.x1_0, v1_0=_bl.v1_0, v2_0=_bl.v2_0, gap0=_bl.gap0, f=0.0, harmonics=10, dt=DEFAULT_DT):
        _ExactTwoMassBacklash(M1=M1, M2=M2, h=h, eps=eps, F=F, omega=omega, phi=phi, x1_0=x1_0,
                              v1_0=v1_0, v2_0=v2_0, gap0=gap0, f=f, harmonics=harmonics)  # its own validation
        check_dt(dt)
        super().__init__(F, omega, phi, f, harmonics, dt)
        self.M1, self.M2, self.h, self.eps = M1, M2, h, eps
        self.x1, self.v1 = float(x1_0), float(v1_0)
        self.g = 0.5 * h if gap0 is None else float(gap0)
        self.w = float(v2_0) - float(v1_0)
        self.impacts = 0
        self.contact = self._contact(self._rest(self.drive.u(0.0)))

    def _rest(self, u):
        """Relative speed below which a wall clamp is resting contact, not an impact."""
        return 2.0 * self.dt * abs(u) / self.M2

    def _contact(self, rest):
        if abs(self.w) <= rest:
            if self.g <= 0.0:
                return LOWER
            if self.g >= self.h:
                return UPPER
        return FREE

    def _y(self):
        return self.x1

    def _step(self, t, h):
        u = self.drive.u(t)
        M1, M2 = self.M1, self.M2
        w = self.w + h * u / M2  # M1 x1'' = 0, M2 x2'' = u
        g = self.g + h * w
        self.x1 += h * self.v1
        rest = self._rest(u)
        if g < 0.0 or g > self.h:
            wall, sigma = (0.0, -1) if g < 0.0 else (self.h, 1)
            self.x1 += M2 * (g - wall) / (M1 + M2)  # clamp, centre of mass kept
            g = wall
            if sigma * w > 0.0:  # closing: Newton's law, momentum kept
                self.v1 += M2 * (1.0 + self.eps) * w / (M1 + M2)
                if abs(w) > rest:
                    self.impacts += 1
                    self.events += 1
                w = -self.eps * w
        self.g, self.w = g, w
        contact = self._contact(rest)
        if contact != self.contact:
            self.contact = contact
            self.events += 1

    def state(self, t=None):
        """(x1, v1, g, w) now (``t`` is accepted for the exact solver's signature and ignored)."""
        return self.x1, self.v1, self.g, self.w

    def output(self):
        """x1, v1, x2, v2, gap at self.t."""
        return _backlash.TABLE.output_type(self.x1, self.v1, self.x1 + self.g, self.v1 + self.w, self.g)


class NaiveStaticBacklash(NaivePlant):
    """Mass + backlash by semi-implicit Euler, the play operator applied at each step; the output is y.

    z = y / k stays within [x - h/2, x + h/2]; when a step leaves x outside,
    z is dragged to the edge and ``engaged`` is the direction (+-1) it moved
    in that step, 0 otherwise. ``events`` counts the changes of ``engaged``.
    """

    def __init__(self, M=_sb.M, k=_sb.k, h=_sb.h, F=0.0, omega=1.0, phi=0.0, x0=_sb.x0, v0=_sb.v0,
                 f=0.0, harmonics=10, dt=DEFAULT_DT):
        _ExactStaticBacklash(M=M, k=k, h=h, F=F, omega=omega, phi=phi, x0=x0, v0=v0,
                             f=f, harmonics=harmonics)  # its own validation
        check_dt(dt)
        super().__init__(F, omega, phi, f, harmonics, dt)
        self.M, self.k, self.h = M, k, h
        self.x, self.v = float(x0), float(v0)
        self.z = self.x  # centred: y = k x0
        self.engaged = 0

    def _y(self):
        return self.k * self.z

    def _step(self, t, h):
        self.v += h * self.drive.u(t) / self.M
        x = self.x = self.x + h * self.v
        half = 0.5 * self.h
        if self.z < x - half:
            self.z, engaged = x - half, 1
        elif self.z > x + half:
            self.z, engaged = x + half, -1
        else:
            engaged = 0
        if engaged != self.engaged:
            self.engaged = engaged
            self.events += 1

    def output(self):
        """x, v, y at self.t."""
        return _static_backlash.TABLE.output_type(self.x, self.v, self.k * self.z)
