"""Typed stage results (:mod:`mbn.experiments.pipeline.results`): written in field order, read
back checked, keys that are not Python names, fields written only when set, and a record's
fields picked out of a larger object."""

from __future__ import annotations

import json
from dataclasses import dataclass

import pytest

from mbn.errors import MbnInputError
from mbn.experiments.pipeline.results import Record, keyed, optional


@dataclass(frozen=True, kw_only=True)
class Inner(Record):
    trials: int
    rate: float


@dataclass(frozen=True, kw_only=True)
class Outer(Record):
    name: str
    passed: bool = keyed("pass")
    floor_error: float = keyed("max_rel_error_ge_0.05")
    inner: Inner
    table: dict[str, Inner]
    rows: list[Inner]
    note: str | None = optional()


def _outer(**kw) -> Outer:
    base = dict(
        name="a",
        passed=True,
        floor_error=0.5,
        inner=Inner(trials=3, rate=1),
        table={"x": Inner(trials=1, rate=0.5)},
        rows=[Inner(trials=2, rate=0.25)],
    )
    return Outer(**{**base, **kw})


def test_a_record_is_written_in_field_order_under_its_keys_and_read_back_equal():
    rec = _outer()
    data = rec.to_json()
    assert list(data) == ["name", "pass", "max_rel_error_ge_0.05", "inner", "table", "rows"]
    assert data["inner"] == {"trials": 3, "rate": 1}  # a 1 stays the 1 it was
    text = json.dumps(data)
    back = Outer.from_json(json.loads(text))
    assert back == rec and json.dumps(back.to_json()) == text
    assert isinstance(back.table["x"], Inner) and isinstance(back.rows[0], Inner)


def test_an_optional_field_is_written_only_while_set():
    assert "note" not in _outer().to_json()
    assert _outer(note="n").to_json()["note"] == "n"
    assert Outer.from_json(_outer().to_json()).note is None


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("pass"), r"where: no 'pass' \(a Outer needs it\)"),
        (lambda d: d.update(extra=1), r"where: unknown key 'extra' for a Outer"),
        (lambda d: d["inner"].update(trials="3"), r"where\.inner\.trials: expected a number"),
        (lambda d: d.update(rows={}), r"where\.rows: expected a list"),
        (
            lambda d: d.update(passed=True),
            r"unknown key 'passed'",
        ),  # the field's name is not its key
    ],
)
def test_a_file_that_is_not_the_record_is_refused_in_one_line_naming_the_key(change, message):
    data = _outer().to_json()
    change(data)
    with pytest.raises(MbnInputError, match=message):
        Outer.from_json(data, "where")


def test_pick_reads_the_record_s_fields_out_of_a_larger_object():
    larger = {"trials": 10, "rate": 0.9, "successes": 9, "timed_out": 0}
    assert Inner.pick(larger) == Inner(trials=10, rate=0.9)
    with pytest.raises(MbnInputError, match="no 'rate'"):
        Inner.pick({"trials": 10, "successes": 9})
