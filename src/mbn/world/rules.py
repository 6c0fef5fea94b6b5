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

**A rule of your own** (:func:`register_rule`) is any choice of exit for every junction's open
exits, priority order or not, and may turn back (``"u-turn"``: back at every junction). It is
registered by name from outside ``mbn`` and is then a rule wherever one is named: the tasks
reward it, the judge judges it, a family's starts are checked under it, a stage learns it::

    register_rule("u-turn", lambda open_exits: "back")

Its exit is asked for every set of open exits a junction has (``{"right"}`` or ``{"left"}`` at a
corner, two or three exits at a T or plus crossing); a corridor is not a junction (straight), a
dead end turns back.

Junction exits are coded as in :mod:`mbn.world.junctions` (0 back, 1 right, 2 straight,
3 left); the rollout records at each junction pass which exits were open
(:data:`OPEN_BITS`), and :func:`rule_exit_codes` gives any rule's exit from that record.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Sequence
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
    "register_rule",
    "rule_exit_codes",
    "rule_names",
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
_NAME_OF: dict[tuple[str, ...], str] = {order: name for name, order in NAMED_RULES.items()}


#: Names a rule may not take: the MBN's behaviour and the "no initial rule" of a trial.
_RESERVED = ("tiles", "none")
_RULE_NAME = re.compile(r"^[a-z][a-z0-9]*(-[a-z0-9]+)*$")
#: The exits a junction can have open (every subset of :data:`RULE_EXITS` but the corridor's
#: ``{"straight"}`` and the dead end's ``{}``), which a registered rule chooses among.
_JUNCTION_OPENINGS: tuple[frozenset[str], ...] = tuple(
    frozenset(e for k, e in enumerate(RULE_EXITS) if index >> k & 1)
    for index in range(8)
    if index not in (0, 2)
)


def _index(open_exits: set[str] | frozenset[str]) -> int:
    """The row of a rule's table for ``open_exits``: bit k for exit ``RULE_EXITS[k]`` (the
    :data:`OPEN_BITS` mask shifted right once, back left out)."""
    return sum(1 << k for k, e in enumerate(RULE_EXITS) if e in open_exits)


@dataclass(frozen=True)
class Rule:
    """A junction rule: ``order``, the three exits right, straight, left in priority order; or,
    for a rule registered by name (:func:`register_rule`), ``table``, the exit it takes for
    each set of open exits (row :func:`_index`, 8 rows), and its name ``label``."""

    order: tuple[str, ...]
    table: tuple[str, ...] = ()
    label: str = ""

    def __post_init__(self) -> None:
        if self.table:
            if self.order or len(self.table) != 8 or not self.label:
                raise MbnInputError(
                    "a registered rule has a name and an exit for each of the 8 sets of open "
                    "exits, and no order"
                )
            return
        if tuple(sorted(self.order)) != tuple(sorted(RULE_EXITS)):
            raise MbnInputError(
                f"a rule orders the exits right, straight and left, each once; got {self.order!r}"
            )

    @property
    def name(self) -> str:
        """The rule's name (:data:`NAMED_RULES`, or the name it was registered under)."""
        return self.label if self.table else _NAME_OF[self.order]

    @property
    def initials(self) -> str:
        """The order as the exits' initials, e.g. ``"RSL"`` (a priority order's only)."""
        if self.table:
            raise MbnInputError(f"rule {self.label!r} is not a priority order of the exits")
        return "".join(e[0].upper() for e in self.order)

    def exit(self, open_exits: set[str] | frozenset[str]) -> str:
        """The exit this rule takes when ``open_exits`` (names) are open: the first open one of
        its order, else ``"back"`` (a registered rule: its table's)."""
        if self.table:
            return self.table[_index(open_exits)]
        return next((e for e in self.order if e in open_exits), "back")

    def __str__(self) -> str:
        return self.name


#: The rules registered by name (:func:`register_rule`), in the order of registration.
_REGISTERED: dict[str, Rule] = {}


