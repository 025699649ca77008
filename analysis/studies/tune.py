"""A tuning study, the one way dfwb does it (the API's :func:`dfwb.tune` and ``dfwb tune`` call
:func:`tune_study`): its input checked, the search of :mod:`dfwb.engine.tune`, its confirmation by the
independent reference, and the :class:`~dfwb.studies.responses.TuneResponse`."""

import time

from dfwb.base.errors import InputError
from dfwb.engine.family import LoopFamily, number
from dfwb.engine.periodic import LoopProblem
from dfwb.engine.tune import confirm, tune
from dfwb.studies.continuation import _text, check_parameter
from dfwb.studies.responses import TuneResponse


def _ranges(free):
    """{name: (lo, hi)} of ``free``, each a pair of finite numbers with lo < hi."""
    if not isinstance(free, dict) or not free:
        raise InputError(f"free = {free!r:.60}: give {{name: (lo, hi)}} of the parameters searched")
    ranges = {}
    for name, bounds in free.items():
        try:
            lo, hi = bounds
        except (TypeError, ValueError):
            raise InputError(f"free {name} = {bounds!r:.60}: give (lo, hi)") from None
        lo, hi = number(f"free {name} lo", lo), number(f"free {name} hi", hi)
        if not lo < hi:
            raise InputError(f"free {name} = ({lo:g}, {hi:g}): expected lo < hi")
        ranges[name] = (lo, hi)
    return ranges


def tune_study(spec, G, values=None, *, free, compensate=None, tolerance=None, robust=None, count=5, fmu_dir=None,
               progress=None):
    """The :class:`~dfwb.studies.responses.TuneResponse` of ``spec`` (a registered plant) under the family ``G``
    with ``values`` given; the rest as :func:`dfwb.tune`. ``progress``: ``progress(stage, done, total)``."""
    if not 2 <= count <= 50:
        raise InputError(f"count = {count}: the values per free parameter, 2 to 50")
    ranges = _ranges(free)
    if tolerance is not None:
        tolerance = number("tolerance", tolerance)
        if tolerance <= 0.0:
            raise InputError(f"tolerance = {tolerance:g}: a standing error above 0")
    if robust is not None and not isinstance(robust, dict):
        raise InputError(f"robust = {robust!r:.60}: give {{name: relative error}} of the plant's parameters")
    if getattr(spec, "foreign", False) or spec.loop is None:
        raise InputError(f"tune: plant {spec.name!r} has no exact closed loop to tune against")
    family = LoopFamily(spec, G, values, free=tuple(ranges), compensate=compensate)
    bad = [name for name in ranges if name in family.plant_names]
    if bad:
        raise InputError(f"free {bad[0]}: a parameter of the plant, not a setting of the controller (give it a "
                         "value, or a relative error with robust)")
    for name, (lo, hi) in ranges.items():  # each end as a study's range is checked (a compensator's own range)
        check_parameter(family, name, lo, hi, plant=False)
    try:  # the plant in the exact loop (a plain low pass in G's place): once here, not in every candidate
        LoopProblem(spec.name, "1/(s + 1)", family.params(), fmu_dir=fmu_dir)
    except InputError as error:
        raise InputError(f"tune: {error}") from None
    started = time.perf_counter()
    chosen, tried, box = tune(family, ranges, tolerance, robust, count,
                              (lambda done, total: progress("settings", done, total)) if progress else None, fmu_dir)
    confirmed, runs = confirm(family, chosen, box, fmu_dir) if chosen is not None else (None, "nothing chosen")
    return TuneResponse(plant=spec.name, G=_text(G, family), free={k: list(v) for k, v in ranges.items()},
                        count=count, tolerance=tolerance, robust=dict(robust or {}), corners=box,
                        settings=None if chosen is None else chosen.values,
                        crossover=None if chosen is None else chosen.crossover,
                        cost={} if chosen is None else chosen.cost, confirmed=confirmed, confirmation=runs,
                        candidates=[c.as_dict() for c in tried],
                        controller=[n for n in ranges if n in family.controller.names], values=family.merged(),
                        unit=spec.unit, seconds=time.perf_counter() - started)
