"""The closed loop as an OSP system structure, run by libcosim.

:func:`write_osp_system` exports the loop of :mod:`dfwb.engine.closed_loop` (a
plant FMU and ``LinearSystem.fmu`` loaded with -G, force = -G(s) position)
as an ``OspSystemStructure.xml`` next to copies of the two FMUs, so that
any OSP tool (libcosim, cosim-cli, the OSP demo app) runs the same system;
:func:`run_osp` runs such a file with libcosim (libcosimpy) and returns the
trajectories shaped like :class:`dfwb.engine.closed_loop.LoopRun`.

libcosim's fixed-step algorithm is the Jacobi scheme of
:func:`dfwb.engine.closed_loop.run_loop` (read every output, set every input, step
every FMU), with two differences of bookkeeping that :func:`run_osp`
accounts for:

* libcosim samples a variable *after* the step, so its time series of the
  plant input ``f`` at step k holds the force applied over the step that
  *ended* at t_k; the force held over [t_k, t_k + step] is the sample at
  step k + 1 (and, at the last point, the controller output ``y`` that
  would be sent next).
* libcosim counts time in whole nanoseconds and converts the file's
  ``BaseStepSize`` by truncation, so the step must be a whole number of
  nanoseconds; the file is written so that it truncates to that number.

Otherwise the two masters exchange the same values in the same order: with
libcosim's clock, :func:`~dfwb.engine.closed_loop.run_loop` reproduces a run of
libcosim bit for bit (tests/test_osp.py). At t = 0 this rests on the plant
FMUs reporting 0 for their outputs in initialisation mode (x0 only after
fmi2ExitInitializationMode): libcosim's initial propagation then gives the
controller u = 0, and the force over the first step is G's output at rest,
0, as in run_loop. A plant reporting x0 there would make libcosim apply
b0 x0 over the first step (b0: the feedthrough of -G), unlike run_loop.
"""

import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import fmpy
import numpy as np

from dfwb.base.errors import InputError, RunError
from dfwb.engine.closed_loop import CONTROLLER, LoopRun, controller_values
from dfwb.engine.transfer import check_transfer_function, parse_transfer_function
from dfwb.fmi.location import fmu_path
from dfwb.plants import plant as find_plant

NAMESPACE = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
FILE_NAME = "OspSystemStructure.xml"
PLANT_INSTANCE, CONTROLLER_INSTANCE = "plant", "controller"  # Simulator names
NANOSECONDS = 1_000_000_000


def write_osp_system(folder, plant, G, params=None, initial=None, step=1e-3, fmu_dir=None):
    """Write the closed loop plant + controller (force = -G(s) position) as an OSP system.

    Parameters
    ----------
    folder : str or Path
        Created if missing; receives copies of the two FMUs and
        ``OspSystemStructure.xml``, which names them by relative path.
    plant : str
        A plant name of :mod:`dfwb.plants.registry` (``friction``, ``backlash``, ...).
    G : control.TransferFunction or str
        The controller G(s), proper, of order 1..8; a string is parsed by
        :func:`dfwb.engine.transfer.parse_transfer_function`.
    params, initial : dict, optional
        Plant parameters and initial state (e.g. ``{"x0": 0.3}``), as for
        :func:`dfwb.engine.closed_loop.run_loop`.
    step : float
        Communication step (``BaseStepSize``), a whole number of nanoseconds.
    fmu_dir : str or Path
        Where the FMUs are built.

    Returns
    -------
    Path
        The written ``OspSystemStructure.xml``.

    Raises
    ------
    PlantError
        For an unknown plant or a bad parameter value.
    ValueError
        For a G(s) the controller FMU cannot take, or a step libcosim cannot step.
    """
    spec = find_plant(plant)
    if isinstance(G, str):
        G = parse_transfer_function(G)
    G = check_transfer_function(G)
    controller = controller_values(G)
    plant_values = dict(spec.defaults(), **spec.check(dict(params or {}, **(initial or {}))), F=0.0)
    step_text = _step_text(step)

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    sources = {}
    fmus = {PLANT_INSTANCE: fmu_path(spec, fmu_dir), CONTROLLER_INSTANCE: fmu_path(CONTROLLER, fmu_dir)}
    for name, path in fmus.items():
        if not (folder / path.name).exists() or not (folder / path.name).samefile(path):
            shutil.copyfile(path, folder / path.name)
        sources[name] = path.name

    ET.register_namespace("", NAMESPACE)
    q = lambda tag: f"{{{NAMESPACE}}}{tag}"  # noqa: E731
    root = ET.Element(q("OspSystemStructure"), version="0.1")
    ET.SubElement(root, q("StartTime")).text = "0.0"
    ET.SubElement(root, q("BaseStepSize")).text = step_text
    ET.SubElement(root, q("Algorithm")).text = "fixedStep"
    simulators = ET.SubElement(root, q("Simulators"))
    for name, values in ((PLANT_INSTANCE, plant_values), (CONTROLLER_INSTANCE, controller)):
        simulator = ET.SubElement(simulators, q("Simulator"), name=name, source=sources[name])
        initial_values = ET.SubElement(simulator, q("InitialValues"))
        for variable, value in values.items():
            element = ET.SubElement(initial_values, q("InitialValue"), variable=variable)
            if variable == "order":
                ET.SubElement(element, q("Integer"), value=str(int(value)))
            else:
                ET.SubElement(element, q("Real"), value=repr(float(value)))
    connections = ET.SubElement(root, q("Connections"))
    for (source, output), (target, input_) in (((PLANT_INSTANCE, spec.output), (CONTROLLER_INSTANCE, "u")),
                                               ((CONTROLLER_INSTANCE, "y"), (PLANT_INSTANCE, "f"))):
        connection = ET.SubElement(connections, q("VariableConnection"))
        ET.SubElement(connection, q("Variable"), simulator=source, name=output)
        ET.SubElement(connection, q("Variable"), simulator=target, name=input_)
    ET.indent(root)
    xml_path = folder / FILE_NAME
    ET.ElementTree(root).write(xml_path, encoding="utf-8", xml_declaration=True)
    return xml_path


