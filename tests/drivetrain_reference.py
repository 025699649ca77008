"""An independent event-driven simulation of the drivetrain of issue 32 (gear play with a sticking load), by scipy.

The reference the coming exact plant ``drivetrain`` is to be checked against, written apart from dfwb's
solvers: M2 (the motor side) carries u = f + F cos(omega t + phi); a clearance h separates it from the load
M1 (gap g = x2 - x1 in [0, h]); impacts follow Newton's law with restitution eps, momentum kept; the load has
viscous B, Coulomb Fc and static Fs friction, stuck exactly at v1 = 0 (the friction mass's model, Dv = 0).

Modes, each integrated by solve_ivp (DOP853, rtol 1e-12, steps of at most 1/64 of the drive's period, so
that a sign change of an event function is seen) to its first event:

- flight: M2 driven, the load sliding (until v1 = 0, where it sticks: nothing pushes it) or stuck; events:
  the gap reaching 0 or h (the wall just left only after the relative motion's apex);
- contact at wall sigma (-1: g = 0, +1: g = h), the masses together at v: sliding, M v' = u - Fc s - B v,
  until v = 0 or the contact force on the load, Nc = u - M2 v', stops pressing (sigma Nc <= 0); stuck
  (v = 0) until |u| > Fs (they slide) or sigma u <= 0 (M2 leaves, the load stays stuck).

At a wall the masses stay together when their relative acceleration presses them into it and the next
bounce would rise less than 1e-12 h (the accumulation of impacts is over), as the two-mass backlash does.
With a controller ``b, a`` (G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an)) the force is
u - G(s) x1: the loop of the drivetrain under feedback of the load's position, its controller in the
controllable canonical form (z1' = z2, ..., zn' = -an z1 - ... - a1 zn + x1, G x1 = (bn - an b0) z1 + ... +
(b1 - a1 b0) zn + b0 x1) integrated beside the plant. Its limits (tests/test_drivetrain_reference.py): without friction it is dfwb's two-mass backlash; as
h -> 0 with eps = 0 it tends to the friction mass of mass M1 + M2, its distance falling as sqrt(h).
"""

import math

import numpy as np
from reference_controller import canonical
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-14


