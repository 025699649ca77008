"""Log-spaced frequency grids as scenes and sweeps write them, without numpy.

A grid's values are keys of cached points, so a scene and a sweep over the
same ``[lo, hi, n]`` must give the same floats: both take them from
:func:`log_grid`, rounded to 12 significant digits (the same value on every
machine and libm, and readable in a CSV). It is plain Python, so a cached
re-run of a scene does not import numpy just to name its points.

Examples
--------
>>> log_grid(0.01, 100.0, 5)
[0.01, 0.1, 1.0, 10.0, 100.0]
>>> log_grid(1.0, 2.0, 3)
[1.0, 1.41421356237, 2.0]
"""

import math

DIGITS = 12  # significant digits of a grid value


def log_grid(lo, hi, n):
    """``n`` values from ``lo`` to ``hi`` (both positive, both kept exactly), evenly spaced in log."""
    n = int(n)
    if not (0 < lo and 0 < hi and math.isfinite(lo) and math.isfinite(hi) and n >= 2):
        raise ValueError(f"log grid [{lo!r}, {hi!r}, {n!r}]: expected 0 < lo, hi finite and n >= 2")
    a, b = math.log10(lo), math.log10(hi)
    inner = [float(f"{10.0 ** (a + (b - a) * i / (n - 1)):.{DIGITS}g}") for i in range(1, n - 1)]
    return [float(lo)] + inner + [float(hi)]
