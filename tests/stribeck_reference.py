"""An independent event-driven simulation of the coming Stribeck friction mass of issue 32, by scipy.

The reference the plant ``stribeck`` is to be checked against, written apart from dfwb's solvers:

    M x'' = u - Ff,   u = f + F cos(omega t + phi),
    sliding (v != 0):  Ff(v) = (Fc + (Fs - Fc) exp(-(|v| / vs)**delta)) sgn(v) + B v,
    stuck (v = 0):     held while |u| <= Fs, breaking away in the direction of u above it (Karnopp's stick,
                       as the friction mass's with Dv = 0).

Each phase is integrated by solve_ivp (DOP853, rtol 1e-12, steps of at most 1/64 of the drive's period) to
its first event: a sliding phase ends where v reaches 0 (then it sticks while |u| <= Fs, else it slides on in
the direction of u), a stuck phase where |u| rises through Fs. Its limits (tests/test_stribeck_reference.py):
Fs = Fc is dfwb's friction mass; as vs -> 0 it tends to it (the Stribeck drop then happens at v = 0).
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-14


def simulate(t_end, M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, delta=2.0, F=0.0, omega=1.0, phi=0.0, f=0.0, x0=0.0,
             v0=0.0, times=None, max_events=100000):
    """(times, [[x, v]] at times, [(t, event)]): at most ``max_events`` events (a run that needs more stops
    there, its later rows NaN)."""
    u = lambda t: f + F * math.cos(omega * t + phi)  # noqa: E731
    times = np.linspace(0.0, t_end, 2001) if times is None else np.asarray(times, float)
    out = np.full((len(times), 2), np.nan)
    events = []
    max_step = 2 * math.pi / omega / 64 if F else math.inf

    def friction(v, s):
        return s * (Fc + (Fs - Fc) * math.exp(-((abs(v) / vs) ** delta))) + B * v

    def at_rest(t):
        """0 (stuck) while |u| <= Fs, else the direction of u."""
        return 0 if abs(u(t)) <= Fs else (1 if u(t) > 0.0 else -1)

    t, y = 0.0, [x0, v0]
    s = (1 if v0 > 0.0 else -1) if v0 != 0.0 else at_rest(0.0)
    for _step in range(max_events):
        if t >= t_end:
            break
        if s:
            def rhs(t, y, s=s):
                return [y[1], (u(t) - friction(y[1], s)) / M]

            def stop(t, y):
                return y[1]

            stop.terminal, stop.direction = True, -s
            event = stop
        else:
            def rhs(t, y):
                return [0.0, 0.0]

            def breakaway(t, y):
                return Fs - abs(u(t))

            breakaway.terminal, breakaway.direction = True, -1
            event = breakaway
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=RTOL, atol=ATOL, events=[event],
                        dense_output=True, max_step=max_step)
        mask = (times >= t) & (times <= sol.t[-1])
        if mask.any():
            out[mask] = sol.sol(times[mask]).T
        if sol.status != 1:
            break
        t = float(sol.t[-1])
        y = [float(sol.y[0, -1]), 0.0 if s else float(sol.y[1, -1])]
        events.append((t, event.__name__))
        s = at_rest(t) if s else (1 if u(t) > 0.0 else -1)  # |u| crossed Fs upwards: it breaks away
    return times, out, events
