"""The true limit cycles of a user's FMU under G(s): for model exchange, the closed loop integrated and shot.

(A co-simulation FMU's loop is co-simulated instead: :mod:`dfwb.foreign.held_loop`; the starts and
what counts as one cycle are shared.)

The loop is the FMU's continuous states with the controller's, ``force =
-G(s) output``, integrated as one :class:`~dfwb.foreign.flow.Flow` (the
controller's states ride along; a feedthrough D is solved with the output).
Each start sets the controller's state so that the first force is +-F0 (the
plant at its start values) and runs until the motion settles: to rest (no
cycle from there), or to a cycle, read on the section where the output
crosses the middle of its swing upwards. The cycle is then shot: Newton on
``P(z) - z`` for the section map P, its Jacobian by differences from the
FMU state saved on the section (so the FMU's discrete states are the
orbit's); the eigenvalues of that Jacobian, the one near 0 along the flow
removed, are the Floquet multipliers; one more period, in pieces, gives the
harmonics of the output and the force and their trace. Runs in the worker process.
"""

import math

import numpy as np

from dfwb.base.defaults import HARMONICS
from dfwb.fmi.simulation import FMUError
from dfwb.foreign import held_loop, model_exchange
from dfwb.foreign.flow import Flow
from dfwb.foreign.native_flow import Drive

__all__ = ["cycles", "realization", "merge"]

SETTLE = 40  # reference periods a start runs before its swing is read
MAX_RETURNS = 200  # section returns before a start counts as not settled
NEWTON = 12  # shooting iterations
TRACE = 200  # samples of a cycle's period in its trace
REST = 1e-6  # a swing below this fraction of the largest output seen is rest (a decay, not a cycle)
SEED_RESIDUAL = 1e-8  # a cycle shot from a DF prediction counts only if Newton got this close


def realization(num, den):
    """(A, B, C, D) of G = num/den (controllable canonical form), so that force = -(C w + D y), w' = A w + B y."""
    num, den = np.atleast_1d(np.asarray(num, float)), np.atleast_1d(np.asarray(den, float))
    num = np.concatenate((np.zeros(len(den) - len(num)), num)) / den[0]
    den = den / den[0]
    n = len(den) - 1
    D = num[0]
    A = np.zeros((n, n))
    if n:
        A[0, :] = -den[1:]
        A[1:, :-1] = np.eye(n - 1)
    B = np.zeros(n)
    if n:
        B[0] = 1.0
    C = num[1:] - D * den[1:]
    return A, B, C, D


class _Loop:
    """The closed loop of one instance under (A, B, C, D), with optional Fourier integrals at omega."""

    def __init__(self, instance, A, B, C, D, omega=None):
        self.inst, self.n = instance, len(B)
        self.flow = Flow(instance, drive=Drive(A=A, B=B, C=C, D=D, K=-1 if omega is None else HARMONICS,
                                               omega=omega or 0.0, u_integrals=omega is not None))

    def atol(self, rtol):
        return self.flow.atol(rtol)


def _still(flow, low, high):
    """Whether an output swinging between low and high is at rest: within REST of the largest output seen."""
    return not high - low > REST * max(abs(high), abs(low), flow.y_max, 1e-300)


def _swing(loop, t, z, duration, rtol):
    """Run ``duration`` in 96 pieces; returns (t, z, lowest y, highest y) of the outputs read at the pieces'
    ends in its last third, or in the first of its twelfths where the motion has come to rest: the output
    within REST of the largest seen and every state moved less than REST of its scale over the twelfth
    (a stuck mass whose controller winds up is not at rest), so that a loop that settles quickly is not
    run on for the whole ``duration``."""
    flow = loop.flow
    last_low = last_high = None
    for twelfth in range(12):
        begin, low, high = z, None, None
        for _ in range(8):
            t, z, _, _ = flow.run(t, z, t + duration / 96, rtol, loop.atol(rtol), first_step=flow.last_step)
            y, _u = flow.evaluate(t, z)
            low, high = (y, y) if low is None else (min(low, y), max(high, y))
        if twelfth >= 8:  # the last third
            last_low, last_high = (low, high) if last_low is None else (min(last_low, low), max(last_high, high))
        elif _still(flow, low, high) and np.all(np.abs(z - begin) <= REST * np.maximum(flow.scale, 1e-300)):
            return t, z, low, high
    return t, z, last_low, last_high


