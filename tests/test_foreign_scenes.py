"""A user's FMU as the plant of a scene: [[series]] and [[limit_cycle]] with ``plant = "path.fmu"``.

The FMUs are the small C model-exchange FMUs of :mod:`foreign_models`, with closed forms. A relative
FMU path starts from the scene file's folder; points are cached and resumed as dfwb's own plants' are,
keyed by the FMU's content; a point the FMU fails costs that point, reported, and is tried again by the
next run; what a scene cannot take yet from a user's FMU is refused in one line.
"""

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import dfwb
from dfwb.studies.runner import run_scene
from dfwb.studies.scene import SceneError, load_scene

sys.path.insert(0, str(Path(__file__).parent))
import foreign_models  # noqa: E402


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A scene folder holding the FMUs (scenes name them by relative paths)."""
    here = tmp_path_factory.mktemp("scene_fmus")
    for name in ("MassSpringDamper", "Saturation", "Crash"):
        foreign_models.build(name, here)
    return here


SERIES = """
title = "a user's FMU"
[engine]
rtol = 1e-9
[[series]]
name = "msd"
plant = "MassSpringDamper.fmu"
F = [1.0, 2.0]
omega = [0.5, 2.0, 3.0]
grid = {c = [0.2, 0.5]}
[[figure]]
name = "nyquist"
kind = "nyquist"
series = ["msd"]
"""


def write(folder, text, name="scene.toml"):
    path = folder / name
    path.write_text(text)
    return path


def test_a_series_of_an_fmu_meets_its_closed_form_and_is_cached_and_up_to_date(folder, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the FMU's path starts from the scene's folder, not from here
    scene = write(folder, SERIES)
    cache = tmp_path / "cache"
    outcome = run_scene(scene, tmp_path / "out", jobs=2, cache=cache, progress=False)
    assert outcome.points == 12 and outcome.computed == 12 and not outcome.failed
    records = __import__("json").loads((tmp_path / "out" / "results.json").read_text())["series"]["msd"]
    assert len(records) == 12
    for r in records:
        truth = foreign_models.msd_df(r["omega"], c=r["params"]["c"])
        error = abs(complex(r["N_re"], r["N_im"]) - truth)
        assert error <= r["N_error"] <= 1e-7 * abs(truth), r
    assert (tmp_path / "out" / "nyquist.png").stat().st_size > 10_000
    assert run_scene(scene, tmp_path / "out", jobs=2, cache=cache, progress=False).up_to_date
    again = run_scene(scene, tmp_path / "again", jobs=2, cache=cache, progress=False)
    assert again.computed == 0 and again.cache_hits == 12  # keyed by the FMU's content and the driver's settings
    write(folder, SERIES.replace("rtol = 1e-9", "rtol = 1e-8"))  # another tolerance: other points
    assert run_scene(scene, tmp_path / "third", jobs=2, cache=cache, progress=False).computed == 12


@pytest.mark.slow
def test_a_limit_cycle_section_of_an_fmu_gives_the_prediction_and_the_true_cycle(folder, tmp_path, monkeypatch):
    """The loop computed once, by the scene: the prediction read from its results.json, the true cycle's
    trace (which no output file holds) from the response the scene's own call of analyse returned."""
    import json

    from dfwb.studies import limit_cycles

    responses, analyse = [], limit_cycles.analyse

    def kept(*args, **kwargs):  # the scene's call, its answer kept
        responses.append(analyse(*args, **kwargs))
        return responses[-1]

    monkeypatch.setattr(limit_cycles, "analyse", kept)
    scene = write(folder, """
title = "a saturating loop"
[[limit_cycle]]
name = "loop"
plant = "Saturation.fmu"
input = "u"
output = "y"
G = "10/(s*(s+1)**2)"
F_range = [0.5, 50]
omega_range = [0.3, 3]
n_F = 5
n_omega = 6
exact = true
[[figure]]
name = "cycles"
kind = "limit_cycle"
series = ["loop"]
""", "loop.toml")
    outcome = run_scene(scene, tmp_path / "out", jobs=2, cache=False, progress=False)
    assert (tmp_path / "out" / "cycles_loop.png").stat().st_size > 10_000  # <figure>_<section>.png
    written = json.loads((tmp_path / "out" / "results.json").read_text())["limit_cycles"]["loop"]
    summary = (tmp_path / "out" / "summary.md").read_text()
    [prediction] = written["predictions"]
    assert prediction["omega"] == pytest.approx(1.0, rel=1e-7)  # the textbook answer (see test_foreign)
    assert f"{prediction['F']:.5g}" in summary and outcome.points == 0
    [response] = responses  # what the scene wrote: its one call's answer
    assert [(p.F, p.omega) for p in response.predictions] == [(prediction["F"], prediction["omega"])]
    [cycle] = response.cycles
    assert len(written["cycles"]) == 1 and written["cycles"][0]["period"] == cycle.period
    assert np.max(np.abs(cycle.trace["y"])) == pytest.approx(1.0, abs=1e-9)


