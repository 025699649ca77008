"""A model-exchange FMU driven by an exact sine: dfwb integrates it, events included.

The right-hand side sets the time, the states and the force ``F cos(w t)``
itself, so the input has no sampling error; the Fourier integrals of the
output, ``int y cos(k w t) dt`` and ``int y sin(k w t) dt``, ride along as
extra states of the same integrator (scipy's DOP853, stepped by hand), so the
harmonics carry the integrator's accuracy with no sampling either. After each
accepted step the event indicators are compared with the step's start; a
change of domain is located on the dense output (brentq), the FMU is put just
past it and handles the event; time events and ``completedIntegratorStep``
requests are handled the same way. Every loop is bounded.

The steady state is read on the section t = kT from the continuous states
(:class:`dfwb.foreign.steady.Sections`); a slow transient is cut short by
Newton shooting on those states when the FMU lets them be set from a saved
point. The last period is run again at a tolerance 100 times tighter, from
the same section: its N is the answer and its distance from the first is the
error estimate (with the transient that remains).
"""

import math

import numpy as np
from scipy.integrate import DOP853
from scipy.optimize import brentq

from dfwb.fmi.simulation import FMUError
from dfwb.foreign.steady import Sections

__all__ = ["point"]

MAX_STEPS = 200_000  # integrator steps per period
MAX_EVENTS = 10_000  # events per period
SHOOT_AFTER = 6  # periods before a slow transient is shot
MAX_SHOTS = 4
RTOL_ROOT = 4 * np.finfo(float).eps  # brentq's finest


class _Period:
    """One forcing period of the FMU and its Fourier integrals, from a section to the next."""

    def __init__(self, instance, F, omega, harmonics):
        self.inst, self.F, self.omega, self.K = instance, F, omega, harmonics
        self.k = np.arange(harmonics + 1)
        self.next_event = None
        self.scale = np.zeros(instance.nx)  # the largest |x_i| seen: the states' absolute tolerances
        self.y_max = 0.0  # the largest |y| seen: the integrals'

    def atol(self, rtol):
        """Absolute tolerances from the scales seen, so that rtol rules (1e-6 of the largest for a state at 0)."""
        T = 2 * math.pi / self.omega
        floor = 1e-6 * max(float(np.max(self.scale, initial=0.0)), 1e-300)
        states = np.maximum(self.scale, floor)
        integrals = np.full(2 * (self.K + 1), T * max(self.y_max, 1e-300))
        return np.maximum(rtol * np.concatenate((states, integrals)), 1e-300)

    def rhs(self, t, z):
        inst = self.inst
        nx = inst.nx
        inst.set_continuous(t, z[:nx], self.F * math.cos(self.omega * t))
        dx = inst.derivatives()
        y = inst.output()
        if not (math.isfinite(y) and np.all(np.isfinite(dx))):
            raise FloatingPointError(f"{inst.info.path}: the output or a derivative is not finite (NaN or overflow) "
                                     f"at t = {float(t)!r}")
        phase = self.k * (self.omega * t)
        return np.concatenate((dx, y * np.cos(phase), y * np.sin(phase)))

    def _domains(self, t, z):
        self.inst.set_continuous(t, z[:self.inst.nx], self.F * math.cos(self.omega * t))
        return self.inst.indicators() > 0.0

    def _crossing(self, dense, t0, t1, before):
        """The first time in (t0, t1] where an indicator leaves its domain, a point just past it."""
        def indicator(i):
            def f(t):
                self.inst.set_continuous(t, dense(t)[:self.inst.nx], self.F * math.cos(self.omega * t))
                value = self.inst.indicators()[i]
                return value if before[i] else -value  # > 0 in the old domain
            return f

        after = self._domains(t1, dense(t1))
        roots = []
        for i in np.flatnonzero(after != before):
            f = indicator(i)
            roots.append(t0 if f(t0) <= 0 else brentq(f, t0, t1, xtol=1e-15 * max(1.0, abs(t1)), rtol=RTOL_ROOT))
        t = min(roots)
        for _ in range(64):  # just past the root: a domain has changed there
            if t >= t1 or np.any(self._domains(t, dense(t)) != before):
                break
            t = t + max(t - min(roots), abs(t) * 2.2e-16, 1e-300)
        return min(t, t1)

    def run(self, t0, x, rtol, atol):
        """(states at t0 + T, the period's X_k, events) from the states x at t0."""
        inst, T = self.inst, 2 * math.pi / self.omega
        end = t0 + T
        z = np.concatenate((x, np.zeros(2 * (self.K + 1))))
        t = t0
        events = 0
        while t < end:
            bound = end if self.next_event is None or self.next_event >= end else max(self.next_event, t)
            solver = DOP853(self.rhs, t, z, bound, rtol=rtol, atol=atol, first_step=min(bound - t, T / 64) or None)
            before = self._domains(t, z)
            handled = False
            for _ in range(MAX_STEPS):
                if solver.status != "running":
                    break
                t_prev = solver.t
                message = solver.step()
                if solver.status == "failed":
                    raise FMUError(f"{inst.info.path}: the integrator failed at t = {float(solver.t)!r}: {message}")
                now = self._domains(solver.t, solver.y)
                if np.any(now != before):
                    dense = solver.dense_output()
                    t = self._crossing(dense, t_prev, solver.t, before)
                    z = dense(t)
                    handled = True
                    break
                inst.set_continuous(solver.t, solver.y[:inst.nx], self.F * math.cos(self.omega * solver.t))
                if inst.completed_step():
                    t, z, handled = solver.t, solver.y.copy(), True
                    break
                before = now
                self.scale = np.maximum(self.scale, np.abs(solver.y[:inst.nx]))
                self.y_max = max(self.y_max, abs(inst.output()))
            else:
                raise FMUError(f"{inst.info.path}: more than {MAX_STEPS} integrator steps in one period")
            if not handled:
                t, z = solver.t, solver.y.copy()
                if self.next_event is None or t < self.next_event:
                    continue  # the period's end
            inst.set_continuous(t, z[:inst.nx], self.F * math.cos(self.omega * t))
            self.next_event = inst.event()
            z = np.concatenate((inst.states(), z[inst.nx:]))
            events += 1
            if events > MAX_EVENTS:
                raise FMUError(f"{inst.info.path}: more than {MAX_EVENTS} events in one period (chattering?)")
        dI = z[inst.nx:]
        X = (dI[:self.K + 1] - 1j * dI[self.K + 1:]) * (2.0 / T)
        X[0] = dI[0] / T
        return z[:inst.nx], X, events

    def shoot(self, t, x, rtol, atol, saved):
        """Newton's step on the section map from x at t (finite-difference Jacobian), or None if singular.

        ``saved``: the FMU state to restore before each trial run (None: the
        FMU has no discrete state that could change, so setting x is enough).
        """
        inst = self.inst
        next_event = self.next_event

        def section(s):
            if saved is not None:
                inst.restore(saved, t)
            self.next_event = next_event
            inst.set_continuous(t, s, self.F * math.cos(self.omega * t))
            return self.run(t, s, rtol, atol)[0]

        p0 = section(x)
        J = np.empty((len(x), len(x)))
        for i in range(len(x)):
            h = 1e-6 * max(abs(x[i]), float(np.max(np.abs(x), initial=0.0)), 1e-12)
            trial = x.copy()
            trial[i] += h
            J[:, i] = (section(trial) - p0) / h
        try:
            s = x - np.linalg.solve(J - np.eye(len(x)), p0 - x)
        except np.linalg.LinAlgError:
            s = None
        if saved is not None:
            inst.restore(saved, t)
        self.next_event = next_event
        if s is not None and np.all(np.isfinite(s)):
            inst.set_continuous(t, s, self.F * math.cos(self.omega * t))
            return s
        inst.set_continuous(t, x, self.F * math.cos(self.omega * t))
        return None


