"""The two backlash solvers in C (fmus/native, dfwb.fmus.native_core) against their Python oracles, and what
the three C solvers offer beyond the Solver protocol: the event log and the state as bytes.

The C solvers port dfwb.fmus.backlash.TwoMassBacklash and dfwb.fmus.static_backlash.StaticBacklash
keeping their operation order, so they must agree to rounding: stepped identically (the quick stress
cases of ``dfwb stress`` with their held inputs, a grid, seeded parameters over the whole float range)
they count the same events, impacts, contacts and engagements at every communication point and give
outputs and Fourier integrals equal to 1e-13 relative (in practice bit for bit; the share is printed).
Every refusal of the Python solvers is a refusal in C with the same message. Event logs are equal to
the bit. A state written as bytes and read back continues bit for bit; bytes that are truncated,
oversized, of another plant or ABI, damaged, or crafted field by field are refused with one line or
accepted as a well-formed state, never a crash nor a step without end (the fuzzing runs in a
subprocess). The library is compiled once per session with -Wall -Wextra -Werror.
"""

import copy
import json
import math
import pickle
import random
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from native_fmu_helpers import HEADER, with_crc
from test_native_core import (
    Agreement,
    _bits,
    python_runs,
    refusal_pair,
    step_both,
    stress_refusals_agree,
    trace,
)

from dfwb.fmus import backlash, native_core, static_backlash
from dfwb.fmus.backlash import TwoMassBacklash
from dfwb.fmus.contract import EventKind, Solver
from dfwb.fmus.exact import PHASE_LIMIT
from dfwb.fmus.friction import FrictionMass
from dfwb.fmus.native_core import (
    ABI,
    CoreError,
    NativeStaticBacklash,
    NativeTwoMassBacklash,
)
from dfwb.fmus.state import StateRefused
from dfwb.fmus.static_backlash import StaticBacklash
from dfwb.plants.stress_kit import Case, InvalidCase, periods
from dfwb.verify.stress import all_cases

pytestmark = pytest.mark.needs_cc


PLANTS = {  # stress plant name -> (Python class, NativeCore attribute, counters)
    "backlash": (TwoMassBacklash, "TwoMassBacklash", ("contact", "impacts")),
    "static-backlash": (StaticBacklash, "StaticBacklash", ("engaged",)),
}




@pytest.fixture(scope="session")
def stress_cases():
    """{plant: (valid cases, invalid cases)} of the quick stress set."""
    cases = all_cases(quick=True)
    out = {}
    for plant in PLANTS:
        valid = [c for c in cases if isinstance(c, Case) and c.plant == plant]
        invalid = [c for c in cases if isinstance(c, InvalidCase) and c.plant == plant]
        assert len(valid) > 50 and len(invalid) > 30
        out[plant] = valid, invalid
    return out


def _native_class(core, plant):
    return getattr(core, PLANTS[plant][1])


def _step_both(plant, case, core, agreement, where, restore=False, python=None):
    return step_both(PLANTS[plant][0], _native_class(core, plant), case, agreement, where, restore, python)


@pytest.fixture(scope="module")
def plant_runs(stress_cases):
    """{plant: run(i)}: the Python oracle's run of the i-th valid stress case of the plant, once for the tests that
    compare C with it (agreement, state round trip, event logs)."""
    return {plant: python_runs(python_class, stress_cases[plant][0], counters)
            for plant, (python_class, _attr, counters) in PLANTS.items()}


# -- agreement ---------------------------------------------------------------------------
@pytest.mark.parametrize("plant", list(PLANTS))
def test_stress_cases_agree(core, stress_cases, plant_runs, plant):
    agreement = Agreement(PLANTS[plant][2])
    total_events = impacts = 0
    for i, case in enumerate(stress_cases[plant][0]):
        a, _ = _step_both(plant, case, core, agreement, case.note, python=plant_runs[plant](i)[0])
        total_events += a.events
        impacts += getattr(a, "impacts", 0)
    print(f"\n{agreement.summary(f'{plant} stress cases ({len(stress_cases[plant][0])})')}, {total_events} events"
          + (f", {impacts} impacts" if plant == "backlash" else ""))
    assert agreement.points > 10_000 and total_events > 900


