"""The exact friction-mass solver in C (fmus/native, loaded by dfwb.fmus.native_core) against the Python oracle.

The C core is a port of dfwb.fmus.friction.FrictionMass that keeps its
operation order, so the two must agree to rounding: stepped identically
(the friction stress cases of ``dfwb stress`` with their held inputs, and a
grid of amplitudes, frequencies and Karnopp bands), they count the same
events at every communication point and give outputs and Fourier integrals
equal to 1e-13 relative (in practice bit for bit; the share is printed).
Every refusal of the Python solver is a refusal of the C core, with the same
message; a copy (copy(), copy.copy, copy.deepcopy, pickle, the state as bytes)
continues exactly as the original, and the event log equals Python's. The
library is compiled once per session with -Wall -Wextra -Werror. (The state
bytes' refusals and fuzzing, for all three plants: tests/test_native_backlash.py.)
"""

import copy
import math
import pickle
import random
import statistics
import struct
import time
from array import array

import pytest

from dfwb.build_fmus.core import CoreBuildError, build_core
from dfwb.fmus.contract import Solver
from dfwb.fmus.exact import PHASE_LIMIT, PlantError
from dfwb.fmus.friction import TABLE, FrictionMass
from dfwb.fmus.native_core import CoreError, NativeFrictionMass, load
from dfwb.plants.stress_kit import Case, InvalidCase, periods
from dfwb.verify.stress import all_cases

pytestmark = pytest.mark.needs_cc

RTOL = 1e-13




@pytest.fixture(scope="session")
def friction_cases():
    """The friction cases of the quick stress set (valid ones, invalid ones)."""
    cases = all_cases(quick=True)
    valid = [c for c in cases if isinstance(c, Case) and c.plant == "friction"]
    invalid = [c for c in cases if isinstance(c, InvalidCase) and c.plant == "friction"]
    assert len(valid) > 50 and len(invalid) > 30
    return valid, invalid


def _bits(value):
    return array("d", [value]).tobytes()


class Agreement:
    """Tally of compared values: how many, how many bit-identical, the largest relative difference.

    Shared by the plants' tests (tests/test_native_backlash.py imports it): ``counters`` are the
    solver's integer attributes (contact, impacts, engaged) that must be equal ints; an output field
    that is an int in Python (friction's mode) must be the same int in C; the other outputs and the
    Fourier integrals must agree to RTOL relative (in practice bit for bit).
    """

    def __init__(self, counters=()):
        self.counters = counters
        self.values = self.identical = self.points = self.events = 0
        self.worst = 0.0

    def compare(self, where, a, b):
        """a (Python) and b (C) at one point: same events, counters and integer outputs, values to RTOL."""
        self.points += 1
        assert a.events == b.events, f"{where}: events {a.events} (Python) != {b.events} (C)"
        assert a.t == b.t, f"{where}: t {a.t!r} != {b.t!r}"
        for name in self.counters:
            mine, theirs = getattr(a, name), getattr(b, name)
            assert mine == theirs and type(theirs) is int, f"{where}: {name} {mine} != {theirs}"
        out_a, out_b = a.output(), b.output()
        assert type(out_a) is type(out_b)
        for name, mine, theirs in zip(out_a._fields, out_a, out_b):
            if type(mine) is int:
                assert mine == theirs and type(theirs) is int, f"{where}: {name} {mine} != {theirs}"
        va = [x for x in out_a if type(x) is not int] + [c for z in a.integrals() for c in (z.real, z.imag)]
        vb = [y for x, y in zip(out_a, out_b) if type(x) is not int] + [
            c for z in b.integrals() for c in (z.real, z.imag)]
        assert len(va) == len(vb)
        for i, (x, y) in enumerate(zip(va, vb)):
            self.values += 1
            if _bits(x) == _bits(y):
                self.identical += 1
                continue
            if x == y:  # 0.0 and -0.0 (a Python whose complex * float skips the zero terms differs there)
                continue
            scale = max(abs(x), abs(y))
            rel = abs(x - y) / scale if scale > 0 else 0.0
            self.worst = max(self.worst, rel)
            assert rel <= RTOL, f"{where}: value {i}: {x!r} (Python) != {y!r} (C), relative {rel:.3g}"
        self.events = max(self.events, a.events)

    def summary(self, label):
        share = self.identical / self.values if self.values else 1.0
        return (f"{label}: {self.points} points, {self.values} values, {self.identical} bit-identical "
                f"({100 * share:.4f} %), max relative difference {self.worst:.3g}")


