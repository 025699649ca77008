"""Hostile input to the files, the cache, the options and the processes (issue 10): each test failed before.

Paths from data stay inside their folder, links are replaced and never written
through, repeated options accumulate, resumed rows are verified, a broken
cache costs a warning and no result, sizes are counted before anything is
allocated, every refusal is one line with exit code 2, and workers die with
their parent.
"""

import base64
import errno
import hashlib
import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from refusals import refused

from dfwb.base import files as dfwb_files
from dfwb.base.files import FolderBusy, file_digest, folder_lock, inside, write_atomic
from dfwb.cli import main
from dfwb.studies.cache import Cache
from dfwb.studies.runner import run_scene
from dfwb.studies.scene import parse_scene
from dfwb.studies.sweep import grid, run_sweep

ROOT = Path(__file__).resolve().parents[1]

FIGURE_SCENE = '''
title = "one figure"
[[series]]
name = "friction"
plant = "friction"
F = [10.0]
omega = [1.0, 2.0]

[[figure]]
name = "nyquist"
kind = "nyquist"
series = ["friction"]
'''


def df_json(capsys, *argv):
    assert main(["df", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


# -- 1. paths from data stay inside their folder ---------------------------------------------------------------
def test_inside_refuses_every_name_that_leaves_its_folder(tmp_path):
    (tmp_path / "link").symlink_to(tmp_path.parent)
    for name in ("../x", "/etc/passwd", "a/../../x", "", ".", "..", ".hidden", "link/x", "a\\..\\x", "x\0y"):
        with pytest.raises(ValueError):
            inside(tmp_path, name)
    assert inside(tmp_path, "traces/a.csv") == tmp_path / "traces" / "a.csv"


def _run_record(cache):
    """The one cache entry holding a whole run's outputs: (its file, its header, its value)."""
    entries = [p for p in cache.rglob("*.json") if b'\\"kind\\":\\"run\\"' in p.read_bytes().split(b"\n")[0]]
    assert len(entries) == 1
    head, body = entries[0].read_bytes().split(b"\n", 1)
    return entries[0], head, json.loads(body)


def _sign(path, head, value):
    """Write ``value`` as a valid entry: whoever can write the cache can sign it."""
    body = json.dumps(value, sort_keys=True, separators=(",", ":")).encode()
    header = dict(json.loads(head), sha256=hashlib.sha256(body).hexdigest())
    path.write_bytes(json.dumps(header).encode() + b"\n" + body)


@pytest.mark.parametrize("craft", ["outside", "extra", "section", "base64", "points", "summary", "negative",
                                   "figures"])
def test_a_crafted_run_record_cannot_write_outside_the_folder_nor_be_copied(fmus, tmp_path, craft):
    cache, out = tmp_path / "cache", tmp_path / "out"
    run_scene(parse_scene(FIGURE_SCENE, "f.toml"), out, jobs=1, cache=cache, progress=False)
    path, head, value = _run_record(cache)
    if craft == "outside":  # a name outside the folder instead of the figure's
        value["files"]["../../outside.png"] = value["files"].pop("nyquist.png")
        value["figures"] = ["../../outside.png"]
    elif craft == "extra":
        value["files"]["planted.sh"] = base64.b64encode(b"planted").decode()
    elif craft == "section":
        value["sections"] = [["t", "../../outside.png", "text"]]
    elif craft == "base64":
        value["files"]["results.csv"] = "not base64!"
    elif craft == "summary":  # a text, not a list of lines: its characters are strings too
        value["summary"] = "x"
    elif craft == "negative":
        value["points"] = -5
    elif craft == "figures":
        value["figures"] = {"nyquist.png": 1}
    else:
        value["points"] = "12"
    _sign(path, head, value)
    outcome = run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "second", jobs=1, cache=cache,
                        progress=False)
    assert not (tmp_path / "outside.png").exists() and not (tmp_path.parent / "outside.png").exists()
    assert not (tmp_path / "second" / "planted.sh").exists()
    assert outcome.rejected == 1 and not outcome.copied and outcome.cache_hits == 2  # run: its 2 points cached
    assert (tmp_path / "second" / "nyquist.png").read_bytes()[:4] == b"\x89PNG"
    assert "1 cache entries rejected" in (tmp_path / "second" / "summary.md").read_text()


def test_an_output_replaced_by_a_link_during_the_run_is_not_stored_in_the_cache(fmus, tmp_path):
    from dfwb.studies.runner import begin_scene

    secret, cache = tmp_path / "secret.txt", tmp_path / "cache"
    secret.write_text("not for the cache")
    run = begin_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "a", 1, None, cache,
                      fmus["FrictionMass"].parent, False)
    (tmp_path / "a" / "results.json").unlink()
    (tmp_path / "a" / "results.json").symlink_to(secret)  # between the run's writing and its record
    run.finish()
    again = run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "b", jobs=1, cache=cache, progress=False)
    assert not again.copied and "not for the cache" not in (tmp_path / "b" / "results.json").read_text()


