"""Settings a researcher can write down: frozen dataclasses whose fields carry their unit, valid
range and source, read from TOML and written back as TOML.

A settings class is a frozen dataclass that derives from :class:`Settings`; each field is
declared with :func:`setting`::

    @dataclass(frozen=True)
    class RFSettings(Settings):
        generations: int = setting(300, low=1, source="docs/reproduce.md", doc="DE generations")

Construction validates every field (type, range, choices) and raises
:class:`~mbn.errors.MbnInputError` with one line naming the field. :func:`read_toml` reads a
settings file into plain data, remembering the line of every key, and :func:`from_mapping` builds
a settings object from one table of it (unknown keys and bad values: one line naming the file,
line and key). :func:`to_toml` writes sections back, with the unit, range and source of each
field as a comment. The schema checks are those of :mod:`mbn.io`.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import textwrap
import tomllib
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from mbn.errors import MbnInputError
from mbn.io import expect_number, integer_digits

__all__ = [
    "Locator",
    "Settings",
    "TomlDocument",
    "from_mapping",
    "from_recorded",
    "plain_text",
    "read_toml",
    "section_description",
    "setting",
    "settings_to_dict",
    "to_toml",
    "toml_error",
]

S = TypeVar("S", bound="Settings")

#: How a check names a setting in its one-line error: ``where(section, key)`` is
#: ``FILE:LINE: section.key`` for a value read from a settings file, else ``section.key``.
Locator = Callable[[str, str], str]


def setting(
    default: Any,
    *,
    doc: str,
    unit: str = "",
    low: float | None = None,
    high: float | None = None,
    choices: Sequence[str] | Callable[[], Sequence[str]] | None = None,
    source: str = "",
) -> Any:
    """A settings field: its default, what it is (``doc``), its ``unit``, the closed range
    ``[low, high]`` of valid values (for numbers, and for every item of a tuple of numbers), the
    valid ``choices`` (for strings, and for every item of a tuple of strings; a function giving
    them, asked at each check, for a registry that grows: the maze families), and ``source``:
    the paper section or ``docs/`` page the default comes from."""
    meta = {
        "doc": doc,
        "unit": unit,
        "low": low,
        "high": high,
        "choices": choices if callable(choices) or choices is None else tuple(choices),
        "source": source,
    }
    if isinstance(default, (list, dict, set)):
        raise TypeError("settings defaults must be immutable (use a tuple)")
    return dataclasses.field(default=default, metadata=meta)


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _describe(hint: Any) -> str:
    origin = typing.get_origin(hint)
    if origin is tuple:
        return f"a list of {_describe(typing.get_args(hint)[0])}s"
    if origin in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return _describe(args[0])
    return {bool: "boolean", int: "integer", float: "number", str: "string"}.get(hint, str(hint))


def _clip(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[:limit] + "..."


def _choices(meta: Mapping[str, Any]) -> tuple[str, ...] | None:
    """A field's choices (:func:`setting`), a function of them asked now."""
    choices = meta.get("choices")
    if callable(choices):
        return tuple(choices())
    return choices


