"""A run's effective settings (:class:`RunConfig`: one settings object per section) and the
section every experiment has (:class:`RunSettings`: ``[run]``)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, TypeVar

from mbn.config import Settings, TomlDocument, setting, settings_to_dict, to_toml
from mbn.precision import PRECISIONS, ROBOT

__all__ = ["RunConfig", "RunSettings", "first_difference"]

S = TypeVar("S", bound=Settings)


@dataclass(frozen=True)
class RunSettings(Settings):
    """How the run as a whole is made."""

    section = "run"
    quick: bool = setting(
        False,
        doc="a smoke run: the experiment's quick preset (tiny budgets) under the file's values",
        source="docs/reproduce.md",
    )
    precision: str = setting(
        ROBOT,
        doc="floating-point precision of every stage",
        choices=PRECISIONS,
        source="docs/precision.md (the robot experiments are evolved and tested in float32)",
    )


@dataclass(frozen=True)
class RunConfig:
    """A run's effective settings: one :class:`~mbn.config.Settings` per section, in order.

    ``origin``: the settings file the values were read from, if any (not part of the config:
    it only lets :meth:`check` name the file and line of a value)."""

    sections: tuple[Settings, ...]
    origin: TomlDocument | None = field(default=None, compare=False, repr=False)

    def __getitem__(self, name: str) -> Any:
        for s in self.sections:
            if s.section == name:
                return s
        raise KeyError(name)

    def get(self, cls: type[S]) -> S:
        """The section of settings class ``cls``, typed (``config.get(RunSettings)``); a
        ``KeyError`` naming the section when the run has none."""
        for s in self.sections:
            if s.section == cls.section:
                if not isinstance(s, cls):
                    raise TypeError(
                        f"section [{cls.section}] holds a {type(s).__name__}, not a {cls.__name__}"
                    )
                return s
        raise KeyError(cls.section)

    @property
    def quick(self) -> bool:
        return self.get(RunSettings).quick

    def where(self, section: str, key: str) -> str:
        """How an error names ``section.key``: with the settings file and line where the value
        was read from one (:meth:`~mbn.config.TomlDocument.where`), else ``section.key``."""
        table = self.origin.data.get(section) if self.origin is not None else None
        if self.origin is not None and isinstance(table, dict) and key in table:
            return self.origin.where(section, key)
        return f"{section}.{key}"

    def check(self) -> None:
        """Check what every section names (:meth:`~mbn.config.Settings.check_names`: mazes,
        connections, rules, against the world and one another) before a run does any work:
        the first problem as one :class:`~mbn.errors.MbnInputError` naming the setting."""
        sections = {s.section: s for s in self.sections}
        for s in self.sections:
            s.check_names(sections, self.where)

    def to_dict(self) -> dict[str, dict[str, Any]]:
        return {s.section: settings_to_dict(s) for s in self.sections}

    def to_toml(self, header: str = "") -> str:
        return to_toml(self.sections, header)


def first_difference(old: Any, new: Any, root: str = "config", path: str = "") -> str:
    """The first place where two JSON records differ, as one line: ``a.b.c: OLD then, NEW
    now`` (``root`` when they differ as wholes)."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in [*old, *(k for k in new if k not in old)]:
            if old.get(key) != new.get(key):
                return first_difference(
                    old.get(key), new.get(key), root, f"{path}.{key}" if path else key
                )
    return f"{path or root}: {json.dumps(old)} then, {json.dumps(new)} now"
