"""Sweeps of describing functions over F x omega x plant parameters, in parallel, resumable.

Every finished point is appended to ``results.csv`` at once (flushed and
synced, with a checksum: :mod:`dfwb.runlog`), so an interrupted sweep loses
at most the points in flight; the next run with the same definition skips
what the CSV verifiably holds. One sweep at a time writes into a folder (a
second is refused), and a sweep has at most ``MAX_POINTS`` points, counted
before any is built. ``results.json`` (the complete list, complex N and -1/N as pairs) is
rewritten atomically as the sweep goes and at its end. The definition
is kept in ``sweep.json``: resuming a different sweep into the same folder is
refused rather than mixed.
"""

import itertools
import json
import math
import os
import time
from pathlib import Path

from tqdm import tqdm

from .describing import HARMONICS, check_point
from .executor import Chunk, Executor, chunked
from .files import folder_lock, read_bytes, write_atomic
from .runlog import RunLog
from .plants import DEFAULT_FMU_DIR, fmu_path, plant as find_plant
from dfwb.fmus.piecewise import PlantError

COLUMNS = (["plant", "F", "omega", "params", "drive", "N_re", "N_im", "minus_inv_N_re", "minus_inv_N_im",
            "periodic", "periods", "orbit_periods", "seconds", "note"]
           + [f"X{k}" for k in range(HARMONICS + 1)])
MAX_POINTS = 200_000  # DF points of one sweep or scene: hours of computing, a few hundred MB of results


def grid_size(*lengths):
    """The number of points of a grid, counted exactly (Python integers never overflow)."""
    return math.prod(int(n) for n in lengths)


def check_size(size, what="the sweep"):
    if size > MAX_POINTS:
        raise PlantError(f"{what} has {size} points: at most {MAX_POINTS} (split it)")


def grid(Fs, omegas, params=None, grid_params=None):
    """The sweep's points, F the outer loop: [(F, omega, {name: value})]; refused beyond MAX_POINTS."""
    grid_params = grid_params or {}
    names = sorted(grid_params)
    check_size(grid_size(len(Fs), len(omegas), *(len(grid_params[n]) for n in names)))
    combos = [dict(zip(names, values)) for values in itertools.product(*(grid_params[n] for n in names))]
    return [(F, omega, dict(params or {}, **combo)) for F in Fs for combo in combos for omega in omegas]


def key(F, omega, params):
    return (repr(float(F)), repr(float(omega)), json.dumps(params, sort_keys=True))


def row(data):
    """A CSV row of a DF result's as_dict(), as text exactly as the CSV holds it (floats round-trip)."""
    data = dict(data)
    data["params"] = json.dumps(data["params"], sort_keys=True)
    for k, value in enumerate(data.pop("harmonics")):
        data[f"X{k}"] = value
    return {name: "" if data.get(name) is None else str(data[name]) for name in COLUMNS}


def parse_row(r):
    """The DF result's as_dict() back from its CSV row."""
    def number(value):
        return None if value == "" else float(value)

    return {"plant": r["plant"], "F": float(r["F"]), "omega": float(r["omega"]), "params": json.loads(r["params"]),
            "drive": r["drive"], "N_re": float(r["N_re"]), "N_im": float(r["N_im"]),
            "minus_inv_N_re": number(r["minus_inv_N_re"]), "minus_inv_N_im": number(r["minus_inv_N_im"]),
            "periodic": r["periodic"] == "True", "periods": int(r["periods"]),
            "orbit_periods": int(r["orbit_periods"]), "seconds": float(r["seconds"]), "note": r["note"],
            "harmonics": [float(r[f"X{k}"]) for k in range(HARMONICS + 1) if r[f"X{k}"] != ""]}


def json_form(result):
    """An as_dict() for results.json: complex N and -1/N as [re, im] pairs."""
    out = {name: result[name] for name in ("plant", "F", "omega", "params", "drive")}
    out["N"] = [result["N_re"], result["N_im"]]
    out["minus_inv_N"] = (None if result["minus_inv_N_re"] is None
                          else [result["minus_inv_N_re"], result["minus_inv_N_im"]])
    out.update({name: result[name] for name in ("periodic", "periods", "orbit_periods", "seconds", "note",
                                                 "harmonics")})
    return out


def as_json(rows):
    """results.json entries of CSV rows."""
    return [json_form(parse_row(r)) for r in rows]


def run_sweep(plant, points, out_dir, jobs=None, drive="internal", samples_per_period=64,
              fmu_dir=DEFAULT_FMU_DIR, progress=True, resume=True):
    """Compute every point not yet in ``out_dir``; return all rows in grid order.

    Parameters
    ----------
    plant : str
    points : list of (F, omega, params)
        Usually from :func:`grid`.
    out_dir : path
        Gets ``results.csv``, ``results.json`` and ``sweep.json``.
    jobs : int, optional
        Worker processes (default: all cores); 1 computes in this process.
    """
    spec = find_plant(plant)
    check_size(len(points))
    points = [(float(F), float(omega), spec.checked(params)) for F, omega, params in points]  # numbers, not text
    for F, omega, _ in points:  # everything is checked before anything runs
        check_point(F, omega)
    out_dir = Path(out_dir)
    definition = {"plant": plant, "drive": drive, "samples_per_period": samples_per_period if drive == "input" else None,
                  "points": [[F, omega, params] for F, omega, params in points]}
    with folder_lock(out_dir):
        stored = out_dir / "sweep.json"
        log = RunLog(out_dir / "results.csv", COLUMNS, max_rows=len(points))
        if resume and stored.exists() and _definition(stored) != definition:
            raise PlantError(f"{out_dir} holds a different sweep (see {stored}); use another folder or --no-resume")
        if not resume:
            log.path.unlink(missing_ok=True)
        write_atomic(stored, json.dumps(definition, indent=1))

        wanted = {key(*p) for p in points}
        done = {}
        for r in log.read():
            try:
                k = key(float(r["F"]), float(r["omega"]), json.loads(r["params"]))
            except (TypeError, ValueError):
                continue
            if k in wanted:
                done[k] = r
        pending = [p for p in points if key(*p) not in done]
        jobs = max(1, min(jobs or os.cpu_count() or 1, len(pending) or 1))
        with log, tqdm(total=len(points), initial=len(points) - len(pending), unit="pt", disable=not progress,
                       desc=f"{plant} DF") as bar:
            last_json = time.monotonic()
            settings = (("drive", drive), ("samples_per_period", samples_per_period))
            fmu = str(fmu_path(spec, fmu_dir))
            with Executor(jobs) as executor:
                for _chunk, results in executor.run(Chunk(plant, fmu, settings, c) for c in chunked(pending, jobs)):
                    rows = [row(r) for r in results]
                    log.append(rows)
                    for r in rows:
                        done[key(float(r["F"]), float(r["omega"]), json.loads(r["params"]))] = r
                    bar.update(len(rows))
                    if time.monotonic() - last_json > 5.0:
                        _write_json(out_dir, points, done)
                        last_json = time.monotonic()
        return _write_json(out_dir, points, done)


def _definition(path):
    """The definition stored in sweep.json, or None when it is not one (damaged, or not JSON)."""
    try:
        return json.loads(read_bytes(path, 256 << 20, "sweep definition"))
    except (OSError, ValueError):
        return None


def _write_json(out_dir, points, done):
    rows = [done[key(*p)] for p in points if key(*p) in done]
    write_atomic(Path(out_dir) / "results.json", json.dumps(as_json(rows), indent=1))
    return rows
