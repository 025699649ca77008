"""Scene files: every shipped scene is valid; every kind of mistake is one message naming file, key and range."""

from pathlib import Path

import pytest

from dfwb.cli import main
from dfwb.plants import names
from dfwb.studies.scene import PAPER_FIGURES, SceneError, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "scenes").glob("*.toml"))

GOOD = '''
title = "t"
[[series]]
name = "s"
plant = "backlash"
F = [50.0]
omega = [20.0]
'''


def test_every_shipped_scene_is_valid_and_the_paper_has_one_scene_per_figure():
    scenes = {path.stem: load_scene(path) for path in SHIPPED}
    papers = [f.paper for scene in scenes.values() for f in scene.figure if f.kind == "paper"]
    assert sorted(papers) == sorted(PAPER_FIGURES)
    assert len([name for name in scenes if name.startswith("lc_")]) == 4
    for name, scene in scenes.items():
        for f in scene.figure:
            if f.kind == "paper":
                assert name.startswith(f.paper) and PAPER_FIGURES[f.paper].file == name


def test_points_expand_F_outer_grid_then_omega_and_merge_log_and_values():
    scene = parse_scene(GOOD.replace("F = [50.0]", "F = [50.0, 10]").replace(
        "omega = [20.0]", "omega = {log = [1, 100, 3], values = [20, 10]}\ngrid = {eps = [0.2, 0.8]}"))
    points = [(p.F, p.params["eps"], p.omega) for p in scene.points()]
    assert points[:5] == [(50.0, 0.2, 1.0), (50.0, 0.2, 10.0), (50.0, 0.2, 20.0), (50.0, 0.2, 100.0),
                          (50.0, 0.8, 1.0)]
    assert len(points) == 2 * 2 * 4 and points[-1] == (10.0, 0.8, 100.0)


@pytest.mark.parametrize("change, message", [
    (("omega = [20.0]", "omega = [20.0]\nomgea = 3"), "series[0]: unknown key 'omgea' (allowed: name, plant, input, output, kind, params"),
    (("title = \"t\"", "title = \"t\"\nresults = 1"), "unknown key 'results' (allowed: title, description"),
    (("F = [50.0]", "F = \"50\""), "series[0].F: Input should be a valid list (got '50')"),
    (("F = [50.0]", "F = [\"50\"]"), "series[0].F[0]: Input should be a valid number (got '50')"),
    (("F = [50.0]", "F = [-5.0]"), "series[0].F[0]: Input should be greater than or equal to 0.000001 (got -5.0)"),
    (("F = [50.0]", "F = [1.7e308]"), "series[0].F[0]: Input should be less than or equal to 1000000000 (got 1.7e+308)"),
    (("omega = [20.0]", "omega = {log = [1e-14, 1e-12, 3]}"), "expected [lo, hi, n] with 0.0001 <= lo < hi <= 100000"),
    (("F = [50.0]", "F = [nan]"), "series[0].F[0]: Input should be a finite number"),
    (("F = [50.0]", "F = []"), "series[0].F: List should have at least 1 item"),
    (("omega = [20.0]", "omega = []"), "series[0].omega: the frequency grid is empty"),
    (("omega = [20.0]", "omega = {log = [10, 1, 5]}"), "series[0].omega: log = [10.0, 1.0, 5.0]: expected"),
    (("omega = [20.0]", "omega = {log = [1, 10, 2.5]}"), "an integer 2 <= n <= 100000"),
    (("omega = [20.0]", "omega = [20.0]\nparams = {eps = 1.5}"),
     "series[0]: eps = 1.5 is out of range: eps must be in [0, 1]"),
    (("omega = [20.0]", "omega = [20.0]\ngrid = {eps = [0.5, 1.5]}"), "series[0]: eps = 1.5 is out of range"),
    (("omega = [20.0]", "omega = [20.0]\ngrid = {eps = []}"), "series[0].grid.eps: List should have at least 1"),
    (("omega = [20.0]", "omega = [20.0]\nparams = {mass = 2}"),
     "series[0]: unknown parameter 'mass' for plant backlash (allowed: "),
    (("omega = [20.0]", "omega = [20.0]\nparams = {omega = 2}"), "omega is set by the describing-function engine"),
    (("plant = \"backlash\"", "plant = \"gearbox\""),
     "series[0].plant: Input should be one of " + ", ".join(map(repr, names())) + " (got 'gearbox')"),
    (("name = \"s\"", "name = \"a b\""), "series[0].name: String should match pattern"),
    (("[[series]]", "[engine]\ndrive = \"held\"\n[[series]]"),
     "engine.drive: Input should be 'internal' or 'input' (got 'held')"),
    (("[[series]]", "[engine]\nsamples_per_period = 2\n[[series]]"),
     "engine.samples_per_period: Input should be greater than or equal to 4 (got 2)"),
    (("title = \"t\"", "title = \" \""), "title: the title is empty"),
])
def test_a_bad_scene_is_one_message_naming_the_key_and_the_allowed_values(change, message):
    with pytest.raises(SceneError) as error:
        parse_scene(GOOD.replace(*change), "my.toml")
    assert str(error.value).startswith("my.toml: ") and message in str(error.value), str(error.value)


