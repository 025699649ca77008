"""The exact closed loops in C (fmus/native hybrid.c, loops.c; dfwb.fmus.native_core) against their Python oracles.

The C loops port dfwb.fmus.loops (FrictionLoop, BacklashLoop, StaticBacklashLoop) and dfwb.fmus.hybrid
(HybridSolver, Mode, Polynomial, trend, Budget) keeping their operation order, chunk grid and bounds, so
they must agree bit for bit - and do: nothing in the port needs a tolerance (sums run left to right from
0.0 as Python's sum() of floats does, k! is the correctly rounded double Python divides by, powers go
through libm's pow as CPython's float ** int). On the loops of tests/test_exact_loop.py and
tests/test_periodic.py they give the same event sequences (kinds and times), the same states after long
advances, whole or stepped, the same section crossings, the same shots, periods, Floquet multipliers and
period traces of dfwb.engine.periodic with the C classes swapped in, the same Budget spent; every refusal
of the Python loops is a refusal in C with the same text; copies are independent. A loop's state as bytes
reads back and continues bit for bit; damaged or crafted bytes are refused with one line or give a loop
whose next step is bounded (fuzzed in a subprocess). The time per event and per period of C and Python is
printed (with -s), not asserted.
"""

import copy
import json
import math
import pickle
import random
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from native_fmu_helpers import HEADER, with_crc
from test_periodic import LOOPS as PERIODIC  # tests/test_periodic.py's loops

from dfwb.engine.cycles import find_cycles
from dfwb.engine.periodic import MAX_CHUNKS, LoopProblem
from dfwb.fmus.backlash import BacklashLoop
from dfwb.fmus.compensation import Coulomb, Deadband, Reset
from dfwb.fmus.exact import PlantError
from dfwb.fmus.friction import FrictionLoop
from dfwb.fmus.hybrid import Budget
from dfwb.fmus.loops import STICK
from dfwb.fmus.native_core import ABI, NativeFrictionLoop, NativeMode
from dfwb.fmus.state import StateRefused
from dfwb.fmus.static_backlash import StaticBacklashLoop

pytestmark = pytest.mark.needs_cc

PID = ([40.0, 300.0, 1000.0], [10.0, 0.0])  # 20 + 100/s + 2s/(0.1s + 1)
PI = ([30.0, 60.0], [0.0])  # 30 + 60/s
LEAD = ([200.0, 400.0], [20.0])  # 200 (s + 2)/(s + 20)
LEAD_LOW = ([20.0, 40.0], [20.0])  # 20 (s + 2)/(s + 20)
THIRD = ([0.0, 0.0, 0.0, 200.0], [3.0, 3.0, 1.0])  # 200/(s + 1)^3


def lagged(G, pole=200.0, lags=7):
    """G(s) (200/(s + 200))^7: the controller G of order 1 made order 8 (its coefficients span 1e0..1e16)."""
    num = np.poly1d(G[0]) * pole ** lags
    den = np.poly1d([1.0] + G[1]) * np.poly1d([1.0, pole]) ** lags
    n = len(den.coeffs) - 1
    return [0.0] * (n + 1 - len(num.coeffs)) + [float(v) for v in num.coeffs], [float(v) for v in den.coeffs[1:]]


FIFTH = ([2.0, 30.0, 200.0, 600.0, 900.0, 500.0], [15.0, 85.0, 225.0, 274.0, 120.0])  # proper, order 5

PYTHON = {"friction": FrictionLoop, "backlash": BacklashLoop, "static-backlash": StaticBacklashLoop}
NATIVE = {"friction": "FrictionLoop", "backlash": "BacklashLoop", "static-backlash": "StaticBacklashLoop"}

CASES = {  # tests/test_exact_loop.py's AGREEMENT and STEPPED, and higher orders
    "friction PID": ("friction", PID, {"x0": 0.3}, 20.0),
    "friction PI": ("friction", PI, {"x0": 0.3}, 20.0),
    "friction third order": ("friction", THIRD, {"x0": 0.3}, 20.0),
    "friction order 8": ("friction", lagged(PI), {"x0": 0.3}, 10.0),
    "backlash lead eps 0.2": ("backlash", LEAD, {"eps": 0.2, "x1_0": 0.03}, 10.0),
    "backlash lead eps 0.8": ("backlash", LEAD, {"eps": 0.8, "x1_0": 0.03}, 20.0),
    "backlash PID eps 0.8": ("backlash", PID, {"eps": 0.8, "x1_0": 0.03}, 5.0),
    "backlash PID eps 0 (plastic)": ("backlash", PID, {"eps": 0.0, "x1_0": 0.03}, 10.0),
    "backlash 50/(s+1) (release)": ("backlash", ([0.0, 50.0], [1.0]), {"eps": 0.2, "x1_0": 0.03}, 3.0),
    "backlash order 5": ("backlash", FIFTH, {"eps": 0.5, "x1_0": 0.05}, 10.0),
    "backlash order 8": ("backlash", lagged(LEAD), {"eps": 0.5, "x1_0": 0.03}, 5.0),
    "static backlash lead": ("static-backlash", LEAD_LOW, {"x0": 0.3}, 20.0),
    "static backlash PI": ("static-backlash", PI, {"x0": 0.3}, 20.0),
    "static backlash order 8": ("static-backlash", lagged(LEAD_LOW), {"x0": 0.3}, 10.0),
    "G = 0, momentum kept": ("backlash", ([0.0, 0.0], [1.0]), {"M2": 3.0, "eps": 0.9, "v2_0": 1.0}, 5.0),
    "integer parameters": ("friction", ([40, 300, 1000], [10, 0]), {"M": 1, "Fc": 5, "Fs": 7, "x0": 1}, 10.0),
}