BACKLASH_GRID = [(F, w, eps) for F in (10.0, 50.0) for w in (5.0, 20.0, 40.0) for eps in (0.0, 0.2, 0.5, 0.8, 1.0)]
STATIC_GRID = [(F, w) for F in (5.0, 50.0) for w in (2.0, 10.0, 20.0)]


def test_grid_agrees(core):
    lines = []
    for plant, grid in (("backlash", BACKLASH_GRID), ("static-backlash", STATIC_GRID)):
        agreement = Agreement(PLANTS[plant][2])
        events = []
        for point in grid:
            params = dict(F=point[0], omega=point[1])
            if plant == "backlash":
                params["eps"] = point[2]
            case = Case(plant, params, *periods(params, 10))
            a, _ = _step_both(plant, case, core, agreement, f"{plant} {params}")
            events.append(a.events)
        lines.append(f"{agreement.summary(f'{plant} grid ({len(grid)} runs)')}, events per run {events}")
        assert max(events) > 0
    print("\n" + "\n".join(lines))


def _log(rng, lo, hi):
    return 10.0 ** rng.uniform(lo, hi)


def _extreme_backlash(rng):
    M1 = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    M2 = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    F = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    w = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -4, 4)
    scale = M2 * w * w
    X = F / scale if scale > 0.0 else 1.0
    h = _log(rng, -290, 300) if rng.random() < 0.15 else min(max(X * 10.0 ** rng.uniform(-2, 1), 1e-290), 1e300)
    h = h if math.isfinite(h) and h > 0.0 else 1.0
    params = dict(M1=M1, M2=M2, h=h, eps=rng.choice([0.0, 1e-9, 0.3, 0.5, 0.9]), F=rng.choice([F, -F]),
                  omega=w, phi=rng.uniform(-4, 4), x1_0=rng.choice([0.0, _log(rng, -300, 300)]),
                  v1_0=rng.choice([0.0, rng.choice([1, -1]) * _log(rng, -300, 300)]),
                  v2_0=rng.choice([0.0, rng.choice([1, -1]) * _log(rng, -6, 6)]),
                  gap0=rng.choice([None, 0.0, h, h * rng.random()]), f=rng.choice([0.0, F * rng.uniform(-1, 1)]),
                  harmonics=rng.randint(0, 10))
    return params, F, w


def _extreme_static(rng):
    M = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    k = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    F = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -6, 6)
    w = _log(rng, -300, 300) if rng.random() < 0.15 else _log(rng, -4, 4)
    scale = M * w * w
    X = F / scale if scale > 0.0 else 1.0
    h = _log(rng, -300, 300) if rng.random() < 0.15 else min(max(X * 10.0 ** rng.uniform(-2, 1), 1e-300), 1e300)
    h = h if math.isfinite(h) and h > 0.0 else 1.0
    params = dict(M=M, k=k, h=h, F=rng.choice([F, -F]), omega=w, phi=rng.uniform(-4, 4),
                  x0=rng.choice([0.0, _log(rng, -300, 300)]),
                  v0=rng.choice([0.0, rng.choice([1, -1]) * _log(rng, -300, 300)]),
                  f=rng.choice([0.0, F * rng.uniform(-1, 1)]), harmonics=rng.randint(0, 10))
    return params, F, w


