"""dfwb's limit-cycle search against cycles found without dfwb: every cycle a long simulation reaches is found.

For each loop of ``LOOPS`` (the issue's friction PI and PID loops, the
two-mass backlash and the static backlash under lead compensation) the
independent reference :func:`dfwb.plants.loop_reference.closed_loop_reference`
(solve_ivp, DOP853 at rtol 1e-12, events located by solve_ivp, the switching
written by hand; it shares no code with dfwb's exact loops or its cycle
search) is used alone to find the cycle the loop settles into:

1. **Settling** (:func:`settle`). The loop runs from rest at the given start
   from one section hit to the next (a Poincare section defined by the
   reference's own events, ``SECTIONS``: friction, the first ``band`` from
   ``slide+`` after one from ``slide-``; backlash, the first ``gap h`` after a
   ``gap 0``; static backlash, the first ``engage+`` after an ``engage-``)
   until successive section states agree to ``SETTLED`` (relative to each
   coordinate's swing over the last period). This proves that the loop,
   started from rest, does settle, and gives the neighbourhood of the cycle.
2. **The cycle** (:func:`reference_cycle`). ``scipy.optimize.root`` (hybr) on
   the reference's return map of that section, in the coordinates the event
   leaves free (the one it fixes removed: v = 0, gap = h, x = y/k + h/2),
   each scaled by its swing, to a residual of ``RESIDUAL``. Its period T is
   the reference's time from the section back to it, omega = 2 pi / T, and
   the amplitude is the first harmonic of the plant output (x, x1 or y),
   ``|2/T int y exp(-j omega t) dt|``, by 16-node Gauss-Legendre quadrature on
   every smooth piece between the period's events, the output sampled from
   solve_ivp's dense output (``t_eval``). The same integral with every piece
   halved agrees to ``QUADRATURE``: the quadrature error is negligible.
3. **Stability** (:func:`test_simulation_converges_to_the_cycle`). The last
   section states of the settling run approach that fixed point (the
   largest distance of the last ``WINDOW`` hits is below that of the
   ``WINDOW`` before, unless it is the map's noise, ``NOISE``; the last is
   within ``APPROACH``): the cycle found is the one the simulation from rest
   converges to, so it is stable. (Windows, not single hits: where the
   leading multipliers are complex, as for backlash with eps = 0.8, single
   distances go up and down on the way in.)
4. **dfwb** (:func:`test_dfwb_finds_the_cycle`). ``find_cycles(LoopProblem(...))``
   lists a *stable* cycle with omega and ``amplitude_x`` within ``AGREE``
   (1e-6 relative) of the reference's. That dfwb's controller coefficients
   are those the reference ran (written here from Kp, Ki, Kd, Tf or K, zero,
   pole, not parsed by dfwb) is checked first.

Together: for every loop here, the cycle an independent long simulation from
rest reaches is in dfwb's answer, stable, with the same frequency and
amplitude to 1e-6. (The other way round, that the cycles dfwb shoots are
periodic orbits of the reference too, is checked in ``tests/test_periodic.py``.)

The friction PI loops with Kp = 40 settle slowly (leading multiplier about
0.99, periods up to 870 s): a simulation to 1e-8 would take thousands of
periods, hence the root finding after settling to 1e-4.

Measured (all 26 loops): dfwb's omega and amplitude_x within 4.4e-12 of the
reference's (relative), so ``AGREE`` keeps a margin of over 1e5; section-map
residuals at most 9.1e-12; halving the quadrature's pieces changes the
amplitude by at most 4.1e-14. Settling takes 6 to 392 section hits (friction
40 + 0.5/s: 392 hits, 4e5 s of simulated time, about 5 s); the module runs in
about 30 s on two cores.
"""

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pytest
from scipy.optimize import root

from dfwb.engine.cycles import find_cycles
from dfwb.engine.periodic import LoopProblem
from dfwb.plants.loop_reference import DEFAULTS, closed_loop_reference