def test_a_point_the_fmu_fails_costs_that_point_and_is_tried_again(folder, tmp_path):
    scene = write(folder, """
title = "a crashing FMU"
[[series]]
name = "crash"
plant = "Crash.fmu"
F = [1.0, 9.0]
omega = [1.0]
""", "crash.toml")
    with pytest.warns(RuntimeWarning, match="Crash"):
        outcome = run_scene(scene, tmp_path / "out", jobs=1, cache=False, progress=False)
    assert outcome.computed == 1 and len(outcome.failed) == 1 and "F = 9" in outcome.failed[0]
    records = __import__("json").loads((tmp_path / "out" / "results.json").read_text())["series"]["crash"]
    assert [r["F"] for r in records] == [1.0]
    assert not (tmp_path / "out" / "manifest.json").exists()  # not up to date: the next run tries F = 9 again
    with pytest.warns(RuntimeWarning, match="Crash"):
        again = run_scene(scene, tmp_path / "out", jobs=1, cache=False, progress=False)
    assert again.resumed == 1 and again.computed == 0 and len(again.failed) == 1


def test_a_scene_traces_an_fmu(folder, tmp_path):
    """A [[trace]] of a user's FMU: model exchange against the same mass-spring-damper solved by scipy from
    rest (1e-9), co-simulation (one step per sample) within the saturation's level."""
    from scipy.integrate import solve_ivp

    scene = write(folder, """
title = "traces of a user's FMU"
[[trace]]
name = "me"
plant = "MassSpringDamper.fmu"
F = 1.0
omega = 2.0
start = 5.0
stop = 20.0
step = 0.05
outputs = ["y"]
[[trace]]
name = "cs"
plant = "Saturation.fmu"
kind = "co-simulation"
F = 3.0
omega = 1.0
stop = 10.0
step = 0.01
outputs = ["y"]
[[figure]]
name = "time"
kind = "trace"
series = ["me", "cs"]
""", "traces.toml")
    run_scene(scene, tmp_path / "out", jobs=1, cache=False, progress=False)
    me = np.genfromtxt(tmp_path / "out" / "traces" / "me.csv", delimiter=",", names=True)
    assert me["time"][0] == pytest.approx(5.0) and me["time"][-1] == pytest.approx(20.0)
    exact = solve_ivp(lambda t, z: [z[1], np.cos(2 * t) - 0.2 * z[1] - 4 * z[0]], (0, 20), [0, 0], rtol=1e-12,
                      atol=1e-12, dense_output=True)
    assert np.max(np.abs(exact.sol(me["time"])[0] - me["y"])) < 1e-9
    cs = np.genfromtxt(tmp_path / "out" / "traces" / "cs.csv", delimiter=",", names=True)
    assert len(cs) == 1001 and np.max(np.abs(cs["y"])) == pytest.approx(1.0)
    assert (tmp_path / "out" / "time.png").stat().st_size > 10_000


