"""File helpers: atomic writes, JSON and CSV reading with errors that name the file and line, and
the one set of schema checks every reader of ``mbn`` uses (controller, multiplier and network
files, run manifests, settings files).

The schema checks take the value read and ``where`` (the file, and the path of the field inside
it, e.g. ``"rf.json: motor.v_max"``) and raise :class:`~mbn.errors.MbnInputError` with one line
that starts with ``where``.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from mbn.errors import MbnInputError

__all__ = [
    "atomic_open",
    "check_fields",
    "expect_int",
    "expect_int_list",
    "expect_number",
    "expect_number_list",
    "expect_object",
    "expect_str",
    "read_csv_columns",
    "read_json",
    "write_csv_atomic",
    "write_json_atomic",
]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success rename it over ``path``.

    If the block raises, the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise MbnInputError(f"{path}: folder {directory} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        # mkstemp makes the file private (0600); give it the permissions open() would
        os.chmod(tmp, 0o666 & ~_umask())
        with os.fdopen(fd, mode) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if hasattr(value, "__array__"):
        return np.asarray(value).tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_json_atomic(path: str | Path, data: Any) -> None:
    """Write ``data`` as indented JSON, atomically."""
    with atomic_open(path) as handle:
        json.dump(data, handle, indent=2, default=_json_default)
        handle.write("\n")


def read_json(path: str | Path) -> Any:
    """Read a JSON file; errors name the file and line."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise MbnInputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise MbnInputError(f"{path}:{exc.lineno}: invalid JSON ({exc.msg})") from None


def read_csv_columns(path: str | Path, columns: Sequence[str]) -> dict[str, np.ndarray]:
    """Read the named numeric columns of a CSV file with a header line.

    Raises:
        MbnInputError: unreadable file, missing columns, a short row or a value that is not a
            finite number, naming the file and line.
    """
    path = Path(path)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise MbnInputError(f"{path}: cannot read ({exc.strerror})") from None
    with handle:
        reader = csv.reader(handle)
        header = next(reader, None)
        if header is None:
            raise MbnInputError(f"{path}:1: empty file, expected a header with {','.join(columns)}")
        header = [h.strip() for h in header]
        missing = [c for c in columns if c not in header]
        if missing:
            raise MbnInputError(
                f"{path}:1: missing column(s) {', '.join(missing)} (header has {','.join(header)})"
            )
        index = [header.index(c) for c in columns]
        rows: list[list[float]] = []
        for row in reader:
            line = reader.line_num
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) < len(header):
                raise MbnInputError(f"{path}:{line}: expected {len(header)} fields, got {len(row)}")
            values: list[float] = []
            for name, i in zip(columns, index, strict=True):
                try:
                    value = float(row[i])
                except ValueError:
                    raise MbnInputError(
                        f"{path}:{line}: column {name}: {row[i].strip()!r} is not a number"
                    ) from None
                if not math.isfinite(value):
                    raise MbnInputError(f"{path}:{line}: column {name}: {row[i]!r} is not finite")
                values.append(value)
            rows.append(values)
    data = np.array(rows, dtype=np.float64).reshape(-1, len(columns))
    return {name: data[:, i] for i, name in enumerate(columns)}


def write_csv_atomic(path: str | Path, header: Sequence[str], rows: np.ndarray) -> None:
    """Write a numeric table with a header, atomically (full float precision)."""
    rows = np.asarray(rows, dtype=np.float64)
    with atomic_open(path) as handle:
        handle.write(",".join(header) + "\n")
        for row in rows:
            handle.write(",".join(repr(float(v)) for v in row) + "\n")


# ---------------------------------------------------------------------------------------------
# Schema checks
# ---------------------------------------------------------------------------------------------


def expect_object(value: Any, where: str) -> dict[str, Any]:
    """``value`` if it is a JSON/TOML object (a dict), else one line naming ``where``."""
    if not isinstance(value, dict):
        raise MbnInputError(f"{where}: expected an object, got {type(value).__name__}")
    return value


def check_fields(
    data: Mapping[str, Any], where: str, required: Sequence[str], optional: Sequence[str] = ()
) -> None:
    """Refuse missing required keys and unknown keys of an object (one line naming them)."""
    missing = [k for k in required if k not in data]
    if missing:
        plural = "s" if len(missing) > 1 else ""
        raise MbnInputError(f"{where}: missing field{plural} {', '.join(map(repr, missing))}")
    unknown = sorted(set(data) - set(required) - set(optional))
    if unknown:
        raise MbnInputError(
            f"{where}: unknown field(s) {', '.join(map(repr, unknown))} (expected "
            f"{', '.join(list(required) + list(optional))})"
        )


def expect_int(value: Any, where: str) -> int:
    """``value`` if it is an integer (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise MbnInputError(f"{where}: expected an integer, got {value!r}")
    return value


def expect_number(value: Any, where: str) -> float:
    """``value`` as a float if it is a finite number (not a bool)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MbnInputError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def expect_str(value: Any, where: str, choices: Sequence[str] | None = None) -> str:
    """``value`` if it is a string (one of ``choices`` when given)."""
    if not isinstance(value, str):
        raise MbnInputError(f"{where}: expected a string, got {value!r}")
    if choices is not None and value not in choices:
        raise MbnInputError(f"{where}: expected one of {', '.join(choices)}, got {value!r}")
    return value


def expect_int_list(value: Any, where: str) -> list[int]:
    """``value`` if it is a list of integers."""
    if not isinstance(value, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in value
    ):
        raise MbnInputError(f"{where}: expected a list of integers, got {value!r}")
    return value


def expect_number_list(value: Any, where: str) -> list[float]:
    """``value`` as a list of floats if it is a list of finite numbers."""
    if not isinstance(value, list):
        raise MbnInputError(f"{where}: expected a list of numbers, got {value!r}")
    return [expect_number(v, where) for v in value]