@pytest.mark.parametrize("plant", list(PLANTS))
def test_extreme_parameters_agree(core, plant):
    """Seeded random parameters over the whole float range: the same values (NaN equal to NaN) or the
    same exception with the same message, wherever Python stops. eps < 1 here (an elastic bounce in a
    clearance far below the motion's scale chatters up to the events-per-period bound: minutes in Python;
    eps = 1 is in the stress cases and the grid), and runs whose C twin fires more than 3000 events are
    left out."""
    rng = random.Random(20240506)
    make_params = _extreme_backlash if plant == "backlash" else _extreme_static
    python_class, _, counters = PLANTS[plant]
    native_class = _native_class(core, plant)
    outcomes, skipped = {}, 0
    for i in range(150):
        params, F, w = make_params(rng)
        period = 2.0 * math.pi / w
        times = sorted(period * rng.uniform(0.0, 3.0) for _ in range(rng.randint(1, 12)))
        inputs = [rng.choice([None, 0.0, F * rng.uniform(-2.0, 2.0)]) for _ in times]
        native = trace(lambda: native_class(**params), times, inputs, counters)
        if native[2] > 3000 or "events per period" in native[0]:
            skipped += 1
            continue
        python = trace(lambda: python_class(**params), times, inputs, counters)
        assert native[0] == python[0], f"case {i} {params}"
        assert len(native[1]) == len(python[1]), f"case {i} {params}"
        for x, y in zip(python[1], native[1]):
            assert x == y or (math.isnan(x) and math.isnan(y)), f"case {i} {params}: {x!r} != {y!r}"
        kind = python[0].split(":")[0] if python[0] != "ok" else "ok"
        outcomes[kind] = outcomes.get(kind, 0) + 1
    print(f"\n{plant} extreme parameters (150 runs, {skipped} left out as chatter): outcomes {outcomes}, "
          f"identical in C")
    assert outcomes.get("ok", 0) > 50 and outcomes.get("OverflowError", 0) > 0


def test_event_limit_refusal_agrees(core):
    """A bounce in a clearance of 1e-280 m chatters: both stop at the events-per-period bound, alike."""
    params = dict(M1=1.0, M2=1.0, h=1e-280, eps=1.0, F=0.0, v1_0=0.0, v2_0=1.0, omega=1.0)
    python = trace(lambda: TwoMassBacklash(**params), [1e-262], [None], ("contact", "impacts"))
    native = trace(lambda: core.TwoMassBacklash(**params), [1e-262], [None], ("contact", "impacts"))
    assert python[0].startswith("PlantError: more than 100000 events per period")
    assert native[:2] == python[:2]


# -- refusals ----------------------------------------------------------------------------
def _refusal_pair(core, plant, params, action=lambda plant: None):
    return refusal_pair(PLANTS[plant][0], _native_class(core, plant), params, action)


@pytest.mark.parametrize("plant", list(PLANTS))
def test_every_python_refusal_is_a_c_refusal(core, stress_cases, plant):
    stress_refusals_agree(PLANTS[plant][0], _native_class(core, plant), stress_cases[plant][1])


@pytest.mark.parametrize("plant, params, action, name", [
    ("backlash", dict(h=1, gap0=2), None, "gap0"),  # ints: named as Python writes them, h in the range too
    ("backlash", dict(h=0.1, gap0=0.1 * (1 + 1e-15)), None, "gap0"),
    ("backlash", dict(h=True), None, "h"),
    ("backlash", dict(h=1e-291), None, "h"),
    ("backlash", dict(eps=2), None, "eps"),
    ("backlash", dict(M2=-0.0), None, "M2"),
    ("backlash", dict(x1_0=None), None, "x1_0"),
    ("backlash", dict(v2_0="1"), None, "v2_0"),
    ("backlash", dict(harmonics=10.5), None, "harmonics"),
    ("backlash", dict(phi=-1e10 * (1 + 1e-15)), None, "phi"),
    ("backlash", dict(F=50.0, omega=20.0), lambda p: (p.advance(3.0), p.advance(2.5)), "t_end"),
    ("backlash", dict(F=50.0, omega=20.0), lambda p: (p.advance(3.0), p.set_input(math.nan)), "f"),
    ("backlash", dict(F=50.0, omega=20.0, phi=5.0), lambda p: p.advance(PHASE_LIMIT / 20.0), "t_end"),
    ("static-backlash", dict(k=0), None, "k"),
    ("static-backlash", dict(h=-1e-300), None, "h"),
    ("static-backlash", dict(M=None), None, "M"),
    ("static-backlash", dict(v0=math.inf), None, "v0"),
    ("static-backlash", dict(omega=0), None, "omega"),
    ("static-backlash", dict(F=50.0, omega=20.0), lambda p: (p.advance(3.0), p.advance(None)), "t_end"),
    ("static-backlash", dict(F=50.0, omega=20.0), lambda p: p.set_input(True), "f"),
    ("static-backlash", dict(F=-50.0, omega=2.0, phi=PHASE_LIMIT), lambda p: p.advance(2.0), "t_end"),
])
def test_refusals_match(core, plant, params, action, name):
    python, native = _refusal_pair(core, plant, params, action or (lambda solver: None))
    assert python is not None and python.startswith(f"{name} = ")
    assert native == python