SETTLED = 1e-4  # successive section states this close (relative to the swing): the simulation has settled
WINDOW = 3  # the approach is seen over windows of this many section hits
MIN_HITS = 2 * WINDOW  # section hits at least, so that the approach can be seen
MAX_HITS = 3000  # ... and at most (the slowest loop here takes 392)
T_MAX = 1e4  # s, the longest wait for a section hit
RESIDUAL = 1e-10  # |P(u) - u| / swing at the reference's fixed point (measured: below 1e-11)
NOISE = 1e-9  # distances to the fixed point below this are the map's noise, not an approach
APPROACH = 0.05  # the last settling state is within this (relative to the swing) of the fixed point
QUADRATURE = 1e-10  # the first harmonic with 16 nodes per piece and per half piece agree this well (relative)
AGREE = 1e-6  # dfwb's omega and amplitude_x against the reference's, relative
NODES = np.polynomial.legendre.leggauss(16)


@dataclass(frozen=True)
class Section:
    """A plant's Poincare section and output: the hit after the arming event, the coordinate the hit fixes."""

    start: str  # the parameter holding the output's start
    arm: tuple  # (kind, mode before or None): the event that arms the section
    hit: tuple  # the event that is the section, once armed
    fixed: int  # the coordinate of the loop state the hit fixes (removed from the map's coordinates)
    value: object  # value(X, p): that coordinate from the others and the parameters
    output: int  # the plant output's index in the loop state


SECTIONS = {
    "friction": Section("x0", ("band", "slide-"), ("band", "slide+"), 1, lambda X, p: 0.0, 0),
    "backlash": Section("x1_0", ("gap 0", None), ("gap h", None), 2, lambda X, p: p["h"], 0),
    "static-backlash": Section("x0", ("engage-", None), ("engage+", None), 0,
                               lambda X, p: X[2] / p["k"] + 0.5 * p["h"], 2),
}


def pi(Kp, Ki):
    """Kp + Ki/s: the text dfwb parses and (b, a), written out."""
    return f"{Kp} + {Ki}/s", [Kp, Ki], [0.0]


def pid(Kp, Ki, Kd, Tf):
    """Kp + Ki/s + Kd s/(Tf s + 1) = ((Kp Tf + Kd) s^2 + (Kp + Ki Tf) s + Ki) / Tf / (s^2 + s/Tf)."""
    return (f"{Kp} + {Ki}/s + {Kd}*s/({Tf}*s+1)", [(Kp * Tf + Kd) / Tf, (Kp + Ki * Tf) / Tf, Ki / Tf],
            [1.0 / Tf, 0.0])


def lead(K, zero, pole):
    """K (s + zero)/(s + pole)."""
    return f"{K}*(s+{zero})/(s+{pole})", [K, K * zero], [pole]


# (plant, (G, b, a), plant parameters, the output's start)
LOOPS = [("friction", pi(Kp, Ki), {}, 0.1) for Kp in (5, 10, 20, 40) for Ki in (0.5, 1, 2, 4)] + [
    ("friction", pid(20, 100, 2, 0.1), {}, 0.3),
    ("friction", pid(40, 200, 4, 0.05), {}, 0.1),
    ("friction", pid(20, 5, 2, 0.05), {}, 0.1),
    ("friction", pi(30, 60), {}, 0.1),
    ("backlash", lead(200, 2, 20), {"eps": 0.2}, 0.03),
    ("backlash", lead(200, 2, 20), {"eps": 0.8}, 0.03),
    ("backlash", lead(100, 1, 10), {"eps": 0.5}, 0.03),
    ("backlash", lead(50, 3, 30), {"eps": 0.0}, 0.1),
    ("static-backlash", lead(20, 2, 20), {}, 0.3),
    ("static-backlash", lead(40, 1, 10), {}, 0.01),
]
IDS = [f"{plant} {G}" + "".join(f" {k} {v}" for k, v in params.items()) for plant, (G, _b, _a), params, _x in LOOPS]


