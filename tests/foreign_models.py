"""The tests' foreign C FMUs: dfwb's well-behaved ones (:mod:`dfwb.build_fmus.c_models`, with closed forms)
and hostile binaries that crash, hang or return NaN once the force exceeds 5 N."""

from dfwb.build_fmus import c_models
from dfwb.build_fmus.c_models import msd_df, relay_df, saturation_df  # noqa: F401  (the closed forms)

MODELS = {
    **c_models.MODELS,
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
