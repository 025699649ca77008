"""dfwb bench end to end on one point per plant: every method measured, files written, fmu-exact exact."""

import csv

from dfwb import bench


def test_bench_measures_every_method_and_writes_its_report(fmus, tmp_path, monkeypatch):
    monkeypatch.setitem(bench.POINTS, "quick", {"friction": [(10.0, 1.0, None)],
                                                "backlash": [(50.0, 20.0, 0.5)],
                                                "static-backlash": [(50.0, 20.0, None)]})
    report = bench.run_bench(tmp_path, quick=True, repeats=1, report=lambda message: None)
    with open(tmp_path / "bench.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["plant", "method", "setting", "F", "omega", "eps", "error", "seconds"]
    for plant in ("friction", "backlash", "static-backlash"):
        methods = {r["method"] for r in rows if r["plant"] == plant}
        assert {"fmu-exact", "fmu-input", "fmu-fixedstep", "scipy-RK45", "scipy-DOP853", "scipy-LSODA",
                "scipy-Radau"} <= methods
        exact = next(r for r in rows if r["plant"] == plant and r["method"] == "fmu-exact")
        assert float(exact["error"]) < 1e-9  # against DOP853 at rtol 1e-12, or the closed form
        assert (tmp_path / f"pareto_{plant}.png").stat().st_size > 10_000
    assert {r["method"] for r in rows if r["plant"] == "friction"} >= {"fmu-karnopp"}
    text = report.read_text()
    assert "fmu-exact against the fastest method at equal or better error" in text
    assert "How the cost grows" in text and "ms per period" in text
