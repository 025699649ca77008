"""The command line: dfwb df's JSON contract, one-line errors, and resumable sweeps."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from dfwb.cli import main
from dfwb.studies.sweep import grid, run_sweep


def run_cli(capsys, *argv):
    code = main(list(argv))
    return code, capsys.readouterr()


def test_df_json_has_one_object_per_point_F_outer(fmus, capsys):
    code, out = run_cli(capsys, "df", "friction", "--F", "10", "20", "--omega", "1", "2", "--json")
    assert code == 0
    results = json.loads(out.out)
    assert [(r["F"], r["omega"]) for r in results] == [(10.0, 1.0), (10.0, 2.0), (20.0, 1.0), (20.0, 2.0)]
    for r in results:
        assert r["plant"] == "friction" and r["params"] == {}
        assert isinstance(r["periodic"], bool) and isinstance(r["periods"], int)
        assert len(r["harmonics"]) == 11 and r["seconds"] > 0
        assert complex(r["N_re"], r["N_im"]) != 0


def test_df_set_and_table(fmus, capsys):
    code, out = run_cli(capsys, "df", "backlash", "--F", "50", "--omega", "20", "--set", "eps=0.2", "h=0.1")
    assert code == 0
    lines = out.out.strip().splitlines()
    assert lines[0].split()[:6] == ["F", "[N]", "omega", "[rad/s]", "Re", "N"] and len(lines) == 2


@pytest.mark.parametrize("argv, message", [
    (["df", "friction", "--F", "0", "--omega", "1"], "F = 0.0 is out of range"),
    (["df", "friction", "--F", "1", "--omega", "-2"], "omega = -2.0 is out of range"),
    (["df", "friction", "--F", "nan", "--omega", "1"], "F = nan is out of range"),
    (["df", "backlash", "--F", "1", "--omega", "1", "--set", "eps=2"], "eps = 2.0 is out of range"),
    (["df", "backlash", "--F", "1", "--omega", "1", "--set", "mass=2"], "unknown parameter 'mass'"),
    (["df", "friction", "--F", "1", "--omega", "1", "--set", "Fs"], "expected NAME=VALUE"),
    (["df", "gearbox", "--F", "1", "--omega", "1"], "unknown plant 'gearbox' (allowed: friction"),
    (["df", "friction", "--F", "1"], "give --omega"),
    (["df", "friction", "--F", "1", "--omega", "1", "--rtol", "1e-8"],
     "rtol: for a user's FMU only (dfwb's own plants are computed exactly)"),
    (["df", "stribeck", "--F", "10", "--omega", "1", "--set", "rtol=1e-8"], "--set rtol=1e-8: give it as --rtol 1e-8"),
    (["limit-cycle", "friction", "--G", "Kp", "--set", "Kp=1", "exact=1"],
     "--set exact=1: exact is a setting of dfwb itself here (dfwb.limit_cycles's), not a parameter of G or"),
])
def test_bad_input_is_one_line_and_exit_code_2(capsys, argv, message):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1]
    assert all("Traceback" not in line for line in err)


def test_the_command_line_is_the_api(fmus, capsys):
    """dfwb df is dfwb.describing_function: the same records, bit for bit, --rtol setting the Stribeck mass's
    tolerance as rtol= does."""
    import dfwb

    code, out = run_cli(capsys, "df", "stribeck", "--F", "10", "20", "--omega", "1", "--rtol", "1e-8", "--json")
    api = dfwb.describing_function("stribeck", F=[[10.0], [20.0]], omega=[1.0], rtol=1e-8)
    keep = ("F", "omega", "params", "N_re", "N_im", "N_error", "harmonics", "periods")
    assert code == 0 and [{k: r[k] for k in keep} for r in json.loads(out.out)] == \
        [{k: r[k] for k in keep} for r in api.points]
    assert api.points[0]["params"] == {"rtol": 1e-8}


def test_stribecks_rtol_reaches_every_point_of_a_sweep(fmus, tmp_path, capsys):
    """--rtol sets the Stribeck mass's tolerance in a sweep as in dfwb df; with rtol also in --grid, one line."""
    code, _ = run_cli(capsys, "sweep", "stribeck", "--F", "10", "--omega", "1", "2", "--rtol", "1e-8", "--jobs", "1",
                      "--quiet", "--no-cache", "--out", str(tmp_path / "s"))
    assert code == 0
    assert [r["params"] for r in json.loads((tmp_path / "s" / "results.json").read_text())] == [{"rtol": 1e-8}] * 2
    with pytest.raises(SystemExit) as stop:
        main(["sweep", "stribeck", "--F", "10", "--omega", "1", "--rtol", "1e-8", "--grid", "rtol=1e-6,1e-7",
              "--quiet", "--no-cache", "--out", str(tmp_path / "t")])
    assert stop.value.code == 2 and "rtol is given both" in capsys.readouterr().err


