"""The closed loop exported as an OSP system structure: libcosim reproduces our fmpy master.

libcosim's fixed-step algorithm and :func:`dfwb.engine.closed_loop.run_loop` are the
same Jacobi scheme (read every output, set every input, step both FMUs), and
both FMUs are exact for inputs held over a step, so on the same grid the two
masters may differ only in how they count time: our master accumulates it
(t += step, off by up to ~3e-13 s after 5000 steps of 1 ms), libcosim counts
whole nanoseconds, so the FMUs are asked for end times that differ in the
last bits. Measured: 5e-14 m / 3e-13 N (static backlash) and 1.2e-12 m /
2.8e-11 N (friction), at most 4e-12 of each signal's largest magnitude.
RTOL = 1e-9 leaves a factor > 200 over that, and is 1e5 times smaller than
what one step of delay in either connection would cause (checked below).
With libcosim's clock (:class:`NanosecondClock`) our master gives libcosim's
run bit for bit: the ordering and the exchanged values are identical.
"""

import math
import xml.etree.ElementTree as ET

import control
import numpy as np
import pytest

from dfwb.engine.closed_loop import controller_values, run_loop
from dfwb.engine.transfer import parse_transfer_function
from dfwb.fmi.location import fmu_path
from dfwb.fmi.session import FMUSession
from dfwb.fmus.piecewise import PlantError
from dfwb.plants import PLANTS
from dfwb.plants import plant as find_plant

try:  # run_osp imports libcosimpy and loads its shared library
    import dfwb.fmi.cosim  # noqa: F401
    from dfwb.engine.osp import NAMESPACE, run_osp, write_osp_system
except (ImportError, OSError) as error:
    pytest.skip(f"libcosimpy cannot be imported: {error}", allow_module_level=True)

pytestmark = pytest.mark.needs_libcosim

RTOL = 1e-9  # relative to the largest magnitude of the signal
# static backlash at 128 steps per period of w = 0.9137 rad/s, rounded to libcosim's whole nanoseconds
BACKLASH_STEP = round(2 * math.pi / 0.9137 / 128 * 1e9) / 1e9
CASES = {  # plant: (controller G, initial values, step, stop time): a loop that settles into an oscillation
    "static-backlash": (lambda: control.tf([20, 40], [1, 20]), {"x0": 0.15}, BACKLASH_STEP, 372 * BACKLASH_STEP),
    "friction": (lambda: parse_transfer_function("20 + 100/s + 2*s/(0.1*s+1)"), {"x0": 0.3}, 1e-3, 5.0),
    "backlash": (lambda: parse_transfer_function("200*(s+2)/(s+20)"), {"x1_0": 0.05}, 1e-3, 5.0),
}
PID = "20 + 100/s + 2*s/(0.1*s+1)"  # the friction loop's controller: stick-slip hunting that keeps going
for _name in PLANTS:  # any other plant: that PID, from its start position (libcosim against fmpy is the point)
    CASES.setdefault(_name, (lambda: parse_transfer_function(PID), {find_plant(_name).position: 0.3}, 1e-3, 5.0))
LOOPS = list(CASES)
Q = f"{{{NAMESPACE}}}"


@pytest.fixture(scope="module")
def fmu_dir(fmus):
    return fmus["LinearSystem"].parent


class NanosecondClock(FMUSession):
    """An FMU session that keeps time as libcosim does: whole nanoseconds, in seconds at each call.

    libcosim hands an FMU t_k = k_ns / 1e9 and the step (k_ns + n) / 1e9 - k_ns / 1e9
    (its to_double_time_point and to_double_duration).
    """

    def __init__(self, fmu_path, step_ns):
        super().__init__(fmu_path)
        self.step_ns = step_ns
        self.steps = 0

    def start(self, values):
        super().start(values)
        self.steps = 0

    def step(self, size, inputs=None):
        start, end = self.steps * self.step_ns, (self.steps + 1) * self.step_ns
        self.time = start / 1e9
        super().step(end / 1e9 - start / 1e9, inputs)
        self.steps += 1


def test_every_registered_plant_has_a_loop():
    missing = [name for name in PLANTS if not find_plant(name).loop]
    assert not missing, f"no closed loop for {missing}"


