"""dfwb paper end to end: every figure, the report, the verdicts; a rerun only redraws."""

import re

import pytest

from dfwb.studies.reproduce import run_paper

FIGURES = ["fig03_friction_nyquist", "fig04_friction_re_im", "fig05_friction_time", "fig06_friction_harmonics",
           "fig08_backlash_nyquist_eps", "fig09_backlash_nyquist_F", "fig10_backlash_re_im",
           "fig11_backlash_velocity", "fig12_backlash_harmonics"]


@pytest.mark.slow
def test_paper_runs_its_scenes_writes_every_figure_and_a_report(fmus, tmp_path):
    cache = tmp_path / "cache"
    report = run_paper(tmp_path / "paper", jobs=2, progress=False, report=lambda message: None, cache=cache)
    for name in FIGURES:
        assert (tmp_path / "paper" / name / f"{name}.png").stat().st_size > 10_000
        assert (tmp_path / "paper" / name / f"{name}.svg").exists()
        assert f"({name}/{name}.png)" in report.read_text()
        assert (tmp_path / "paper" / name / "summary.md").exists()
    text = report.read_text()
    assert "w_C" in text and "w_J" in text and "w_L" in text
    assert len(re.findall(r"\*\*(agrees|does not agree)\*\*", text)) >= 8
    assert "equals its closed form (eq. 6-7) to" in text
    assert text.index("Fig. 3 ") < text.index("Fig. 6 ") < text.index("Fig. 9 ") < text.index("Fig. 12 ")
    before = {path: path.read_bytes() for path in (tmp_path / "paper").glob("*/results.csv")}
    assert len(before) == 9
    # the folder is up to date: nothing is recomputed or redrawn
    run_paper(tmp_path / "paper", jobs=2, progress=False, report=lambda message: None, cache=cache)
    assert {path: path.read_bytes() for path in before} == before
    # another folder: the scenes' outputs are copied from the cache; same report
    run_paper(tmp_path / "again", jobs=2, progress=False, report=lambda message: None, cache=cache)
    again = (tmp_path / "again" / "report.md").read_text()
    assert again.split("## Validity")[1] == text.split("## Validity")[1]
    for name in FIGURES:
        assert "every output copied from the cache" in (tmp_path / "again" / name / "summary.md").read_text()
        assert (tmp_path / "again" / name / "results.csv").read_bytes() == \
            (tmp_path / "paper" / name / "results.csv").read_bytes()