def test_no_core_no_instance():
    with pytest.raises(CoreError, match="needs a C core"):
        NativeTwoMassBacklash(F=1.0)
    with pytest.raises(CoreError, match="needs a C core"):
        NativeStaticBacklash.from_bytes(b"")


# -- the binding -------------------------------------------------------------------------
def test_solver_protocol(core):
    for plant, (python_class, attr, counters) in PLANTS.items():
        native = getattr(core, attr)()
        python = python_class()
        assert isinstance(native, Solver) and native.t == 0.0 and native.events == 0 and native.harmonics == 10
        assert native.output() == python.output() and type(native.output()) is type(python.output())
        assert native.integrals() == [0j] * 11 and native.event_log is None
        assert all(getattr(native, name) == getattr(python, name) for name in counters)
    assert isinstance(core.TwoMassBacklash(), NativeTwoMassBacklash)
    assert type(core.TwoMassBacklash(h=0.2).output()) is backlash.TABLE.output_type
    assert type(NativeStaticBacklash(harmonics=2, core=core).output()) is static_backlash.TABLE.output_type
    assert NativeStaticBacklash(harmonics=2, core=core).integrals() == [0j] * 3
    assert core.TwoMassBacklash(h=0.2).output().gap == 0.1  # gap0=None: h/2


# -- fixed parameters --------------------------------------------------------------------
SAME = {  # plant -> (parameters, {fixed parameter: another value}, {not fixed: another value}, native class)
    "backlash": (dict(F=50.0, omega=20.0, eps=0.5, harmonics=10),
                 dict(M1=2.0, M2=0.5, h=0.2, eps=0.25, F=40.0, omega=10.0, phi=0.5, harmonics=3),
                 dict(x1_0=1.0, v1_0=-2.0, v2_0=3.0, gap0=0.01, f=1.5), NativeTwoMassBacklash),
    "static-backlash": (dict(F=50.0, omega=20.0, harmonics=10),
                        dict(M=3.0, k=2.0, h=0.2, F=40.0, omega=10.0, phi=0.5, harmonics=3),
                        dict(x0=1.0, v0=-2.0, f=1.5), NativeStaticBacklash),
}


@pytest.mark.parametrize("plant", list(PLANTS))
def test_same_parameters(core, plant):
    """Equal fixed parameters survive a run, an input change, a copy and the state bytes; a change of any one
    fixed parameter (as bits: -0.0 is not 0.0) makes them differ; the initial state and the input do not."""
    params, fixed, free, base = SAME[plant]
    names = (backlash if plant == "backlash" else static_backlash).TABLE.core_order
    assert set(fixed) | set(free) == set(names) and not set(fixed) & set(free)
    cls = _native_class(core, plant)
    a, b = cls(**params), cls(**params)
    assert a.same_parameters(b) and b.same_parameters(a) and a.same_parameters(a)
    period = 2 * math.pi / params["omega"]
    a.advance(3.3 * period)
    a.set_input(20.0)
    a.advance(5.1 * period)
    assert a.events > 0 and a.same_parameters(b) and b.same_parameters(a)
    assert a.same_parameters(cls(**dict(params, **free))) and a.same_parameters(base(**params, core=core))
    restored = cls.from_bytes(a.to_bytes())
    assert restored.same_parameters(b) and b.same_parameters(restored) and restored.same_parameters(a.copy())
    for name, value in fixed.items():
        assert params.get(name) != value
        other = cls(**dict(params, **{name: value}))
        assert not a.same_parameters(other) and not other.same_parameters(a), name
        assert not restored.same_parameters(cls.from_bytes(other.to_bytes())), name
        assert other.same_parameters(cls.from_bytes(other.to_bytes())), name
    for name in ("phi", "F") + (("eps",) if plant == "backlash" else ()):
        assert not cls(**{name: 0.0}).same_parameters(cls(**{name: -0.0})), name
    assert not cls(F=10.0).same_parameters(cls(F=-10.0))  # stored as a phase shift of pi
    others = [PLANTS[plant][0](**params), None, 1.0, core.FrictionMass()]
    others.append(core.StaticBacklash() if plant == "backlash" else core.TwoMassBacklash())
    for other in others:
        assert a.same_parameters(other) is False
    assert core.api.same_parameters(None, a._handle) == 0 == core.api.same_parameters(a._handle, None)


