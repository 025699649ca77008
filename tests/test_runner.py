"""dfwb run: only what a scene needs, found again in the cache, resumed after a kill, the same on Dask."""

import csv
import hashlib
import json
import os
import signal
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from dfwb.engine.describing import DFEngine
from dfwb.engine.limit_cycles import search
from dfwb.engine.transfer import parse_transfer_function
from dfwb.fmi.location import fmu_path
from dfwb.fmi.simulation import simulate
from dfwb.studies.runner import run_scene
from dfwb.studies.scene import parse_scene

ROOT = Path(__file__).resolve().parents[1]

SCENE = '''
title = "{title}"
[[series]]
name = "friction"
plant = "friction"
F = [10.0, 30.0]
omega = [0.5, 1.0, 5.0]

[[series]]
name = "backlash"
plant = "backlash"
grid = {{ eps = [0.2, 0.5] }}
F = [50.0]
omega = [15.0, 20.0, 40.0]
params = {{ h = {h} }}

[[figure]]
name = "nyquist"
kind = "nyquist"
series = ["friction", "backlash"]
marks = [1.0, 20.0]

[[figure]]
name = "re_im"
kind = "re_im"
series = ["friction"]
'''


def scene(h=0.1, extra="", title="two plants"):
    """The two-plant scene; another ``title`` makes another scene over the same points (not copied whole)."""
    return parse_scene(SCENE.format(h=h, title=title) + extra, "test.toml")


def df_entries(cache):
    """The cache's entries of DF points (it also holds figures, traces and judge runs)."""
    return sorted(path for path in Path(cache).rglob("*.json")
                  if json.loads(json.loads(path.read_bytes().split(b"\n")[0])["key"])["kind"] == "df")


def results(out):
    """results.json without the timings, which are the only thing allowed to differ."""
    document = json.loads((Path(out) / "results.json").read_text())
    for rows in document["series"].values():
        for r in rows:
            r.pop("seconds")
    return document


def test_a_scene_matches_the_engine_and_writes_csv_json_figures_and_summary(fmus, tmp_path):
    outcome = run_scene(scene(), tmp_path / "out", jobs=1, cache=tmp_path / "cache", progress=False)
    assert (outcome.points, outcome.computed, outcome.cache_hits) == (12, 12, 0)
    document = results(tmp_path / "out")
    engine = DFEngine("backlash")
    for r in document["series"]["backlash"]:
        direct = engine.point(r["F"], r["omega"], r["params"])
        assert complex(r["N_re"], r["N_im"]) == direct.N and r["periods"] == direct.periods
        assert r["params"] == {"h": 0.1, "eps": r["params"]["eps"]}
        assert len(r["harmonics"]) == 2  # a DF-only scene records X_0 and X_1 only
    with open(tmp_path / "out" / "results.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [row["series"] for row in rows] == ["friction"] * 6 + ["backlash"] * 6
    assert [float(row["N_re [m/N]"]) for row in rows[6:]] == [r["N_re"] for r in document["series"]["backlash"]]
    for name in ("nyquist", "re_im"):
        assert (tmp_path / "out" / f"{name}.png").stat().st_size > 10_000
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "12 DF points: 12 computed" in summary and "![nyquist](nyquist.png)" in summary


def test_a_second_run_recomputes_nothing_and_a_changed_parameter_only_its_points(fmus, tmp_path):
    cache = tmp_path / "cache"
    first = run_scene(scene(), tmp_path / "a", jobs=2, cache=cache, progress=False)
    again = run_scene(scene(), tmp_path / "b", jobs=2, cache=cache, progress=False)
    assert (first.computed, again.computed, again.cache_hits) == (12, 0, 12)
    assert results(tmp_path / "a") == results(tmp_path / "b")
    assert again.figures_cached == 2  # copied, not redrawn: the same bytes
    for name in ("nyquist.png", "nyquist.svg", "re_im.png"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    changed = run_scene(scene(h=0.2), tmp_path / "c", jobs=2, cache=cache, progress=False)
    assert (changed.computed, changed.cache_hits) == (6, 6)  # only the backlash points depend on h
    same = run_scene(scene(), tmp_path / "a", jobs=2, cache=cache, progress=False)
    assert same.up_to_date and same.computed == 0  # the folder already holds this run
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "a").iterdir()}
    run_scene(scene(), tmp_path / "a", jobs=2, cache=cache, progress=False)
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "a").iterdir()} == before


