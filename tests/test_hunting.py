"""Hunting maps (dfwb.hunting_map, dfwb map) and limit-cycle margins (dfwb.limit_cycle_margin, dfwb margin).

The oracle is a published result: with static friction above Coulomb friction, PID position control of a
mass hunts for every stabilizing choice of gains, and it does not hunt when they are equal (Armstrong and
Amin, "PID control in the presence of static friction: a comparison of algebraic and describing function
analysis", Automatica 32(5), 1996). The maps that say both, PI and PID, are the hunting notebook's
(tests/test_examples.py checks what it says); their claim of absence (Fs = Fc) is checked here against a
long independent event-driven simulation. A map equals the search cell by cell, resumes after a kill,
reads its cells back from the cache, and draws the linear loop's boundary where python-control puts it.
A margin's boundary is confirmed by cycles on its two sides. What a map reads back (its folder, the cache)
is checked: a crafted row or entry is recomputed, never shown.
"""

import json
import os
import signal
import subprocess
import sys
import time

import control
import numpy as np
import pytest

import dfwb
from dfwb.engine.cycles import find_cycles
from dfwb.engine.family import LoopFamily
from dfwb.plants.loop_reference import closed_loop_reference

PI = "Kp + Ki/s"
PID = "20 + 100/s + 2*s/(0.1*s+1)"