# -- copies ------------------------------------------------------------------------------
@pytest.mark.parametrize("plant", list(PLANTS))
def test_copy_continues_identically(core, plant):
    python_class, attr, counters = PLANTS[plant]
    params = dict(F=50.0, omega=20.0, harmonics=10)
    period = 2 * math.pi / 20.0
    python, native = python_class(**params), getattr(core, attr)(**params)
    for solver in (python, native):
        solver.advance(3.3 * period)
        solver.set_input(20.0)
        solver.advance(5.1 * period)
    python_copy = copy.deepcopy(python)
    clones = [native.copy(), copy.copy(native), copy.deepcopy(native), pickle.loads(pickle.dumps(native)),
              type(native).from_bytes(native.to_bytes())]
    assert all(type(clone) is type(native) for clone in clones)
    native.set_input(-50.0)  # the original moves on: the copies must not
    native.advance(9.0 * period)
    agreement = Agreement(counters)
    for j, k in enumerate(range(1, 97)):
        t = 5.1 * period + k * period / 16
        for solver in [python_copy] + clones:
            solver.set_input(30.0 * math.sin(j / 5.0))
            solver.advance(t)
        for clone in clones:
            agreement.compare(f"copy t={t!r}", python_copy, clone)
    assert agreement.events > 10 and agreement.identical == agreement.values


# -- the event log -----------------------------------------------------------------------
def _logged_run(solver, case):
    solver.event_log = []
    for j, t in enumerate(case.times):
        if case.inputs is not None:
            solver.set_input(case.inputs[j])
        solver.advance(t)
    return solver.event_log


def test_event_logs_are_equal(core, stress_cases, plant_runs):
    """Every counted event, (t, EventKind), identical to the bit, in the order Python logs it."""
    total, kinds = {}, set()
    for plant, (_python_class, attr, _) in PLANTS.items():
        for i in range(0, len(stress_cases[plant][0]), 3):
            case = stress_cases[plant][0][i]
            python = plant_runs[plant](i)[1]  # the log of Python's run, as _logged_run keeps it
            native_solver = getattr(core, attr)(**case.params)
            native = _logged_run(native_solver, case)
            assert len(native) == len(python) == native_solver.events, case.note
            assert all(type(t) is float and kind in EventKind for t, kind in native)
            assert [(_bits(t), kind) for t, kind in native] == [(_bits(t), kind) for t, kind in python], case.note
            total[plant] = total.get(plant, 0) + len(native)
            kinds.update(str(kind) for _, kind in native)
    params = dict(F=10.0, omega=1.0, Dv=1e-3)
    case = Case("friction", params, *periods(params, 5))
    native = _logged_run(core.FrictionMass(**params), case)
    assert native == _logged_run(FrictionMass(**params), case) != []
    kinds.update(str(kind) for _, kind in native)
    print(f"\nevent logs equal: {total} events logged, kinds {sorted(kinds)}")
    assert min(total.values()) > 100 and {"gap 0", "gap h", "engage+", "engage-", "reverse", "edge", "band"} <= kinds


def test_event_log_bounds_and_switches(core, monkeypatch):
    params = dict(F=50.0, omega=20.0)
    period = 2 * math.pi / 20.0
    solver = core.TwoMassBacklash(**params)
    solver.advance(period)  # no log: nothing recorded
    assert solver.event_log is None and solver.events > 0
    log = solver.event_log = []
    solver.advance(2 * period)
    seen = len(log)
    assert seen > 0 and solver.event_log is log
    solver.event_log = None
    solver.advance(3 * period)
    assert len(log) == seen
    monkeypatch.setattr(native_core, "LOG_CAPACITY", 3)
    solver.event_log = []
    before = solver.events
    with pytest.warns(RuntimeWarning, match="were not recorded"):
        solver.advance(6 * period)
    assert len(solver.event_log) == 3 and solver.event_log_dropped == solver.events - before - 3