class Seen:
    """What a Python solver showed at one point of a run (t, events, the counters, output(), integrals()): it
    stands for the solver in Agreement.compare, which reads nothing else."""

    def __init__(self, solver, counters=()):
        self.t, self.events = solver.t, solver.events
        for name in counters:
            setattr(self, name, getattr(solver, name))
        self._output, self._integrals = solver.output(), list(solver.integrals())

    def output(self):
        return self._output

    def integrals(self):
        return self._integrals


def python_run(python_class, case, counters=(), log=True):
    """The Python oracle through a stress case's points (inputs set before each step), with ``log`` its event log
    on: ([Seen at t = 0 and at every point], the event log). The log only records what the run does (piecewise.py
    appends to it, nothing reads it), so one run serves the agreement, the state round trip and the event log tests."""
    a = python_class(**case.params)
    if log:
        a.event_log = []
    points = [Seen(a, counters)]
    for j, t in enumerate(case.times):
        if case.inputs is not None:
            a.set_input(case.inputs[j])
        a.advance(t)
        points.append(Seen(a, counters))
    return points, a.event_log


def python_runs(python_class, cases, counters=()):
    """run(i): python_run of cases[i], each run once (module-scoped fixtures share them between tests)."""
    done = {}

    def run(i):
        if i not in done:
            done[i] = python_run(python_class, cases[i], counters)
        return done[i]

    return run


def step_both(python_class, native_class, case, agreement, where, restore=False, python=None):
    """Run the Python and the C solver through a stress case's points (inputs set before each step); with
    ``restore`` the C solver is replaced by one read back from its state bytes at every point. ``python``: the
    Python run's points (python_run), if it has been run already. (What Python showed at the last point, C solver.)"""
    points = python_run(python_class, case, agreement.counters, log=False)[0] if python is None else python
    b = native_class(**case.params)
    agreement.compare(f"{where} t=0", points[0], b)
    for j, t in enumerate(case.times):
        if case.inputs is not None:
            b.set_input(case.inputs[j])
        b.advance(t)
        agreement.compare(f"{where} t={t!r}", points[j + 1], b)
        if restore:
            data = b.to_bytes()
            b = native_class.from_bytes(data)
            assert b.to_bytes() == data, f"{where} t={t!r}: the state read back writes other bytes"
    return points[-1], b


def _step_both(case, core, agreement, where, restore=False, python=None):
    return step_both(FrictionMass, core.FrictionMass, case, agreement, where, restore, python)


@pytest.fixture(scope="module")
def friction_runs(friction_cases):
    """run(i): the Python oracle's run of the i-th valid friction stress case, once for the tests that compare
    C with it (agreement, state round trip, event log)."""
    return python_runs(FrictionMass, friction_cases[0])


def test_stress_cases_agree(core, friction_cases, friction_runs):
    agreement = Agreement()
    total_events = 0
    for i, case in enumerate(friction_cases[0]):
        a, _ = _step_both(case, core, agreement, case.note, python=friction_runs(i)[0])
        total_events += a.events
    print(f"\n{agreement.summary(f'friction stress cases ({len(friction_cases[0])})')}, {total_events} events")
    assert agreement.points > 10_000 and total_events > 1000


GRID = [(F, w, Dv) for F in (7.5, 10.0, 30.0, 50.0) for w in (0.1, 1.0, 5.0, 20.0) for Dv in (0.0, 1e-3)]


def test_grid_agrees(core):
    agreement = Agreement()
    events = []
    for F, w, Dv in GRID:
        params = dict(F=F, omega=w, Dv=Dv)
        case = Case("friction", params, *periods(params, 10))
        a, _ = _step_both(case, core, agreement, f"F={F} w={w} Dv={Dv}")
        events.append(a.events)
    print(f"\n{agreement.summary(f'grid F x omega x Dv ({len(GRID)} runs)')}, events per run {events}")
    assert min(events) > 0


