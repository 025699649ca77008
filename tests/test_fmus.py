"""The FMUs as an importer sees them: compliance, step independence, errors, loading, builds."""

import math
import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from dfwb.build_fmus import builder
from dfwb.fmi.simulation import FMUError, simulate, sine_input
from dfwb.fmus import FrictionMass, StaticBacklash, TwoMassBacklash

MODELS = ["FrictionMass", "TwoMassBacklash", "StaticBacklash"]
EXCITED = {  # model: (start values, stop time, outputs)
    "FrictionMass": ({"F": 10.0, "omega": 1.0}, 20.0, ["x", "v", "Ff", "Ic1", "Is1"]),
    "TwoMassBacklash": ({"F": 50.0, "omega": 20.0, "eps": 0.5}, 2.0, ["x1", "v1", "x2", "v2", "gap", "Ic1"]),
    "StaticBacklash": ({"F": 50.0, "omega": 20.0}, 2.0, ["x", "y", "Ic1", "Is1"]),
}
SOLVERS = {"FrictionMass": FrictionMass, "TwoMassBacklash": TwoMassBacklash, "StaticBacklash": StaticBacklash}


@pytest.mark.parametrize("model", MODELS)
def test_fmpy_validate_finds_no_problem(fmus, model):
    assert validate_fmu(str(fmus[model])) == []


@pytest.mark.parametrize("model", MODELS)
def test_every_variable_is_described_and_dimensioned(fmus, model):
    description = fmpy.read_model_description(str(fmus[model]))
    assert description.defaultExperiment is not None
    assert description.coSimulation.modelIdentifier == model
    dimensionless = {"eps", "k", "harmonics", "mode", "contact", "impacts", "events", "engaged"}
    for variable in description.modelVariables:
        assert variable.description, variable.name
        if variable.name not in dimensionless:
            assert variable.unit, variable.name


@pytest.mark.parametrize("model", MODELS)
def test_result_does_not_depend_on_the_communication_step(fmus, model):
    start, stop, outputs = EXCITED[model]
    coarse = simulate(fmus[model], stop, stop / 20, start, outputs)
    fine = simulate(fmus[model], stop, stop / 2000, start, outputs)
    fine = fine[::100]
    assert np.allclose(coarse["time"], fine["time"], rtol=0, atol=1e-12)
    for name in outputs:
        scale = np.max(np.abs(fine[name]))
        assert np.max(np.abs(coarse[name] - fine[name])) <= 1e-9 * scale, name


@pytest.mark.parametrize("model", MODELS)
def test_fmu_runs_the_solver_exactly(fmus, model):
    """What fmpy reads from the FMU is, bit for bit, what the solver computes in-process."""
    start, stop, outputs = EXCITED[model]
    result = simulate(fmus[model], stop, stop / 50, start, outputs)
    solver = SOLVERS[model](**start)
    first = outputs[0]
    for row in result[1:]:
        solver.advance(row["time"])
        assert row[first] == solver.output()[0]


def test_sampled_input_converges_to_the_built_in_excitation(fmus):
    """fmpy holding a sampled sine over each step: error falls as the sampling gets finer."""
    start, stop, _ = EXCITED["StaticBacklash"]
    exact = simulate(fmus["StaticBacklash"], stop, 2 * math.pi / 20 / 1024, start, ["y"])
    errors = []
    for samples in (32, 128, 512):
        table = sine_input(start["F"], start["omega"], stop, samples)
        held = simulate(fmus["StaticBacklash"], stop, 2 * math.pi / 20 / samples, {"omega": 20.0}, ["y"], input=table)
        errors.append(np.max(np.abs(np.interp(held["time"], exact["time"], exact["y"]) - held["y"])))
    assert errors[0] > errors[1] > errors[2]


@pytest.mark.parametrize("model, values, message", [
    ("FrictionMass", {"M": 0.0}, "M = 0.0 is out of range"),
    ("FrictionMass", {"B": -1.0}, "B = -1.0 is out of range"),
    ("FrictionMass", {"Fs": 1.0}, "Fs = 1.0 is out of range: Fs must be >= Fc"),
    ("TwoMassBacklash", {"h": 0.0}, "h = 0.0 is out of range"),
    ("TwoMassBacklash", {"eps": 1.5}, "eps = 1.5 is out of range: eps must be in \\[0, 1\\]"),
    ("TwoMassBacklash", {"eps": -0.5}, "eps = -0.5 is out of range"),
    ("TwoMassBacklash", {"gap0": 0.3}, "gap0 = 0.3 is out of range"),
    ("StaticBacklash", {"h": -0.1}, "h = -0.1 is out of range"),
    ("StaticBacklash", {"omega": 0.0}, "omega = 0.0 is out of range"),
])
def test_bad_parameter_is_an_error_naming_it(fmus, model, values, message):
    with pytest.raises(FMUError, match=f"{model}: .*{message}"):
        simulate(fmus[model], 1.0, 0.1, values)