def _step_text(step):
    """``BaseStepSize`` text that libcosim truncates to exactly the step's nanoseconds."""
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0.0):
        raise InputError(f"step = {step!r}: the communication step must be > 0 and finite")
    step_ns = round(step * NANOSECONDS)
    if step_ns < 1 or not math.isclose(step_ns / NANOSECONDS, step, rel_tol=1e-9):
        raise InputError(f"step = {step!r} is not a whole number of nanoseconds, libcosim's time unit "
                         f"(nearest: {step_ns / NANOSECONDS!r})")
    seconds = step_ns / NANOSECONDS
    if _libcosim_ns(seconds) != step_ns:  # e.g. 15e-9 * 1e9 = 14.999...: step up by one ulp
        seconds = math.nextafter(seconds, math.inf)
    assert _libcosim_ns(float(repr(seconds))) == step_ns
    return repr(seconds)


def _libcosim_ns(seconds):
    """libcosim's to_duration: duration_cast<nanoseconds>(duration<double>), a truncation."""
    return int(seconds * 1e9)


def run_osp(xml_path, stop_time, step):
    """Run an OSP system written by :func:`write_osp_system` with libcosim.

    Parameters
    ----------
    xml_path : str or Path
        The ``OspSystemStructure.xml``.
    stop_time : float
        End of the run, a whole number of steps (the run starts at 0).
    step : float
        The communication step; it must be the file's ``BaseStepSize``.

    Returns
    -------
    dfwb.engine.closed_loop.LoopRun
        The plant output and the plant input ``f`` at every communication
        point, ``force[k]`` being the force held over [t_k, t_k + step], as
        :func:`dfwb.engine.closed_loop.run_loop` records them.

    Raises
    ------
    ValueError
        For a file that is not such a loop, or a step or stop time that
        does not match it.
    dfwb.fmi.simulation.FMUError
        When libcosim cannot load the system or a step fails.
    RuntimeError
        When libcosim's samples contradict the connections (a bug, not bad input).

    Notes
    -----
    An FMU that fails during initialisation aborts the whole Python process
    in libcosim 0.11 (see :mod:`dfwb.fmi.cosim`); files from
    :func:`write_osp_system` carry only validated values.
    """
    from dfwb.fmi.cosim import _grid  # imports libcosimpy and lowers its log level
    from dfwb.fmi.simulation import FMUError

    xml_path = Path(xml_path).resolve()
    system = _read_system(xml_path)
    steps, step_ns = _grid(stop_time, step)
    if _libcosim_ns(system["step"]) != step_ns:
        raise InputError(f"step = {step!r}, but {xml_path} has BaseStepSize {system['step']!r}")
    samples, failure = _run(xml_path, system, steps)
    if failure is not None:
        raise FMUError(f"{xml_path}: {failure}")
    position, plant_f, controller_u, controller_y = (np.asarray(column, dtype=float) for column in samples)
    # libcosim samples after each step: the input f sampled at step k + 1 is the force held
    # over [t_k, t_k + step]; it must be the controller output at t_k, unchanged, and the
    # controller's input over that step the plant output at t_k (the Jacobi exchange).
    if not (np.array_equal(plant_f[1:], controller_y[:-1]) and np.array_equal(controller_u[1:], position[:-1])):
        raise RunError(f"{xml_path}: libcosim's inputs are not the other FMU's outputs one step earlier")
    force = np.concatenate([plant_f[1:], controller_y[-1:]])  # the last: what would be sent next
    time = np.arange(steps + 1) * step_ns / NANOSECONDS
    return LoopRun(time, position, force, step_ns / NANOSECONDS)


