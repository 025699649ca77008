"""dfwb paper end to end: every figure, the report, the verdicts; a rerun only redraws."""

import re

from dfwb.paper import run_paper

FIGURES = ["fig03_friction_nyquist", "fig04_friction_re_im", "fig05_friction_time", "fig06_friction_harmonics",
           "fig08_backlash_nyquist_eps", "fig09_backlash_nyquist_F", "fig10_backlash_re_im",
           "fig11_backlash_velocity", "fig12_backlash_harmonics"]


def test_paper_writes_every_figure_and_a_report(fmus, tmp_path):
    report = run_paper(tmp_path, jobs=2, progress=False, report=lambda message: None)
    for name in FIGURES:
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000
        assert (tmp_path / f"{name}.svg").exists()
        assert f"({name}.png)" in report.read_text()
    text = report.read_text()
    assert "w_C" in text and "w_J" in text and "w_L" in text
    assert len(re.findall(r"\*\*(agrees|does not agree)\*\*", text)) >= 8
    assert "equals its closed form (eq. 6-7) to" in text
    before = {path: path.read_bytes() for path in tmp_path.glob("data/*/results.csv")}
    assert len(before) == 6
    run_paper(tmp_path, jobs=2, progress=False, report=lambda message: None)
    assert {path: path.read_bytes() for path in before} == before  # resumed: nothing recomputed