def test_nan_input_is_an_error_with_its_time(fmus):
    table = sine_input(10.0, 1.0, 2.0, 16)
    table["f"][5] = np.nan
    with pytest.raises(FMUError, match=r"FrictionMass: .*t = 1\.96.*f = nan is out of range"):
        simulate(fmus["FrictionMass"], 2.0, 2 * math.pi / 16, {"omega": 1.0}, ["x"], input=table)


@pytest.mark.parametrize("step", [0.0, -0.1, math.nan])
def test_zero_negative_or_nan_step_is_refused_by_the_fmu(raw_fmu, step):
    """The FMU itself (not only our wrapper) refuses a bad step, with a message."""
    fmu, messages = raw_fmu("FrictionMass")
    fmu.doStep(0.0, 0.1)
    with pytest.raises(Exception, match="fmi2DoStep failed"):
        fmu.doStep(0.1, step)
    assert (3, f"FrictionMass: communication step {step!r} at t = 0.1: it must be > 0 and finite") in messages


def test_truncated_result_is_an_error(tmp_path):
    """An FMU that discards a step: fmpy stops quietly, simulate() must raise."""
    from pythonfmu.builder import FmuBuilder

    script = tmp_path / "Quitter.py"
    script.write_text(
        "from pythonfmu import Fmi2Slave, Real, Fmi2Causality\n"
        "class Quitter(Fmi2Slave):\n"
        "    def __init__(self, **kw):\n"
        "        super().__init__(**kw)\n"
        "        self.y = 0.0\n"
        "        self.register_variable(Real('y', causality=Fmi2Causality.output))\n"
        "    def do_step(self, t, dt):\n"
        "        self.y = t\n"
        "        return t < 0.5\n")
    fmu = FmuBuilder.build_FMU(script, dest=tmp_path)
    with pytest.raises(FMUError, match=r"Quitter: the simulation stopped at t = 0\.[56].* before stop_time = 1\.0"):
        simulate(fmu, 1.0, 0.1)


def test_all_fmus_load_together_in_any_order_and_repeatedly(fmus):
    """pythonfmu instantiation must survive many instances of several FMUs in one process."""
    reference = {model: simulate(fmus[model], 0.2, 0.01, EXCITED[model][0], EXCITED[model][2][:1])
                 for model in MODELS}
    for order in (MODELS, MODELS[::-1], MODELS[1:] + MODELS[:1]) * 4:
        for model in order:
            again = simulate(fmus[model], 0.2, 0.01, EXCITED[model][0], EXCITED[model][2][:1])
            assert np.array_equal(again, reference[model])


def test_fmus_bundle_their_code_under_a_source_hash(fmus):
    for model in MODELS:
        digest = builder.source_hash(getattr(builder.facade, model))
        with zipfile.ZipFile(fmus[model]) as archive:
            names = archive.namelist()
            assert f"resources/dfwb_fmus_{digest}/friction.py" in names
            assert f"resources/dfwb_fmus_{digest}/naive.py" not in names  # the benchmark's twins stay out
            assert archive.read("resources/slavemodule.txt").decode() == f"{model}_{digest}"
        assert builder.recorded_hash(fmus[model]) == digest


def test_build_skips_unchanged_fmus_and_hash_follows_sources(tmp_path, monkeypatch):
    messages = []
    models = [builder.facade.FrictionMass, builder.facade.LinearSystem]
    first = builder.build(tmp_path, models, report=messages.append)
    stamps = [path.stat().st_mtime_ns for path in first]
    builder.build(tmp_path, models, report=messages.append)
    assert [path.stat().st_mtime_ns for path in first] == stamps
    assert sum("up to date" in message for message in messages) == len(models)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["FrictionMass.fmu", "LinearSystem.fmu"]

    sources = tmp_path / "sources"
    sources.mkdir()
    for path in builder.FMUS_DIR.glob("*.py"):
        (sources / path.name).write_bytes(path.read_bytes())
    monkeypatch.setattr(builder, "FMUS_DIR", sources)
    before = builder.source_hash(builder.facade.FrictionMass)
    (sources / "exact.py").write_text((sources / "exact.py").read_text() + "\n# changed\n")
    assert builder.source_hash(builder.facade.FrictionMass) != before


