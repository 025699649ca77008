"""The limit-cycle margin of a controller, the one way dfwb computes it (the API and ``dfwb margin`` call
:func:`gain_margin`): the gain factors k for which k G hunts, by the truth and by the DF
(:mod:`dfwb.engine.margin`), for dfwb's own plants and for a user's FMU (:mod:`dfwb.foreign.hunting`)."""

from dfwb.base.defaults import DF_MAP_SIZE, K_COUNT, K_RANGE
from dfwb.base.errors import InputError
from dfwb.engine.describing import DFEngine
from dfwb.engine.family import LoopFamily
from dfwb.engine.margin import margins
from dfwb.foreign.hunting import classifier, no_fmu_options, study
from dfwb.foreign.plant import fmu_plant, is_fmu_path
from dfwb.studies.continuation import _text
from dfwb.studies.responses import MarginResponse


def gain_margin(plant, G, values=None, *, k_range=K_RANGE, count=K_COUNT, df=True, fmu_dir=None, progress=None,
                F_range=None, omega_range=None, n_F=DF_MAP_SIZE[0], n_omega=DF_MAP_SIZE[1], rtol=None, timeout=None,
                compensate=None):
    """The :class:`~dfwb.studies.responses.MarginResponse` of ``plant`` under k ``G`` for k in ``k_range``.

    ``plant``: a registered plant, or a user's FMU (an FMUPlant or an .fmu path), which needs ``F_range``
    and ``omega_range`` (its DF map's, ``n_F`` x ``n_omega``, shared by every k) and takes ``rtol`` and
    ``timeout``. ``compensate``: compensators in the loop (the truth alone then: no DF of a compensated loop)."""
    if isinstance(count, bool) or not isinstance(count, int) or not 3 <= count <= 1000:
        raise InputError(f"count = {count!r}: the gain factors scanned, an integer from 3 to 1000")
    if is_fmu_path(plant):
        plant = fmu_plant(plant)
    family = LoopFamily(plant, G, values, compensate=compensate)
    df = df and not family.compensation
    report = None if progress is None else (lambda done, total: progress("gain factors", done, total))
    if getattr(family.spec, "foreign", False):
        engine, F, omega = study(family.spec, F_range, omega_range, (n_F, n_omega), rtol, timeout)
        found = margins(family, k_range, count, None, engine if df else None, report,
                        classifier=classifier(engine, F, omega, (n_F, n_omega)))
    else:
        no_fmu_options(F_range, omega_range, (n_F, n_omega), rtol, timeout)
        engine = DFEngine(family.spec.name, fmu_dir=fmu_dir) if df else None
        found = margins(family, k_range, count, fmu_dir, engine, report)
    return MarginResponse(plant=family.spec.name, G=_text(G, family), values=family.merged(),
                          k_range=[float(k) for k in k_range], truth=found[0],
                          df=found[1] if len(found) > 1 else None, unit=family.spec.unit)