# -- the state as bytes ------------------------------------------------------------------
@pytest.mark.parametrize("plant", list(PLANTS))
def test_state_round_trip_continues_identically(core, stress_cases, plant_runs, plant):
    """At every point of every quick stress case the C solver is replaced by one read back from its
    bytes: the run stays identical to Python's (no honest state is refused, nothing is lost)."""
    agreement = Agreement(PLANTS[plant][2])
    for i in range(0, len(stress_cases[plant][0]), 2):
        case = stress_cases[plant][0][i]
        _step_both(plant, case, core, agreement, case.note, restore=True, python=plant_runs[plant](i)[0])
    print(f"\n{agreement.summary(f'{plant} restored from bytes at every point')}")
    assert agreement.identical == agreement.values and agreement.points > 3000


def _states(core):
    """A few honest states of each plant (mid-flight, in contact, engaged, after an input change)."""
    out = {}
    for attr, params in (("FrictionMass", dict(F=10.0, omega=1.0, Dv=1e-3)),
                         ("TwoMassBacklash", dict(F=50.0, omega=20.0, eps=0.5)),
                         ("StaticBacklash", dict(F=50.0, omega=20.0))):
        solver = getattr(core, attr)(**params)
        period = 2 * math.pi / params["omega"]
        states = []
        for k in range(1, 9):
            solver.advance(k * period / 7)
            if k == 5:
                solver.set_input(3.0)
            states.append(solver.to_bytes())
        out[attr] = states
    return out


def test_state_refusals(core):
    states = _states(core)
    sizes = {attr: len(s[0]) for attr, s in states.items()}
    assert sizes == {attr: core.api.state_sizes[kind]
                     for attr, kind in (("FrictionMass", 1), ("TwoMassBacklash", 2), ("StaticBacklash", 3))}
    data = states["TwoMassBacklash"][3]
    cls = core.TwoMassBacklash
    assert cls.from_bytes(bytearray(data)).to_bytes() == data == cls.from_bytes(memoryview(data)).to_bytes()
    cases = [
        (data[:10], "is truncated: its header alone has 24"),
        (data[:-1], "truncated or oversized"),
        (data + b"\0", "truncated or oversized"),
        (data + data, "truncated or oversized"),
        (b"", "is truncated"),
        (b"X" + data[1:], "not a state of the dfwb C core"),
        (data[:8] + struct.pack("<I", ABI - 1) + data[12:], f"written by core ABI {ABI - 1}, this core is ABI {ABI}"),
        (data[:8] + struct.pack("<I", ABI + 1) + data[12:], f"written by core ABI {ABI + 1}"),
        (states["FrictionMass"][0], "is one of a dfwb_friction, not of a dfwb_backlash"),
        (states["StaticBacklash"][0], "is one of a dfwb_static_backlash, not of a dfwb_backlash"),
        (data[:12] + struct.pack("<I", 9) + data[16:], "is one of a unknown plant"),
        (data[:16] + struct.pack("<I", 10**9) + data[20:], "truncated or oversized"),
        (data[:-1] + bytes([data[-1] ^ 1]), "checksum does not match"),
    ]
    for bad, message in cases:
        with pytest.raises(StateRefused, match="^[^\n]*" + message.replace("(", r"\(")):
            cls.from_bytes(bad)
    with pytest.raises(StateRefused, match="must be bytes, not str"):
        cls.from_bytes("state")
    # crafted with a valid checksum: a field out of range is named
    for index, value, message in ((0, math.nan, "the state's f = nan is out of range"),  # fields: f, F, omega, phi,
                                  (3, 2e10, "the state's phi = 20000000000.0 is out of range"),  # harmonics, t...
                                  (5, -1.0, "the state's t = -1.0 is out of range"),
                                  (2, 1e300, "the state's t = .* is out of range: must be >= 0 with the phase")):
        crafted = bytearray(data)
        crafted[HEADER + 8 * index:HEADER + 8 * index + 8] = struct.pack("<d", value)
        with pytest.raises(StateRefused, match=message):
            cls.from_bytes(with_crc(crafted))
    crafted = bytearray(data)
    crafted[HEADER + 4 * 8:HEADER + 5 * 8] = struct.pack("<q", 11)  # harmonics
    with pytest.raises(StateRefused, match="harmonics = 11 is out of range"):
        cls.from_bytes(with_crc(crafted))
    crafted[HEADER + 4 * 8:HEADER + 5 * 8] = struct.pack("<q", 2**40)
    with pytest.raises(StateRefused, match="integer field out of range"):
        cls.from_bytes(with_crc(crafted))


