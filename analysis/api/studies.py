"""The public functions that write studies to a folder: scenes, sweeps and their grids.

Apart from :mod:`dfwb.api.functions` because a scene re-run from the cache
only copies: importing this loads no numpy, fmpy or python-control.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Optional, Sequence, Union

from dfwb.base.defaults import SAMPLES_PER_PERIOD
from dfwb.base.errors import InputError
from dfwb.base.values import short as _short

__all__ = ["run_scene", "sweep", "grid"]


def folder(name, value):
    """An output folder given to the API: a path, never empty ('' is the current folder to pathlib, as the
    command line's --out '' would be: refused there too)."""
    if not isinstance(value, (str, os.PathLike)):
        raise InputError(f"{name} = {_short(value)} is not a folder: give a path")
    if not os.fspath(value).strip():
        raise InputError(f"{name} = {_short(value)} is empty: give a folder ('.' for the current one)")
    return value



def run_scene(scene: Union[str, Path, Any], out_dir: Optional[Union[str, Path]] = None, *,
              jobs: Optional[int] = None, dask: Optional[str] = None, cache: Union[bool, str, Path] = True,
              fmu_dir: Optional[Union[str, Path]] = None, progress: bool = False):
    """Run a scene file (or a parsed :class:`dfwb.studies.scene.Scene`): compute what it needs, write its results.

    Parameters
    ----------
    scene : path or Scene
        A scene TOML file (see ``scenes/`` and the README), or ``dfwb.studies.scene.parse_scene(text)``.
    out_dir : path, optional
        Default ``out/scenes/<file stem>`` (required for a Scene object).
    jobs : int, optional, keyword-only
        Local worker processes (default: all cores); 1 computes in this process.
    dask : str, optional, keyword-only
        ``"local"`` or the address of a dask.distributed scheduler.
    cache : bool or path, keyword-only
        True: the user's cache folder; a path; False: no cache.
    fmu_dir : path, optional, keyword-only
        Where the FMUs are.
    progress : bool, keyword-only
        Show a progress display.

    Returns
    -------
    dfwb.studies.runner.Outcome
        Counts (``points``, ``computed``, ``cache_hits``, ``resumed``), ``seconds``, ``out_dir``
        and the figures written. ``out_dir`` holds ``results.csv`` (one flattened DF record per
        row, units in the column names), ``results.json`` (the records) and ``summary.md``.

    Examples
    --------
    >>> import tempfile, dfwb
    >>> from dfwb.studies.scene import parse_scene
    >>> scene = parse_scene('title = "t"\\n[[series]]\\nname = "s"\\nplant = "friction"\\nF = [10]\\nomega = [1, 2]\\n')
    >>> with tempfile.TemporaryDirectory() as out:
    ...     outcome = dfwb.run_scene(scene, out, jobs=1, cache=False)
    >>> outcome.points, outcome.computed
    (2, 2)
    """
    from dfwb.fmi.location import fmu_folder
    from dfwb.studies.runner import run_scene as run
    from dfwb.studies.scene import Scene

    paths = (str, os.PathLike)
    if not isinstance(scene, paths + (Scene,)):
        raise InputError(f"scene = {_short(scene)} is not a scene: give a path to a scene file, or a Scene")
    if out_dir is not None:
        folder("out_dir", out_dir)
    if not isinstance(cache, paths + (bool,)):
        raise InputError(f"cache = {_short(cache)}: give True, False or a folder")
    if not isinstance(cache, bool):
        folder("cache", cache)
    return run(scene, out_dir, jobs, dask, cache, None if fmu_dir is None else fmu_folder(fmu_dir), progress)


def grid(F: Sequence[float], omega: Sequence[float], params: Optional[dict] = None,
         grid_params: Optional[dict] = None) -> list:
    """The points of a sweep, F the outer loop: ``[(F, omega, {name: value})]``.

    ``grid_params`` maps a parameter to the values it takes (every combination is swept).

    Examples
    --------
    >>> import dfwb
    >>> dfwb.grid([10.0], [1.0, 2.0], grid_params={"B": [0.5, 1.0]})
    [(10.0, 1.0, {'B': 0.5}), (10.0, 2.0, {'B': 0.5}), (10.0, 1.0, {'B': 1.0}), (10.0, 2.0, {'B': 1.0})]
    """
    from dfwb.studies.sweep import grid as make

    return make(F, omega, params, grid_params)


def sweep(plant: Any, points: Sequence, out_dir: Union[str, Path], *, jobs: Optional[int] = None,
          drive: str = "internal", samples_per_period: int = SAMPLES_PER_PERIOD,
          fmu_dir: Optional[Union[str, Path]] = None,
          progress: bool = False, resume: bool = True, rtol: Optional[float] = None,
          timeout: Optional[float] = None, cache: Union[bool, str, Path] = True) -> list:
    """A resumable, parallel sweep of DF points into ``out_dir``; returns the record of every point.

    Parameters
    ----------
    plant : str or FMUPlant
        A registered plant, or your own FMU (:func:`fmu_plant`, or the path of an FMU).
    points : list of (F, omega, params)
        Usually from :func:`grid`.
    out_dir : path
        Gets ``results.csv`` (one flattened record per row, appended as points finish),
        ``results.json`` (the records) and ``sweep.json`` (the definition, for resuming).
    jobs : int, optional, keyword-only
        Worker processes (default: all cores); 1 computes in this process.
    drive, samples_per_period, fmu_dir, rtol, timeout : keyword-only
        As for :func:`describing_function`.
    progress : bool, keyword-only
        Show a progress bar.
    resume : bool, keyword-only
        Keep the points ``out_dir`` already holds (False: start afresh).
    cache : bool or path, keyword-only
        As for :func:`run_scene`: True, the user's cache folder; a folder; False, none. A point not in
        ``out_dir`` is taken from the cache if a sweep or a scene computed it before, and a computed
        point is stored there (a scene over the same points then computes none of them).

    Returns
    -------
    dfwb.studies.sweep.Sweep
        The records (:meth:`dfwb.engine.describing.DFResult.as_dict`), a list in the order of ``points``;
        ``.computed``, ``.cached`` and ``.resumed`` count where they came from, and ``.plot()`` draws the
        -1/N curves (``.figure(path)`` writes them to a PNG and an SVG).

    Examples
    --------
    >>> import tempfile, dfwb
    >>> with tempfile.TemporaryDirectory() as out:
    ...     records = dfwb.sweep("friction", dfwb.grid([10.0], [1.0, 2.0]), out, jobs=1, cache=False)
    >>> [(r["F"], r["omega"], round(r["N_re"], 9)) for r in records]
    [(10.0, 1.0, -0.235053392), (10.0, 2.0, -0.082036929)]
    >>> records.computed, records.cached, records.resumed
    (2, 0, 0)
    """
    import itertools

    from dfwb.foreign.plant import resolve_plant, tolerance_parameter
    from dfwb.studies.sweep import MAX_POINTS, run_sweep

    spec = resolve_plant(plant)
    rtol, extra = tolerance_parameter(spec, rtol, {})
    if extra:  # the Stribeck mass's tolerance is its parameter rtol: each point gets it (what is not a point is
        # left for run_sweep to name; one point past the most it takes is enough for it to refuse them)
        try:
            points = list(itertools.islice(points, MAX_POINTS + 1))
        except TypeError:  # not a sequence
            pass
        else:
            given = [p[2] for p in points if isinstance(p, tuple) and len(p) == 3 and isinstance(p[2], dict)]
            if any("rtol" in params for params in given):
                raise InputError("rtol is given both as rtol= and by the points' parameters: give it in one of them")
            points = [(p[0], p[1], dict(p[2], **extra)) if isinstance(p, tuple) and len(p) == 3 and
                      isinstance(p[2], dict) else p for p in points]
    return run_sweep(spec, points, folder("out_dir", out_dir), jobs, drive, samples_per_period,
                     fmu_dir, cache=cache, progress=progress, resume=resume, rtol=rtol, timeout=timeout)
