"""A continuation study, the one way dfwb does it (the API, ``dfwb continue`` and scenes call :func:`follow`).

For a parameter of the controller or of the plant over a range: the true
cycles found by the systematic search (:func:`dfwb.engine.cycles.find_cycles`)
at the range's ends, and the DF's predictions there (on ranges derived from
the plant and G), each followed by pseudo-arclength through the range with
its bifurcations located (:mod:`dfwb.engine.continuation`). A cycle or
prediction that lies on a branch already followed is not followed again.
"""

import math

from dfwb.base.defaults import BRANCH_POINTS, DF_MAP_SIZE
from dfwb.base.errors import DfwbError, InputError
from dfwb.engine.continuation import continue_cycles, continue_predictions
from dfwb.engine.family import LoopFamily, number
from dfwb.foreign.hunting import no_fmu_options
from dfwb.foreign.plant import fmu_plant, is_fmu_path
from dfwb.studies.responses import ContinuationResponse

SOURCES = ("truth", "df")
MAX_STARTS = 16  # parameter values searched for starts, at most
SAMPLES = 11  # values where a user's FMU's true cycles are searched


def check_parameter(family, name, start, stop, plant=True):
    """(name, (lo, hi)) of a continuation or map axis, refused in one line before anything runs.

    ``plant``: check a plant parameter's ends against the plant's ranges (with the other values given;
    a map of two plant parameters checks its corners instead)."""
    if not isinstance(name, str):
        raise InputError(f"parameter = {name!r:.60}: give its name (a parameter of G or of the plant)")
    family.check_name(name)
    values = [number(f"{name} {label}", value, "the range's ends must be finite numbers")
              for label, value in (("start", start), ("stop", stop))]
    if values[0] == values[1] or not math.isfinite(values[1] - values[0]):
        raise InputError(f"{name} = {values[0]:g}:{values[1]:g}: the range is empty or wider than the floats "
                         "(give START:STOP with START != STOP, STOP - START finite)")
    if plant and name in family.plant_names:
        check = family.params  # the plant's own range, at both ends (checked all along anyway)
    elif family.compensation.numeric(name):
        check = family.check_compensator  # a compensator's own range, which each end must fit
    else:
        return name, (min(values), max(values))
    for value in values:
        try:
            check({name: value})
        except DfwbError as error:
            raise InputError(f"{name} = {values[0]:g}:{values[1]:g}: {error}") from None
    return name, (min(values), max(values))


def check_somewhere(family, settings, where):
    """Refuse a study whose loop is refused at every one of ``settings`` ({name: value} each: where it starts,
    a map's corners) before anything runs or is written: G checked as ``dfwb limit-cycle`` checks it
    (:meth:`LoopFamily.check`), the plant's values as the plant checks them. Where only some are refused
    (``Kp/Ki`` at Ki = 0), the study reports them where it meets them."""
    labels, first = [], None
    for setting in settings:
        try:
            family.params(setting)
            family.check(setting)
            return
        except DfwbError as error:
            first = first or " ".join(str(error).split())
            labels.append(", ".join(f"{name} = {value:g}" for name, value in setting.items()))
    raise InputError(f"{first}, at {where} ({'; '.join(labels)}): the loop must be defined at one at least")


