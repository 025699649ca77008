"""One step's work is bounded: drive periods and events per plant step, chunks and events per loop step.

An importer may ask for any step (doStep(0, 1e9)); without these bounds a step
would run for as long as the motion is long (minutes to hours). The bounds
refuse a step with one PlantError before the work (a plant's span) or as soon
as a count exceeds it (events, loop chunks), the same text in C and in
Python; a refused span leaves the solver as it was, and a long motion taken
in several steps runs as before.

The bounds are large (1e6 periods, 5e6 events, 1e7 chunks), so they are
tested on a core compiled with small ones (``-D``, see fmus/native/exact.h and
hybrid.h) against the Python solvers with the same small values patched in;
the real ones are checked where refusing costs nothing (a plant's span).
"""

import math

import pytest

from dfwb.build_fmus.core import build_core
from dfwb.fmus import backlash, exact, friction, hybrid, piecewise, static_backlash
from dfwb.fmus.backlash import TwoMassBacklash
from dfwb.fmus.friction import FrictionMass
from dfwb.fmus.native_core import load
from dfwb.fmus.static_backlash import StaticBacklash

PERIODS, EVENTS, CHUNKS = 10, 20, 200  # the small bounds
PLANTS = [(FrictionMass, "FrictionMass", {"F": 10.0, "omega": 1.0}),
          (TwoMassBacklash, "TwoMassBacklash", {"F": 50.0, "omega": 20.0, "eps": 0.5}),
          (StaticBacklash, "StaticBacklash", {"F": 50.0, "omega": 20.0})]
LOOP = {"b": [20.0, 40.0], "a": [20.0]}  # G(s) = 20 (s + 2) / (s + 20) around the friction mass


@pytest.fixture(scope="module")
def small_core(core, tmp_path_factory):
    """A C core compiled with the small bounds."""
    flags = ("-Wall", "-Wextra", "-Werror", f"-DDFWB_MAX_PERIODS_PER_STEP={PERIODS}",
             f'-DDFWB_MAX_PERIODS_PER_STEP_TEXT="{PERIODS}"', f"-DDFWB_MAX_EVENTS_PER_STEP={EVENTS}",
             f"-DDFWB_HY_MAX_CHUNKS_PER_STEP={CHUNKS}")
    return load(build_core(tmp_path_factory.mktemp("small_bounds"), flags))


@pytest.fixture
def small(small_core, monkeypatch):
    """The small-bounds core, with the Python solvers patched to the same bounds for the test."""
    for module in (exact, piecewise, hybrid):
        monkeypatch.setattr(module, "MAX_EVENTS_PER_STEP", EVENTS)
    monkeypatch.setattr(piecewise, "MAX_PERIODS_PER_STEP", PERIODS)
    monkeypatch.setattr(hybrid, "MAX_CHUNKS_PER_STEP", CHUNKS)
    return small_core


def refusal(solver, t_end):
    with pytest.raises(exact.PlantError) as error:
        solver.advance(t_end)
    return str(error.value)


def outputs(solver):
    return (solver.t, solver.events, solver.output(), solver.integrals())


@pytest.mark.parametrize("python_class, name, params", PLANTS, ids=[p[1] for p in PLANTS])
def test_a_plant_step_spans_at_most_the_bound_in_periods(small, python_class, name, params):
    period = 2 * math.pi / params["omega"]
    python, native = python_class(**params), getattr(small, name)(**params)
    for solver in (python, native):
        solver.advance(0.25 * period)
    text = refusal(python, 0.25 * period + 10.5 * period)
    assert text == refusal(native, 0.25 * period + 10.5 * period)
    assert text.startswith("t_end = ") and f"a step spans at most {PERIODS} periods of the drive" in text
    assert "this one 10.5 from t = " in text and text.endswith("take smaller steps"), text
    assert native.t == python.t == 0.25 * period  # refused before any work: the solvers are where they were
    twin = getattr(small, name)(**params)  # never refused
    twin.advance(0.25 * period)
    for solver in (python, native, twin):
        for k in (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 10.5):  # the same span in steps (about 4 events per period)
            solver.advance(0.25 * period + k * period)
    assert outputs(native) == outputs(twin) and outputs(native) == outputs(python)


@pytest.mark.parametrize("python_class, name, params", PLANTS, ids=[p[1] for p in PLANTS])
def test_a_plant_step_fires_at_most_the_bound_in_events(small, python_class, name, params):
    period = 2 * math.pi / params["omega"]
    python, native = python_class(**params), getattr(small, name)(**params)
    text = refusal(python, 10 * period)  # about 4 events per period
    assert text == refusal(native, 10 * period)
    assert text.startswith(f"more than {EVENTS} events in one step between t = 0.0 and t = ")
    assert text.endswith("): take smaller steps"), text
    stepped, whole = python_class(**params), getattr(small, name)(**params)
    for k in range(1, 11):
        stepped.advance(k * period)
        whole.advance(k * period)
    assert stepped.events > EVENTS and outputs(stepped) == outputs(whole)


@pytest.mark.parametrize("python_class, name, params", PLANTS, ids=[p[1] for p in PLANTS])
def test_the_real_span_bound_refuses_at_once_with_one_text(core, python_class, name, params):
    period = 2 * math.pi / params["omega"]
    t_end = 1.5e6 * period  # within the phase limit, beyond the span bound: minutes of work if it ran
    text = refusal(getattr(core, name)(**params), t_end)  # C first: a defect here costs seconds, not minutes
    assert text == refusal(python_class(**params), t_end)
    assert "a step spans at most 1e+06 periods of the drive" in text and "this one 1500000.0 from" in text


PID = ([40.0, 300.0, 1000.0], [10.0, 0.0])  # 20 + 100/s + 2s/(0.1s + 1): hunting, events first
LEAD = ([200.0, 400.0], [20.0])  # 200 (s + 2)/(s + 20)
LEAD_LOW = ([20.0, 40.0], [20.0])  # 20 (s + 2)/(s + 20): few events, chunks first
LOOPS = [(friction.LOOP, "FrictionLoop", PID, {"x0": 0.1}, "events"),
         (backlash.LOOP, "BacklashLoop", LEAD, {"eps": 0.2, "x1_0": 0.1}, None),
         (static_backlash.LOOP, "StaticBacklashLoop", LEAD_LOW, {"x0": 0.1}, "chunks")]


@pytest.mark.parametrize("python_class, name, G, params, first", LOOPS, ids=[loop[1] for loop in LOOPS])
def test_a_loop_step_integrates_at_most_the_bounds_in_chunks_and_events(small, python_class, name, G, params, first):
    t_end = 20.0  # 40 to 70 events and 300 to 500 chunks: beyond both small bounds
    text = refusal(python_class(*G, **params), t_end)
    assert text == refusal(getattr(small, name)(*G, **params), t_end)
    chunks = text.startswith(f"more than {CHUNKS} chunks of integration in one step from t = 0.0 (at t = ")
    events = text.startswith(f"more than {EVENTS} events in one step between t = 0.0 and t = ")
    assert (chunks or events) and text.endswith("take smaller steps"), text
    assert first is None or (first == "chunks") == chunks, text
    counted = hybrid.Budget(10**6)  # counts the chunks of the stepped run
    python = python_class(*G, **params, budget=counted)
    native = getattr(small, name)(*G, **params)
    for k in range(1, 41):  # the same motion in steps of 0.5 s
        python.advance(0.5 * k)
        native.advance(0.5 * k)
    assert (native.t, native.events, native.state()) == (python.t, python.events, python.state())
    assert (python.events > EVENTS) if events else (counted.total - counted.left > CHUNKS)