def test_defaults_given_or_omitted_are_the_same_point_and_harmonics_serve_df_only_scenes(fmus, tmp_path):
    cache = tmp_path / "cache"
    rich = scene(extra='[[figure]]\nname = "k"\nkind = "harmonics"\nseries = ["backlash"]\n')
    full = run_scene(rich, tmp_path / "rich", jobs=1, cache=cache, progress=False)
    assert full.computed == 12
    assert all(len(r["harmonics"]) == 11 for r in results(tmp_path / "rich")["series"]["backlash"])
    assert (tmp_path / "rich" / "k.png").exists()
    plain = parse_scene(SCENE.format(h=0.1, title="two plants").replace("params = { h = 0.1 }", "").replace(
        "grid = { eps", "params = {M1 = 1.0}\ngrid = { eps"), "plain.toml")
    slim = run_scene(plain, tmp_path / "slim", jobs=1, cache=cache, progress=False)
    assert (slim.computed, slim.cache_hits) == (0, 12)  # h = 0.1 and M1 = 1 are the defaults
    for a, b in zip(results(tmp_path / "rich")["series"]["backlash"], results(tmp_path / "slim")["series"]["backlash"]):
        assert (a["N_re"], a["N_im"]) == (b["N_re"], b["N_im"]) and b["harmonics"] == a["harmonics"][:2]


def test_a_corrupt_cache_is_detected_and_recomputed(fmus, tmp_path):
    cache = tmp_path / "cache"
    run_scene(scene(), tmp_path / "a", jobs=1, cache=cache, progress=False)
    entries = df_entries(cache)
    assert len(entries) == 12
    entries[0].write_bytes(entries[0].read_bytes()[:-40])  # cut short
    head, body = entries[1].read_bytes().split(b"\n", 1)
    value = json.loads(body)
    value["N_re"] += 1.0  # tampered
    entries[1].write_bytes(head + b"\n" + json.dumps(value).encode())
    again = run_scene(scene(title="another"), tmp_path / "b", jobs=1, cache=cache, progress=False)
    assert (again.computed, again.cache_hits, again.rejected) == (2, 10, 2)
    assert dict(results(tmp_path / "a"), title="another") == results(tmp_path / "b")
    assert "2 cache entries rejected" in (tmp_path / "b" / "summary.md").read_text()


def test_no_cache_writes_no_cache(fmus, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    run_scene(scene(), tmp_path / "a", jobs=1, cache=False, progress=False)
    assert not (tmp_path / "xdg").exists()
    run_scene(scene(), tmp_path / "b", jobs=1, cache=True, progress=False)
    assert len(df_entries(tmp_path / "xdg" / "dfwb")) == 12


def test_an_interrupted_run_loses_only_the_points_in_flight_and_resumes(fmus, tmp_path, killed_run_tmpdir):
    """A run killed half way keeps the points it wrote and a rerun computes only the rest. Enough points
    that the run lasts well over the 50 ms poll (a native backlash point takes a fraction of a ms)."""
    points = 1500
    path = tmp_path / "long.toml"
    path.write_text('title = "long"\n[[series]]\nname = "b"\nplant = "backlash"\nF = [50.0]\n'
                    f'omega = {{log = [12.0, 60.0, {points}]}}\ngrid = {{eps = [0.3]}}\n')
    out = tmp_path / "out"
    command = [sys.executable, "-m", "dfwb.cli", "run", str(path), "--out", str(out), "--jobs", "1", "--no-cache",
               "--quiet"]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               env=dict(os.environ, TMPDIR=str(killed_run_tmpdir)))
    deadline = time.monotonic() + 120
    rows = 0
    while time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.05)
        if (out / "results.csv").exists():
            rows = (out / "results.csv").read_text().count("\n") - 1
            if rows >= 5:
                break
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert 5 <= rows < points, "the run finished before it could be interrupted"
    kept = (out / "results.csv").read_text().count("\n") - 1
    assert not (out / "results.json").exists() and not (out / "summary.md").exists()
    outcome = run_scene(path, out, jobs=1, cache=False, progress=False)
    assert outcome.resumed >= kept >= rows and outcome.computed == points - outcome.resumed
    run_scene(path, tmp_path / "fresh", jobs=1, cache=False, progress=False)
    assert results(out) == results(tmp_path / "fresh")
    assert not list(out.rglob("*.partial"))


