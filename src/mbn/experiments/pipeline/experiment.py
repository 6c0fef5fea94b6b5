"""An experiment: its stages, and how a run of it is configured (its sections, the quick preset,
a settings file) and summed up. The runner (:mod:`~mbn.experiments.pipeline.runner`) runs one;
:mod:`~mbn.experiments.pipeline.reuse` reads another run's."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from mbn.config import Settings, TomlDocument, from_mapping, from_recorded
from mbn.errors import MbnInputError
from mbn.experiments.pipeline.registry import Registry
from mbn.experiments.pipeline.runconfig import RunConfig, RunSettings
from mbn.experiments.pipeline.rundir import RunDir

__all__ = ["Experiment", "Results"]


Results = Callable[[RunDir, dict[str, dict[str, Any]], RunConfig], dict[str, Any]]


@dataclass(frozen=True)
class Experiment:
    """An experiment: its stages and how a run of it is configured and summed up.

    Attributes:
        name: the experiment's name (``reproduce``).
        kind: the ``kind`` of its ``run.json`` (``mbn.reproduce``).
        registry: its stages, in order.
        shared: settings classes shared by several stages (sections before the stages' own;
            :class:`RunSettings` comes first in every experiment).
        defaults: the experiment's own defaults, ``section -> {setting: value}``, over the
            settings' (a library stage's section set for this experiment: the rule a
            ``programs`` stage learns); the quick preset and the file's values come over them.
        quick: the quick preset: ``section -> {setting: value}`` applied under the file's values.
        seeds: the seeds derived from the run's seed (for NumPy edges), recorded in results.
        results: extra entries of ``results.json`` from the stages' data (e.g. tests and claims).
        report: writes the report from the run folder (and ``results.json``) alone.
    """

    name: str
    kind: str
    registry: Registry
    shared: tuple[type[Settings], ...] = ()
    defaults: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    quick: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    seeds: Callable[[int], dict[str, int]] = lambda seed: {"seed": seed}
    results: Results | None = None
    report: Callable[[RunDir], None] | None = None

    def section_types(self) -> tuple[type[Settings], ...]:
        stages = tuple(s.settings for s in self.registry if s.settings is not None)
        return (RunSettings, *self.shared, *stages)

    def config(self, *, quick: bool = False, document: TomlDocument | None = None) -> RunConfig:
        """The effective config: the settings' defaults, then the experiment's
        (:attr:`defaults`), then the quick preset (when ``quick`` or the file's
        ``[run] quick = true``), then the file's values. Unknown tables and keys, and bad
        values, are refused in one line naming the file, line and key."""
        types = {cls.section: cls for cls in self.section_types()}
        for table in self.defaults:
            if table not in types:
                raise MbnInputError(
                    f"{self.name}: defaults: unknown section [{table}] "
                    f"(the sections of {self.name}: {', '.join(types)})"
                )
        data = dict(document.data) if document is not None else {}
        for table in data:
            if table not in types:
                where = document.where(table) if document is not None else f"[{table}]"
                raise MbnInputError(
                    f"{where}: unknown section (the sections of {self.name}: {', '.join(types)})"
                )
        run_table = data.get("run", {})
        file_quick = isinstance(run_table, dict) and run_table.get("quick") is True
        use_quick = quick or file_quick
        sections = []
        for name, cls in types.items():
            current: Settings = cls()
            if self.defaults.get(name):
                current = from_mapping(cls, dict(self.defaults[name]), base=current)
            if use_quick:
                preset = dict(self.quick.get(name, {}))
                if name == "run":
                    preset["quick"] = True
                if preset:
                    current = from_mapping(cls, preset, base=current)
            if name in data:
                current = from_mapping(
                    cls, data[name], base=current, where=_locator(document, name)
                )
            if isinstance(current, RunSettings) and use_quick and not current.quick:
                current = current.replace(quick=True)
            sections.append(current)
        return RunConfig(tuple(sections), origin=document)

    def config_from_dict(self, data: Any, where: str) -> RunConfig:
        """The config recorded in a ``run.json`` (a table per section)."""
        if not isinstance(data, dict):
            raise MbnInputError(f"{where}: config: expected an object, got {type(data).__name__}")
        types = {cls.section: cls for cls in self.section_types()}
        sections = []
        for name, cls in types.items():
            # a section (or a key) the run was recorded without ran as it did before it existed
            sections.append(
                from_recorded(
                    cls, data.get(name, {}), where=lambda key, t=name: f"{where}: config.{t}.{key}"
                )
            )
        return RunConfig(tuple(sections))


def _locator(document: TomlDocument | None, table: str) -> Callable[[str], str] | None:
    """How errors name a key of ``table`` in ``document`` (file, line and key)."""
    if document is None:
        return None
    return lambda key: document.where(table, key)