def follow(plant, G, parameter, start, stop, values=None, *, sources=SOURCES, max_points=BRANCH_POINTS, starts=None,
           fmu_dir=None, progress=None, F_range=None, omega_range=None, n_F=DF_MAP_SIZE[0], n_omega=DF_MAP_SIZE[1],
           rtol=None, timeout=None, samples=SAMPLES, compensate=None):
    """The branches of true cycles and of DF predictions over ``parameter`` in [start, stop], with bifurcations.

    ``values``: G's and the plant's other parameters; ``starts``: parameter values where cycles and
    predictions are searched to start branches from (default: the range's two ends); ``progress``:
    ``progress(stage, done, total)``. Returns a :class:`~dfwb.studies.responses.ContinuationResponse`.
    A user's model-exchange FMU (an FMUPlant or an .fmu path) has its DF predictions followed, found on
    its DF map over ``F_range`` x ``omega_range`` (``n_F`` x ``n_omega``) at the start values, and its
    true cycles searched at ``samples`` values of the range and joined into branches
    (:mod:`dfwb.foreign.continuation`: their changes bracketed by the samples). ``compensate``: compensators
    in the loop (:mod:`dfwb.engine.compensators`), whose parameters may be the one followed; a compensated
    loop's true cycles are followed, and its DF where the compensated plant is a plant (said in the notes
    where not).
    """
    from dfwb.engine.cycles import find_cycles
    from dfwb.engine.describing import F_RANGE, DFEngine
    from dfwb.engine.limit_cycles import search
    from dfwb.engine.scales import search_ranges

    if is_fmu_path(plant):
        plant = fmu_plant(plant)
    if parameter in (values or {}):
        raise InputError(f"{parameter} is the parameter followed: give its range, not a value for it")
    family = LoopFamily(plant, G, values, free=(parameter,) if isinstance(parameter, str) else (),
                        compensate=compensate)
    if "dither" in family.compensation.kinds:
        raise InputError("compensate: a dithered loop is forced, its responses fixed points of its stroboscopic map "
                         "(dfwb.engine.dither), which continuation does not follow: map it (dfwb map) or search it "
                         "(dfwb limit-cycle --exact)")
    name, bounds = check_parameter(family, parameter, start, stop)
    sources = _sources(sources)
    at = [float(start), float(stop)] if starts is None else _starts(starts, bounds)
    notes = []
    if family.compensation and "df" in sources and all(_df_params(family, {name: value}) is None for value in at):
        sources = tuple(source for source in sources if source != "df")
        notes.append("the DF of this compensated loop is not computed (its compensated plant is no plant): its true "
                     "cycles alone are followed")
        if not sources:
            raise InputError("compensate: this compensated loop is followed by its truth (sources = 'truth'): its "
                             "compensated plant is no plant, whose DF could be computed")
    if isinstance(max_points, bool) or not isinstance(max_points, int) or not 2 <= max_points <= 10_000:
        raise InputError(f"max_points = {max_points!r}: an integer from 2 to 10000 (points per branch)")
    check_somewhere(family, [{name: value} for value in at],
                    "both ends of the range" if starts is None else "every start value")
    searches, cycle_starts, prediction_starts, ranges = [], [], [], []
    foreign = getattr(family.spec, "foreign", False)
    if foreign:
        engine, fixed = _foreign_engine(family.spec, F_range, omega_range, n_F, n_omega, rtol, timeout)
        if isinstance(samples, bool) or not isinstance(samples, int) or not 2 <= samples <= 1000:
            raise InputError(f"samples = {samples!r}: the values where a user's FMU's cycles are searched, 2 to "
                             "1000")
    else:
        no_fmu_options(F_range, omega_range, (n_F, n_omega), rtol, timeout, samples=(samples, SAMPLES),
                       own="dfwb's own plants derive their ranges, are computed exactly and continued")
        # the plant's engine, or the compensated plant's own (a closed form: dfwb.engine.inverse_df)
        engine = family.df_engine(DFEngine(family.spec.name, fmu_dir=fmu_dir)) if "df" in sources else None
    if foreign and "df" in sources:
        from dfwb.foreign.hunting import predictor

        predict = predictor(engine, *fixed[:2], fixed[2:])  # one DF map for the values that share it
    for k, value in enumerate(at):
        if foreign and "df" not in sources:
            continue
        if foreign:  # its predictions, on its DF map at this value (its truth is sampled below)
            try:
                predictions = predict(family.G({name: value}), family.params({name: value}))
            except DfwbError as error:
                notes.append(f"{name} = {value:g}: no DF search: {error}")
                predictions = []
            ranges.append(fixed[0])
            prediction_starts += [(value, prediction) for prediction in predictions]
            if progress:
                progress("starts", k + 1, len(at))
            continue
        try:
            problem = family.problem({name: value}, fmu_dir)
        except InputError as error:
            notes.append(f"{name} = {value:g}: {error}")
            continue
        if "truth" in sources:
            found = find_cycles(problem)
            searches.append({"parameter": value, "cycles": len(found.cycles), "coverage": found.coverage.as_dict()})
            if not found.coverage.settled:
                notes.append(f"{name} = {value:g}: the search for true cycles is not settled ("
                             + ("the work budget ran out" if not found.coverage.complete else "runs failed")
                             + "): a branch may be missing")
            cycle_starts += [(value, cycle) for cycle in found.cycles]
        if "df" in sources:
            df_params = _df_params(family, {name: value}) if family.compensation else problem.params
            if df_params is None:
                notes.append(f"{name} = {value:g}: no DF (the compensated plant is no plant there)")
            else:
                F, omega = search_ranges(problem)
                try:
                    predictions = search(family.spec.name, problem.G, df_params, F, omega, engine=engine).cycles
                except DfwbError as error:  # the plant refuses a DF point here (a motion it cannot resolve)
                    notes.append(f"{name} = {value:g}: no DF search: {error}")
                    predictions = []
                ranges.append(F)
                prediction_starts += [(value, prediction) for prediction in predictions]
        if progress:
            progress("starts", k + 1, len(at))
    branches, bifurcations = [], []
    if foreign and "truth" in sources:
        from dfwb.foreign.continuation import sampled_branches

        more, found = sampled_branches(engine, family, name, bounds, samples, fixed[0], fixed[1], fixed[2:],
                                       progress)
        branches += more
        bifurcations += found
        notes.append(f"the true cycles searched at {samples} values of {name} and joined where near: where a "
                     "branch begins, ends or changes its stability is bracketed by the samples")
    if cycle_starts:
        more, found = continue_cycles(family, name, bounds, cycle_starts, fmu_dir, max_points)
        branches += more
        bifurcations += found
    if prediction_starts:
        F_range = fixed[0] if foreign else (min(F[0] for F in ranges), min(max(F[1] for F in ranges) * 10.0,
                                                                            F_RANGE[1]))
        more, found = continue_predictions(family, name, bounds, prediction_starts, engine, F_range, max_points)
        branches += more
        bifurcations += found
    return ContinuationResponse(plant=family.spec.name, G=_text(G, family), parameter=name, range=list(bounds),
                                values=family.merged(), branches=branches,
                                bifurcations=sorted(bifurcations, key=lambda b: (b.source, b.parameter)),
                                searches=searches, notes=notes, unit=family.spec.unit)