def test_step_independent_like_python(core):
    """One long step ends where 320 short ones do (bit for bit), in C as in Python."""
    params = dict(F=30.0, omega=5.0, Dv=1e-3, harmonics=3)
    stop = 10 * 2 * math.pi / 5.0
    one, many = core.FrictionMass(**params), core.FrictionMass(**params)
    one.advance(stop)
    for k in range(1, 321):
        many.advance(stop * k / 320)
    assert one.events == many.events > 0
    assert [_bits(v) for v in one.output()] == [_bits(v) for v in many.output()]
    assert one.integrals() == many.integrals()


def _extreme_case(rng):
    """Parameters from 1e-300 to 1e300 (Python refuses some: an event search beyond its bound, an overflow)."""
    def log(lo, hi):
        return 10.0 ** rng.uniform(lo, hi)

    M = log(-300, 300) if rng.random() < 0.2 else log(-6, 6)
    F = log(-300, 300) if rng.random() < 0.2 else log(-6, 6)
    w = log(-300, 300) if rng.random() < 0.2 else log(-4, 4)
    Fc = F * rng.uniform(0.0, 1.5)
    params = dict(M=M, B=rng.choice([0.0, M * w * rng.uniform(0.0, 3.0), log(-300, 300)]), Fc=Fc,
                  Fs=Fc * rng.choice([1.0, 1.3]), Dv=rng.choice([0.0, log(-12, 3)]), F=rng.choice([F, -F]),
                  omega=w, phi=rng.uniform(-4.0, 4.0), x0=rng.choice([0.0, log(-300, 300)]),
                  v0=rng.choice([0.0, log(-300, 300) * rng.choice([1.0, -1.0])]),
                  f=rng.choice([0.0, F * rng.uniform(-1.0, 1.0)]), harmonics=rng.randint(0, 10))
    period = 2.0 * math.pi / w
    times = sorted(period * rng.uniform(0.0, 5.0) for _ in range(rng.randint(1, 20)))
    inputs = [rng.choice([None, 0.0, F * rng.uniform(-2.0, 2.0)]) for _ in times]
    return params, times, inputs


def trace(make, times, inputs, counters=()):
    """(outcome, the values read at every point, the events so far) of one run; outcome 'ok' or
    'Type: message'. ``counters``: the solver's integer attributes read too (contact, impacts, engaged)."""
    values = []

    def read(plant):
        values.extend([*plant.output(), *(c for z in plant.integrals() for c in (z.real, z.imag)),
                       plant.events, plant.t, *(getattr(plant, name) for name in counters)])

    plant = None
    try:
        plant = make()
        read(plant)
        for t, f in zip(times, inputs):
            if f is not None:
                plant.set_input(f)
            plant.advance(t)
            read(plant)
    except Exception as error:  # noqa: BLE001 - the C core must raise what Python raises
        return f"{type(error).__name__}: {error}", values, 0 if plant is None else plant.events
    return "ok", values, plant.events


def test_extreme_parameters_agree(core):
    """Seeded random parameters over the whole float range: the same values (NaN equal to NaN: its sign
    bit may differ) or the same exception with the same message, wherever Python stops."""
    rng = random.Random(20240505)
    outcomes = {}
    for i in range(150):
        params, times, inputs = _extreme_case(rng)
        python = trace(lambda: FrictionMass(**params), times, inputs)
        native = trace(lambda: core.FrictionMass(**params), times, inputs)
        assert native[0] == python[0], f"case {i} {params}"
        assert len(native[1]) == len(python[1])
        for x, y in zip(python[1], native[1]):
            assert x == y or (math.isnan(x) and math.isnan(y)), f"case {i} {params}: {x!r} != {y!r}"
        kind = python[0].split(":")[0] if python[0] != "ok" else "ok"
        outcomes[kind] = outcomes.get(kind, 0) + 1
    print(f"\nextreme parameters (150 runs): outcomes {outcomes}, identical in C")
    assert outcomes.get("PlantError", 0) > 0 and outcomes.get("OverflowError", 0) > 0  # both refusal paths ran


# -- refusals ----------------------------------------------------------------------------
def _refusal(make, action):
    try:
        plant = make()
        action(plant)
    except PlantError as error:
        return str(error)
    return None


def refusal_pair(python_class, native_class, params, action=lambda plant: None):
    """(the Python refusal's text, the C one's) of making a solver from params and acting on it (None: none)."""
    return _refusal(lambda: python_class(**params), action), _refusal(lambda: native_class(**params), action)


