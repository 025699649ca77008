"""Values handed to dfwb by a program or read back from a file: shown shortly in messages, turned into
arrays only once counted, and checked against the shape they must have.

A caller may pass a list of a billion numbers, or one nested a million deep;
each is refused in one line before numpy builds anything. A document read
back from a cache or a log (which anyone can write) is used only if it
:func:`conforms` to its schema.
"""

import math
import numbers
import re

from dfwb.base.errors import InputError

__all__ = ["short", "leaves", "reals", "integer", "flags", "conforms", "positive", "decimal", "whole", "real"]

# (each digit has one place in a match: a long run of digits fails in linear time)
_DECIMAL = re.compile(r"[+-]?(?:(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.IGNORECASE | re.ASCII)
_WHOLE = re.compile(r"[+-]?\d+", re.ASCII)
NUMBER_FORMS = "a plain decimal number such as 10, -1.5e3 or inf"  # what a number's text may be
MAX_WHOLE_DIGITS = 18  # an integer option's digits: beyond, out of every range (int() refuses 4300)


def short(value, width=80):
    """``repr(value)`` on one line, cut to ``width`` characters (an integer too long to print by its size)."""
    try:
        text = " ".join(repr(value).split())
    except ValueError:  # Python prints no integer of over 4300 digits
        text = f"an integer of {value.bit_length()} bits" if isinstance(value, int) else "a value that cannot print"
    return text if len(text) <= width else text[:width - 3] + "..."


def leaves(value, limit, odd=None):
    """The numbers in a nested list/tuple/range, counted without building them (stops past ``limit``); ``odd``,
    a list, gets each item that numpy would read as a number though it is none (a bool, bytes)."""
    import numpy as np  # here, not at the top: a message or a schema check needs no numpy

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
            if odd is not None and isinstance(item, (bool, np.bool_, bytes, bytearray, memoryview)):
                odd.append(item)
    return total


def reals(name, value, limit, advice=""):
    """``value`` as a float array: real numbers only (no bool, complex, text or objects), at most ``limit``."""
    import numpy as np

    odd = []
    if leaves(value, limit, odd) > limit:
        raise InputError(f"{name} has more than {limit} numbers: at most {limit}{advice}")
    try:
        array = None if odd else np.asarray(value)  # (numpy reads [True, 2] as [1, 2] and a bytearray's bytes)
    except (TypeError, ValueError):
        array = None
    if array is not None and array.dtype == object:  # Fractions, Decimals, integers beyond 64 bits: each by real()
        flat = [real(item) for item in array.ravel()]
        array = None if None in flat else np.array(flat, dtype=float).reshape(array.shape)
    if array is None or array.dtype.kind not in "iuf":
        raise InputError(f"{name} = {short(value)} is not a number or an array of numbers "
                         "(real ones: no bool, complex, text, bytes or None)")
    if array.size > limit:
        raise InputError(f"{name} has {array.size} numbers: at most {limit}{advice}")
    return array.astype(float)


def decimal(text):
    """The float that a number's text names in its plain forms ('10', '-1.5e3', '.5', 'inf'), else ValueError.

    Python's ``float`` also reads '1_0' as 10, ' 1 ' as 1 and digits other than 0-9: typos, not numbers.

    >>> decimal("-1.5e3"), decimal("inf")
    (-1500.0, inf)
    >>> decimal("1_0")
    Traceback (most recent call last):
    ...
    ValueError: '1_0' is not a number (a plain decimal number such as 10, -1.5e3 or inf)
    """
    if not (isinstance(text, str) and _DECIMAL.fullmatch(text)):
        raise ValueError(f"{short(text)} is not a number ({NUMBER_FORMS})")
    return float(text)


def real(value):
    """The float of one real number as a program or a user gives it, else None: a real of Python or numpy (a
    Fraction, a Decimal), or its text in a plain form (:func:`decimal`); never a bool, complex, bytes or a
    container (``float`` reads b'0.1' and '1_0').

    >>> real(3), real("2.5e1"), real("1_0"), real(b"1"), real(True), real(2 + 0j)
    (3.0, 25.0, None, None, None, None)
    """
    if isinstance(value, str):
        try:
            return decimal(value)
        except ValueError:
            return None
    number = isinstance(value, numbers.Number) and (isinstance(value, numbers.Real)
                                                     or not isinstance(value, numbers.Complex))  # (Decimal)
    if not number or isinstance(value, bool):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer beyond a float's range: an infinity, refused as out of range
        return math.inf if value > 0 else -math.inf
    except Exception:  # noqa: BLE001 - a signalling NaN, or a hostile __float__: no number
        return None


def whole(text):
    """The int that an integer's text names in its plain form ('12', '-3'), else ValueError ('1_0', ' 12');
    OverflowError beyond MAX_WHOLE_DIGITS digits (out of any range an option has)."""
    if not (isinstance(text, str) and _WHOLE.fullmatch(text)):
        raise ValueError(f"{short(text)} is not an integer")
    if len(text.lstrip("+-")) > MAX_WHOLE_DIGITS:
        raise OverflowError(f"{short(text)} is out of range")
    return int(text)


def integer(name, value):
    """An integer option (a Python or numpy integer, not a bool), as int."""
    import numpy as np

    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} = {short(value)} is not an integer")
    return int(value)


def flags(**values):
    """Refuse an option that must be True or False given as anything else (1, "yes", None)."""
    for name, value in values.items():
        if not isinstance(value, bool):
            raise InputError(f"{name} = {value!r} must be True or False")


def positive(value):
    """A finite number > 0 (a schema leaf of :func:`conforms`)."""
    return conforms(value, float) and value > 0


def conforms(value, schema):
    """Whether a JSON document ``value`` has the shape ``schema`` describes.

    ``float``: a finite number (not a bool); ``int``, ``bool``, ``str``: exactly that type; ``None``: None;
    ``object``: anything; a tuple: any of its schemas; a frozenset: one of its texts; ``[s]``: a list of
    ``s``; ``{key: s}``: a dict with exactly these keys (``...: object`` among them allows others), or
    ``{str: s}`` a dict of texts to ``s``; another callable: a predicate. The walk follows the schema, so a
    document nested a million deep costs no more than the schema's depth.

    >>> conforms({"x": 1.5, "tags": ["a"]}, {"x": float, "tags": [str]})
    True
    >>> conforms({"x": float("nan"), "tags": []}, {"x": float, "tags": [str]})
    False
    """
    if isinstance(schema, tuple):
        return any(conforms(value, s) for s in schema)
    if schema is None or schema is object:
        return schema is object or value is None
    if schema is float:
        return type(value) in (int, float) and math.isfinite(value)
    if schema in (int, bool, str):
        return type(value) is schema
    if isinstance(schema, frozenset):
        return type(value) is str and value in schema
    if isinstance(schema, list):
        return type(value) is list and all(conforms(v, schema[0]) for v in value)
    if isinstance(schema, dict):
        if type(value) is not dict:
            return False
        if set(schema) == {str}:
            return all(type(k) is str and conforms(v, schema[str]) for k, v in value.items())
        named = {k: s for k, s in schema.items() if k is not ...}
        return ((... in schema or set(value) == set(named)) and set(named) <= set(value)
                and all(conforms(value[k], s) for k, s in named.items()))
    return bool(schema(value))
