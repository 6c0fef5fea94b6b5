"""File helpers: atomic writes, JSON and CSV reading with errors that name the file and line."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from mbn.errors import MbnInputError

__all__ = ["atomic_open", "read_csv_columns", "read_json", "write_csv_atomic", "write_json_atomic"]


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
