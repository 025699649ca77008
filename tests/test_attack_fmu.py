"""Attacks on the FMUs as a hostile or careless master: no crash, no hang, no code, errors are fmi2Error.

Every FMI-level test runs its calls in a fresh Python subprocess that does not
import dfwb (``HOST`` below, fmpy's ``FMU2Slave`` and raw ctypes calls into the
shim; a fork of ``SERVER``, which has imported fmpy once), so a segfault or an
abort is seen as the exit code. The crafted-state
tests drive the facade classes directly: the code inside the FMU is the same.

Found and fixed here (see the shim's docstring, point 4, and
``SolverFMU._check_solver_state``):

* fmi2FreeFMUstate(c, NULL) segfaulted; freeing a state twice released it twice
  (pythonfmu never sets ``*FMUstate`` to NULL); fmi2GetFMUstate(c, NULL)
  segfaulted; fmi2SetFMUstate(c, NULL) and fmi2DeSerializeFMUstate of more than
  PY_SSIZE_T_MAX bytes were fmi2Fatal (the instance lost for good).
* fmi2SerializeFMUstate with a buffer larger than the state read past pythonfmu's
  bytes (segfault with a large buffer), and with a smaller one truncated it and
  returned fmi2OK.
* fmi2SetString with a string that is not UTF-8 was fmi2Fatal; fmi2GetRealStatus
  (and the other status getters) with a NULL value segfaulted.
* fmi2Instantiate aborted the host (std::logic_error) for a NULL instanceName,
  segfaulted for an instanceName that is not UTF-8 and for a resource folder that
  is not the FMU's, ignored fmuGUID and fmuType, and failed for a percent-encoded
  (non-space) or ``file:/`` resource URI.
* A crafted state with well-typed but absurd solver contents was accepted: 10**9
  harmonics (13 s and 2 GB at the next setFMUstate with a start time), a
  LinearSystem of order 10**6 (hours at the next step of a new length), a solver
  time of -1e308 or a search chunk of 1e-300 s (endless search loops), a 10**100000
  event count (an fmi2Integer that cannot be converted).
* A 4 MiB pickle of one-byte opcodes built ~370 MB of objects before the check:
  the cap is now 256 kB (a real state is at most ~45 kB).
"""

import json
import math
import os
import pickle
import select
import shutil
import subprocess
import sys
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dfwb.fmi.simulation import unpacked
from dfwb.fmus import facade, state
from dfwb.fmus.contract import EventKind

pytestmark = pytest.mark.needs_cc

MODELS = ("FrictionMass", "TwoMassBacklash", "StaticBacklash", "LinearSystem")
OK, WARNING, DISCARD, ERROR, FATAL = range(5)

HOST = r'''
import ctypes, json, os, sys
from ctypes import byref, c_size_t, c_void_p
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2FMUstate, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                       fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE)

INFO = json.loads(os.environ["ATTACK_INFO"])  # {model: [unzipped folder, guid]}
LOG, KEEP, OUT = [], [], {}


def callbacks(kind="full"):
    cb = fmi2CallbackFunctions()
    if kind in ("full", "logger only"):
        cb.logger = fmi2CallbackLoggerTYPE(
            lambda env, inst, status, cat, msg: LOG.append((status, msg.decode("utf-8", "replace"))))
    if kind == "full":
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    KEEP.append(cb)
    return cb


def make(model="FrictionMass", name="attack", kind="full"):
    folder, guid = INFO[model]
    fmu = FMU2Slave(guid=guid, unzipDirectory=folder, modelIdentifier=model, instanceName=name)
    fmu.instantiate(loggingOn=True, callbacks=callbacks(kind))
    KEEP.append(fmu)
    return fmu


def st(fmu, name, *args):
    try:
        getattr(fmu, name)(*args)
        return 0
    except FMICallException as error:
        return error.status


def raw(fmu, name):
    return getattr(fmu.dll, name)


def init(fmu, t0=0.0):
    assert [st(fmu, "setupExperiment", None, t0), st(fmu, "enterInitializationMode"),
            st(fmu, "exitInitializationMode")] == [0, 0, 0], LOG


def instantiate(model="FrictionMass", name=b"attack", fmu_type=1, guid=None, uri=None, functions="full"):
    folder, real_guid = INFO[model]
    fmu = FMU2Slave(guid=real_guid, unzipDirectory=folder, modelIdentifier=model, instanceName="x")
    function = raw(fmu, "fmi2Instantiate")
    function.restype = c_void_p
    location = ("file://" + folder + "/resources").encode() if uri is None else uri
    pointer = None if functions is None else byref(callbacks(functions))
    component = function(name, fmu_type, real_guid.encode() if guid is None else guid, location, pointer, 0, 1)
    if component:
        fmu.component = component
        KEEP.append(fmu)
    return fmu if component else None
'''