STUDIES = """
title = "studies of a user's FMU"
[[map]]
name = "hunting"
plant = "Saturation.fmu"
G = "K*(s+z)/(s*(s+1)**2)"
F_range = [0.2, 50]
omega_range = [0.1, 5]
n_F = 3
n_omega = 4
x = {name = "K", start = 1, stop = 10, n = 2}
y = {name = "z", start = 1, stop = 3, n = 2}
[[continuation]]
name = "branch"
plant = "Saturation.fmu"
G = "K*10/(s*(s+1)**2)"
parameter = "K"
start = 0.1
stop = 1
sources = ["df"]
F_range = [0.5, 50]
omega_range = [0.3, 3]
n_F = 3
n_omega = 3
max_points = 2
[[figure]]
name = "maps"
kind = "map"
series = ["hunting"]
[[figure]]
name = "diagram"
kind = "continuation"
series = ["branch"]
"""


@pytest.mark.slow
def test_a_scene_maps_and_follows_an_fmu_loop(folder, tmp_path):
    """A hunting map (against Routh: the saturating loop hunts where K (z - 2) > 2, see test_foreign) and a
    continuation of the DF's predictions of a user's FMU, declared in a scene, drawn, and up to date after.

    Kept cheap: the classes against Routh are test_foreign's (its own 2 x 2 map), so here the smallest map a
    scene takes (2 x 2: an axis has 2 cells at least; one cell hunts, three do not) on a 3 x 4 DF map (the
    saturation's N does not depend on omega), and the branch of predictions from K = 1 (at K = 0.1 the loop
    cannot hunt: |G(j1)| = 0.5) for 2 points (test_foreign follows it over the whole range)."""
    import json

    scene = write(folder, STUDIES, "studies.toml")
    outcome = run_scene(scene, tmp_path / "out", jobs=2, cache=tmp_path / "cache", progress=False)
    cells = json.loads((tmp_path / "out" / "map_hunting" / "cells.json").read_text())["cells"]
    for source in ("truth", "df"):  # (K, z) = (1, 1), (10, 1), (1, 3), (10, 3)
        assert [c[source]["class"] for c in cells] == ["none", "none", "none", "stable"]
    branches = json.loads((tmp_path / "out" / "results.json").read_text())["continuations"]["branch"]["branches"]
    assert [(b["source"], len(b["points"]), b["points"][-1]["parameter"]) for b in branches] == [("df", 2, 1.0)]
    for name in ("maps_hunting.png", "diagram_branch.png"):
        assert (tmp_path / "out" / name).stat().st_size > 10_000
    assert "branch" in (tmp_path / "out" / "summary.md").read_text() and len(outcome.figures) == 2
    assert run_scene(scene, tmp_path / "out", jobs=2, cache=tmp_path / "cache", progress=False).up_to_date


