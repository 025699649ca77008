"""benchmarks/new_plants.py runs (``--quick``) and reports issue 32's two DF targets.

The timings are never asserted (the machine's load blurs them): only that the benchmark runs to the end as a
user runs it, and that its report holds every plant's row and both verdicts.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "new_plants.py"


@pytest.mark.slow
def test_the_report_holds_every_plant_and_both_verdicts(fmus, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(out)], capture_output=True,
                          text=True, timeout=900, env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-4000:]
    text = (out / "new_plants.md").read_text()
    for plant, points in (("stribeck", 40), ("friction", 40), ("drivetrain", 5), ("drivetrain, Fc = Fs = B = 0", 5),
                          ("backlash", 5)):
        assert re.search(rf"^\| {plant} \| {points} \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \|", text, re.M), plant
    assert re.search(r"stribeck, mean DF point at rtol 1e-9: [0-9.]+ ms \(target <= 1 ms\): \*\*(PASS|FAIL)\*\*", text)
    assert re.search(r"drivetrain against backlash, mean DF point: [0-9.]+x .*\*\*(PASS|FAIL)\*\*", text)
    assert re.search(r"With the load.s friction off \(drivetrain, Fc = Fs = B = 0\) it is [0-9.]+x, in [0-9]+ periods", text)
    assert "Machine:" in text


def test_an_output_folder_that_cannot_be_made_is_one_line_before_anything_runs(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(blocker / "out")], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 2 and "Traceback" not in done.stderr and "round" not in done.stdout
    assert done.stderr.strip().splitlines()[-1].startswith("new_plants.py: error: --out ")