@pytest.fixture(scope="module")
def info(fmus):
    """{model: [unzipped folder, guid]} of the production FMUs, for the host subprocesses."""
    table = {}
    for model in MODELS:
        folder, description = unpacked(fmus[model])
        table[model] = [str(folder), description.guid]
    return table


# The host processes are forks of one Python that has imported what HOST imports (fmpy: 0.3 s of CPU a process,
# 60 processes): each request is a script run as ``python -c script`` runs it, in a child forked for it alone, with
# the request's environment, stdin /dev/null, stdout and stderr into files, SIGALRM after the timeout; it ends as
# that Python does (a traceback and exit code 1, or the interpreter finalized), and the server answers its exit code
# (-N: killed by signal N). No FMU is loaded before the fork: every host loads the FMUs afresh, as before.
SERVER = r'''
import json, os, signal, sys
import ctypes, fmpy.fmi1, fmpy.fmi2

for line in sys.stdin:
    request = json.loads(line)
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        break
    print(json.dumps(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])), flush=True)
else:
    sys.exit(0)
os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
for fd, path in ((1, request["stdout"]), (2, request["stderr"])):
    os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), fd)
os.environ.clear()
os.environ.update(request["env"])
signal.alarm(request["timeout"])
exec(compile(request.pop("script"), "<string>", "exec"), {"__name__": "__main__", "__builtins__": __builtins__})
'''


