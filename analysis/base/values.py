"""Values handed to dfwb by a program: shown shortly in messages, and turned into arrays only once counted.

A caller may pass a list of a billion numbers, or one nested a million deep;
each is refused in one line before numpy builds anything.
"""

import numpy as np

from dfwb.base.errors import InputError

__all__ = ["short", "leaves", "reals", "integer"]


def short(value, width=80):
    """``repr(value)`` on one line, cut to ``width`` characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= width else text[:width - 3] + "..."


def leaves(value, limit):
    """The numbers in a nested list/tuple/range, counted without building them (stops past ``limit``)."""
    total, stack = 0, [value]
    while stack and total <= limit:
        item = stack.pop()
        if isinstance(item, np.ndarray):
            total += item.size
        elif isinstance(item, range):
            total += len(item)
        elif isinstance(item, (list, tuple)):
            stack.extend(item)
        else:
            total += 1
    return total


def reals(name, value, limit, advice=""):
    """``value`` as a float array: real numbers only (no bool, complex, text or objects), at most ``limit``."""
    if leaves(value, limit) > limit:
        raise InputError(f"{name} has more than {limit} numbers: at most {limit}{advice}")
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        array = None
    if array is None or array.dtype.kind not in "iuf":
        raise InputError(f"{name} = {short(value)} is not a number or an array of numbers "
                         "(real ones: no bool, complex, text or None)")
    if array.size > limit:
        raise InputError(f"{name} has {array.size} numbers: at most {limit}{advice}")
    return array.astype(float)


def integer(name, value):
    """An integer option (a Python or numpy integer, not a bool), as int."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} = {short(value)} is not an integer")
    return int(value)