class Loop:
    """One loop as the reference runs it: its section map, from state to state."""

    def __init__(self, plant, G, params, start):
        self.plant, (self.G, self.b, self.a), self.params = plant, G, params
        self.section = SECTIONS[plant]
        self.p = {**DEFAULTS[plant], **params}
        self.rest = {**params, self.section.start: start}

    def until(self):
        """A fresh ``until`` stopping at the section's hit once its arming event has happened."""
        armed = False

        def stop(kind, before):
            nonlocal armed
            arm_kind, arm_mode = self.section.arm
            hit_kind, hit_mode = self.section.hit
            armed = armed or (kind == arm_kind and arm_mode in (None, before))
            return armed and kind == hit_kind and hit_mode in (None, before)
        return stop

    def run(self, X=None, t_eval=None):
        """The reference from X (None: rest at the start) to the next section hit; the hit's time is ``t``."""
        kwargs = {"params": self.rest} if X is None else {"params": self.params, "state": list(X)}
        r = closed_loop_reference(self.plant, self.b, self.a, T_MAX, until=self.until(), t_eval=t_eval,
                                  max_events=100_000, **kwargs)
        assert r["t"] < T_MAX, f"{self.plant} {self.G}: no section hit within {T_MAX} s (the loop came to rest?)"
        return r

    def reduce(self, X):
        """The map's coordinates: X without the coordinate the section fixes."""
        return np.delete(np.asarray(X, dtype=float), self.section.fixed)

    def full(self, u):
        """The loop state on the section with the map's coordinates u."""
        X = np.insert(np.asarray(u, dtype=float), self.section.fixed, 0.0)
        X[self.section.fixed] = self.section.value(X, self.p)
        return X

    def swing(self, X, period):
        """Each coordinate's largest magnitude over the period from X (sampled), the map's scale."""
        samples = self.run(X, t_eval=np.linspace(0.0, period, 65))["samples"]
        swing = self.reduce(np.nanmax(np.abs(np.vstack([samples, X])), axis=0))
        return np.where(swing > 0.0, swing, 1.0)


@dataclass
class Settling:
    states: list  # the section states hit, in the map's coordinates
    periods: list  # the times between hits (s)
    scale: np.ndarray  # the coordinates' swing over the last period


@dataclass
class Cycle:
    omega: float
    amplitude: float
    period: float
    residual: float  # |P(u) - u| / scale at the fixed point
    fixed_point: np.ndarray  # u
    distances: list  # the settling states' distances to u, relative to the swing
    quadrature: float  # the relative change of the amplitude when every piece is halved


@lru_cache(maxsize=None)
def settle(index):
    """Run LOOPS[index] from rest through section hits until successive ones agree to SETTLED."""
    loop = Loop(*LOOPS[index])
    r = loop.run()
    states, periods = [loop.reduce(r["state"])], [r["t"]]
    scale = loop.swing(loop.full(states[-1]), periods[-1])
    while True:
        X = loop.full(states[-1])
        r = loop.run(X)
        states.append(loop.reduce(r["state"]))
        periods.append(r["t"])
        change = np.max(np.abs(states[-1] - states[-2]) / scale)
        if len(states) >= MIN_HITS and change < SETTLED:
            break
        assert len(states) < MAX_HITS, (f"{IDS[index]} has not settled after {MAX_HITS} section hits "
                                        f"({sum(periods):.4g} s): successive hits differ by {change:.2e}")
        if len(states) % 50 == 0:  # the swing changes as the motion settles
            scale = loop.swing(X, periods[-1])
    return Settling(states, periods, loop.swing(loop.full(states[-2]), periods[-1]))


def gauss_legendre(edges, parts):
    """Nodes and weights of 16-node Gauss-Legendre on every piece between the edges, cut into ``parts`` each."""
    nodes, weights = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        cuts = np.linspace(a, b, parts + 1)
        for lo, hi in zip(cuts[:-1], cuts[1:]):
            nodes.append(0.5 * (lo + hi) + 0.5 * (hi - lo) * NODES[0])
            weights.append(0.5 * (hi - lo) * NODES[1])
    return np.concatenate(nodes), np.concatenate(weights)


def first_harmonics(loop, X, period, events):
    """|first harmonic| of the output over the period from X, with 16 nodes per smooth piece and per half piece."""
    omega = 2.0 * math.pi / period
    rules = [gauss_legendre(sorted({0.0, period, *(t for t, _kind in events)}), parts) for parts in (1, 2)]
    times = np.concatenate([nodes for nodes, _weights in rules])
    order = np.argsort(times)
    r = loop.run(X, t_eval=times[order])
    assert [kind for _t, kind in r["events"]] == [kind for _t, kind in events] and r["t"] == period, \
        f"{loop.plant} {loop.G}: the sampled period is not the one timed"
    y = np.empty(len(times))
    y[order] = r["samples"][:, loop.section.output]
    amplitudes, offset = [], 0
    for nodes, weights in rules:
        part, offset = y[offset:offset + len(nodes)], offset + len(nodes)
        amplitudes.append(abs(2.0 / period * np.sum(weights * part * np.exp(-1j * omega * nodes))))
    return amplitudes