def cycles(instance, num, den, params, starts, omega_ref, rtol=1e-9, seeds=()):
    """(cycles found as dicts, outcomes per start, then per seed) of the loop from each start force in
    ``starts``, and by Newton from each DF prediction (F, omega) in ``seeds`` (model exchange).

    ``omega_ref``: a frequency that sets the time scales (a DF prediction's, or G's crossover).
    """
    A, B, C, D = realization(num, den)
    if len(B) == 0:
        raise FMUError("the true cycles need a controller with a state (a dynamic G): G is a pure gain here")
    cosimulation = instance.kind == "co-simulation"
    if not cosimulation and not instance.info.can_save_state.get("model-exchange", False):
        raise FMUError(f"{instance.info.path}: cannot save and restore its state (canGetAndSetFMUstate): the "
                       "cycles cannot be shot from it")
    T_ref = 2 * math.pi / omega_ref

    settled = []  # (period, swing, cycle) of the cycles shot so far: a later start that settles on one is not shot

    def from_start(F0):
        instance.start(params, F0)
        w0 = -F0 * C / float(C @ C) if float(C @ C) > 0 else np.zeros(len(B))
        if cosimulation:
            return held_loop.settle_and_refine(instance, A, B, C, D, w0, T_ref, rtol, SETTLE)
        z = np.concatenate((instance.states(), w0))
        return _settle_and_shoot(instance, _Loop(instance, A, B, C, D), z, T_ref, rtol, A, B, C, D, settled)

    runs = [(f"F0={F0:g}", lambda F0=F0: from_start(F0)) for F0 in starts]
    runs += [(f"DF F={F:.6g}, omega={omega:.6g}", lambda F=F, omega=omega: _seeded(instance, params, F, omega, rtol,
                                                                                   A, B, C, D))
             for F, omega in (seeds if not cosimulation else ())]
    found, outcomes = [], []
    for label, run in runs:
        try:
            outcome, cycle = run()
        except (FMUError, FloatingPointError) as error:
            outcome, cycle = f"failed: {error}", None
        outcomes.append(outcome)
        if cycle is not None:
            merge(found, dict(cycle, started_from=[label]))
    return found, outcomes


def merge(found, cycle):
    """Add ``cycle`` to the list ``found``, or its starts to the same cycle there (period and amplitude
    within 1e-5, or within a co-simulated cycle's estimated errors)."""
    errors = cycle.get("errors", {})
    same = [c for c in found if all(abs(c[name] - cycle[name]) <= max(1e-5 * cycle[name], errors.get(name, 0.0))
                                    for name in ("period", "amplitude_x"))]
    if same:
        same[0]["started_from"] += cycle["started_from"]
    else:
        found.append(cycle)


def _settle_and_shoot(instance, loop, z, T_ref, rtol, A, B, C, D, settled):
    """(outcome, cycle or None) of one start: settled, its section returns followed until they repeat, shot.
    Where the motion repeats with the period (to 1e-6) and the swing (to 1e-4) of a cycle in ``settled``
    it is that cycle (already shot from another start); a cycle shot here is added to ``settled``."""
    flow = loop.flow
    flow.scale = np.maximum(flow.scale, np.abs(z))
    t, z, low, high = _swing(loop, 0.0, z, SETTLE * T_ref, rtol)
    if _still(flow, low, high):
        return "rest", None
    middle = 0.5 * (low + high)

    def section(t, w, y):
        return y - middle

    # to the section, then returns until the orbit repeats
    t, z, _, crossed = flow.run(t, z, t + 20 * T_ref, rtol, loop.atol(rtol), section)
    if not crossed:
        return "rest", None
    previous, period = z, None
    for _ in range(MAX_RETURNS):
        t0 = t
        t, z, _, crossed = flow.run(t, z, t + 20 * T_ref, rtol, loop.atol(rtol), section)
        if not crossed:
            return "rest", None
        close = np.all(np.abs(z - previous) <= 1e-6 * np.maximum(flow.scale, 1e-300))
        if close and period is not None and abs((t - t0) - period) <= 1e-6 * period:
            break
        previous, period = z, t - t0
    else:
        return "not settled", None
    swing = high - low
    for known_period, known_swing, cycle in settled:
        if abs(period - known_period) <= 1e-6 * period and abs(swing - known_swing) <= 1e-4 * swing:
            return "cycle", cycle
    outcome, cycle = _shoot(instance, loop, t, z, period, section, rtol, A, B, C, D)
    if cycle is not None:
        settled.append((period, swing, cycle))
    return outcome, cycle


