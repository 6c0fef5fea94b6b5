"""The ``--seeds`` syntax."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mbn.errors import MbnInputError
from mbn.experiments.sweep.seeds import MAX_SEEDS, format_seeds, parse_seeds


@pytest.mark.parametrize(
    ("text", "seeds"),
    [
        ("0-9", tuple(range(10))),
        ("3", (3,)),
        ("0,2,5-7", (0, 2, 5, 6, 7)),
        (" 4 , 1-2 ", (4, 1, 2)),
        ("2,2,1-3", (2, 1, 3)),
        ("0-999", tuple(range(1000))),
        ("4294967295", (2**32 - 1,)),
    ],
)
def test_seeds_parse(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("5-2", "runs backwards"),
        ("a-b", "not a seed or a range"),
        ("", "empty"),
        ("  ", "empty"),
        ("1,,2", "empty part"),
        ("-1", "seeds are >= 0"),
        ("-3-4", "seeds are >= 0"),
        ("0-1000", f"more than {MAX_SEEDS} seeds"),
        ("0-500,600-1200", f"more than {MAX_SEEDS} seeds"),
        ("4294967296", "not below 2**32"),
        ("1.5", "not a seed"),
    ],
)
def test_bad_seeds_are_one_line_naming_the_fault(text, says):
    with pytest.raises(MbnInputError) as err:
        parse_seeds(text)
    assert says in str(err.value)
    assert "\n" not in str(err.value)


@given(st.lists(st.integers(0, 5000), min_size=1, max_size=60, unique=True))
def test_format_then_parse_is_the_sorted_set(seeds):
    ordered = sorted(seeds)
    text = format_seeds(ordered)
    assert parse_seeds(text) == tuple(ordered)
    assert len(text.split(",")) <= len(ordered)


@given(st.integers(0, 10**6), st.integers(0, 999))
def test_a_range_holds_every_seed_from_low_to_high(low, width):
    assert parse_seeds(f"{low}-{low + width}") == tuple(range(low, low + width + 1))
