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
unknown one) in one line naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, TypeVar

from mbn.errors import MbnInputError

__all__ = ["Readable", "Record", "optional"]

R = TypeVar("R", bound="Record")
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


def optional(default: Any = None) -> Any:
    """A field written only while it is not None (declare it ``T | None``)."""
    return dataclasses.field(default=default, metadata={"omit_none": True})


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
            out[f.name] = _to_json(value)
        return out

    @classmethod
    def from_json(cls: type[R], data: Any, where: str = "") -> R:
        """The record held by ``data`` (a JSON object); :class:`~mbn.errors.MbnInputError`
        naming ``where`` and the key when a key is missing, unknown or of the wrong kind."""
        here = where or cls.__name__
        if not isinstance(data, Mapping):
            raise MbnInputError(f"{here}: expected an object, got {type(data).__name__}")
        hints = _hints_of(cls)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = [k for k in data if k not in names]
        if unknown:
            raise MbnInputError(f"{here}: unknown key {unknown[0]!r} for a {cls.__name__}")
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name not in data:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    raise MbnInputError(f"{here}: no {f.name!r} (a {cls.__name__} needs it)")
                continue
            values[f.name] = _from_json(data[f.name], hints[f.name], f"{here}.{f.name}")
        return cls(**values)


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
