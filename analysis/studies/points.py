"""The cache key of a DF point: one definition, so that scenes and sweeps find each other's points.

A point's key (:mod:`dfwb.studies.cache` hashes it) holds everything its
value depends on: the model and the FMU's revision, the code's revision,
the engine's settings, the complete parameter set (defaults filled in) and
(F, omega). A scene's runner (:mod:`dfwb.studies.runner`) and a sweep
(:mod:`dfwb.studies.sweep`) both build it here, so a point computed by one is
found by the other whenever the values would be equal:

- dfwb's own plants: the drive, the harmonics recorded, ``max_periods`` and,
  for ``drive = "input"`` only, ``samples_per_period`` (the internal drive
  does not use it);
- a user's FMU: the harmonics, ``max_periods``, the tolerance (None is the
  driver's default for the FMU's kind, written out: the same value given or
  defaulted is the same point), its input, output and kind.

A sweep records X_0 .. X_10 (:data:`dfwb.engine.describing.HARMONICS`): its
points are a scene's that records harmonics, and a scene that records only
N (harmonics = 1) takes them too (the runner accepts an entry with more
harmonics: N is the same to the last bit).

Examples
--------
>>> from dfwb.plants import plant
>>> key = df_key(plant("friction"), 10, 1, {}, fmu="abc", code="def", harmonics=1)
>>> key["model"], key["settings"], key["F"]
('FrictionMass', {'drive': 'internal', 'harmonics': 1, 'max_periods': 150}, 10.0)
"""

from dfwb.base.defaults import DF_PERIODS as MAX_PERIODS
from dfwb.base.defaults import HARMONICS, SAMPLES_PER_PERIOD


def df_key(spec, F, omega, params, *, fmu, code, drive="internal", harmonics=HARMONICS, max_periods=MAX_PERIODS,
           samples_per_period=SAMPLES_PER_PERIOD, rtol=None):
    """The cache key of the DF point of ``spec`` at (F, omega, params).

    Parameters
    ----------
    spec : plant entry or FMUPlant
        A registered plant, or a user's FMU (``spec.foreign``).
    params : dict
        The parameters as checked (:meth:`check`); the key holds them completed with the defaults.
    fmu : str
        The FMU's revision: :func:`dfwb.studies.cache.fmu_revision` of dfwb's own FMU, the SHA-256 of a user's.
    code : str
        :func:`dfwb.studies.cache.code_revision`.
    drive, harmonics, max_periods, samples_per_period :
        The engine's settings (:class:`dfwb.engine.describing.DFEngine`); ``drive`` and
        ``samples_per_period`` are dfwb's own plants' only.
    rtol : float, optional
        A user's FMU's tolerance (None: its kind's default, :data:`dfwb.foreign.engine.RTOL`).
    """
    if getattr(spec, "foreign", False):  # a user's FMU: its file, variables and the driver's settings
        from dfwb.foreign.engine import RTOL  # (with its worker's machinery: only for a user's FMU)

        settings = {"harmonics": int(harmonics), "max_periods": int(max_periods),
                    "rtol": float(RTOL[spec.kind] if rtol is None else rtol),
                    "input": spec.input, "output": spec.output, "drive": spec.kind}
        model = "foreign"
    else:
        settings = {"drive": drive, "harmonics": int(harmonics), "max_periods": int(max_periods)}
        if drive != "internal":  # the internal drive is exact: the steps per period do not enter
            settings["samples_per_period"] = int(samples_per_period)
        model = spec.fmu_name
    return {"kind": "df", "model": model, "fmu": fmu, "code": code, "settings": settings,
            "params": spec.complete(params), "F": float(F), "omega": float(omega)}
