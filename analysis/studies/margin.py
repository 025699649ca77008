"""The limit-cycle margin of a controller, the one way dfwb computes it (the API and ``dfwb margin`` call
:func:`gain_margin`): the gain factors k for which k G hunts, by the truth and by the DF
(:mod:`dfwb.engine.margin`)."""

from dfwb.base.errors import InputError
from dfwb.engine.describing import DFEngine
from dfwb.engine.family import LoopFamily
from dfwb.engine.margin import K_RANGE, SCAN, margins
from dfwb.studies.continuation import _text
from dfwb.studies.responses import MarginResponse


def gain_margin(plant, G, values=None, *, k_range=K_RANGE, count=SCAN, df=True, fmu_dir=None, progress=None):
    """The :class:`~dfwb.studies.responses.MarginResponse` of ``plant`` under k ``G`` for k in ``k_range``."""
    if isinstance(count, bool) or not isinstance(count, int) or not 3 <= count <= 1000:
        raise InputError(f"count = {count!r}: the gain factors scanned, an integer from 3 to 1000")
    family = LoopFamily(plant, G, values)
    engine = DFEngine(family.spec.name, fmu_dir=fmu_dir) if df else None
    report = None if progress is None else (lambda done, total: progress("gain factors", done, total))
    found = margins(family, k_range, count, fmu_dir, engine, report)
    return MarginResponse(plant=family.spec.name, G=_text(G), values=family.merged(),
                          k_range=[float(k) for k in k_range], truth=found[0],
                          df=found[1] if len(found) > 1 else None, unit=family.spec.unit)
