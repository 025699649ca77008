"""A model-exchange FMU driven by an exact sine: dfwb integrates it, events included.

A :class:`dfwb.foreign.flow.Flow` whose input law is the force ``F cos(w t)``
itself, so the input has no sampling error, and whose extra states are the
Fourier integrals of the output, ``int y cos(k w t) dt`` and
``int y sin(k w t) dt``, so the harmonics carry the integrator's accuracy
with no sampling either; events are handled by the flow.

The steady state is read on the section t = kT from the continuous states
(:class:`dfwb.foreign.steady.Sections`); a slow transient is cut short by
Newton shooting on those states when the FMU lets them be set from a saved
point. The last period is run again at a tolerance 100 times tighter, from
the same section: its N is the answer and its distance from the first is the
error estimate (with the transient that remains).
"""

import math

import numpy as np

from dfwb.base.defaults import DF_PERIODS, HARMONICS
from dfwb.foreign.flow import Flow
from dfwb.foreign.native_flow import Drive
from dfwb.foreign.steady import Sections, ramp

__all__ = ["point"]

MAX_SHOTS = 4
NOISE = 128  # ulps of the output: the rounding of a period's Fourier integrals (up to 45 seen)
STATE_NOISE = 16  # ... and of what an orbit's rounding of the states leaves in them, per orbit
EPS = np.finfo(float).eps
CONTRACTION = 0.99  # at most, per orbit, in the transient's tail (a slower one is not periodic to this accuracy)


class _Period:
    """Forcing periods of the FMU with the Fourier integrals of its output riding along (a :class:`Flow`)."""

    def __init__(self, instance, F, omega, harmonics):
        self.inst, self.F, self.omega, self.K = instance, F, omega, harmonics
        self.contraction = None  # the section map's spectral radius, where a shot has differenced it
        self.flow = Flow(instance, drive=Drive(F=F, omega_f=omega, K=harmonics, omega=omega))

    @property
    def next_event(self):
        return self.flow.next_event

    @next_event.setter
    def next_event(self, value):
        self.flow.next_event = value

    def atol(self, rtol):
        """Absolute tolerances from the scales seen, so that rtol rules (1e-6 of the largest for a state at 0)."""
        T = 2 * math.pi / self.omega
        scale = self.flow.scale[:self.inst.nx]
        floor = 1e-6 * max(float(np.max(scale, initial=0.0)), 1e-300)
        integrals = np.full(2 * (self.K + 1), T * max(self.flow.y_max, 1e-300))
        return np.maximum(rtol * np.concatenate((np.maximum(scale, floor), integrals)), 1e-300)

    def run(self, t0, x, rtol, atol):
        """(states at t0 + T, the period's X_k, events) from the states x at t0."""
        T = 2 * math.pi / self.omega
        nx = self.inst.nx
        _t, z, events, _crossed = self.flow.run(t0, np.concatenate((x, np.zeros(2 * (self.K + 1)))), t0 + T,
                                                rtol, atol)
        dI = z[nx:]
        X = (dI[:self.K + 1] - 1j * dI[self.K + 1:]) * (2.0 / T)
        X[0] = dI[0] / T
        return z[:nx], X, events

    def shoot(self, t, x, rtol, atol, saved):
        """(state, runs): Newton's step on the section map from x at t (finite-difference Jacobian), the
        state None if singular or no closer to a periodic orbit than x; ``runs``: the periods it ran. The
        Jacobian's spectral radius is kept as :attr:`contraction`.

        ``saved``: the FMU state to restore before each trial run (None: the
        FMU has no discrete state that could change, so setting x is enough).
        """
        inst = self.inst
        next_event = self.next_event
        runs = 0

        def section(s):
            nonlocal runs
            runs += 1
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
        self.contraction = float(np.max(np.abs(np.linalg.eigvals(J)))) if np.all(np.isfinite(J)) else None
        try:
            s = x - np.linalg.solve(J - np.eye(len(x)), p0 - x)
        except np.linalg.LinAlgError:
            s = None
        if s is not None and np.all(np.isfinite(s)):  # kept only if it is closer to a periodic orbit
            scale = np.maximum(np.abs(x), 1e-12 * float(np.max(np.abs(x), initial=0.0)) + 1e-300)
            if not np.max(np.abs(section(s) - s) / scale) < np.max(np.abs(p0 - x) / scale):
                s = None  # e.g. a drifting state, whose multiplier 1 makes the step meaningless
        else:
            s = None
        if saved is not None:
            inst.restore(saved, t)
        self.next_event = next_event
        inst.set_continuous(t, x if s is None else s, self.F * math.cos(self.omega * t))
        return s, runs


def point(instance, F, omega, params, harmonics=HARMONICS, rtol=1e-10, max_periods=DF_PERIODS):
    """(X_k, N error, periodic, periods, orbit periods, note) of one DF point of a model-exchange FMU."""
    return periodic_response(instance, F, omega, params, harmonics, rtol, max_periods)[:6]


def periodic_response(instance, F, omega, params, harmonics=HARMONICS, rtol=1e-10, max_periods=DF_PERIODS):
    """:func:`point`'s answer, then the time (a whole number of periods) and the FMU's continuous states
    where its runs ended: on the periodic response, the force at its crest."""
    period, orbit, t, x, periods = settle(instance, F, omega, params, harmonics, rtol, max_periods)
    X, error, t, x = _final(period, orbit, t, x, rtol, harmonics)
    note = "" if orbit.periodic else f"no periodic response within {max_periods} periods: averaged"
    return X, error, orbit.periodic, periods + orbit.lag, orbit.lag, note, t, x