def test_json_is_strict_a_failed_points_numbers_are_null(capsys, monkeypatch):
    """A point that failed has no N: --json writes null there, never NaN (which is not JSON)."""
    from dfwb import cli

    monkeypatch.setattr(sys, "stdout", sys.stdout)
    cli._json({"N_re": float("nan"), "N_error": float("inf"), "harmonics": [1.0, float("-inf")]})
    assert json.loads(capsys.readouterr().out) == {"N_re": None, "N_error": None, "harmonics": [1.0, None]}


def test_bad_sweep_writes_nothing(tmp_path, capsys):
    out = tmp_path / "sweep"
    with pytest.raises(SystemExit):
        main(["sweep", "friction", "--F", "10", "-1", "--omega", "1", "--out", str(out)])
    assert not out.exists()


def test_sweep_resumes_and_recomputes_nothing(fmus, tmp_path):
    points = grid([10.0, 20.0], [0.5, 1.0, 2.0], grid_params={"B": [0.5, 1.0]})
    assert len(points) == 12
    first = run_sweep("friction", points, tmp_path, jobs=1, progress=False)
    assert [(r["F"], r["omega"], r["params"]) for r in first] == points  # the records of the points
    # an interruption: 5 rows kept, the 6th cut in the middle
    csv_path = tmp_path / "results.csv"
    lines = csv_path.read_text().splitlines(keepends=True)
    csv_path.write_text("".join(lines[:6]) + lines[6][:20])
    again = run_sweep("friction", points, tmp_path, jobs=1, progress=False)
    assert [r["N_re"] for r in again] == [r["N_re"] for r in first]
    assert [r["seconds"] for r in again[:5]] == [r["seconds"] for r in first[:5]]  # kept, not recomputed
    assert len(json.loads((tmp_path / "results.json").read_text())) == 12


def test_parallel_sweep_equals_serial(fmus, tmp_path):
    points = grid([30.0, 50.0], [15.0, 25.0], grid_params={"eps": [0.2, 0.8]})
    serial = run_sweep("backlash", points, tmp_path / "serial", jobs=1, progress=False)
    parallel = run_sweep("backlash", points, tmp_path / "parallel", jobs=2, progress=False)
    assert [(r["N_re"], r["N_im"], r["periodic"]) for r in serial] == \
        [(r["N_re"], r["N_im"], r["periodic"]) for r in parallel]


def test_a_different_sweep_is_not_mixed_into_a_folder(fmus, tmp_path):
    run_sweep("friction", grid([10.0], [1.0]), tmp_path, jobs=1, progress=False)
    with pytest.raises(ValueError, match="holds a different sweep"):
        run_sweep("friction", grid([10.0], [2.0]), tmp_path, jobs=1, progress=False)


