"""The public functions of dfwb: describing functions, limit cycles, scenes and sweeps.

Every function checks its whole input (plant, parameters, every point)
before anything runs; a problem raises a :class:`dfwb.DfwbError` subclass
with a one-line message. Plant parameters are keyword arguments named as
the plant's FMU names them (``M``, ``Fc``, ``eps``, ...; see
``dfwb.plant(name).defaults()``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional, Sequence, Union

import numpy as np

from dfwb.api.responses import DescribingFunctionResponse, LimitCycleResponse
from dfwb.base.errors import InputError
from dfwb.engine.describing import HARMONICS, DFEngine, check_point
from dfwb.plants import plant as find_plant
from dfwb.studies.sweep import MAX_POINTS

__all__ = ["describing_function", "limit_cycles", "transfer_function", "run_scene", "sweep", "grid"]

ArrayLike = Union[float, Sequence, np.ndarray]


def _leaves(value, limit):
    """The numbers in a nested list/tuple/range, counted without building them (stops past ``limit``)."""
    total, stack = 0, [value]
    while stack and total <= limit:
        item = stack.pop()
        if isinstance(item, np.ndarray):
            total += item.size
        elif isinstance(item, range):
            total += len(item)
        elif isinstance(item, (list, tuple)):
            stack.extend(item)
        else:
            total += 1
    return total


def _reals(name, value):
    """``value`` as a float array: real numbers only (no bool, complex, text or objects), counted before it is built."""
    if _leaves(value, MAX_POINTS) > MAX_POINTS:
        raise InputError(f"{name} has more than {MAX_POINTS} points: at most {MAX_POINTS} in one call "
                         "(split it, or use dfwb.sweep)")
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        array = None
    if array is None or array.dtype.kind not in "iuf":
        raise InputError(f"{name} = {_short(value)} is not a number or an array of numbers "
                         "(real ones: no bool, complex, text or None)")
    if array.size > MAX_POINTS:
        raise InputError(f"{name} has {array.size} points: at most {MAX_POINTS} in one call "
                         "(split it, or use dfwb.sweep)")
    return array.astype(float)


def _short(value):
    text = " ".join(repr(value).split())
    return text if len(text) <= 80 else text[:77] + "..."


def _integer(name, value):
    """An integer option (a Python or numpy integer, not a bool), as int."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} = {_short(value)} is not an integer")
    return int(value)


def _grid(F: ArrayLike, omega: ArrayLike) -> tuple:
    """F and omega as float arrays broadcast against each other; InputError if they are not."""
    arrays = [_reals("F", F), _reals("omega", omega)]
    try:
        F, omega = np.broadcast_arrays(*arrays)
    except ValueError:
        raise InputError(f"F of shape {arrays[0].shape} and omega of shape {arrays[1].shape} "
                         "do not broadcast together") from None
    if F.size > MAX_POINTS:
        raise InputError(f"{F.size} points: at most {MAX_POINTS} in one call (split it, or use dfwb.sweep)")
    return np.array(F), np.array(omega)