def _check_scalar(value: Any, hint: Any, meta: Mapping[str, Any], where: str) -> Any:
    if hint is bool:
        if not isinstance(value, bool):
            raise MbnInputError(f"{where}: expected true or false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise MbnInputError(f"{where}: expected an integer, got {_clip(repr(value))}")
        if abs(value) > 2**53:
            raise MbnInputError(f"{where}: {integer_digits(value)}-digit integer is too large")
    elif hint is float:
        value = expect_number(value, where)
    elif hint is str:
        if not isinstance(value, str):
            raise MbnInputError(f"{where}: expected a string, got {value!r}")
        choices = _choices(meta)
        if choices is not None and value not in choices:
            raise MbnInputError(f"{where}: expected one of {', '.join(choices)}, got {value!r}")
        return value
    low, high = meta.get("low"), meta.get("high")
    if low is not None and value < low:
        raise MbnInputError(f"{where}: must be >= {low:g}, got {value!r}")
    if high is not None and value > high:
        raise MbnInputError(f"{where}: must be <= {high:g}, got {value!r}")
    return value


def _check_value(value: Any, hint: Any, meta: Mapping[str, Any], where: str) -> Any:
    """``value`` converted to the field's type (a list becomes a tuple), or one line."""
    origin = typing.get_origin(hint)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        return _check_value(value, args[0], meta, where)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise MbnInputError(f"{where}: expected {_describe(hint)}, got {value!r}")
        item = typing.get_args(hint)[0]
        return tuple(_check_scalar(v, item, meta, f"{where}[{k}]") for k, v in enumerate(value))
    return _check_scalar(value, hint, meta, where)


@dataclass(frozen=True)
class Settings:
    """Base of settings classes: every field is checked on construction (:func:`setting`)."""

    #: The name of the section (TOML table) these settings are read from.
    section: typing.ClassVar[str] = ""
    #: What a recorded config (a ``run.json``) written before this section (or some of its
    #: keys) existed ran with: the values read for the keys missing there (others: defaults).
    recorded_before: typing.ClassVar[dict[str, typing.Any]] = {}

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):
            where = f"{self.section}.{f.name}" if self.section else f.name
            value = _check_value(getattr(self, f.name), hints[f.name], f.metadata, where)
            object.__setattr__(self, f.name, value)

    def replace(self: S, **changes: Any) -> S:
        """A copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def check_names(self, sections: Mapping[str, Settings], where: Locator) -> None:
        """Check what this section names (mazes, connections, rules) against the world and the
        run's other ``sections`` (``section -> settings``), before any work: a maze that cannot
        be read or run in, a connection the network lacks, a rule no stage provides. Raises one
        :class:`~mbn.errors.MbnInputError` whose message starts with ``where(section, key)``
        (``FILE:LINE: section.key`` where the value came from a settings file). A settings class
        whose fields name nothing checks nothing (this default)."""


def settings_to_dict(settings: Settings) -> dict[str, Any]:
    """Plain data (tuples as lists) of a settings object, for JSON and TOML."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        out[f.name] = list(value) if isinstance(value, tuple) else value
    return out


# ---------------------------------------------------------------------------------------------
# TOML
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TomlDocument:
    """A settings file read by :func:`read_toml`: its tables and the line of every key.

    Attributes:
        path: the file.
        data: the parsed TOML (tables of the top level).
        lines: ``(table, key) -> line`` (1-based) of every key, and ``(table, "") -> line`` of
            every table header.
    """

    path: Path
    data: dict[str, Any]
    lines: dict[tuple[str, str], int]

    def where(self, table: str, key: str = "") -> str:
        """``FILE:LINE: table.key`` (or without the line where it is not known)."""
        line = self.lines.get((table, key)) or self.lines.get((table, ""))
        name = f"{table}.{key}" if key else f"[{table}]"
        return f"{self.path}:{line}: {name}" if line else f"{self.path}: {name}"


_TABLE = re.compile(r"^\s*\[\s*([A-Za-z0-9_.\-]+)\s*\]\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-]+)\s*=")


def toml_error(exc: tomllib.TOMLDecodeError, text: str, where: str) -> MbnInputError:
    """A TOML syntax error as ``"{where}:{line}: message (column c)"``."""
    message = str(exc)
    match = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", message)
    if match is not None:
        body = message[: match.start()]
        return MbnInputError(
            f"{where}:{match.group(1)}: TOML syntax error: {body} (column {match.group(2)})"
        )
    match = re.search(r"\s*\(at end of document\)\s*$", message)
    if match is not None:
        last = max(1, len(text.splitlines()))
        body = message[: match.start()]
        return MbnInputError(f"{where}:{last}: TOML syntax error: {body} (at end of file)")
    lineno = getattr(exc, "lineno", None)
    if isinstance(lineno, int):
        return MbnInputError(f"{where}:{lineno}: TOML syntax error: {message}")
    return MbnInputError(f"{where}: TOML syntax error: {message}")


def read_toml(path: str | Path) -> TomlDocument:
    """Read a settings file (TOML). Errors: one line naming the file (and the line)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise MbnInputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MbnInputError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise toml_error(exc, text, str(path)) from None
    except ValueError as exc:  # an integer of thousands of digits
        raise MbnInputError(f"{path}: invalid TOML ({str(exc).split(':')[0]})") from None
    except RecursionError:
        raise MbnInputError(f"{path}: invalid TOML (nested too deeply)") from None
    lines: dict[tuple[str, str], int] = {}
    table = ""
    for number, line in enumerate(text.splitlines(), start=1):
        m = _TABLE.match(line)
        if m:
            table = m.group(1)
            lines.setdefault((table, ""), number)
            continue
        m = _KEY.match(line)
        if m:
            lines.setdefault((table, m.group(1)), number)
    return TomlDocument(path=path, data=data, lines=lines)


def from_recorded(cls: type[S], table: Any, where: Any = None) -> S:
    """Settings ``cls`` as a run recorded them (``table``: its section of a recorded config;
    missing: ``{}``): a key the run was recorded without reads as it ran before the key existed
    (``cls.recorded_before``), then the class's default; ``where`` as :func:`from_mapping`."""
    if isinstance(table, dict):
        table = {**cls.recorded_before, **table}
    return from_mapping(cls, table, where=where)


