"""The FMUs run in a host that is not Python: a short C importer (tests/c_host/fmu_host.c).

Why: an FMU is meant for any FMI importer (a C/C++ co-simulation master, a
Modelica tool, ...), yet every other test drives it through fmpy, from inside
a Python process that has already loaded libpython, set up ``sys.path`` and
imported numpy. This test proves that the FMU loads and runs with none of
that: a C program dlopen()s binaries/linux64/<id>.so, calls the FMI 2.0
functions itself, and must produce the very numbers of the fmpy path
(``dfwb.fmi.simulation.simulate``) on the same grid -- it is the same Python code
inside the FMU, so they agree to 1e-12 relative -- and must see the FMU's
own error message and an error status when a parameter is out of range.

What the host process needs: nothing. binaries/linux64/<id>.so is dfwb's FMI shim
(build_fmus/shim/fmi2_shim.c), which loads a libpython itself when the process
has none (the one that built the FMU, recorded in resources/dfwb_python.txt,
else libpython3.13 ... 3.10 from the library path) and gives it its home, before
loading pythonfmu's binary (<id>.pythonfmu.so; its ``Py_*`` symbols are
undefined). So the host runs with an empty environment: no LD_PRELOAD, no
PYTHONHOME, no PYTHONPATH, no PATH; the FMU finds its own code and its copy of
pythonfmu in its resources/ folder. The old recipe still works and is tested
once: ``LD_PRELOAD=<LIBDIR>/libpython3.X.so`` and ``PYTHONHOME=<sys.base_prefix>``
(with a preloaded libpython the shim loads none and sets no home).
"""

import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import fmpy
import numpy as np
import pytest

from dfwb.fmi.simulation import simulate

pytestmark = pytest.mark.needs_cc

HOST_SOURCE = Path(__file__).resolve().parent / "c_host" / "fmu_host.c"
FMI_HEADERS = Path(fmpy.__file__).resolve().parent / "c-code"  # fmi2Functions.h & co.


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    """The compiled C host (skips without a C compiler)."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH to build tests/c_host/fmu_host.c")
    binary = tmp_path_factory.mktemp("c_host") / "fmu_host"
    build = subprocess.run(
        [cc, "-std=c99", "-D_DEFAULT_SOURCE", "-Wall", "-Wextra", "-O1", f"-I{FMI_HEADERS}",
         str(HOST_SOURCE), "-o", str(binary), "-ldl", "-lm"],
        capture_output=True, text=True)
    assert build.returncode == 0, f"compiling the C host failed:\n{build.stderr}"
    return binary


@pytest.fixture(scope="module")
def host_env():
    """The whole environment of the host process: empty (the shim finds libpython and its home)."""
    return {}


@pytest.fixture(scope="module")
def preload_env():
    """The environment of the pre-shim recipe: libpython preloaded and PYTHONHOME."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    names = [sysconfig.get_config_var(key) or "" for key in ("LDLIBRARY", "INSTSONAME")]
    shared = [Path(libdir, name) for name in names if ".so" in name and Path(libdir, name).is_file()]
    if not shared:
        pytest.skip(f"this Python ({sys.executable}) has no shared libpython in {libdir!r} "
                    f"(LDLIBRARY = {names[0]!r}): a non-Python host cannot load its FMUs")
    return {"LD_PRELOAD": str(shared[0]), "PYTHONHOME": sys.base_prefix}