def describing_function(plant: str, F: ArrayLike, omega: ArrayLike, *, drive: str = "internal",
                        samples_per_period: int = 64, max_periods: int = 150, harmonics: int = HARMONICS,
                        fmu_dir: Optional[Union[str, Path]] = None, **params: float) -> DescribingFunctionResponse:
    """The describing function N(F, omega) of a plant, at every point of a broadcast grid.

    The plant starts at rest, is driven by ``F cos(omega t)`` and runs to its
    periodic steady state; N = X_1 / F, the first harmonic of its output over
    the force amplitude, exact to the FMU's integration.

    Parameters
    ----------
    plant : str
        A registered plant, e.g. ``"friction"`` (see :func:`dfwb.names`).
    F : float or array_like
        Force amplitude(s) [N].
    omega : float or array_like
        Frequency(ies) [rad/s], broadcast against F (``F[:, None]`` and ``omega`` give a 2-D grid).
    drive : {"internal", "input"}, keyword-only
        ``"internal"``: the FMU's own, exactly integrated excitation; ``"input"``: the sine
        sampled into the input ``f`` at ``samples_per_period`` steps per period.
    samples_per_period : int, keyword-only
        Communication steps per period with ``drive="input"``.
    max_periods : int, keyword-only
        Periods simulated before a response is declared not periodic.
    harmonics : int, keyword-only
        The harmonics X_0 .. X_harmonics recorded (1 to 10).
    fmu_dir : path, optional, keyword-only
        Where the FMUs are (built there if missing); default ``$DFWB_FMU_DIR`` or the user's cache.
    **params : float
        Plant parameters, e.g. ``M=2.0``; checked against the plant's ranges.

    Returns
    -------
    DescribingFunctionResponse
        ``.N`` (complex, shaped like ``np.broadcast(F, omega)``; a complex scalar for scalar
        input), ``.harmonics``, ``.periodic``, ``.points`` (the records) and ``.plot()``.

    Raises
    ------
    dfwb.DfwbError
        An unknown plant or parameter, a value out of range, F and omega that do not broadcast.

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.describing_function("friction", F=10.0, omega=1.0)
    >>> complex(round(response.N.real, 9), round(response.N.imag, 9)), bool(response.periodic)
    ((-0.235053392-0.297987542j), True)
    >>> grid = dfwb.describing_function("friction", F=[[10.0], [20.0]], omega=[0.5, 1.0, 2.0], M=1.0)
    >>> grid.N.shape, grid.harmonics.shape, grid.periodic.all()
    ((2, 3), (2, 3, 11), np.True_)
    >>> grid.points[0]["F"], grid.points[0]["omega"], grid.points[0]["params"]
    (10.0, 0.5, {'M': 1.0})
    """
    spec = find_plant(plant)
    checked = spec.checked(params)
    F_grid, omega_grid = _grid(F, omega)
    for F_value, omega_value in zip(F_grid.flat, omega_grid.flat):  # every point before anything runs
        check_point(float(F_value), float(omega_value))
    options = {name: _integer(name, value) for name, value in
               (("samples_per_period", samples_per_period), ("max_periods", max_periods), ("harmonics", harmonics))}
    engine = DFEngine(spec.name, fmu_dir=fmu_dir, drive=drive, **options)  # checks the options (an empty grid too)
    harmonics = engine.harmonics
    shape = F_grid.shape
    N = np.zeros(shape, dtype=complex)
    amplitudes = np.zeros(shape + (harmonics + 1,))
    periodic = np.zeros(shape, dtype=bool)
    points = []
    if F_grid.size:
        for index in np.ndindex(shape):
            result = engine.point(float(F_grid[index]), float(omega_grid[index]), checked)
            N[index], periodic[index] = result.N, result.periodic
            amplitudes[index] = result.harmonics
            points.append(result.as_dict())
    if shape == ():
        N, periodic = N[()], periodic[()]
    return DescribingFunctionResponse(plant=spec.name, params=checked, F=F_grid, omega=omega_grid, N=N,
                                      harmonics=amplitudes, periodic=periodic, points=points)


