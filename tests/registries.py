"""What a test registers from outside ``mbn`` (maze families, rules, fitnesses, maze formats)
stays in that test: :func:`isolate` gives each registry a copy that ``monkeypatch`` puts back
afterwards, so that a name registered in one test is unknown to the next."""

from __future__ import annotations

import pytest


def isolate(monkeypatch: pytest.MonkeyPatch) -> None:
    """Copy every registry of ``mbn`` for the test (restored when it ends)."""
    from mbn.experiments import crossroads, maze_task
    from mbn.world import rules
    from mbn.world.mazes import families, load

    for module, names in (
        (families, ("FAMILIES", "ZERO_SHOT", "_FAMILY_SALT")),
        (rules, ("_REGISTERED",)),
        (crossroads, ("_FITNESSES", "_RULE_FITNESS")),
        (maze_task, ("_FITNESSES", "_RULE_FITNESS")),
        (load, ("_FORMATS",)),
    ):
        for name in names:
            monkeypatch.setattr(module, name, dict(getattr(module, name)))
