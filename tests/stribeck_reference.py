"""An independent event-driven simulation of the coming Stribeck friction mass of issue 32, by scipy.

The reference the plant ``stribeck`` (and its closed loop) is to be checked against, written apart from
dfwb's solvers:

    M x'' = u - Ff,   u = f + F cos(omega t + phi),
    sliding (v != 0):  Ff(v) = (Fc + (Fs - Fc) exp(-(|v| / vs)**delta)) sgn(v) + B v,
    stuck (v = 0):     held while |u| <= Fs, breaking away in the direction of u above it (Karnopp's stick,
                       as the friction mass's with Dv = 0).

Each phase is integrated by solve_ivp (DOP853, rtol 1e-12, steps of at most 1/64 of the drive's period; within
|v| < 3 vs, where the friction drops, a phase of its own with steps of at most half of vs: an error estimate
steps over a drop much narrower than its step, and a stop was once 3e-4 s late at vs = 0.01 m/s) to
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
from reference_controller import canonical
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-14
NEAR = 3.0  # |v| < NEAR vs: the Stribeck drop's region, integrated apart with steps of at most half of vs
LOOP_MAX_STEP = 0.05  # s: the slides' steps' bound in closed loop (with the drive's period / 64 when F != 0)


def simulate(t_end, M=1.0, B=0.5, Fc=5.0, Fs=7.0, vs=0.1, delta=2.0, F=0.0, omega=1.0, phi=0.0, f=0.0, x0=0.0,
             v0=0.0, times=None, max_events=100000, b=None, a=None, z0=None):
    """(times, [[x, v, z...]] at times (z the controller's state when ``b, a`` are given), [(t, event)]): at
    most ``max_events`` events (a run that needs more stops there, its later rows NaN)."""
    n = 0 if b is None else len(a)
    if n:
        Ac, Cz, b0 = canonical(b, a)
        Ac, Cz = Ac.tolist(), Cz.tolist()  # plain floats: they serve every evaluation
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
    stuck_step = max_step = 2 * math.pi / omega / 64 if F else math.inf  # stuck: the force is smooth in time
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
    inside = abs(v0) < NEAR * vs  # within the drop's region (decided by the events crossing its edge after t = 0)
    for _step in range(max_events):
        if t >= t_end:
            break
        step, watch = (max_step if s else stuck_step), []
        if s:
            def rhs(t, y, s=s):
                y = y.tolist()
                return [y[1], (force(t, y) - friction(y[1], s)) / M] + controller(y)

            def stop(t, y):
                return y[1]

            stop.terminal, stop.direction = True, -s
            event = stop
            if Fs > Fc:  # the drop happens within |v| ~ vs: resolved apart, half of vs a step at most
                push = 2.0 * (abs(force(t, y)) + abs(F) + Fs + B * abs(y[1])) / M  # |v'| at most, with margin
                # outside: phases ending where |v| halves (or reaches NEAR vs), each in 4 steps at least, so that
                # no step jumps over the region; inside: steps of half of vs, until |v| leaves it again
                edge = NEAR * vs if inside else max(NEAR * vs, 0.5 * abs(y[1]))

                def near(t, y, edge=edge):
                    return abs(y[1]) - edge

                near.terminal, near.direction = True, (1 if inside else -1)
                span = 0.5 * vs if inside else 0.25 * max(abs(y[1]) - edge, 0.1 * vs)
                step = min(max_step, span / push) if push > 0.0 else max_step
                watch = [near]
                if not inside:  # speeding away: a new phase, with larger steps, where |v| doubles
                    def far(t, y, edge=2.0 * max(abs(y[1]), NEAR * vs)):
                        return abs(y[1]) - edge

                    far.terminal, far.direction = True, 1
                    watch.append(far)
        else:
            def rhs(t, y):
                return [0.0, 0.0] + controller(y.tolist())

            def breakaway(t, y):
                return Fs - abs(force(t, np.asarray(y).tolist()))

            breakaway.terminal, breakaway.direction = True, -1
            event = breakaway
        sol = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=RTOL, atol=ATOL, events=[event] + watch,
                        dense_output=True, max_step=step)
        mask = (times >= t) & (times <= sol.t[-1])
        if mask.any():
            out[mask] = sol.sol(times[mask]).T
        if sol.status != 1:
            break
        t = float(sol.t[-1])
        y = [float(value) for value in sol.y[:, -1]]
        if watch and len(sol.t_events[0]) == 0:  # nearer the region, into it or out of it: the slide goes on
            inside = not inside and len(sol.t_events[1]) > 0 and abs(y[1]) <= NEAR * vs * (1.0 + 1e-9)
            continue
        inside = True  # a stop (v = 0) or a breakaway (from v = 0)
        if s:
            y[1] = 0.0
        events.append((t, event.__name__))
        s = at_rest(t, y) if s else (1 if force(t, y) > 0.0 else -1)  # |u| crossed Fs upwards: it breaks away
    return times, out, events