def _seeded(instance, params, F, omega, rtol, A, B, C, D):
    """(outcome, cycle or None): Newton from the harmonic balance at a DF prediction (F, omega), which may
    be unstable. The FMU is driven by F cos(omega t) to its periodic response; the controller's state is
    set to its response to that output's mean and first harmonic; the loop, closed there, is run to the
    output's next upward crossing of its mean and shot from it."""
    T = 2 * math.pi / omega
    X, _error, periodic, *_rest, t, x = model_exchange.periodic_response(instance, F, omega, params, harmonics=1,
                                                                          rtol=rtol)
    if not periodic:
        return "seed not periodic", None
    n = len(B)
    w = np.real(np.linalg.solve(1j * omega * np.eye(n) - A, B * X[1]))  # at t = kT, e^{j omega t} = 1
    try:
        w = w - np.linalg.solve(A, B * X[0].real)  # the mean's part, where G has no pole at 0
    except np.linalg.LinAlgError:
        pass
    loop = _Loop(instance, A, B, C, D)
    z = np.concatenate((x, w))
    loop.flow.scale = np.maximum(loop.flow.scale, np.abs(z))
    loop.flow.y_max = abs(X[0]) + abs(X[1])
    middle = X[0].real

    def section(t, w, y):
        return y - middle

    t, z, _, crossed = loop.flow.run(t, z, t + 3 * T, rtol, loop.atol(rtol), section)
    if not crossed:
        return "seed lost", None
    outcome, cycle = _shoot(instance, loop, t, z, T, section, rtol, A, B, C, D)
    if cycle is None or cycle["residual"] > SEED_RESIDUAL:
        return "seed not converged", None
    return "seed cycle", cycle


def _shoot(instance, loop, t, z, period, section, rtol, A, B, C, D):
    """Newton on the section map from z at t (on the section), the FMU's state saved there; then one period
    measured: (outcome, cycle dict)."""
    flow = loop.flow
    saved = instance.save()
    t_section = t

    def section_map(u):
        instance.restore(saved, t_section)
        flow.next_event = None
        t1, z1, events, crossed = flow.run(t_section, u, t_section + 3 * period, rtol / 10, loop.atol(rtol / 10),
                                           section)
        return (z1, t1 - t_section, events) if crossed else (None, None, None)

    u = z.copy()
    scale = np.maximum(flow.scale, 1e-6 * float(np.max(flow.scale)))
    iterations, residual = 0, math.inf
    for iterations in range(1, NEWTON + 1):
        z1, T, events = section_map(u)
        if z1 is None:
            return "not settled", None
        r = z1 - u
        columns = []
        for j in range(len(u)):
            du = np.zeros(len(u))
            du[j] = 1e-6 * scale[j]
            zj, _, _ = section_map(u + du)
            if zj is None:
                return "not settled", None
            columns.append((zj - z1) / du[j])
        DP = np.array(columns).T
        residual = float(np.max(np.abs(r) / scale))
        if residual < 1e-10:
            break
        try:
            u = u - np.linalg.solve(DP - np.eye(len(u)), r)
        except np.linalg.LinAlgError:
            return "not settled", None
    multipliers = sorted(np.linalg.eigvals(DP), key=abs, reverse=True)[:-1]  # the flow's (near 0) removed
    # one period measured: the harmonics of the output and the force
    omega = 2 * math.pi / T
    instance.restore(saved, t_section)
    measure = _Loop(instance, A, B, C, D, omega)
    n = len(B)
    measure.flow.scale = np.concatenate((flow.scale, np.full(2 * (HARMONICS + 1) + 2, T * max(flow.y_max, 1e-300))))
    extra = np.zeros(2 * (HARMONICS + 1) + 2)
    start = np.concatenate((u, extra))
    z_end, events = start, 0
    times = t_section + T * np.arange(TRACE + 1) / TRACE
    y, f = np.empty(TRACE + 1), np.empty(TRACE + 1)
    y[0], f[0] = measure.flow.evaluate(times[0], z_end)
    for i in range(TRACE):  # in pieces, the output and the force read at each end (the trace drawn)
        _t, z_end, more, _ = measure.flow.run(times[i], z_end, times[i + 1], rtol / 10, measure.atol(rtol / 10),
                                              first_step=times[i + 1] - times[i])
        events += more
        y[i + 1], f[i + 1] = measure.flow.evaluate(times[i + 1], z_end)
    I = z_end[instance.nx + n:]
    Y = (I[:HARMONICS + 1] - 1j * I[HARMONICS + 1:2 * HARMONICS + 2]) * (2 / T)
    Y[0] = I[0] / T
    force = complex(I[-2], -I[-1]) * (2 / T)
    if not abs(Y[1]) > REST * flow.y_max:  # Newton found the equilibrium the motion decays to, not a cycle
        return "rest", None
    return "cycle", {
        "omega": omega, "period": T, "amplitude_x": abs(Y[1]), "F": abs(force),
        "stable": bool(max(abs(m) for m in multipliers) < 1.0) if multipliers else True,
        "multipliers": [abs(m) for m in multipliers], "residual": residual, "iterations": iterations,
        "state": [float(v) for v in u], "returns": 1, "harmonics": [abs(y) for y in Y],
        "counts": {"events": int(events)}, "signature": [],
        "spectrum": [[float(m.real), float(m.imag)] for m in multipliers], "sections": [[float(v) for v in u]],
        "swing": [float(v) for v in flow.scale],
        "trace": {"t": (times - t_section).tolist(), "y": y.tolist(), "f": f.tolist(), "events": []},
    }
