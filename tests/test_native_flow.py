"""The model-exchange stepper in C (:mod:`dfwb.foreign.native_flow`) against its oracle, scipy's DOP853.

The same method, stepped the same way: from one state, a run of the C stepper and a run of scipy's
take the same steps (the same count, the same evaluations, the same events; at most one step more or
less where a state lands a rounding short of an event's edge) and end on the same state to rounding - a DF's forcing periods with their Fourier integrals, and a closed loop (a controller's
states, an algebraic loop through a feedthrough, a Poincare section). The FMUs run in this process
(well-behaved ones: the hostile ones are the worker's, tests/test_foreign.py).
"""

import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import dfwb
from dfwb.base.errors import InputError
from dfwb.foreign import loop, model_exchange, native_flow
from dfwb.foreign.instance import Instance

sys.path.insert(0, str(Path(__file__).parent))
import foreign_models  # noqa: E402


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("native_flow")
    names = ("MassSpringDamper", "Saturation", "Relay", "NotANumber")
    return {name: foreign_models.build(name, folder) for name in names}


def _instance(path):
    plant = dfwb.fmu_plant(path)
    return Instance(plant.info, plant.kind, plant.input, plant.output)


def _use(monkeypatch, mode):
    monkeypatch.setenv("DFWB_FOREIGN_FLOW", mode)
    monkeypatch.setattr(native_flow, "_LIBRARY", {})


def _periods(built, monkeypatch, mode, name, F, omega, params, count=3, rtol=1e-9):
    """(state, X, steps, evaluations) after ``count`` forcing periods from rest, as a DF point runs them."""
    _use(monkeypatch, mode)
    inst = _instance(built[name])
    next_event = inst.start(params, F)
    period = model_exchange._Period(inst, F, omega, 10)  # after the start: the FMU's states are known
    period.next_event = next_event
    x, t, T = inst.states(), 0.0, 2 * math.pi / omega
    inst.set_continuous(0.0, x, F)
    period.flow.scale[:len(x)] = np.maximum(np.abs(x), np.abs(inst.derivatives()) * T)
    period.flow.y_max = 1.0
    for _ in range(count):
        x, X, _events = period.run(t, x, rtol, period.atol(rtol))
        t += T
    stepped_in_c = period.flow.native is not None
    return x, X, period.flow.steps, period.flow.evaluations, stepped_in_c


@pytest.mark.parametrize("name, F, omega, params", [
    ("MassSpringDamper", 1.0, 2.0, {"c": 0.2}),  # states only
    ("Saturation", 3.0, 1.0, {}),  # no state, kinks: steps aimed at them
    ("Relay", 3.0, 2.0, {"a": 0.7, "Y": 2.0}),  # events
])
def test_a_forcing_period_is_scipys_to_rounding(built, monkeypatch, name, F, omega, params):
    x_py, X_py, steps_py, evaluations_py, c_py = _periods(built, monkeypatch, "python", name, F, omega, params)
    x_c, X_c, steps_c, evaluations_c, c_c = _periods(built, monkeypatch, "native", name, F, omega, params)
    assert not c_py and c_c
    assert (steps_c, evaluations_c) == (steps_py, evaluations_py)
    assert np.allclose(x_c, x_py, rtol=1e-12, atol=1e-14)
    assert np.allclose(X_c, X_py, rtol=1e-12, atol=1e-12 * np.max(np.abs(X_py)))  # (a harmonic at 1e-15: noise)