def pair(core, plant, G, params, **kw):
    """(Python loop, C loop) of the same arguments, event logs on."""
    loops = PYTHON[plant](G[0], G[1], **params, **kw), getattr(core, NATIVE[plant])(G[0], G[1], **params, **kw)
    for loop in loops:
        loop.event_log = []
    return loops


def same(py, c):
    """Everything the Python loop exposes equals the C loop's, bit for bit."""
    assert c.t == py.t
    assert c.state() == py.state()
    assert c.output() == py.output()
    assert c.key == py.key
    assert c.events == py.events
    assert c.counts() == py.counts()
    assert c.event_log == py.event_log  # (t, EventKind): kinds and times
    assert c.crossings == py.crossings  # (t, X)


def grid(t_end, dt):
    count = math.ceil(t_end / dt)
    return [min(k * dt, t_end) for k in range(1, count + 1)]


@pytest.fixture(scope="module")
def python_whole():
    """whole(case, section=None, steps=1): [(the Python loop of CASES[case], event log on, as it was after advancing
    to k t_end in one step, the seconds that step took) for k = 1 .. steps]: each Python run once for the tests that
    compare C with it (the order 8 loops take a second a run). Each entry is a deep copy: read it, do not advance it.
    (The event log only records: hybrid.py appends to it, nothing reads it.)"""
    runs = {}

    def whole(case, section=None, steps=1):
        plant, G, params, t_end = CASES[case]
        if (case, section) not in runs:
            loop = PYTHON[plant](G[0], G[1], **params, **({} if section is None else {"section": section}))
            loop.event_log = []
            runs[case, section] = loop, []
        loop, done = runs[case, section]
        while len(done) < steps:
            t0 = time.perf_counter()
            loop.advance((len(done) + 1) * t_end)
            done.append((copy.deepcopy(loop), time.perf_counter() - t0))
        return done[:steps]

    return whole


@pytest.mark.parametrize("case", CASES)
def test_a_long_advance_is_bit_identical(core, python_whole, case):
    plant, G, params, t_end = CASES[case]
    py, c = pair(core, plant, G, params)
    same(py, c)
    (py, _), (twice, _) = python_whole(case, steps=2)  # Python advanced to t_end, then to 2 t_end
    c.advance(t_end)
    same(py, c)
    assert len(py.event_log) >= 3
    c.advance(2.0 * t_end)
    same(twice, c)


@pytest.mark.parametrize("case", ["friction PID", "backlash lead eps 0.8", "backlash PID eps 0.8",
                                  "static backlash lead", "friction order 8"])
def test_any_communication_step_is_bit_identical(core, case):
    plant, G, params, t_end = CASES[case]
    whole = pair(core, plant, G, params)[1]
    whole.advance(t_end)
    for dt in (0.1, 0.0137):
        py, c = pair(core, plant, G, params)
        for t in grid(t_end, dt):
            py.advance(t)
            c.advance(t)
            assert c.state() == py.state() and c.key == py.key
        same(py, c)
        assert c.state() == whole.state() and c.event_log == whole.event_log  # as in Python: step-independent


def test_constants_and_controller_are_python_s(core):
    for plant, G, params, _t in CASES.values():
        py, c = pair(core, plant, G, params)
        for name in ("order", "Ac", "Bc", "C", "D", "coordinates", "OUTPUT", "initial_parameters"):
            assert getattr(c, name) == getattr(py, name), name
            assert type(getattr(c, name)) is type(getattr(py, name)), name
        for name in {"friction": ("M", "B", "Fc", "Fs", "sticks"), "backlash": ("M1", "M2", "h", "eps", "r2", "tol_h",
                                                                                "impacts"),
                     "static-backlash": ("M", "k", "h", "engagements")}[plant]:
            assert getattr(c, name) == getattr(py, name), name
        X = [0.1 * (i + 1) for i in range(len(py.coordinates) + py.order)]
        assert c.force(X) == py.force(X)
        assert c.translate([0.1] * len(py.coordinates), 0.2) == py.translate([0.1] * len(py.coordinates), 0.2)
        assert {key: mode.h for key, mode in c._modes.items()} == {key: mode.h for key, mode in py._modes.items()}
        assert {key: mode.terms for key, mode in c._modes.items()} == {key: m.terms for key, m in py._modes.items()}
    assert core.FrictionLoop.plant is core.FrictionMass  # the open-loop solver of a shooting's start, in C too


@pytest.mark.parametrize("cls, state", [("backlash", [0.0, 0.0, 0.0, 0.0, 0.0]),
                                        ("static-backlash", [0.05, 0.0, 0.0, 0.0]),
                                        ("backlash", [0.0, 0.0, 0.1, 0.0, 0.0]),
                                        ("friction", [0.2, 0.0, 0.01])])
