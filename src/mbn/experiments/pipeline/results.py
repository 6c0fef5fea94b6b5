"""Typed stage results: what a stage hands to the stages after it, the report and the claims.

A stage's result is a frozen dataclass deriving from :class:`Record`, one field per key of its
``stages/NAME.json`` in the order the file holds them. :meth:`Record.to_json` writes it (the
runner does, and ``results.json`` keeps the same keys), :meth:`Record.from_json` reads it back,
checked, so that a later stage reads ``ctx.read(RFStage).best_fitness`` rather than
``ctx.read("rf")["best_fitness"]``: a name that is wrong fails when the module is checked, not
in the third hour of a run.

The fields' types say how a value is read: a :class:`Record` (nested), ``list[T]``,
``tuple[T, ...]``, ``dict[str, T]``, ``T | None`` or a JSON value (``int``, ``float``, ``str``,
``bool``, ``Any``: kept as read, so a float the file holds as ``1`` stays the ``1`` it was). A
field declared with :func:`optional` is left out of the file while it is None (a key the stage
writes only sometimes: the validation of a validated run, the restarts of several).

Reading refuses a file whose keys are not the record's (a missing key without a default, or an
unknown one) in one line naming the file and the key; :meth:`Record.pick` reads a record's
fields out of a larger object (the trials and successes every test record has).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, TypeVar

from mbn.errors import MbnInputError

if typing.TYPE_CHECKING:
    from mbn.config import Settings

__all__ = ["ClaimRow", "Readable", "Record", "RunResults", "Versions", "keyed", "optional"]

R = TypeVar("R", bound="Record")
S = TypeVar("S", bound="Settings")
D_co = TypeVar("D_co", covariant=True)


class Readable(Protocol[D_co]):
    """What reading a stage's result by its class needs (``ctx.read(RFStage)``,
    ``rundir.read_result(RFStage)``; :class:`~mbn.experiments.pipeline.registry.Stage` has it):
    its name, its ``run`` (whose return type is the type read) and how its data is read from
    its file."""

    name: ClassVar[str]

    def run(self, ctx: Any) -> D_co: ...

    @classmethod
    def from_json(cls, data: dict[str, Any], where: Any = "") -> Any: ...


def optional(default: Any = None, *, key: str | None = None) -> Any:
    """A field written only while it is not None (declare it ``T | None``); ``key``: its key
    in the file where that is not the field's name (see :func:`keyed`)."""
    meta: dict[str, Any] = {"omit_none": True}
    if key is not None:
        meta["key"] = key
    return dataclasses.field(default=default, metadata=meta)


def keyed(key: str, default: Any = dataclasses.MISSING) -> Any:
    """A field whose key in the file is not a Python name: ``passed: bool = keyed("pass")``
    (a keyword), ``product_floor_error: float = keyed("max_rel_error_product_ge_0.05")``."""
    return dataclasses.field(default=default, metadata={"key": key})


def _key(f: dataclasses.Field[Any]) -> str:
    return str(f.metadata.get("key", f.name))


