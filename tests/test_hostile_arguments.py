"""Hostile arguments (issue 31): each answered with the right result, or exit 2 and one line naming the value.

- A continuation's range far wider than its branch (Ki = 1:1e4, 1:1e8, 1:1e308) follows the branch a range
  of 1:30 follows, to the same nonsmooth fold near Ki = 24.77: the parameter's scale in the arclength is
  its size where the branch is, not the range's width (before: 1 point at 1e8, no branch at 1e308).
- A G that no end of a continuation's range, and no corner of a map, makes a controller ("Kp/0 + Ki") is
  refused before anything runs or is written, by the check ``dfwb limit-cycle`` makes.
- An empty --out (and every other folder, file or name option) is refused, never read as the current folder.
- A name is what is written: a G whose name is not ASCII ("K𝐢", which Python's parser folds into "Ki") is
  refused, as --set, --x and --y refuse it (no parameter has that name).
"""

import os
from pathlib import Path

import pytest
from refusals import refused

import dfwb

PI = "Kp + Ki/s"
FOLD = 24.773045  # the nonsmooth fold of the PI-controlled friction mass at Kp = 10 (tests/test_continuation.py)
NAMES = "Kp, Ki, M, B, Fc, Fs, Dv"  # G's and the friction plant's parameters, as the refusals list them


@pytest.mark.parametrize("hi", [1e4, 1e8, 1e308])
def test_a_range_far_wider_than_the_branch_follows_the_same_branch(hi):
    response = dfwb.continuation("friction", PI, "Ki", 1.0, hi, Kp=10, sources="truth", starts=[1.0])
    (branch,) = response.branches
    assert len(branch.points) > 20 and max(p.parameter for p in branch.points) == pytest.approx(FOLD, abs=1e-4)
    kinds = {b.kind: b for b in response.bifurcations}
    assert kinds["nonsmooth-fold"].parameter == pytest.approx(FOLD, abs=1e-4)
    assert kinds["nonsmooth-fold"].accuracy < 1e-4  # relative to the branch, not to the range's width
    assert kinds["infinity"].parameter == pytest.approx(5.0, rel=1e-6)  # Routh: Ki = B Kp / M


def test_the_scale_of_the_parameter_is_the_branch_s_bounded_by_the_range():
    from dfwb.engine.continuation import parameter_scale

    assert parameter_scale(29.0, 1.0) == 29.0  # a range of 1:30 is followed as before
    assert parameter_scale(1e308, 1.0) == parameter_scale(1e8, 1.0) == 30.0  # wider ones: as wide as the branch
    assert parameter_scale(1e308, 1e307) == 1e308 and parameter_scale(1e308, 0.0) > 0.0  # near 0: FLOOR


@pytest.mark.parametrize("command, message", [
    (["continue", "friction", "--G", "Kp/0 + Ki", "--set", "Kp=10", "--parameter", "Ki=1:30"],
     "G(s) = Kp/0 + Ki: division by zero, at both ends of the range (Ki = 1; Ki = 30)"),
    (["continue", "friction", "--G", "Kp/0 + Ki/s", "--set", "Kp=10", "--parameter", "Ki=1:30"],
     "G(s) = Kp/0 + Ki/s: division by zero, at both ends of the range"),
    (["map", "friction", "--G", "Kp/0 + Ki", "--x", "Kp=1:50:3", "--y", "Ki=0.1:25:3"],
     "G(s) = Kp/0 + Ki: division by zero, at every corner of the map (Kp = 1, Ki = 0.1; "),
    (["map", "friction", "--G", "Kp/0 + Ki/s", "--x", "Kp=1:50:3", "--y", "Fs=8:9:3", "--set", "Ki=1"],
     "G(s) = Kp/0 + Ki/s: division by zero, at every corner of the map"),
    (["limit-cycle", "friction", "--G", "Kp/0 + Ki", "--set", "Kp=10", "Ki=1"], "G(s) = Kp/0 + Ki: division by zero"),
])
def test_a_g_that_is_no_controller_anywhere_is_refused_before_anything_is_written(capsys, tmp_path, monkeypatch,
                                                                                  command, message):
    monkeypatch.chdir(tmp_path)
    line = refused(capsys, *command)
    assert message in line, line
    assert os.listdir(tmp_path) == []  # no out/maps/... written


@pytest.mark.parametrize("section, message", [
    ('[[continuation]]\nname = "c"\nplant = "friction"\nG = "Kp/0 + Ki/s"\nparams = {Kp = 10}\n'
     'parameter = "Ki"\nstart = 1\nstop = 30\n', "at both ends of the range (Ki = 1; Ki = 30)"),
    ('[[map]]\nname = "m"\nplant = "friction"\nG = "Kp/0 + Ki/s"\nx = {name = "Kp", start = 1, stop = 50, n = 2}\n'
     'y = {name = "Ki", start = 0.1, stop = 25, n = 2}\n', "at every corner of the map (Kp = 1, Ki = 0.1; "),
])
def test_a_scene_whose_g_is_no_controller_anywhere_is_refused_when_read(capsys, tmp_path, monkeypatch, section,
                                                                         message):
    monkeypatch.chdir(tmp_path)
    Path("scene.toml").write_text('title = "t"\n\n' + section)
    line = refused(capsys, "run", "scene.toml", "--out", "o")
    assert "G(s) = Kp/0 + Ki/s: division by zero" in line and message in line, line
    assert os.listdir(tmp_path) == ["scene.toml"]  # nothing written: refused as the scene is read


