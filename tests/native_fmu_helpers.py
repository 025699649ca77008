"""Helpers shared by the tests of the FMUs on the compiled core (plant and loop FMUs) and of the C states.

The FMU helpers drive an FMU in this process (fmpy's simulate_fmu, or a raw FMU2Slave from
conftest.new_instance); ``solver`` is the conftest fixture that sets DFWB_FMU_SOLVER for the instances
made next. The state helpers (HEADER, with_crc, read_or_refuse) serve the fuzzing subprocesses too.
"""

import shutil
import struct
import sys
import zipfile
import zlib

import fmpy
import pytest
from conftest import new_instance
from fmpy.fmi1 import FMICallException

from dfwb.build_fmus import builder
from dfwb.fmi.simulation import unpacked
from dfwb.fmus.state import StateRefused

HEADER = 24  # the C state's header: magic, ABI, kind, payload length, CRC-32; then 8-byte fields


# -- the C state's bytes (also imported by the fuzzing subprocesses) -------------------------------------------

def with_crc(data):
    """``data`` with the checksum of its header made valid again (only the C core's other checks stand)."""
    data = bytearray(data)
    data[20:24] = struct.pack("<I", zlib.crc32(bytes(data[HEADER:])))
    return bytes(data)


def read_or_refuse(cls, data, tally, **options):
    """cls.from_bytes(data, **options), or None when it is refused (with one nonempty line), counted in tally;
    an accepted state must write back the bytes it reads."""
    try:
        solver = cls.from_bytes(data, **options)
    except StateRefused as error:
        assert "\n" not in str(error) and str(error)
        tally["refused"] += 1
        return None
    tally["accepted"] += 1
    assert cls.from_bytes(solver.to_bytes()).to_bytes() == solver.to_bytes()
    return solver


def counted_once(tally, attempt):
    """``attempt(cls, data)`` that runs once per (cls, bytes): the same bytes again (a field set to the value it
    has, the same mix drawn twice) are the same attempt, a fresh solver from them, so what its run added to
    ``tally`` is added again without running it."""
    seen = {}

    def once(cls, data):
        if (cls, data) not in seen:
            before = dict(tally)
            attempt(cls, data)
            seen[cls, data] = {name: tally[name] - before[name] for name in tally}
            return
        for name, count in seen[cls, data].items():
            tally[name] += count

    return once


# -- FMUs built with the compiled core --------------------------------------------------------------------------

def has_cc():
    return any(shutil.which(name) for name in ("cc", "gcc", "clang"))


def build_with_core(folder, models):
    """{model: path} of the FMUs of ``models``, built with the compiled core into ``folder`` (skips without cc)."""
    if not has_cc():
        pytest.skip("no C compiler (cc) on PATH to build the core")
    core, why = builder.core_binary()
    assert core is not None, why
    lines = []
    paths = builder.build(folder, list(models), report=lines.append)
    assert not [line for line in lines if "cannot" in line], lines
    for path in paths:
        with zipfile.ZipFile(path) as archive:
            assert archive.read(builder.CORE_RESOURCE) == core
    return {path.stem: path for path in paths}


