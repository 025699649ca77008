"""Every FMU dfwb builds gives the outputs recorded before a change, to the bit.

The guard of a redesign that must not change a number (issue 32: one plant table behind the FMUs, the C
core and the loops): each FMU - the pythonfmu plants, their naive twins, LinearSystem, the exact closed
loops, the native plant FMUs as FMI 2.0 and 3.0 - is simulated by fmpy over a few forcing periods and
every output at every communication point is compared with ``tests/data/recorded_outputs.json`` (floats
as ``float.hex``); a plant added since has no record (its own tests check it). A change that is meant to change the numbers records them again, on purpose:
``python tests/test_recorded_outputs.py`` (with the FMUs built, as ``make test`` builds them).
"""

import json
import math
import sys
from pathlib import Path

import fmpy

RECORD = Path(__file__).parent / "data" / "recorded_outputs.json"
# start values per model (the others its defaults): each plant forced so that it sticks, slips, impacts
START = {
    "FrictionMass": {"F": 10.0, "omega": 1.0},
    "NaiveFrictionMass": {"F": 10.0, "omega": 1.0},
    "TwoMassBacklash": {"F": 50.0, "omega": 20.0},
    "NaiveTwoMassBacklash": {"F": 50.0, "omega": 20.0},
    "StaticBacklash": {"F": 3.0, "omega": 2.0},
    "NaiveStaticBacklash": {"F": 3.0, "omega": 2.0},
    # the loops under their controllers (tests/test_loop_fmu_native.py's first cases): hunting, impacts, engagements
    "FrictionMassLoop": {"order": 2, "b0": 40.0, "b1": 600.0, "b2": 1200.0, "a1": 20.0, "x0": 1.0},
    "TwoMassBacklashLoop": {"order": 1, "b0": 40.0, "b1": 400.0, "a1": 20.0, "x1_0": 1.0, "eps": 0.5},
    "StaticBacklashLoop": {"order": 1, "b0": 100.0, "b1": 400.0, "a1": 20.0, "x0": 1.0, "z1_0": 0.01},
}
PERIODS, POINTS = 3, 24  # simulated periods of the force (of omega = 1 where it has none), communication points


def _outputs(path):
    return [v.name for v in fmpy.read_model_description(str(path)).modelVariables if v.causality == "output"]


def simulate(path, model):
    """[[t, outputs...] as float.hex] at POINTS communication points over PERIODS periods."""
    start = START.get(model, {})
    stop = PERIODS * 2 * math.pi / start.get("omega", 1.0)
    result = fmpy.simulate_fmu(str(path), stop_time=stop, output_interval=stop / POINTS, start_values=start,
                               output=_outputs(path))
    return [[float(value).hex() for value in row] for row in result.tolist()]


def fmus_of(fmus, native_fmus, fmi3_fmus):
    """{"<kind>/<Model>": path} of every FMU dfwb builds."""
    found = {f"pythonfmu/{name}": path for name, path in fmus.items()}
    found.update({f"native-fmi2/{name}": path for name, path in native_fmus.items()})
    found.update({f"native-fmi3/{name}": path for name, path in fmi3_fmus.items()})
    return dict(sorted(found.items()))


def test_every_fmu_gives_the_recorded_outputs(fmus, native_fmus, fmi3_fmus):
    recorded = json.loads(RECORD.read_text())
    found = fmus_of(fmus, native_fmus, fmi3_fmus)
    missing = sorted(set(recorded) - set(found))
    assert not missing, f"FMUs recorded are no longer built: {missing}"  # a new plant's FMUs have no record
    changed = []
    for key in recorded:
        path = found[key]
        rows = simulate(path, key.split("/")[1])
        if rows != recorded[key]:
            first = next((i for i, (a, b) in enumerate(zip(rows, recorded[key])) if a != b), len(rows))
            changed.append(f"{key}: row {first} of {len(rows)}")
    assert not changed, f"outputs changed (not to the bit): {changed}"


if __name__ == "__main__":  # record again, on purpose
    sys.path.insert(0, str(Path(__file__).parent))
    import conftest

    fmus = conftest.project_fmus()
    found = fmus_of(fmus, conftest.native_of(2, fmus), conftest.native_of(3, fmus))
    RECORD.parent.mkdir(exist_ok=True)
    rows = {key: simulate(path, key.split("/")[1]) for key, path in found.items()}
    RECORD.write_text("{\n" + ",\n".join(f"{json.dumps(key)}: {json.dumps(value)}" for key, value in rows.items())
                      + "\n}\n")
    print(f"{RECORD}: {len(found)} FMUs recorded", file=sys.stderr)
