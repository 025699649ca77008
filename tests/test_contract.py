"""The plant contract: one suite that every registered plant passes, an extra plant defined here included.

tests/contract_plant.py defines a plant outside dfwb (its solver, FMU facade
and registry entry only); it is registered for this module and the suite
below runs on it as on the built-in plants, with nothing else to edit:

(a) its FMU builds (only its own modules bundled) and passes ``fmpy validate``;
(b) its outputs do not depend on the communication step;
(c) a bad parameter (NaN, or outside its range) is refused, by name;
(d) its describing function in a linear limit is the transfer function's value;
(e) its solver implements :class:`dfwb.fmus.Solver`, its outputs a named tuple of FMU outputs.

docs/plants/adding-a-plant.md is written from this file.
"""

import math
import zipfile

import contract_plant
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from dfwb.build_fmus import builder
from dfwb.engine.describing import DFEngine
from dfwb.fmi.location import fmu_path
from dfwb.fmi.simulation import simulate
from dfwb.fmus import PlantError, Solver
from dfwb.plants import names, plant, register, unregister

EXTRA = contract_plant.entry()
NAMES = tuple(dict.fromkeys(names() + (EXTRA.name,)))  # the registered plants, the extra one included
LINEAR_POINT = (50.0, 1.0)  # F (N), omega (rad/s): X = F / (M omega^2) >> a clearance of 1e-9 m


def _friction_linear(omega, p):  # Fc = Fs = 0: a mass-damper, N = 1 / (M (j w)^2 + B j w)
    return 1.0 / complex(-p["M"] * omega ** 2, p["B"] * omega)


def _backlash_linear(omega, p):  # h = 1e-9 m << X: one mass M1 + M2 (error ~ h / X = 4e-11)
    return 1.0 / complex(-(p["M1"] + p["M2"]) * omega ** 2, 0.0)


def _static_backlash_linear(omega, p):  # h = 1e-9 m << X: k times the mass's response (error ~ h / X)
    return p["k"] / complex(-p["M"] * omega ** 2, 0.0)


# The built-in entries declare no Plant.linear (yet): their linear limits, here.
BUILT_IN_LINEAR = {
    "friction": ({"Fc": 0.0, "Fs": 0.0}, _friction_linear),
    "backlash": ({"h": 1e-9}, _backlash_linear),
    "static-backlash": ({"h": 1e-9}, _static_backlash_linear),
}


@pytest.fixture(autouse=True, scope="module")
def extra_plant():
    """The extra plant is registered while this module runs, and only then."""
    added = EXTRA.name not in names()
    if added:
        register(EXTRA)
    yield EXTRA
    if added:
        unregister(EXTRA.name)


def _start(entry):
    """Start values that excite the plant (its demo's, else F = 10 N at 1 rad/s) and the stop time (2 periods)."""
    start = dict(entry.demo.start) if entry.demo is not None else {"F": 10.0, "omega": 1.0}
    return start, 4.0 * math.pi / start["omega"]


def test_the_extra_plant_is_registered_like_the_built_in_ones():
    assert EXTRA.name in names() and plant(EXTRA.name) is EXTRA
    assert set(NAMES) == set(names())


@pytest.mark.parametrize("name", NAMES)
def test_a_fmu_builds_and_validates(name):
    entry = plant(name)
    path = fmu_path(entry, kind="python")  # the pythonfmu FMU (the native twins: tests/test_native_fmus.py)
    assert path.name == f"{entry.fmu_name}.fmu"
    assert validate_fmu(str(path)) == []
    digest = builder.source_hash(entry.model)
    assert builder.recorded_hash(path) == digest
    with zipfile.ZipFile(path) as archive:
        bundled = {name.rpartition("/")[2] for name in archive.namelist()
                   if name.startswith(f"resources/dfwb_fmus_{digest}/")}
    assert bundled == set(builder.sources(entry.model))
    assert "naive.py" not in bundled and "facade.py" in bundled


