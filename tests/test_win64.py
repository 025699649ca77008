"""The native FMUs' win64 binaries, run by a Windows host under Wine, against their linux64 binaries.

The C host (tests/c_host/fmu_host.c) is compiled from one source for
linux64 with the system's compiler and for Windows with mingw-w64, each for
FMI 2.0 and (``-DFMI3``) FMI 3.0; the Windows host loads
``binaries/win64/<Model>.dll`` (FMI 3.0: ``binaries/x86_64-windows/``) with
LoadLibrary and runs under Wine. Both run the same FMU (the one archive carries both binaries)
through the same calls: a run on a grid, its FMU state taken half way,
serialized, refused when cut by one byte, deserialized, set, and the second
half run again; and refusals (a bad parameter) with the FMU's own message.

What must agree, and how closely:

* Within each platform the state round trip is exact: the rows after the
  restore equal the first run's, bit for bit.
* Across platforms the control flow is the same: the grid, the row count,
  the state's size, the statuses and every logged message (numbers in them
  included: mingw-w64 is built with C99's printf) are identical.
* The numbers are those of two C runtimes' math libraries (sin, cos, exp of
  glibc against the msvcrt that mingw-w64 links, here Wine's): they agree
  to their last bits, not always bit for bit. Bound: ``ULP_BOUND`` units in
  the last place of the output's largest magnitude over the run; measured:
  bit for bit in most cases, 8 ulps at most (FrictionMass.x); a wrong
  formula, a missed event or an uninitialised value is off by millions.

Wine under real Windows is not Windows: what this proves is that the DLL is a
well-formed win64 FMU whose code gives linux64's numbers on Wine's C runtime;
Microsoft's msvcrt may round its sin and cos differently in the last bit.

The pythonfmu FMUs' win64 binary is dfwb's shim too (build_fmus/shim), in
front of pythonfmu's DLL. That DLL needs a Windows Python (python3.dll) and
the MSVC runtime, which Wine here has not: what is tested is the shim alone,
its exports, its checks before anything is loaded (a wrong GUID refused with
a message) and its one-line fatal message naming the DLL that cannot load.
A pythonfmu FMU running on Windows is not tested.

Skips without mingw-w64 or Wine, unless DFWB_REQUIRE_WIN64=1 (set by .ci/run,
which installs both), where their absence fails.
"""

import fcntl
import locale
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

HOST_SOURCE = Path(__file__).resolve().parent / "c_host" / "fmu_host.c"
FMI_HEADERS = Path(fmpy.__file__).resolve().parent / "c-code"
MINGW = "x86_64-w64-mingw32-gcc"
ULP_BOUND = 64

pytestmark = pytest.mark.needs_cc


def _missing(what):
    if os.environ.get("DFWB_REQUIRE_WIN64") == "1":
        pytest.fail(f"DFWB_REQUIRE_WIN64=1 but {what} (Debian: gcc-mingw-w64-x86-64, wine)")
    pytest.skip(what)


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    """{(FMI version, platform): (command prefix, environment)} of the C host compiled for linux64 and for
    Windows (run by Wine), for FMI 2.0 and 3.0.

    Made once a session: the pytest-xdist workers share one folder (their temporary folders' parent), and the
    first to get here compiles the hosts and makes the Wine prefix (~7 s of CPU) while the other waits for it."""
    if not shutil.which(MINGW):
        _missing(f"no {MINGW} on PATH")
    wine = shutil.which("wine")
    if not wine:
        _missing("no wine on PATH")
    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "win64_hosts"
    folder.mkdir(exist_ok=True)
    prefix = folder / "wineprefix"  # a private prefix, nothing in $HOME
    env = {"WINEPREFIX": str(prefix), "WINEDEBUG": "-all", "HOME": str(folder), "PATH": os.environ["PATH"],
           "WINEDLLOVERRIDES": "mscoree,mshtml="}  # no Mono or Gecko installer dialogs
    builds = {"linux64": (["cc", "-D_DEFAULT_SOURCE"], "fmu_host{}", ["-lm", "-ldl"]),
              "win64": ([MINGW], "fmu_host{}.exe", [])}
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (folder / "ready").exists():
            for version in (2, 3):
                for compiler, binary, libraries in builds.values():
                    build = subprocess.run(compiler + ["-std=c99", "-O1", "-Wall", "-Wextra", "-Werror",
                                                       f"-I{FMI_HEADERS}"] + (["-DFMI3"] if version == 3 else [])
                                           + [str(HOST_SOURCE), "-o", str(folder / binary.format(version))]
                                           + libraries, capture_output=True, text=True)
                    assert build.returncode == 0, f"compiling the C host failed:\n{build.stderr}"
            # The prefix, made before the first run (which would make it otherwise), by a process whose output
            # goes nowhere: the Wine services it starts keep their standard streams open.
            boot = subprocess.run([wine, "wineboot", "--init"], env=env, stdin=subprocess.DEVNULL,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=300)
            assert boot.returncode == 0, "wineboot --init failed"
            (folder / "ready").touch()
    return {**{(version, "linux64"): ([str(folder / f"fmu_host{version}")], {}) for version in (2, 3)},
            **{(version, "win64"): ([wine, str(folder / f"fmu_host{version}.exe")], env) for version in (2, 3)}}


