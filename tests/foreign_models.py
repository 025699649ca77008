"""The tests' foreign C FMUs: dfwb's well-behaved ones (:mod:`dfwb.build_fmus.c_models`, with closed forms),
a relay for co-simulation, and hostile binaries that crash, hang or return NaN once the force exceeds 5 N."""

from dfwb.build_fmus import c_models
from dfwb.build_fmus.c_models import msd_df, relay_df, saturation_df  # noqa: F401  (the closed forms)

MODELS = {
    **c_models.MODELS,
    # a relay with hysteresis for co-simulation (run it with kind="co-simulation"): it switches inside doStep,
    # at the first RK4 stage whose input is past +-a, so under a held input its output jumps at a step's start
    # and dfwb has to locate where the sine crosses; its DF is relay_df's. Not for model exchange (it switches
    # while its derivatives are evaluated).
    "RelayCS": dict(
        params=[("Y", 1.0, "m"), ("a", 0.5, "N")], nx=0, nz=0,
        derivatives="if (U - P(1) > 0) D = 1; else if (U + P(1) <= 0) D = -1;", output="P(0) * D",
        indicators="", update="", start="D = U > 0 ? 1 : -1;"),
    # hostile binaries: a crash, a hang and NaN, each once the force exceeds 5 N
    "Crash": dict(
        params=[("M", 1.0, "kg")], nx=2, nz=0,
        derivatives="if (U > 5.0) { volatile int* null = 0; *null = 1; } dx[0] = X(1); dx[1] = U / P(0);",
        output="X(0)", indicators="", update="", start=""),
    "Hang": dict(
        params=[("M", 1.0, "kg")], nx=2, nz=0,
        derivatives="volatile int forever = U > 5.0; while (forever) {} dx[0] = X(1); dx[1] = U / P(0);",
        output="X(0)", indicators="", update="", start=""),
    "NotANumber": dict(
        params=[("M", 1.0, "kg")], nx=2, nz=0,
        derivatives="dx[0] = X(1); dx[1] = U / P(0);",
        output="U > 5.0 ? NAN : X(0)", indicators="", update="", start=""),
}


def build(name, folder, interpolate=False):
    """``folder/<name>.fmu`` of one of :data:`MODELS` (see :func:`dfwb.build_fmus.c_models.build`)."""
    return c_models.build(name, folder, interpolate, MODELS[name])