LIMIT_CYCLE = '''
title = "t"
[[limit_cycle]]
name = "lc"
plant = "static-backlash"
G = "20*(s+2)/(s+20)"
F_range = [0.01, 100.0]
omega_range = [0.1, 50.0]
'''


@pytest.mark.parametrize("change, message", [
    (("G = \"20*(s+2)/(s+20)\"", "G = \"s**2/(s+1)\""), "limit_cycle[0]: G(s) = s**2/(s+1) is improper"),
    (("G = \"20*(s+2)/(s+20)\"", "G = \"__import__('os')\""),
     "limit_cycle[0]: G(s) = __import__('os'): Call is not allowed (numbers, s, parameters, + - * / **, parentheses)"),
    (("G = \"20*(s+2)/(s+20)\"", "num = [1.0]"), "limit_cycle[0]: num and den both need at least one coefficient"),
    (("G = \"20*(s+2)/(s+20)\"", ""), "limit_cycle[0]: give the controller either as G"),
    (("G = \"20*(s+2)/(s+20)\"", "G = \"1/(s+1)\"\nnum = [1.0]"), "give the controller either as G"),
    (("F_range = [0.01, 100.0]", "F_range = [100.0, 0.01]"), "limit_cycle[0]: F_range = [100, 0.01]: expected"),
    (("F_range = [0.01, 100.0]", "F_range = [0.01]"), "limit_cycle[0].F_range: List should have at least 2"),
    (("omega_range = [0.1, 50.0]", "omega_range = [0.1, 50.0]\nsamples_per_period = 8"),
     "limit_cycle[0].samples_per_period: Input should be greater than or equal to 16"),
    (("G = \"20*(s+2)/(s+20)\"", "G = \"1/(s+1)**9\""),
     "limit_cycle[0]: G(s) = 1/(s+1)**9 has order 9: the exact closed loop takes controllers of order 1..8"),
    (("G = \"20*(s+2)/(s+20)\"", "G = \"1e308*s/(1e-308*s+1)\""),
     "divided by the leading denominator coefficient 1e-308 are not finite numbers"),
    (("G = \"20*(s+2)/(s+20)\"", "num = [1e308]\nden = [1e-308, 1.0]"),
     "limit_cycle[0]: G(s) = ([1e+308])/([1e-308, 1.0]): its coefficients divided by the leading"),
    (("G = \"20*(s+2)/(s+20)\"", "G = \"10**400*s/(s+1)\""),
     "the power 400 is not allowed: integer powers 0..20 only (write a large number out, e.g. 1e40)"),
])
def test_a_bad_limit_cycle_names_the_problem(change, message):
    with pytest.raises(SceneError) as error:
        parse_scene(LIMIT_CYCLE.replace(*change), "lc.toml")
    assert message in str(error.value), str(error.value)