def test_fmus_from_different_sources_never_share_code(fmus, tmp_path, monkeypatch):
    """An FMU built from changed sources runs its own code beside the current one."""
    sources = tmp_path / "sources"
    sources.mkdir()
    for path in builder.FMUS_DIR.glob("*.py"):
        (sources / path.name).write_bytes(path.read_bytes())
    friction = sources / "friction.py"
    original = "return TABLE.output_type(x, v, ff, self.direction if self.mode == SLIDE else 0)"
    assert original in friction.read_text()
    friction.write_text(friction.read_text().replace(original, original.replace("x, v,", "x + 1.0, v,", 1)))
    monkeypatch.setattr(builder, "FMUS_DIR", sources)
    changed = builder.build_one(builder.facade.FrictionMass, tmp_path)

    start = {"F": 10.0, "omega": 1.0}
    current = simulate(fmus["FrictionMass"], 5.0, 0.5, start, ["x"])
    other = simulate(changed, 5.0, 0.5, start, ["x"])
    again = simulate(fmus["FrictionMass"], 5.0, 0.5, start, ["x"])
    assert np.array_equal(other["x"], current["x"] + 1.0)
    assert np.array_equal(again["x"], current["x"])


def test_nan_communication_time_is_refused_by_the_fmu(raw_fmu):
    fmu, messages = raw_fmu("FrictionMass")
    with pytest.raises(Exception, match="fmi2DoStep failed"):
        fmu.doStep(math.nan, 0.1)
    assert (3, "FrictionMass: doStep at t = nan, but the FMU is at t = 0.0") in messages


ALL_MODELS = MODELS + ["LinearSystem", "NaiveFrictionMass", "NaiveTwoMassBacklash", "NaiveStaticBacklash"]
RANGES = {  # model: {variable: (min, max)} the model description must state
    "FrictionMass": {"M": ("0.0", None), "B": ("0.0", None), "Fs": ("0.0", None), "omega": ("0.0", None),
                     "harmonics": ("0", "10")},
    "TwoMassBacklash": {"eps": ("0.0", "1.0"), "gap0": ("-1.0", None), "M1": ("0.0", None), "h": ("0.0", None)},
    "StaticBacklash": {"k": ("0.0", None), "h": ("0.0", None), "harmonics": ("0", "10")},
    "LinearSystem": {"order": ("1", "8")},
    "NaiveFrictionMass": {"dt": ("0.0", None), "M": ("0.0", None)},
}
FEEDTHROUGH = {"FrictionMass": {"Ff", "mode"}, "NaiveFrictionMass": {"Ff", "mode"}, "LinearSystem": {"y"}}  # outputs the input feeds directly


@pytest.mark.parametrize("model", ALL_MODELS)
def test_model_description_states_ranges_dependencies_and_state_support(fmus, model):
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(fmus[model]) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    cosimulation = root.find("CoSimulation")
    assert cosimulation.get("canGetAndSetFMUstate") == "true"
    assert cosimulation.get("canSerializeFMUstate") == "true"
    variables = list(root.find("ModelVariables"))
    for name, (low, high) in RANGES.get(model, {}).items():
        element = next(scalar for scalar in variables if scalar.get("name") == name)[0]
        assert (element.get("min"), element.get("max")) == (low, high), name
    index = {str(i): scalar for i, scalar in enumerate(variables, start=1)}
    inputs = [i for i, scalar in index.items() if scalar.get("causality") == "input"]
    outputs = root.find("ModelStructure/Outputs")
    assert len(outputs) == sum(scalar.get("causality") == "output" for scalar in variables)
    for unknown in outputs:
        name = index[unknown.get("index")].get("name")
        if name in FEEDTHROUGH.get(model, ()):
            assert unknown.get("dependencies") == inputs[0] and unknown.get("dependenciesKind"), name
        else:
            assert unknown.get("dependencies") == "", name  # a state: the input does not feed it directly
    assert len(root.find("ModelStructure/InitialUnknowns")) == len(outputs)


@pytest.mark.parametrize("model", ALL_MODELS)
def test_fmu_manipulation_toolbox_check_finds_no_error(fmus, model):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    fmutool = shutil.which("fmutool") or str(Path(sys.executable).with_name("fmutool"))
    if not Path(fmutool).exists():
        pytest.skip("fmu-manipulation-toolbox is not installed (pip install .[test])")
    run = subprocess.run([fmutool, "-input", str(fmus[model]), "-check"], capture_output=True, text=True, timeout=120)
    report = run.stdout + run.stderr
    assert run.returncode == 0, report
    assert "seems to be compliant with FMI-2.0" in report, report
    assert "No semantic error" in report, report
    assert "ERROR" not in report, report


def test_outputs_that_overflow_are_refused_never_served(fmus):
    """A force and a mass out of scale: exitInitializationMode fails with the reason logged, no NaN output."""
    from conftest import new_instance
    from fmpy.fmi1 import FMICallException

    fmu, description, messages = new_instance(fmus["FrictionMass"], "overflow")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([vr["M"], vr["F"]], [1e-300, 1e100])
    with pytest.raises(FMICallException):
        fmu.exitInitializationMode()
    assert any("overflow" in text for _status, text in messages)