@pytest.fixture(scope="module")
def small_map():
    return dfwb.hunting_map("friction", PI, ("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2), jobs=1, curves=False)


@pytest.fixture
def coarse_boundary(monkeypatch):
    """The linear loop's boundary from 8 x 8 settings instead of 80 x 80, for the tests whose claims are about the
    cells (searched, resumed, cached, refused), not the boundary: its 6400 loops take a second of a 2 x 2 map (nine
    over two plant parameters). The boundary is checked on the full grid, with small_map."""
    from dfwb.studies import hunting

    monkeypatch.setattr(hunting, "LINEAR_GRID", 8)


def test_a_map_is_the_search_cell_by_cell(small_map):
    family = LoopFamily("friction", PI, free=("Kp", "Ki"))
    for j, Ki in enumerate(small_map.ys):
        for i, Kp in enumerate(small_map.xs):
            cell = small_map.cells[j][i]
            direct = find_cycles(family.problem({"Kp": Kp, "Ki": Ki})).stable()
            assert cell["truth"]["class"] == "stable" and len(direct) == 1
            (mapped,) = [c for c in cell["truth"]["cycles"] if c["stable"]]
            assert mapped["omega"] == pytest.approx(direct[0].omega, rel=1e-9)
            assert mapped["amplitude_x"] == pytest.approx(direct[0].amplitude_x, rel=1e-9)
            assert cell["linear"]["stable"] == (Ki < 0.5 * Kp)
            G = family.G({"Kp": Kp, "Ki": Ki})
            for p in cell["df"]["predictions"]:  # each a harmonic balance of the exact DF
                N = dfwb.describing_function("friction", F=p["F"], omega=p["omega"]).N
                assert abs(1 + complex(G(1j * p["omega"])) * N) < 1e-6


def test_the_absence_at_coulomb_is_what_a_long_independent_simulation_does():
    """Fs = Fc, Kp = 10, Ki = 2: from rest at 0.1 m the mass stops closer to 0 at every stick, for hours."""
    state, sticks = [0.1, 0.0, 0.0], []
    for _ in range(40):
        run = closed_loop_reference("friction", [10.0, 2.0], [0.0], 1e5, {"Fs": 5.0, "Fc": 5.0}, state=state,
                                    until=lambda kind, mode: kind == "band")
        if run["t"] >= 1e5:
            break  # stuck so close to 0 that the integrator takes longer than a day to move it
        state = run["state"]
        sticks.append(abs(state[0]))
    assert len(sticks) >= 5
    assert all(b < a for a, b in zip(sticks, sticks[1:])) and sticks[-1] < 1e-2 * sticks[0]


def test_the_linear_boundary_is_where_python_control_puts_it(small_map):
    linear = small_map.linear
    plant = control.tf([1.0], [1.0, 0.5, 0.0])
    for j in (0, 17, 40, 79):
        for i in (0, 33, 79):
            Kp, Ki, growth = linear["x"][i], linear["y"][j], linear["growth"][j][i]
            poles = control.feedback(control.tf([Kp, Ki], [1.0, 0.0]) * plant, 1).poles()
            assert growth == pytest.approx(float(np.max(poles.real)), abs=1e-9)


@pytest.mark.usefixtures("coarse_boundary")
def test_a_map_reads_its_cells_back_from_the_cache(tmp_path):
    axes = (("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2))
    first = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, cache=tmp_path / "cache")
    again = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, cache=tmp_path / "cache")
    assert first.counts["computed"] == 4 and again.counts == {"cells": 4, "computed": 0, "cached": 4, "resumed": 0}
    assert again.as_dict()["cells"] == first.as_dict()["cells"]


@pytest.mark.slow
def test_a_killed_map_resumes_with_what_it_had(fmus, tmp_path, killed_run_tmpdir):
    out = tmp_path / "map"
    argv = [sys.executable, "-m", "dfwb.cli", "map", "friction", "--G", PI, "--x", "Kp=5:20:3", "--y", "Ki=1:4:3",
            "--out", str(out), "--jobs", "1", "--no-cache", "--no-curves", "--json", "--fmus",
            str(fmus["FrictionMass"].parent)]
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                               env=dict(os.environ, TMPDIR=str(killed_run_tmpdir)))
    log = out / "cells.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and (not log.exists() or log.read_text().count("\n") < 3):
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    done = log.read_text().count("\n") - 1
    assert 2 <= done < 9
    resumed = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    report = json.loads(resumed.stdout)
    assert report["counts"]["resumed"] >= done - 1 and report["counts"]["computed"] <= 9 - done + 1
    fresh = dfwb.hunting_map("friction", PI, ("Kp", 5.0, 20.0, 3), ("Ki", 1.0, 4.0, 3), jobs=1, curves=False)
    assert [(c["x"], c["y"], c["truth"]["class"], c["df"]["class"]) for c in report["cells"]] == \
        [(c["x"], c["y"], c["truth"]["class"], c["df"]["class"]) for c in fresh.as_dict()["cells"]]
    assert report["cells"][0]["truth"]["cycles"][0]["omega"] == \
        pytest.approx(fresh.cells[0][0]["truth"]["cycles"][0]["omega"], rel=1e-12)


def test_the_command_line_writes_the_map_and_its_json(fmus, tmp_path, capsys):
    from dfwb.cli import main

    out = tmp_path / "m"
    assert main(["map", "friction", "--G", PI, "--x", "Kp=5:20:2", "--y", "Ki=1:4:2", "--out", str(out), "--jobs", "1",
                 "--no-cache", "--json", "--fmus", str(fmus["FrictionMass"].parent)]) == 0
    report = json.loads(capsys.readouterr().out)
    assert len(report["cells"]) == 4
    cell = report["cells"][0]
    assert {"x", "y", "truth", "df"} <= set(cell) and {"class", "cycles"} <= set(cell["truth"])
    assert {"class", "predictions"} <= set(cell["df"])
    assert {p.name for p in out.iterdir()} >= {"cells.csv", "cells.json", "map.json", "hunting_map.png"}
    assert (out / "hunting_map.png").stat().st_size > 30_000


@pytest.mark.parametrize("argv, message", [
    (["--x", "Kp=1:50:1000", "--y", "Ki=0.1:25:1000"], "a map of 1000 x 1000 = 1000000 cells: at most 10000"),
    (["--x", "Kp=1:nan:5", "--y", "Ki=0.1:25:5"], "Kp stop = nan: the range's ends must be finite"),
    (["--x", "Kp=1:50:5", "--y", "Kp=0.1:25:5"], "x and y are both Kp"),
    (["--x", "Kp=1:50:1", "--y", "Ki=0.1:25:5"], "N = 1 cells: an integer from 2 to 1000"),
    (["--x", "Kp=1:50:2.5", "--y", "Ki=0.1:25:5"], "N a whole number of cells"),
    (["--x", "Kp=1:50:inf", "--y", "Ki=0.1:25:5"], "N a whole number of cells"),
    (["--x", "Kp=1:50:nan", "--y", "Ki=0.1:25:5"], "N a whole number of cells"),
    (["--x", "Kp=-1e308:1e308:5", "--y", "Ki=0.1:25:5"], "wider than the floats"),
    (["--x", "Fc=8:9:2", "--y", "Fs=1:2:2", "--set", "Kp=1", "Ki=1"], "at every corner of the map (Fc = 8, Fs = 1;"),
    (["--x", "Kp=1:50:5", "--y", "Ki=0.1:25:5", "--set", "Kp=3"], "Kp is an axis of the map"),
    (["--x", "Kp=1:50:5", "--y", "M=-1:25:5", "--set", "Ki=2"], "M = -1.0 is out of range"),
    (["--x", "Kp=1:50:5", "--y", "s=0:1:5"], "s is the variable of G(s)"),
])
def test_hostile_map_input_is_one_line_before_anything_runs(capsys, tmp_path, argv, message):
    from dfwb.cli import main

    started = time.perf_counter()
    with pytest.raises(SystemExit) as exit_:
        main(["map", "friction", "--G", PI, "--out", str(tmp_path / "m")] + argv)
    assert exit_.value.code == 2 and time.perf_counter() - started < 5.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "m").exists()