@lru_cache(maxsize=None)
def reference_cycle(index):
    """The cycle LOOPS[index] settles into, found with the reference alone (the root of its section map)."""
    loop = Loop(*LOOPS[index])
    settling = settle(index)
    scale = settling.scale

    runs = {}  # {bytes of X: the run from X}: the root's own point was run by the root finder already

    def run(X):
        key = X.tobytes()
        if key not in runs:
            runs[key] = loop.run(X)
        return runs[key]

    def residual(v):
        u = v * scale
        return (loop.reduce(run(loop.full(u))["state"]) - u) / scale

    u = root(residual, settling.states[-1] / scale, method="hybr", options={"xtol": 1e-13}).x * scale
    X = loop.full(u)
    r = run(X)
    period = r["t"]
    whole, halved = first_harmonics(loop, X, period, r["events"])
    return Cycle(omega=2.0 * math.pi / period, amplitude=whole, period=period,
                 residual=float(np.max(np.abs(loop.reduce(r["state"]) - u) / scale)), fixed_point=u,
                 distances=[float(np.max(np.abs(state - u) / scale)) for state in settling.states],
                 quadrature=abs(halved - whole) / whole)


@pytest.fixture(scope="module", params=range(len(LOOPS)), ids=IDS)
def index(request):
    """The index in LOOPS, a module-scoped parameter: pytest runs a loop's three tests one after the other, so
    that a pytest-xdist worker that finds its reference (cached by reference_cycle) also runs the others
    (parametrized per test, the tests of one loop were spread over the workers, each finding it again)."""
    return request.param


def test_reference_cycle_is_a_fixed_point(index):
    """The root finder found the section map's fixed point, to RESIDUAL, and its harmonic is well integrated."""
    cycle = reference_cycle(index)
    assert cycle.residual < RESIDUAL, f"{IDS[index]}: |P(u) - u| = {cycle.residual:.2e}"
    assert cycle.quadrature < QUADRATURE, f"{IDS[index]}: the quadrature changes {cycle.quadrature:.2e}"


def test_simulation_converges_to_the_cycle(index):
    """The last settling hits approach the fixed point (until the noise): it is the stable cycle reached."""
    d = reference_cycle(index).distances
    before, after = max(d[-2 * WINDOW:-WINDOW]), max(d[-WINDOW:])
    assert d[-1] < APPROACH, f"{IDS[index]}: the last hit is {d[-1]:.2e} from the cycle"
    assert after < before or after < NOISE, \
        f"{IDS[index]}: the last hits' distances to the cycle {d[-2 * WINDOW:]} do not shrink"


def test_dfwb_finds_the_cycle(index):
    """find_cycles lists a stable cycle with the reference's omega and amplitude to AGREE."""
    plant, (G, b, a), params, _start = LOOPS[index]
    problem = LoopProblem(plant, G, params)
    assert np.allclose(problem.b, b, rtol=1e-14, atol=0.0) and np.allclose(problem.a, a, rtol=1e-14, atol=0.0), \
        f"{IDS[index]}: dfwb's G is b = {problem.b}, a = {problem.a}, the reference's b = {b}, a = {a}"
    truth = reference_cycle(index)
    found = find_cycles(problem).cycles
    match = [c for c in found if c.stable and abs(c.omega - truth.omega) <= AGREE * truth.omega
             and abs(c.amplitude_x - truth.amplitude) <= AGREE * truth.amplitude]
    listed = [(c.omega, c.amplitude_x, c.stable) for c in found]
    assert match, (f"{IDS[index]}: the reference's cycle omega = {truth.omega!r}, amplitude = "
                   f"{truth.amplitude!r} is not among dfwb's stable cycles (omega, amplitude_x, stable): {listed}")