def test_two_figures_cannot_write_the_same_file():
    text = GOOD + '[[figure]]\nname = "a_b"\nkind = "nyquist"\nseries = ["s"]\n' + \
        '[[limit_cycle]]\nname = "b"\nplant = "static-backlash"\nG = "20*(s+2)/(s+20)"\n' + \
        '[[figure]]\nname = "a"\nkind = "limit_cycle"\nseries = ["b"]\n'
    with pytest.raises(SceneError, match=r"figure\[1\]: figure a writes a_b.png, as figure a_b does: rename one"):
        parse_scene(text, "f.toml")


@pytest.mark.parametrize("figure, message", [
    ('kind = "nyquist"\nseries = ["nope"]', "figure[0] (f): 'nope' is not a [[series]] of this scene (allowed: s)"),
    ('kind = "nyquist"', "figure[0] (f): series is empty (allowed: s)"),
    ('kind = "trace"\nseries = ["s"]', "'s' is not a [[trace]] of this scene (allowed: none)"),
    ('kind = "paper"\npaper = "fig07"', "paper = 'fig07' is not one of the paper's figures (allowed: fig03, fig04"),
    ('kind = "paper"\npaper = "fig03"', "the paper's fig03 needs a [[series]] 'friction' of plant friction"),
    ('kind = "bode"\nseries = ["s"]', "figure[0].kind: Input should be 'nyquist', 're_im', 'harmonics'"),
    ('kind = "nyquist"\nseries = ["s"]\nxlim = [0, "a"]', "figure[0].xlim[1]: Input should be a valid number"),
])
def test_figures_must_name_what_the_scene_computes(figure, message):
    with pytest.raises(SceneError) as error:
        parse_scene(GOOD + f'[[figure]]\nname = "f"\n{figure}\n', "f.toml")
    assert message in str(error.value), str(error.value)


def test_scene_level_mistakes():
    with pytest.raises(SceneError, match="the scene asks for nothing"):
        parse_scene('title = "t"\n', "e.toml")
    with pytest.raises(SceneError, match="the name 's' is used twice"):
        parse_scene(GOOD + GOOD.split("\n", 2)[2], "d.toml")
    with pytest.raises(SceneError, match=r"^bad.toml: not valid TOML: .*line 1"):
        parse_scene("title = = 3", "bad.toml")
    with pytest.raises(SceneError, match="missing.toml: cannot read the scene"):
        load_scene("missing.toml")
    trace = ('title = "t"\n[[trace]]\nname = "t"\nplant = "friction"\nF = 1.0\nomega = 1.0\nstop = 1.0\n'
             'step = 0.1\noutputs = ["y"]\n')
    with pytest.raises(SceneError, match=r"trace\[0\]: output 'y' is not an output of plant friction \(allowed: x, v"):
        parse_scene(trace, "t.toml")
    with pytest.raises(SceneError, match=r"trace\[0\]: start = 2 must be < stop = 1"):
        parse_scene(trace.replace('["y"]', '["x"]\nstart = 2.0'), "t.toml")