def _read_system(xml_path):
    """The loop in an OSP file: the base step, the two FMUs and the observed variables."""
    try:
        root = ET.parse(xml_path).getroot()
    except (OSError, ET.ParseError) as error:
        raise InputError(f"cannot read {xml_path}: {error}") from None
    q = lambda tag: f"{{{NAMESPACE}}}{tag}"  # noqa: E731
    if root.tag != q("OspSystemStructure"):
        raise InputError(f"{xml_path} is not an OSP system structure ({NAMESPACE})")
    try:
        base_step = float(root.findtext(q("BaseStepSize")))
    except (TypeError, ValueError):
        raise InputError(f"{xml_path}: no valid BaseStepSize") from None
    sources = {s.get("name"): xml_path.parent / s.get("source", "")
               for s in root.iter(q("Simulator"))}
    links = {}
    for connection in root.iter(q("VariableConnection")):
        ends = [(v.get("simulator"), v.get("name")) for v in connection.findall(q("Variable"))]
        if len(ends) == 2:
            links[ends[1]] = ends[0]
    plant, controller = PLANT_INSTANCE, CONTROLLER_INSTANCE
    plant_output = links.get((controller, "u"))
    if set(sources) != {plant, controller} or plant_output is None or plant_output[0] != plant \
            or links.get((plant, "f")) != (controller, "y"):
        raise InputError(f"{xml_path} is not a loop written by write_osp_system: simulators {plant!r} and "
                         f"{controller!r}, {plant}.<output> -> {controller}.u, {controller}.y -> {plant}.f")
    observed = []
    for simulator, name in ((plant, plant_output[1]), (plant, "f"), (controller, "u"), (controller, "y")):
        try:
            description = fmpy.read_model_description(str(sources[simulator]))
        except Exception as error:  # fmpy raises plain Exceptions for a missing or bad FMU
            raise InputError(f"{xml_path}: cannot read the FMU of {simulator!r}: {error}") from None
        variable = {v.name: v for v in description.modelVariables}.get(name)
        if variable is None or variable.type != "Real":
            raise InputError(f"{xml_path}: {simulator} has no Real variable {name!r}")
        observed.append((simulator, variable))
    return {"step": base_step, "observed": observed}


def _run(xml_path, system, steps):
    """Load, step and read one execution; return (samples, None) or (None, reason).

    As in :func:`dfwb.fmi.cosim._run`, every libcosim object lives and dies in
    this frame, so that a traceback kept after a failure does not hold them.
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    from dfwb.fmi.cosim import _last_error, _series

    try:
        execution = CosimExecution.from_osp_config_file(str(xml_path))
    except AssertionError:  # libcosimpy asserts on a failed load
        return None, f"libcosim cannot load the system ({_last_error()})"
    observer = CosimObserver.create_time_series(buffer_size=steps + 1)  # every sample of the run
    execution.add_observer(observer)
    observed = []
    for simulator, variable in system["observed"]:
        index = execution.slave_index_from_instance_name(simulator)
        observer.start_time_series(index, variable.valueReference, CosimVariableType.REAL)
        observed.append((index, variable))
    # libcosim initialises the slaves (and samples t = 0) in the first step
    if not execution.step(steps):
        reached = execution.status().current_time / NANOSECONDS
        return None, f"the step from t = {reached!r} failed ({_last_error()})"
    step_ns = _libcosim_ns(system["step"])
    return [_series(observer, index, variable, steps, step_ns) for index, variable in observed], None