def test_starts_on_a_boundary(core, cls, state):
    py, c = pair(core, cls, LEAD, {}, state=state)
    for t in (0.5, 2.0):
        py.advance(t)
        c.advance(t)
        same(py, c)


def test_friction_sticks_exactly_in_c(core):
    py, c = pair(core, "friction", PID, {"x0": 0.3})
    stuck = 0
    for t in np.linspace(0.0, 20.0, 2001)[1:]:
        py.advance(float(t))
        c.advance(float(t))
        assert c.state() == py.state() and c.key == py.key
        stuck += c.key == STICK and c.state()[1] == 0.0
    assert stuck >= 50 and c.sticks == py.sticks >= 10


def _random_case(rng):
    """A loop with a random controller of order 1..8 (real poles, some unstable, an integrator now and then), random
    plant values, start, section, steps, stops at the section and budget."""
    plant = rng.choice(list(PYTHON))
    n = rng.randint(1, 8)
    poles = [-rng.uniform(0.01, 50.0) * rng.choice([1.0, 1.0, 1.0, -0.1]) for _ in range(n)]
    if rng.random() < 0.3:
        poles[0] = 0.0
    den = [1.0]
    for p in poles:
        den = [x - p * y for x, y in zip(den + [0.0], [0.0] + den)]
    gain = 10 ** rng.uniform(-1, 3.5) * rng.choice([1.0, 1.0, 1.0, -1.0])
    b = [gain * rng.uniform(-0.2, 1.0) for _ in range(n + 1)]
    if rng.random() < 0.5:
        b[0] = 0.0
    if plant == "friction":
        kw = dict(x0=rng.uniform(-0.5, 0.5), v0=rng.choice([0.0, rng.uniform(-1, 1)]), Fc=rng.choice([0.0, 5.0]),
                  Fs=rng.choice([7.0, 5.0]), B=rng.choice([0.0, 0.5]))
    elif plant == "backlash":
        kw = dict(eps=rng.choice([0.0, 0.2, 0.8, 1.0]), x1_0=rng.uniform(-0.1, 0.1),
                  gap0=rng.choice([None, 0.0, 0.1, 0.03]), h=rng.choice([0.1, 1e-6]))
    else:
        kw = dict(x0=rng.uniform(-0.5, 0.5), v0=rng.uniform(-1, 1), k=rng.choice([1.0, 3.0]))
    if rng.random() < 0.3:
        m = len(PYTHON[plant].coordinates)
        state = [rng.uniform(-0.05, 0.05) for _ in range(m + n)]
        if plant == "backlash":
            state[2] = rng.choice([0.0, 0.1, 0.04])
        elif plant == "static-backlash":
            state[0] = state[2] / kw["k"] + rng.choice([0.05, -0.05, 0.01])
        elif rng.random() < 0.5:
            state[1] = 0.0
        kw["state"] = state
    t_end = 10 ** rng.uniform(-1, 1.3)
    steps = sorted(rng.uniform(0, t_end) for _ in range(rng.randint(0, 20))) + [t_end]
    return plant, b, den[1:], kw, rng.choice([None, 0.0, rng.uniform(-0.1, 0.1)]), steps, rng.random() < 0.5, \
        rng.choice([50, 5000, 20000])


def _trace(cls, b, a, kw, section, steps, stop, total):
    """Everything a run shows at each step, or its refusal (with the budget left)."""
    budget = Budget(total)
    try:
        loop = cls(b, a, section=section, budget=budget, **kw)
        loop.event_log = []
        trace = []
        for t in steps:
            for _ in range(100):
                if loop.t >= t:
                    break
                loop.advance(t, stop_at_section=stop)
                trace.append((loop.t, loop.state(), loop.key, loop.events, loop.counts()))
        return "ran", trace, loop.event_log, loop.crossings, budget.left
    except (PlantError, OverflowError) as error:
        return "refused", type(error).__name__, str(error), budget.left


@pytest.mark.slow
def test_random_loops_agree(core):
    """Seeded random controllers (order 1..8), plants, starts, sections and steps: identical runs or refusals."""
    rng = random.Random(2024)
    outcomes = {"ran": 0, "refused": 0}
    for _ in range(60):
        plant, b, a, kw, section, steps, stop, total = _random_case(rng)
        py = _trace(PYTHON[plant], b, a, kw, section, steps, stop, total)
        c = _trace(getattr(core, NATIVE[plant]), b, a, kw, section, steps, stop, total)
        assert c == py, (plant, b, a, kw, section, steps, stop, total)
        outcomes[py[0]] += 1
    print(f"\nrandom loops: {outcomes}")
    assert outcomes["ran"] >= 20 and outcomes["refused"] >= 5


# -- sections ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case, level", [("friction PID", 0.0), ("friction PID", 0.05), ("backlash lead eps 0.2", 0.0),
                                         ("backlash PID eps 0.8", 0.001), ("static backlash lead", 0.0),
                                         ("static backlash order 8", -0.1), ("friction order 8", 0.0),
                                         ("backlash order 8", 0.0)])
