"""Run FMUs with libcosim (libcosimpy), an FMI importer independent of fmpy.

fmpy is the project's importer (:mod:`dfwb.fmi.simulation`); running the same
FMUs in the Open Simulation Platform's libcosim checks that their behaviour
does not depend on one importer's reading of the FMI standard. The results
are shaped like fmpy's: a structured array with a column ``time`` (from
t = 0, after initialisation) plus one column per output.

libcosim counts time in whole nanoseconds and steps with a fixed
communication step; it logs every FMI Library call at debug level to
*stdout* by default, so importing this module lowers its log level to
warnings (an FMU's own warnings and errors still appear there).
pythonfmu FMUs run inside this Python interpreter: libcosim calls them from
its worker threads, which take the GIL (ctypes releases it during a step).
"""

import math
from pathlib import Path

import fmpy
import numpy as np
from libcosimpy._internal import get_last_error_message  # libcosimpy's only way to libcosim's error text
from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

from dfwb.base.errors import InputError, RunError
from dfwb.fmi.simulation import FMUError

NANOSECONDS = 1_000_000_000
# FMI type -> (libcosim variable type, numpy dtype of the column, as fmpy records it)
TYPES = {
    "Real": (CosimVariableType.REAL, np.float64),
    "Integer": (CosimVariableType.INTEGER, np.int32),
}

log_output_level(CosimLogLevel.WARNING)


def simulate_cosim(fmu_path, stop_time, step, start_values=None, outputs=None):
    """Simulate one co-simulation FMU with libcosim; raise FMUError if a step fails.

    Parameters
    ----------
    fmu_path : str or Path
        The FMU.
    stop_time : float
        End of the run; it must be a whole number of steps (the run starts at 0).
    step : float
        Fixed communication step, a whole number of nanoseconds.
    start_values : dict, optional
        {name: value} of Real or Integer variables, set before initialisation.
    outputs : list of str, optional
        Real or Integer variables to record; default: every output, as fmpy does.
        Columns come in fmpy's order (Reals, then Integers). Boolean and String
        variables are not supported (libcosim's time-series observer keeps
        only reals and integers).

    Returns
    -------
    numpy.ndarray
        Structured array like fmpy's: ``time`` plus the outputs, one row per
        communication point from t = 0 to ``stop_time``.

    Raises
    ------
    FMUError
        When a step fails: the model, the time and libcosim's reason (the
        FMU's own message is in libcosim's log, on stdout).
    ValueError
        For unknown or unsupported variables, or a grid libcosim cannot step.

    Notes
    -----
    An FMU that fails during initialisation (e.g. a parameter out of range)
    aborts the whole Python process in libcosim 0.11.2: the error escapes a
    worker thread. Check doubtful parameters with :func:`dfwb.fmi.simulation.simulate`
    first.
    """
    return simulate_cosim_together([(fmu_path, start_values, outputs)], stop_time, step)[0]


def simulate_cosim_together(runs, stop_time, step):
    """Simulate several FMUs as unconnected slaves of one libcosim execution.

    All slaves step together, on libcosim's worker threads; this checks that
    the FMUs can share one process and one system without interfering.

    Parameters
    ----------
    runs : sequence of (fmu_path, start_values, outputs)
        One entry per slave, with the meaning of :func:`simulate_cosim`'s arguments.
    stop_time, step : float
        As for :func:`simulate_cosim`, common to all slaves.

    Returns
    -------
    list of numpy.ndarray
        One fmpy-shaped result per entry of ``runs``, in the same order.
    """
    steps, step_ns = _grid(stop_time, step)
    slaves = []
    for fmu_path, start_values, outputs in runs:
        description = fmpy.read_model_description(str(fmu_path))
        variables = {variable.name: variable for variable in description.modelVariables}
        if outputs is None:
            outputs = [name for name, variable in variables.items() if variable.causality == "output"]
        start_values = dict(start_values or {})
        unknown = [name for name in [*start_values, *outputs] if name not in variables]
        if unknown:
            raise InputError(f"{description.modelName}: no variables named {unknown}")
        unsupported = [name for name in [*start_values, *outputs] if variables[name].type not in TYPES]
        if unsupported:
            raise InputError(f"{description.modelName}: {unsupported} are neither Real nor Integer")
        slaves.append({
            "path": str(Path(fmu_path).resolve()),
            "model": description.modelName,
            "start": [(variables[name], value) for name, value in start_values.items()],
            # fmpy's column order: the Reals, then the Integers, each in model-description order
            "outputs": [variable for kind in TYPES for variable in description.modelVariables
                        if variable.type == kind and variable.name in outputs],
        })
    names = [slave["model"] for slave in slaves]
    for i, slave in enumerate(slaves):  # libcosim needs distinct instance names
        slave["instance"] = slave["model"] if names.count(slave["model"]) == 1 else f"{slave['model']}_{i}"

    samples, failure = _run(slaves, steps, step_ns)
    if failure is not None:
        raise FMUError(f"{', '.join(dict.fromkeys(names))}: {failure}")

    time = np.arange(steps + 1) * step_ns / NANOSECONDS  # libcosim's own ns -> s conversion
    results = []
    for slave, columns in zip(slaves, samples):
        dtype = [("time", np.float64)] + [(v.name, TYPES[v.type][1]) for v in slave["outputs"]]
        result = np.zeros(steps + 1, dtype=dtype)
        result["time"] = time
        for variable, values in zip(slave["outputs"], columns):
            result[variable.name] = values
        results.append(result)
    return results


