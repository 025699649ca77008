"""The truth of an exact loop, whichever kind it is: the one call the studies make for it.

An autonomous loop's truth is its limit cycles, found on an event section
(:func:`dfwb.engine.cycles.find_cycles`); a dithered loop is forced, and its
truth is the fixed points of its stroboscopic map and the hunting not locked
to the dither (:func:`dfwb.engine.dither.find_responses`).
"""

from dfwb.engine.cycles import find_cycles
from dfwb.engine.dither import find_responses

__all__ = ["search"]


def search(problem, predictions=(), amplitudes=None, boundaries=True, progress=None):
    """The :class:`~dfwb.engine.cycles.CycleSearch` of ``problem`` (a
    :class:`~dfwb.engine.dither.DitherSearch` where it has a dither, whose search links ``predictions`` but
    starts no run from them, and takes no ``boundaries``); the arguments as
    :func:`~dfwb.engine.cycles.find_cycles` takes them."""
    if problem.dither is not None:
        return find_responses(problem, amplitudes, progress=progress, predictions=predictions)
    return find_cycles(problem, predictions, amplitudes, boundaries=boundaries, progress=progress)