def test_a_margin_boundary_is_confirmed_on_its_two_sides():
    margin = dfwb.limit_cycle_margin("friction", PID, count=9, df=False)
    (boundary,) = margin.truth.boundaries
    assert boundary.kind == "nonsmooth-fold" and boundary.starts and boundary.accuracy < 1e-4 * boundary.k
    assert margin.truth.hunts_at(1.0) and margin.truth.room() == (boundary.k, None)
    family = LoopFamily("friction", PID).scaled("k")
    assert find_cycles(family.problem({"k": boundary.k * (1 + 1e-4)})).stable()
    assert not find_cycles(family.problem({"k": boundary.k * (1 - 1e-4)})).stable()


def test_a_pi_controller_that_keeps_its_ratio_hunts_at_every_gain(capsys):
    """k (10 + 2/s): Ki / Kp = 0.2 < B / M for every k, so the linear loop is always stable: it always hunts."""
    from dfwb.cli import main

    assert main(["margin", "friction", "--G", "10 + 2/s", "--count", "7", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["truth"]["intervals"] == [[0.01, 100.0]] and report["truth"]["hunts_at_1"] is True
    assert report["truth"]["boundaries"] == [] and report["truth"]["up"] is None


@pytest.mark.parametrize("argv, message", [
    (["--k-range", "2", "10"], "expected 1e-06 <= low < 1 < high <= 1e+06"),
    (["--k-range", "0", "10"], "expected 1e-06 <= low < 1 < high <= 1e+06"),
    (["--k-range", "0.1", "nan"], "expected 1e-06 <= low < 1 < high <= 1e+06"),
    (["--G", "k*(1 + 1/s)"], "the parameter k is given no value"),
])
def test_hostile_margin_input_is_one_line(capsys, argv, message):
    from dfwb.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["margin", "friction"] + (argv if "--G" in argv else ["--G", "10 + 2/s"] + argv))
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def _rewrite_rows(log, change):
    """cells.csv with change(row) applied to each row (None drops it) and the checksums made right again:
    a row crafted by someone who knows the format."""
    import csv

    from dfwb.base.runlog import CHECKSUM, checksum

    with open(log, newline="") as stream:
        rows = list(csv.DictReader(stream))
    columns = list(rows[0])
    kept = []
    for i, row in enumerate(rows):
        row = change(i, dict(row))
        if row is not None:
            row[CHECKSUM] = checksum(row, columns)
            kept.append(row)
    with open(log, "w", newline="") as stream:
        writer = csv.DictWriter(stream, columns)
        writer.writeheader()
        writer.writerows(kept)


@pytest.mark.usefixtures("coarse_boundary")
def test_a_map_resumes_only_its_own_well_formed_cells(tmp_path):
    axes = (("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2))
    out = tmp_path / "m"
    first = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, out_dir=out)
    assert first.counts["computed"] == 4

    def craft(i, row):
        cell = json.loads(row["cell"])
        if i == 0:
            cell["truth"]["class"] = "hunts a lot"
        elif i == 1:
            row["key"] = "0" * 64  # another map's (or another code's) row
        elif i == 2:
            cell["truth"]["cycles"] = [{"omega": -1.0}]
        row["cell"] = json.dumps(cell)
        return row

    _rewrite_rows(out / "cells.csv", craft)
    again = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, out_dir=out)
    assert again.counts["resumed"] == 1 and again.counts["computed"] == 3
    assert again.as_dict()["cells"] == first.as_dict()["cells"]


@pytest.mark.usefixtures("coarse_boundary")
def test_a_crafted_cache_entry_of_a_map_cell_is_recomputed(tmp_path):
    import hashlib

    axes = (("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2))
    first = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, cache=tmp_path / "cache")
    entries = sorted((tmp_path / "cache").rglob("*.json"))
    assert len(entries) == 4
    for path, body in zip(entries[:3], (b'{"truth": 1}', b"[" * 100_000, b'{"x": 5.0, "y": 1.0, "error": 7}')):
        head = json.loads(path.read_bytes().partition(b"\n")[0])
        head["sha256"] = hashlib.sha256(body).hexdigest()  # a valid entry for its key, with a crafted value
        path.write_bytes(json.dumps(head).encode() + b"\n" + body)
    again = dfwb.hunting_map("friction", PI, *axes, jobs=1, curves=False, cache=tmp_path / "cache")
    assert again.counts["cached"] == 1 and again.counts["computed"] == 3
    assert again.as_dict()["cells"] == first.as_dict()["cells"]


@pytest.mark.usefixtures("coarse_boundary")
def test_a_map_under_a_function_never_resumes_another_functions_cells(tmp_path):
    out = tmp_path / "m"
    axes = (("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2))
    dfwb.hunting_map("friction", lambda Kp, Ki: control.tf([Kp, Ki], [1, 0]), *axes, jobs=1, curves=False,
                     out_dir=out)
    doubled = dfwb.hunting_map("friction", lambda Kp, Ki: control.tf([2 * Kp, Ki], [1, 0]), *axes, jobs=1,
                               curves=False, out_dir=out)
    assert doubled.counts["resumed"] == 0 and doubled.counts["computed"] == 4
    assert doubled.as_dict()["cells"] == dfwb.hunting_map("friction", "2*Kp + Ki/s", *axes, jobs=1,
                                                          curves=False).as_dict()["cells"]


@pytest.mark.parametrize("Kp, Ki", [(-10.0, 2.0), (-1.0, -1.0), (5.0, -3.0)])
def test_a_loop_that_grows_without_crossing_the_section_diverges(Kp, Ki):
    """An unstable loop can run away monotonically, never crossing the section again: not rest."""
    from dfwb.engine.hunting import classify

    cell = classify(LoopFamily("friction", PI, {"Kp": Kp, "Ki": Ki}).problem(), df=False)
    assert cell["truth"]["class"] == "diverges" and not cell["linear"]["stable"]
    assert cell["truth"]["coverage"]["outcomes"].get("diverged", 0) >= 10


def test_a_search_with_failed_runs_settles_nothing():
    from dfwb.engine.cycles import Coverage, CycleSearch
    from dfwb.engine.hunting import truth_class

    def search(outcomes, complete=True):
        coverage = Coverage([0.1, 10.0], 3, ["x"], outcomes=outcomes, complete=complete)
        return CycleSearch(cycles=[], links=[], coverage=coverage, fates=[])

    assert truth_class(search({"rest": 19, "failed": 1}))[0] == "incomplete"
    assert truth_class(search({"rest": 20}, complete=False))[0] == "incomplete"
    assert truth_class(search({"rest": 19, "diverged": 1}))[0] == "diverges"
    assert truth_class(search({"rest": 20}))[0] == "none"


def test_a_nearly_absent_controller_state_is_not_sent_to_1e300():
    """Ki = 1e-300: displacing the integrator by the force G_c a / Ki would put it at 1e300 (every later
    sum rounded away); it moves at most Z_CAP times its size in a motion of the start's amplitude."""
    from dfwb.engine.cycles import Z_CAP, starts

    problem = LoopFamily("friction", PI, {"Kp": 10, "Ki": 1e-300}).problem()
    omega_c = problem.scales.omega_c
    for start in starts(problem, [0.1, 1.0]):
        assert abs(start.state[-1]) <= Z_CAP * start.amplitude / omega_c * (1 + 1e-12)
    usual = LoopFamily("friction", PI, {"Kp": 10, "Ki": 2}).problem()  # a usual Ki is displaced as before
    G_c = abs(complex(usual.G(1j * usual.scales.omega_c)))
    assert max(abs(s.state[-1]) for s in starts(usual, [1.0])) == pytest.approx(G_c / 2.0, rel=1e-12)


def test_the_gain_factor_does_not_collide_with_a_plant_parameter_named_k():
    from dfwb.engine.margin import GAIN

    family = LoopFamily("static-backlash", "1 + 0.5*s/(0.01*s + 1)", {"k": 2.0})
    problem = family.scaled(GAIN).problem({GAIN: 3.0})
    assert problem.params["k"] == 2.0
    assert complex(problem.G(1j)) == pytest.approx(3.0 * complex(family.G()(1j)), rel=1e-12)


@pytest.mark.slow
@pytest.mark.usefixtures("coarse_boundary")
def test_a_map_of_two_plant_parameters_reports_the_cells_the_plant_refuses():
    """Fc and Fs over a grid where Fs < Fc at one corner: that cell says why, the others are computed."""
    m = dfwb.hunting_map("friction", PI, ("Fc", 4.0, 6.0, 2), ("Fs", 5.0, 7.0, 2), jobs=1, curves=False,
                         Kp=10, Ki=2)
    classes = m.classes("truth")
    assert classes[0][1] == "error" and "Fs" in m.cells[0][1]["error"]
    assert classes[0][0] == classes[1][0] == classes[1][1] == "stable"


@pytest.mark.usefixtures("coarse_boundary")
def test_a_scenes_own_map_folder_starts_over_when_the_map_changes(tmp_path):
    from dfwb.base.errors import InputError
    from dfwb.studies.hunting import run_map

    out = tmp_path / "map_pi"
    run_map("friction", PI, ("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 4.0, 2), out_dir=out, jobs=1, curves=False)
    edited = (("Kp", 5.0, 20.0, 2), ("Ki", 1.0, 3.0, 2))
    with pytest.raises(InputError, match="holds a different map"):
        run_map("friction", PI, *edited, out_dir=out, jobs=1, curves=False)
    again = run_map("friction", PI, *edited, out_dir=out, jobs=1, curves=False, own_folder=True)
    assert again.counts["resumed"] == 0 and again.counts["computed"] == 4
    assert json.loads((out / "map.json").read_text())["y"] == ["Ki", [1.0, 3.0]]


def test_the_boundarys_stacked_roots_are_numpys_one_by_one():
    """A map's boundary takes the largest real part of 6400 polynomials' roots in stacks of one degree:
    the same numbers as np.roots one by one, with zero leading or trailing coefficients and constants."""
    from dfwb.engine.scales import largest_real_parts

    rng = np.random.default_rng(7)
    polynomials = [rng.normal(size=rng.integers(1, 8)) for _ in range(500)]
    polynomials += [[0.0, 0.0, 1.0, 2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 3.0], [2.0], [0.0, 1.0, -1.0], [1.0, np.nan]]
    expected = [max(np.roots(p).real) if len(np.roots(p)) else np.inf for p in polynomials[:-1]] + [np.inf]
    assert largest_real_parts(polynomials).tolist() == expected