def _df_params(family, values):
    """:meth:`LoopFamily.df_params` at the values, None where there is no DF (a compensated plant that is no
    plant; a value it refuses)."""
    try:
        return family.df_params(values)
    except InputError:
        return None


def _foreign_engine(spec, F_range, omega_range, n_F, n_omega, rtol, timeout):
    """(engine, (F_range, omega_range, n_F, n_omega)) of a continuation of a user's FMU, refused in one line
    where it cannot go."""
    from dfwb.foreign.hunting import study

    if spec.kind != "model-exchange":
        raise InputError(f"{spec.name}: the DF and the cycles of a co-simulation FMU are too rough to follow (give "
                         "a model-exchange FMU)")
    engine, F, omega = study(spec, F_range, omega_range, (n_F, n_omega), rtol, timeout)
    return engine, (F, omega, n_F, n_omega)


def _sources(sources):
    if sources == "both":
        sources = SOURCES
    if isinstance(sources, str):
        sources = (sources,)
    try:
        chosen = tuple(dict.fromkeys(sources))
    except TypeError:
        raise InputError(f"sources = {sources!r:.60}: give some of {', '.join(SOURCES)}") from None
    if not chosen or any(source not in SOURCES for source in chosen):
        raise InputError(f"sources = {sources!r:.60}: give some of {', '.join(SOURCES)}")
    return chosen


def _starts(starts, bounds):
    if isinstance(starts, (int, float)) and not isinstance(starts, bool):
        starts = [starts]
    try:
        if isinstance(starts, (str, bytes)) or len(starts) > MAX_STARTS:
            raise TypeError
        values = sorted({number("starts", v) for v in starts})
    except (TypeError, ValueError, InputError):
        raise InputError(f"starts = {starts!r:.60}: a list of parameter values") from None
    if not 1 <= len(values) <= MAX_STARTS or not all(bounds[0] <= v <= bounds[1] for v in values):
        raise InputError(f"starts = {starts!r:.60}: 1 to {MAX_STARTS} values within [{bounds[0]:g}, {bounds[1]:g}]")
    return values


def _text(G, family=None):
    """G as text for reports: the expression, or num/den; with the compensators of ``family``, if any."""
    if family is not None and family.compensation:
        return f"{_text(G)}, compensated by {', '.join(family.compensation.kinds)}"
    if isinstance(G, str):
        return G
    if getattr(G, "num", None) is not None:
        from dfwb.engine.transfer import num_den

        return "({}) / ({})".format(*num_den(G))
    return getattr(G, "__name__", "G")
