"""Typed records read from parsed TOML: strict rules per field, one message naming the key path.

A record is a frozen, keyword-only dataclass whose fields say their rule
with :func:`rule`; :func:`record` builds one from a TOML table, checking
every value (no unknown keys, no silent conversions: an integer is a
number, text is not, a boolean is neither) and then the record's own
``__post_init__`` (rules between fields, raising :class:`InputError`). The
first problem, in the order the fields are declared, is one
:class:`Invalid` whose ``where`` is the path of the bad value
(``series[0].F[1]``).

Why not pydantic: a scene is a few small tables, and a cached re-run of
one must start in well under a tenth of a second, of which pydantic's
import and schema building took half. The rules are those of its strict
mode and the messages its words, so scene files and their errors read as
before.

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True, kw_only=True)
... class Drive:
...     amplitude: float = rule(Number(gt=0))
...     periods: int = rule(Integer(ge=1, le=100), default=10)
>>> record(Drive, {"amplitude": 2})
Drive(amplitude=2.0, periods=10)
>>> try:
...     record(Drive, {"amplitude": 2, "periods": 0})
... except Invalid as error:
...     print(f"{error.where}: {error}")
periods: Input should be greater than or equal to 1 (got 0)
"""

import dataclasses
import math
import re

from dfwb.base.errors import InputError

__all__ = ["Invalid", "rule", "record", "shown", "Number", "Integer", "Boolean", "Text", "OneOf", "ListOf",
           "TableOf", "Table", "Checked"]

SHOWN = 60  # characters of a value a message shows: a message stays one short line, whatever the file holds
_PLAIN_KEY = re.compile(r"[A-Za-z0-9_-]{1,%d}" % SHOWN)


def shown(value):
    """``repr(value)`` for a message: one line (repr escapes newlines), its start only if long."""
    try:
        text = repr(value)
    except ValueError:  # an integer beyond Python's digit limit for str()
        return f"<an integer of more than {SHOWN} digits>"
    return text if len(text) <= SHOWN + 20 else text[:SHOWN] + "..."


class Invalid(InputError):
    """A value that breaks its rule: the message, and ``path`` (keys and list indices) to the value."""

    def __init__(self, message, path=()):
        super().__init__(message)
        self.path = list(path)

    @property
    def where(self):
        """The path as written in messages: ``series[0].omega.log[2]`` ('' for the top level)."""
        text = ""
        for part in self.path:
            if isinstance(part, int):
                text += f"[{part}]"
            else:  # a key as written, or quoted when it is not a plain word (a newline, a space, 10,000 characters)
                text += ("." if text else "") + (part if _PLAIN_KEY.fullmatch(part) else shown(part))
        return text


def _wrong(message, value):
    """An Invalid that also shows the value (see :func:`shown`)."""
    return Invalid(f"{message} (got {shown(value)})")


def _at(key, check, value):
    """``check(value)``, a problem's path prefixed with ``key``; a plain InputError becomes Invalid here."""
    try:
        return check(value)
    except Invalid as error:
        error.path.insert(0, key)
        raise
    except InputError as error:
        raise Invalid(str(error), [key]) from None


def _plain(x):
    """A bound as people write it: 0, 0.000001, 1000000000 (no exponent)."""
    if x == int(x) and abs(x) < 1e16:
        return str(int(x))
    text = repr(float(x))
    if "e" not in text:
        return text
    from decimal import Decimal  # only for a bound written with an exponent

    return format(Decimal(text), "f")


def _within(value, number, gt, ge, le):
    """``number`` (the checked form of ``value``) unless it breaks a bound."""
    for bound, holds, words in ((gt, lambda b: number > b, "greater than"),
                                (ge, lambda b: number >= b, "greater than or equal to"),
                                (le, lambda b: number <= b, "less than or equal to")):
        if bound is not None and not holds(bound):
            raise _wrong(f"Input should be {words} {_plain(bound)}", value)
    return number