def _loop_run(built, monkeypatch, mode, G, name, params, duration):
    """(t, z, events, crossed, steps, evaluations): a closed loop of ``name`` under G from a start force of
    2, run for ``duration`` or to its section (the controller's output crossing 0 upwards)."""
    _use(monkeypatch, mode)
    inst = _instance(built[name])
    num, den = G
    A, B, C, D = loop.realization(num, den)
    inst.start(params, 2.0)
    the_loop = loop._Loop(inst, A, B, C, D, omega=1.0)
    z = np.concatenate((inst.states(), -2.0 * C / float(C @ C), np.zeros(the_loop.flow.extra - len(B))))
    t, z, events, crossed = the_loop.flow.run(0.0, z, duration, 1e-9, the_loop.atol(1e-9),
                                              section=lambda t, w, y: float(C @ w[:len(B)]) + 0.5 * y)
    return t, z, events, crossed, the_loop.flow.steps, the_loop.flow.evaluations


@pytest.mark.parametrize("G, name, params", [
    (([10.0], [1.0, 2.0, 1.0, 0.0]), "Saturation", {}),  # 10/(s (s + 1)^2), the saturating loop of the tests
    (([0.5, 1.0], [1.0, 1.0]), "Saturation", {"a": 0.2}),  # 0.5 (s + 2)/(s + 1): a feedthrough, D = 0.5
    (([4.0, 2.0], [1.0, 1.0, 0.0]), "MassSpringDamper", {}),  # (4 s + 2)/(s (s + 1)) on a plant with states
])
def test_a_closed_loop_run_is_scipys_to_rounding(built, monkeypatch, G, name, params):
    python = _loop_run(built, monkeypatch, "python", G, name, params, 30.0)
    native = _loop_run(built, monkeypatch, "native", G, name, params, 30.0)
    assert native[2:4] == python[2:4] and native[0] == pytest.approx(python[0], rel=1e-12, abs=1e-12)
    assert abs(native[4] - python[4]) <= 1  # steps: a state a rounding short of an event's edge costs one
    assert np.allclose(native[1], python[1], rtol=1e-10, atol=1e-12)


def test_a_derivative_that_is_not_finite_is_said_as_scipys_path_says_it(built, monkeypatch):
    messages = []
    for mode in ("python", "native"):
        with pytest.raises(FloatingPointError) as caught:
            _periods(built, monkeypatch, mode, "NotANumber", 8.0, 1.0, {})
        messages.append(str(caught.value))
    assert messages[0] == messages[1] and "not finite" in messages[0]


def test_the_choice_is_checked_and_a_library_that_cannot_be_built_falls_back_to_scipy(built, monkeypatch):
    _use(monkeypatch, "fortran")
    with pytest.raises(InputError, match="DFWB_FOREIGN_FLOW = 'fortran' is not allowed: native or python"):
        native_flow.library()
    _use(monkeypatch, "python")
    assert native_flow.library() is None

    from dfwb.build_fmus import core

    def refuse(*args, **kwargs):
        raise core.CoreBuildError("building the C core needs a C compiler: no $CC, cc, gcc or clang on PATH")

    _use(monkeypatch, "native")
    monkeypatch.setattr(core, "build_library", refuse)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        x, X, *_rest, stepped_in_c = _periods(built, monkeypatch, "native", "MassSpringDamper", 1.0, 2.0, {})
    assert not stepped_in_c and np.all(np.isfinite(X))
    assert any("scipy's DOP853 runs instead" in str(w.message) for w in caught)


def test_the_stepper_compiles_without_a_warning(tmp_path):
    from dfwb.build_fmus.core import build_library

    path = build_library(tmp_path, [native_flow.SOURCE], "libdfwb_flow-", extra_flags=("-Wall", "-Wextra", "-Werror"))
    assert path.is_file() and path.name.startswith("libdfwb_flow-")


def test_a_bad_choice_is_one_line_before_any_point(built, tmp_path):
    run = subprocess.run([sys.executable, "-m", "dfwb.cli", "df", str(built["Saturation"]), "--input", "u",
                          "--output", "y", "--F", "1", "--omega", "1"], capture_output=True, text=True, cwd=tmp_path,
                         env=dict(os.environ, DFWB_FOREIGN_FLOW="fortran"), timeout=120)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "DFWB_FOREIGN_FLOW = 'fortran' is not allowed: native or python" in run.stderr