def _refusal_pair(core, params, action=lambda plant: None):
    return refusal_pair(FrictionMass, core.FrictionMass, params, action)


def stress_refusals_agree(python_class, native_class, invalid_cases):
    """Every invalid stress case is refused by C with Python's text (at construction, set_input or advance)."""
    for case in invalid_cases:
        if case.action == "set_input":
            def action(plant, value=case.value):
                plant.set_input(value)
        elif case.action == "advance":
            def action(plant, value=case.value):
                plant.advance(1.0)
                plant.advance(value)
        else:
            def action(plant):
                return None
        python, native = refusal_pair(python_class, native_class, case.params, action)
        assert python is not None and python.startswith(f"{case.name} = "), case.describe()
        assert native == python, case.describe()


def test_every_python_refusal_is_a_c_refusal(core, friction_cases):
    stress_refusals_agree(FrictionMass, core.FrictionMass, friction_cases[1])


@pytest.mark.parametrize("params, action, name", [
    (dict(Fc=5.0, Fs=4.999), None, "Fs"),
    (dict(Fc=5, Fs=4), None, "Fs"),  # ints: named as Python writes them
    (dict(harmonics=11), None, "harmonics"),
    (dict(harmonics=True), None, "harmonics"),
    (dict(M=-0.0), None, "M"),
    (dict(phi=-1e10 * (1 + 1e-15)), None, "phi"),
    (dict(F=10.0), lambda p: (p.advance(3.0), p.advance(2.5)), "t_end"),  # backwards
    (dict(F=10.0), lambda p: (p.advance(3.0), p.advance(None)), "t_end"),
    (dict(F=10.0), lambda p: (p.advance(3.0), p.set_input(math.nan)), "f"),
    (dict(F=10.0), lambda p: p.set_input("8"), "f"),
    (dict(F=10.0, omega=1.0, phi=5.0), lambda p: p.advance(PHASE_LIMIT), "t_end"),  # phase beyond the limit
    (dict(F=10.0, omega=1e-3), lambda p: p.advance(PHASE_LIMIT * 1e3 * (1 + 1e-15)), "t_end"),
    (dict(F=-10.0, omega=2.0, phi=PHASE_LIMIT), lambda p: p.advance(2.0), "t_end"),  # F < 0: phi - pi
])
def test_refusals_match(core, params, action, name):
    python, native = _refusal_pair(core, params, action or (lambda plant: None))
    assert python is not None and python.startswith(f"{name} = ")
    assert native == python


def test_floats_are_written_as_python_repr_writes_them(core):
    """The C core's messages write floats as repr() does: random bit patterns, subnormals, the exponent edges."""
    rng = random.Random(7)
    values = [struct.unpack("d", struct.pack("Q", rng.getrandbits(64)))[0] for _ in range(3000)]
    values += [1e16, 1e15, 9999999999999998.0, 1e-4, 1e-5, 0.00011, 5e-324, 2.2250738585072014e-308,
               1.7976931348618157e308, 123.0, 0.1, 1 / 3, 2.0 ** 53, 1e22, 1e23, math.pi * 1e-300]
    values = [-abs(v) for v in values if v == v and v != 0.0] + [1e10 + 0.5, 2e10, 1e300]  # backwards, beyond
    python, native = FrictionMass(F=1.0, phi=-0.3), core.FrictionMass(F=1.0, phi=-0.3)
    for value in values:
        messages = [_refusal(lambda: plant, lambda p, v=value: p.advance(v)) for plant in (python, native)]
        assert messages[0] is not None and messages[1] == messages[0]


def test_refused_step_leaves_the_instance_usable(core):
    plant = core.FrictionMass(F=10.0)
    plant.advance(2.0)
    before = plant.output(), plant.integrals(), plant.events
    with pytest.raises(PlantError, match=r"^t_end = 1\.0 is out of range: the end of a step must be >= the current time 2\.0$"):
        plant.advance(1.0)
    with pytest.raises(PlantError, match=r"^f = inf is out of range"):
        plant.set_input(math.inf)
    assert (plant.output(), plant.integrals(), plant.events) == before and plant.t == 2.0


