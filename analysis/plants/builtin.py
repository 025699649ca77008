"""dfwb's own plants (:mod:`dfwb.fmus.plants`), as registry entries.

The three plants of the paper have entries here with what dfwb knows of
them beyond the solver, its loop, its table and the FMU facade
(:mod:`dfwb.fmus`): see :class:`~dfwb.plants.registry.Plant`. Any other
plant of :mod:`dfwb.fmus.plants` is registered with its table's facts alone.
The independent references (:mod:`dfwb.plants.reference`, scipy) are imported
only when a reference is asked for.
"""

import math

from dfwb.fmus import facade, naive_facade
from dfwb.plants.registry import Demo, Plant, names, register
from dfwb.plants.stress_profiles import BACKLASH as BACKLASH_STRESS
from dfwb.plants.stress_profiles import DRIVETRAIN as DRIVETRAIN_STRESS
from dfwb.plants.stress_profiles import FRICTION as FRICTION_STRESS
from dfwb.plants.stress_profiles import STATIC_BACKLASH as STATIC_BACKLASH_STRESS
from dfwb.plants.stress_profiles import STRIBECK as STRIBECK_STRESS


def _reference(plant):
    """N by the scipy event-driven reference at tight tolerance (DOP853, rtol 1e-12)."""

    def reference(F, omega, params=None):
        from dfwb.plants.reference import describing_function_reference

        return describing_function_reference(plant, F, omega, method="DOP853", rtol=1e-12, **(params or {}))["N"]

    return reference


def _static_backlash_reference(F, omega, params=None):
    """N in closed form (the mass's sinusoid through the backlash's DF)."""
    from dfwb.plants.closed_forms import static_backlash_plant_df

    return complex(static_backlash_plant_df(F, omega, **(params or {})))


def _scipy(plant):
    """N by the scipy event-driven reference at a user's method and tolerance (the benchmark's rival)."""

    def scipy(F, omega, params, method, rtol):
        from dfwb.plants.reference import describing_function_reference

        return describing_function_reference(plant, F, omega, method=method, rtol=rtol, **(params or {}))["N"]

    return scipy


def _static_backlash_scipy(F, omega, params, method, rtol):
    """N by solve_ivp for the mass and the play operator on a dense grid (the benchmark's rival)."""
    from dfwb.plants.reference import static_backlash_scipy

    return static_backlash_scipy(F, omega, method, rtol, **(params or {}))


FRICTION = register(Plant(
    "friction", facade.FrictionMass,
    naive=naive_facade.NaiveFrictionMass,
    reference=_reference("friction"),
    scipy=_scipy("friction"),
    stress=FRICTION_STRESS,
    bench={"quick": [(10.0, 1.0, {}), (30.0, 5.0, {})],
           "full": [(10.0, 1.0, {}), (30.0, 1.0, {}), (50.0, 0.5, {}), (20.0, 5.0, {}), (10.0, 0.1, {})]},
    variants=tuple((f"Dv={dv:g}", {"Dv": dv}) for dv in (1e-1, 1e-2, 1e-3, 1e-4)),
    demo=Demo({"F": 10.0, "omega": 1.0}, 8 * math.pi, 64,
              (("x", "position x [m]"), ("v", "velocity v [m/s]"), ("Ff", "friction force Ff [N]"))),
))

BACKLASH = register(Plant(
    "backlash", facade.TwoMassBacklash,
    never_engaged="the masses do not touch in the steady state: x1 is constant, N = 0",
    naive=naive_facade.NaiveTwoMassBacklash,
    reference=_reference("backlash"),
    scipy=_scipy("backlash"),
    stress=BACKLASH_STRESS,
    bench={"quick": [(50.0, 20.0, {"eps": 0.5}), (30.0, 25.0, {"eps": 0.2})],
           "full": [(50.0, 20.0, {"eps": 0.5}), (50.0, 20.0, {"eps": 0.8}), (50.0, 40.0, {"eps": 0.2}),
                    (30.0, 25.0, {"eps": 0.2}), (50.0, 15.0, {"eps": 0.1})]},
    demo=Demo({"F": 50.0, "omega": 20.0, "eps": 0.5}, 4 * math.pi / 20.0, 64,
              (("x1", "x1 [m]"), ("x2", "x2 [m]"), ("gap", "gap x2 - x1 [m]"))),
))

STATIC_BACKLASH = register(Plant(
    "static-backlash", facade.StaticBacklash,
    never_engaged="the backlash does not engage in the steady state (X <= h/2): N = 0",
    naive=naive_facade.NaiveStaticBacklash,
    reference=_static_backlash_reference,
    scipy=_static_backlash_scipy,
    stress=STATIC_BACKLASH_STRESS,
    bench={"quick": [(50.0, 20.0, {})],
           "full": [(50.0, 20.0, {}), (50.0, 10.0, {}), (5.0, 2.0, {})]},
    demo=Demo({"F": 50.0, "omega": 20.0}, 4 * math.pi / 20.0, 64,
              (("x", "mass position x [m]"), ("y", "backlash output y [m]"))),
))

# the stress profiles of the plants registered with their table's facts
STRESS = {"drivetrain": DRIVETRAIN_STRESS, "stribeck": STRIBECK_STRESS}

for _facade in facade.PLANTS:  # a plant of dfwb.fmus.plants without an entry above: its table's facts
    if _facade.table.name not in names():
        register(Plant(_facade.table.name, _facade, stress=STRESS.get(_facade.table.name)))