def test_section_crossings_and_returns_are_bit_identical(core, python_whole, case, level):
    plant, G, params, t_end = CASES[case]
    c = pair(core, plant, G, params, section=level)[1]
    py = python_whole(case, level)[0][0]  # Python advanced to t_end
    c.advance(t_end)
    same(py, c)
    # stopping at each upward crossing (the return map of a shooting)
    py, c = pair(core, plant, G, params, section=level)
    returns = 0
    while py.t < t_end and returns < 50:
        py.advance(t_end, stop_at_section=True)
        c.advance(t_end, stop_at_section=True)
        same(py, c)
        returns += 1
    assert returns >= 2


def test_section_started_on_the_level(core):
    py, c = pair(core, "friction", PID, {}, state=[0.1, 1.0, 0.0, 0.0], section=0.1)
    for _ in range(5):
        py.advance(10.0, stop_at_section=True)
        c.advance(10.0, stop_at_section=True)
        same(py, c)
    assert py.crossings and py.crossings[0][0] > 0.0


# -- dfwb.engine.periodic with the C classes swapped in ----------------------------------------------------------
def problem(core, plant, G, params=None, native=True, max_chunks=None):
    """A LoopProblem on the Python loops, or with the C loop class swapped in (a fresh modes cache and budget)."""
    p = LoopProblem(plant, G, params) if max_chunks is None else LoopProblem(plant, G, params, max_chunks)
    if native:
        p.cls = getattr(core, NATIVE[plant])
        p._modes = {}
        p.budget = Budget(p.budget.total)
    return p


