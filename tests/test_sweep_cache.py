"""Sweeps in the content-addressed cache, shared with scenes both ways, and ``dfwb sweep --plot``.

A sweep's point and a scene's are one cache entry (:func:`dfwb.studies.points.df_key`): a scene over a sweep's
points computes none of them and a sweep over a scene's neither, with the same values to the bit. A corrupt
entry is rejected and computed again; a cache that cannot be written costs a warning. ``--plot`` draws the
-1/N curves into the sweep's folder, and says in one line when there are none to draw.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import dfwb
from dfwb.base.errors import RunError
from dfwb.cli import main
from dfwb.studies.cache import CacheWarning
from dfwb.studies.runner import run_scene
from dfwb.studies.scene import parse_scene
from dfwb.studies.sweep import grid, run_sweep

sys.path.insert(0, str(Path(__file__).parent))
import foreign_models  # noqa: E402

SCENE = '''
title = "shared points"
harmonics = {harmonics}
[[series]]
name = "s"
plant = "backlash"
F = [20.0, 50.0]
omega = [5.0, 20.0]
params = {{eps = 0.2}}
'''
POINTS = grid([20.0, 50.0], [5.0, 20.0], {"eps": 0.2})  # the scene's points, in its order


def scene(harmonics=True):
    return parse_scene(SCENE.format(harmonics="true" if harmonics else "false"), "shared.toml")


def scene_records(out):
    return json.loads((out / "results.json").read_text())["series"]["s"]


def entries(cache):
    return sorted((cache / "v2").rglob("*.json"))


def test_a_scene_after_a_sweep_computes_none_of_its_points(fmus, tmp_path):
    cache = tmp_path / "cache"
    records = run_sweep("backlash", POINTS, tmp_path / "sweep", jobs=1, progress=False, cache=cache)
    assert (records.computed, records.cached, records.resumed) == (4, 0, 0) and len(entries(cache)) == 4

    outcome = run_scene(scene(), tmp_path / "scene", jobs=1, cache=cache, progress=False)
    assert outcome.points == 4 and outcome.computed == 0 and outcome.cache_hits == 4
    assert scene_records(tmp_path / "scene") == list(records)  # every field, to the bit

    # a scene that records only N takes them too (N is the same with 1 harmonic or 10)
    outcome = run_scene(scene(harmonics=False), tmp_path / "n_only", jobs=1, cache=cache, progress=False)
    assert outcome.computed == 0 and outcome.cache_hits == 4
    for theirs, ours in zip(scene_records(tmp_path / "n_only"), records):
        assert theirs == dict(ours, harmonics=ours["harmonics"][:2])


def test_a_sweep_after_a_scene_computes_none_of_its_points(fmus, tmp_path):
    cache = tmp_path / "cache"
    outcome = run_scene(scene(), tmp_path / "scene", jobs=1, cache=cache, progress=False)
    assert outcome.computed == 4

    records = run_sweep("backlash", POINTS, tmp_path / "sweep", jobs=1, progress=False, cache=cache)
    assert (records.computed, records.cached, records.resumed, records.rejected) == (0, 4, 0, 0)
    assert list(records) == scene_records(tmp_path / "scene")
    # the cached points are the sweep's: in its results.csv, and resumed from there by the next run
    again = run_sweep("backlash", POINTS, tmp_path / "sweep", jobs=1, progress=False, cache=False)
    assert (again.computed, again.cached, again.resumed) == (0, 0, 4) and again == records


def test_a_sweep_after_a_scene_of_n_only_computes_the_harmonics(fmus, tmp_path):
    """A scene without harmonics keeps X_0 and X_1: a sweep, which records X_0 .. X_10, computes its points."""
    cache = tmp_path / "cache"
    run_scene(scene(harmonics=False), tmp_path / "scene", jobs=1, cache=cache, progress=False)
    records = run_sweep("backlash", POINTS, tmp_path / "sweep", jobs=1, progress=False, cache=cache)
    assert records.computed == 4 and all(len(r["harmonics"]) == 11 for r in records)
    assert [r["N_re"] for r in records] == [r["N_re"] for r in scene_records(tmp_path / "scene")]


def test_a_sweep_with_cache_false_neither_reads_nor_writes_it(fmus, tmp_path):
    cache = tmp_path / "cache"
    run_sweep("backlash", POINTS, tmp_path / "a", jobs=1, progress=False, cache=cache)
    records = run_sweep("backlash", POINTS, tmp_path / "b", jobs=1, progress=False, cache=False)
    assert records.computed == 4 and records.cached == 0 and len(entries(cache)) == 4


def test_a_corrupt_entry_is_rejected_and_its_point_computed_again(fmus, tmp_path):
    cache = tmp_path / "cache"
    first = run_sweep("friction", grid([10.0], [0.5, 1.0, 2.0]), tmp_path / "a", jobs=1, progress=False,
                      cache=cache)
    damaged = entries(cache)[0]
    damaged.write_bytes(damaged.read_bytes()[:-7])
    again = run_sweep("friction", grid([10.0], [0.5, 1.0, 2.0]), tmp_path / "b", jobs=1, progress=False,
                      cache=cache)
    assert (again.computed, again.cached, again.rejected) == (1, 2, 1)
    assert [(r["N_re"], r["N_im"], r["harmonics"]) for r in again] == \
        [(r["N_re"], r["N_im"], r["harmonics"]) for r in first]
    third = run_sweep("friction", grid([10.0], [0.5, 1.0, 2.0]), tmp_path / "c", jobs=1, progress=False,
                      cache=cache)
    assert (third.computed, third.cached, third.rejected) == (0, 3, 0)  # the entry was written again


def test_a_cache_that_cannot_be_written_costs_a_warning_not_the_sweep(fmus, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "v2").write_text("a file where the entries' folder belongs")
    with pytest.warns(CacheWarning, match="cannot be written"):
        records = run_sweep("friction", grid([10.0], [1.0, 2.0]), tmp_path / "out", jobs=1, progress=False,
                            cache=cache)
    assert records.computed == 2 and len(json.loads((tmp_path / "out" / "results.json").read_text())) == 2


def test_a_sweep_of_a_users_fmu_shares_its_points_with_a_scene(tmp_path):
    folder = tmp_path / "fmus"
    folder.mkdir()
    path = foreign_models.build("Saturation", folder)
    text = ('title = "t"\nharmonics = true\n[[series]]\nname = "s"\nplant = "Saturation.fmu"\n'
            'F = [0.5, 3.0]\nomega = [1.0]\n')
    (folder / "s.toml").write_text(text)
    cache = tmp_path / "cache"
    records = dfwb.sweep(path, dfwb.grid([0.5, 3.0], [1.0]), tmp_path / "sweep", jobs=1, cache=cache)
    assert records.computed == 2 and len(entries(cache)) == 2
    outcome = run_scene(folder / "s.toml", tmp_path / "scene", jobs=1, cache=cache, progress=False)
    assert outcome.computed == 0 and outcome.cache_hits == 2
    assert [(r["N_re"], r["N_im"], r["harmonics"]) for r in scene_records(tmp_path / "scene")] == \
        [(r["N_re"], r["N_im"], r["harmonics"]) for r in records]


# -- --plot, --cache, --no-cache --------------------------------------------------------------------------------------
def sweep_argv(out, *extra, F=("20", "50"), omega=("5", "10", "20")):
    return ["sweep", "backlash", "--F", *F, "--omega", *omega, "--grid", "eps=0.2,0.8", "--out", str(out),
            "--jobs", "1", "--quiet", *extra]


def test_cli_plot_writes_the_nyquist_figure_and_says_where(fmus, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(sweep_argv(out, "--plot", "--cache", str(tmp_path / "cache"))) == 0
    line = capsys.readouterr().out.strip()
    assert line == (f"12 points in {out}/results.csv and results.json (12 computed, 0 from the cache, 0 resumed); "
                    f"the -1/N curves in {out / 'nyquist.png'} and .svg")
    assert (out / "nyquist.png").stat().st_size > 10_000
    assert (out / "nyquist.svg").read_text().lstrip().startswith("<?xml")


def test_cli_cache_options_are_the_run_commands(fmus, tmp_path, capsys):
    cache = tmp_path / "cache"
    assert main(sweep_argv(tmp_path / "a", "--cache", str(cache))) == 0
    assert main(sweep_argv(tmp_path / "b", "--cache", str(cache))) == 0
    assert main(sweep_argv(tmp_path / "c", "--no-cache")) == 0
    counts = re.findall(r"\((\d+) computed, (\d+) from the cache, (\d+) resumed\)", capsys.readouterr().out)
    assert counts == [("12", "0", "0"), ("0", "12", "0"), ("12", "0", "0")]
    assert len(entries(cache)) == 12
    with pytest.raises(SystemExit) as stop:
        main(sweep_argv(tmp_path / "d", "--cache", str(cache), "--no-cache"))
    assert stop.value.code == 2 and "give --cache DIR or --no-cache, not both" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_cli_plot_without_any_minus_one_over_n_is_one_line_and_exit_2(fmus, tmp_path, capsys):
    """Backlash masses that never touch: N = 0 at every point, no -1/N to draw. The results are kept."""
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:
        main(["sweep", "backlash", "--F", "1", "--omega", "100", "1000", "--out", str(out), "--jobs", "1", "--quiet",
              "--no-cache", "--plot"])
    captured = capsys.readouterr()
    assert stop.value.code == 2
    assert captured.err.splitlines() == [f"dfwb sweep: error: --plot: no point has a finite -1/N (N = 0, or the point "
                                         f"failed, at every one): no curves to draw; the results are in {out}"]
    assert captured.out.startswith("2 points in")
    assert len(json.loads((out / "results.json").read_text())) == 2 and not (out / "nyquist.png").exists()


def test_the_api_draws_a_sweep(fmus, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    records = dfwb.sweep("backlash", dfwb.grid([20.0, 50.0], [5.0, 10.0, 20.0], grid_params={"eps": [0.2, 0.8]}),
                         tmp_path / "s", jobs=1, cache=False)
    lines = records.plot()
    assert len(lines) == 4 and lines[0].get_label() == "backlash: F = 20 N, eps = 0.2"
    assert len(lines[0].get_xdata()) == 3  # omega along the curve
    plt.close("all")
    png = records.figure(tmp_path / "f.png")
    assert png == tmp_path / "f.png" and png.stat().st_size > 10_000 and (tmp_path / "f.svg").exists()

    none = dfwb.sweep("backlash", dfwb.grid([1.0], [100.0]), tmp_path / "none", jobs=1, cache=False)
    assert none.plot() == []
    plt.close("all")
    with pytest.raises(RunError, match="no point of the sweep"):
        none.figure(tmp_path / "none.png")


def test_a_sweep_without_plot_does_not_load_matplotlib(fmus, tmp_path):
    probe = ("import sys\nfrom dfwb.cli import main\n"
             f"main({sweep_argv(tmp_path / 'out', '--no-cache', F=('20',), omega=('5',))!r})\n"
             "print('matplotlib' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "False"