@pytest.mark.dask
def test_dask_local_cluster_gives_the_results_of_local_processes(fmus, tmp_path):
    run_scene(scene(), tmp_path / "local", jobs=2, cache=False, progress=False)
    outcome = run_scene(scene(), tmp_path / "dask", jobs=2, dask="local", cache=False, progress=False)
    assert outcome.computed == 12
    assert results(tmp_path / "local") == results(tmp_path / "dask")
    assert "computed on dask (local)" in (tmp_path / "dask" / "summary.md").read_text()


@pytest.mark.dask
@pytest.mark.slow
def test_an_unreachable_dask_scheduler_is_a_clear_error(fmus, tmp_path):
    with pytest.raises(RuntimeError, match="cannot reach the Dask scheduler 'tcp://127.0.0.1:9'"):
        run_scene(scene(), tmp_path / "x", dask="tcp://127.0.0.1:9", cache=False, progress=False)


def test_traces_equal_a_direct_simulation_and_are_cached(fmus, tmp_path):
    text = ('title = "trace"\n[[trace]]\nname = "t"\nplant = "friction"\nF = 10.0\nomega = 0.5\nstart = 5.0\n'
            'stop = 20.0\nstep = 0.05\noutputs = ["x", "v"]\n[[figure]]\nname = "f"\nkind = "trace"\nseries = ["t"]\n')
    first = run_scene(parse_scene(text), tmp_path / "a", cache=tmp_path / "cache", progress=False)
    direct = simulate(fmus["FrictionMass"], 20.0, 0.05, {"F": 10.0, "omega": 0.5}, ["x", "v"])
    keep = direct["time"] >= 5.0 - 1e-12
    with open(tmp_path / "a" / "traces" / "t.csv") as handle:
        columns = list(zip(*csv.reader(handle)))
    assert [c[0] for c in columns] == ["time", "x", "v"]
    for column in columns:
        assert np.array_equal(np.array(column[1:], dtype=float), direct[column[0]][keep])
    assert (tmp_path / "a" / "f.png").exists() and first.points == 0
    other = text.replace('title = "trace"', 'title = "the same trace"')  # not copied whole: the trace's entry
    second = run_scene(parse_scene(other), tmp_path / "b", cache=tmp_path / "cache", progress=False)
    assert second.cache_hits == 1 and not second.copied
    assert (tmp_path / "b" / "traces" / "t.csv").read_bytes() == (tmp_path / "a" / "traces" / "t.csv").read_bytes()


def test_a_limit_cycle_scene_equals_the_direct_search_and_reruns_from_the_cache(fmus, tmp_path):
    text = ('title = "lead"\n[[limit_cycle]]\nname = "lead"\nplant = "static-backlash"\nG = "20*(s+2)/(s+20)"\n'
            'F_range = [0.01, 100.0]\nomega_range = [0.1, 50.0]\nn_F = 8\nn_omega = 16\n'
            '[[figure]]\nname = "fig"\nkind = "limit_cycle"\nseries = ["lead"]\n')
    first = run_scene(parse_scene(text), tmp_path / "a", cache=tmp_path / "cache", progress=False)
    cycles = search("static-backlash", parse_transfer_function("20*(s+2)/(s+20)"), {}, (0.01, 100.0),
                    (0.1, 50.0), 8, 16).cycles
    found = json.loads((tmp_path / "a" / "results.json").read_text())["limit_cycles"]["lead"]["predictions"]
    assert [(c["F"], c["omega"]) for c in found] == [(c.F, c.omega) for c in cycles] and len(cycles) == 1
    assert first.computed > 8 * 16 and (tmp_path / "a" / "fig_lead.png").exists()
    second = run_scene(parse_scene(text), tmp_path / "b", cache=tmp_path / "cache", progress=False)
    assert second.computed == 0 and second.cache_hits == first.computed
    assert json.loads((tmp_path / "b" / "results.json").read_text())["limit_cycles"]["lead"]["predictions"] == found


def test_dfwb_run_from_the_command_line(fmus, tmp_path, capsys):
    from dfwb.cli import main

    path = tmp_path / "s.toml"
    path.write_text(SCENE.format(h=0.1, title="two plants"))
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "c"), "--quiet"]) == 0
    assert "12 points (12 computed, 0 cached, 0 resumed), 2 figure(s)" in capsys.readouterr().out
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "c"), "--quiet"]) == 0
    assert "up to date (12 points, 2 figure(s))" in capsys.readouterr().out