def _same_cycle(a, b):
    for name in ("omega", "period", "amplitude_x", "F", "stable", "multipliers", "residual", "iterations", "state",
                 "returns", "harmonics", "counts", "signature", "spectrum", "sections", "swing", "started_from",
                 "prediction", "df"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("t", "y", "f"):
        assert np.array_equal(a.trace[name], b.trace[name]), name
    assert a.trace["events"] == b.trace["events"]


def _hits(p, state, count):
    """The (time, state, stopped kind) of ``count`` section hits from ``state`` (the event stops)."""
    solver, hits = p.solver(state), []
    for _ in range(count):
        assert p.hit(solver, p.horizon)
        hits.append((solver.t, solver.state(), solver.stopped))
    return hits


@pytest.mark.parametrize("name", list(PERIODIC))
def test_section_hits_and_shooting_are_bit_identical(core, name):
    plant, G, params, start = PERIODIC[name]
    results = []
    for native in (False, True):
        p = problem(core, plant, G, params, native)
        t0 = time.perf_counter()
        hits = _hits(p, p.rest_start(start), 40)
        cycle = p.shoot(hits[-1][1], on_section=True)
        results.append((hits, cycle, p.budget.left, time.perf_counter() - t0))
    (h_py, c_py, left_py, t_py), (h_c, c_c, left_c, t_c) = results
    assert h_c == h_py and h_c[-1][2] in {kind for _key, kind in p.legs[-1]}
    _same_cycle(c_py, c_c)
    assert left_c == left_py  # the same chunks integrated, through the shared Budget
    print(f"\n{name}: 40 section hits + shoot, Python {t_py:.3f} s, C {t_c:.3f} s ({t_py / t_c:.0f}x), "
          f"{MAX_CHUNKS - left_py} chunks")



def test_find_cycles_with_predictions_is_bit_identical(core):
    from dfwb.engine.limit_cycles import Cycle

    predictions = [Cycle(F=8.6348346, omega=3.4061359, N=0.269278 / 8.6348346, amplitude_x=0.269278,
                         distortion=0.08, stable=True, loeb=1.0, residual=0.0, periodic=True),
                   Cycle(F=15.557092, omega=4.728799, N=0.572046 / 15.557092, amplitude_x=0.572046,
                         distortion=0.02, stable=False, loeb=-1.0, residual=0.0, periodic=True)]
    found = []
    for native in (False, True):
        p = problem(core, "friction", "20 + 100/s + 2*s/(0.1*s+1)", native=native)
        t0 = time.perf_counter()
        search = find_cycles(p, predictions, amplitudes=[0.3], boundaries=False)
        found.append((search.cycles, search.links, p.budget.left, time.perf_counter() - t0))
    (cycles_py, links_py, left_py, t_py), (cycles_c, links_c, left_c, t_c) = found
    assert links_c == links_py == [0, 1] and left_c == left_py
    assert len(cycles_c) == len(cycles_py) == 2
    for a, b in zip(cycles_py, cycles_c):
        _same_cycle(a, b)
    print(f"\nfind_cycles (friction PID, 2 predictions, df starts on the C plant): Python {t_py:.2f} s, "
          f"C {t_c:.2f} s ({t_py / t_c:.0f}x)")


def test_a_study_too_stiff_for_its_budget_stops_alike(core):
    outcomes = []
    for native in (False, True):
        p = problem(core, "friction", "20 + 100/s + 2*s/(1e-4*s+1)", native=native, max_chunks=20_000)
        with pytest.raises(PlantError, match="more than 20000 chunks"):
            p.solver(p.rest_start(0.1)).advance(1e3)
        search = find_cycles(p, [])
        outcomes.append((search.coverage.as_dict(), [vars(f) for f in search.fates], p.budget.left))
    assert outcomes[0] == outcomes[1]
    assert outcomes[0][2] < 0 and outcomes[0][0]["complete"] is False


def test_shared_modes_bound_a_step_as_in_python(core):
    """The loops of one study share their modes; the fastest one built by any bounds every step (t_end)."""
    outcomes = []
    for cls in (BacklashLoop, core.BacklashLoop):
        modes = {}
        held = cls(*LEAD, M2=1e-3, state=[0.0] * 5, modes=modes)  # at rest in contact: the contact mode only
        alone = refusal(lambda: held.advance(3e10))  # 1e12 of its chunks (h = 0.0278 s) is 2.8e10 s
        cls(*LEAD, M2=1e-3, modes=modes)  # flying: the free mode, faster (h = 0.0131 s), into the shared dict
        shared = refusal(lambda: held.advance(2e10))  # now 1e12 chunks of the free mode (1.3e10 s) bound it
        outcomes.append((alone, shared, sorted((key, mode.h) for key, mode in modes.items())))
    assert outcomes[0] == outcomes[1]
    assert "at most 2.77778e+10 s" in outcomes[0][0][1] and "at most 1.31072e+10 s" in outcomes[0][1][1]
    assert all(type(mode) is NativeMode for mode in modes.values())


# -- refusals: the same texts --------------------------------------------------------------------------------------
def refusal(make):
    """(exception type, message) of make(), or None."""
    try:
        make()
    except (PlantError, OverflowError) as error:
        return type(error).__name__, str(error)
    return None


def same_refusal(core, plant, run):
    """run(cls) refuses alike for the Python class and the C one (and does refuse)."""
    py = refusal(lambda: run(PYTHON[plant]))
    c = refusal(lambda: run(getattr(core, NATIVE[plant])))
    assert py is not None and c == py
    return py


BAD_CONTROLLERS = [([1.0], [], "order = 0 "), ([1.0] * 10, [1.0] * 9, "order = 9 "),
                   ([1.0, 2.0, 3.0], [1.0], "number of numerator coefficients = 3 "),
                   ([1.0], [1.0], "number of numerator coefficients = 1 "), ([1.0, math.nan], [1.0], "b1 = nan "),
                   ([1.0, 2.0], [math.inf], "a1 = inf "), ([1.0, 2.0, 3.0], [1.0, -math.inf], "a2 = -inf "),
                   ([None, 2.0], [1.0], "b0 = None "), ([1.0, 2.0], ["x"], "a1 = 'x' ")]


@pytest.mark.parametrize("b, a, text", BAD_CONTROLLERS)
@pytest.mark.parametrize("plant", list(PYTHON))
def test_bad_controllers_are_refused_alike(core, plant, b, a, text):
    assert text in same_refusal(core, plant, lambda cls: cls(b=b, a=a))[1]


@pytest.mark.parametrize("plant, params", [
    ("friction", {"Dv": 0.01}), ("friction", {"Dv": -1e-9}), ("friction", {"Dv": math.nan}), ("friction", {"M": 0.0}),
    ("friction", {"B": -1.0}), ("friction", {"Fc": -1.0}), ("friction", {"Fs": 4.0}), ("friction", {"Fc": 5, "Fs": 4}),
    ("friction", {"x0": math.inf}), ("friction", {"v0": None}), ("friction", {"M": True}),
    ("backlash", {"M1": 0.0}), ("backlash", {"M2": -1.0}), ("backlash", {"h": 1e-300}), ("backlash", {"eps": 1.5}),
    ("backlash", {"gap0": 0.2}), ("backlash", {"gap0": -0.01}), ("backlash", {"gap0": math.nan}),
    ("backlash", {"h": 1, "gap0": 2}), ("backlash", {"x1_0": math.nan}), ("backlash", {"v2_0": "1"}),
    ("static-backlash", {"M": 0.0}), ("static-backlash", {"k": 0.0}), ("static-backlash", {"h": -0.1}),
    ("static-backlash", {"x0": math.nan}), ("static-backlash", {"v0": math.inf}),
])
def test_bad_parameters_are_refused_alike(core, plant, params):
    same_refusal(core, plant, lambda cls: cls(*LEAD, **params))


@pytest.mark.parametrize("plant, kw", [
    ("friction", {"state": [0.0, 0.0]}), ("friction", {"state": [0.0, 0.0, 0.0, 0.0]}),
    ("friction", {"state": [0.0, math.nan, 0.0]}), ("friction", {"state": [0.0, 0.0, math.inf]}),
    ("friction", {"state": [None, 0.0, 0.0]}),
    ("backlash", {"state": [0.0, 0.0, 0.05, 0.0, 0.0, 0.0]}), ("backlash", {"state": [math.nan, 0.0, 0.05, 0.0, 0.0]}),
    ("backlash", {"state": [0.0, 0.0, 0.05, 0.0, math.nan]}), ("backlash", {"state": [0.0, 0.0, 0.2, 0.0, 0.0]}),
    ("backlash", {"state": [0.0, 0.0, -0.01, 0.0, 0.0]}), ("backlash", {"state": [0.0, 0.0, math.nan, 0.0, 0.0]}),
    ("backlash", {"state": [0.0, 0.0]}), ("backlash", {"h": 1, "state": [0.0, 0.0, 2.0, 0.0, 0.0]}),
    ("static-backlash", {"state": [0.0, 0.0, 0.0, 0.0, 0.0]}), ("static-backlash", {"state": [0.0, math.nan, 0.0, 0.0]}),
    ("static-backlash", {"state": [0.2, 0.0, 0.0, 0.0]}), ("static-backlash", {"state": [0.0, 0.0]}),
    ("friction", {"z0": [0.0, 0.0]}), ("friction", {"z0": [math.nan]}), ("friction", {"z0": [None]}),
    ("friction", {"section": math.nan}), ("friction", {"section": "0"}),
])
def test_bad_states_are_refused_alike(core, plant, kw):
    same_refusal(core, plant, lambda cls: cls(*LEAD, **kw))


@pytest.mark.parametrize("t_end", [math.nan, -1.0, math.inf, 0.5, "2", None, 1e11, 10 ** 13])
def test_bad_end_times_are_refused_alike(core, t_end):
    def run(cls):
        loop = cls(*PID, x0=0.3)
        loop.advance(1.0)
        try:
            loop.advance(t_end)
        finally:
            assert loop.t == 1.0

    same_refusal(core, "friction", run)


DIVERGED = "the state is beyond [-1e+150, 1e+150] at t = "  # MAX_STATE: long before an event search fails


@pytest.mark.parametrize("plant, G, params, t_end, kind, text", [
    ("friction", ([0.0, -1e4], [1.0]), {"x0": 0.3}, 1e4, "Diverged", DIVERGED),
    ("backlash", ([0.0, -10.0], [1.0]), {"x1_0": 0.03}, 1e5, "Diverged", DIVERGED),
    ("static-backlash", ([0.0, -10.0], [1.0]), {"x0": 0.3}, 1e5, "Diverged", DIVERGED),
    ("backlash", ([0.0, -1.0], [1.0]), {"x1_0": 0.03}, 1e5, "Diverged", DIVERGED),
    ("static-backlash", ([0.0, -1.0], [1.0]), {"x0": 0.3}, 1e5, "Diverged", DIVERGED),
])
def test_unresolvable_motions_are_refused_alike(core, plant, G, params, t_end, kind, text):
    outcome = same_refusal(core, plant, lambda cls: cls(*G, **params).advance(t_end))
    assert outcome[0] == kind and outcome[1].startswith(text)


def test_a_heavy_mass_under_a_vanishing_controller_coasts_alike(core):
    """M = 1e100 kg under G = 1e-200 / (s + 1e-200): the chunk 1/rho was 1e200 s and its Taylor bounds
    overflowed (an OverflowError, C and Python alike); a chunk is now at most 2^20 s, and the mass coasts."""
    G, params = ([0.0, 1e-200], [1e-200]), {"M": 1e100, "B": 0.0, "x0": 0.3, "v0": 1.0}
    python, c = FrictionLoop(*G, **params), core.FrictionLoop(*G, **params)
    python.advance(1.0)
    c.advance(1.0)
    assert python.state() == c.state() and python.events == c.events == 0
    assert python.state()[:2] == [1.3, 1.0]


def test_a_budget_is_spent_alike(core):
    for total in (1, 12, 13, 78, 500, 50):  # the first step takes 12 chunks, both 78
        budgets = [Budget(total), Budget(total)]
        outcomes = []
        for cls, budget in zip((BacklashLoop, core.BacklashLoop), budgets):
            loop = cls(*PID, eps=0.8, x1_0=0.03, budget=budget)
            other = cls(*LEAD, eps=0.2, x1_0=0.03, budget=budget)  # one budget, two solvers
            outcomes.append([refusal(lambda: loop.advance(1.0)), refusal(lambda: other.advance(3.0)), budget.left])
        assert outcomes[0] == outcomes[1]
    assert outcomes[0][0] is None and re.match(r"the exact loop needed more than 50 chunks of integration "
                                               r"\(at t = [0-9.e+-]+ s a chunk is [0-9.e+-]+ s\)", outcomes[0][1][1])


def test_a_refused_step_leaves_a_usable_loop(core):
    py, c = pair(core, "friction", PID, {"x0": 0.3})
    for loop in (py, c):
        loop.advance(2.0)
        with pytest.raises(PlantError):
            loop.advance(1.0)
        loop.advance(5.0)
    same(py, c)


def test_no_core_no_loop():
    from dfwb.fmus.native_core import CoreError

    with pytest.raises(CoreError, match="needs a C core"):
        NativeFrictionLoop(*PID)


# -- copies ------------------------------------------------------------------------------------------------------
def test_copies_are_independent_and_exact(core):
    plant, G, params, t_end = CASES["backlash PID eps 0.8"]
    py, c = pair(core, plant, G, params, section=0.0)
    py.advance(1.0)
    c.advance(1.0)
    clone, shallow, deep = c.copy(), copy.copy(c), copy.deepcopy(py)
    assert clone.state() == c.state() and clone.event_log == c.event_log and clone.crossings == c.crossings
    assert clone.event_log is not c.event_log and clone.crossings is not c.crossings
    clone.advance(3.0)  # the copy runs on; the original stays where it was
    assert c.t == 1.0 and c.state() == py.state() and c.event_log == py.event_log
    deep.advance(3.0)
    same(deep, clone)
    for loop in (py, c, shallow):
        loop.advance(t_end)
    same(py, c)
    same(py, shallow)
    del c  # the copy owns its C instance
    clone.advance(t_end)
    same(py, clone)


# -- the state as bytes ---------------------------------------------------------------------------------------------
def _states(core):
    """{NativeCore attribute: [hex of states]} along runs with a section (pending events, contacts, sticks...)."""
    found = {}
    for case in ("friction PID", "backlash PID eps 0.8", "static backlash lead", "friction order 8"):
        plant, G, params, t_end = CASES[case]
        loop = getattr(core, NATIVE[plant])(*G, **params, section=0.0)
        states = found.setdefault(NATIVE[plant], [])
        for k in range(1, 30):
            loop.advance(k * t_end / 29.0, stop_at_section=k % 3 == 0)
            states.append(loop.to_bytes().hex())
    loop = core.FrictionLoop([10.0, 2.0], [0.0], x0=0.7, section=0.0,
                             compensation=[Coulomb(1.5), Reset(), Deadband(0.05)])
    for k in range(1, 30):  # the compensators' fields, the deadband's sides
        loop.advance(k * 10.0, stop_at_section=k % 3 == 0)
        found["FrictionLoop"].append(loop.to_bytes().hex())
    return found


@pytest.mark.parametrize("case", ["friction PID", "backlash PID eps 0.8", "backlash PID eps 0 (plastic)",
                                  "static backlash lead", "friction order 8", "G = 0, momentum kept"])
def test_state_round_trip_continues_bit_for_bit(core, python_whole, case):
    plant, G, params, t_end = CASES[case]
    py = python_whole(case, 0.0)[0][0]  # Python advanced to t_end
    c = getattr(core, NATIVE[plant])(*G, **params, section=0.0)
    cls = type(c)
    for k in range(1, 24):
        c.advance(k * t_end / 23.0, stop_at_section=k % 2 == 0)
        data = c.to_bytes()
        again = cls.from_bytes(data)
        assert again.to_bytes() == data and again.same_parameters(c) and c.same_parameters(again)
        assert again.state() == c.state() and again.key == c.key and again.t == c.t and again.counts() == c.counts()
        assert pickle.loads(pickle.dumps(c)).to_bytes() == data
        for name in ("order", "Ac", "Bc", "C", "D") + cls.CONSTANTS:
            assert getattr(again, name) == getattr(py, name), name
        again.advance(t_end)
        assert again.state() == py.state() and again.events == py.events and again.counts() == py.counts()
    # 440 + 5 compensator fields + an integrated step (62) + a dither's 2 coordinates (12 arrays' entries) and 3
    # fields + a backlash inverse's correction (6 arrays' entries) and 2 fields
    assert len(data) == HEADER + 1096 + 8 * 8 == core.loop_api.state_size


def test_same_parameters(core):
    make = core.BacklashLoop
    a = make(*LEAD, eps=0.2, section=0.0)
    assert a.same_parameters(make(*LEAD, eps=0.2, section=0.0, x1_0=0.5))  # initial values are no parameters
    for other in (make(*LEAD, eps=0.3, section=0.0), make(*LEAD, eps=0.2), make(*LEAD, eps=0.2, section=-0.0),
                  make(*PID, eps=0.2, section=0.0), core.FrictionLoop(*LEAD, section=0.0)):
        assert not a.same_parameters(other)
    assert not a.same_parameters(BacklashLoop(*LEAD, eps=0.2, section=0.0)) and not a.same_parameters(None)


def test_damaged_states_are_refused(core):
    data = core.FrictionLoop(*PID, x0=0.3).to_bytes()
    cases = [
        (data[:10], "truncated"), (data[:-8], "truncated or oversized"), (data + b"\0" * 8, "truncated or oversized"),
        (b"X" + data[1:], "no DFWBSTAT header"),
        (data[:8] + struct.pack("<I", ABI - 1) + data[12:], f"written by core ABI {ABI - 1}, this core is ABI {ABI}"),
        (core.BacklashLoop(*PID).to_bytes(), "one of a dfwb_backlash_loop, not of a dfwb_friction_loop"),
        (core.FrictionMass().to_bytes(), "one of a dfwb_friction, not of a dfwb_friction_loop"),
        (data[:-1] + bytes([data[-1] ^ 1]), "checksum does not match"),
        (with_crc(data[:HEADER + 56] + struct.pack("<q", 9) + data[HEADER + 64:]), "order = 9 is out of range"),
        (with_crc(data[:HEADER] + struct.pack("<d", -1.0) + data[HEADER + 8:]),
         "parameters are refused: M = -1.0 is out of range"),
    ]
    for crafted, text in cases:
        with pytest.raises(StateRefused, match=re.escape(text)) as error:
            core.FrictionLoop.from_bytes(crafted)
        assert "\n" not in str(error.value)
    with pytest.raises(StateRefused, match="must be bytes, not str"):
        core.FrictionLoop.from_bytes("abc")
    with pytest.raises(StateRefused, match="one of a dfwb_friction_loop, not of a dfwb_friction"):
        core.FrictionMass.from_bytes(data)


FUZZ = r"""
import json, math, random, struct, sys
sys.path.insert(0, sys.argv[2])
from native_fmu_helpers import HEADER, counted_once, read_or_refuse, with_crc as crc
from dfwb.fmus.hybrid import Budget
from dfwb.fmus.native_core import load
from dfwb.fmus.exact import PlantError

core = load(sys.argv[1])
states = json.loads(sys.stdin.read())
rng = random.Random(7)
SPECIAL = [math.nan, math.inf, -math.inf, -1.0, 0.0, -0.0, 1.0, 0.5, 2.0, 3.0, 1e308, -1e308, 5e-324, 1e-300, 1e10]
INTS = [-1, 1, 2, 3, 4, 5, 8, 9, 11, 101, 102, 2**31 - 1, -2**31, 2**62, -2**63]
tally = {"refused": 0, "accepted": 0, "stepped": 0, "step refused": 0}

def _attempt(cls, data):
    loop = read_or_refuse(cls, data, tally, budget=Budget(20000))
    if loop is None:
        return
    loop.state(); loop.output(); loop.counts(); loop.key; loop.copy()
    loop.event_log = []
    try:
        loop.advance(loop.t + 1.0)  # at most 20000 chunks: the budget bounds a crafted fast mode's work
        loop.state()
        tally["stepped"] += 1
    except (PlantError, OverflowError):
        tally["step refused"] += 1

attempt = counted_once(tally, _attempt)  # the same bytes run once, counted each time

for attr, entries in states.items():
    cls = getattr(core, attr)
    for hexdata in entries[::4]:
        data = bytes.fromhex(hexdata)
        for i in range((len(data) - HEADER) // 8):  # every field set to each special value, the checksum made valid
            for value in SPECIAL + INTS:
                crafted = bytearray(data)
                raw = struct.pack("<d", value) if isinstance(value, float) else struct.pack("<q", value)
                crafted[HEADER + 8 * i:HEADER + 8 * i + 8] = raw
                attempt(cls, crc(crafted))
    for _ in range(300):  # fields mixed across the honest states, or scaled
        data = bytes.fromhex(rng.choice(entries))
        crafted, other = bytearray(data), bytes.fromhex(rng.choice(entries))
        for _ in range(rng.randint(1, 4)):
            i = rng.randrange((len(data) - HEADER) // 8)
            if rng.random() < 0.6:
                raw = other[HEADER + 8 * i:HEADER + 8 * i + 8]
            else:
                raw = struct.pack("<d", struct.unpack("<d", bytes(crafted[HEADER + 8 * i:HEADER + 8 * i + 8]))[0]
                                  * rng.choice([-1.0, 0.5, 2.0, 1 + 1e-15, 1e6]))
            crafted[HEADER + 8 * i:HEADER + 8 * i + 8] = raw
        attempt(cls, crc(crafted))
print(json.dumps(tally))
"""


@pytest.mark.slow
def test_state_fuzzing_never_crashes(core):
    """Fields set to extreme values, fields mixed across states (checksums made valid): refused with one line,
    or accepted as a loop whose copy, outputs and next step (within a Budget) work and whose bytes read back
    the same; in a subprocess, so that a crash would fail the test, not end it."""
    run = subprocess.run([sys.executable, "-c", FUZZ, str(core.path), str(Path(__file__).resolve().parent)],
                         input=json.dumps(_states(core)), capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"the fuzzing process failed (exit {run.returncode}): {run.stderr[-2000:]}"
    tally = json.loads(run.stdout)
    print(f"\nloop state fuzzing: {tally}")
    assert tally["refused"] > 1000 and tally["stepped"] > 500


# -- timing (printed, not asserted) -----------------------------------------------------------------------------
def test_time_per_event_and_per_period(core, python_whole):
    rows = []
    for case in ("friction PID", "backlash PID eps 0.8", "static backlash lead", "friction order 8"):
        plant, G, params, t_end = CASES[case]
        times = [python_whole(case)[0][1]]  # Python's step to t_end, as timed when it ran
        for loop in pair(core, plant, G, params)[1:]:
            t0 = time.perf_counter()
            loop.advance(t_end)
            times.append(time.perf_counter() - t0)
        events = max(loop.events, 1)
        rows.append(f"{case}: {loop.events} events in {t_end:g} s, per event Python {1e6 * times[0] / events:.0f} us, "
                    f"C {1e6 * times[1] / events:.1f} us ({times[0] / times[1]:.0f}x)")
    for name in ("friction_pid", "backlash_lead_eps08", "static_backlash_lead"):
        plant, G, params, start = PERIODIC[name]
        per = []
        for native in (False, True):
            p = problem(core, plant, G, params, native)
            first = p.first_return(_hits(p, p.rest_start(start), 40)[-1][1])
            periods, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < 0.3 or periods < 3:
                first = p.first_return(first[0])
                periods += 1
            per.append((time.perf_counter() - t0) / periods)
        rows.append(f"{name}: one period (a return to the section, a new solver each) Python {1e3 * per[0]:.2f} ms, "
                    f"C {1e3 * per[1]:.3f} ms ({per[0] / per[1]:.0f}x)")
    print("\n" + "\n".join(rows))