def point(instance, F, omega, params, harmonics=10, rtol=1e-10, max_periods=150):
    """(X_k, N error, periodic, periods, orbit periods, note) of one DF point of a model-exchange FMU."""
    T = 2 * math.pi / omega
    period = _Period(instance, F, omega, harmonics)
    period.next_event = instance.start(params, F)
    x = instance.states()
    instance.set_continuous(0.0, x, F)
    period.scale = np.maximum(np.abs(x), np.abs(instance.derivatives()) * T)  # a first guess: one period's travel
    period.y_max = abs(instance.output())
    sections = Sections(tol=10 * rtol)
    can_save = instance.info.can_save_state.get("model-exchange", False)
    shots, found, t, periods = 0, None, 0.0, 0
    while periods < max_periods:
        atol = period.atol(rtol)
        if len(sections.sections) >= SHOOT_AFTER and shots < MAX_SHOTS and len(x) and \
                (can_save or (instance.nz == 0 and period.next_event is None)):
            shots += 1
            shot = period.shoot(t, x, rtol, atol, instance.save() if can_save else None)
            periods += len(x) + 1
            if shot is not None:
                x, sections = shot, Sections(tol=10 * rtol)
                continue
        x, X, _events = period.run(t, x, rtol, atol)
        t += T
        periods += 1
        found = sections.add(x, X, period.scale)
        if found is not None:
            break
    steady = found if found is not None else sections.average()
    # the last orbit again, 100 times tighter, from the same section: the answer and its error
    tight = []
    for _ in range(steady.lag):
        x, X, _events = period.run(t, x, rtol / 100, period.atol(rtol / 100))
        t += T
        tight.append(X)
    X = np.mean(tight, axis=0)
    error = abs(X[1] - steady.X[1]) + steady.residual
    note = "" if steady.periodic else f"no periodic response within {max_periods} periods: averaged"
    return X, error, steady.periodic, periods + steady.lag, steady.lag, note
