"""An independent event-driven simulation of the coming Stribeck friction mass of issue 32, by scipy.

The reference the plant ``stribeck`` (and its closed loop) is to be checked against, written apart from
dfwb's solvers:

    M x'' = u - Ff,   u = f + F cos(omega t + phi),
    sliding (v != 0):  Ff(v) = (Fc + (Fs - Fc) exp(-(|v| / vs)**delta)) sgn(v) + B v,
    stuck (v = 0):     held while |u| <= Fs, breaking away in the direction of u above it (Karnopp's stick,
                       as the friction mass's with Dv = 0).

Each phase is integrated by solve_ivp (DOP853, rtol 1e-12, steps of at most 1/64 of the drive's period) to
its first event: a sliding phase ends where v reaches 0 (then it sticks while |u| <= Fs, else it slides on in
the direction of u), a stuck phase where |u| rises through Fs.

With a controller ``b, a`` (G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an)) the force is
u = f + F cos(omega t + phi) - G(s) x: the mass under feedback of its position, as in
tests/drivetrain_reference.py, its controller in the controllable canonical form (z1' = z2, ..., zn' = -an z1
- ... - a1 zn + x, G x = (bn - an b0) z1 + ... + (b1 - a1 b0) zn + b0 x) integrated beside the mass, the
state rows [x, v, z1..zn]. The stick and slide logic is the same with this u, which now depends on the state:
stuck, x is held while z evolves (z' = Ac z + Bc x) until |u| rises through Fs (the event Fs - |u(t, y)|); at
the stop of a slide it sticks while |u| <= Fs there, else it slides on in the direction of u. In closed loop
the steps are at most 0.05 s (and 1/64 of the drive's period when F != 0), a fixed bound, not one derived
from the loop's time constants: it is M / ((Fs - Fc) / vs), the time of the Stribeck drop's negative damping,
with the default parameters, and a sixth or less of the half-oscillations of the loops tested (the stiffest,
10 rad/s under 100 + 2/s), so that a sign change of an event function is seen.

Its limits (tests/test_stribeck_reference.py): Fs = Fc is dfwb's friction mass (and, under control, its exact
friction loop FrictionLoop, whose state [x, v, z1..zn] has the same z); as vs -> 0 it tends to it (the
Stribeck drop then happens at v = 0).
"""

import math

import numpy as np
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-14
LOOP_MAX_STEP = 0.05  # s: the steps' bound in closed loop (with the drive's period / 64 when F != 0)


def simulate(t_end, M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, delta=2.0, F=0.0, omega=1.0, phi=0.0, f=0.0, x0=0.0,
             v0=0.0, times=None, max_events=100000, b=None, a=None, z0=None):
    """(times, [[x, v, z...]] at times (z the controller's state when ``b, a`` are given), [(t, event)]): at
    most ``max_events`` events (a run that needs more stops there, its later rows NaN)."""
    n = 0 if b is None else len(a)
    if n:
        a_, b_ = np.asarray(a, float), np.zeros(n + 1)
        b_[n + 1 - len(b):] = b  # b0..bn, leading zeros for a proper G
        Ac = np.zeros((n, n))
        Ac[:-1, 1:] = np.eye(n - 1)
        Ac[-1, :] = -a_[::-1]
        Cz = b_[:0:-1] - a_[::-1] * b_[0]  # (bn - an b0, ..., b1 - a1 b0)
        Ac, Cz, b0 = Ac.tolist(), Cz.tolist(), float(b_[0])  # plain floats: they serve every evaluation
    else:
        Ac, Cz, b0 = [], [], 0.0
    excitation = lambda t: f + F * math.cos(omega * t + phi)  # noqa: E731

    def force(t, y):
        """u at (t, y) (y a list): the excitation, less G(s) x under control."""
        return excitation(t) - (sum(c * z for c, z in zip(Cz, y[2:])) + b0 * y[0] if n else 0.0)

    def controller(y):
        """z' = Ac z + Bc x (Bc = (0, ..., 0, 1)) at y (a list)."""
        z = y[2:]
        dz = [sum(c * value for c, value in zip(row, z)) for row in Ac]
        if n:
            dz[-1] += y[0]
        return dz

    times = np.linspace(0.0, t_end, 2001) if times is None else np.asarray(times, float)
    out = np.full((len(times), 2 + n), np.nan)
    events = []
    max_step = 2 * math.pi / omega / 64 if F else math.inf
    if n:
        max_step = min(max_step, LOOP_MAX_STEP)

    def friction(v, s):
        return s * (Fc + (Fs - Fc) * math.exp(-((abs(v) / vs) ** delta))) + B * v

    def at_rest(t, y):
        """0 (stuck) while |u| <= Fs, else the direction of u."""
        u = force(t, y)
        return 0 if abs(u) <= Fs else (1 if u > 0.0 else -1)

    t, y = 0.0, [x0, v0] + ([0.0] * n if z0 is None else [float(value) for value in z0])
    s = (1 if v0 > 0.0 else -1) if v0 != 0.0 else at_rest(0.0, y)
    for _step in range(max_events):
        if t >= t_end:
            break
        if s:
            def rhs(t, y, s=s):
                y = y.tolist()
                return [y[1], (force(t, y) - friction(y[1], s)) / M] + controller(y)

            def stop(t, y):
                return y[1]

            stop.terminal, stop.direction = True, -s
            event = stop
        else:
            def rhs(t, y):
                return [0.0, 0.0] + controller(y.tolist())

            def breakaway(t, y):
                return Fs - abs(force(t, np.asarray(y).tolist()))

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
        y = [float(value) for value in sol.y[:, -1]]
        if s:
            y[1] = 0.0
        events.append((t, event.__name__))
        s = at_rest(t, y) if s else (1 if force(t, y) > 0.0 else -1)  # |u| crossed Fs upwards: it breaks away
    return times, out, events