def simulate(t_end, M1=1.0, M2=1.0, h=0.1, eps=0.5, B=0.5, Fc=5.0, Fs=7.0, F=0.0, omega=1.0, phi=0.0, f=0.0,
             x1_0=0.0, v1_0=0.0, v2_0=0.0, gap0=None, times=None, max_events=100000, b=None, a=None, z0=None,
             inverse=0.0):
    """(times, [[x1, v1, g, w, z...]] at times (g = x2 - x1, w = v2 - v1, z the controller's state when ``b, a``
    are given), [(t, event)]); at most ``max_events`` events (the accumulation of impacts ends; a run that needs
    more stops there, its later rows NaN). ``inverse``: a backlash inverse's h_hat, the controller then seeing
    x1 + h_hat/2 s, s the wall M2 last reached (set before that wall's logic; at t = 0 on a wall too)."""
    M = M1 + M2
    n = 0 if b is None else len(a)
    if n:
        Ac, Cz, b0 = canonical(b, a)
    excitation = lambda t: f + F * math.cos(omega * t + phi)  # noqa: E731

    seen = [0.0]  # the backlash inverse's correction: the controller sees x1 + seen[0]

    def force(t, y):
        """u at (t, y): the excitation, less G(s) x1 under control."""
        return excitation(t) - (float(Cz @ np.asarray(y[4:])) + b0 * (y[0] + seen[0]) if n else 0.0)

    times = np.linspace(0.0, t_end, 2001) if times is None else np.asarray(times, float)
    out = np.full((len(times), 4 + n), np.nan)
    events = []
    tol_h = 1e-12 * h
    max_step = 2 * math.pi / omega / 64 if F else math.inf
    sgn = lambda v: int(v > 0) - int(v < 0)  # noqa: E731

    def rest_in_contact(t, y, sigma):
        """Mode at v = 0 in contact at wall sigma."""
        u = force(t, y)
        if sigma * u <= 0.0:
            return ("flight", 0, sigma)  # M2 leaves the wall, M1 stays stuck
        if abs(u) <= Fs:
            return ("contact", sigma, 0)
        return ("contact", sigma, sgn(u))

    def at_wall(t, y, sigma):
        """The mode after reaching wall sigma (after its impact): contact when the relative acceleration presses
        the masses together and the next bounce would rise less than 1e-12 h, else flight away from it."""
        seen[0] = 0.5 * inverse * sigma  # the touch, before the wall's logic
        x1, v1, g, w = y[:4]
        z = list(y[4:])
        g = 0.0 if sigma < 0 else h
        if sigma * w > 0.0:  # closing: Newton's impact law, momentum kept
            new = -eps * w
            v1, w = v1 + M2 / M * (w - new), new
        v = v1 + M2 / M * w  # the common velocity if they stay together
        if v == 0.0:
            mode = rest_in_contact(t, y, sigma)
            if mode[0] == "contact" and w == 0.0:
                return mode, [x1, 0.0, g, 0.0] + z
            return ("flight", 0 if v1 == 0.0 else sgn(v1), sigma), [x1, v1, g, w] + z
        s = sgn(v)
        relative = (M1 * force(t, y) + M2 * (Fc * s + B * v)) / (M1 * M2)  # g'' in flight, the load sliding at v
        if sigma * relative > 0.0 and 0.5 * w * w <= tol_h * abs(relative):
            return ("contact", sigma, s), [x1, v, g, 0.0] + z
        return ("flight", sgn(v1), sigma), [x1, v1, g, w] + z

    t = 0.0
    g = 0.5 * h if gap0 is None else gap0
    y = [x1_0, v1_0, g, v2_0 - v1_0] + ([0.0] * n if z0 is None else list(z0))  # the gap g = x2 - x1, w = g'
    controller = (lambda y: list(Ac @ np.asarray(y[4:]) + np.eye(n)[-1] * (y[0] + seen[0]))) if n else (lambda y: [])
    if 0.0 < g < h:
        mode = ("flight", sgn(v1_0), 0)
    else:
        mode, y = at_wall(0.0, y, -1 if g <= 0.0 else 1)
    for _step in range(2 * max_events):  # an apex (not an event) comes between two events at most
        if t >= t_end or len(events) >= max_events:
            break
        if mode[0] == "flight":
            s, departing = mode[1], mode[2]  # departing: the wall just left (its event armed after the apex)

            def rhs(t, y, s=s):
                a1 = -(Fc * s + B * y[1]) / M1 if s else 0.0
                return [y[1], a1, y[3], force(t, y) / M2 - a1] + controller(y)

            def lower(t, y):
                return y[2]

            def upper(t, y):
                return h - y[2]

            def stop(t, y):
                return y[1]

            def apex(t, y):
                return y[3]

            lower.terminal = upper.terminal = stop.terminal = apex.terminal = True
            lower.direction = upper.direction = -1
            stop.direction, apex.direction = -s, departing
            walls = {-1: [upper, apex], 1: [lower, apex], 0: [lower, upper]}[departing]
            evs = walls + ([stop] if s else [])
        else:
            sigma, s = mode[1], mode[2]

            def accel(t, y, s=s):
                return (force(t, y) - Fc * s - B * y[1]) / M if s else 0.0

            def rhs(t, y):
                return [y[1], accel(t, y), 0.0, 0.0] + controller(y)

            def release(t, y, sigma=sigma):
                return sigma * (force(t, y) - M2 * accel(t, y))

            def stop(t, y):
                return y[1]

            def breakaway(t, y):
                return Fs - abs(force(t, y))

            release.terminal = stop.terminal = breakaway.terminal = True
            release.direction = breakaway.direction = -1
            stop.direction = -s
            evs = [release] + ([stop] if s else [breakaway])
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=RTOL, atol=ATOL, events=evs, dense_output=True,
                        max_step=max_step)  # events are sign changes at step ends: a still mode steps no further
        t1 = sol.t[-1]
        mask = (times >= t) & (times <= t1)
        if mask.any():
            out[mask] = sol.sol(times[mask]).T
        if sol.status != 1:
            break
        which = next(i for i, te in enumerate(sol.t_events) if len(te))
        kind = evs[which].__name__
        y = [float(value) for value in sol.y[:, -1]]
        events.append((t1, kind))
        t = t1
        if mode[0] == "flight":
            if kind == "stop":
                y[1] = 0.0
                mode = ("flight", 0, departing)
            elif kind == "apex":
                events.pop()  # not an event of the plant
                mode = ("flight", s, 0)
            else:
                mode, y = at_wall(t, y, -1 if kind == "lower" else 1)
        else:
            sigma = mode[1]
            if kind == "release":
                mode = ("flight", sgn(y[1]) if mode[2] else 0, sigma)
            elif kind == "stop":
                y[1] = 0.0
                mode = rest_in_contact(t, y, sigma)
            else:  # breakaway
                mode = ("contact", sigma, sgn(force(t, y)))
    return times, out, events