def _run(hosts, version, platform, directory, model, stop, step, values, outputs, state_time=None, guid=None):
    command, env = hosts[version, platform]
    where = f"Z:{directory}" if platform == "win64" else str(directory)
    args = command + [where, model, repr(stop), repr(step)]
    args += ["--state", repr(state_time)] if state_time is not None else []
    args += ["--guid", guid] if guid is not None else []
    args += [f"{vr}={value!r}" for vr, value in values.items()] + [str(vr) for vr in outputs]
    for attempt in (1, 2):
        # Output into files, not pipes: the Wine services a run starts inherit its standard streams and stay
        # until the wineserver ends, 3 s after its last client; reading pipes to their end would wait for that.
        with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
            code = subprocess.run(args, stdout=out, stderr=err, timeout=120, env=env).returncode
            stdout, stderr = (_text(stream) for stream in (out, err))
        clean = [line.rstrip("\r") for line in stderr.splitlines() if "[" in line or "fmu_host" in line]
        if code == 0 or platform != "win64" or stdout or clean or attempt == 2:
            break
        # Wine failed before the host said a word (a CI run once exited 1 with no output, the other xdist worker
        # running Wine at the same moment): run it again, once; a host's own failure always says something
    if code != 0 and not stdout and not clean:
        clean = [line.rstrip("\r") for line in stderr.splitlines()][-10:]  # then what Wine said, to read
    return code, [line.rstrip("\r") for line in stdout.splitlines()], clean


def _text(stream):
    stream.seek(0)
    return stream.read().decode(locale.getpreferredencoding(False))


WINDOWS_FOLDER = {2: "win64", 3: "x86_64-windows"}


def _extracted(path, tmp_path, version):
    directory = Path(fmpy.extract(str(path), unzipdir=str(tmp_path / path.stem)))
    assert (directory / "binaries" / WINDOWS_FOLDER[version] / f"{path.stem}.dll").is_file()
    description = fmpy.read_model_description(str(path))
    return directory, {v.name: v.valueReference for v in description.modelVariables}


def _rows(lines):
    """(the numeric rows of the first run, those after the restore, the '#' lines)."""
    restored = next(i for i, line in enumerate(lines) if line.startswith("# restored"))
    rows = [[float(word) for word in line.split()] for line in lines if not line.startswith("#")]
    before = sum(not line.startswith("#") for line in lines[:restored])  # the rows of the first run
    return np.array(rows[:before]), np.array(rows[before:]), [line for line in lines if line.startswith("#")]


CASES = [
    ("FrictionMass", 20.0, 0.1, {"F": 10.0, "omega": 1.0}, ["x", "v", "Ff", "Ic1", "Is1"], 10.0),
    ("FrictionMass", 10.0, 0.05, {"F": 6.0, "omega": 3.0}, ["x", "v", "Ff", "Ic1", "Is1"], 4.0),
    ("TwoMassBacklash", 1.0, 0.01, {"F": 50.0, "omega": 20.0, "eps": 0.5}, ["x1", "gap", "v2", "Ic1"], 0.5),
    ("TwoMassBacklash", 2.0, 0.02, {"F": 30.0, "omega": 25.0, "eps": 0.9}, ["x1", "x2", "gap", "Is1"], 1.0),
    ("StaticBacklash", 10.0, 0.05, {"F": 1.0, "omega": 2.0}, ["y", "v", "Is1"], 5.0),
]


@pytest.fixture(params=[2, 3], ids=["FMI2", "FMI3"])
def fmus_of_version(request, native_fmus, fmi3_fmus):
    """(FMI version, {model: path}) of the native FMUs of that version."""
    return request.param, (native_fmus if request.param == 2 else fmi3_fmus)


