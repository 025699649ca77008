"""The native plant FMUs under attack: what a hostile or sloppy FMI importer does to them.

The binaries are driven through ctypes as a C importer would drive them (NULL components, arrays and
callbacks, valueReferences out of range, every call in every phase, NaN/inf/huge/denormal values, steps
and start times out of scale, a failing allocator, FMU states set across instances and models, freed twice,
serialized into short buffers, deserialized from truncated, extended, bit-flipped, random and
checksum-fixed crafted bytes). Standard: a correct result or a refusal (fmi2Error with one logged error),
never a crash, a hang, a NaN output or a leak. What could crash runs in a subprocess, so that a crash fails
the test instead of killing pytest; the subprocess reports its findings as JSON.

Found and fixed in fmus/native/fmu/fmi2_plant.c (these tests failed before):
- an FMU state of another model (FrictionMass's given to TwoMassBacklash) was read as this model's:
  heap overflow reads, and fmi2FreeFMUstate freed a solver of the wrong type;
- an Integer output beyond 32 bits (the events or impacts counter of a crafted state or of a run of more
  than 2**31 events) was cast to fmi2Integer: undefined behaviour, a negative count in practice.
"""

import json
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path

import fmpy
import pytest
from conftest import new_instance

pytestmark = pytest.mark.needs_cc

MODELS = ("FrictionMass", "TwoMassBacklash", "StaticBacklash")


def extracted(path, tmp_path):
    """(the .so of an FMU extracted under tmp_path, its GUID, {name: [vr, integer, causality]})."""
    folder = tmp_path / path.stem
    with zipfile.ZipFile(path) as archive:
        archive.extractall(folder)
    description = fmpy.read_model_description(str(path))
    table = {v.name: [v.valueReference, v.type == "Integer", v.causality] for v in description.modelVariables}
    return str(folder / "binaries" / "linux64" / f"{path.stem}.so"), description.guid, table