def test_a_g_refused_at_one_end_only_is_followed_from_the_other():
    response = dfwb.continuation("friction", "Kp/Ki + 1/s", "Ki", 0.0, 2.0, Kp=1, sources="df")
    assert any("Ki = 0: G(s) = Kp/Ki + 1/s: division by zero" in note for note in response.notes)


OUT = [  # every command with a folder option, given as ''
    ["build", "--out"], ["sweep", "friction", "--F", "10", "--omega", "1", "--out"],
    ["map", "friction", "--G", PI, "--x", "Kp=1:50:2", "--y", "Ki=0.1:25:2", "--out"], ["examples", "--out"],
    ["bench", "--out"], ["run", "scene.toml", "--out"], ["paper", "--out"], ["demo", "--out"],
    ["paper", "--cache"], ["df", "friction", "--F", "10", "--omega", "1", "--fmus"],
]


@pytest.mark.parametrize("command", OUT, ids=lambda command: " ".join(command[:1] + command[-1:]))
@pytest.mark.parametrize("empty", ["", "  "])
def test_an_empty_folder_is_refused_never_the_current_one(capsys, tmp_path, monkeypatch, command, empty):
    monkeypatch.chdir(tmp_path)
    line = refused(capsys, *command, empty)
    assert f"argument {command[-1]}: {empty!r} is empty: give a folder (. for the current one)" in line, line
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("command, option", [
    (["limit-cycle", "friction", "--G", PI, "--set", "Kp=10", "Ki=2"], "--plot"),
    (["continue", "friction", "--G", PI, "--set", "Kp=10", "--parameter", "Ki=1:30"], "--plot"),
    (["margin", "friction", "--G", PI, "--set", "Kp=10", "Ki=2"], "--plot"),
    (["map", "friction", "--G", PI, "--x", "Kp=1:50:2", "--y", "Ki=0.1:25:2"], "--dask"),
    (["df", "model.fmu", "--F", "10", "--omega", "1"], "--input"),
    (["df", "model.fmu", "--F", "10", "--omega", "1"], "--output"),
])
def test_an_empty_name_is_refused_not_dropped(capsys, tmp_path, monkeypatch, command, option):
    monkeypatch.chdir(tmp_path)
    line = refused(capsys, *command, option, "")
    assert f"argument {option}: '' is empty: give " in line, line
    assert os.listdir(tmp_path) == []


def test_an_empty_folder_is_refused_by_the_api(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(dfwb.InputError, match=r"out_dir = '' is empty: give a folder"):
        dfwb.sweep("friction", dfwb.grid([10.0], [1.0]), "", jobs=1, cache=False)
    with pytest.raises(dfwb.InputError, match=r"out_dir = ' ' is empty"):
        dfwb.hunting_map("friction", PI, ("Kp", 1, 50, 2), ("Ki", 0.1, 25, 2), out_dir=" ")
    with pytest.raises(dfwb.InputError, match=r"cache = '' is empty"):
        dfwb.run_scene("scene.toml", "out", cache="")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("G, written", [("Kp + K𝐢/s", "K𝐢"), ("Kp + Ki/ｓ", "ｓ"), ("ǅ + 1/s", "ǅ")])
def test_a_name_in_g_is_what_is_written_ascii(capsys, G, written):
    line = refused(capsys, "limit-cycle", "friction", "--G", G, "--set", "Kp=10", "Ki=2")
    assert f"the name {written!r} (a parameter is an ASCII letter or _, then ASCII letters, digits or _) is not " \
           "allowed" in line, line
    with pytest.raises(dfwb.InputError, match="is not allowed"):
        dfwb.transfer_function(G)


@pytest.mark.parametrize("argv", [
    ["map", "friction", "--G", PI, "--x", "Kp=1:50:2", "--y", "K𝐢=0.1:25:2"],
    ["continue", "friction", "--G", PI, "--set", "Kp=10", "--parameter", "K𝐢=1:30"],
    ["limit-cycle", "friction", "--G", PI, "--set", "Kp=10", "Ki=2", "K𝐢=3"],
])
def test_a_name_elsewhere_is_what_is_written_too(capsys, tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    line = refused(capsys, *argv)
    assert f"unknown parameter 'K𝐢': G's and the friction plant's are {NAMES}" in line, line


def test_an_ascii_name_reads_as_before():
    from dfwb.engine.transfer import TransferFamily

    family = TransferFamily("Kp_1 + _ki/s")
    assert family.names == ("Kp_1", "_ki")
    assert family.coefficients({"Kp_1": 10, "_ki": 2}) == ([10.0, 2.0], [1.0, 0.0])