def rule_names() -> tuple[str, ...]:
    """Every rule's name: :data:`NAMED_RULES`, then the registered ones (:func:`register_rule`)."""
    return (*NAMED_RULES, *_REGISTERED)


def register_rule(name: str, exits: Callable[[frozenset[str]], str]) -> Rule:
    """Register a junction rule of your own under ``name`` (lower-case words joined by ``-``):
    ``exits(open_exits)`` is the exit (``"right"``, ``"straight"``, ``"left"`` or ``"back"``) it
    takes at a junction whose open exits are ``open_exits`` (a frozenset of ``"right"``,
    ``"straight"``, ``"left"``; asked once for each set a junction can have). After it,
    :func:`parse_rule` gives the rule for ``name`` anywhere a rule is named. Registering the
    same name with the same exits again is allowed (a module imported twice); a name taken, an
    exit that is not open, or the exits of a rule that exists already are refused in one line."""
    where = f"register_rule({name!r})"
    if not isinstance(name, str) or not _RULE_NAME.match(name):
        raise MbnInputError(f"{where}: a rule's name is lower-case words joined by '-' (u-turn)")
    if not callable(exits):
        raise MbnInputError(f"{where}: exits must be a function of the open exits")
    table = ["back"] * 8
    table[_index({"straight"})] = "straight"  # a corridor: no junction
    for opened in _JUNCTION_OPENINGS:
        try:
            chosen = exits(opened)
        except Exception as exc:  # the user's function: say where it failed
            raise MbnInputError(f"{where}: exits({set(opened)}) failed: {exc!r}") from None
        if chosen not in (*opened, "back"):
            raise MbnInputError(
                f"{where}: with {', '.join(sorted(opened))} open, exits gave {chosen!r}: an open "
                "exit or 'back'"
            )
        table[_index(opened)] = chosen
    rule = Rule((), tuple(table), name)
    held = _REGISTERED.get(name)
    if held is not None:
        if held.table != rule.table:
            raise MbnInputError(f"{where}: a rule of that name is registered already")
        return held
    if name in NAMED_RULES or name in _RESERVED or _order_of(name) is not None:
        raise MbnInputError(f"{where}: {name!r} names a rule of mbn's already")
    for other in (*all_rules(), *_REGISTERED.values()):
        if all(other.exit(o) == rule.exit(o) for o in _JUNCTION_OPENINGS):
            raise MbnInputError(
                f"{where}: it takes the exits of the rule {other.name!r} at every junction "
                f"(name that one)"
            )
    _REGISTERED[name] = rule
    return rule


def _order_of(key: str) -> tuple[str, str, str] | None:
    """The priority order ``key`` writes (``"srl"``, ``"s>r>l"``), or None."""
    parts = [p.strip() for p in key.split(">")] if ">" in key else list(key.upper())
    words = [_INITIAL.get(p.upper(), p) if len(p) == 1 else p for p in parts]
    if len(words) == 3 and sorted(words) == sorted(RULE_EXITS):
        return (words[0], words[1], words[2])
    return None


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
    if key in _REGISTERED:
        return _REGISTERED[key]
    order = _order_of(key)
    if order is not None:
        return Rule(order)
    raise MbnInputError(
        f"unknown rule {text!r}: a name ({', '.join(rule_names())}) or an order of the exits "
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
    if r.table:  # a registered rule: its table, row by the open exits (back's bit left out)
        codes = xp.asarray([_CODE[e] for e in r.table], xp.int32)
        return xp.where(m < 0, -1, codes[(m >> 1) & 7])
    out = xp.zeros(m.shape, xp.int32)  # back
    done = xp.zeros(m.shape, bool)
    for e in r.order:
        take = ~done & ((m & OPEN_BITS[e]) != 0)
        out = xp.where(take, _CODE[e], out)
        done = done | take
    return xp.where(m < 0, -1, out)