FUZZ = r"""
import json, math, random, struct, sys
from array import array
sys.path.insert(0, sys.argv[2])
from native_fmu_helpers import HEADER, counted_once, read_or_refuse, with_crc as crc
from dfwb.fmus.native_core import load
from dfwb.fmus.state import StateRefused
from dfwb.fmus.exact import PlantError

core = load(sys.argv[1])
states = json.loads(sys.stdin.read())
rng = random.Random(5)
SPECIAL = [math.nan, math.inf, -math.inf, -1.0, 0.0, -0.0, 1.0, 0.5, 2.0, 3.0, 1e308, -1e308, 5e-324, 1e-300, 1e10,
           2.0 ** 63]
INTS = [-1, 2, 3, 4, 7, 8, 11, 12, 2**31 - 1, -2**31, 2**62, -2**63]
tally = {"flips": 0, "refused": 0, "accepted": 0, "stepped": 0, "step refused": 0}

def _attempt(cls, data):
    solver = read_or_refuse(cls, data, tally)
    if solver is None:
        return
    solver.output(); solver.integrals(); solver.copy()
    solver.event_log = []
    try:
        solver.set_input(1.5)
        solver.advance(solver.t + min(solver.period / 8.0, 1.0))  # the state's own period: a step of honest cost
        solver.output(); solver.integrals()
        tally["stepped"] += 1
    except (PlantError, OverflowError):
        tally["step refused"] += 1

attempt = counted_once(tally, _attempt)  # the same bytes run once, counted each time

for attr, entries in states.items():
    cls = getattr(core, attr)
    for index, hexdata in enumerate(entries):
        data = bytes.fromhex(hexdata)
        n = (len(data) - HEADER) // 8
        if index == 0:  # every single bit flipped: the checksum refuses them all
            for bit in range(8 * len(data)):
                flipped = bytearray(data)
                flipped[bit // 8] ^= 1 << (bit % 8)
                try:
                    cls.from_bytes(bytes(flipped))
                    raise AssertionError(f"{attr}: bit {bit} flipped and accepted")
                except StateRefused:
                    tally["flips"] += 1
        for i in range(n):  # every field set to each special value, the checksum made valid
            for value in SPECIAL + INTS:
                crafted = bytearray(data)
                raw = struct.pack("<d", value) if isinstance(value, float) else struct.pack("<q", value)
                crafted[HEADER + 8 * i:HEADER + 8 * i + 8] = raw
                attempt(cls, crc(crafted))
        for _ in range(150):  # a few fields at once, from random bits or another honest state
            crafted = bytearray(data)
            other = bytes.fromhex(rng.choice(entries))
            for _ in range(rng.randint(1, 4)):
                i = rng.randrange(n)
                source = rng.random()
                if source < 0.4:
                    raw = other[HEADER + 8 * i:HEADER + 8 * i + 8]
                elif source < 0.7:
                    raw = struct.pack("<d", struct.unpack("<d", bytes(crafted[HEADER + 8 * i:HEADER + 8 * i + 8]))[0]
                                      * rng.choice([-1.0, 0.5, 2.0, 1 + 1e-15, 1e6]))
                else:
                    raw = rng.getrandbits(64).to_bytes(8, "little")
                crafted[HEADER + 8 * i:HEADER + 8 * i + 8] = raw
            attempt(cls, crc(crafted))
        for _ in range(100):  # random payloads behind a valid header
            attempt(cls, crc(data[:HEADER] + rng.randbytes(len(data) - HEADER)))
print(json.dumps(tally))
"""