@dataclasses.dataclass(frozen=True)
class Record:
    """Base of the typed results (frozen dataclasses): :meth:`to_json` and :meth:`from_json`."""

    _hints: ClassVar[dict[type, dict[str, Any]]] = {}

    def to_json(self) -> dict[str, Any]:
        """The record as JSON data: its fields in order (an :func:`optional` one left out while
        it is None), nested records, lists and tables written the same way."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if value is None and f.metadata.get("omit_none"):
                continue
            out[_key(f)] = _to_json(value)
        return out

    @classmethod
    def from_json(cls: type[R], data: Any, where: str = "") -> R:
        """The record held by ``data`` (a JSON object); :class:`~mbn.errors.MbnInputError`
        naming ``where`` and the key when a key is missing, unknown or of the wrong kind."""
        here = where or cls.__name__
        if not isinstance(data, Mapping):
            raise MbnInputError(f"{here}: expected an object, got {type(data).__name__}")
        hints = _hints_of(cls)
        names = {_key(f) for f in dataclasses.fields(cls)}
        unknown = [k for k in data if k not in names]
        if unknown:
            raise MbnInputError(f"{here}: unknown key {unknown[0]!r} for a {cls.__name__}")
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            key = _key(f)
            if key not in data:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    raise MbnInputError(f"{here}: no {key!r} (a {cls.__name__} needs it)")
                continue
            values[f.name] = _from_json(data[key], hints[f.name], f"{here}.{key}")
        return cls(**values)

    @classmethod
    def pick(cls: type[R], data: Any, where: str = "") -> R:
        """The record's fields read out of a larger object ``data`` (its other keys left
        alone): what several records share, read as the one a reader needs (a test's trials and
        successes from any experiment's test records). Missing or ill-typed keys are refused as
        by :meth:`from_json`."""
        if isinstance(data, Mapping):
            names = {_key(f) for f in dataclasses.fields(cls)}
            data = {k: v for k, v in data.items() if k in names}
        return cls.from_json(data, where)


def _hints_of(cls: type) -> dict[str, Any]:
    cached = Record._hints.get(cls)
    if cached is None:
        cached = Record._hints[cls] = typing.get_type_hints(cls)
    return cached


def _to_json(value: Any) -> Any:
    if isinstance(value, Record):
        return value.to_json()
    if isinstance(value, list | tuple):
        return [_to_json(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_json(v) for k, v in value.items()}
    return value


def _from_json(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        others = [a for a in args if a is not type(None)]
        return _from_json(value, others[0], where) if len(others) == 1 else value
    if isinstance(hint, type) and issubclass(hint, Record):
        return hint.from_json(value, where)
    if origin in (list, tuple):
        if not isinstance(value, list):
            raise MbnInputError(f"{where}: expected a list, got {type(value).__name__}")
        item = args[0] if args else Any
        items = [_from_json(v, item, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict:
        if not isinstance(value, dict):
            raise MbnInputError(f"{where}: expected an object, got {type(value).__name__}")
        item = args[1] if len(args) == 2 else Any
        return {k: _from_json(v, item, f"{where}.{k}") for k, v in value.items()}
    if hint in (int, float) and (isinstance(value, bool) or not isinstance(value, int | float)):
        raise MbnInputError(f"{where}: expected a number, got {value!r}")
    if hint is str and not isinstance(value, str):
        raise MbnInputError(f"{where}: expected a string, got {value!r}")
    if hint is bool and not isinstance(value, bool):
        raise MbnInputError(f"{where}: expected true or false, got {value!r}")
    return value


@dataclasses.dataclass(frozen=True, kw_only=True)
class Versions(Record):
    """What a run's figures depend on (``results.json``'s ``versions``)."""

    mbn: str
    python: str
    jax: str
    jaxlib: str
    numpy: str
    optax: str
    matplotlib: str
    os: str
    platform: str


@dataclasses.dataclass(frozen=True, kw_only=True)
class ClaimRow(Record):
    """A row of a run's claims table: the claim, what the run measured, whether it holds (None:
    judged over runs, not per run), and the paper's figure and the criterion (the reproduction's
    rows) or the target (the other experiments')."""

    claim: str
    measured: str
    passed: bool | None = keyed("pass")
    paper: str | None = optional()
    criterion: str | None = optional()
    target: str | None = optional()

    @property
    def judged_by(self) -> str:
        """The criterion or target it is judged by."""
        return self.criterion or self.target or ""


@dataclasses.dataclass(frozen=True, kw_only=True)
class RunResults(Record):
    """A run's ``results.json`` as every reader shares it (the runner writes it: seeds,
    settings, versions, the code, the stages' metrics, the tests and the claims); an
    experiment's own extras (``variants``, ``levels``, ...) are left to its own readers, so read
    it with :meth:`~Record.pick`: ``RunResults.pick(read_json(path), str(path))``."""

    seed: int
    seeds: dict[str, int]
    quick: bool
    config: dict[str, Any]
    versions: Versions
    code: dict[str, Any] | None = optional()  # runs before the code's identity was recorded
    maze_splits: dict[str, list[int]] | None = optional()
    mazes_looked_into: dict[str, list[int]] | None = optional()  # runs before 2026-12-08
    stages: dict[str, Any]
    tests: dict[str, Any]
    claims: list[ClaimRow]

    def settings(self, cls: type[S], where: str = "results.json") -> S:
        """The run's recorded section of settings class ``cls``, typed; a section (or a key) the
        run was recorded without reads as it ran before it existed (``cls.recorded_before``,
        as :meth:`~mbn.experiments.pipeline.experiment.Experiment.config_from_dict` reads a
        ``run.json``), never as a default of today's code that changed since."""
        from mbn.config import from_recorded

        return from_recorded(
            cls,
            self.config.get(cls.section, {}),
            where=lambda key: f"{where}: config.{cls.section}.{key}",
        )

    def recorded(self, cls: type[Any]) -> bool:
        """Whether the run recorded the section of settings class ``cls``."""
        return cls.section in self.config
