"""ecos (ecospy), a third independent FMI importer, runs the native plant FMUs as fmpy does.

ecos (https://github.com/Ecos-platform/ecos, PyPI ``ecospy``) loads FMUs
through fmi4c, its own C loader, and imports FMI 1.0, 2.0 and 3.0
co-simulation FMUs; so the native plants are run in it both as FMI 2.0
(``native_fmus``) and as FMI 3.0 (``fmi3_fmus``). Each plant is a single
model in an ecos simulation structure; its start values are a parameter set
applied by ``init``, before initialization (they are fixed parameters), and
its outputs are read at t = 0 and after each fixed step. fmpy's
``simulate_fmu`` on the same grid is the reference.

The plants are exact solvers: their result does not depend on the
communication step, only on the times the importer asks for. ecos counts
time by adding the step (t += h), fmpy as k * h, so the grids differ by up
to 7e-16 s at t = 1 s, and that is all that differs. Measured: at most
1.4e-14 of each output's largest magnitude (TwoMassBacklash's gap;
FrictionMass 1.1e-15, StaticBacklash 1.3e-15), the same for FMI 2.0 and
3.0. RTOL = 1e-12 leaves a factor 70 over that, and is 2000 times smaller
than what a start value off by one part in 1e9 causes (checked below).

Needs ``pip install ecospy`` and Intel TBB (Debian: ``apt-get install libtbb12``),
which ecos's shared library links against.
"""

import fmpy
import numpy as np
import pytest

try:  # ecospy loads its shared library (libecosc.so, linked against libtbb.so.12) on import
    from ecospy import EcosLib, EcosSimulation, EcosSimulationStructure
except (ImportError, OSError) as error:
    pytest.skip(f"ecospy cannot be imported (pip install ecospy; it needs libtbb12): {error}",
                allow_module_level=True)

pytestmark = pytest.mark.needs_cc  # the FMUs are built by the native_fmus and fmi3_fmus fixtures

STEP = 0.01
STEPS = 100  # 1 s
CASES = {  # model: (start values, outputs compared)
    "FrictionMass": ({"F": 10.0, "omega": 1.0}, ["x", "v", "Ff"]),
    "TwoMassBacklash": ({"F": 50.0, "omega": 20.0, "eps": 0.7}, ["x1", "gap"]),
    "StaticBacklash": ({"F": 1.0, "omega": 2.0}, ["y"]),
}
RTOL = 1e-12  # relative to the largest magnitude of each output
ATOL = 1e-15  # the time grid: ecos adds up the step, fmpy multiplies it (7e-16 s apart at t = 1 s)


@pytest.fixture(scope="module")
def fmu_paths(request):
    """{FMI version: {model name: path}}; an FMI version's FMUs are built only when a test asks for them."""
    EcosLib.set_log_level("warn")
    fixtures = {2: "native_fmus", 3: "fmi3_fmus"}

    class Paths(dict):
        def __missing__(self, version):
            self[version] = request.getfixturevalue(fixtures[version])
            return self[version]

    return Paths()


def run_ecos(path, start_values, outputs):
    """{"time": ..., output: ...} from ecos: the FMU alone, start values set before initialization, read at t = 0
    and after each of STEPS fixed steps of STEP."""
    rows = []
    with EcosSimulationStructure() as structure:
        structure.add_model("plant", str(path))
        structure.add_parameter_set("start", {f"plant::{name}": value for name, value in start_values.items()})
        with EcosSimulation(structure=structure, step_size=STEP) as sim:
            assert sim.init(parameter_set="start"), EcosLib.get_last_error()
            applied = {name: sim.get_real(f"plant::{name}") for name in start_values}
            assert applied == start_values, "ecos did not apply the start values"
            rows.append([sim.get_time()] + [sim.get_real(f"plant::{name}") for name in outputs])
            for _ in range(STEPS):
                time = sim.step()
                rows.append([time] + [sim.get_real(f"plant::{name}") for name in outputs])
            sim.terminate()
    columns = np.array(rows).T
    return dict(zip(["time", *outputs], columns))


def run_fmpy(path, start_values, outputs):
    return fmpy.simulate_fmu(str(path), stop_time=STEPS * STEP, output_interval=STEP, start_values=start_values,
                             output=outputs)


def worst(expected, actual, name):
    """(largest |difference| of a column, at time, its tolerance)."""
    reference = np.asarray(expected[name], dtype=float)
    error = np.abs(np.asarray(actual[name], dtype=float) - reference)
    index = int(np.argmax(error))
    tolerance = ATOL if name == "time" else RTOL * float(np.max(np.abs(reference)))
    return float(error[index]), float(expected["time"][index]), tolerance


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("model", list(CASES))
def test_same_results_as_fmpy(fmu_paths, model, version):
    start_values, outputs = CASES[model]
    path = fmu_paths[version][model]
    expected = run_fmpy(path, start_values, outputs)
    actual = run_ecos(path, start_values, outputs)
    assert len(actual["time"]) == len(expected) == STEPS + 1
    for name in ["time", *outputs]:
        error, time, tolerance = worst(expected, actual, name)
        assert error <= tolerance, f"FMI {version}.0 {model}.{name} differs by {error:.3g} at t = {time} " \
                                   f"(tolerance {tolerance:.3g})"
    assert np.max(np.abs(expected[outputs[0]])) > 0.1  # the plant moved


@pytest.mark.parametrize("version", [2, 3])
def test_a_wrong_start_value_is_detected(fmu_paths, version):
    """The comparison has teeth: ecos with F off by one part in 1e9 is 2e-9 away, 2000 times RTOL."""
    start_values, outputs = CASES["FrictionMass"]
    path = fmu_paths[version]["FrictionMass"]
    expected = run_fmpy(path, start_values, outputs)
    actual = run_ecos(path, {**start_values, "F": start_values["F"] * (1 + 1e-9)}, outputs)
    error, _, tolerance = worst(expected, actual, "x")
    assert error > 100 * tolerance