# The importer from hell, run in a subprocess: argv = JSON [[so, guid, variables], ...] (the first is attacked,
# a second one lends its states), then what to run. Prints JSON {"problems": [...], "counts": {...}}.
ATTACK = r'''
import ctypes as C, json, math, random, struct, sys, time, zlib

models = json.loads(sys.argv[1])
what = sys.argv[2].split(",")
libc = C.CDLL(None)
libc.calloc.restype = C.c_void_p
libc.calloc.argtypes = [C.c_size_t, C.c_size_t]
libc.free.argtypes = [C.c_void_p]
LOGGER = C.CFUNCTYPE(None, C.c_void_p, C.c_char_p, C.c_int, C.c_char_p, C.c_char_p)
ALLOC = C.CFUNCTYPE(C.c_void_p, C.c_size_t, C.c_size_t)
FREE = C.CFUNCTYPE(None, C.c_void_p)


class Callbacks(C.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", ALLOC), ("freeMemory", FREE), ("stepFinished", C.c_void_p),
                ("componentEnvironment", C.c_void_p)]


log = []
problems = []
counts = {}
live = [0]
fail_after = [None]  # the allocator fails once this many more allocations were made


def problem(text):
    if len(problems) < 50:
        problems.append(text)


@LOGGER
def logger(env, name, status, category, message):
    log.append((status, message.decode("utf-8", "replace")))


@ALLOC
def allocate(n, size):
    if fail_after[0] is not None:
        if fail_after[0] <= 0:
            return None
        fail_after[0] -= 1
    live[0] += 1
    return libc.calloc(n, size)


@FREE
def release(p):
    if p:
        live[0] -= 1
    libc.free(p)


CALLBACKS = Callbacks(logger, allocate, release, None, None)
SILENT = Callbacks(LOGGER(), allocate, release, None, None)
Component, State, VR, Real, Int = C.c_void_p, C.c_void_p, C.c_uint, C.c_double, C.c_int
SIGNATURES = {
    "Instantiate": (Component, [C.c_char_p, C.c_int, C.c_char_p, C.c_char_p, C.c_void_p, C.c_int, C.c_int]),
    "FreeInstance": (None, [Component]),
    "SetupExperiment": (C.c_int, [Component, C.c_int, Real, Real, C.c_int, Real]),
    "EnterInitializationMode": (C.c_int, [Component]), "ExitInitializationMode": (C.c_int, [Component]),
    "DoStep": (C.c_int, [Component, Real, Real, C.c_int]), "Terminate": (C.c_int, [Component]),
    "Reset": (C.c_int, [Component]), "CancelStep": (C.c_int, [Component]),
    "SetDebugLogging": (C.c_int, [Component, C.c_int, C.c_size_t, C.c_void_p]),
    "GetReal": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "GetInteger": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "GetBoolean": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "GetString": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "SetReal": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "SetInteger": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "SetBoolean": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "SetString": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "GetFMUstate": (C.c_int, [Component, C.c_void_p]), "SetFMUstate": (C.c_int, [Component, State]),
    "FreeFMUstate": (C.c_int, [Component, C.c_void_p]),
    "SerializedFMUstateSize": (C.c_int, [Component, State, C.c_void_p]),
    "SerializeFMUstate": (C.c_int, [Component, State, C.c_void_p, C.c_size_t]),
    "DeSerializeFMUstate": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p]),
    "GetStatus": (C.c_int, [Component, C.c_int, C.c_void_p]),
    "GetRealStatus": (C.c_int, [Component, C.c_int, C.c_void_p]),
    "GetIntegerStatus": (C.c_int, [Component, C.c_int, C.c_void_p]),
    "GetBooleanStatus": (C.c_int, [Component, C.c_int, C.c_void_p]),
    "GetStringStatus": (C.c_int, [Component, C.c_int, C.c_void_p]),
    "GetDirectionalDerivative": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p, C.c_size_t, C.c_void_p,
                                           C.c_void_p]),
    "SetRealInputDerivatives": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p, C.c_void_p]),
    "GetRealOutputDerivatives": (C.c_int, [Component, C.c_void_p, C.c_size_t, C.c_void_p, C.c_void_p]),
}


class FMU:
    def __init__(self, so, guid, variables):
        self.lib = C.CDLL(so)
        self.guid, self.vars = guid.encode(), variables
        for name, (restype, argtypes) in SIGNATURES.items():
            function = getattr(self.lib, "fmi2" + name)
            function.restype, function.argtypes = restype, argtypes
            setattr(self, name, function)
        self.names = sorted(variables, key=lambda n: variables[n][0])
        self.nv = len(variables)

    def new(self, name=b"attack", callbacks=CALLBACKS):
        c = self.Instantiate(name, 1, self.guid, b"", C.byref(callbacks), 0, 1)
        if not c:
            problem("instantiate failed")
        return c

    def vr(self, name):
        return self.vars[name][0]

    def stepping(self, t0=0.0, **values):
        c = self.new()
        for name, value in values.items():
            self.set(c, name, value)
        self.SetupExperiment(c, 0, 0.0, t0, 0, 0.0)
        self.EnterInitializationMode(c)
        if self.ExitInitializationMode(c) != 0:
            problem(f"exitInitializationMode with {values}: {log[-1:]}")
        return c

    def set(self, c, name, value):
        vr, integer, _ = self.vars[name]
        array = (Int if integer else Real)(value)
        return (self.SetInteger if integer else self.SetReal)(c, C.byref(VR(vr)), 1, C.byref(array))

    def outputs_finite(self, c, where):
        for name in self.names:
            vr, integer, causality = self.vars[name]
            if causality != "output":
                continue
            value = (Int if integer else Real)(0)
            status = (self.GetInteger if integer else self.GetReal)(c, C.byref(VR(vr)), 1, C.byref(value))
            if status == 0 and not math.isfinite(value.value):
                problem(f"{where}: {name} = {value.value}")

    def time(self, c):
        t = Real()
        self.GetRealStatus(c, 2, C.byref(t))  # fmi2LastSuccessfulTime
        return t.value


def call(what, function, *args, want=None, slow=2.0):
    """function(*args), checked: OK or Error only, an error logged exactly once, an OK with none, fast."""
    n = len(log)
    start = time.perf_counter()
    status = function(*args)
    spent = time.perf_counter() - start
    errors = sum(1 for s, _ in log[n:] if s >= 3)
    if spent > slow:
        problem(f"{what}: took {spent:.2f} s")
    if status not in (0, 3):
        problem(f"{what}: status {status}")
    if status == 3 and errors != 1:
        problem(f"{what}: refused with {errors} logged errors")
    if status == 0 and errors:
        problem(f"{what}: OK with {errors} logged errors")
    if want is not None and status != want:
        problem(f"{what}: status {status}, expected {want} ({log[-1:]})")
    return status


fmu = FMU(*models[0])
NULL = None


def nulls():
    f = fmu
    r, i, st, size = Real(), Int(), State(), C.c_size_t()
    vr = C.byref(VR(0))
    bad = Callbacks(logger, ALLOC(), release, None, None)
    if f.Instantiate(b"x", 1, f.guid, b"", None, 0, 0):
        problem("NULL callbacks accepted")
    if f.Instantiate(b"x", 1, f.guid, b"", C.byref(bad), 0, 0):
        problem("NULL allocateMemory accepted")
    for guid, kind in ((None, 1), (b"{not this}", 1), (f.guid, 0), (f.guid, 77)):
        if f.Instantiate(b"x", kind, guid, b"", C.byref(CALLBACKS), 0, 0):
            problem(f"instantiate of GUID {guid} type {kind} accepted")
    c = f.Instantiate(None, 1, f.guid, None, C.byref(SILENT), 0, 1)  # no name, no logger
    if not c:
        problem("a NULL instance name or logger refused")
    f.SetupExperiment(c, 0, 0.0, math.nan, 0, 0.0)
    f.DoStep(c, 0.0, 1.0, 0)
    f.FreeInstance(c)
    f.FreeInstance(None)
    nullable = {"SetupExperiment": (NULL, 0, 0.0, 0.0, 0, 0.0), "DoStep": (NULL, 0.0, 1.0, 0),
                "SetDebugLogging": (NULL, 1, 0, NULL), "GetFMUstate": (NULL, C.byref(st)),
                "SetFMUstate": (NULL, NULL), "FreeFMUstate": (NULL, C.byref(st)),
                "SerializedFMUstateSize": (NULL, NULL, C.byref(size)),
                "SerializeFMUstate": (NULL, NULL, C.byref(r), 8), "DeSerializeFMUstate": (NULL, C.byref(r), 8,
                                                                                         C.byref(st)),
                "GetDirectionalDerivative": (NULL, vr, 1, vr, 1, C.byref(r), C.byref(r)),
                "SetRealInputDerivatives": (NULL, vr, 1, C.byref(i), C.byref(r)),
                "GetRealOutputDerivatives": (NULL, vr, 1, C.byref(i), C.byref(r))}
    for name in ("EnterInitializationMode", "ExitInitializationMode", "Terminate", "Reset", "CancelStep"):
        nullable[name] = (NULL,)
    for name in ("GetReal", "GetInteger", "GetBoolean", "GetString", "SetReal", "SetInteger", "SetBoolean",
                 "SetString"):
        nullable[name] = (NULL, vr, 1, C.byref(r))
    for name in ("GetStatus", "GetRealStatus", "GetIntegerStatus", "GetBooleanStatus", "GetStringStatus"):
        nullable[name] = (NULL, 0, C.byref(r))
    for name, args in nullable.items():
        if getattr(f, name)(*args) != 3:
            problem(f"{name} of a NULL component not refused")
    c = f.stepping()
    for name in ("GetStatus", "GetRealStatus", "GetIntegerStatus", "GetBooleanStatus", "GetStringStatus"):
        if getattr(f, name)(c, 0, NULL) != 3:
            problem(f"{name} with a NULL value not refused")
    for name in ("GetReal", "GetInteger", "SetReal", "SetInteger", "GetBoolean", "GetString", "SetBoolean",
                 "SetString"):
        call(f"{name}(NULL vr)", getattr(f, name), c, NULL, 1, C.byref(r), want=3)
        f.Reset(c)
        if name not in ("GetBoolean", "GetString", "SetBoolean", "SetString"):
            call(f"{name}(NULL values)", getattr(f, name), c, vr, 1, NULL, want=3)
            f.Reset(c)
        call(f"{name}(n = 0)", getattr(f, name), c, NULL, 0, NULL, want=0)
    call("SetInteger(n huge, NULL)", f.SetInteger, c, vr, 10**6, NULL, want=3)
    f.Reset(c)
    call("SetDebugLogging(NULL categories)", f.SetDebugLogging, c, 1, 5, NULL, want=0)
    call("GetFMUstate(NULL)", f.GetFMUstate, c, NULL, want=3)
    f.Reset(c)
    call("SetFMUstate(NULL)", f.SetFMUstate, c, NULL, want=3)
    f.Reset(c)
    call("FreeFMUstate(NULL)", f.FreeFMUstate, c, NULL, want=0)
    call("FreeFMUstate(&NULL)", f.FreeFMUstate, c, C.byref(State()), want=0)
    call("SerializedFMUstateSize(NULL)", f.SerializedFMUstateSize, c, NULL, C.byref(size), want=3)
    f.Reset(c)
    call("DeSerializeFMUstate(NULL bytes)", f.DeSerializeFMUstate, c, NULL, 100, C.byref(st), want=3)
    f.Reset(c)
    call("DeSerializeFMUstate(NULL state)", f.DeSerializeFMUstate, c, C.byref(r), 8, NULL, want=3)
    f.Reset(c)
    f.GetFMUstate(c, C.byref(st))
    call("SerializedFMUstateSize(NULL size)", f.SerializedFMUstateSize, c, st, NULL, want=3)
    f.Reset(c)
    call("SerializeFMUstate(NULL buffer)", f.SerializeFMUstate, c, st, NULL, 10**4, want=3)
    f.FreeFMUstate(c, C.byref(st))
    f.FreeInstance(c)


def value_references():
    f = fmu
    for bad in (f.nv, f.nv + 1, 2**31 - 1, 2**31, 2**32 - 2, 2**32 - 1):
        for name in ("GetReal", "GetInteger", "SetReal", "SetInteger", "GetBoolean", "GetString", "SetBoolean",
                     "SetString"):
            c = f.stepping()
            vrs, values = (VR * 2)(0, bad), (Real * 2)(7.0, 7.0)
            call(f"{name}(vr {bad})", getattr(f, name), c, vrs, 2, values, want=3)
            if name == "GetReal" and list(values) != [0.0, 0.0]:
                problem(f"getReal of vr {bad}: the values are not zeroed: {list(values)}")
            f.FreeInstance(c)
    for name in f.names:  # each variable through the other type
        vr, integer, _ = f.vars[name]
        c = f.new()
        call(f"{'GetReal' if integer else 'GetInteger'}({name})", f.GetReal if integer else f.GetInteger, c,
             C.byref(VR(vr)), 1, C.byref(Real()), want=3)
        f.FreeInstance(c)
    c = f.new()  # long lists: the refusal's list of names or references is bounded
    vrs, bools, reals = (VR * 5000)(*[2**32 - 1 - k for k in range(5000)]), (Int * 5000)(), (Real * 5000)()
    call("SetBoolean(5000 refs)", f.SetBoolean, c, vrs, 5000, bools, want=3)
    f.Reset(c)
    f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
    f.EnterInitializationMode(c)
    f.ExitInitializationMode(c)
    f.Terminate(c)
    parameters = [f.vars[n][0] for n in f.names if f.vars[n][2] == "parameter" and not f.vars[n][1]]
    vrs = (VR * 5000)(*[parameters[k % len(parameters)] for k in range(5000)])
    call("SetReal(5000 refs) when terminated", f.SetReal, c, vrs, 5000, reals, want=3)
    f.FreeInstance(c)


PHASES = ("instantiated", "initialization", "stepping", "terminated", "error")


def in_phase(phase):
    f = fmu
    c = f.new()
    if phase == "instantiated":
        return c
    f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
    f.EnterInitializationMode(c)
    if phase == "initialization":
        return c
    f.ExitInitializationMode(c)
    if phase == "terminated":
        f.Terminate(c)
    elif phase == "error":
        f.DoStep(c, 0.0, 0.1, 0)
        f.DoStep(c, 5.0, 0.1, 0)
    return c


def round_trip(c, then_step):
    f = fmu
    st, again, size = State(), State(), C.c_size_t()
    status = f.GetFMUstate(c, C.byref(st))
    if status == 0:
        f.SerializedFMUstateSize(c, st, C.byref(size))
        buffer = (C.c_char * size.value)()
        status = f.SerializeFMUstate(c, st, buffer, size.value)
        status = status or f.DeSerializeFMUstate(c, buffer, size.value, C.byref(again))
        status = status or f.DeSerializeFMUstate(c, buffer, size.value, C.byref(again))  # into an existing one
        status = status or f.SetFMUstate(c, again)
        status = status or f.GetFMUstate(c, C.byref(st))  # overwritten in place
        f.FreeFMUstate(c, C.byref(again))
        f.FreeFMUstate(c, C.byref(st))
        if st.value or again.value:
            problem("freeFMUstate left the pointer set")
        if status == 0 and then_step:
            status = f.DoStep(c, f.time(c), 0.1, 0)
    return status


def orders():
    f = fmu
    F, force = C.byref(VR(f.vr("F"))), C.byref(VR(f.vr("f")))
    one = C.byref(Real(1.0))
    harmonics = C.byref(VR(f.vr("harmonics")))
    operations = {
        "setup twice": lambda c: f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) or f.SetupExperiment(c, 0, 0.0, 3.0, 0,
                                                                                                   0.0),
        "enter twice": lambda c: f.EnterInitializationMode(c) or f.EnterInitializationMode(c),
        "exit twice": lambda c: f.ExitInitializationMode(c) or f.ExitInitializationMode(c),
        "exit, enter": lambda c: f.ExitInitializationMode(c) or f.EnterInitializationMode(c),
        "doStep": lambda c: f.DoStep(c, f.time(c), 0.1, 0),
        "terminate twice": lambda c: f.Terminate(c) or f.Terminate(c),
        "terminate, doStep": lambda c: f.Terminate(c) or f.DoStep(c, f.time(c), 0.1, 0),
        "reset twice, run": lambda c: (f.Reset(c) or f.Reset(c) or f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
                                       or f.EnterInitializationMode(c) or f.ExitInitializationMode(c)
                                       or f.DoStep(c, 0.0, 0.5, 0)),
        "setReal F": lambda c: f.SetReal(c, F, 1, one),
        "setReal f": lambda c: f.SetReal(c, force, 1, one),
        "setInteger harmonics": lambda c: f.SetInteger(c, harmonics, 1, C.byref(Int(3))),
        "getReal F": lambda c: f.GetReal(c, F, 1, C.byref(Real())),
        "state round trip": lambda c: round_trip(c, False),
        "state round trip, step": lambda c: round_trip(c, True),
        "cancelStep": lambda c: f.CancelStep(c),
        "directional derivative": lambda c: f.GetDirectionalDerivative(c, F, 1, F, 1, one, C.byref(Real())),
        "output derivatives": lambda c: f.GetRealOutputDerivatives(c, F, 1, C.byref(Int(1)), C.byref(Real())),
        "debug logging off, bad step": lambda c: f.SetDebugLogging(c, 0, 0, NULL) or f.DoStep(c, f.time(c), -1.0, 0),
    }
    for phase in PHASES:
        for name, operation in operations.items():
            c = in_phase(phase)
            call(f"{name} in the {phase} state", operation, c)
            fmu.outputs_finite(c, f"{name} in the {phase} state")
            f.FreeInstance(c)


NASTY = (math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, -5e-324, 2.2e-308, 1e-300, 1e-20, 1e20, 1e100, 1e200, 1e300,
         1.7976931348623157e308, -1e300, -1.0, 1e10, -1e10, 1e-9, 0.5, 7.0)


def parameters():
    f = fmu
    for name in f.names:
        vr, integer, causality = f.vars[name]
        if causality not in ("parameter", "input"):
            continue
        values = (-2**31, -1, 0, 11, 2**31 - 1) if integer else NASTY
        for value in values:
            if name == "omega" and value > 1e3:
                continue  # the work of a step grows with the drive's periods in it (see test_step_work_is_bounded)
            c = f.new()
            what = f"{name} = {value!r}"
            if call(f"set {what}", f.set, c, name, value) != 0:
                f.FreeInstance(c)
                continue
            if name != "F":
                f.set(c, "F", 10.0)
            f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
            f.EnterInitializationMode(c)
            if call(f"exitInitializationMode with {what}", f.ExitInitializationMode, c) == 0:
                t = 0.0
                for h in (0.37,) * 10 + (20.0,):
                    if call(f"doStep({t}, {h}) with {what}", f.DoStep, c, t, h, 0) != 0:
                        break
                    t += h
            f.outputs_finite(c, what)
            f.FreeInstance(c)
    for value in NASTY:  # the input while stepping
        c = f.stepping()
        status = call(f"set f = {value!r} while stepping", f.set, c, "f", value)
        if (status == 0) != (math.isfinite(value) and abs(value) <= 1e100):
            problem(f"f = {value!r}: status {status}")
        if status == 0:
            call(f"doStep with f = {value!r}", f.DoStep, c, 0.0, 5.0, 0)
        f.outputs_finite(c, f"f = {value!r}")
        f.FreeInstance(c)


def steps():
    f = fmu
    sizes = (1e-300, 5e-324, 1e-15, 1e-9, 1e3, 1e8, 1e11, 1e15, 1e100, 1e300, 1.7976931348623157e308, math.inf, -1.0,
             -0.0, 0.0, math.nan, -1e-300)
    starts = (0.0, -0.0, 1e-300, -1.0, -1e9, 1e9, 1e10, 1e12, 1e100, 1e300, -1e300, 1.7976931348623157e308, math.nan,
              math.inf, -math.inf, 5e-324)
    for t0 in starts:
        for h in sizes:
            c = f.new()
            f.set(c, "F", 10.0)
            status = call(f"setupExperiment({t0!r})", f.SetupExperiment, c, 0, 0.0, t0, 0, 0.0)
            if (status == 0) != math.isfinite(t0):
                problem(f"start time {t0!r}: status {status}")
            f.EnterInitializationMode(c)
            if f.ExitInitializationMode(c) == 0:
                status = call(f"doStep({t0!r}, {h!r})", f.DoStep, c, t0, h, 0)
                if status == 0 and not (math.isfinite(h) and h > 0):
                    problem(f"a step of {h!r} accepted")
                f.outputs_finite(c, f"t0 = {t0!r}, h = {h!r}")
                if status == 0:
                    call(f"doStep after doStep({t0!r}, {h!r})", f.DoStep, c, f.time(c), 1.0, 0)
            f.FreeInstance(c)
    c = f.stepping()
    call("doStep(0, 1)", f.DoStep, c, 0.0, 1.0, 0, want=0)
    call("doStep within 1e-9 of the time", f.DoStep, c, 1.0 + 5e-10, 0.1, 0, want=0)
    call("doStep ending before the time", f.DoStep, c, f.time(c) - 5e-10, 1e-10, 0, want=0)
    call("doStep at the wrong time", f.DoStep, c, 3.0, 0.1, 0, want=3)
    f.FreeInstance(c)


def allocator():
    f = fmu
    for budget in range(4):  # instantiate with 0..3 allocations allowed, then states
        fail_after[0] = budget
        c = f.Instantiate(b"oom", 1, f.guid, b"", C.byref(CALLBACKS), 0, 1)
        fail_after[0] = None
        if c:
            f.FreeInstance(c)
    c = f.stepping()
    st = State()
    fail_after[0] = 0
    call("getFMUstate out of memory", f.GetFMUstate, c, C.byref(st), want=3)
    fail_after[0] = None
    f.Reset(c)
    f.SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0)
    f.EnterInitializationMode(c)
    f.ExitInitializationMode(c)
    f.GetFMUstate(c, C.byref(st))
    size = C.c_size_t()
    f.SerializedFMUstateSize(c, st, C.byref(size))
    buffer = (C.c_char * size.value)()
    f.SerializeFMUstate(c, st, buffer, size.value)
    f.FreeFMUstate(c, C.byref(st))
    fail_after[0] = 0
    call("deSerializeFMUstate out of memory", f.DeSerializeFMUstate, c, buffer, size.value, C.byref(st), want=3)
    fail_after[0] = None
    f.FreeInstance(c)


def many():
    f = fmu
    instances = [f.stepping(0.001 * k) for k in range(500)]
    for k, c in enumerate(instances):
        call("doStep of one of many", f.DoStep, c, 0.001 * k, 0.1, 0, want=0)
    for c in instances:
        f.FreeInstance(c)


def states_across():
    f = fmu
    for p in PHASES:
        for q in PHASES:
            a, b = in_phase(p), in_phase(q)
            st = State()
            status = f.GetFMUstate(a, C.byref(st))
            if (status == 0) != (p != "error"):
                problem(f"getFMUstate in the {p} state: {status}")
            if status == 0:
                f.FreeInstance(a)  # the state outlives its instance
                a = None
                call(f"setFMUstate of a {p} state into a {q} instance", f.SetFMUstate, b, st, want=0)
                call(f"round trip of a {p} state in a {q} instance", round_trip, b, p in ("stepping",), want=0)
                f.outputs_finite(b, "states across")
                f.FreeFMUstate(b, C.byref(st))
                call("freeFMUstate twice (NULL)", f.FreeFMUstate, b, C.byref(st), want=0)
            if a:
                f.FreeInstance(a)
            f.FreeInstance(b)
    c = f.stepping(0.5)
    st = State()
    f.GetFMUstate(c, C.byref(st))
    size = C.c_size_t()
    f.SerializedFMUstateSize(c, st, C.byref(size))
    buffer = (C.c_char * (size.value + 8))()
    for short in (0, 1, 8, size.value // 2, size.value - 1):
        call(f"serializeFMUstate into {short} bytes", f.SerializeFMUstate, c, st, buffer, short, want=3)
        f.Reset(c)
    f.FreeFMUstate(c, C.byref(st))
    f.FreeInstance(c)


def foreign():
    """States of another model's FMU (models[1]) in every state call of this one."""
    other = FMU(*models[1])
    a, b = other.stepping(), fmu.stepping()
    other.DoStep(a, 0.0, 0.1, 0)
    theirs, mine, size = State(), State(), C.c_size_t()
    other.GetFMUstate(a, C.byref(theirs))
    fmu.GetFMUstate(b, C.byref(mine))
    buffer = (C.c_char * 4096)()
    attempts = {
        "setFMUstate": lambda: fmu.SetFMUstate(b, theirs),
        "getFMUstate over it": lambda: fmu.GetFMUstate(b, C.byref(State(theirs.value))),
        "freeFMUstate": lambda: fmu.FreeFMUstate(b, C.byref(State(theirs.value))),
        "serializedFMUstateSize": lambda: fmu.SerializedFMUstateSize(b, theirs, C.byref(size)),
        "serializeFMUstate": lambda: fmu.SerializeFMUstate(b, theirs, buffer, 4096),
        "deSerializeFMUstate into it": lambda: fmu.DeSerializeFMUstate(b, buffer, 4096, C.byref(State(theirs.value))),
    }
    for name, attempt in attempts.items():
        n = len(log)
        call(f"{name} with a state of another FMU", attempt, want=3)
        if not any("is not one of this FMU" in text for _s, text in log[n:]):
            problem(f"{name} with a state of another FMU: {log[n:]}")
        fmu.Reset(b)
    call("their state still works for them", other.SetFMUstate, a, theirs, want=0)
    call("mine still works for me", fmu.SetFMUstate, b, mine, want=0)
    other.FreeFMUstate(a, C.byref(theirs))
    fmu.FreeFMUstate(b, C.byref(mine))
    other.FreeInstance(a)
    fmu.FreeInstance(b)


def fuzz():
    f = fmu
    rng = random.Random(2024)
    c = f.stepping(0.5, F=50.0, omega=20.0)
    t = 0.5
    for _ in range(40):
        f.DoStep(c, t, 0.013, 0)
        t += 0.013
    st, size = State(), C.c_size_t()
    f.GetFMUstate(c, C.byref(st))
    f.SerializedFMUstateSize(c, st, C.byref(size))
    data = (C.c_char * size.value)()
    f.SerializeFMUstate(c, st, data, size.value)
    f.FreeFMUstate(c, C.byref(st))
    f.FreeInstance(c)
    data = bytes(data)
    fixed = 56 + 8 * (3 + f.nv + 1)  # the wrapper's part; then the core's: a 24-byte header (CRC-32 at 20); then
    # the wrapper's seal: a CRC-32 of all that (4 bytes)

    def fix_crc(blob):
        if len(blob) > fixed + 28:
            blob[fixed + 20:fixed + 24] = struct.pack("<I", zlib.crc32(bytes(blob[fixed + 24:-4])))
        if len(blob) > 4:
            blob[-4:] = struct.pack("<I", zlib.crc32(bytes(blob[:-4])))
        return blob

    c = f.new()
    outcome = {"deserialize refused": 0, "set refused": 0, "accepted": 0}

    def attempt(blob, label):
        st = State()
        n = len(log)
        buffer = (C.c_char * max(len(blob), 1)).from_buffer_copy(bytes(blob) or b"\0")
        if call(f"deSerializeFMUstate({label})", f.DeSerializeFMUstate, c, buffer, len(blob), C.byref(st)) != 0:
            outcome["deserialize refused"] += 1
        elif call(f"setFMUstate({label})", f.SetFMUstate, c, st) != 0:
            outcome["set refused"] += 1
        else:
            outcome["accepted"] += 1
            f.outputs_finite(c, label)
            now = f.time(c)
            if call(f"doStep from {label}", f.DoStep, c, now, 0.05, 0) == 0:
                call(f"doStep of 10 s from {label}", f.DoStep, c, now + 0.05, 10.0, 0)
            f.outputs_finite(c, label + ", stepped")
        f.FreeFMUstate(c, C.byref(st))
        f.Reset(c)
        return len(log) - n

    attempt(bytearray(data), "the state itself")
    if outcome["accepted"] != 1:
        problem(f"the state itself was refused: {log[-1:]}")
    for length in list(range(0, len(data), 7)) + [len(data) - 1, len(data) + 1, len(data) + 8, len(data) + 4096]:
        before = outcome["accepted"]
        attempt(bytearray(data[:length]) + bytearray(max(0, length - len(data))), f"{length} bytes")
        if outcome["accepted"] != before:
            problem(f"a state of {length} bytes accepted (it has {len(data)})")
    special = (math.nan, math.inf, -math.inf, 0.0, -0.0, 1e300, -1e300, 1e-300, 5e-324, 1e10, -1.0, 1.0, 2.0**31,
               -2.0**31 - 1, 1e18, 0.5)
    deadline = time.perf_counter() + float(what[-1]) if what[-1][0].isdigit() else time.perf_counter() + 3.0
    k = 0
    while time.perf_counter() < deadline:
        blob = bytearray(data)
        kind = k % 4
        if kind == 0:  # bit flips, checksums as they are (refused by the seal)
            for _ in range(rng.randint(1, 3)):
                blob[rng.randrange(len(blob))] ^= 1 << rng.randrange(8)
        elif kind == 1:  # bit flips past the checksum
            for _ in range(rng.randint(1, 3)):
                blob[rng.randrange(56, len(blob))] ^= 1 << rng.randrange(8)
            fix_crc(blob)
        elif kind == 2:  # one 8-byte field replaced, checksum fixed
            at = 56 + 8 * rng.randrange((len(blob) - 56) // 8)
            if rng.random() < 0.5:
                blob[at:at + 8] = struct.pack("<d", rng.choice(special))
            else:
                blob[at:at + 8] = struct.pack("<Q", rng.getrandbits(rng.choice((8, 32, 64))))
            fix_crc(blob)
        else:  # random bytes, sometimes behind a valid header
            blob = bytearray(rng.getrandbits(8) for _ in range(rng.randrange(len(data) + 64)))
            if rng.random() < 0.5 and len(blob) >= 56:
                blob[:56] = data[:56]
        attempt(blob, f"fuzz case {k} (kind {kind})")
        k += 1
    counts.update(outcome, cases=k)
    f.FreeInstance(c)


for name in what:
    if name in globals():
        globals()[name]()
if live[0]:
    problem(f"{live[0]} allocations of allocateMemory not freed")
print(json.dumps({"problems": problems, "counts": counts}))
'''