@dataclasses.dataclass(frozen=True)
class Number:
    """A finite real number (an integer is taken as a float) within optional bounds."""

    gt: float = None
    ge: float = None
    le: float = None

    def __call__(self, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _wrong("Input should be a valid number", value)
        try:
            number = float(value)
        except OverflowError:  # an integer beyond a float's range
            number = math.inf
        if not math.isfinite(number):
            raise _wrong("Input should be a finite number", value)
        return _within(value, number, self.gt, self.ge, self.le)


@dataclasses.dataclass(frozen=True)
class Integer:
    """An integer (not a float, not a boolean) within optional bounds."""

    ge: int = None
    le: int = None

    def __call__(self, value):
        if isinstance(value, bool) or not isinstance(value, int):
            raise _wrong("Input should be a valid integer", value)
        return _within(value, value, None, self.ge, self.le)


@dataclasses.dataclass(frozen=True)
class Boolean:
    """true or false."""

    def __call__(self, value):
        if not isinstance(value, bool):
            raise _wrong("Input should be a valid boolean", value)
        return value


@dataclasses.dataclass(frozen=True)
class Text:
    """A string, optionally at most ``max_length`` characters and matching ``pattern`` as a whole.

    ``pattern`` is matched from the first character to the last (``re.fullmatch``: no newline may end it).
    """

    pattern: str = None
    max_length: int = None

    def __call__(self, value):
        if not isinstance(value, str):
            raise _wrong("Input should be a valid string", value)
        if self.max_length is not None and len(value) > self.max_length:
            raise _wrong(f"String should have at most {self.max_length} characters", value)
        if self.pattern is not None and not re.fullmatch(self.pattern, value):
            raise _wrong(f"String should match pattern '^{self.pattern}$'", value)
        return value


class OneOf:
    """One of the given strings."""

    def __init__(self, *choices):
        self.choices = choices

    def __call__(self, value):
        if not isinstance(value, str) or value not in self.choices:
            quoted = [repr(choice) for choice in self.choices]
            listed = quoted[0] if len(quoted) == 1 else f"{', '.join(quoted[:-1])} or {quoted[-1]}"
            raise _wrong(f"Input should be {listed}", value)
        return value


def _items(count):
    return f"{count} item{'' if count == 1 else 's'}"


class ListOf:
    """A list whose items each pass ``item``, of ``min_length`` to ``max_length`` items."""

    def __init__(self, item, min_length=None, max_length=None):
        self.item, self.min_length, self.max_length = item, min_length, max_length

    def __call__(self, value):
        if not isinstance(value, list):
            raise _wrong("Input should be a valid list", value)
        checked = [_at(i, self.item, item) for i, item in enumerate(value)]
        if self.min_length is not None and len(checked) < self.min_length:
            raise _wrong(f"List should have at least {_items(self.min_length)} after validation, not {len(checked)}",
                         value)
        if self.max_length is not None and len(checked) > self.max_length:
            raise _wrong(f"List should have at most {_items(self.max_length)} after validation, not {len(checked)}",
                         value)
        return checked


class TableOf:
    """A table (``{name = value}``) whose values each pass ``value``."""

    def __init__(self, value):
        self.value = value

    def __call__(self, table):
        if not isinstance(table, dict):
            raise _wrong("Input should be a valid dictionary", table)
        return {key: _at(key, self.value, item) for key, item in table.items()}


class Table:
    """A nested record: a table read by :func:`record`; ``shorthand`` may first turn another form into a table."""

    def __init__(self, cls, shorthand=None):
        self.cls, self.shorthand = cls, shorthand

    def __call__(self, value):
        return record(self.cls, self.shorthand(value) if self.shorthand else value)


class Checked:
    """``then(check(value))``: a further rule (raising InputError) on a value that passed ``check``."""

    def __init__(self, check, then):
        self.check, self.then = check, then

    def __call__(self, value):
        return self.then(self.check(value))


_REQUIRED = dataclasses.MISSING


def rule(check, default=_REQUIRED):
    """A record field checked by ``check``; without ``default`` the key is required (lists and tables are copied)."""
    metadata = {"check": check}
    if isinstance(default, (list, dict)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def record(cls, table):
    """The record ``cls`` from a TOML table; :class:`Invalid` at the first problem (see the module docstring)."""
    if not isinstance(table, dict):
        raise _wrong(f"Input should be a valid dictionary or instance of {cls.__name__}", table)
    fields = dataclasses.fields(cls)
    known = [f.name for f in fields]
    unknown = [key for key in table if key not in known]
    if unknown:
        raise Invalid(f"unknown key {shown(unknown[0])} (allowed: {', '.join(known)})")
    values = {}
    for f in fields:
        if f.name in table:
            values[f.name] = _at(f.name, f.metadata["check"], table[f.name])
        elif f.default is _REQUIRED and f.default_factory is _REQUIRED:
            raise Invalid("Field required", [f.name])
    try:
        return cls(**values)
    except Invalid:
        raise
    except InputError as error:  # a rule between fields: the problem is the record's
        raise Invalid(str(error)) from None
