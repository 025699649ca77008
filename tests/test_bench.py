"""dfwb bench end to end on one point per plant: every method measured, files written, the exact FMUs exact."""

import csv
import functools

import pytest

from dfwb.engine import describing
from dfwb.plants import PLANTS, builtin
from dfwb.verify import bench, foreign_bench

SCIPY = {f"scipy-{method}" for method in bench.SCIPY_METHODS}
EXACT = {"fmu-native", "fmu-python-core", "fmu-pure-python"}  # native FMU; pythonfmu on its C core; pure Python
BENCHED = [entry.name for entry in PLANTS.values() if entry.reference is not None and entry.bench.get("quick")]


def test_every_registered_plant_has_what_the_benchmark_needs():
    """The built-in plants have points, a reference, a naive twin and a scipy rival; the points are well formed."""
    for entry in (builtin.FRICTION, builtin.BACKLASH, builtin.STATIC_BACKLASH):
        assert entry.name in BENCHED and entry.naive is not None and entry.scipy is not None
    for entry in PLANTS.values():
        for which in entry.bench:
            for F, omega, params in entry.bench[which]:
                assert F > 0 and omega > 0 and isinstance(params, dict), (entry.name, which)
                entry.check(params)


@pytest.mark.slow
def test_bench_measures_every_method_and_writes_its_report(fmus, tmp_path, monkeypatch):
    for name in BENCHED:  # one point per plant: its first quick one
        monkeypatch.setitem(PLANTS[name].bench, "quick", PLANTS[name].bench["quick"][:1])
    # the cost per event timed once, not the median of EVENT_REPEATS: its rows are checked here, not its timing
    monkeypatch.setattr(bench, "event_cost", functools.partial(bench.event_cost, repeats=1))
    folders = []  # the FMU folder of every FMU the benchmark runs (its exact kinds and its other engines)
    for module in (bench, describing, foreign_bench):
        def recorded(model, fmu_dir=None, kind=None, found=module.fmu_path):
            folders.append(fmu_dir)
            return found(model, fmu_dir, kind=kind)
        monkeypatch.setattr(module, "fmu_path", recorded)
    folder = fmus["FrictionMass"].parent
    report = bench.run_bench(tmp_path, quick=True, repeats=1, report=lambda message: None, fmu_dir=folder)
    assert folders and set(folders) == {folder}  # dfwb bench --fmus DIR: every FMU from DIR
    with open(tmp_path / "bench.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["plant", "method", "setting", "F", "omega", "eps", "error", "seconds"]
    for plant in BENCHED:
        entry = PLANTS[plant]
        methods = {r["method"] for r in rows if r["plant"] == plant}
        expected = EXACT | {"fmu-input"}
        expected |= {"fmu-fixedstep"} if entry.naive is not None else set()
        expected |= SCIPY if entry.scipy is not None else set()
        expected |= {"fmu-karnopp"} if entry.variants else set()
        assert methods == expected, plant
        exact = {r["method"]: r for r in rows if r["plant"] == plant and r["method"] in EXACT}
        assert float(exact["fmu-native"]["error"]) < 1e-9  # against DOP853 at rtol 1e-12, or the closed form
        assert len({r["error"] for r in exact.values()}) == 1, plant  # the same N bit for bit, whatever the kind
        assert (tmp_path / f"pareto_{plant}.png").stat().st_size > 10_000
    assert {r["method"] for r in rows if r["plant"] == "friction"} >= {"fmu-karnopp"}
    text = report.read_text()
    assert "fmu-native against the fastest method at equal or better error" in text
    assert "## Cost per event" in text
    for plant in BENCHED:
        for method in EXACT:  # every plant has its cost per event for each exact kind
            assert f"| {plant} | {method} |" in text, (plant, method)
    assert "How the cost grows" in text and "ms per period" in text
    # a user's FMU: small C model-exchange FMUs at 1e-8, the native FMUs as black-box co-simulation at 1e-6
    with open(tmp_path / "foreign.csv") as handle:
        foreign = list(csv.DictReader(handle))
    kinds = {(r["kind"], r["plant"]) for r in foreign}
    assert kinds == {("model-exchange", m) for m in ("MassSpringDamper", "Saturation", "Relay")} | {
        ("co-simulation", plant) for plant in BENCHED}
    for row in foreign:
        error, estimate = float(row["error"]), float(row["N_error"])
        assert error <= estimate, row  # the reported error is honest
        assert error < (1e-7 if row["kind"] == "model-exchange" else 1e-4), row
    assert "## A user's FMU through the generic driver" in text
    assert f"below `N_error` at {len(foreign)} of {len(foreign)} points" in text


@pytest.mark.parametrize("plant", [name for name in BENCHED if PLANTS[name].scipy is not None])
def test_the_scipy_rival_approaches_the_reference(plant):
    """What a user would write with solve_ivp agrees with the plant's reference at a tight tolerance."""
    entry = PLANTS[plant]
    F, omega, params = entry.bench["quick"][0]
    truth = entry.reference(F, omega, dict(params))
    assert abs(entry.scipy(F, omega, dict(params), "DOP853", 1e-9) - truth) <= 1e-5 * abs(truth)
