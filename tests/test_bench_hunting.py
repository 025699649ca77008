"""benchmarks/hunting.py runs (``--quick``) and its report names every quantity it measures.

The timings themselves are never asserted (the machine's load blurs them): only that the benchmark
runs to the end as a user runs it, and that hunting.md and hunting.json hold every measurement.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "hunting.py"

# what the report must name: (a) the map, (b) the continuation, (c) find_cycles, and the targets' verdicts
NAMED = ("map wall time", "time per cell", "per-cell compute time", "median", "90th percentile", "max",
         "continuation wall time", "time per point", "find_cycles", "a 30 x 30 map in <= 60 s",
         "200 continuation points in <= 5 s", "Machine:", "noisy")


@pytest.fixture(scope="module")
def report(fmus, tmp_path_factory):
    """(hunting.md, hunting.json) of one quick run, on a 4 x 4 map with a 2 x 2 sample (the quick default: 10 x 10
    and 4 x 4): the report's structure is checked here, the speed by the benchmark itself."""
    tmp_path = tmp_path_factory.mktemp("bench_hunting")
    out = tmp_path / "out"
    env = dict(os.environ, MPLCONFIGDIR=str(tmp_path / "mpl"))
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--size", "4", "--sample", "2", "--out", str(out)], capture_output=True,
                          text=True, timeout=1800, env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-4000:]
    return (out / "hunting.md").read_text(), json.loads((out / "hunting.json").read_text())


@pytest.mark.slow
def test_the_report_names_every_measured_quantity(report):
    text, data = report
    assert [name for name in NAMED if name not in text] == []
    assert [name for name in data["quantities"] if name not in text] == []
    assert text.count("| 5 | 0.5 |") == 1 and text.count("| 40 | 4 |") == 1  # find_cycles: every loop has a row


@pytest.mark.slow
def test_the_json_holds_every_measurement(report):
    _, data = report
    assert data["quick"] is True and data["machine"]["cpus"] >= 1
    the_map = data["map"]
    assert the_map["size"] == [4, 4] and the_map["cells"] == 16 and the_map["jobs"] == 2
    assert the_map["runs"][0]["counts"]["computed"] == 16
    for key in ("seconds", "seconds_per_cell", "cells_seconds_per_cell"):
        assert the_map[key] > 0.0, key
    assert {"setup", "df map", "cells", "linear map", "curves", "write"} <= set(the_map["phases"])
    assert the_map["target_met"] is None  # a 4 x 4 map is not the target's 30 x 30
    sample = the_map["sample"]
    assert len(sample["cells"]) == 4 and sample["same_as_map"] == 4
    assert 0.0 < sample["seconds"]["median"] <= sample["seconds"]["p90"] <= sample["seconds"]["max"]
    assert sum(the_map["truth"].values()) == sum(the_map["df"].values()) == 16

    continuation = data["continuation"]
    assert continuation["points"] >= 200  # the set reaches the target's 200 points
    assert len(continuation["continuations"]) == 4
    assert all(row["seconds"] > 0.0 and row["points"] > 0 for row in continuation["continuations"])
    assert continuation["seconds_per_point"] > 0.0 and isinstance(continuation["target_met"], bool)

    pairs = data["find_cycles"]["pairs"]
    assert sorted((p["Kp"], p["Ki"]) for p in pairs) == sorted(
        (Kp, Ki) for Kp in (5, 10, 20, 40) for Ki in (0.5, 1, 2, 4))
    assert all(p["seconds"] > 0.0 and p["coverage"].startswith("searched") for p in pairs)