def attack(libraries, parts, timeout=120):
    """Run parts of ATTACK on [(so, guid, variables), ...] in a subprocess: (its problems, its counts)."""
    run = subprocess.run([sys.executable, "-c", ATTACK, json.dumps(libraries), ",".join(parts)],
                         capture_output=True, text=True, timeout=timeout)
    assert run.returncode == 0, f"the importer crashed (exit {run.returncode}):\n{run.stdout[-2000:]}\n" \
                                f"{run.stderr[-4000:]}"
    report = json.loads(run.stdout.strip().splitlines()[-1])
    return report["problems"], report["counts"]


@pytest.fixture(scope="module")
def libraries(native_fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("attacked")
    return {model: extracted(Path(native_fmus[model]), folder) for model in MODELS}


@pytest.mark.parametrize("model", MODELS)
def test_hostile_calls_are_refused_never_crash(libraries, model):
    problems, _ = attack([libraries[model]], ["nulls", "value_references", "orders", "parameters", "steps",
                                              "allocator", "many", "states_across"])
    assert problems == []


@pytest.mark.parametrize("model, other", [("TwoMassBacklash", "FrictionMass"), ("FrictionMass", "StaticBacklash"),
                                          ("StaticBacklash", "TwoMassBacklash")])
def test_a_state_of_another_fmu_is_refused(libraries, model, other):
    problems, _ = attack([libraries[model], libraries[other]], ["foreign"])
    assert problems == []


@pytest.mark.parametrize("model", MODELS)
def test_fuzzed_serialized_states_never_crash(libraries, model):
    problems, counts = attack([libraries[model]], ["fuzz", "2.5"])
    assert problems == []
    assert counts["cases"] > 300 and counts["accepted"] > 0 and counts["deserialize refused"] > 0, counts


def crafted(data, value, at):
    """The serialized state ``data`` with the int64 at ``at`` (in the core's bytes) set to ``value``, the core's
    CRC-32 and the wrapper's seal fixed: bytes the checksums see as valid."""
    core = data.index(b"DFWBSTAT")  # the core's header: magic, ABI, kind, length, CRC-32 (at 20), then the payload
    blob = bytearray(data)
    struct.pack_into("<q", blob, at, value)
    struct.pack_into("<I", blob, core + 20, zlib.crc32(bytes(blob[core + 24:-4])))
    struct.pack_into("<I", blob, len(blob) - 4, zlib.crc32(bytes(blob[:-4])))  # the wrapper's seal
    return bytes(blob)


def counter_offset(fmu, vr_events, data, events):
    """Where the core keeps the events counter in the state's bytes (an int64): found by trying."""
    core = data.index(b"DFWBSTAT")
    for at in range(core + 24, len(data) - 7, 8):
        if struct.unpack_from("<q", data, at)[0] != events:
            continue
        state = fmu.deSerializeFMUstate(crafted(data, events + 1, at))
        try:
            fmu.setFMUstate(state)
            if fmu.getInteger([vr_events]) == [events + 1]:
                return at
        except Exception:  # noqa: BLE001 - not the counter: refused
            pass
        finally:
            fmu.freeFMUstate(state)
            fmu.reset()
    raise AssertionError("the events counter was not found in the state's bytes")


@pytest.mark.parametrize("model", MODELS)
def test_a_counter_beyond_32_bits_is_refused_not_wrapped(native_fmus, model):
    fmu, description, log = new_instance(native_fmus[model], "counter")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    fmu.setReal([vr["F"], vr["omega"]], [50.0, 20.0])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(0.0, 1.0)
    events = fmu.getInteger([vr["events"]])[0]
    assert events > 0
    state = fmu.getFMUstate()
    data = bytes(fmu.serializeFMUstate(state))
    fmu.freeFMUstate(state)
    at = counter_offset(fmu, vr["events"], data, events)
    for count, fits in ((2**31 - 1, True), (2**31, False), (2**40, False), (2**63 - 1, False)):
        state = fmu.deSerializeFMUstate(crafted(data, count, at))
        fmu.setFMUstate(state)
        fmu.freeFMUstate(state)
        if fits:
            assert fmu.getInteger([vr["events"]]) == [count]
        else:
            n = len(log)
            with pytest.raises(Exception):
                fmu.getInteger([vr["events"]])
            assert [text for status, text in log[n:] if status == 3] == [
                f"{model}: getInteger: events = {float(count):.0f} does not fit a 32-bit Integer"]
        fmu.reset()


def test_step_work_is_bounded_by_the_phase_limit_only(native_fmus):
    """A step's work grows with the drive periods it spans; past the phase limit (1e10 rad) it is refused at once.

    Not a bound in practice: doStep(0, 1e9) at omega = 1 is accepted and runs for many minutes (~1.6e8 periods
    of events, as the pythonfmu twin would): what is checked here is only that the refusals are immediate."""
    for t0, h in ((0.0, 1e11), (0.0, 1e300), (-1e9, 1e11), (1e9, 1e300)):
        fmu, description, log = new_instance(native_fmus["FrictionMass"], "long")
        vr = {v.name: v.valueReference for v in description.modelVariables}
        fmu.setReal([vr["F"]], [10.0])
        fmu.setupExperiment(startTime=t0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        start = time.perf_counter()
        with pytest.raises(Exception):
            fmu.doStep(t0, h)
        assert time.perf_counter() - start < 0.5
        assert "must stay within +-1e+10 rad" in log[-1][1]


@pytest.mark.parametrize("model, name", [("FrictionMass", "M"), ("TwoMassBacklash", "omega"),
                                         ("StaticBacklash", "M")])
def test_outputs_after_a_refused_start_are_not_nan(native_fmus, model, name):
    """Fixed: outputs that overflow at exitInitializationMode were kept (NaN); now the start values (0) stay."""
    fmu, description, log = new_instance(native_fmus[model], "start")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    reals = [v.valueReference for v in description.modelVariables if v.causality == "output" and v.type == "Real"]
    fmu.setReal([vr[name], vr["F"]], [5e-324, 10.0])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    with pytest.raises(Exception):
        fmu.exitInitializationMode()
    assert "the outputs at the start overflow a float" in log[-1][1]
    assert fmu.getReal(reals) == [0.0] * len(reals)


@pytest.mark.parametrize("model", MODELS)
def test_a_state_from_before_initialisation_reads_as_a_reset_instance(native_fmus, model):
    """Fixed: after restoring a state taken before initialisation, the outputs of the later run were still read."""
    fmu, description, _log = new_instance(native_fmus[model], "before")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    outputs = [v for v in description.modelVariables if v.causality == "output"]
    reals = [v.valueReference for v in outputs if v.type == "Real"]
    integers = [v.valueReference for v in outputs if v.type == "Integer"]
    state = fmu.getFMUstate()
    fmu.setReal([vr["F"], vr["omega"]], [10.0, 3.0])
    fmu.setupExperiment(startTime=0.25)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(0.25, 2.0)
    assert any(fmu.getReal(reals)) and any(fmu.getInteger(integers))
    fmu.setFMUstate(state)
    fmu.freeFMUstate(state)
    restored = fmu.getReal(reals + [vr["F"]]), fmu.getInteger(integers)
    fmu.reset()
    assert restored == (fmu.getReal(reals + [vr["F"]]), fmu.getInteger(integers))


# Hostile call sequences on the raw FMI API: the native FMU and the pythonfmu twin (its pure-Python solver) give
# the same statuses and values, and log an error exactly when the other does (the texts of refusals the
# pythonfmu shim makes itself - wrong call orders - differ in wording).
NAN, INF = float("nan"), float("inf")


def _init(t0=0.0, **values):
    def step(fmu, vr):
        for name, value in values.items():
            (fmu.setInteger if name == "harmonics" else fmu.setReal)([vr[name]], [value])
        fmu.setupExperiment(startTime=t0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
    return step


def _state(fmu, _vr):
    state = fmu.getFMUstate()
    data = fmu.serializeFMUstate(state)
    fmu.freeFMUstate(state)
    state = fmu.deSerializeFMUstate(data)
    fmu.setFMUstate(state)
    fmu.freeFMUstate(state)


def _get(*names):
    return lambda fmu, vr: fmu.getReal([vr[name] for name in names])


def _step(t, h):
    return lambda fmu, vr: fmu.doStep(t, h)


_SETUP = lambda fmu, vr: fmu.setupExperiment(startTime=0.0)  # noqa: E731
_ENTER = lambda fmu, vr: fmu.enterInitializationMode()  # noqa: E731
_EXIT = lambda fmu, vr: fmu.exitInitializationMode()  # noqa: E731
_TERMINATE = lambda fmu, vr: fmu.terminate()  # noqa: E731
_RESET = lambda fmu, vr: fmu.reset()  # noqa: E731
SEQUENCES = {
    "setup twice": [_SETUP, _SETUP, _get("F")],
    "enter twice": [_SETUP, _ENTER, _ENTER],
    "exit twice": [_init(), _EXIT],
    "enter after exit": [_init(), _ENTER],
    "terminate twice": [_init(), _TERMINATE, _TERMINATE],
    "doStep before init": [_step(0.0, 0.1)],
    "doStep after terminate": [_init(), _step(0.0, 0.1), _TERMINATE, _step(0.1, 0.1)],
    "after an error": [_init(F=3.0), _step(0.0, 0.5), _step(9.0, 0.5), _step(0.5, 0.5), _get("Ic1", "Is2", "F")],
    "reset everywhere": [_RESET, _SETUP, _RESET, _SETUP, _ENTER, _RESET, _init(F=2.0), _step(0.0, 0.1),
                         _step(7.0, 1.0), _RESET, _init(), _step(0.0, 0.5), _get("Ic0", "F")],
    "start time nan": [lambda fmu, vr: fmu.setupExperiment(startTime=NAN)],
    "start time 1e300": [_init(1e300)],
    "start time 1e9": [_init(1e9, F=10.0), _step(1e9, 1.0), _step(1e9 + 1.0, 1.0), _get("Ic1", "Is1")],
    "step 1e-300": [_init(F=10.0), _step(0.0, 1e-300), _step(1e-300, 1e-300), _get("Ic1")],
    "step 1e300": [_init(F=10.0), _step(0.0, 1e300)],
    "step inf, nan, -0": [_init(), _step(0.0, INF), _RESET, _init(), _step(0.0, NAN), _RESET, _init(),
                          _step(0.0, -0.0)],
    "time nan": [_init(), _step(NAN, 0.1)],
    "harmonics out of range": [_init(harmonics=11), _RESET, _init(harmonics=-1), _RESET, _init(harmonics=2**31 - 1),
                               _RESET, _init(harmonics=-2**31)],
    "harmonics 0": [_init(harmonics=0, F=5.0), _step(0.0, 1.0), _get("Ic0", "Is0", "Ic1", "Is10")],
    "valueReference 2**32 - 1": [_init(), lambda fmu, vr: fmu.getReal([2**32 - 1])],
    "input 1e100, then 1e101": [lambda fmu, vr: fmu.setReal([vr["f"]], [1e100]), _init(), _step(0.0, 1.0),
                                lambda fmu, vr: fmu.setReal([vr["f"]], [-1e101])],
    "a parameter when terminated": [_init(), _TERMINATE, lambda fmu, vr: fmu.setReal([vr["F"]], [2.0])],
    "states in every phase": [_state, _SETUP, _ENTER, _state, _EXIT, _state, _step(0.0, 0.1), _TERMINATE, _state,
                              _step(0.1, 0.1)],  # then the twins differ: the pythonfmu shim's refusal leaves the
    # instance terminated (getFMUstate works), the native one enters the Error state (getFMUstate is refused)
    "a state in the error state": [_init(), _step(3.0, 1.0), _state],
}


def _run(path, sequence):
    fmu, description, log = new_instance(path, "twins")
    vr = {v.name: v.valueReference for v in description.modelVariables}
    results = []
    for step in sequence:
        n = len(log)
        try:
            value = step(fmu, vr)
            outcome = "ok" if value is None else repr(value)
        except Exception:  # noqa: BLE001 - a refusal
            outcome = "refused"
        results.append((outcome, any(status >= 3 for status, _ in log[n:])))
    return results


@pytest.fixture
def python_oracle(monkeypatch):
    monkeypatch.setenv("DFWB_FMU_SOLVER", "python")


@pytest.mark.parametrize("model", MODELS)
def test_hostile_sequences_as_the_pythonfmu_twin(native_fmus, fmus, python_oracle, model):
    for name, sequence in SEQUENCES.items():
        assert _run(native_fmus[model], sequence) == _run(fmus[model], sequence), name
