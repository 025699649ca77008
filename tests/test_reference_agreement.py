"""The FMU DF engine against the independent scipy reference, to 1e-8.

``dfwb.engine.describing.DFEngine`` (exact event-driven FMUs, Poincare-section
search with Aitken shooting) and ``dfwb.plants.reference`` (plain ``solve_ivp``
between events, at its documented high-accuracy setting DOP853, rtol = 1e-12)
are two independent implementations of the same models and the
same DF convention (docs/models.md: start at rest, ``N = X_1 / F`` over one period
of the periodic steady state). Where both find a one-period orbit they must
agree on N and on the harmonics |X_k| (k = 1, 3, 5, relative to |X_1|) to
1e-8; a shared misreading of docs/models.md is the only way both could be wrong
together.

Every registered plant with a reference (``Plant.reference``) has its points
in ``POINTS``; a plant that ``dfwb.plants.reference`` does not simulate (the
static backlash) is checked on N against its own reference, a closed form.
"""

import pytest

from dfwb.engine.describing import DFEngine
from dfwb.plants import PLANTS
from dfwb.plants import reference as scipy_reference
from dfwb.plants.reference import describing_function_reference

RTOL = 1e-8
REFERENCE = dict(method="DOP853", rtol=1e-12)  # reference.py's high-accuracy setting for these tests

FRICTION_POINTS = [
    *[(F, omega, {}) for F in (10.0, 30.0, 50.0) for omega in (0.1, 1.0, 5.0)],
    (30.0, 1.0, {"B": 0.2}),  # exact stick (Dv = 0, no Karnopp band), lighter damping
    # Fs = Fc at a stick-slip point: at (30, 1) the mass never sticks, so Fs = 5 gives
    # exactly the default N there and would not test Fs = Fc; (10, 1) sticks every half period.
    (10.0, 1.0, {"Fs": 5.0}),
]

BACKLASH_POINTS = [
    (50.0, 20.0, {"eps": 0.5}),
    (50.0, 20.0, {"eps": 0.8}),
    (50.0, 40.0, {"eps": 0.2}),
    (50.0, 15.0, {"eps": 0.1}),
    # Replaces (50, 30, eps = 0.9): the engine reports that orbit with orbit_periods = 2 (the
    # section converges to a period-1 orbit through a multiplier near -1, so the lag-2 test
    # closes first); (50, 30, eps = 0.8) is a one-period orbit for both.
    (50.0, 30.0, {"eps": 0.8}),
    (30.0, 25.0, {"eps": 0.2}),
]

STATIC_BACKLASH_POINTS = [  # against the closed form (its reference): N only
    (50.0, 20.0, {}),
    (50.0, 10.0, {}),
    (5.0, 2.0, {}),
    (50.0, 20.0, {"k": 2.0, "h": 0.05}),
]

POINTS = {"friction": FRICTION_POINTS, "backlash": BACKLASH_POINTS, "static-backlash": STATIC_BACKLASH_POINTS}
CASES = [(plant, *point) for plant, points in POINTS.items() if plant in PLANTS for point in points]


def _ids(cases):
    return [f"{plant}-F={F:g}-w={omega:g}" + "".join(f"-{k}={v:g}" for k, v in params.items())
            for plant, F, omega, params in cases]


def test_every_registered_plant_with_a_reference_has_points():
    missing = [entry.name for entry in PLANTS.values() if entry.reference is not None and entry.name not in POINTS]
    assert not missing, f"add agreement points to POINTS for {missing}"


@pytest.fixture(scope="module")
def engines(fmus):
    return {}


def _agree(engines, plant, F, omega, params):
    if plant not in engines:
        engines[plant] = DFEngine(plant)
    result = engines[plant].point(F, omega, params)
    # Preconditions, not skips: every point above was chosen periodic with a one-period orbit.
    assert result.periodic and result.orbit_periods == 1, (result.periods, result.orbit_periods, result.note)
    if plant not in scipy_reference.PLANTS:  # the plant's own reference (a closed form): N only
        N = PLANTS[plant].reference(F, omega, dict(params))
        assert N != 0
        dN = abs(result.N - N)
        assert dN <= RTOL * abs(N), f"FMU N = {result.N!r}, reference N = {N!r}, rel {dN / abs(N):.3g}"
        return
    ref = describing_function_reference(plant, F, omega, max_periods=400, **REFERENCE, **params)
    assert ref["periodic"], ref["periods"]
    assert ref["N"] != 0
    dN = abs(result.N - ref["N"])
    assert dN <= RTOL * abs(ref["N"]), f"FMU N = {result.N!r}, reference N = {ref['N']!r}, rel {dN / abs(ref['N']):.3g}"
    X1 = ref["harmonics"][1]
    for k in (1, 3, 5):
        dk = abs(result.harmonics[k] - ref["harmonics"][k])
        assert dk <= RTOL * X1, (
            f"|X_{k}|: FMU {result.harmonics[k]!r}, reference {ref['harmonics'][k]!r}, rel to |X_1| {dk / X1:.3g}")


@pytest.mark.parametrize("plant, F, omega, params", CASES, ids=_ids(CASES))
@pytest.mark.slow
def test_agrees_with_reference(engines, plant, F, omega, params):
    _agree(engines, plant, F, omega, params)