def without_core(path, tmp_path, replacement=None):
    """A copy of the FMU whose core is missing (or replaced by ``replacement`` bytes)."""
    copy = tmp_path / "bare" / path.name
    copy.parent.mkdir(exist_ok=True)
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(copy, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            if item.filename == builder.CORE_RESOURCE:
                if replacement is not None:
                    target.writestr(item, replacement)
            else:
                target.writestr(item, source.read(item.filename))
    return copy


# -- fmpy runs -------------------------------------------------------------------------------------------------

def simulate(directory, description, start, t0, stop, dt):
    """(fmpy's result, its log [(status, text)], the error or None) of one run of every output."""
    messages = []

    def logger(_env, _instance, status, _category, text):
        messages.append((status, text.decode()))

    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    try:
        result = fmpy.simulate_fmu(str(directory), model_description=description, start_time=t0, stop_time=stop,
                                   output_interval=dt, start_values=dict(start), output=outputs, logger=logger,
                                   debug_logging=True, validate=False)
    except FMICallException as error:
        return None, messages, str(error)
    return result, messages, None


def both(path, solver, start, t0, stop, dt):
    """(simulate on the default solver (the core), simulate with DFWB_FMU_SOLVER=python)."""
    directory, description = unpacked(path)
    solver(None)
    native = simulate(directory, description, start, t0, stop, dt)
    solver("python")
    python = simulate(directory, description, start, t0, stop, dt)
    solver(None)
    return native, python


def identical_on_both(path, solver, start, t0, stop, dt):
    """(result, native log, Python log) of a run whose every output, events included, is the same bit for bit
    on the core and in Python."""
    (native, native_log, error), (python, python_log, python_error) = both(path, solver, start, t0, stop, dt)
    assert error is None and python_error is None, (native_log, python_log)
    assert native.dtype == python.dtype and len(native) == len(python) > 10
    assert native.tobytes() == python.tobytes()  # every output, events and counters included
    assert native["events"][-1] > 0  # the cases exercise events
    return native, native_log, python_log


def refused_on_both(path, solver, start, stop):
    """(native log, Python log, native error, Python error) of a run refused with the same one error both ways."""
    (_, native_log, error), (_, python_log, python_error) = both(path, solver, start, 0.0, stop, 0.1)
    assert error and python_error
    native_errors = [m for m in native_log if m[0] >= 3]
    python_errors = [m for m in python_log if m[0] >= 3]
    assert native_errors == python_errors and len(native_errors) == 1, (native_log, python_log)
    return native_log, python_log, error, python_error


def falls_back(path, tmp_path, solver, damage, case):
    """The FMU without its core (or with ``damage`` for one) runs ``case`` in Python, bit for bit as the intact
    FMU with DFWB_FMU_SOLVER=python, and fails at exitInitializationMode with DFWB_FMU_SOLVER=native:
    (the log of the run, the errors of the refused one)."""
    directory, description = unpacked(without_core(path, tmp_path, damage))
    start, t0, stop, dt = case
    result, log, error = simulate(directory, description, start, t0, stop, dt)
    assert error is None
    solver("python")
    reference, _, _ = simulate(*unpacked(path), start, t0, stop, dt)
    assert result.tobytes() == reference.tobytes()

    solver("native")  # the core is required: its absence is an error at exitInitializationMode
    refused, refused_log, error = simulate(directory, description, start, t0, stop, dt)
    assert refused is None and "ExitInitializationMode" in error
    return log, [text for status, text in refused_log if status >= 3]


def refuses_a_bad_choice(path, solver):
    """The errors of a run with DFWB_FMU_SOLVER=fortran, which fails."""
    solver("fortran")
    result, log, error = simulate(*unpacked(path), {"F": 1.0}, 0.0, 1.0, 0.1)
    assert result is None and error
    return [text for status, text in log if status >= 3]


# -- raw instances and FMU states ------------------------------------------------------------------------------

def initialised(path, start, start_time=0.0, name="state"):
    """(raw FMU2Slave initialised with ``start`` (Integer or Real values), its description, its log)."""
    fmu, description, messages = new_instance(path, name)
    fmu.setupExperiment(startTime=start_time)
    fmu.enterInitializationMode()
    by_name = {v.name: v for v in description.modelVariables}
    for name, value in start.items():
        var = by_name[name]
        if var.type == "Integer":
            fmu.setInteger([var.valueReference], [int(value)])
        else:
            fmu.setReal([var.valueReference], [float(value)])
    fmu.exitInitializationMode()
    return fmu, description, messages


def instance(path, start, kind, solver, start_time=0.0):
    """initialised(...) on the solver ``kind`` (None: the default, "python" or "native")."""
    solver(kind)
    made = initialised(path, start, start_time)
    solver(None)
    return made


def run(fmu, t, t_end, dt):
    """doStep from t by dt until t_end; the time reached."""
    while t < t_end - 1e-12:
        fmu.doStep(t, dt)
        t += dt
    return t


def read(fmu, description):
    """Every Real (as bit patterns) and Integer variable."""
    reals = [v.valueReference for v in description.modelVariables if v.type == "Real"]
    integers = [v.valueReference for v in description.modelVariables if v.type == "Integer"]
    return [struct.pack("<d", value) for value in fmu.getReal(reals)], list(fmu.getInteger(integers))


def solver_log(messages):
    return [text for status, text in messages if "runs on" in text]


def states_continue(path, start, solver, t_save, t_end, dt):
    """A state saved at t_save on the core continues bit for bit as the Python solver's run to t_end: in memory,
    from bytes, and in another instance of default parameters. (the bytes, the logs of both instances)."""
    python, description, _ = instance(path, start, "python", solver, start_time=0.5)
    run(python, 0.5, t_end, dt)
    reference = read(python, description)

    fmu, _, messages = instance(path, start, None, solver, start_time=0.5)
    assert "runs on the compiled core" in solver_log(messages)[0]
    t1 = run(fmu, 0.5, t_save, dt)
    saved = fmu.getFMUstate()
    data = fmu.serializeFMUstate(saved)
    run(fmu, t1, t_end, dt)
    assert read(fmu, description) == reference
    fmu.setFMUstate(saved)  # in memory: the C solver copied
    run(fmu, t1, t_end, dt)
    assert read(fmu, description) == reference
    fmu.setFMUstate(fmu.deSerializeFMUstate(data))  # from bytes: read back by the instance's own core
    run(fmu, t1, t_end, dt)
    assert read(fmu, description) == reference
    fmu.freeFMUstate(saved)

    fresh, _, fresh_messages = instance(path, {}, None, solver)  # another instance, default parameters
    fresh.setFMUstate(fresh.deSerializeFMUstate(data))
    run(fresh, t1, t_end, dt)
    assert read(fresh, description) == reference
    assert not [m for m in messages + fresh_messages if m[0] >= 1]
    return data, messages, fresh_messages


def state_crosses_solvers(path, start, solver, source, target, t_save, t_end, dt):
    """A state of an instance on ``source`` continues on an instance on ``target`` as on its own."""
    fmu, description, _ = instance(path, start, source, solver)
    t1 = run(fmu, 0.0, t_save, dt)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    run(fmu, t1, t_end, dt)
    other, _, messages = instance(path, {}, target, solver)
    other.setFMUstate(other.deSerializeFMUstate(data))
    run(other, t1, t_end, dt)
    assert read(other, description) == read(fmu, description)
    assert not [m for m in messages if m[0] >= 1]


def fmu_classes(path, module):
    """(the FMU's own facade class, its state module): the FMU runs in this process under its package name;
    ``module`` is the facade's module ("facade" or "loop_facade")."""
    package = f"dfwb_fmus_{builder.recorded_hash(path)}"
    return getattr(sys.modules[f"{package}.{module}"], path.stem), sys.modules[f"{package}.state"]


def crafted(path, module, data, change):
    """``data`` (serialized) decoded by the FMU's own code, changed by change(state, NativeState), encoded again."""
    cls, state_module = fmu_classes(path, module)
    decoded = cls._fmu_state_from_bytes(data)
    assert type(decoded.solver).__name__ == "NativeState"
    change(decoded, state_module.NativeState)
    return cls._fmu_state_to_bytes(decoded)


def flip(offset):
    """A change for crafted(): one bit of the C solver's bytes flipped at ``offset``."""
    def change(decoded, _native_state):
        raw = bytearray(decoded.solver.data)
        raw[offset % len(raw)] ^= 0x10
        decoded.solver.data = bytes(raw)
    return change


def crafted_is_refused(path, module, start, solver, change, t_save, dt):
    """A state saved at t_save, crafted by ``change``, is refused and changes nothing:
    (the instance, its good state's bytes, t_save reached, its errors)."""
    fmu, description, messages = instance(path, start, None, solver)
    t1 = run(fmu, 0.0, t_save, dt)
    good = fmu.serializeFMUstate(fmu.getFMUstate())
    bad = crafted(path, module, good, change)
    assert bad != good
    before = read(fmu, description)
    with pytest.raises(Exception, match="failed with status 3"):
        fmu.setFMUstate(fmu.deSerializeFMUstate(bad))
    assert read(fmu, description) == before  # nothing changed, the getters still work
    return fmu, good, t1, [text for status, text in messages if status >= 3]


def refused_without_core(path, start, solver, tmp_path):
    """The errors of a core state set into a copy of the FMU without its core (refused)."""
    fmu, _, _ = instance(path, start, None, solver)
    run(fmu, 0.0, 0.5, 0.1)
    data = fmu.serializeFMUstate(fmu.getFMUstate())
    bare, _, messages = instance(without_core(path, tmp_path), {}, None, solver)
    assert [status for status, text in messages if "runs on the pure-Python solver" in text] == [1]
    with pytest.raises(Exception, match="failed with status 3"):
        bare.setFMUstate(bare.deSerializeFMUstate(data))
    return [text for status, text in messages if status >= 3]