@pytest.mark.parametrize("name", NAMES)
def test_b_outputs_do_not_depend_on_the_communication_step(name):
    entry = plant(name)
    start, stop = _start(entry)
    outputs = [output for output, *_ in entry.model.outputs] + ["events", "Ic1", "Is1"]
    coarse = simulate(fmu_path(entry), stop, stop / 8, start, outputs)
    fine = simulate(fmu_path(entry), stop, stop / 64, start, outputs)[::8]
    assert len(coarse) == len(fine) == 9
    assert np.allclose(coarse["time"], fine["time"], rtol=0, atol=1e-12 * stop)
    for output in outputs:
        scale = np.max(np.abs(fine[output]))
        assert np.max(np.abs(coarse[output] - fine[output])) <= 1e-12 * scale, output


def _outside(low, high):
    """A value below and one above [low, high]."""
    below = low / 10 if low > 0 else (low * 10 if low < 0 else -1.0)
    above = high * 10 if high > 0 else (high / 10 if high < 0 else 1.0)
    return below, above


@pytest.mark.parametrize("name", NAMES)
def test_c_bad_parameters_are_refused_by_name(name):
    entry = plant(name)
    assert entry.check({}) == {}
    for parameter in entry.defaults():
        bad = [math.nan, math.inf]
        limits = entry.limits(parameter)
        if limits is not None:
            bad += list(_outside(*limits[:2]))
        for value in bad:
            with pytest.raises(PlantError) as error:
                entry.check({parameter: value})
            assert str(error.value).startswith(f"{parameter} = "), (parameter, value, str(error.value))
    with pytest.raises(PlantError, match="unknown parameter 'nonsense'"):
        entry.check({"nonsense": 1.0})


@pytest.mark.parametrize("name", NAMES)
def test_d_describing_function_of_the_linear_limit(name):
    entry = plant(name)
    linear = entry.linear or BUILT_IN_LINEAR.get(name)
    if linear is None:
        pytest.skip(f"plant {name!r} declares no linear limit (Plant.linear)")
    params, exact = linear
    F, omega = LINEAR_POINT
    result = DFEngine(name).point(F, omega, params)
    expected = exact(omega, entry.complete(params))
    assert result.periodic
    assert abs(result.N - expected) <= 1e-9 * abs(expected), (result.N, expected)


@pytest.mark.parametrize("name", NAMES)
def test_e_solver_implements_the_protocol(name):
    entry = plant(name)
    start, stop = _start(entry)
    kwargs = entry.model.solver_kwargs(dict(entry.defaults(), **start))
    solver = entry.model.solver_class(**kwargs)
    assert isinstance(solver, Solver)
    solver.set_input(1.0)
    solver.advance(0.5 * stop)
    assert solver.t == 0.5 * stop
    out = solver.output()
    fmu_outputs = [output for output, *_ in entry.model.all_outputs()]
    assert out._fields == tuple(fmu_outputs[:len(out)])  # named like the FMU's outputs, in their order
    assert len(solver.integrals()) == kwargs.get("harmonics", 10) + 1
    assert isinstance(solver.events, int)


def test_a_plant_module_that_needs_dfwb_at_import_is_refused(tmp_path, monkeypatch):
    """An FMU runs without dfwb: only imports of dfwb.fmus are bundled (rewritten), others only inside functions."""
    import importlib
    import sys

    module = tmp_path / "needs_registry.py"
    module.write_text(contract_plant.__loader__.get_source("contract_plant").replace(
        "def entry():", "from dfwb.plants.registry import Plant  # noqa: E402\n\n\ndef entry():"))
    monkeypatch.syspath_prepend(str(tmp_path))
    loaded = importlib.import_module("needs_registry")
    try:
        with pytest.raises(builder.BuildError, match="needs_registry.*from dfwb.plants.registry import"):
            builder.sources(loaded.MassSpringDamper)
    finally:
        sys.modules.pop("needs_registry", None)


def test_the_extra_plants_imports_are_rewritten_line_for_line():
    text = builder.sources(contract_plant.MassSpringDamper)["contract_plant.py"].decode()
    original = contract_plant.__loader__.get_source("contract_plant")
    assert "from .facade import PlantFMU\nfrom .piecewise import check\n" in text
    assert "    from dfwb.plants.registry import Demo, Plant\n" in text  # inside entry(): never run in the FMU
    assert len(text.splitlines()) == len(original.splitlines())