def test_no_core_no_instance():
    with pytest.raises(CoreError, match="needs a C core"):
        NativeFrictionMass(F=1.0)


# -- copies ------------------------------------------------------------------------------
def test_copy_continues_identically(core):
    params = dict(F=10.0, omega=1.0, Dv=1e-3, harmonics=10)
    period = 2 * math.pi
    python, native = FrictionMass(**params), core.FrictionMass(**params)
    for plant in (python, native):
        plant.advance(3.3 * period)
        plant.set_input(2.0)
        plant.advance(5.1 * period)
    python_copy = copy.deepcopy(python)
    clones = {"copy()": native.copy(), "copy.copy": copy.copy(native), "copy.deepcopy": copy.deepcopy(native),
              "pickle": pickle.loads(pickle.dumps(native)), "from_bytes": type(native).from_bytes(native.to_bytes())}
    assert all(type(clone) is type(native) for clone in clones.values())
    native.set_input(-50.0)  # the original moves on: the copies must not
    native.advance(9.0 * period)
    agreement = Agreement()
    for j, k in enumerate(range(1, 97)):
        t = 5.1 * period + k * period / 16
        for plant in [python_copy, *clones.values()]:
            plant.set_input(3.0 * math.sin(j / 5.0))
            plant.advance(t)
        for how, clone in clones.items():
            agreement.compare(f"{how} t={t!r}", python_copy, clone)
    assert agreement.events > 30 and agreement.identical == agreement.values
    assert native.events != clones["copy()"].events or native.output() != clones["copy()"].output()


def test_state_round_trip_continues_identically(core, friction_cases, friction_runs):
    """At every point of every other friction stress case the C solver is replaced by one read back from
    its bytes: the run stays identical to Python's (no honest state is refused, nothing is lost)."""
    agreement = Agreement()
    for i in range(0, len(friction_cases[0]), 2):
        case = friction_cases[0][i]
        _step_both(case, core, agreement, case.note, restore=True, python=friction_runs(i)[0])
    print(f"\n{agreement.summary('friction restored from bytes at every point')}")
    assert agreement.identical == agreement.values and agreement.points > 5000


def test_event_log_equals_python(core, friction_cases, friction_runs):
    """Every counted event as (t, EventKind), to the bit and in order, as FrictionMass.event_log has it."""
    logged = 0
    for i in range(0, len(friction_cases[0]), 3):
        case = friction_cases[0][i]
        points, log = friction_runs(i)  # Python's run, its event log on
        assert len(log) == points[-1].events
        logs = [[(_bits(t), kind) for t, kind in log]]
        plant = core.FrictionMass(**case.params)
        plant.event_log = []
        for j, t in enumerate(case.times):
            if case.inputs is not None:
                plant.set_input(case.inputs[j])
            plant.advance(t)
        assert len(plant.event_log) == plant.events
        logs.append([(_bits(t), kind) for t, kind in plant.event_log])
        assert logs[1] == logs[0], case.note
        logged += len(logs[0])
    assert logged > 200


# -- fixed parameters --------------------------------------------------------------------
FIXED = dict(M=2.0, B=0.25, Fc=4.0, Fs=8.0, Dv=2e-3, F=12.0, omega=2.0, phi=0.5, harmonics=3)  # one changed at a time