def run_host(host, host_env, fmu, tmp_path, stop_time, step, start_values, outputs):
    """Run the C host on an extracted copy of ``fmu``; return the CompletedProcess."""
    directory = fmpy.extract(str(fmu), unzipdir=str(tmp_path / fmu.stem))
    description = fmpy.read_model_description(str(fmu))
    vr = {variable.name: variable.valueReference for variable in description.modelVariables}
    args = [str(host), directory, description.coSimulation.modelIdentifier, repr(stop_time), repr(step)]
    args += [f"{vr[name]}={value!r}" for name, value in start_values.items()]
    args += [str(vr[name]) for name in outputs]
    return subprocess.run(args, env=host_env, cwd=tmp_path, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("model, stop_time, step, start_values, outputs", [
    ("FrictionMass", 20.0, 0.1, {"F": 10.0, "omega": 1.0}, ["x", "v"]),
    ("TwoMassBacklash", 1.0, 0.01, {"F": 50.0, "omega": 20.0, "eps": 0.5}, ["x1", "gap"]),
])
def test_c_host_matches_fmpy(fmus, host, host_env, tmp_path, model, stop_time, step, start_values, outputs):
    run = run_host(host, host_env, fmus[model], tmp_path, stop_time, step, start_values, outputs)
    assert run.returncode == 0, f"C host failed ({run.returncode}):\n{run.stderr}"
    from_c = np.array([[float(word) for word in line.split()] for line in run.stdout.splitlines()])

    reference = simulate(fmus[model], stop_time, step, start_values, outputs)
    assert from_c.shape == (len(reference), 1 + len(outputs))
    for k, name in enumerate(["time"] + outputs):
        expected = reference[name]
        # 1e-12 relative to each value, and to the signal's scale where it crosses zero
        np.testing.assert_allclose(from_c[:, k], expected, rtol=1e-12,
                                   atol=1e-12 * np.max(np.abs(expected)), err_msg=f"{model}.{name}")


def test_c_host_reports_bad_parameter(fmus, host, preload_env, tmp_path):
    """With libpython preloaded (the recipe before the shim) the FMU's error reaches the host."""
    run = run_host(host, preload_env, fmus["TwoMassBacklash"], tmp_path, 1.0, 0.01,
                   {"F": 50.0, "omega": 20.0, "eps": 1.5}, ["x1"])
    assert run.returncode != 0
    assert "eps = 1.5 is out of range" in run.stderr  # the FMU's own message, via the logger
    assert "returned status" in run.stderr  # the host names the failed call and its status
    assert run.stdout == ""  # not a single output row from a refused initialisation


@pytest.mark.parametrize("model, stop_time, step, start_values, outputs", [
    ("FrictionMass", 20.0, 0.1, {"F": 10.0, "omega": 1.0}, ["x", "v", "Ff", "Ic1", "Is1"]),
    ("TwoMassBacklash", 1.0, 0.01, {"F": 50.0, "omega": 20.0, "eps": 0.5}, ["x1", "gap", "Ic1"]),
    ("StaticBacklash", 10.0, 0.05, {"F": 1.0, "omega": 2.0}, ["y", "Is1"]),
])
def test_c_host_runs_native_fmus(native_fmus, fmus, host, tmp_path, model, stop_time, step, start_values, outputs,
                                 monkeypatch):
    """The native FMUs need no Python at all (not even the shim's libpython): the host's numbers are the oracle's."""
    run = run_host(host, {}, native_fmus[model], tmp_path, stop_time, step, start_values, outputs)
    assert run.returncode == 0, f"C host failed ({run.returncode}):\n{run.stderr}"
    from_c = np.array([[float(word) for word in line.split()] for line in run.stdout.splitlines()])
    monkeypatch.setenv("DFWB_FMU_SOLVER", "python")  # the pythonfmu FMU on its pure-Python solver
    reference = simulate(fmus[model], stop_time, step, start_values, outputs)
    assert from_c.shape == (len(reference), 1 + len(outputs))
    for k, name in enumerate(["time"] + outputs):  # %.17g round-trips: bit for bit
        np.testing.assert_array_equal(from_c[:, k], reference[name], err_msg=f"{model}.{name}")


def test_c_host_sees_native_refusal(native_fmus, host, tmp_path):
    run = run_host(host, {}, native_fmus["TwoMassBacklash"], tmp_path, 1.0, 0.01,
                   {"F": 50.0, "omega": 20.0, "eps": 1.5}, ["x1"])
    assert run.returncode != 0
    assert "eps = 1.5 is out of range" in run.stderr
    assert run.stdout == ""
