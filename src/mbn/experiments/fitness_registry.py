"""The one way a task's fitnesses are registered by name (:func:`add_fitness`): the crossroad
task's (:func:`mbn.experiments.crossroads.register_fitness`) and the maze task's
(:func:`mbn.experiments.maze_task.register_fitness`) each keep their own tables and call it."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

from mbn.errors import MbnInputError
from mbn.world.rules import parse_rules

__all__ = ["add_fitness"]

_NAME = re.compile(r"^[a-z][a-z0-9]*(-[a-z0-9]+)*$")


def add_fitness(
    fitnesses: dict[str, Any],
    rule_fitness: dict[str, str],
    name: str,
    fitness: Callable[..., Any],
    rules: Sequence[str],
    arguments: str,
) -> None:
    """Register ``fitness`` under ``name`` (lower-case words joined by ``-``) in ``fitnesses``,
    and as the fitness of ``rules`` in ``rule_fitness``. A name or a rule's fitness registered
    already is refused in one line (the same function again is allowed: a module imported
    twice); ``arguments`` names what the function takes, for the error of one that is not."""
    where = f"register_fitness({name!r})"
    if not isinstance(name, str) or not _NAME.match(name):
        raise MbnInputError(f"{where}: a fitness's name is lower-case words joined by '-'")
    if not callable(fitness):
        raise MbnInputError(f"{where}: the fitness must be a function ({arguments})")
    if name in fitnesses and fitnesses[name] is not fitness:
        raise MbnInputError(f"{where}: a fitness of that name is registered already")
    names = parse_rules(rules, f"{where}: rules")
    for rule in names:
        if rule_fitness.get(rule, name) != name:
            raise MbnInputError(
                f"{where}: the rule {rule!r} has the fitness {rule_fitness[rule]!r} already"
            )
    fitnesses[name] = fitness
    rule_fitness.update(dict.fromkeys(names, name))