@pytest.mark.slow
def test_a_results_csv_that_is_not_a_run_log_is_set_aside_not_trusted(fmus, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.csv").write_text("")  # killed before the header reached the disk
    first = run_scene(scene(), out, jobs=1, cache=False, progress=False)
    assert first.computed == 12
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "results.csv").write_text("plant,F,omega\nfriction,10,1\n")  # e.g. a dfwb sweep folder
    again = run_scene(scene(), foreign, jobs=1, cache=False, progress=False)
    assert again.computed == 12 and (foreign / "results.csv.unrecognised").read_text().startswith("plant,F")
    assert results(out) == results(foreign)


@pytest.mark.slow
def test_a_folder_changed_since_its_run_is_not_up_to_date(fmus, tmp_path):
    cache = tmp_path / "cache"
    out = tmp_path / "out"
    run_scene(scene(), out, jobs=1, cache=cache, progress=False)
    broken = scene(extra='[[figure]]\nname = "p"\nkind = "paper"\npaper = "fig12"\n'
                   '[[series]]\nname = "backlash_F50"\nplant = "backlash"\nF = [50.0]\nomega = [20.0]\n')
    with pytest.raises(RuntimeError, match="figure p: the paper's fig12 cannot be drawn from this scene's points"):
        run_scene(broken, out, jobs=1, cache=cache, progress=False)  # another scene, failing half-way
    again = run_scene(scene(), out, jobs=1, cache=cache, progress=False)
    assert not again.up_to_date and again.computed == 0 and again.cache_hits == 12
    (out / "results.json").write_text("")  # an output damaged after the run
    assert not run_scene(scene(), out, jobs=1, cache=cache, progress=False).up_to_date
    assert run_scene(scene(), out, jobs=1, cache=cache, progress=False).up_to_date
    assert json.loads((out / "results.json").read_text())["title"] == "two plants"


def test_results_from_a_worker_running_other_code_are_refused(fmus, tmp_path, monkeypatch):
    from dfwb.studies import executor

    real = executor.compute
    monkeypatch.setattr(executor, "compute", lambda chunk, data=None: ("0123456789abcdef", real(chunk)[1]))
    with pytest.raises(RuntimeError, match="a worker ran dfwb code revision 0123456789abcdef, this process has"):
        run_scene(scene(), tmp_path / "out", jobs=1, cache=tmp_path / "cache", progress=False)
    assert not list((tmp_path / "cache").rglob("*.json"))  # nothing of it was cached


def test_the_cache_keys_cover_the_computing_code_and_not_the_command_line_or_the_plots(tmp_path):
    """Editing a plot or the CLI keeps every cached point; editing the engine gives new keys."""
    import shutil

    from dfwb.studies.cache import COMPUTING, DRAWING, revision

    package = tmp_path / "analysis"
    shutil.copytree(ROOT / "analysis", package, ignore=shutil.ignore_patterns("__pycache__"))
    layers = {path.parent.name for path in package.glob("*/__init__.py")}
    assert layers == set(COMPUTING) | set(DRAWING) | {"verify", "api"}  # a new layer must be placed
    code, drawing = revision(COMPUTING, package), revision(DRAWING, package)

    def edited(path):
        path.write_text(path.read_text() + "\n# edited\n")
        revision.cache_clear()
        return revision(COMPUTING, package), revision(DRAWING, package)

    assert edited(package / "cli.py") == (code, drawing)
    new_code, new_drawing = edited(package / "plotting" / "plots.py")
    assert new_code == code and new_drawing != drawing
    assert edited(package / "engine" / "describing.py")[0] != code
    assert edited(package / "plants" / "registry.py")[0] not in (code, new_code)


def test_in_this_process_every_point_is_recorded_as_it_finishes():
    from dfwb.studies.executor import chunked

    assert {len(c) for c in chunked(list(range(100)), 1)} == {1}
    assert max(len(c) for c in chunked(list(range(1000)), 2)) == 16


