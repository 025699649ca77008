"""dfwb.base.schema: strict rules, the path of the first bad value, records that cannot change."""

import dataclasses
import datetime
from typing import Optional

import pytest

from dfwb.base import schema
from dfwb.base.errors import InputError
from dfwb.base.schema import Invalid, record, rule


def _positive_sum(values):
    if sum(values) <= 0:
        raise InputError("the sum must be positive")
    return values


@dataclasses.dataclass(frozen=True, kw_only=True)
class Inner:
    level: float = rule(schema.Number(ge=0, le=1e9))
    names: list = rule(schema.ListOf(schema.Text()), [])


@dataclasses.dataclass(frozen=True, kw_only=True)
class Outer:
    title: str = rule(schema.Text(pattern=r"[a-z]+", max_length=8))
    count: int = rule(schema.Integer(ge=2, le=10), 3)
    mode: str = rule(schema.OneOf("fast", "exact", "slow"), "exact")
    on: bool = rule(schema.Boolean(), False)
    gains: dict = rule(schema.TableOf(schema.ListOf(schema.Number(gt=0), min_length=1, max_length=2)), {})
    inner: Optional[Inner] = rule(schema.Table(Inner, shorthand=lambda v: {"level": v} if isinstance(v, (int, float)) else v),
                                  None)
    items: list = rule(schema.ListOf(schema.Table(Inner)), [])
    weights: list = rule(schema.Checked(schema.ListOf(schema.Number()), _positive_sum), [1.0])

    def __post_init__(self):
        if self.on and self.inner is None:
            raise InputError("on = true needs an inner table")


def problem(table, cls=Outer):
    """'where: message' of the Invalid that record raises."""
    with pytest.raises(Invalid) as error:
        record(cls, table)
    return f"{error.value.where}: {error.value}"


def test_a_good_table_gives_typed_values_and_defaults():
    built = record(Outer, {"title": "abc", "gains": {"k": [1, 2.5]}, "inner": {"level": 3}, "items": [{"level": 0}]})
    assert built == Outer(title="abc", count=3, mode="exact", on=False, gains={"k": [1.0, 2.5]},
                          inner=Inner(level=3.0, names=[]), items=[Inner(level=0.0, names=[])], weights=[1.0])
    assert type(built.inner.level) is float and type(built.gains["k"][0]) is float
    assert record(Outer, {"title": "a", "inner": 7}).inner == Inner(level=7.0)  # the shorthand


def test_defaults_are_not_shared_and_records_are_frozen():
    first, second = record(Inner, {"level": 1}), record(Inner, {"level": 2})
    first.names.append("x")
    assert second.names == [] and record(Outer, {"title": "a"}).weights == [1.0]
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.level = 5.0


@pytest.mark.parametrize("table, message", [
    ({"title": 5}, "title: Input should be a valid string (got 5)"),
    ({"title": "a1"}, "title: String should match pattern '^[a-z]+$' (got 'a1')"),
    ({"title": "abcdefghi"}, "title: String should have at most 8 characters (got 'abcdefghi')"),
    ({}, "title: Field required"),
    ({"title": "a", "cuont": 3}, ": unknown key 'cuont' (allowed: title, count, mode, on, gains, inner, items, weights)"),
    ({"title": "a", "count": 2.0}, "count: Input should be a valid integer (got 2.0)"),
    ({"title": "a", "count": True}, "count: Input should be a valid integer (got True)"),
    ({"title": "a", "count": 11}, "count: Input should be less than or equal to 10 (got 11)"),
    ({"title": "a", "mode": "quick"}, "mode: Input should be 'fast', 'exact' or 'slow' (got 'quick')"),
    ({"title": "a", "on": 1}, "on: Input should be a valid boolean (got 1)"),
    ({"title": "a", "on": True}, ": on = true needs an inner table"),
    ({"title": "a", "gains": []}, "gains: Input should be a valid dictionary (got [])"),
    ({"title": "a", "gains": {"k": []}}, "gains.k: List should have at least 1 item after validation, not 0 (got [])"),
    ({"title": "a", "gains": {"k": [1, 2, 3]}}, "gains.k: List should have at most 2 items after validation, not 3"),
    ({"title": "a", "gains": {"k": [1, 0]}}, "gains.k[1]: Input should be greater than 0 (got 0)"),
    ({"title": "a", "gains": {"k": [True]}}, "gains.k[0]: Input should be a valid number (got True)"),
    ({"title": "a", "gains": {"k": ["1"]}}, "gains.k[0]: Input should be a valid number (got '1')"),
    ({"title": "a", "gains": {"k": [float("nan")]}}, "gains.k[0]: Input should be a finite number (got nan)"),
    ({"title": "a", "gains": {"k": [float("inf")]}}, "gains.k[0]: Input should be a finite number (got inf)"),
    ({"title": "a", "inner": "x"}, "inner: Input should be a valid dictionary or instance of Inner (got 'x')"),
    ({"title": "a", "inner": -1}, "inner.level: Input should be greater than or equal to 0 (got -1)"),
    ({"title": "a", "inner": 2e9}, "inner.level: Input should be less than or equal to 1000000000 (got 2000000000.0)"),
    ({"title": "a", "items": [{"level": 1}, {"level": 1, "names": ["a", 3]}]},
     "items[1].names[1]: Input should be a valid string (got 3)"),
    ({"title": "a", "items": [{"level": 1}, {}]}, "items[1].level: Field required"),
    ({"title": "a", "weights": [1, -2]}, "weights: the sum must be positive"),
    ({"title": "a", "weights": [datetime.date(2000, 1, 1)]},
     "weights[0]: Input should be a valid number (got datetime.date(2000, 1, 1))"),
])
def test_the_first_problem_is_one_message_at_its_path(table, message):
    assert problem(table).startswith(message), problem(table)


def test_fields_are_checked_in_their_declared_order():
    assert problem({"title": 1, "count": 0, "mode": 2}).startswith("title:")
    assert problem({"title": "a", "count": 0, "mode": 2}).startswith("count:")


def test_bounds_read_without_exponents():
    assert problem({"level": -1}, Inner).startswith("level: Input should be greater than or equal to 0 ")
    tiny = dataclasses.make_dataclass("Tiny", [("x", float, rule(schema.Number(ge=1e-6, le=1e-4)))], frozen=True, kw_only=True)
    assert problem({"x": 0}, tiny) == "x: Input should be greater than or equal to 0.000001 (got 0)"
    assert problem({"x": 1}, tiny) == "x: Input should be less than or equal to 0.0001 (got 1)"


def test_a_long_value_is_shown_by_its_start_only():
    message = problem({"title": "a" * 100_000})
    assert len(message) < 200 and message.endswith("...)"), message
    assert len(problem({"title": "a", "inner": ["x"] * 10_000})) < 200


def test_not_a_table_at_the_top():
    assert problem(["title"]) == ": Input should be a valid dictionary or instance of Outer (got ['title'])"
