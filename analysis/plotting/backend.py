"""The batch backend, chosen without importing matplotlib (a run whose figures all come from the cache
never pays for pyplot)."""

import os
import sys


def use_batch_backend():
    """Select matplotlib's Agg backend: figures are written to files, never shown (no display needed).

    Before matplotlib is imported this only sets ``MPLBACKEND`` (read by
    matplotlib when, and if, it is imported; inherited by worker processes).
    """
    if "matplotlib" in sys.modules:
        import matplotlib

        matplotlib.use("Agg")
    else:
        os.environ["MPLBACKEND"] = "Agg"
