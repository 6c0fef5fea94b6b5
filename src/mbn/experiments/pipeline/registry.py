"""Stages and the registry that lists them in order.

A stage is one step of an experiment: it has a ``name``, a fixed ``key_id`` (the number folded into
the run's key to give the stage its random stream: adding a stage never moves another's key), the
stages whose outputs it reads (``needs``, checked by the runner), an optional settings class (its
section of the run's config), ``run(ctx) -> data`` (writing through ``ctx.rundir``) and a one-line
``summary(data)``. ``metrics(data)`` is what ``results.json`` keeps of its data (by default all of
it but the bulky ``details``).
"""

from __future__ import annotations

import abc
from collections.abc import Iterator, Sequence
from typing import Any, ClassVar

from mbn.config import Settings
from mbn.experiments.pipeline.context import StageContext

__all__ = ["Registry", "Stage"]


class Stage(abc.ABC):
    """Base of the stages: set the class attributes, implement :meth:`run` and :meth:`summary`.

    Attributes:
        name: the stage's name (its file ``stages/NAME.json``, its section of the config).
        key_id: fixed number of its random stream (``fold_in(run key, key_id)``).
        needs: names of the stages whose outputs it reads.
        settings: its settings class (a :class:`~mbn.config.Settings` with ``section == name``),
            or None.
        outputs: files it writes (relative to the run folder) that later stages or the report
            read: a finished stage whose output is missing is run again.
    """

    name: ClassVar[str] = ""
    key_id: ClassVar[int] = 0
    needs: ClassVar[tuple[str, ...]] = ()
    settings: ClassVar[type[Settings] | None] = None
    outputs: ClassVar[tuple[str, ...]] = ()

    @abc.abstractmethod
    def run(self, ctx: StageContext) -> dict[str, Any]:
        """Do the stage's work (writing through ``ctx.rundir``); return its data (JSON)."""

    def summary(self, data: dict[str, Any]) -> str:
        return "done"

    def metrics(self, data: dict[str, Any]) -> dict[str, Any]:
        """What ``results.json`` keeps of the stage's data."""
        return {k: v for k, v in data.items() if k != "details"}


class Registry:
    """Stages in the order they run, checked on construction: unique names and key numbers,
    ``needs`` naming earlier stages, settings sections named after their stage."""

    def __init__(self, stages: Sequence[Stage]) -> None:
        names: list[str] = []
        keys: set[int] = set()
        for stage in stages:
            if not stage.name or stage.name in names:
                raise ValueError(f"stage name {stage.name!r} is empty or used twice")
            if stage.key_id < 1 or stage.key_id in keys:
                raise ValueError(f"stage {stage.name}: key_id {stage.key_id} is < 1 or used twice")
            missing = [n for n in stage.needs if n not in names]
            if missing:
                raise ValueError(f"stage {stage.name} needs {missing}, which do not run before it")
            if stage.settings is not None and stage.settings.section != stage.name:
                raise ValueError(
                    f"stage {stage.name}: its settings section is {stage.settings.section!r}"
                )
            names.append(stage.name)
            keys.add(stage.key_id)
        self._stages = tuple(stages)

    def __iter__(self) -> Iterator[Stage]:
        return iter(self._stages)

    def __len__(self) -> int:
        return len(self._stages)

    def __getitem__(self, name: str) -> Stage:
        for stage in self._stages:
            if stage.name == name:
                return stage
        raise KeyError(name)

    def __contains__(self, name: object) -> bool:
        return any(stage.name == name for stage in self._stages)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(stage.name for stage in self._stages)

    def with_stage(self, stage: Stage) -> Registry:
        """A new registry with ``stage`` appended."""
        return Registry([*self._stages, stage])