def transfer_function(G: Any):
    """A controller G(s) as a python-control TransferFunction, checked (proper, finite, SISO).

    Parameters
    ----------
    G : str, (num, den), control.TransferFunction or control.StateSpace
        An expression in ``s`` (``"20*(s+2)/(s+20)"``), a pair of coefficient lists
        (highest power first), or a python-control system (a StateSpace is converted
        with ``control.ss2tf``).

    Returns
    -------
    control.TransferFunction

    Examples
    --------
    >>> import dfwb
    >>> G = dfwb.transfer_function(([20.0, 40.0], [1.0, 20.0]))
    >>> G.num[0][0].tolist(), G.den[0][0].tolist()
    ([20.0, 40.0], [1.0, 20.0])
    """
    import control as ct

    from dfwb.engine.transfer import MAX_DEGREE, check_transfer_function, from_coefficients, parse_transfer_function

    if isinstance(G, str):
        return parse_transfer_function(G)
    if isinstance(G, (ct.TransferFunction, ct.StateSpace)):
        text = f"the {type(G).__name__} {G.name!r}"  # str(G) is a multi-line table
        if G.ninputs != 1 or G.noutputs != 1:
            raise InputError(f"G(s) = {text} must have one input and one output (it has {G.ninputs} and "
                             f"{G.noutputs})")
        if isinstance(G, ct.StateSpace):
            if G.nstates > MAX_DEGREE:
                raise InputError(f"G(s) = {text} has {G.nstates} states: a degree of at most {MAX_DEGREE} is allowed")
            if not all(np.all(np.isfinite(np.asarray(m, dtype=complex))) for m in (G.A, G.B, G.C, G.D)):
                raise InputError(f"G(s) = {text} has matrix entries that are not finite")
            if not G.isctime():
                raise InputError(f"G(s) = {text} must be a continuous-time system (dt = 0), not dt = {G.dt}")
        return check_transfer_function(G, text)
    if isinstance(G, (tuple, list)) and len(G) == 2:
        try:
            num, den = (_reals(name, part) for name, part in zip(("num", "den"), G))
        except InputError as error:
            raise InputError(f"G = {_short(G)}: num and den must be lists of real numbers ({error})") from None
        if num.ndim > 1 or den.ndim > 1:
            raise InputError(f"G = {_short(G)}: num and den must be flat lists of real numbers")
        if max(num.size, den.size) > MAX_DEGREE + 1:
            raise InputError(f"G = {_short(G)}: a polynomial of degree {max(num.size, den.size) - 1}, "
                             f"at most {MAX_DEGREE} is allowed")
        return from_coefficients(np.atleast_1d(num).tolist(), np.atleast_1d(den).tolist(), names=("num", "den"))
    raise InputError(f"G = {_short(G)} is not a controller: give an expression in s, (num, den), "
                     "or a python-control TransferFunction or StateSpace")


def limit_cycles(plant: str, G: Any, *, F_range: tuple = (1.0, 100.0), omega_range: tuple = (0.1, 100.0),
                 n_F: int = 16, n_omega: int = 48, exact: bool = False, fmu_dir: Optional[Union[str, Path]] = None,
                 progress: bool = False, **params: float) -> LimitCycleResponse:
    """The limit cycles of a plant under negative feedback through a controller G(s).

    Solves the harmonic balance ``1 + G(jw) N(F, w) = 0`` in both unknowns F and w:
    a DF map of ``n_F x n_omega`` points locates the candidates, Newton steps on
    the exact DF refine each, and Loeb's criterion judges its stability
    (:mod:`dfwb.engine.limit_cycles`).

    Parameters
    ----------
    plant : str
        A registered plant, e.g. ``"static-backlash"``.
    G : str, (num, den), control.TransferFunction or control.StateSpace
        The controller from the plant output (position) to its input force,
        force = -G(s) position (see :func:`transfer_function`).
    F_range : (float, float), keyword-only
        Force amplitudes searched [N].
    omega_range : (float, float), keyword-only
        Frequencies searched [rad/s].
    n_F, n_omega : int, keyword-only
        The DF map's size (2 to 1000 each).
    exact : bool, keyword-only
        Also find the true cycles of the exact closed loop (shooting from the
        predictions and from simulations, Floquet stability; :mod:`dfwb.engine.periodic`)
        and link each prediction to its true cycle.
    fmu_dir : path, optional, keyword-only
        Where the FMUs are.
    progress : bool, keyword-only
        Show a progress bar while the map is computed.
    **params : float
        Plant parameters, e.g. ``eps=0.2``.

    Returns
    -------
    LimitCycleResponse
        ``.predictions`` (list of :class:`~dfwb.engine.limit_cycles.Cycle`, sorted by F),
        the DF map (``.F_grid``, ``.omega_grid``, ``.N_grid``) and ``.plot()``; with
        ``exact``, ``.cycles`` (list of :class:`~dfwb.engine.periodic.TrueCycle`) and
        ``.links`` (for each prediction the index of its true cycle, or None).

    Examples
    --------
    >>> import dfwb
    >>> response = dfwb.limit_cycles("static-backlash", "20*(s+2)/(s+20)", F_range=(0.01, 100),
    ...                              omega_range=(0.1, 50))
    >>> [(round(c.F, 6), round(c.omega, 6), c.stable) for c in response.predictions]
    [(0.248573, 0.913732, True)]
    >>> exact = dfwb.limit_cycles("backlash", "200*(s+2)/(s+20)", F_range=(0.01, 100), omega_range=(0.1, 60),
    ...                           n_F=8, n_omega=24, exact=True, eps=0.2)
    >>> [(round(c.omega, 6), round(c.amplitude_x, 7), c.stable) for c in exact.cycles], exact.links
    ([(7.92883, 0.028911, True)], [0])
    """
    from dfwb.engine.limit_cycles import search

    spec = find_plant(plant)
    checked = spec.checked(params)
    controller = transfer_function(G)
    try:
        ranges = [(float(lo), float(hi)) for lo, hi in (F_range, omega_range)]
    except (TypeError, ValueError):
        raise InputError(f"F_range = {F_range!r} and omega_range = {omega_range!r} must be (low, high) pairs "
                         "of numbers") from None
    n_F, n_omega = _integer("n_F", n_F), _integer("n_omega", n_omega)
    if not isinstance(exact, bool):
        raise InputError(f"exact = {exact!r} must be True or False")
    problem = None
    if exact:
        from dfwb.engine.periodic import LoopProblem

        problem = LoopProblem(spec.name, controller, checked, fmu_dir=fmu_dir)
    engine = DFEngine(spec.name, fmu_dir=fmu_dir)
    found = search(spec.name, controller, checked, ranges[0], ranges[1], n_F, n_omega, engine=engine,
                   progress=progress)
    cycles, links = [], []
    if problem is not None:
        from dfwb.engine.periodic import find_cycles

        cycles, links = find_cycles(problem, found.cycles)
    return LimitCycleResponse(plant=spec.name, params=checked, G=controller, predictions=found.cycles,
                              F_grid=found.F_grid, omega_grid=found.omega_grid, N_grid=found.N_grid,
                              cycles=cycles, links=links)


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
    import os

    from dfwb.fmi.location import fmu_folder
    from dfwb.studies.runner import run_scene as run
    from dfwb.studies.scene import Scene

    paths = (str, os.PathLike)
    if not isinstance(scene, paths + (Scene,)):
        raise InputError(f"scene = {_short(scene)} is not a scene: give a path to a scene file, or a Scene")
    if out_dir is not None and not isinstance(out_dir, paths):
        raise InputError(f"out_dir = {_short(out_dir)} is not a folder: give a path")
    if not isinstance(cache, paths + (bool,)):
        raise InputError(f"cache = {_short(cache)}: give True, False or a folder")
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


