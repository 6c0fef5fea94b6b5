"""mbn.io: strict JSON out, readers that name the file and line, writers that refuse early."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.io import (
    atomic_open,
    check_writable,
    json_text,
    read_csv_columns,
    read_json,
    read_text,
)


def test_json_text_is_strict_json_with_null_for_values_that_are_not_finite():
    text = json_text({"a": math.nan, "b": [1.0, math.inf, np.float32(2.5)], "c": np.int64(3)})
    assert json.loads(text) == {"a": None, "b": [1.0, None, 2.5], "c": 3}
    assert "NaN" not in text and "Infinity" not in text


def test_read_text_names_the_line_of_a_byte_that_is_not_utf8(tmp_path):
    path = tmp_path / "f.txt"
    path.write_bytes(b"ok\nok\nbad \xff here\n")
    with pytest.raises(MbnInputError, match=r"f\.txt:3: not UTF-8 text \(byte 10\)"):
        read_text(path)


def test_read_json_refuses_deep_nesting_and_names_the_line_of_a_syntax_error(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(MbnInputError, match="nested too deeply"):
        read_json(deep)
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "a": 1,\n  "b": }\n')
    with pytest.raises(MbnInputError, match=r"bad\.json:3: invalid JSON"):
        read_json(bad)


def test_a_csv_field_over_the_limit_is_one_short_line(tmp_path):
    path = tmp_path / "big.csv"
    path.write_text("x1,x2\n" + "9" * 200_000 + ",1\n")
    with pytest.raises(MbnInputError) as exc:
        read_csv_columns(path, ["x1", "x2"])
    assert "big.csv:2: invalid CSV (field larger than field limit" in str(exc.value)
    assert len(str(exc.value)) < 300


def test_check_writable_refuses_early_and_leaves_nothing(tmp_path):
    assert check_writable(tmp_path / "out.json") == tmp_path / "out.json"
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(MbnInputError, match="is a folder, not a file"):
        check_writable(tmp_path)
    with pytest.raises(MbnInputError, match="does not exist"):
        check_writable(tmp_path / "no" / "out.json")
    with pytest.raises(MbnInputError, match=r"/proc/mbn\.json: cannot write"):
        check_writable("/proc/mbn.json")


def test_atomic_open_turns_a_system_error_into_one_line_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "f.txt"
    path.write_text("old")
    with pytest.raises(MbnInputError, match="is a folder"), atomic_open(tmp_path):
        pass
    with pytest.raises(MbnInputError, match=r"f\.txt: cannot write"), atomic_open(path) as h:
        h.write("new")
        raise OSError(28, "No space left on device")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["f.txt"]