def test_killed_sweep_resumes_where_it_stopped(fmus, tmp_path, killed_run_tmpdir):
    """SIGKILL in the middle of a sweep: every finished point survives; the rerun completes it. Enough points
    that the sweep outlasts the poll (a native friction point takes about 0.1 ms)."""
    points = 1500
    out = tmp_path / "killed"
    argv = [sys.executable, "-m", "dfwb.cli", "sweep", "friction", "--F", "10", "30", "50",
            "--omega-log", "0.05", "5", str(points // 3), "--out", str(out), "--jobs", "1", "--quiet"]
    process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               env=dict(os.environ, TMPDIR=str(killed_run_tmpdir)))
    csv_path = out / "results.csv"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if csv_path.exists() and len(csv_path.read_text().splitlines()) >= 6:
            break
        time.sleep(0.005)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    with open(csv_path) as handle:
        kept = list(csv.DictReader(handle))
    assert 5 <= len(kept) < points
    finished = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    assert finished.returncode == 0, finished.stderr
    with open(csv_path) as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == points
    assert rows[: len(kept)] == kept


@pytest.mark.parametrize("plant, extra", [("friction", []), ("backlash", ["--set", "eps=0.2"]),
                                          ("static-backlash", [])])
def test_fmu_kinds_give_the_same_numbers(fmus, capsys, monkeypatch, plant, extra):
    """--fmu-kind native (the default) and --fmu-kind python, and the python FMU on its pure-Python solver: the same
    points, bit for bit (only the seconds differ)."""
    monkeypatch.setenv("DFWB_FMU", "native")  # main() sets it from --fmu; restored after the test
    runs = {}
    for kind, solver in (("native", ""), ("python", ""), ("python", "python")):
        monkeypatch.setenv("DFWB_FMU_SOLVER", solver)
        code, out = run_cli(capsys, "df", plant, "--F", "10", "50", "--omega", "1", "20", "--json", "--fmu-kind", kind,
                            *extra)
        assert code == 0
        runs[kind, solver] = [dict(point, seconds=0) for point in json.loads(out.out)]
    assert runs["native", ""] == runs["python", ""] == runs["python", "python"]


def test_fmu_kind_is_checked(capsys, monkeypatch):
    monkeypatch.setenv("DFWB_FMU", "native")
    with pytest.raises(SystemExit) as stopped:
        main(["df", "friction", "--F", "10", "--omega", "1", "--fmu-kind", "c"])
    assert stopped.value.code == 2 and "invalid choice: 'c'" in capsys.readouterr().err
    monkeypatch.setenv("DFWB_FMU", "fortran")
    with pytest.raises(SystemExit) as stopped:
        main(["df", "friction", "--F", "10", "--omega", "1"])
    assert stopped.value.code == 2 and "DFWB_FMU = 'fortran' is not an FMU kind" in capsys.readouterr().err


def test_version(capsys):
    import dfwb
    from dfwb.cli import main

    with pytest.raises(SystemExit) as stopped:
        main(["--version"])
    assert stopped.value.code == 0 and capsys.readouterr().out.strip() == f"dfwb {dfwb.__version__}"


def test_every_command_has_a_description_and_an_example_that_parses():
    import shlex

    from dfwb.cli import EXAMPLES, parser

    top = parser()
    commands = top._subparsers._group_actions[0].choices
    assert set(commands) == set(EXAMPLES)
    for name, command in commands.items():
        text = command.format_help()
        assert command.description and " ".join(command.description.split()) in " ".join(text.split()), name
        assert f"example:\n  {EXAMPLES[name]}" in text, name
        args = top.parse_args(shlex.split(EXAMPLES[name])[1:])  # the example is valid on the command line
        assert args.command == name


def test_a_controller_is_required_and_shown_so(capsys):
    from dfwb.cli import parser

    usage = parser()._subparsers._group_actions[0].choices["limit-cycle"].format_usage()
    assert "(--G G | --num NUM [NUM ...])" in " ".join(usage.split())
    with pytest.raises(SystemExit) as stopped:
        parser().parse_args(["limit-cycle", "friction"])
    assert stopped.value.code == 2 and "one of the arguments --G --num is required" in capsys.readouterr().err


def test_the_stress_help_says_the_quick_sets_size():
    import re

    from dfwb.cli import parser
    from dfwb.verify.stress import all_cases

    text = " ".join(parser()._subparsers._group_actions[0].choices["stress"].format_help().split())
    assert int(re.search(r"the quick set \((\d+) cases", text).group(1)) == len(all_cases(quick=True))