def test_same_parameters(core):
    """Equal fixed parameters survive a run, an input change, a copy and the state bytes; a change of any one
    fixed parameter (as bits: -0.0 is not 0.0) makes them differ; the initial state and the input do not."""
    params = dict(F=10.0, omega=1.0, Dv=1e-3, harmonics=10)
    a, b = core.FrictionMass(**params), core.FrictionMass(**params)
    assert a.same_parameters(b) and b.same_parameters(a) and a.same_parameters(a)
    a.advance(7.0)
    a.set_input(3.0)
    a.advance(9.0)
    assert a.events > 0 and a.same_parameters(b) and b.same_parameters(a)
    assert a.same_parameters(core.FrictionMass(**params, x0=1.0, v0=-2.0, f=1.5))
    assert a.same_parameters(NativeFrictionMass(**params, core=core))
    restored = type(a).from_bytes(a.to_bytes())
    assert restored.same_parameters(b) and b.same_parameters(restored) and restored.same_parameters(a.copy())
    assert set(FIXED) == set(TABLE.core_order) - {"x0", "v0", "f"}
    for name, value in FIXED.items():
        assert params.get(name) != value
        other = core.FrictionMass(**dict(params, **{name: value}))
        assert not a.same_parameters(other) and not other.same_parameters(a), name
        assert not restored.same_parameters(type(other).from_bytes(other.to_bytes())), name
        assert other.same_parameters(type(other).from_bytes(other.to_bytes())), name
    for name in ("B", "phi", "F", "Dv", "Fc"):
        assert not core.FrictionMass(**{name: 0.0}).same_parameters(core.FrictionMass(**{name: -0.0})), name
    assert not core.FrictionMass(F=10.0).same_parameters(core.FrictionMass(F=-10.0))  # stored as a phase shift
    for other in (FrictionMass(**params), None, "a", core.TwoMassBacklash(), core.StaticBacklash()):
        assert a.same_parameters(other) is False
    assert core.api.same_parameters(None, a._handle) == 0 == core.api.same_parameters(a._handle, None)


# -- the binding -------------------------------------------------------------------------
def test_solver_protocol(core):
    plant = core.FrictionMass()
    assert isinstance(plant, Solver) and isinstance(plant, NativeFrictionMass)
    assert plant.t == 0.0 and plant.events == 0 and plant.harmonics == 10
    assert plant.output() == TABLE.output_type(0.0, 0.0, 0.0, 0)
    assert plant.integrals() == [0j] * 11
    assert NativeFrictionMass(harmonics=2, core=core).integrals() == [0j] * 3
    assert load(core.path) is core
    assert plant.period == 2 * math.pi and plant.event_log is None
    drive = core.FrictionMass(F=-2.0, f=1.0, omega=3.0).drive  # a negative amplitude: a phase shift of pi
    assert (drive.f, drive.F, drive.omega, drive.phi) == (1.0, 2.0, 3.0, math.pi)
    plant.advance(1.0)
    clone = pickle.loads(pickle.dumps(plant))
    assert type(clone) is type(plant) and clone.to_bytes() == plant.to_bytes() and clone.t == 1.0


def test_build_reuses_and_refuses(core, tmp_path, monkeypatch):
    first = build_core(tmp_path)
    stamp = first.stat().st_mtime_ns
    assert build_core(tmp_path) == first and first.stat().st_mtime_ns == stamp
    assert [p.name for p in tmp_path.iterdir()] == [first.name]  # no temporary left behind
    with pytest.raises(CoreBuildError) as failed:
        build_core(tmp_path, extra_flags=("--no-such-flag-for-dfwb",))
    assert "\n" not in str(failed.value) and "compiling the C core failed" in str(failed.value)
    assert [p.name for p in tmp_path.iterdir()] == [first.name]
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(CoreBuildError, match="needs a C compiler"):
        build_core(tmp_path / "other")


# -- timing (printed, not asserted) --------------------------------------------------------
def test_time_per_event(core):
    """Median time per event of a DF-like run, Python and C: in one step, stepped, stepped with reads."""
    params = dict(F=10.0, omega=1.0, harmonics=10)
    times, _ = periods(params, 20)  # 20 periods, 32 points each

    def run(cls, mode):
        plant = cls(**params)
        start = time.perf_counter()
        for t in times[-1:] if mode == "one step" else times:
            plant.advance(t)
            if mode == "stepped, read":
                plant.output()
                plant.integrals()
        return time.perf_counter() - start, plant.events

    lines = []
    for mode in ("one step", "stepped", "stepped, read"):
        python = [run(FrictionMass, mode) for _ in range(5)]
        native = [run(core.FrictionMass, mode) for _ in range(25)]
        events = python[0][1]
        assert events == native[0][1] > 0
        per_python = statistics.median(s for s, _ in python) / events
        per_native = statistics.median(s for s, _ in native) / events
        lines.append(f"  {mode:>14}: Python {1e6 * per_python:7.1f} us, C {1e6 * per_native:6.2f} us "
                     f"per event ({per_python / per_native:.0f}x)")
    print(f"\nDF-like run (F=10, omega=1, 20 periods, harmonics 10, {events} events; stepped: 640 points, "
          f"read: output() and integrals() at each), median per event:\n" + "\n".join(lines))