def test_write_atomic_never_touches_the_process_umask(tmp_path, monkeypatch):
    """Reading the umask sets it for a moment: a thread writing meanwhile would make a world-writable folder."""
    def refuse(mask):
        raise AssertionError("os.umask called while writing")

    monkeypatch.setattr(os, "umask", refuse)
    write_atomic(tmp_path / "f", b"x")
    assert (tmp_path / "f").stat().st_mode & 0o777 == 0o644 & ~dfwb_files.UMASK


def test_a_run_copied_from_the_cache_writes_what_the_run_wrote(fmus, tmp_path):
    cache = tmp_path / "cache"
    first = run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "a", jobs=1, cache=cache, progress=False)
    copied = run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "b", jobs=1, cache=cache, progress=False)
    assert copied.copied and not first.copied and (copied.points, copied.computed) == (first.points, 0)
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == names
    for name in names:
        a, b = (tmp_path / "a" / name).read_text(errors="replace"), (tmp_path / "b" / name).read_text(errors="replace")
        if name == "summary.md":  # all but the line saying where the results came from
            assert "every output copied from the cache" in b
            a, b = (text.split("\n", 4)[4] for text in (a, b))
        if name != "manifest.json":
            assert a == b, name
    assert run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path / "b", jobs=1, cache=cache,
                     progress=False).up_to_date


def test_a_manifest_naming_files_outside_the_folder_is_damaged(fmus, tmp_path):
    out = tmp_path / "out"
    scene = parse_scene(FIGURE_SCENE, "f.toml")
    run_scene(scene, out, jobs=1, cache=False, progress=False)
    secret = tmp_path / "secret.txt"
    secret.write_text("not dfwb's")
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["files"]["../secret.txt"] = file_digest(secret)
    (out / "manifest.json").write_text(json.dumps(manifest))
    outcome = run_scene(scene, out, jobs=1, cache=False, progress=False)
    assert not outcome.up_to_date  # the run is redone, not trusted
    assert "../secret.txt" not in json.loads((out / "manifest.json").read_text())["files"]


# -- 2. FMUs shipped to workers ----------------------------------------------------------------------------------
def test_shipped_fmus_live_in_a_private_folder_and_are_verified_at_every_use(fmus, tmp_path, monkeypatch):
    import dfwb.studies.executor as executor

    monkeypatch.setattr(executor, "_SHIPPED_DIR", [])
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)
    data = Path(fmus["FrictionMass"]).read_bytes()
    planted = tmp_path / "dfwb-fmus" / hashlib.sha256(data).hexdigest()[:16] / "FrictionMass.fmu"
    planted.parent.mkdir(parents=True)
    planted.write_bytes(b"planted code")  # where the old code looked
    path = executor._materialize("FrictionMass.fmu", data)
    assert path != planted and path.read_bytes() == data
    assert stat.S_IMODE(path.parent.parent.stat().st_mode) == 0o700
    path.write_bytes(b"changed after shipping")
    again = executor._materialize("FrictionMass.fmu", data)
    assert again.read_bytes() == data