@pytest.mark.parametrize("text, message", [
    ('[[trace]]\nname = "t"\nplant = "MassSpringDamper.fmu"\nF = 1\nomega = 1\nstop = 1\nstep = 0.1\n'
     'outputs = ["x"]', "trace[0]: output 'x' is not an output of plant"),
    ('[[series]]\nname = "s"\nplant = "friction"\ninput = "f"\nF = [1]\nomega = [1]',
     "series[0]: input, output and kind are for a plant given as an FMU: plant 'friction' is dfwb's own"),
    ('[[series]]\nname = "s"\nplant = "Missing.fmu"\nF = [1]\nomega = [1]',
     "Missing.fmu': cannot read the FMU (No such file or directory)"),
    ('[[series]]\nname = "s"\nplant = "MassSpringDamper.fmu"\noutput = "nope"\nF = [1]\nomega = [1]',
     "MassSpringDamper.fmu: no output 'nope' (its Real outputs: y)"),
    ('[[series]]\nname = "s"\nplant = "MassSpringDamper.fmu"\nparams = {k = "x"}\nF = [1]\nomega = [1]',
     "series[0].params.k: Input should be a valid number"),
    ('[[series]]\nname = "s"\nplant = "MassSpringDamper.fmu"\nparams = {q = 1}\nF = [1]\nomega = [1]',
     "no parameter 'q' (its parameters: M, c, k)"),
    ('[[series]]\nname = "s"\nplant = "Saturation.fmu"\noutput = "y"\nF = [1]\nomega = [1]\n'
     '[[series]]\nname = "t"\nplant = "Saturation.fmu"\nF = [1]\nomega = [1]',
     "here and (None, 'y', None) before: one input, output and kind per FMU in a scene"),
    ('[[limit_cycle]]\nname = "l"\nplant = "Saturation.fmu"\nG = "1/s"', "give F_range and omega_range"),
    ('[[limit_cycle]]\nname = "l"\nplant = "Saturation.fmu"\nG = "1/s"\nF_range = [1, 2]\nomega_range = [1, 2]\n'
     'verify = true', "verify runs dfwb's own closed-loop FMUs"),
    ('[[map]]\nname = "m"\nplant = "Saturation.fmu"\nG = "K*(s+z)/(s*(s+1)**2)"\n'
     'x = {name = "K", start = 1, stop = 2, n = 2}\ny = {name = "z", start = 1, stop = 2, n = 2}',
     "map[0]: give F_range and omega_range"),
    ('[[continuation]]\nname = "c"\nplant = "friction"\nG = "K/s"\nparameter = "K"\nstart = 1\nstop = 2\n'
     'F_range = [1, 2]', "continuation[0]: F_range: for a user's FMU only"),
    ('[engine]\nrtol = 1e-6\n[[series]]\nname = "s"\nplant = "friction"\nF = [1]\nomega = [1]',
     "engine: rtol is the tolerance of a user's FMU: this scene names none"),
    ('[engine]\nrtol = 1\n[[series]]\nname = "s"\nplant = "friction"\nF = [1]\nomega = [1]', "engine.rtol: Input should be less than or equal to 0.01 (got 1)"),
])
def test_a_scene_refuses_what_it_cannot_do_with_an_fmu_in_one_line(folder, text, message):
    path = write(folder, 'title = "bad"\n' + text, "bad.toml")
    with pytest.raises(SceneError) as error:
        load_scene(path)
    assert message in str(error.value) and "\n" not in str(error.value) and str(path) in str(error.value)


def test_an_fmu_path_outside_the_scene_folder_is_taken_as_written(folder, tmp_path):
    """An absolute path is used as it is; a scene copied elsewhere keeps naming its own folder's FMUs."""
    copy = tmp_path / "elsewhere"
    copy.mkdir()
    shutil.copy(folder / "MassSpringDamper.fmu", copy / "MassSpringDamper.fmu")
    text = 'title = "t"\n[[series]]\nname = "s"\nplant = "{}"\nF = [1]\nomega = [1]\n'
    scene = load_scene(write(tmp_path, text.format(copy / "MassSpringDamper.fmu")))
    assert scene.series[0].plant == str(copy / "MassSpringDamper.fmu")
    scene = load_scene(write(copy, text.format("MassSpringDamper.fmu")))
    assert scene.plant(scene.series[0].plant).info.digest == dfwb.fmu_plant(folder / "MassSpringDamper.fmu").info.digest


def test_a_scene_chooses_how_an_fmu_runs(folder):
    text = 'title = "t"\n[[series]]\nname = "s"\nplant = "Saturation.fmu"\n{}F = [3]\nomega = [1]\n'
    default = load_scene(write(folder, text.format(""), "kind.toml"))
    assert default.plant(default.series[0].plant).kind == "model-exchange"  # the best it offers
    chosen = load_scene(write(folder, text.format('kind = "co-simulation"\n'), "kind.toml"))
    assert chosen.plant(chosen.series[0].plant).kind == "co-simulation"