@pytest.fixture(scope="module")
def host(info, tmp_path_factory):
    """run(code, timeout=120): HOST + code in a fresh Python process (no dfwb); (exit code, OUT as a dict, stderr)."""
    folder = tmp_path_factory.mktemp("hosts")
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    server = subprocess.Popen([sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True, env=env)
    count = 0

    def run(code, timeout=120):
        nonlocal count
        count += 1
        stdout, stderr = folder / f"{count}.out", folder / f"{count}.err"
        env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
        env["ATTACK_INFO"] = json.dumps(info)
        script = HOST + code + "\nprint(json.dumps(OUT))\n"
        server.stdin.write(json.dumps({"script": script, "env": env, "timeout": timeout, "stdout": str(stdout),
                                       "stderr": str(stderr)}) + "\n")
        server.stdin.flush()
        ready, _, _ = select.select([server.stdout], [], [], timeout + 60)
        answer = server.stdout.readline() if ready else ""
        if not answer:
            server.kill()
            raise RuntimeError(f"the host server did not answer (exit code {server.poll()})")
        returncode = json.loads(answer)
        lines = stdout.read_text().strip().splitlines()
        out = json.loads(lines[-1]) if returncode == 0 and lines else None
        return returncode, out, stderr.read_text()

    yield run
    server.stdin.close()
    server.wait(timeout=60)


def _ok(result):
    code, out, stderr = result
    assert code == 0, f"the host died with exit code {code}:\n{stderr[-3000:]}"
    return out


# -- FMU state pointers -----------------------------------------------------------------

def test_state_pointers_null_freed_twice(host):
    out = _ok(host('''
fmu = make(); init(fmu)
state = fmu.getFMUstate()
OUT["free"] = st(fmu, "freeFMUstate", state)
OUT["nulled"] = state.value is None
OUT["free again"] = st(fmu, "freeFMUstate", state)          # *FMUstate is NULL now: ignored
OUT["step"] = st(fmu, "doStep", 0.0, 0.1)
size = c_size_t()
OUT["size of freed"] = raw(fmu, "fmi2SerializedFMUstateSize")(fmu.component, state, byref(size))
OUT["reset 1"] = st(fmu, "reset")
OUT["free NULL pointer"] = raw(fmu, "fmi2FreeFMUstate")(fmu.component, None)
OUT["reset 2"] = st(fmu, "reset")
OUT["get NULL pointer"] = raw(fmu, "fmi2GetFMUstate")(fmu.component, None)
OUT["reset 3"] = st(fmu, "reset")
init(fmu)
OUT["set NULL"] = raw(fmu, "fmi2SetFMUstate")(fmu.component, None)
OUT["step in error"] = st(fmu, "doStep", 0.0, 0.1)
OUT["reset 4"] = st(fmu, "reset")
init(fmu)
OUT["step after"] = st(fmu, "doStep", 0.0, 0.1)
OUT["fatal"] = [text for status, text in LOG if status == 4]
fmu.freeInstance()
'''))
    assert out == {"free": OK, "nulled": True, "free again": OK, "step": OK, "size of freed": ERROR,
                   "reset 1": OK, "free NULL pointer": ERROR, "reset 2": OK, "get NULL pointer": ERROR,
                   "reset 3": OK, "set NULL": ERROR, "step in error": ERROR, "reset 4": OK, "step after": OK,
                   "fatal": []}


def test_serialize_into_a_buffer_of_the_wrong_size(host):
    out = _ok(host('''
fmu = make(); init(fmu); fmu.doStep(0.0, 0.1)
state = fmu.getFMUstate()
exact = fmu.serializeFMUstate(state)
big = ctypes.create_string_buffer(len(exact) + (64 << 20))     # 64 MiB more than the state
OUT["big"] = raw(fmu, "fmi2SerializeFMUstate")(fmu.component, state, big, c_size_t(len(big)))
OUT["same bytes"] = big.raw[:len(exact)] == exact and big.raw[len(exact):len(exact) + 4096] == bytes(4096)
small = ctypes.create_string_buffer(10)
OUT["small"] = raw(fmu, "fmi2SerializeFMUstate")(fmu.component, state, small, c_size_t(10))
OUT["message"] = LOG[-1][1]
OUT["null buffer"] = raw(fmu, "fmi2SerializeFMUstate")(fmu.component, state, None, c_size_t(len(exact)))
'''))
    assert out["big"] == OK and out["same bytes"]
    assert out["small"] == ERROR and "a buffer of 10 bytes, but the state needs" in out["message"]
    assert out["null buffer"] == ERROR


def test_deserialize_bad_arguments(host):
    out = _ok(host('''
fmu = make(); init(fmu)
deserialize = raw(fmu, "fmi2DeSerializeFMUstate")
target = fmi2FMUstate()
OUT["huge size"] = deserialize(fmu.component, b"x", c_size_t(2**63 + 5), byref(target))
OUT["reset 1"] = st(fmu, "reset")
OUT["NULL bytes"] = deserialize(fmu.component, None, c_size_t(100), byref(target))
OUT["reset 2"] = st(fmu, "reset")
OUT["NULL state pointer"] = deserialize(fmu.component, b"abc", c_size_t(3), None)
OUT["reset 3"] = st(fmu, "reset")
init(fmu)
OUT["step"] = st(fmu, "doStep", 0.0, 0.1)
OUT["statuses"] = sorted({status for status, _ in LOG})
'''))
    assert out == {"huge size": ERROR, "reset 1": OK, "NULL bytes": ERROR, "reset 2": OK,
                   "NULL state pointer": ERROR, "reset 3": OK, "step": OK,
                   "statuses": [OK, ERROR]}  # OK: the plant says which solver it runs on


def test_states_across_instances_and_models(host):
    out = _ok(host('''
a, b, other = make(name="a"), make(name="b"), make("LinearSystem", name="c")
for fmu in (a, b, other):
    init(fmu)
a.doStep(0.0, 0.1); a.doStep(0.1, 0.1)
from_a = a.getFMUstate()
OUT["b takes a's state"] = st(b, "setFMUstate", from_a)
OUT["b steps from a's time"] = st(b, "doStep", 0.2, 0.1)
OUT["same as a"] = (a.doStep(0.2, 0.1), list(a.getReal([0, 1, 2, 3])))[1] == list(b.getReal([0, 1, 2, 3]))
OUT["another model's state"] = st(other, "setFMUstate", from_a)
OUT["message"] = LOG[-1][1]
OUT["serialized into the other model"] = st(other, "deSerializeFMUstate", a.serializeFMUstate(from_a))
OUT["a free in b"] = st(b, "freeFMUstate", from_a)
terminated = make(name="t"); init(terminated); terminated.terminate()
OUT["deserialize into terminated"] = st(terminated, "deSerializeFMUstate", a.serializeFMUstate(a.getFMUstate()))
OUT["free NULL instance"] = raw(a, "fmi2FreeInstance")(None)
for fmu in (a, b, other, terminated):
    fmu.freeInstance()
OUT["fatal"] = [text for status, text in LOG if status == 4]
'''))
    assert out["b takes a's state"] == OK and out["b steps from a's time"] == OK and out["same as a"]
    assert out["another model's state"] == ERROR and "not of this FMU" in out["message"]
    assert out["serialized into the other model"] == ERROR
    assert out["a free in b"] == OK and out["deserialize into terminated"] == OK and out["fatal"] == []


# -- fmi2Instantiate's arguments ------------------------------------------------------------

def test_instantiate_arguments(info, host, tmp_path):
    folder = info["FrictionMass"][0]
    odd = tmp_path / "a b" / "ü дир %41"
    odd.parent.mkdir()
    os.symlink(folder, odd)
    quoted = "file://" + "/".join(__import__("urllib.parse").parse.quote(part) for part in str(odd).split("/"))
    out = _ok(host(f'''
def runs(fmu):
    if fmu is None:
        return None
    init(fmu)
    return st(fmu, "doStep", 0.0, 0.1)

cases = {{
    "name NULL": dict(name=None), "name empty": dict(name=b""), "name not UTF-8": dict(name=b"\\xff\\xfe\\xed\\xa0\\x80"),
    "name 1 MB": dict(name=b"%n%s" * 250000), "model exchange": dict(fmu_type=0),
    "wrong GUID": dict(guid=b"{{00000000-0000-0000-0000-000000000000}}"),
    "GUID printf": dict(guid=b"%n%s%999999d" * 1000), "GUID not UTF-8": dict(guid=b"\\xff" * 1000000),
    "GUID NULL": dict(guid=b""),
    "no callbacks, bad GUID": dict(guid=b"{{x}}", functions=None),
    "no logger, bad GUID": dict(guid=b"{{x}}", functions="none"),
    "no allocator": dict(functions="logger only"),
    "no callbacks at all": dict(functions=None),
    "resources NULL": dict(uri=b""), "http": dict(uri=b"http://example.com/resources"),
    "missing folder": dict(uri=b"file:///nonexistent/resources"),
    "file:/": dict(uri=b"file:" + INFO["FrictionMass"][0].encode() + b"/resources"),
    "localhost": dict(uri=b"file://localhost" + INFO["FrictionMass"][0].encode() + b"/resources"),
    "percent-encoded unicode": dict(uri={quoted!r}.encode() + b"/resources"),
}}
for label, kwargs in cases.items():
    if kwargs.get("uri") == b"":
        kwargs["uri"] = None
        folder, guid = INFO["FrictionMass"]
        probe = FMU2Slave(guid=guid, unzipDirectory=folder, modelIdentifier="FrictionMass", instanceName="x")
        function = raw(probe, "fmi2Instantiate"); function.restype = c_void_p
        OUT[label] = bool(function(b"x", 1, guid.encode(), None, byref(callbacks()), 0, 1))
        continue
    if kwargs.get("guid") == b"":
        kwargs["guid"] = None
        folder, guid = INFO["FrictionMass"]
        probe = FMU2Slave(guid=guid, unzipDirectory=folder, modelIdentifier="FrictionMass", instanceName="x")
        function = raw(probe, "fmi2Instantiate"); function.restype = c_void_p
        OUT[label] = bool(function(b"x", 1, None, ("file://" + folder + "/resources").encode(),
                                   byref(callbacks()), 0, 1))
        continue
    OUT[label] = runs(instantiate(**kwargs))
OUT["printf doubled"] = any("%%n%%s%%999999d" in text for _, text in LOG)
'''))
    started = {label: out.pop(label) for label in list(out) if label != "printf doubled"}
    assert started == {
        "name NULL": OK, "name empty": OK, "name not UTF-8": OK, "name 1 MB": OK, "model exchange": None,
        "wrong GUID": None, "GUID printf": None, "GUID not UTF-8": None, "GUID NULL": False,
        "no callbacks, bad GUID": None, "no logger, bad GUID": None, "no allocator": OK, "no callbacks at all": OK,
        "resources NULL": False, "http": None, "missing folder": None, "file:/": OK, "localhost": OK,
        "percent-encoded unicode": OK}
    assert out["printf doubled"]


def test_errors_without_a_logger(host):
    """A host without a logger (the standard requires one): refused calls are still fmi2Error, no crash."""
    out = _ok(host('''
fmu = instantiate(functions=None)
init(fmu)
OUT["bad input"] = st(fmu, "setReal", [7], [float("nan")])
OUT["step"] = st(fmu, "doStep", 0.0, 0.1)
OUT["reset"] = st(fmu, "reset")
fmu.freeInstance()
'''))
    assert out == {"bad input": ERROR, "step": ERROR, "reset": OK}


def test_odd_arguments_of_other_calls(host):
    out = _ok(host('''
from ctypes import c_char_p, c_uint
fmu = make(); init(fmu)
set_string = raw(fmu, "fmi2SetString")
for label, text in (("string not UTF-8", b"\\xff\\xfe"), ("string NULL", None)):
    OUT[label] = set_string(fmu.component, (c_uint * 1)(0), c_size_t(1), (c_char_p * 1)(text))
    OUT[label + ", reset"] = st(fmu, "reset"); init(fmu)
OUT["getReal NULL array"] = raw(fmu, "fmi2GetReal")(fmu.component, None, c_size_t(3), None)
OUT["getReal NULL array, reset"] = st(fmu, "reset"); init(fmu)
for function in ("fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus",
                 "fmi2GetStringStatus"):
    OUT[function] = raw(fmu, function)(fmu.component, 2, None)
OUT["reset"] = st(fmu, "reset"); init(fmu)
n = 300000
OUT["setBoolean, 300000 references"] = st(fmu, "setBoolean", list(range(n)), [True] * n)
OUT["fatal"] = [text for status, text in LOG if status == 4]
'''))
    assert out == {"string not UTF-8": ERROR, "string not UTF-8, reset": OK, "string NULL": ERROR,
                   "string NULL, reset": OK, "getReal NULL array": ERROR, "getReal NULL array, reset": OK,
                   "fmi2GetStatus": ERROR, "fmi2GetRealStatus": ERROR, "fmi2GetIntegerStatus": ERROR,
                   "fmi2GetBooleanStatus": ERROR, "fmi2GetStringStatus": ERROR, "reset": OK,
                   "setBoolean, 300000 references": ERROR, "fatal": []}


def test_fifty_instances_interleaved(host):
    out = _ok(host('''
import itertools
models = list(INFO)
fmus = [make(models[i % len(models)], name=f"i{i}") for i in range(50)]
for fmu in fmus:
    init(fmu)
statuses = set()
for k in range(5):
    for fmu in fmus:
        statuses.add(st(fmu, "doStep", k * 0.1, 0.1))
states = [fmu.getFMUstate() for fmu in fmus]
for fmu, state in zip(fmus, reversed(states)):
    statuses.add(st(fmu, "setFMUstate", state))   # half of them another model's: refused
for fmu in fmus:
    statuses.add(st(fmu, "reset"))
for fmu, state in zip(fmus, states):
    statuses.add(st(fmu, "freeFMUstate", state))
for fmu in fmus:
    fmu.freeInstance()
OUT["statuses"] = sorted(statuses)
'''))
    assert out["statuses"] == [OK, ERROR]


# -- random call sequences --------------------------------------------------------------------

SEQUENCE = r'''
import math, random
ops = json.loads(os.environ["ATTACK_OPS"])
models = list(INFO)
alive, states, blobs = [], [], []
VRS = [0, 1, 5, 7, 8, 9, 12, 40, 200, 0x7FFFFFFF, 0xFFFFFFFF, 0x80000000]
REALS = [0.0, 1.0, -5.0, 1e300, float("nan"), float("inf"), -float("inf"), 1e-320]
INTS = [-1, 0, 3, 10, 11, 2**31 - 1, -2**31]
TIMES = [0.0, 0.1, 2.0, -1.0, float("nan"), float("inf"), 1e308, -1e308]
STEPS = [0.1, 0.0, -0.1, float("nan"), float("inf"), 1e300, 1e-300, 5e-324]
bad = []
for i, (op, a, b) in enumerate(ops):
    print(i, op, a, b, file=sys.stderr, flush=True)
    if op == "new" or not alive:
        if len(alive) < 50:
            alive.append([make(models[a % len(models)], name=f"n{i}"), 0.0])
        continue
    fmu, t = alive[a % len(alive)]
    entry = alive[a % len(alive)]
    if op == "free":
        alive.remove(entry)
        states[:] = [s for s in states if s[0] is not fmu]
        fmu.freeInstance()
        continue
    if op == "setup":
        s = st(fmu, "setupExperiment", None, TIMES[b % len(TIMES)])
        if s == 0:
            entry[1] = TIMES[b % len(TIMES)]
    elif op == "init":  # reset, then initialise at t = 0
        s = max(st(fmu, "reset"), st(fmu, "setupExperiment", None, 0.0), st(fmu, "enterInitializationMode"),
                st(fmu, "exitInitializationMode"))
        if s == 0:
            entry[1] = 0.0
            OUT["initialised"] = OUT.get("initialised", 0) + 1
    elif op == "enter":
        s = st(fmu, "enterInitializationMode")
    elif op == "exit":
        s = st(fmu, "exitInitializationMode")
    elif op == "step":
        h = STEPS[b % len(STEPS)] if b % 2 else 0.05  # half of the steps good ones
        now = t if b % 5 else [t + 1.0, float("nan"), -t][b % 3]
        s = st(fmu, "doStep", now, h)
        if s == 0:
            entry[1] = t + h
            OUT["steps"] = OUT.get("steps", 0) + 1
    elif op == "getReal":
        s = st(fmu, "getReal", [VRS[b % len(VRS)]])
    elif op == "getInteger":
        s = st(fmu, "getInteger", [VRS[b % len(VRS)]])
    elif op == "setReal":
        s = st(fmu, "setReal", [VRS[b % len(VRS)]], [REALS[(b // 7) % len(REALS)]])
    elif op == "setInteger":
        s = st(fmu, "setInteger", [VRS[b % len(VRS)]], [INTS[(b // 7) % len(INTS)]])
    elif op == "terminate":
        s = st(fmu, "terminate")
    elif op == "reset":
        s = st(fmu, "reset")
    elif op == "getState":
        state = fmi2FMUstate()
        s = raw(fmu, "fmi2GetFMUstate")(fmu.component, byref(state))
        if s == 0:
            states.append((fmu, state))
    elif op == "setState":
        if not states:
            continue
        s = st(fmu, "setFMUstate", states[b % len(states)][1])
    elif op == "freeState":
        if not states:
            continue
        owner, state = states.pop(b % len(states))
        s = st(owner, "freeFMUstate", state)
        s2 = st(owner, "freeFMUstate", state)      # twice: ignored
        if s2:
            bad.append((i, op, "second free", s2))
    elif op == "serialize":
        if not states:
            continue
        owner, state = states[b % len(states)]
        try:
            blobs.append(owner.serializeFMUstate(state))
            s = 0
        except FMICallException as error:
            s = error.status
    elif op == "deserialize":
        if not blobs:
            continue
        blob = bytearray(blobs[b % len(blobs)])
        if b % 3 == 1:
            blob[(b * 7919) % len(blob)] ^= 1 << (b % 8)
        elif b % 3 == 2:
            blob = blob[: (b * 31) % len(blob)]
        target = fmi2FMUstate()
        s = raw(fmu, "fmi2DeSerializeFMUstate")(fmu.component, bytes(blob), c_size_t(len(blob)), byref(target))
        if s == 0:
            states.append((fmu, target))
    else:
        continue
    if s not in (0, 3):
        bad.append((i, op, a, b, s))
for fmu, _ in alive:
    fmu.freeInstance()
OUT["bad"] = bad
OUT["fatal"] = [text for status, text in LOG if status == 4][:5]
'''

OPS = st.sampled_from(["new", "free", "init", "init", "reset", "setup", "enter", "exit", "step", "step", "step", "getReal", "getInteger",
                       "setReal", "setInteger", "terminate", "reset", "getState", "setState", "freeState",
                       "serialize", "deserialize"])


@settings(max_examples=int(os.environ.get("DFWB_ATTACK_EXAMPLES", "12")), deadline=None, suppress_health_check=list(HealthCheck))
def _run_sequence(host, ops):
    """Run the call sequence ``ops`` in a host subprocess; it must exit 0 with every status OK or Error."""
    os.environ["ATTACK_OPS"] = json.dumps(ops)
    try:
        code, out, stderr = host(SEQUENCE, timeout=60)
    finally:
        del os.environ["ATTACK_OPS"]
    said = "\n".join(line for line in stderr.splitlines() if not line[:1].isdigit())  # not the trace of calls
    assert code == 0, f"the host died ({code}) at:\n{stderr[-1500:]}\nand said:\n{said[-1500:]}"
    assert out["bad"] == [] and out["fatal"] == [], out
    return out


@pytest.mark.slow
@given(st.lists(st.tuples(OPS, st.integers(0, 1000), st.integers(0, 1000)), min_size=20, max_size=400))
def test_random_call_sequences(host, ops):
    """Random FMI call sequences over up to 50 instances of every model: every status is OK or Error."""
    _run_sequence(host, ops)


@pytest.mark.parametrize("seed", range(3))
def test_long_random_call_sequences(host, seed):
    """1500 calls of a seeded random sequence: every status OK or Error, and the sequence did step."""
    rng = __import__("random").Random(seed)
    names = sorted(set(OPS.wrapped_strategy.elements if hasattr(OPS, "wrapped_strategy") else OPS.elements))
    weights = [{"step": 30, "init": 6, "reset": 6, "new": 1, "free": 1}.get(name, 2) for name in names]
    ops = [(rng.choices(names, weights)[0], rng.randrange(1001), rng.randrange(1001)) for _ in range(1500)]
    out = _run_sequence(host, ops)
    assert out.get("steps", 0) > 10 and out.get("initialised", 0) > 10, out


# -- crafted states (the facade's code, the same inside the FMU) ---------------------------

def _stepped(model_class, start_time=0.0, **values):
    fmu = model_class(instance_name="attack")
    fmu.setup_experiment(start_time)
    fmu.enter_initialization_mode()
    for name, value in values.items():
        setattr(fmu, name, value)
    fmu.exit_initialization_mode()
    assert fmu.do_step(start_time, 0.1), fmu
    return fmu


def _crafted(model_class, tamper, start_time=0.0, **values):
    """A state of model_class tampered with, serialized and deserialized; (instance it was set into, refused?)."""
    source = _stepped(model_class, start_time, **values)
    saved = source._get_fmu_state()
    tamper(saved)
    data = model_class._fmu_state_to_bytes(saved)
    restored = model_class._fmu_state_from_bytes(data)
    target = model_class(instance_name="target")
    started = time.monotonic()
    target._set_fmu_state(restored)
    refused = target._phase == facade.ERROR
    if not refused:  # accepted: the next step must be clean and quick
        target.do_step(saved.values["_time"], 0.37)
        target.get_real(list(range(6)))
    assert time.monotonic() - started < 10.0
    return target, refused


def _set(path, value):
    def tamper(saved):
        obj = saved
        *names, last = path.split(".")
        for name in names:
            obj = getattr(obj, name)
        setattr(obj, last, value)
    return tamper


@pytest.mark.parametrize("label, model, tamper, start", [
    ("10**9 harmonics", facade.FrictionMass, _set("solver.harmonics", 10**9), 0.0),
    ("10**9 harmonics, start time 1", facade.FrictionMass, _set("solver.harmonics", 10**9), 1.0),
    ("order 10**6", facade.LinearSystem, _set("solver.order", 10**6), 0.0),
    ("t = -1e308", facade.FrictionMass, _set("solver.t", -1e308), 0.0),
    ("piece start -1e308", facade.TwoMassBacklash, _set("solver._t_piece", -1e308), 0.0),
    ("searched -1e308", facade.StaticBacklash, _set("solver._searched", -1e308), 0.0),
    ("period 1e-300", facade.FrictionMass, _set("solver.period", 1e-300), 0.0),
    ("huge event count", facade.FrictionMass, _set("solver.events", 10**100000), 0.0),
    ("mass changed", facade.FrictionMass, _set("solver.M", 1e-300), 0.0),
    ("omega changed", facade.TwoMassBacklash, _set("solver.drive.omega", 1e-300), 0.0),
    ("short integrals", facade.FrictionMass, _set("solver._integrals", [0j]), 0.0),
    ("state vector too long", facade.LinearSystem, _set("solver.x", [0.0] * 100), 0.0),
])
def test_crafted_solver_contents_are_refused(label, model, tamper, start):
    values = {"F": 10.0} if model is not facade.LinearSystem else {}
    target, refused = _crafted(model, tamper, start, **values)
    assert refused, label


@pytest.mark.parametrize("label, tamper", [
    ("inf in a motion", _set("solver._output.x0", math.inf)),
    ("inf input", _set("solver.drive.f", math.inf)),
])
def test_crafted_motion_values_fail_cleanly(label, tamper):
    """Well-typed wrong numbers may be accepted; the next step is then a clean error (or finite)."""
    target, refused = _crafted(facade.FrictionMass, tamper, F=10.0)
    assert refused or target._phase in (facade.ERROR, facade.STEPPING)
    assert all(math.isfinite(value) for value in target.get_real(list(range(12))))


def _framed(model_class, payload):
    """A crafted payload with a well-formed header (its checksum made to match): read by the unpickler."""
    return state.frame(model_class.__name__, model_class._package(), payload)


@pytest.mark.parametrize("label, payload", [
    ("many tiny objects", b"\x80\x04(" + b"\x8f" * (4 << 20) + b"l}\x86."),
    ("memo references", b"\x80\x04]\x94" + b"h\x00" * (2 << 20) + b"."),
    ("nested 100000 deep", b"\x80\x04" + b"]" * 100000 + b"a" * 99999 + b"}\x86."),
    ("unclosed marks", b"\x80\x04" + b"(" * 1000000 + b"."),
    ("extension code", b"\x80\x04\x82\x01."),
    ("huge int", b"\x80\x04\x8b" + (200000).to_bytes(4, "little") + b"\xff" * 200000 + b"."),
    ("persistent id", b"\x80\x04\x8c\x01x\x94Q."),
    ("out-of-band buffer", b"\x80\x05\x97."),
    ("bogus EventKind", b"\x80\x04}\x8c" + bytes([len(EventKind.__module__)]) + EventKind.__module__.encode()
     + b"\x8c\tEventKind\x93\x8c\x05bogus\x85R\x86."),
])
def test_crafted_pickles_are_refused_quickly(label, payload):
    started = time.monotonic()
    restored = facade.FrictionMass._fmu_state_from_bytes(_framed(facade.FrictionMass, payload))
    assert isinstance(restored, state.RefusedState), label
    assert time.monotonic() - started < 10.0


def test_build_opcode_cannot_add_attributes():
    """BUILD with a slot state on a class with __slots__ only: a name that is not a slot is refused."""
    fmu = _stepped(facade.FrictionMass, F=10.0)
    good = fmu._fmu_state_to_bytes(fmu._get_fmu_state())
    head, payload = good.split(b"\n", 2)[1:]
    loaded = pickle.loads(payload)
    module = type(loaded[1].drive).__module__.encode()
    evil = (b"\x80\x04\x8c" + bytes([len(module)]) + module + b"\x8c\x05Drive\x93)\x81"
            b"N}\x8c\x08__dict__}s\x86b}\x86.")
    restored = facade.FrictionMass._fmu_state_from_bytes(_framed(facade.FrictionMass, evil))
    assert isinstance(restored, state.RefusedState)


def test_a_large_state_is_capped():
    assert state.MAX_BYTES <= 1 << 18
    data = _framed(facade.FrictionMass, b"\x80\x04" + b"]" * state.MAX_BYTES)
    restored = facade.FrictionMass._fmu_state_from_bytes(data)
    assert isinstance(restored, state.RefusedState) and "larger than" in restored.refused


@pytest.mark.parametrize("model", [facade.FrictionMass, facade.TwoMassBacklash, facade.StaticBacklash,
                                   facade.LinearSystem])
@pytest.mark.parametrize("start", [0.0, 2.5])
def test_genuine_states_pass_the_new_checks(model, start):
    values = {"F": 30.0, "omega": 7.0} if model is not facade.LinearSystem else {"order": 2, "a2": 4.0, "b2": 1.0}
    fmu = _stepped(model, start, **values)
    for k in range(1, 40):
        fmu.do_step(fmu._time, 0.05 * k)
        saved = model._fmu_state_from_bytes(model._fmu_state_to_bytes(fmu._get_fmu_state()))
        twin = model(instance_name="twin")
        twin._set_fmu_state(saved)
        assert twin._phase == facade.STEPPING, k


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind (.ci/run installs it)")
def test_a_python_host_exits_without_touching_freed_memory(info, tmp_path):
    """pythonfmu 0.7.0 releases its interpreter state twice at exit, the second time in freed memory (a
    host aborted at exit, now and then); the shim releases it once before. valgrind sees the use after
    free in every run where it happens, so this fails every time the shim does not."""
    script = tmp_path / "host.py"
    script.write_text(HOST + "for model in INFO:\n    make(model, name='exit').freeInstance()\n"
                      "print(json.dumps(OUT))\n")
    log = tmp_path / "valgrind.log"
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    env.update(ATTACK_INFO=json.dumps(info), PYTHONMALLOC="malloc")
    done = subprocess.run(["valgrind", "--error-limit=no", f"--log-file={log}", sys.executable, str(script)],
                          capture_output=True, text=True, timeout=600, env=env)
    assert done.returncode == 0, done.stderr[-1500:]
    text = log.read_text()
    assert "ERROR SUMMARY" in text  # valgrind ran the host to its end
    assert "finalizePythonInterpreter" not in text, text[text.find("finalizePythonInterpreter") - 300:][:2500]