def settle(instance, F, omega, params, harmonics, rtol, max_periods):
    """(the periods' runner, the steady orbit found at rtol, time, states, periods run): the transient
    run out (or shot) until the section repeats to 10 rtol."""
    T = 2 * math.pi / omega
    next_event = instance.start(params, F)
    period = _Period(instance, F, omega, harmonics)  # after start: the FMU's number of states is known
    period.next_event = next_event
    x = instance.states()
    instance.set_continuous(0.0, x, F)
    period.flow.scale[:len(x)] = np.maximum(np.abs(x), np.abs(instance.derivatives()) * T)  # one period's travel
    period.flow.y_max = abs(instance.output())
    nx = len(x)
    sections = Sections(tol=10 * rtol, output=nx)  # the section: the states, and the output (its drift)
    can_save = instance.info.can_save_state.get("model-exchange", False)
    shots, found, t, periods = 0, None, 0.0, 0
    while periods < max_periods:
        atol = period.atol(rtol)
        if shots < MAX_SHOTS and len(x) and _slow(sections, 10 * rtol, len(x) + 2) and \
                (can_save or (instance.nz == 0 and period.next_event is None)):
            shots += 1
            shot, runs = period.shoot(t, x, rtol, atol, instance.save() if can_save else None)
            periods += runs
            if shot is not None:
                x, sections = shot, Sections(tol=10 * rtol, output=nx)
                continue
        x, X, _events = period.run(t, x, rtol, atol)
        t += T
        periods += 1
        y, _u = period.flow.evaluate(t, np.concatenate((x, np.zeros(2 * (harmonics + 1)))))
        found = sections.add(np.append(x, y), X, np.append(period.flow.scale[:nx], period.flow.y_max))
        if found is not None:
            break
    orbit = found if found is not None else sections.average()
    return period, orbit, t, x, periods


def _slow(sections, tol, cost):
    """Whether the sections' transient, shrinking geometrically by the ratio of its last two changes, would
    take more than ``cost`` periods more to reach ``tol``: then a shot (``cost`` periods) is quicker."""
    if len(sections.sections) < 3:
        return False
    last, before = sections.change(0), sections.change(1)
    if not last > tol:
        return False
    if not last < before:
        return True  # not contracting: waiting may never end
    return math.log(tol / last) / math.log(last / before) > cost


def _final(period, orbit, t, x, rtol, harmonics):
    """(X_k, error, time, states) from the settled section: the orbit run twice more at rtol / 100.

    The answer is the second tight orbit; its error has three parts:

    - integration: the loose orbit's distance from it times 0.1 (DOP853's error falls at least as the
      square root of its tolerance; with each event's step integrated again up to the event it falls about
      as the tolerance, so the tight orbit's is far smaller than the loose one's);
    - transient: the section state sits on the loose orbit, or on a transient's tail; what the second
      tight orbit still has of it is the last change above rounding times rho / (1 - rho), twice (a
      geometric decay's tail is not exactly geometric), rho the states' contraction per orbit: the
      spectral radius of a shot's Jacobian where the point was shot, else the ratio of the two orbits'
      changes, else (those at rounding) 0.99; no continuous state: 0;
    - rounding: :data:`NOISE` ulps of the output's size, and :data:`STATE_NOISE` ulps more per orbit that
      a rounding error of the states takes to decay, rho / (1 - rho) of them. A shot orbit of Q = 50 keeps
      a hundred ulps.

    An orbit that never repeated adds its spread. Measured on the tests' closed forms (saturation, relay,
    mass-spring-damper up to Q = 50, drifting mass): 1 to 10 times the true error (at least 16 ulps of N).
    """
    T = 2 * math.pi / period.omega
    nx = period.inst.nx
    orbits, ends = [], [x]
    for _ in range(2):
        tight = []
        for _ in range(orbit.lag):
            x, X, _events = period.run(t, x, rtol / 100, period.atol(rtol / 100))
            t += T
            tight.append(X)
        orbits.append(np.mean(tight, axis=0))
        ends.append(x)
    X = orbits[1].copy()
    if orbit.drift:  # the output creeps by the same amount each period: its ramp is not part of the orbit
        X[1:] -= ramp(orbit.drift, harmonics)[1:]
    noise = NOISE * EPS * max(abs(X[1]), period.flow.y_max)
    scale = np.maximum(period.flow.scale[:nx], 1e-300)
    steps = [float(np.max(np.abs(b - a) / scale, initial=0.0)) for a, b in zip(ends, ends[1:])]
    if orbit.drift or not nx:
        rho = 0.0  # a drift's states never repeat; without continuous states nothing contracts
    elif period.contraction is not None:  # a shot's Jacobian: the section map's contraction, measured
        rho = min(period.contraction, CONTRACTION)
    elif min(steps) > NOISE * EPS:  # else the ratio of the two orbits' changes (noisy: up to 1.3 seen at
        rho = min(steps[1] / steps[0], CONTRACTION)  # a true 0.81, when the tight runs moved the orbit)
    else:
        rho = CONTRACTION  # the states' changes are rounding: their contraction cannot be read
    change = max(abs(orbits[1][1] - orbits[0][1]) - noise, 0.0)
    integration = 0.1 * abs(X[1] - orbit.X[1])  # (the loose orbit's ramp is removed as well)
    error = integration + (2.0 * change + noise * STATE_NOISE / NOISE) * rho / (1.0 - rho) + noise
    if not orbit.periodic:
        error += orbit.residual
    return X, error, t, x