@pytest.mark.parametrize("plant", LOOPS)
def test_libcosim_reproduces_the_fmpy_master(plant, fmu_dir, tmp_path):
    make_G, initial, step, stop_time = CASES[plant]
    G = make_G()
    xml_path = write_osp_system(tmp_path / "loop", plant, G, initial=initial, step=step, fmu_dir=fmu_dir)
    ours = run_loop(plant, G, step=step, stop_time=stop_time, initial=initial, fmu_dir=fmu_dir)
    theirs = run_osp(xml_path, stop_time, step)

    assert len(theirs.time) == len(ours.time) == round(stop_time / step) + 1
    np.testing.assert_allclose(theirs.time, ours.time, rtol=0, atol=1e-12)
    assert theirs.step == step
    assert theirs.position[0] == ours.position[0]
    assert theirs.force[0] == ours.force[0] == 0.0  # the controller starts at rest with u = 0 in both
    for name in ("position", "force"):
        expected, actual = getattr(ours, name), getattr(theirs, name)
        scale = np.max(np.abs(expected))
        error = np.abs(actual - expected)
        worst = int(np.argmax(error))
        assert error[worst] <= RTOL * scale, (
            f"{name} differs by {error[worst]:.3g} (tolerance {RTOL * scale:.3g}) at t = {ours.time[worst]}")
        # a step of delay would shift the settled oscillation by far more than the tolerance
        settled = expected[len(expected) // 2:]
        assert np.max(np.abs(np.diff(settled))) >= 1e5 * RTOL * scale, name
        assert np.ptp(settled) >= 0.5 * scale, name  # still oscillating: not two runs at rest


@pytest.mark.parametrize("plant", LOOPS)
def test_with_libcosims_clock_our_master_gives_libcosims_run_bit_for_bit(plant, fmu_dir, tmp_path):
    """The only difference between the masters is how they count time."""
    make_G, initial, step, stop_time = CASES[plant]
    G = make_G()
    xml_path = write_osp_system(tmp_path / "loop", plant, G, initial=initial, step=step, fmu_dir=fmu_dir)
    theirs = run_osp(xml_path, stop_time, step)
    step_ns = round(step * 1e9)
    sessions = (NanosecondClock(fmu_path(find_plant(plant), fmu_dir), step_ns),
                NanosecondClock(fmu_path("LinearSystem", fmu_dir), step_ns))
    ours = run_loop(plant, G, step=step, stop_time=stop_time, initial=initial, sessions=sessions)
    np.testing.assert_array_equal(theirs.position, ours.position)
    np.testing.assert_array_equal(theirs.force, ours.force)


def test_the_exported_file(fmu_dir, tmp_path):
    G = parse_transfer_function("20 + 100/s + 2*s/(0.1*s+1)")
    xml_path = write_osp_system(tmp_path / "loop", "friction", G, params={"Fc": 4.0}, initial={"x0": 0.3},
                                step=1e-3, fmu_dir=fmu_dir)
    assert xml_path == tmp_path / "loop" / "OspSystemStructure.xml"
    root = ET.parse(xml_path).getroot()
    assert root.tag == Q + "OspSystemStructure" and root.get("version") == "0.1"
    assert float(root.findtext(Q + "BaseStepSize")) == 1e-3
    simulators = {s.get("name"): s for s in root.iter(Q + "Simulator")}
    assert set(simulators) == {"plant", "controller"}
    assert simulators["plant"].get("source") == "FrictionMass.fmu"
    assert simulators["controller"].get("source") == "LinearSystem.fmu"
    for simulator in simulators.values():
        assert (xml_path.parent / simulator.get("source")).is_file()

    def initial_values(name):
        return {v.get("variable"): (v[0].tag.removeprefix(Q), v[0].get("value"))
                for v in simulators[name].iter(Q + "InitialValue")}

    plant = initial_values("plant")
    assert plant["x0"] == ("Real", "0.3") and plant["Fc"] == ("Real", "4.0") and plant["F"] == ("Real", "0.0")
    controller = initial_values("controller")
    expected = controller_values(G)
    assert controller.pop("order") == ("Integer", str(expected.pop("order")))
    assert {name: (kind, float(value)) for name, (kind, value) in controller.items()} == \
        {name: ("Real", value) for name, value in expected.items()}
    connections = [[(v.get("simulator"), v.get("name")) for v in c] for c in root.iter(Q + "VariableConnection")]
    assert connections == [[("plant", "x"), ("controller", "u")], [("controller", "y"), ("plant", "f")]]


def test_bad_input_is_refused_before_anything_is_written(fmu_dir, tmp_path):
    G = control.tf([20, 40], [1, 20])
    folder = tmp_path / "loop"
    with pytest.raises(PlantError, match="unknown plant"):
        write_osp_system(folder, "pendulum", G, fmu_dir=fmu_dir)
    with pytest.raises(PlantError, match="M = -1.0"):
        write_osp_system(folder, "friction", G, params={"M": -1.0}, fmu_dir=fmu_dir)
    with pytest.raises(PlantError, match="set by the describing-function engine"):
        write_osp_system(folder, "friction", G, params={"F": 1.0}, fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="improper"):
        write_osp_system(folder, "friction", control.tf([1, 0, 0], [1, 1]), fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="orders 1..8"):
        write_osp_system(folder, "friction", control.tf([1], [1] + [1] * 9), fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="the parameter x is given no value"):
        write_osp_system(folder, "friction", "20 + x", fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="whole number of nanoseconds"):
        write_osp_system(folder, "friction", G, step=2 * math.pi / 0.9137 / 128, fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="must be > 0"):
        write_osp_system(folder, "friction", G, step=0.0, fmu_dir=fmu_dir)
    assert not folder.exists()


def test_run_osp_refuses_a_step_or_file_that_does_not_match(fmu_dir, tmp_path):
    xml_path = write_osp_system(tmp_path / "loop", "friction", control.tf([20, 40], [1, 20]), step=1e-3,
                                fmu_dir=fmu_dir)
    with pytest.raises(ValueError, match="BaseStepSize"):
        run_osp(xml_path, 1.0, 2e-3)
    with pytest.raises(ValueError, match="whole number of steps"):
        run_osp(xml_path, 1.0005e-3 * 7, 1e-3)
    other = tmp_path / "other.xml"
    other.write_text(xml_path.read_text().replace('name="u"', 'name="b0"'))
    with pytest.raises(ValueError, match="not a loop written by write_osp_system"):
        run_osp(other, 1.0, 1e-3)


def test_a_step_that_truncates_wrongly_is_written_so_that_libcosim_reads_it(fmu_dir, tmp_path):
    """libcosim truncates BaseStepSize * 1e9: 15e-9 would become 14 ns, so the file says 15e-9 + 1 ulp."""
    from dfwb.engine.osp import _libcosim_ns

    assert _libcosim_ns(15e-9) == 14
    xml_path = write_osp_system(tmp_path / "loop", "friction", control.tf([1], [1, 1]), step=15e-9,
                                fmu_dir=fmu_dir)
    text = ET.parse(xml_path).getroot().findtext(Q + "BaseStepSize")
    assert _libcosim_ns(float(text)) == 15 and math.isclose(float(text), 15e-9, rel_tol=1e-15)
