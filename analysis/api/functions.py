"""The public functions of dfwb's analyses: describing functions, limit cycles, continuation, maps, margins.

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

from dfwb.api.studies import folder as _folder
from dfwb.base.defaults import (
    BRANCH_POINTS,
    DF_MAP_SIZE,
    DF_PERIODS,
    HARMONICS,
    JUDGE_SAMPLES,
    K_COUNT,
    K_RANGE,
    SAMPLES_PER_PERIOD,
)
from dfwb.base.errors import InputError, fmu_only
from dfwb.base.values import flags, reals
from dfwb.base.values import integer as _integer
from dfwb.engine.describing import check_point
from dfwb.foreign.engine import engine_for
from dfwb.foreign.plant import resolve_plant, tolerance_parameter
from dfwb.studies.responses import (
    ContinuationResponse,
    DescribingFunctionResponse,
    HuntingMapResponse,
    LimitCycleResponse,
    MarginResponse,
    TuneResponse,
)
from dfwb.studies.sweep import MAX_POINTS

__all__ = ["describing_function", "limit_cycles", "continuation", "hunting_map", "limit_cycle_margin", "tune",
           "transfer_function"]

ArrayLike = Union[float, Sequence, np.ndarray]


ADVICE = " in one call (split it, or use dfwb.sweep)"


def _reals(name, value):
    """``value`` as a float array of at most MAX_POINTS real numbers."""
    return reals(name, value, MAX_POINTS, ADVICE)


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


def describing_function(plant: Any, F: ArrayLike, omega: ArrayLike, *, drive: str = "internal",
                        samples_per_period: int = SAMPLES_PER_PERIOD, max_periods: int = DF_PERIODS,
                        harmonics: int = HARMONICS,
                        fmu_dir: Optional[Union[str, Path]] = None, rtol: Optional[float] = None,
                        timeout: Optional[float] = None, **params: float) -> DescribingFunctionResponse:
    """The describing function N(F, omega) of a plant, at every point of a broadcast grid.

    The plant starts at rest, is driven by ``F cos(omega t)`` and runs to its
    periodic steady state; N = X_1 / F, the first harmonic of its output over
    the force amplitude, exact to the FMU's integration.

    Parameters
    ----------
    plant : str or FMUPlant
        A registered plant, e.g. ``"friction"`` (see :func:`dfwb.names`), or your own
        FMU: :func:`dfwb.fmu_plant` (``fmu_plant("drive.fmu", input="tau", output="phi")``)
        or the path of an FMU with one Real input and one Real output.
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
    rtol : float, optional, keyword-only
        Your FMU only: the accuracy aimed at (model exchange: the integrator's tolerance,
        default 1e-10; co-simulation: the extrapolated DF's, default 1e-6).
    timeout : float, optional, keyword-only
        Your FMU only: seconds one point may take; a point cut is tried once more with twice the
        limit, then skipped (default: 120 s per 150 periods allowed, and at least 10 times the
        slowest point so far).
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
    spec = resolve_plant(plant)
    rtol, params = tolerance_parameter(spec, rtol, params)
    checked = spec.checked(params)
    F_grid, omega_grid = _grid(F, omega)
    for F_value, omega_value in zip(F_grid.flat, omega_grid.flat):  # every point before anything runs
        check_point(float(F_value), float(omega_value))
    options = {name: _integer(name, value) for name, value in
               (("samples_per_period", samples_per_period), ("max_periods", max_periods), ("harmonics", harmonics))}
    engine = engine_for(spec, fmu_dir=fmu_dir, drive=drive, rtol=rtol, timeout=timeout, **options)
    harmonics = engine.harmonics
    shape = F_grid.shape
    N = np.zeros(shape, dtype=complex)
    errors = np.full(shape, np.nan)
    amplitudes = np.zeros(shape + (harmonics + 1,))
    periodic = np.zeros(shape, dtype=bool)
    points = []
    if F_grid.size:
        indices = list(np.ndindex(shape))
        wanted = [(float(F_grid[index]), float(omega_grid[index]), checked) for index in indices]
        many = getattr(engine, "batch", None)  # a user's FMU: its points on several worker processes at once
        results = many(wanted) if many is not None else (engine.point(*point) for point in wanted)
        for index, result in zip(indices, results):
            N[index], periodic[index] = result.N, result.periodic
            errors[index] = np.nan if result.N_error is None else result.N_error
            amplitudes[index] = result.harmonics
            points.append(result.as_dict())
    if shape == ():
        N, periodic, errors = N[()], periodic[()], errors[()]
    return DescribingFunctionResponse(plant=spec.name, params=checked, F=F_grid, omega=omega_grid, N=N,
                                      harmonics=amplitudes, periodic=periodic, points=points, N_error=errors)


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
    from dfwb.engine.transfer import to_transfer_function

    return to_transfer_function(G)


def limit_cycles(plant: str, G: Any, *, F_range: Optional[tuple] = None, omega_range: Optional[tuple] = None,
                 n_F: Optional[int] = None, n_omega: Optional[int] = None, exact: bool = False, verify: bool = False,
                 samples_per_period: int = JUDGE_SAMPLES, amplitudes: Optional[Sequence[float]] = None,
                 fmu_dir: Optional[Union[str, Path]] = None, progress: bool = False,
                 rtol: Optional[float] = None, timeout: Optional[float] = None,
                 compensate: Union[None, str, Sequence[str]] = None, **params: float) -> LimitCycleResponse:
    """The limit cycles of a plant under negative feedback through a controller G(s).

    Solves the harmonic balance ``1 + G(jw) N(F, w) = 0`` in both unknowns F and w:
    a DF map of ``n_F x n_omega`` points locates the candidates, Newton steps on
    the exact DF refine each, and Loeb's criterion judges its stability
    (:mod:`dfwb.engine.limit_cycles`). The ranges are derived from the plant and
    G unless given (:mod:`dfwb.engine.scales`): from the force that moves the
    plant to what the linear loop allows, frequencies around its crossover.

    Parameters
    ----------
    plant : str
        A registered plant, e.g. ``"static-backlash"``.
    G : str, callable, (num, den), control.TransferFunction or control.StateSpace
        The controller from the plant output (position) to its input force,
        force = -G(s) position (see :func:`transfer_function`). An expression may
        name parameters (``"Kp + Ki/s"``) whose values come with ``params``; a
        function of named parameters may build a python-control system.
    F_range : (float, float), optional, keyword-only
        Force amplitudes searched [N] (default: derived).
    omega_range : (float, float), optional, keyword-only
        Frequencies searched [rad/s] (default: derived).
    n_F, n_omega : int, keyword-only
        The DF map's size (2 to 1000 each; default 16 x 48, and 4 x 12 for the dither's DF, whose points cost
        0.01 to 2 s each).
    exact : bool, keyword-only
        Also find the true cycles of the exact closed loop (a systematic search of
        starts and section hits, Floquet stability; :mod:`dfwb.engine.cycles`), link
        each prediction to its true cycle and say what the search covered. For your own
        FMU: model exchange is integrated and shot (Floquet stability); co-simulation is
        co-simulated with G solved exactly, refined and extrapolated, each cycle with its
        estimated ``errors`` (stable cycles only).
    verify : bool, keyword-only
        Also judge each prediction by closed-loop co-simulation of the FMUs.
    samples_per_period : int, keyword-only
        The judge's steps per predicted period.
    amplitudes : list of float, optional, keyword-only
        The exact search's start amplitudes of the output (default: derived).
    fmu_dir : path, optional, keyword-only
        Where the FMUs are.
    progress : bool, keyword-only
        Show progress while the map and the search run.
    rtol, timeout : float, optional, keyword-only
        Your FMU only: as for :func:`describing_function` (the map runs 1000 times looser).
    compensate : str or list of str, optional, keyword-only
        Compensators between the controller and the plant: ``"coulomb"`` (Coulomb friction feedforward,
        parameters ``F_hat`` [N] and ``signal``, ``"velocity"`` or ``"control"``), ``"deadband"`` (the
        integrator holds while ``|y| < d``), ``"reset"`` (the integrator cleared when the mass comes
        to rest), ``"dither"`` (``a sin(w_d t)`` added to the force, ``a`` [N], ``w_d`` [rad/s]: a
        forced loop, :mod:`dfwb.engine.dither`) and ``"backlash-inverse"`` (the controller sees
        ``y + k h_hat/2 s``, s the side of the play's last touch, ``h_hat`` [m]; plants with a play); their
        parameters come with ``params`` like G's (:mod:`dfwb.engine.compensators`).
        A compensated loop is judged by its truth, with its cost (:mod:`dfwb.engine.cost`): ``exact`` is
        required; its DF is computed where the compensated plant is a plant (the feedforward of the velocity
        on the friction mass, ``F_hat <= Fc``: the mass with ``Fc - F_hat``) or has a DF of its own (the
        backlash inverse on the static backlash, in closed form; a dither alone on the friction mass, the
        dual-input DF averaged over the dither's phase, :mod:`dfwb.engine.dither_df`).
    **params : float
        Plant parameters (``eps=0.2``), G's (``Kp=10``) and the compensators' (``F_hat=3``).

    Returns
    -------
    LimitCycleResponse
        ``.predictions`` (list of :class:`~dfwb.engine.limit_cycles.Cycle`, sorted by F),
        the DF map (``.F_grid``, ``.omega_grid``, ``.N_grid``), ``.plot()`` and ``.summary()``;
        with ``exact``, ``.cycles`` (list of :class:`~dfwb.engine.periodic.TrueCycle`),
        ``.links`` (for each prediction the index of its true cycle, or None) and ``.coverage``.

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
    >>> hunting = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, Kp=10, Ki=2)
    >>> hunting.predictions, [(round(c.period, 4), round(c.amplitude_x, 5)) for c in hunting.cycles]
    ([], [(57.2628, 0.23665)])

    An integrator deadband of 0.2 m stops that hunting, at a price: the mass stops short of its target.

    >>> quiet = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, compensate="deadband", Kp=10, Ki=2, d=0.2)
    >>> quiet.cycles, round(quiet.cost.standing_error, 4)
    ([], 0.1415)
    """
    from dfwb.foreign.engine import engine_for
    from dfwb.studies.limit_cycles import analyse

    n_F, n_omega = (None if n is None else _integer(name, n) for name, n in (("n_F", n_F), ("n_omega", n_omega)))
    samples_per_period = _integer("samples_per_period", samples_per_period)
    flags(exact=exact, verify=verify, progress=progress)
    spec = resolve_plant(plant)
    rtol, params = tolerance_parameter(spec, rtol, params)
    engine = engine_for(spec, rtol=rtol, timeout=timeout) if getattr(spec, "foreign", False) else None
    if engine is None:
        fmu_only({"rtol": (rtol, None), "timeout": (timeout, None)}, "dfwb's own plants are computed exactly")
    with _reporter(f"limit cycles of {spec.name}", progress) as report:
        return analyse(spec, G, params, F_range=F_range, omega_range=omega_range, n_F=n_F, n_omega=n_omega,
                       exact=exact, verify=verify, samples_per_period=samples_per_period, amplitudes=amplitudes,
                       fmu_dir=fmu_dir, engine=engine, progress=report if progress else None, compensate=compensate)


def continuation(plant: Any, G: Any, parameter: str, start: float, stop: float, *,
                 sources: Union[str, Sequence[str]] = ("truth", "df"), max_points: int = BRANCH_POINTS,
                 starts: Optional[Sequence[float]] = None, fmu_dir: Optional[Union[str, Path]] = None,
                 progress: bool = False, F_range: Optional[tuple] = None, omega_range: Optional[tuple] = None,
                 n_F: int = DF_MAP_SIZE[0], n_omega: int = DF_MAP_SIZE[1], rtol: Optional[float] = None,
                 timeout: Optional[float] = None,
                 samples: int = 11, compensate: Union[None, str, Sequence[str]] = None,
                 **params: float) -> ContinuationResponse:
    """Limit cycles followed in one parameter, with their bifurcations: which values make the loop hunt.

    The true cycles the systematic search finds at the range's ends (and at ``starts``), and the DF's
    predictions there, are each followed by pseudo-arclength continuation through the range, past folds;
    bifurcations are detected and located to 1e-7 of the range: folds, period doublings and tori from the
    Floquet multipliers, and the nonsmooth ones from the cycle's events (a stick phase or an impact appearing
    or vanishing; two branches meeting where the stick phase shrinks to nothing, a nonsmooth fold), and
    branches going to infinity at the linear loop's stability boundary (:mod:`dfwb.engine.continuation`).

    Your own model-exchange FMU has its DF's predictions followed, found on its DF map at the start values,
    and its true cycles searched at ``samples`` values and joined into branches, where they begin, end or
    change their stability bracketed by the samples (:mod:`dfwb.foreign.continuation`).

    Parameters
    ----------
    plant : str or FMUPlant
        A plant with an exact loop: ``friction``, ``backlash``, ``static-backlash``; or your own FMU
        (:func:`dfwb.fmu_plant`, or the path of an .fmu).
    G : str, callable, (num, den) or python-control system
        The controller; an expression may name parameters (``"Kp + Ki/s"``).
    parameter : str
        The parameter followed: one of G's or of the plant's (``"Ki"``, ``"Fs"``, ``"eps"``).
    start, stop : float
        Its range.
    sources : "truth", "df" or both, keyword-only
        Follow the true cycles, the DF's predictions, or both.
    max_points : int, keyword-only
        Points per branch, at most (2 to 10000).
    starts : list of float, optional, keyword-only
        Parameter values where branches are searched for (default: start and stop).
    fmu_dir : path, optional, keyword-only
        Where the FMUs are.
    progress : bool, keyword-only
        Show progress.
    F_range, omega_range, n_F, n_omega, rtol, timeout : keyword-only
        Your FMU only: as for :func:`limit_cycle_margin` (the ranges are required).
    samples : int, keyword-only
        Your FMU only: the values where its true cycles are searched (2 to 1000).
    compensate : str or list of str, optional, keyword-only
        Compensators between the controller and the plant: ``"coulomb"`` (Coulomb friction feedforward,
        parameters ``F_hat`` [N] and ``signal``, ``"velocity"`` or ``"control"``), ``"deadband"`` (the
        integrator holds while ``|y| < d``), ``"reset"`` (the integrator cleared when the mass comes
        to rest), ``"dither"`` (``a sin(w_d t)`` added to the force, ``a`` [N], ``w_d`` [rad/s]: a
        forced loop, :mod:`dfwb.engine.dither`) and ``"backlash-inverse"`` (the controller sees
        ``y + k h_hat/2 s``, s the side of the play's last touch, ``h_hat`` [m]; plants with a play); their
        parameters come with ``params`` like G's (:mod:`dfwb.engine.compensators`).
        A compensated loop is judged by its truth, with its cost (:mod:`dfwb.engine.cost`), and its DF is
        followed where the compensated plant is a plant (the feedforward of the velocity on the friction mass,
        ``F_hat <= Fc``); the parameter followed may be a compensator's.
    **params : float
        The other parameters of G and of the plant.

    Returns
    -------
    ContinuationResponse
        ``.branches``, ``.bifurcations``, ``.plot()`` (the bifurcation diagram), ``.summary()``, ``.as_dict()``.

    Examples
    --------
    >>> import dfwb
    >>> r = dfwb.continuation("friction", "Kp + Ki/s", "Ki", 1, 30, Kp=10, sources="truth")
    >>> [(b.kind, round(b.parameter, 4)) for b in r.bifurcations]
    [('infinity', 5.0), ('nonsmooth-fold', 24.773)]
    """
    from dfwb.studies.continuation import follow

    flags(progress=progress)
    spec = resolve_plant(plant)
    rtol, params = tolerance_parameter(spec, rtol, params)
    with _reporter(f"continuation of {spec.name} in {parameter}", progress) as report:
        return follow(spec, G, parameter, start, stop, params, sources=sources, max_points=max_points,
                      starts=starts, fmu_dir=fmu_dir, progress=report if progress else None, F_range=F_range,
                      omega_range=omega_range, n_F=_integer("n_F", n_F), n_omega=_integer("n_omega", n_omega),
                      rtol=rtol, timeout=timeout, samples=_integer("samples", samples), compensate=compensate)


def hunting_map(plant: Any, G: Any, x: tuple, y: tuple, *, out_dir: Optional[Union[str, Path]] = None,
                jobs: Optional[int] = None, dask: Optional[str] = None, cache: Union[bool, str, Path] = False,
                amplitudes: Optional[int] = None, curves: bool = True, resume: bool = True,
                fmu_dir: Optional[Union[str, Path]] = None, progress: bool = False,
                F_range: Optional[tuple] = None, omega_range: Optional[tuple] = None, n_F: int = DF_MAP_SIZE[0],
                n_omega: int = DF_MAP_SIZE[1], rtol: Optional[float] = None, timeout: Optional[float] = None,
                compensate: Union[None, str, Sequence[str]] = None, **params: float) -> HuntingMapResponse:
    """Which settings of two parameters make the machine hunt: a map, by the truth and by the DF.

    Each cell of the grid ``x`` by ``y`` is classified by the exact loop's systematic search (hunts with a
    stable cycle, its amplitude and period; only unstable cycles; diverges; no cycle in the range searched)
    and by the describing function (a stable prediction, only unstable ones, none), side by side, with the
    linear loop's stability boundary and the bifurcation curves continued across the map
    (:mod:`dfwb.engine.hunting`, :mod:`dfwb.studies.hunting`).

    With your own FMU the axes are G's parameters: each cell's truth is its loop's search
    (:mod:`dfwb.foreign.hunting`), its DF verdict comes from one map of the FMU's DF, computed here
    with the FMU's own workers; there is no linear loop nor bifurcation curve to draw.

    Parameters
    ----------
    plant : str or FMUPlant
        A plant with an exact loop, or your own FMU (:func:`dfwb.fmu_plant`, or the path of an .fmu).
    G : str, callable, (num, den) or python-control system
        The controller; an expression may name parameters (``"Kp + Ki/s"``).
    x, y : (str, float, float, int)
        Each axis: a parameter of G or of the plant, its first and last value and the number of cells
        (2 to 1000; at most 10000 cells in all).
    out_dir : path, optional, keyword-only
        A folder for ``cells.csv`` (appended as cells finish: a killed map resumes), ``cells.json``,
        ``map.json`` and ``hunting_map.png``.
    jobs : int, optional, keyword-only
        Worker processes (default: all cores, once the work shows it is worth it); 1: this process.
    dask : str, optional, keyword-only
        ``"local"`` or a dask.distributed scheduler's address.
    cache : bool or path, keyword-only
        Keep cells in the user's cache (True) or a folder; False: no cache.
    amplitudes : int, optional, keyword-only
        Start amplitudes per cell (default 5: one per decade of the loop's span).
    curves : bool, keyword-only
        Continue the bifurcations across the map.
    resume : bool, keyword-only
        Keep the cells ``out_dir`` already holds.
    fmu_dir : path, optional, keyword-only
    progress : bool, keyword-only
    F_range, omega_range, n_F, n_omega, rtol, timeout : keyword-only
        Your FMU only: as for :func:`limit_cycle_margin` (the ranges are required).
    compensate : str or list of str, optional, keyword-only
        Compensators between the controller and the plant: ``"coulomb"`` (Coulomb friction feedforward,
        parameters ``F_hat`` [N] and ``signal``, ``"velocity"`` or ``"control"``), ``"deadband"`` (the
        integrator holds while ``|y| < d``), ``"reset"`` (the integrator cleared when the mass comes
        to rest), ``"dither"`` (``a sin(w_d t)`` added to the force, ``a`` [N], ``w_d`` [rad/s]: a
        forced loop, :mod:`dfwb.engine.dither`) and ``"backlash-inverse"`` (the controller sees
        ``y + k h_hat/2 s``, s the side of the play's last touch, ``h_hat`` [m]; plants with a play); their
        parameters come with ``params`` like G's (:mod:`dfwb.engine.compensators`).
        A compensated loop is judged by its truth, with its cost (:mod:`dfwb.engine.cost`) in every cell and
        its DF where the compensated plant is a plant (the feedforward of the velocity on the friction mass,
        ``F_hat <= Fc``) or has a closed-form DF (the static backlash's inverse); a dither's DF is not mapped
        (``limit_cycles`` shows it); an axis may be a compensator's parameter.
    **params : float
        The other parameters of G and of the plant.

    Returns
    -------
    HuntingMapResponse
        ``.cells``, ``.classes(source)``, ``.linear``, ``.curves``, ``.plot()``, ``.summary()``, ``.as_dict()``.

    Examples
    --------
    >>> import dfwb
    >>> m = dfwb.hunting_map("friction", "Kp + Ki/s", ("Kp", 5, 20, 2), ("Ki", 1, 4, 2), jobs=1, curves=False)
    >>> m.classes("truth").tolist()
    [['stable', 'stable'], ['stable', 'stable']]
    """
    from dfwb.studies.hunting import run_map

    flags(curves=curves, resume=resume, progress=progress)
    if out_dir is not None:
        _folder("out_dir", out_dir)
    spec = resolve_plant(plant)
    rtol, params = tolerance_parameter(spec, rtol, params)
    with _reporter(f"hunting map of {spec.name}", progress) as report:
        return run_map(spec, G, x, y, params, out_dir=out_dir, jobs=jobs, dask=dask, cache=cache, fmu_dir=fmu_dir,
                       amplitudes=amplitudes, curves=curves, resume=resume, progress=report if progress else None,
                       F_range=F_range, omega_range=omega_range, n_F=_integer("n_F", n_F),
                       n_omega=_integer("n_omega", n_omega), rtol=rtol, timeout=timeout, compensate=compensate)


def limit_cycle_margin(plant: Any, G: Any, *, k_range: tuple = K_RANGE, count: int = K_COUNT, df: bool = True,
                       fmu_dir: Optional[Union[str, Path]] = None, progress: bool = False,
                       F_range: Optional[tuple] = None, omega_range: Optional[tuple] = None,
                       n_F: int = DF_MAP_SIZE[0], n_omega: int = DF_MAP_SIZE[1], rtol: Optional[float] = None,
                       timeout: Optional[float] = None, compensate: Union[None, str, Sequence[str]] = None,
                       **params: float) -> MarginResponse:
    """The limit-cycle margin of a controller: the gain factors k for which k G makes the machine hunt.

    "How much more gain can I use before it hunts?": ``count`` gain factors log-spaced over ``k_range`` are
    classified by the truth (the exact loop's search: a stable cycle) and by the DF (a stable prediction);
    each boundary between hunting and not is located, the truth's by continuing the stable cycle to the
    bifurcation that ends it (a fold, a nonsmooth fold, a loss of stability, infinity at the linear loop's
    stability boundary), the DF's by bisection (:mod:`dfwb.engine.margin`).

    With your own FMU the truth is its loop's search at each k (:mod:`dfwb.foreign.hunting`), the DF's
    verdict comes from one map of its DF over ``F_range`` x ``omega_range``, and every boundary is
    bisected.

    Parameters
    ----------
    plant : str or FMUPlant
        A registered plant, or your own FMU (:func:`dfwb.fmu_plant`, or the path of an .fmu).
    G : str, callable, (num, den) or python-control system
        The controller at k = 1; an expression's parameters come with ``params``.
    k_range : (float, float), keyword-only
        Gain factors searched: 1e-6 <= low < 1 < high <= 1e6.
    count : int, keyword-only
        Gain factors scanned (3 to 1000).
    df : bool, keyword-only
        Also the DF's margin.
    fmu_dir : path, optional, keyword-only
    progress : bool, keyword-only
    F_range, omega_range : (float, float), keyword-only
        Your FMU only (required): the forces [N] and frequencies [rad/s] of its DF map.
    n_F, n_omega : int, keyword-only
        Your FMU only: the DF map's size (as for :func:`limit_cycles`).
    rtol, timeout : float, optional, keyword-only
        Your FMU only: as for :func:`describing_function`.
    compensate : str or list of str, optional, keyword-only
        Compensators between the controller and the plant (as for :func:`limit_cycles`): the truth's margin
        alone then.
    **params : float
        G's, the plant's and the compensators' parameters.

    Returns
    -------
    MarginResponse
        ``.truth`` and ``.df`` (each with ``intervals``, ``boundaries``, ``hunts_at(k)``, ``room()``),
        ``.summary()``, ``.plot()``, ``.as_dict()``.

    Examples
    --------
    >>> import dfwb
    >>> m = dfwb.limit_cycle_margin("friction", "20 + 100/s + 2*s/(0.1*s+1)", count=9, df=False)
    >>> m.truth.hunts_at(1.0), [(round(b.k, 5), b.kind) for b in m.truth.boundaries]
    (True, [(0.83005, 'nonsmooth-fold')])
    """
    from dfwb.studies.margin import gain_margin

    flags(df=df, progress=progress)
    spec = resolve_plant(plant)
    rtol, params = tolerance_parameter(spec, rtol, params)
    with _reporter(f"limit-cycle margin of {spec.name}", progress) as report:
        return gain_margin(spec, G, params, k_range=k_range, count=_integer("count", count), df=df,
                           fmu_dir=fmu_dir, progress=report if progress else None, F_range=F_range,
                           omega_range=omega_range, n_F=_integer("n_F", n_F), n_omega=_integer("n_omega", n_omega),
                           rtol=rtol, timeout=timeout, compensate=compensate)


def tune(plant: Any, G: Any, *, free: dict, compensate: Union[None, str, Sequence[str]] = None,
         tolerance: Optional[float] = None, robust: Optional[dict] = None, count: int = 5,
         fmu_dir: Optional[Union[str, Path]] = None, progress: bool = False, **params: Any) -> TuneResponse:
    """The fastest controller of a family, with its compensators, that does not hunt.

    Over a grid of the free parameters' ranges, the setting whose linear loop has the highest crossover
    frequency such that the exact loop has no stable cycle and its step response rests within ``tolerance``
    of the target, at the nominal plant and at every corner of the box ``robust``; then confirmed by the
    independent reference at every corner (:mod:`dfwb.engine.tune`, where the search is described).

    Parameters
    ----------
    plant : str
        A registered plant with an exact loop.
    G : str, callable, (num, den) or python-control system
        The controller family: an expression whose parameters are free or given with ``params``.
    free : dict, keyword-only
        ``{name: (lo, hi)}``: the parameters searched, G's and the compensators' (``{"Kp": (2, 50), "d": (0,
        0.5)}``); log-spaced where the range is positive.
    compensate : str or list of str, optional, keyword-only
        The compensators (as for :func:`limit_cycles`).
    tolerance : float, optional, keyword-only
        The largest standing error allowed [the output's unit] (default: none required).
    robust : dict, optional, keyword-only
        ``{name: relative error}`` of the plant's parameters (``{"Fc": 0.2}``: +-20 %): the corners checked.
    count : int, keyword-only
        Values per free parameter (2 to 50).
    fmu_dir : path, optional, keyword-only
    progress : bool, keyword-only
    **params
        The other parameters of G, the plant and the compensators (``signal="control"``).

    Returns
    -------
    TuneResponse
        ``.settings``, ``.crossover``, ``.cost``, ``.confirmed``, ``.candidates``, ``.plot()``, ``.summary()``.

    Examples
    --------
    >>> import dfwb
    >>> r = dfwb.tune("friction", "Kp + Ki/s", compensate="deadband", free={"Kp": (2, 50), "Ki": (0.2, 10),
    ...               "d": (0.01, 0.5)}, tolerance=0.1, count=3)
    >>> {k: round(v, 4) for k, v in r.settings.items()}, r.confirmed
    ({'Kp': 50.0, 'Ki': 10.0, 'd': 0.0707}, True)
    """
    from dfwb.studies.tune import tune_study

    flags(progress=progress)
    count = _integer("count", count)
    spec = resolve_plant(plant)
    with _reporter(f"tuning {spec.name}", progress) as report:
        return tune_study(spec, G, params, free=free, compensate=compensate, tolerance=tolerance, robust=robust,
                          count=count, fmu_dir=fmu_dir, progress=report if progress else None)


def _reporter(title, enabled):
    """A progress(stage, done, total) shown as a rich display (nothing when not ``enabled``)."""
    from dfwb.studies.progress import Reporter

    return Reporter(title, enabled)
