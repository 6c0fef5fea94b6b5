"""Junction rules: names, orders, parsing, and the exit each takes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.junctions import rule_exit
from mbn.world.mazes.builtin import crossroad
from mbn.world.rules import (
    NAMED_RULES,
    OPEN_BITS,
    Rule,
    all_rules,
    open_mask,
    parse_rule,
    rule_exit_codes,
)


def test_the_six_orders_have_names_and_parse_from_names_initials_and_arrows():
    assert len(all_rules()) == 6
    assert {r.order for r in all_rules()} == set(
        itertools.permutations(("right", "straight", "left"))
    )
    assert parse_rule("right").order == ("right", "straight", "left")
    assert parse_rule("left").order == ("left", "straight", "right")
    assert parse_rule("straight-right").order == ("straight", "right", "left")
    assert parse_rule("straight-left").order == ("straight", "left", "right")
    for rule in all_rules():
        for text in (
            rule.name,
            rule.initials,
            rule.initials.lower(),
            ">".join(rule.order),
            " > ".join(c for c in rule.initials),
        ):
            assert parse_rule(text) == rule, text
    assert parse_rule("RSL").name == "right" and parse_rule("lsr").name == "left"
    assert parse_rule(parse_rule("SRL")) == parse_rule("straight-right")
    assert set(NAMED_RULES) == {r.name for r in all_rules()}


@pytest.mark.parametrize("text", ["RRL", "RS", "up", "right>left", "R>S>L>B", "", "straight-up"])
def test_a_bad_rule_is_one_clear_error(text):
    with pytest.raises(MbnInputError, match="rule"):
        parse_rule(text)
    with pytest.raises(MbnInputError, match="each once"):
        Rule(("right", "right", "left"))


def test_each_rule_takes_the_first_open_exit_of_its_order_else_back():
    exits = ("right", "straight", "left")
    for rule in all_rules():
        for k in range(4):
            for open_set in itertools.combinations(exits, k):
                want = next((e for e in rule.order if e in open_set), "back")
                assert rule.exit(set(open_set)) == want
                code = rule_exit_codes(rule, np.array([open_mask(open_set)]))[0]
                assert code == {"back": 0, "right": 1, "straight": 2, "left": 3}[want]
    assert rule_exit_codes("left", np.array([-1, OPEN_BITS["left"]])).tolist() == [-1, 3]


def test_rule_exit_in_a_maze_for_every_rule():
    # entering the junction of a T with left and right open (LR), and of a plus (LSR)
    tee, plus = crossroad("LR"), crossroad("LSR")
    for rule in all_rules():
        assert rule_exit(plus, (3, 3), "N", rule.name) == rule.order[0]
        want = next(e for e in rule.order if e != "straight")
        assert rule_exit(tee, (3, 3), "N", rule.initials) == want
    with pytest.raises(MbnInputError, match="unknown rule"):
        rule_exit(plus, (3, 3), "N", "upward")


def test_parse_rules_names_each_rule_and_says_where_one_is_wrong():
    from mbn.world.rules import parse_rules

    assert parse_rules(["SRL", "straight-left", "right"], "x.rules") == [
        "straight-right",
        "straight-left",
        "right",
    ]
    with pytest.raises(MbnInputError, match=r"^x\.rules: unknown rule 'SSS'"):
        parse_rules(["right", "SSS"], "x.rules")