def test_state_fuzzing_never_crashes(core):
    """Bit flips, fields set to extreme values, fields mixed across states, random payloads (checksums
    made valid): refused with one line, or accepted as a state whose copy, outputs and next step work and
    whose bytes read back the same; in a subprocess, so that a crash would fail the test, not end it."""
    states = {attr: [s.hex() for s in entries[::2]] for attr, entries in _states(core).items()}
    run = subprocess.run([sys.executable, "-c", FUZZ, str(core.path), str(Path(__file__).resolve().parent)],
                         input=json.dumps(states), capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, f"the fuzzing process failed (exit {run.returncode}): {run.stderr[-2000:]}"
    tally = json.loads(run.stdout)
    print(f"\nstate fuzzing: {tally}")
    assert tally["flips"] > 10_000 and tally["refused"] > 1000 and tally["stepped"] > 100


# -- timing (printed, not asserted) --------------------------------------------------------
def test_time_per_event(core):
    """Median time per event of one long step (100 periods), Python and C."""
    lines = []
    for plant, params in (("backlash", dict(M1=1.0, M2=1.0, h=0.1, eps=0.5, F=50.0, omega=20.0)),
                          ("static-backlash", dict(M=2.0, k=1.0, h=0.1, F=50.0, omega=20.0))):
        python_class, attr, _ = PLANTS[plant]
        stop = 100 * 2 * math.pi / params["omega"]

        def run(cls):
            solver = cls(**params)
            start = time.perf_counter()
            solver.advance(stop)
            return time.perf_counter() - start, solver.events

        python = [run(python_class) for _ in range(3)]
        native = [run(getattr(core, attr)) for _ in range(15)]
        events = python[0][1]
        assert events == native[0][1] > 0
        per_python = statistics.median(s for s, _ in python) / events
        per_native = statistics.median(s for s, _ in native) / events
        lines.append(f"  {plant:>15}: {events} events, Python {1e6 * per_python:6.1f} us, C {1e6 * per_native:5.2f} us "
                     f"per event ({per_python / per_native:.0f}x)")
    print("\none step of 100 periods (F=50, omega=20), median per event:\n" + "\n".join(lines))


def test_one_api_for_every_plant(core):
    """ABI 6: dfwb_plant_* serve every plant; a kind, a parameter count or a counter the core does not know is
    refused, never read out of bounds."""
    import ctypes

    api = core.api
    err = ctypes.create_string_buffer(256)
    handle = ctypes.c_void_p()
    params = (ctypes.c_double * 13)(*([1.0] * 13))
    for kind, n in ((99, 12), (0, 12), (1, 13), (2, 12), (3, 0)):
        assert api.new(kind, params, n, ctypes.byref(handle), err, 256) == 5  # DFWB_E_ARGUMENT
        assert not handle.value
        assert err.value.decode().startswith("dfwb_plant_new: "), err.value
    assert b"unknown plant kind 99" in (api.new(99, params, 12, ctypes.byref(handle), err, 256) and err.value)
    assert api.shape(99, None, None, None) == 5 and api.state_size(99) == 0
    assert api.from_bytes(99, b"x", 1, ctypes.byref(handle), err, 256) == 5 and not handle.value
    shapes = {}
    for kind in (1, 2, 3):
        sizes = [ctypes.c_size_t() for _ in range(3)]
        assert api.shape(kind, *map(ctypes.byref, sizes)) == 0
        shapes[kind] = tuple(size.value for size in sizes)
    assert shapes == {1: (12, 4, 0), 2: (13, 5, 2), 3: (10, 3, 1)}
    friction, backlash = core.FrictionMass(), core.TwoMassBacklash(F=50.0, omega=20.0)
    backlash.advance(1.0)
    lib = ctypes.CDLL(str(core.path))
    kind_of = lib.dfwb_plant_kind
    kind_of.restype, kind_of.argtypes = ctypes.c_int, [ctypes.c_void_p]
    assert (kind_of(friction._handle), kind_of(backlash._handle), kind_of(None)) == (1, 2, 0)
    assert api.counter(friction._handle, 0) == -1 and api.counter(backlash._handle, 2) == -1
    assert api.counter(backlash._handle, 1) == backlash.impacts > 0 and api.counter(None, 0) == -1
    assert api.same_parameters(friction._handle, backlash._handle) == 0
