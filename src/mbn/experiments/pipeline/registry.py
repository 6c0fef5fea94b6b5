"""Stages and the registry that lists them in order.

A stage is one step of an experiment: it has a ``name``, a fixed ``key_id`` (the number folded into
the run's key to give the stage its random stream: adding a stage never moves another's key), the
stages whose outputs it reads (``needs``, checked by the runner), an optional settings class (its
section of the run's config), ``run(ctx) -> data`` (writing through ``ctx.rundir``) and a one-line
``summary(data)``. ``metrics(data)`` is what ``results.json`` keeps of its data (by default all of
it but the bulky ``details``).

A stage whose data is typed names its :class:`~mbn.experiments.pipeline.results.Record` in
``result`` and in its base, ``class RFStage(Stage[RFResult])``: its ``run`` returns the record,
the runner writes it (:meth:`~mbn.experiments.pipeline.results.Record.to_json`), and the stages
after it read it typed, ``ctx.read(RFStage).best_fitness``.
"""

from __future__ import annotations

import abc
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

from mbn.config import Settings
from mbn.experiments.pipeline.context import StageContext
from mbn.experiments.pipeline.results import Record

__all__ = ["Registry", "Stage"]

D = TypeVar("D")


class Stage(abc.ABC, Generic[D]):
    """Base of the stages: set the class attributes, implement :meth:`run` and :meth:`summary`.

    Attributes:
        name: the stage's name (its file ``stages/NAME.json``, its section of the config).
        key_id: fixed number of its random stream (``fold_in(run key, key_id)``).
        needs: names of the stages whose outputs it reads.
        settings: its settings class (a :class:`~mbn.config.Settings` with ``section == name``),
            or None.
        outputs: files it writes (relative to the run folder) that later stages or the report
            read: a finished stage whose output is missing is run again.
        result: the class of its data (a :class:`~mbn.experiments.pipeline.results.Record`),
            or None for a stage whose data is a plain JSON object.
    """

    name: ClassVar[str] = ""
    key_id: ClassVar[int] = 0
    needs: ClassVar[tuple[str, ...]] = ()
    settings: ClassVar[type[Settings] | None] = None
    outputs: ClassVar[tuple[str, ...]] = ()
    result: ClassVar[type[Record] | None] = None

    @abc.abstractmethod
    def run(self, ctx: StageContext) -> D:
        """Do the stage's work (writing through ``ctx.rundir``); return its data (its
        :attr:`result` record, or a JSON object)."""

    def summary(self, data: D) -> str:
        return "done"

    @classmethod
    def to_json(cls, data: Any) -> dict[str, Any]:
        """The stage's data as written to ``stages/NAME.json``."""
        return data.to_json() if isinstance(data, Record) else data

    @classmethod
    def from_json(cls, data: dict[str, Any], where: str | Path = "") -> Any:
        """The stage's data read from ``stages/NAME.json``: its :attr:`result` record, checked
        (one line naming ``where`` and the key when it does not fit), or the object as it is."""
        if cls.result is None:
            return data
        return cls.result.from_json(data, str(where) or f"stage {cls.name}")

    def metrics(self, data: dict[str, Any]) -> dict[str, Any]:
        """What ``results.json`` keeps of the stage's data."""
        return {k: v for k, v in data.items() if k != "details"}


class Registry:
    """Stages in the order they run, checked on construction: unique names and key numbers,
    ``needs`` naming earlier stages, settings sections named after their stage."""

    def __init__(self, stages: Sequence[Stage[Any]]) -> None:
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
            result = stage.result
            if result is not None and not (isinstance(result, type) and issubclass(result, Record)):
                raise ValueError(
                    f"stage {stage.name}: its result is {result!r}, not a Record (a frozen "
                    "dataclass deriving from mbn.experiments.pipeline.Record)"
                )
            names.append(stage.name)
            keys.add(stage.key_id)
        self._stages = tuple(stages)

    def __iter__(self) -> Iterator[Stage[Any]]:
        return iter(self._stages)

    def __len__(self) -> int:
        return len(self._stages)

    def __getitem__(self, name: str) -> Stage[Any]:
        for stage in self._stages:
            if stage.name == name:
                return stage
        raise KeyError(name)

    def __contains__(self, name: object) -> bool:
        return any(stage.name == name for stage in self._stages)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(stage.name for stage in self._stages)

    def with_stage(self, stage: Stage[Any]) -> Registry:
        """A new registry with ``stage`` appended."""
        return Registry([*self._stages, stage])