def from_mapping(
    cls: type[S],
    data: Any,
    *,
    base: S | None = None,
    where: Any = None,
) -> S:
    """Settings ``cls`` from a table ``data`` (a subset of its fields), over ``base`` (default:
    ``cls()``). ``where(key)`` names a key in errors (default ``section.key``)."""
    name = cls.section

    def at(key: str) -> str:
        return where(key) if where is not None else (f"{name}.{key}" if key else f"[{name}]")

    if not isinstance(data, dict):
        raise MbnInputError(f"{at('')}: expected a table, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in data:
        if key not in fields:
            raise MbnInputError(
                f"{at(key)}: unknown setting (the settings of [{name}]: {', '.join(fields)})"
            )
    hints = _hints(cls)
    changes = {
        key: _check_value(value, hints[key], fields[key].metadata, at(key))
        for key, value in data.items()
    }
    start = base if base is not None else cls()
    try:
        return dataclasses.replace(start, **changes)
    except MbnInputError as exc:
        # a check of the whole section that names one key of the table: that key's line
        text = str(exc)
        for key in data:
            prefix = f"{name}.{key}"
            if text.startswith(prefix) and text[len(prefix) : len(prefix) + 1] in (":", "[", " "):
                raise MbnInputError(f"{at(key)}{text[len(prefix) :]}") from None
        raise MbnInputError(f"{at('')}: {exc}") from None


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"not a TOML value: {value!r}")


def _comment(f: dataclasses.Field[Any]) -> str:
    meta = f.metadata
    parts = [plain_text(meta.get("doc", ""))]
    if meta.get("unit"):
        parts.append(f"unit: {meta['unit']}")
    low, high = meta.get("low"), meta.get("high")
    if low is not None or high is not None:
        lo = "-inf" if low is None else f"{low:g}"
        hi = "inf" if high is None else f"{high:g}"
        parts.append(f"range [{lo}, {hi}]")
    choices = _choices(meta)
    if choices:
        parts.append("one of " + ", ".join(choices))
    if meta.get("source"):
        parts.append(f"source: {plain_text(meta['source'])}")
    return "; ".join(p for p in parts if p)


#: reST markup in docstrings: a role (``:mod:``), then text in single or double backquotes.
_REST = re.compile(r"(?::[a-z]+:)?`{1,2}~?([^`]+?)`{1,2}")

#: Width of the comment lines :func:`to_toml` wraps a section's description to.
COMMENT_WIDTH = 99


def plain_text(text: str) -> str:
    """``text`` with its reST markup replaced by the text marked (a role and its backquotes,
    or double backquotes, dropped) and its lines joined into one."""
    return " ".join(_REST.sub(r"\1", text).split())


def section_description(cls: type[Settings]) -> str:
    """What a settings section is, in plain text: the first paragraph of its docstring, whole
    (every sentence of it), without reST markup; empty when it has no docstring."""
    doc = inspect.cleandoc(cls.__doc__ or "")
    return plain_text(doc.split("\n\n")[0])


def to_toml(sections: Sequence[Settings], header: str = "") -> str:
    """The sections as a TOML document: each table after a comment with what it is (the first
    paragraph of its docstring, whole and in plain text), each field after a comment with what
    it is, its unit, range and source (reads back with :func:`read_toml` into the same
    settings)."""
    out = [f"# {line}" if line else "#" for line in header.splitlines()]
    for s in sections:
        if out:
            out.append("")
        description = section_description(type(s))
        if description:
            out.extend(f"# {line}" for line in textwrap.wrap(description, COMMENT_WIDTH - 2))
        out.append(f"[{s.section}]")
        for f in dataclasses.fields(s):
            value = getattr(s, f.name)
            out.append(f"# {_comment(f)}")
            if value is None:
                out.append(f"# {f.name} = (not set)")
                continue
            out.append(f"{f.name} = {_toml_value(value)}")
    return "\n".join(out) + "\n"