def test_dfwb_run_reports_a_bad_scene_in_one_line_and_exit_code_2(tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text(GOOD.replace("F = [50.0]", "F = [50.0]\nparams = {eps = 1.5}"))
    with pytest.raises(SystemExit) as stop:
        main(["run", str(scene), "--out", str(tmp_path / "out"), "--no-cache"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{scene}: series[0]: eps = 1.5 is out of range" in err
    assert not (tmp_path / "out").exists()  # nothing written


def test_the_documented_scene_is_valid():
    page = (ROOT / "docs" / "guide" / "scenes.md").read_text()
    block = page.split("```toml\n", 1)[1].split("```", 1)[0]  # the scenes guide's first scene
    scene = parse_scene(block, "scenes.md")
    assert [s.name for s in scene.series] == ["backlash"] and scene.limit_cycle[0].verify
    assert len(scene.points()) == 2 * 2 * 43 and not scene.needs_harmonics


LONG = "a" * 100_000
FIGURE = '[[figure]]\nname = "f"\nkind = "nyquist"\n'


@pytest.mark.parametrize("text, message", [
    (GOOD.replace("F = [50.0]", "F = [1" + "0" * 400 + "]"), "series[0].F[0]: Input should be a finite number (got 1000"),
    (GOOD.replace("F = [50.0]", "F = [1" + "0" * 5000 + "]"), "an integer of more than 4300 digits"),
    (GOOD + "x = " + "[" * 5000 + "]" * 5000, "not valid TOML: arrays or tables nested too deeply"),
    (GOOD + "x = " + "{a=" * 3000 + "1" + "}" * 3000, "not valid TOML: arrays or tables nested too deeply"),
    (GOOD + f"{LONG} = 1", "unknown key 'aaaaaaaaaa"),
    (GOOD.replace("F = [50.0]", f"F = [50.0]\nparams = {{{LONG} = 1.0}}"), "series[0]: unknown parameter 'aaaa"),
    (GOOD.replace("F = [50.0]", f'F = [50.0]\nparams = {{{LONG} = "x"}}'), "series[0].params.'aaaaaaaa"),
    (GOOD.replace('plant = "backlash"', f'plant = "{LONG}"'), "series[0].plant: Input should be one of 'friction'"),
    (GOOD + FIGURE + f'series = ["{LONG}"]', "figure[0] (f): 'aaaaaaaa"),
    (GOOD + FIGURE.replace("nyquist", "paper") + f'paper = "{LONG}"', "figure[0] (f): paper = 'aaaaaaa"),
    (GOOD.replace("F = [50.0]", 'F = [50.0]\nparams = {"a\\nb" = "x"}'), "series[0].params.'a\\nb': Input should be"),
    (GOOD + FIGURE.replace('"f"', '"f\\n"') + 'series = ["s"]', "figure[0].name: String should match pattern"),
    (LIMIT_CYCLE.replace('G = "20*(s+2)/(s+20)"', f"num = [{', '.join(['1.0'] * 50_000)}]\nden = [1.0]"),
     "limit_cycle[0]: "),
    (LIMIT_CYCLE.replace('G = "20*(s+2)/(s+20)"', 'G = "(s\\n+1)"'), "limit_cycle[0]: G(s) = (s\\n+1) is improper"),
])
def test_a_hostile_scene_is_still_one_short_line(text, message):
    with pytest.raises(SceneError) as error:
        parse_scene(text, "h.toml")
    text = str(error.value)
    assert text.startswith("h.toml: ") and message in text, text[:400]
    assert "\n" not in text and len(text) <= 300, text[:400]


def test_parameter_sets_are_checked_only_within_the_scene_size(monkeypatch):
    from dfwb.studies import scene as module

    checked = []
    real = module._check_plant
    monkeypatch.setattr(module, "_check_plant", lambda plant, params: checked.append(1) or real(plant, params))
    big = ('[[series]]\nname = "s{}"\nplant = "friction"\nF = [10.0]\nomega = [1.0]\n'
           'grid = {{M = [{}], B = [{}]}}\n')
    values = ", ".join(str(float(k + 1)) for k in range(300))
    text = 'title = "t"\n' + "".join(big.format(i, values, values) for i in range(5))  # 5 x 90,000 points
    with pytest.raises(SceneError, match="450000 DF points"):
        parse_scene(text, "big.toml")
    assert checked == []  # refused by its size before any of its 450,000 parameter sets is checked
    parse_scene(GOOD.replace("F = [50.0]", "F = [50.0]\ngrid = {eps = [0.1, 0.2, 0.3]}"), "ok.toml")
    assert len(checked) == 3


def test_a_byte_order_mark_is_named(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    with pytest.raises(SceneError, match="byte-order mark"):
        load_scene(path)