def _grid(stop_time, step):
    """(number of steps, step in ns), refusing grids libcosim cannot step exactly."""
    if not (math.isfinite(step) and step > 0.0):
        raise InputError(f"step = {step!r}: the communication step must be > 0 and finite")
    step_ns = round(step * NANOSECONDS)
    if step_ns < 1 or not math.isclose(step_ns / NANOSECONDS, step, rel_tol=1e-9):
        raise InputError(f"step = {step!r} is not a whole number of nanoseconds, libcosim's time unit")
    steps = round(stop_time / step) if math.isfinite(stop_time) else 0
    if steps < 1 or not math.isclose(steps * step, stop_time, rel_tol=1e-9):
        raise InputError(f"stop_time = {stop_time!r} is not a positive whole number of steps of {step!r}")
    return steps, step_ns


def _run(slaves, steps, step_ns):
    """Build, step and read one execution; return (samples, None) or (None, reason).

    Every libcosim object lives and dies in this frame. The caller raises,
    so that a traceback kept after a failure (by pytest, or a debugger)
    does not hold them: destroying a failed slave at interpreter exit
    crashes the process.
    """
    execution = CosimExecution.from_step_size(step_ns)
    # buffer every sample of the run: libcosim discards the oldest beyond the buffer
    observer = CosimObserver.create_time_series(buffer_size=steps + 1)
    execution.add_observer(observer)
    local_slaves = []  # the Python handles must outlive the run
    for slave in slaves:
        local_slave = CosimLocalSlave(fmu_path=slave["path"], instance_name=slave["instance"])
        local_slaves.append(local_slave)
        index = execution.add_local_slave(local_slave)
        if index < 0:
            return None, f"libcosim could not load {slave['path']} ({_last_error()})"
        slave["index"] = index
        for variable, value in slave["start"]:
            if variable.type == "Real":
                ok = execution.real_initial_value(index, variable.valueReference, float(value))
            else:
                ok = execution.integer_initial_value(index, variable.valueReference, int(value))
            if not ok:
                return None, f"cannot set {variable.name} = {value!r} ({_last_error()})"
        for variable in slave["outputs"]:
            observer.start_time_series(index, variable.valueReference, TYPES[variable.type][0])

    # libcosim initialises the slaves (and samples t = 0) in the first step
    if not execution.step(steps):
        reached = execution.status().current_time / NANOSECONDS
        return None, f"the step from t = {reached!r} failed ({_last_error()})"
    samples = [[_series(observer, slave["index"], variable, steps, step_ns) for variable in slave["outputs"]]
               for slave in slaves]
    return samples, None


def _last_error():
    """libcosim's last error message on one line.

    For a failed step it names the slave and the FMI call; the FMU's own
    explanation only reaches libcosim's log (stdout), printed just before.
    """
    return " ".join(get_last_error_message().split())


def _series(observer, index, variable, steps, step_ns):
    """Samples of one variable at steps 0..steps, checked against the grid.

    libcosimpy 0.0.6 trims every read by the number of step numbers equal
    to 0, which drops a real sample whenever a read includes step 0; so
    step 0 is read as the first of two samples, and steps 1..N on their own.
    """
    if TYPES[variable.type][0] is CosimVariableType.REAL:
        read = observer.time_series_real_samples
    else:
        read = observer.time_series_integer_samples
    _, first_steps, first_values = read(index, variable.valueReference, 0, 2)
    times, numbers, values = read(index, variable.valueReference, 1, steps)
    if first_steps[:1] != [0] or numbers != list(range(1, steps + 1)) or \
            times != [k * step_ns for k in range(1, steps + 1)]:
        raise RunError(f"libcosim's time series of {variable.name} does not match the "
                           f"{steps} steps of {step_ns} ns")
    return first_values[:1] + values