def sweep(plant: str, points: Sequence, out_dir: Union[str, Path], *, jobs: Optional[int] = None,
          drive: str = "internal", samples_per_period: int = 64, fmu_dir: Optional[Union[str, Path]] = None,
          progress: bool = False, resume: bool = True) -> list:
    """A resumable, parallel sweep of DF points into ``out_dir``; returns the record of every point.

    Parameters
    ----------
    plant : str
        A registered plant.
    points : list of (F, omega, params)
        Usually from :func:`grid`.
    out_dir : path
        Gets ``results.csv`` (one flattened record per row, appended as points finish),
        ``results.json`` (the records) and ``sweep.json`` (the definition, for resuming).
    jobs : int, optional, keyword-only
        Worker processes (default: all cores); 1 computes in this process.
    drive, samples_per_period, fmu_dir : keyword-only
        As for :func:`describing_function`.
    progress : bool, keyword-only
        Show a progress bar.
    resume : bool, keyword-only
        Keep the points ``out_dir`` already holds (False: start afresh).

    Returns
    -------
    list of dict
        The records (:meth:`dfwb.engine.describing.DFResult.as_dict`), in the order of ``points``.

    Examples
    --------
    >>> import tempfile, dfwb
    >>> with tempfile.TemporaryDirectory() as out:
    ...     records = dfwb.sweep("friction", dfwb.grid([10.0], [1.0, 2.0]), out, jobs=1)
    >>> [(r["F"], r["omega"], round(r["N_re"], 9)) for r in records]
    [(10.0, 1.0, -0.235053392), (10.0, 2.0, -0.082036929)]
    """
    from dfwb.studies.sweep import run_sweep

    return run_sweep(plant, points, out_dir, jobs, drive, samples_per_period, fmu_dir, progress=progress,
                     resume=resume)