def test_the_command_line_checks_every_scene_before_running_any_and_reports_os_errors(fmus, tmp_path, capsys):
    from dfwb.cli import main

    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(SCENE.format(h=0.1, title="two plants"))
    bad.write_text(SCENE.format(h=0.1, title="two plants").replace("omega = [0.5, 1.0, 5.0]", "omega = [0.5, 1e9]"))
    with pytest.raises(SystemExit) as stop:
        main(["run", str(good), str(bad), "--out", str(tmp_path / "o"), "--no-cache", "--quiet"])
    assert stop.value.code == 2 and not (tmp_path / "o").exists()
    assert "bad.toml: series[0].omega.values[1]: Input should be less than or equal to 100000" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as stop:
        main(["run", str(good), "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "file"), "--quiet"])
    assert stop.value.code == 2 and "is a file, not a folder" in capsys.readouterr().err
    bad.write_bytes(b"title = \"\xff\"\n")
    with pytest.raises(SystemExit):
        main(["run", str(bad), "--no-cache", "--quiet"])
    assert f"{bad}: not UTF-8 text (byte 9)" in capsys.readouterr().err


@pytest.mark.dask
@pytest.mark.slow
def test_a_running_dask_scheduler_gets_the_fmus_shipped_and_gives_the_local_results(fmus, tmp_path):
    """The documented set-up: `dask scheduler`, `dask worker ADDRESS`, `dfwb run --dask ADDRESS`; the worker
    runs in another directory and never sees build/fmus."""
    dask = Path(sys.executable).with_name("dask")
    info = tmp_path / "scheduler.json"
    worker_dir = tmp_path / "worker"
    worker_dir.mkdir()
    scheduler = subprocess.Popen([str(dask), "scheduler", "--scheduler-file", str(info), "--no-dashboard",
                                  "--port", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = None
    try:
        deadline, address = time.monotonic() + 60, None
        while address is None and time.monotonic() < deadline:  # dask writes the file in place: it can be
            try:                                                 # there, empty or half written
                address = json.loads(info.read_text())["address"]
            except (OSError, ValueError, KeyError):
                time.sleep(0.1)
        assert address, "the dask scheduler wrote no address within 60 s"
        worker = subprocess.Popen([str(dask), "worker", address, "--nthreads", "1", "--no-dashboard"],
                                  cwd=worker_dir, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        outcome = run_scene(scene(), tmp_path / "remote", dask=address, cache=False, progress=False)
        assert outcome.computed == 12
        run_scene(scene(), tmp_path / "local", jobs=1, cache=False, progress=False)
        assert results(tmp_path / "remote") == results(tmp_path / "local")
        assert not (worker_dir / "build").exists()
        for model in ("FrictionMass", "TwoMassBacklash"):  # what the worker ran: the shipped bytes, in private
            digest = hashlib.sha256(fmu_path(model).read_bytes()).hexdigest()  # the kind that ran (native)
            shipped = list(Path(tempfile.gettempdir()).glob(f"dfwb-fmus-*/{digest}/{model}.fmu"))
            assert shipped and all(stat.S_IMODE(path.parent.parent.stat().st_mode) == 0o700 for path in shipped)
    finally:
        for process in (worker, scheduler):
            if process is not None:
                process.terminate()
                process.wait(timeout=30)


@pytest.mark.parametrize("pool_worth, pooled", [(1e9, False), (0.0, True)])
def test_the_default_executor_starts_its_pool_only_for_long_work(monkeypatch, pool_worth, pooled):
    """jobs=None: chunks run in this process until the work left, estimated from those done here (but the
    first), exceeds POOL_WORTH CPU seconds, the rest in the pool; the results are the same either way. An
    executor shared by several runs keeps its pool for the next."""
    from dfwb.studies import executor

    monkeypatch.setattr(executor, "POOL_AFTER", 0.0)
    monkeypatch.setattr(executor, "POOL_WORTH", pool_worth)
    path = str(fmu_path("FrictionMass"))
    chunks = [executor.Chunk("friction", path, (), ((F, 1.0, {}),)) for F in (10.0, 20.0, 30.0, 40.0)]
    with executor.Executor(jobs=None) as runner:
        runner.jobs = max(runner.jobs, 2)  # a pool even on a one-core machine
        runner._local_first = True
        got = {chunk.points[0][0]: results for chunk, results in runner.run(chunks)}
        assert (runner._pool is not None) == pooled
        pool = runner._pool
        assert len(list(runner.run(chunks[:2]))) == 2 and runner._pool is pool
    with executor.Executor(jobs=1) as alone:
        expected = {chunk.points[0][0]: results for chunk, results in alone.run(chunks)}
    assert {F: [dict(r, seconds=0) for r in rows] for F, rows in got.items()} == \
           {F: [dict(r, seconds=0) for r in rows] for F, rows in expected.items()}