# -- 3. links inside --out ------------------------------------------------------------------------------------------
def test_links_in_the_output_folder_are_replaced_not_written_through(fmus, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    victim = elsewhere / "victim.csv"
    victim.write_text("precious\n")
    out = tmp_path / "sweep"
    out.mkdir()
    (out / "results.csv").symlink_to(victim)
    (out / "results.json").symlink_to(elsewhere / "victim.json")
    run_sweep("friction", grid([10.0], [1.0]), out, jobs=1, progress=False)
    assert victim.read_text() == "precious\n" and not (elsewhere / "victim.json").exists()
    assert not (out / "results.csv").is_symlink() and len((out / "results.csv").read_text().splitlines()) == 2

    scene_out = tmp_path / "scene"
    scene_out.mkdir()
    (scene_out / "traces").symlink_to(elsewhere, target_is_directory=True)
    (scene_out / "summary.md").symlink_to(victim)
    traced = FIGURE_SCENE + '''
[[trace]]
name = "x"
plant = "friction"
F = 10.0
omega = 1.0
stop = 1.0
step = 0.1
outputs = ["x"]
'''
    run_scene(parse_scene(traced, "t.toml"), scene_out, jobs=1, cache=False, progress=False)
    assert victim.read_text() == "precious\n" and sorted(p.name for p in elsewhere.iterdir()) == ["victim.csv"]
    assert (scene_out / "traces" / "x.csv").is_file() and not (scene_out / "traces").is_symlink()


def test_a_planted_partial_file_is_not_followed(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    for pid in range(os.getpid(), os.getpid() + 3):
        (tmp_path / f".out.txt.{pid}.partial").symlink_to(victim)
    write_atomic(tmp_path / "out.txt", "new")
    assert victim.read_text() == "precious" and (tmp_path / "out.txt").read_text() == "new"


# -- 4. and 5. repeated options, parameters as numbers ------------------------------------------------------------
def test_repeated_options_accumulate(fmus, capsys):
    results = df_json(capsys, "backlash", "--F", "30", "--F", "50", "--omega", "20", "--set", "eps=0.2",
                      "--set", "h=0.05")
    assert [r["F"] for r in results] == [30.0, 50.0]
    assert all(r["params"] == {"eps": 0.2, "h": 0.05} for r in results)
    alone = df_json(capsys, "backlash", "--F", "30", "--omega", "20", "--set", "h=0.05", "eps=0.2")
    assert alone[0]["N_re"] == results[0]["N_re"]


@pytest.mark.parametrize("argv, message", [
    (["df", "backlash", "--F", "30", "--omega", "20", "--set", "eps=0.2", "eps=0.9"], "--set eps given twice"),
    (["df", "backlash", "--F", "30", "--omega", "20", "--set", "eps=0.2", "--set", "eps=0.9"], "--set eps given twice"),
    (["sweep", "friction", "--F", "10", "--omega", "1", "--out", "a", "--out", "b"], "--out given twice (a and b)"),
    (["sweep", "friction", "--F", "10", "--omega", "1", "--grid", "B=1,2", "--grid", "B=3", "--out", "a"],
     "--grid B given twice"),
    (["sweep", "friction", "--F", "10", "--omega", "1", "--set", "B=1", "--grid", "B=1,2", "--out", "a"],
     "B is given both by --set and by --grid"),
    (["df", "friction", "--F", "10", "--omega-log", "1", "2", "3", "--omega-log", "1", "2", "4"],
     "--omega-log given twice"),
    (["df", "friction", "--F", "10", "--omega", "1", "--omega-log", "1", "2", "3"], "not both"),
    (["limit-cycle", "friction", "--G", "1/s", "--G", "2/s"], "--G given twice"),
])
def test_a_name_given_twice_with_two_values_is_an_error(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    assert message in refused(capsys, *argv)
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_with_set_resumes_its_points(fmus, tmp_path, capsys):
    argv = ["sweep", "backlash", "--F", "50", "--omega", "20", "30", "--set", "eps=0.2", "--out", str(tmp_path),
            "--jobs", "1", "--quiet"]
    assert main(argv) == 0
    assert main(argv) == 0
    assert "2 points" in capsys.readouterr().out
    assert len((tmp_path / "results.csv").read_text().splitlines()) == 3  # header and two rows, not four
    rows = json.loads((tmp_path / "results.json").read_text())
    assert [r["params"] for r in rows] == [{"eps": 0.2}] * 2


# -- 7. resumed rows are verified --------------------------------------------------------------------------------------
def test_an_edited_row_is_recomputed_not_trusted(fmus, tmp_path):
    points = grid([10.0], [1.0, 2.0])
    first = run_sweep("friction", points, tmp_path, jobs=1, progress=False)
    path = tmp_path / "results.csv"
    path.write_text(path.read_text().replace(repr(first[0]["N_re"]), "123.0", 1))
    again = run_sweep("friction", points, tmp_path, jobs=1, progress=False)
    assert again[0]["N_re"] == first[0]["N_re"] and again[1]["seconds"] == first[1]["seconds"]

    scene = parse_scene(FIGURE_SCENE, "f.toml")
    out = tmp_path / "scene"
    run_scene(scene, out, jobs=1, cache=False, progress=False)
    log = out / "results.csv"
    original = json.loads((out / "results.json").read_text())["series"]["friction"][0]["N_re"]
    log.write_text(log.read_text().replace(repr(original), "123.0", 1))
    (out / "manifest.json").unlink()
    outcome = run_scene(scene, out, jobs=1, cache=False, progress=False)
    assert outcome.resumed == 1 and outcome.computed == 1 and outcome.rejected == 1
    assert json.loads((out / "results.json").read_text())["series"]["friction"][0]["N_re"] == original


# -- 8. one folder, one run ------------------------------------------------------------------------------
def test_two_scenes_of_the_same_name_are_refused(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for folder in ("a", "b"):
        (tmp_path / folder / "s.toml").write_text(FIGURE_SCENE)
    line = refused(capsys, "run", str(tmp_path / "a" / "s.toml"), str(tmp_path / "b" / "s.toml"),
                   "--out", str(tmp_path / "o"), "--quiet")
    assert "would both write to" in line and not (tmp_path / "o").exists()


def test_a_second_run_into_a_busy_folder_is_refused(fmus, tmp_path):
    with folder_lock(tmp_path):
        with pytest.raises(FolderBusy, match="in use by another dfwb run"):
            run_sweep("friction", grid([10.0], [1.0]), tmp_path, jobs=1, progress=False)
        with pytest.raises(FolderBusy):
            run_scene(parse_scene(FIGURE_SCENE, "f.toml"), tmp_path, jobs=1, cache=False, progress=False)
    assert not (tmp_path / "results.csv").exists() and not (tmp_path / ".dfwb.lock").exists()  # none left
    run_sweep("friction", grid([10.0], [1.0]), tmp_path, jobs=1, progress=False)  # free again
    assert (tmp_path / "results.csv").exists() and not (tmp_path / ".dfwb.lock").exists()


# -- 9. a cache that cannot be written ------------------------------------------------------------------------------
def test_a_cache_that_cannot_be_written_costs_a_warning_not_a_result(fmus, tmp_path, capsys):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "v2").write_text("a file where the entries' folder belongs")
    scene_file = tmp_path / "s.toml"
    scene_file.write_text(FIGURE_SCENE)
    assert main(["run", str(scene_file), "--out", str(tmp_path / "o"), "--cache", str(cache), "--jobs", "1",
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: the cache") == 1 and "cannot be written" in err
    assert len(json.loads((tmp_path / "o" / "results.json").read_text())["series"]["friction"]) == 2
    store = Cache(cache)
    with pytest.warns(UserWarning, match="cannot be written"):
        store.put({"kind": "demo"}, {"y": 1.0})  # never raises
    assert store.failed == 1 and store.get({"kind": "demo"}) is None


# -- 11. sizes are counted before anything is allocated ------------------------------------------------------------
def test_sizes_are_counted_before_anything_is_built(tmp_path, capsys):
    assert "--omega-log 1 10 1e+09" in refused(capsys, "sweep", "friction", "--F", "10", "--omega-log", "1", "10",
                                                "1e9", "--out", str(tmp_path / "o"))
    assert "not a regular file" in refused(capsys, "run", "/dev/zero", "--out", str(tmp_path / "o"))
    huge = tmp_path / "huge.toml"
    huge.write_text(FIGURE_SCENE + "#" * (2 << 20))
    assert "larger than" in refused(capsys, "run", str(huge), "--out", str(tmp_path / "o"))
    assert not (tmp_path / "o").exists()
    values = ", ".join(["1.0"] * 1024)
    overflow = FIGURE_SCENE.replace('omega = [1.0, 2.0]', 'omega = [1.0, 2.0]\ngrid = { ' + ", ".join(
        f"{name} = [{values}]" for name in ("M", "B", "Fc", "Fs", "Dv", "v0", "x0")) + " }")
    with pytest.raises(ValueError, match="at most 200000"):  # 1024**7 = 2**70 was 0 for np.prod
        parse_scene(overflow, "g.toml")
    soak = FIGURE_SCENE + ('[[trace]]\nname = "t"\nplant = "friction"\nF = 10.0\nomega = 10.0\nstop = 1e9\n'
                           'step = 1e5\noutputs = ["x"]\n')
    with pytest.raises(ValueError, match="forcing periods"):  # 1e4 samples but 1.6e9 periods: it ran for hours
        parse_scene(soak, "t.toml")
    maps = FIGURE_SCENE + ('[[limit_cycle]]\nname = "lc"\nplant = "friction"\nG = "10/s"\nF_range = [8.0, 100.0]\n'
                           'omega_range = [0.1, 10.0]\nn_F = 1000\nn_omega = 1000\n')
    with pytest.raises(ValueError, match="limit-cycle maps"):
        parse_scene(maps, "m.toml")


def test_files_are_hashed_in_pieces(tmp_path):
    path = tmp_path / "sparse"
    with open(path, "wb") as stream:
        stream.truncate((3 << 20) + 5)
        stream.seek(1 << 20)
        stream.write(b"x")
    assert file_digest(path) == hashlib.sha256(path.read_bytes()).hexdigest()


# -- 12. one line and exit code 2, never a traceback ------------------------------------------------------------------
@pytest.mark.parametrize("argv, message", [
    (["df", "friction", "--F", "10", "--omega", "1e300"], "omega = 1e+300 is out of range"),
    (["df", "friction", "--F", "10", "--omega", "1e-300"], "omega = 1e-300 is out of range"),
    (["df", "friction", "--F", "1e30", "--omega", "1"], "F = 1e+30 is out of range"),
    (["limit-cycle", "static-backlash", "--G", "s**(1e309)"], "not finite"),
    (["limit-cycle", "static-backlash", "--G=" + "-" * 100000 + "s"], "at most 1000"),
    (["limit-cycle", "static-backlash", "--G=" + "-" * 900 + "s"], "nested more than"),
    (["limit-cycle", "friction", "--G", "1/s", "--omega-range", "1e-300", "1"], "omega range = [1e-300, 1.0]"),
    (["limit-cycle", "friction", "--G", "10/s", "--verify", "--samples-per-period", "0"],
     "--samples-per-period: 0 is out of range"),
    (["sweep", "friction", "--F", "10", "--omega", "1", "--out", "o", "--jobs", "-3"], "--jobs: -3 is out of range"),
    (["df", "friction", "--F", "10", "--omega", "1", "--samples-per-period", "x"], "'x' is not an integer"),
    (["run", "nowhere.toml", "--cache", "c", "--no-cache"], "not both"),
    (["df", "friction", "--F", "1", "--omega-log", "1", "5", "inf"], "--omega-log 1 5 inf"),
    (["limit-cycle", "friction", "--G", "10/s", "--plot", "out/"], "expected a file name ending in .png"),
    (["limit-cycle", "friction", "--G", "10/s", "--plot", "missing/cycle.png"], "the folder missing does not exist"),
    # numbers in their plain forms only: Python reads '1_0' as 10 and other scripts' digits as digits
    (["df", "friction", "--F", "1_0", "--omega", "1"], "argument --F: '1_0' is not a number"),
    (["df", "friction", "--F", "\u0661\u0660", "--omega", "1"], "is not a number"),
    (["limit-cycle", "friction", "--G", "Kp/s", "--set", "Kp=1_0"], "Kp = '1_0' is not a number"),
    (["limit-cycle", "friction", "--G", "10/s", "--map-size", "1_6", "48"], "'1_6' is not an integer"),
    (["df", "friction", "--F", "10", "--omega", "1", "--samples-per-period", " 64"], "' 64' is not an integer"),
    (["df", "friction", "--F", "10", "--omega", "1", "--samples-per-period", "9" * 5000], "is out of range: an integer"),
    (["df", "friction", "--F", "1" * 100_000 + "x", "--omega", "1"], "... is not a number (a plain decimal"),
])
def test_bad_values_are_one_line_not_a_traceback(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    if argv[0] == "run":
        (tmp_path / "nowhere.toml").write_text(FIGURE_SCENE)
    assert message in refused(capsys, *argv)


def test_dask_without_distributed_is_one_line(fmus, tmp_path):
    code = ("import sys; sys.modules['distributed'] = None\n"
            "from dfwb.cli import main\n"
            f"main(['run', {str(ROOT / 'scenes' / 'fig03_friction_nyquist.toml')!r}, '--dask', 'local', "
            f"'--out', {str(tmp_path / 'o')!r}, '--no-cache', '--quiet'])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.strip() == \
        "dfwb run: error: --dask needs dask.distributed: pip install -e '.[dask]'"


# -- 13. processes ---------------------------------------------------------------------------------------
def _children(pid):
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    found.append(int(entry.name))
            except (OSError, IndexError, ValueError):
                continue
    return found


def _alive(pid):
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_workers_exit_when_their_parent_is_killed(fmus, tmp_path, killed_run_tmpdir):
    # 60,000 points: the workers are still busy when the parent dies (a native friction point takes ~0.1 ms)
    argv = [sys.executable, "-m", "dfwb.cli", "sweep", "friction", "--F", "10", "30", "50", "--omega-log", "0.05",
            "5", "20000", "--out", str(tmp_path / "o"), "--jobs", "2", "--quiet", "--fmus", str(Path(fmus["FrictionMass"]).parent)]
    process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               env=dict(os.environ, TMPDIR=str(killed_run_tmpdir)))
    deadline = time.monotonic() + 90
    children = []
    while time.monotonic() < deadline and len(children) < 3:  # the resource tracker and two workers
        time.sleep(0.2)
        children = _children(process.pid)
    assert len(children) >= 3, children
    time.sleep(1.0)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(_alive(pid) for pid in children):
        time.sleep(0.2)
    left = [pid for pid in children if _alive(pid)]
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert not left, "orphans left running"
    assert [path.name for path in killed_run_tmpdir.glob("dfwb_*")] == []  # the pool's folder went with its workers


def test_sigterm_during_a_step_reads_interrupted(fmus, tmp_path):
    # 100,000 points: about half a minute on the native FMU, still stepping when the signal comes at 4 s
    argv = [sys.executable, "-m", "dfwb.cli", "df", "backlash", "--F", "50", "--omega-log", "1", "100", "100000",
            "--fmus", str(Path(fmus["FrictionMass"]).parent)]
    process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(4.0)  # imports done, deep in the FMU's steps
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130 and err.strip().splitlines() == ["dfwb df: interrupted"], err


# -- 14. a full disk names its file ----------------------------------------------------------------------
def test_a_write_error_names_its_file(fmus, tmp_path, capsys, monkeypatch):
    def full(descriptor):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("dfwb.base.runlog.os.fsync", full)
    line = refused(capsys, "sweep", "friction", "--F", "10", "--omega", "1", "--out", str(tmp_path), "--jobs", "1",
                   "--quiet")
    assert line == f"dfwb sweep: error: {tmp_path / 'results.csv'}: No space left on device"
