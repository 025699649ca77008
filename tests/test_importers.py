"""fmpy and libcosim (libcosimpy), two independent FMI importers, give the same results.

The plants are exact event-driven solvers, so on the same communication grid
both importers must agree to round-off; a difference would mean that an FMU
depends on one importer's reading of the FMI standard.
"""

import numpy as np
import pytest

from dfwb.fmi.simulation import simulate
from dfwb.fmus.plants import KINDS, TABLES
from dfwb.plants import PLANTS
from dfwb.plants import plant as find_plant

try:  # dfwb.fmi.cosim imports libcosimpy and loads its shared library
    from dfwb.fmi.cosim import simulate_cosim, simulate_cosim_together
except (ImportError, OSError) as error:
    pytest.skip(f"libcosimpy cannot be imported: {error}", allow_module_level=True)

pytestmark = pytest.mark.needs_libcosim

# plant: (start values, real outputs, integer outputs, stop time, step); the FMU is the plant's model
CASES = {
    "friction": (dict(F=10.0, omega=1.0), ["x", "v", "Ff", "Ic1", "Is1"], ["mode", "events"], 20.0, 0.1),
    "backlash": (dict(F=50.0, omega=20.0, eps=0.5), ["x1", "v1", "x2", "v2", "gap", "Ic1", "Is1"],
                 ["contact", "impacts", "events"], 1.0, 0.005),
    "static-backlash": (dict(F=50.0, omega=20.0), ["x", "y", "Ic1"], ["engaged", "events"], 1.0, 0.005),
}
for _table in TABLES:  # any other plant of dfwb: its demo's drive, its real outputs (and the first harmonic)
    _demo = find_plant(_table.name).demo
    CASES.setdefault(_table.name, (dict(F=_demo.start["F"], omega=_demo.start["omega"]) if _demo else
                                   dict(F=10.0, omega=1.0),
                                   [o.name for o in _table.outputs if not o.integer] + ["Ic1", "Is1"],
                                   [o.name for o in _table.outputs if o.integer] + ["events"], 5.0, 0.01))
PLANT_NAMES = [name for name in PLANTS if name in CASES]
RTOL = 1e-12  # relative to the largest magnitude of the output
ATOL = 1e-15


def assert_close(expected, actual, names):
    """Each column within RTOL of its largest magnitude (at least ATOL); report the worst point."""
    assert len(actual) == len(expected), f"{len(actual)} rows, expected {len(expected)}"
    for name in ["time", *names]:
        tolerance = max(RTOL * np.max(np.abs(expected[name])), ATOL)
        error = np.abs(actual[name] - expected[name])
        worst = int(np.argmax(error))
        assert error[worst] <= tolerance, (
            f"{name} differs by {error[worst]:.3g} (tolerance {tolerance:.3g}) at t = {expected['time'][worst]}: "
            f"{actual[name][worst]!r} instead of {expected[name][worst]!r}")


def test_every_plant_of_dfwb_has_a_case():
    missing = [name for name in KINDS if name not in CASES]
    assert not missing, f"no case for {missing}"


@pytest.mark.parametrize("plant", PLANT_NAMES)
def test_libcosim_matches_fmpy(fmus, plant):
    start_values, reals, integers, stop_time, step = CASES[plant]
    model = PLANTS[plant].fmu_name
    expected = simulate(fmus[model], stop_time, step, start_values=start_values, outputs=reals + integers)
    actual = simulate_cosim(fmus[model], stop_time, step, start_values=start_values, outputs=reals + integers)
    assert actual.dtype.names == expected.dtype.names
    assert len(actual) == round(stop_time / step) + 1 and actual["time"][0] == 0.0
    assert_close(expected, actual, reals)
    for name in integers:  # counts and modes: exactly equal
        np.testing.assert_array_equal(actual[name], expected[name], err_msg=name)


def test_every_plant_in_one_execution(fmus):
    """One system, a slave per plant stepping together: each gives what it gives alone (bit for bit)."""
    stop_time, step = 1.0, 0.005
    runs = [(fmus[PLANTS[plant].fmu_name], start_values, reals + integers)
            for plant, (start_values, reals, integers, _stop, _step) in CASES.items() if plant in PLANTS]
    together = simulate_cosim_together(runs, stop_time, step)
    assert len(together) == len(runs)
    for (path, start_values, outputs), result in zip(runs, together):
        alone = simulate_cosim(path, stop_time, step, start_values=start_values, outputs=outputs)
        assert result.dtype == alone.dtype
        for name in alone.dtype.names:
            np.testing.assert_array_equal(result[name], alone[name], err_msg=f"{path.stem}: {name}")