@pytest.mark.parametrize("model, stop, step, values, outputs, state_time", CASES)
def test_win64_binary_gives_the_linux64_numbers(fmus_of_version, hosts, tmp_path, model, stop, step, values, outputs,
                                                state_time):
    version, fmus = fmus_of_version
    directory, vr = _extracted(fmus[model], tmp_path, version)
    runs = {}
    for platform in ("linux64", "win64"):
        code, lines, log = _run(hosts, version, platform, directory, model, stop, step,
                                {vr[k]: v for k, v in values.items()}, [vr[name] for name in outputs], state_time)
        assert code == 0, (platform, log)
        first, again, notes = _rows(lines)
        np.testing.assert_array_equal(again, first[-len(again):], err_msg=f"{platform}: the restored run")
        runs[platform] = first, notes, log
    (linux, linux_notes, linux_log), (win, win_notes, win_log) = runs["linux64"], runs["win64"]
    assert win_notes == linux_notes and "status 3" in linux_notes[1]  # same state size; the cut state refused
    assert win_log == linux_log and len(linux) > 20
    assert win.shape == linux.shape
    np.testing.assert_array_equal(win[:, 0], linux[:, 0])  # the grid
    for k, name in enumerate(outputs, start=1):
        scale = np.max(np.abs(linux[:, k]))
        ulps = np.max(np.abs(win[:, k] - linux[:, k])) / np.spacing(scale) if scale else 0.0
        assert ulps <= ULP_BOUND, f"{model}.{name}: win64 and linux64 differ by {ulps:.0f} ulps of {scale:g}"


@pytest.mark.parametrize("model, values, words", [
    ("TwoMassBacklash", {"F": 50.0, "omega": 20.0, "eps": 1.5}, "eps = 1.5 is out of range"),
    ("FrictionMass", {"M": -1.0}, "M = -1.0"),
    ("StaticBacklash", {"k": -2.5e-7, "F": 1.0}, "k = -2.5e-07"),
])
def test_win64_refuses_as_linux64(fmus_of_version, hosts, tmp_path, model, values, words):
    """A refused parameter: the same exit, status and message (its numbers printed alike) on both platforms."""
    version, fmus = fmus_of_version
    directory, vr = _extracted(fmus[model], tmp_path, version)
    out = {platform: _run(hosts, version, platform, directory, model, 1.0, 0.1,
                          {vr[k]: v for k, v in values.items()}, [vr[next(iter(vr))]])
           for platform in ("linux64", "win64")}
    assert out["linux64"][0] == out["win64"][0] == 1
    assert out["linux64"][1] == out["win64"][1] == []
    assert out["win64"][2] == out["linux64"][2] and any(words in line for line in out["linux64"][2]), out


def _dll_table(path):
    """(exported names, imported DLL names) of a PE DLL, read by mingw-w64's objdump."""
    dump = subprocess.run([MINGW.replace("gcc", "objdump"), "-p", str(path)], capture_output=True, text=True,
                          check=True).stdout
    exports = re.findall(r"^\s*\[\s*\d+\]\s+(\w+)$", dump, re.M)
    return set(exports), set(re.findall(r"DLL Name: (\S+)", dump))


def test_pythonfmu_fmu_carries_the_shim_for_win64(fmus, native_fmus, hosts, tmp_path):
    directory, vr = _extracted(fmus["FrictionMass"], tmp_path, 2)
    shim = directory / "binaries" / "win64" / "FrictionMass.dll"
    inner = directory / "binaries" / "win64" / "FrictionMass.pythonfmu.dll"
    exports, imports = _dll_table(shim)
    native = _dll_table(_extracted(native_fmus["TwoMassBacklash"], tmp_path / "native", 2)[0] / "binaries" / "win64"
                        / "TwoMassBacklash.dll")[0]  # the 34 functions of FMI 2.0 co-simulation, as fmpy loads them
    assert exports == native and len(exports) == 34, exports ^ native
    assert imports == {"KERNEL32.dll", "msvcrt.dll"} and "python3.dll" in _dll_table(inner)[1]
    code, lines, log = _run(hosts, 2, "win64", directory, "FrictionMass", 1.0, 0.1, {}, [vr["x"]],
                            guid="{not-this-fmu}")
    assert code == 1 and lines == [] and any("fmuGUID {not-this-fmu} is not this FMU's guid" in line for line in log)
    code, lines, log = _run(hosts, 2, "win64", directory, "FrictionMass", 1.0, 0.1, {}, [vr["x"]])
    said = " ".join(log)
    assert code == 1 and "status 4" in said and "FrictionMass.pythonfmu.dll: Windows error 126" in said, log
