"""Junction rules: priority orders over the exits right, straight and left.

A rule takes, at a junction, the first of its three exits that is open, else it turns back. The
paper's two rules are wall followers: the **right** rule is right > straight > left (the
right-hand rule), the **left** rule left > straight > right. Any of the six orders is a rule;
four more have names here:

========================  ==========================
name                      order
========================  ==========================
``right``                 right > straight > left
``left``                  left > straight > right
``straight-right``        straight > right > left
``straight-left``         straight > left > right
``right-left``            right > left > straight
``left-right``            left > right > straight
========================  ==========================

A rule is written by its name or by its order: the three exits' initials in priority order
(``"SRL"``), or the exits joined by ``>`` (``"straight>right>left"``, ``"S>R>L"``), in any case.
:func:`parse_rule` gives the :class:`Rule`; its :attr:`Rule.name` is the name above.

Junction exits are coded as in :mod:`mbn.world.junctions` (0 back, 1 right, 2 straight,
3 left); the rollout records at each junction pass which exits were open
(:data:`OPEN_BITS`), and :func:`rule_exit_codes` gives any rule's exit from that record.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mbn.errors import MbnInputError

__all__ = [
    "NAMED_RULES",
    "OPEN_BITS",
    "RULE_EXITS",
    "Rule",
    "all_rules",
    "open_mask",
    "parse_rule",
    "parse_rules",
    "rule_exit_codes",
]

#: The exits a rule orders.
RULE_EXITS = ("right", "straight", "left")
#: Exit codes (:data:`mbn.world.junctions.EXIT_CODES`) of the exits a rule orders.
_CODE = {"back": 0, "right": 1, "straight": 2, "left": 3}
#: Bit of each exit in an open-exit mask (bit ``code``: 1 back, 2 right, 4 straight, 8 left).
OPEN_BITS = {name: 1 << code for name, code in _CODE.items()}
_INITIAL = {"R": "right", "S": "straight", "L": "left"}

#: The rules with names, by priority order.
NAMED_RULES: dict[str, tuple[str, str, str]] = {
    "right": ("right", "straight", "left"),
    "left": ("left", "straight", "right"),
    "straight-right": ("straight", "right", "left"),
    "straight-left": ("straight", "left", "right"),
    "right-left": ("right", "left", "straight"),
    "left-right": ("left", "right", "straight"),
}
_NAME_OF = {order: name for name, order in NAMED_RULES.items()}


@dataclass(frozen=True)
class Rule:
    """A junction rule: ``order``, the three exits right, straight, left in priority order."""

    order: tuple[str, str, str]

    def __post_init__(self) -> None:
        if tuple(sorted(self.order)) != tuple(sorted(RULE_EXITS)):
            raise MbnInputError(
                f"a rule orders the exits right, straight and left, each once; got {self.order!r}"
            )

    @property
    def name(self) -> str:
        """The rule's name (:data:`NAMED_RULES`)."""
        return _NAME_OF[self.order]

    @property
    def initials(self) -> str:
        """The order as the exits' initials, e.g. ``"RSL"``."""
        return "".join(e[0].upper() for e in self.order)

    def exit(self, open_exits: set[str] | frozenset[str]) -> str:
        """The exit this rule takes when ``open_exits`` (names) are open: the first open one of
        its order, else ``"back"``."""
        return next((e for e in self.order if e in open_exits), "back")

    def __str__(self) -> str:
        return self.name


def parse_rule(text: str | Rule) -> Rule:
    """The :class:`Rule` named or written by ``text`` (see the module docstring), or one clear
    error naming it."""
    if isinstance(text, Rule):
        return text
    if not isinstance(text, str):
        raise MbnInputError(f"a rule is a name or an order such as 'SRL', got {text!r}")
    key = text.strip().lower()
    if key in NAMED_RULES:
        return Rule(NAMED_RULES[key])
    parts = [p.strip() for p in key.split(">")] if ">" in key else list(key.upper())
    words = [_INITIAL.get(p.upper(), p) if len(p) == 1 else p for p in parts]
    if len(words) == 3 and sorted(words) == sorted(RULE_EXITS):
        return Rule((words[0], words[1], words[2]))
    raise MbnInputError(
        f"unknown rule {text!r}: a name ({', '.join(NAMED_RULES)}) or an order of the exits "
        "right, straight and left, each once (e.g. 'SRL' or 'straight>right>left')"
    )


def parse_rules(texts: Sequence[str | Rule], where: str) -> list[str]:
    """The names of the rules ``texts`` (:func:`parse_rule`), in order; a text that names no rule
    is one error prefixed with ``where`` (e.g. ``"contest.rules"``)."""
    names = []
    for text in texts:
        try:
            names.append(parse_rule(text).name)
        except MbnInputError as exc:
            raise MbnInputError(f"{where}: {exc}") from None
    return names


def all_rules() -> tuple[Rule, ...]:
    """The six rules, named ones in the order of :data:`NAMED_RULES`."""
    rules = tuple(Rule(order) for order in NAMED_RULES.values())
    assert len(rules) == len(set(itertools.permutations(RULE_EXITS)))
    return rules


def open_mask(open_exits: set[str] | frozenset[str] | list[str]) -> int:
    """The open-exit mask (:data:`OPEN_BITS`) of the exits named."""
    return sum(OPEN_BITS[e] for e in set(open_exits))


def rule_exit_codes(rule: str | Rule, mask: Any) -> Any:
    """The exit code (0 back, 1 right, 2 straight, 3 left) ``rule`` takes at junctions whose
    open exits are ``mask`` (an array of :data:`OPEN_BITS` masks; -1 where there is no
    junction, which stays -1): a NumPy array, or a JAX one for a JAX array (traced too)."""
    r = parse_rule(rule)
    import jax

    # NumPy for host arrays; jax.numpy for device or traced ones (a compiled fitness)
    xp: Any = np
    m = mask
    if isinstance(mask, jax.Array):
        import jax.numpy as xp
    else:
        m = np.asarray(mask)
    out = xp.zeros(m.shape, xp.int32)  # back
    done = xp.zeros(m.shape, bool)
    for e in r.order:
        take = ~done & ((m & OPEN_BITS[e]) != 0)
        out = xp.where(take, _CODE[e], out)
        done = done | take
    return xp.where(m < 0, -1, out)
