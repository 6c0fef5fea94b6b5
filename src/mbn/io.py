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
import gzip
import io
import json
import math
import os
import tempfile
import zlib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from mbn.errors import MbnInputError

__all__ = [
    "atomic_open",
    "check_fields",
    "check_writable",
    "expect_int",
    "expect_int_list",
    "expect_number",
    "expect_number_list",
    "expect_object",
    "expect_str",
    "integer_digits",
    "json_text",
    "read_csv_columns",
    "read_json",
    "read_text",
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
    if path.is_dir():
        raise MbnInputError(f"{path}: is a folder, not a file")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise MbnInputError(f"{path}: cannot write ({exc.strerror})") from None
    try:
        # mkstemp makes the file private (0600); give it the permissions open() would
        os.chmod(tmp, 0o666 & ~_umask())
        with os.fdopen(fd, mode) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise MbnInputError(f"{path}: cannot write ({exc.strerror or exc})") from None
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


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, np.generic):
        return _finite(value.item())
    return value


def json_text(data: Any, indent: int | None = None) -> str:
    """``data`` as strict JSON: a value that is not finite (NaN, inf) becomes ``null``, so what
    ``--json`` prints always parses."""
    return json.dumps(_finite(data), indent=indent, allow_nan=False, default=_json_default)


def write_json_atomic(path: str | Path, data: Any) -> None:
    """Write ``data`` as indented JSON, atomically."""
    with atomic_open(path) as handle:
        json.dump(data, handle, indent=2, default=_json_default)
        handle.write("\n")


def check_writable(path: str | Path, what: str = "--out") -> Path:
    """Refuse, before any long work, an output file that cannot be written: its folder missing,
    read-only, full or not a real file system, or the path a folder (one line naming the path and
    the system's reason). Nothing is left behind."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise MbnInputError(f"{what} {path}: is a folder, not a file")
    if not directory.is_dir():
        raise MbnInputError(f"{what} {path}: folder {directory} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(b"\0")
                handle.flush()
                os.fsync(handle.fileno())
        finally:
            os.unlink(tmp)
    except OSError as exc:
        raise MbnInputError(f"{what} {path}: cannot write ({exc.strerror or exc})") from None
    return path


def read_text(path: str | Path) -> str:
    """A text file as UTF-8, gzip-compressed where its name ends in ``.gz`` (errors: one line
    naming the file: unreadable, not gzip, not UTF-8)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MbnInputError(f"{path}: cannot read ({exc.strerror})") from None
    if path.suffix == ".gz":
        try:
            data = gzip.decompress(data)
        except (OSError, EOFError, zlib.error) as exc:
            raise MbnInputError(f"{path}: not gzip-compressed ({exc})") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise MbnInputError(f"{path}:{line}: not UTF-8 text (byte {exc.start})") from None


def read_json(path: str | Path) -> Any:
    """Read a JSON file; errors name the file and line (unreadable, not UTF-8, invalid JSON,
    nested too deeply)."""
    path = Path(path)
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise MbnInputError(f"{path}:{exc.lineno}: invalid JSON ({exc.msg})") from None
    except RecursionError:
        raise MbnInputError(f"{path}: invalid JSON (nested too deeply)") from None
    except ValueError as exc:  # an integer of thousands of digits
        raise MbnInputError(f"{path}: invalid JSON ({str(exc).split(':')[0]})") from None


def read_csv_columns(path: str | Path, columns: Sequence[str]) -> dict[str, np.ndarray]:
    """Read the named numeric columns of a CSV file with a header line.

    Raises:
        MbnInputError: unreadable file, missing columns, a short row or a value that is not a
            finite number, naming the file and line.
    """
    path = Path(path)
    reader = csv.reader(io.StringIO(read_text(path), newline=""))
    try:
        return _csv_columns(path, reader, columns)
    except csv.Error as exc:
        raise MbnInputError(f"{path}:{reader.line_num}: invalid CSV ({exc})") from None


def _clip(text: str, limit: int = 40) -> str:
    """``text``, cut to ``limit`` characters for an error message."""
    return text if len(text) <= limit else text[:limit] + "..."


def _csv_columns(path: Path, reader: Any, columns: Sequence[str]) -> dict[str, np.ndarray]:
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
                    f"{path}:{line}: column {name}: {_clip(row[i].strip())!r} is not a number"
                ) from None
            if not math.isfinite(value):
                raise MbnInputError(
                    f"{path}:{line}: column {name}: {_clip(row[i].strip())!r} is not finite"
                )
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


def integer_digits(n: int) -> int:
    """Decimal digits of an integer, also of one too long for ``str`` (over 4300 digits)."""
    try:
        return len(str(abs(n)))
    except ValueError:
        return int(abs(n).bit_length() * 0.30103) + 1


def expect_number(value: Any, where: str) -> float:
    """``value`` as a float if it is a finite number (not a bool; an integer of hundreds of
    digits is refused as too large, not overflowed)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise MbnInputError(f"{where}: expected a finite number, got {_clip(repr(value))}")
    try:
        number = float(value)
    except OverflowError:
        raise MbnInputError(
            f"{where}: {integer_digits(int(value))}-digit integer is too large"
        ) from None
    if not math.isfinite(number):
        raise MbnInputError(f"{where}: expected a finite number, got {value!r}")
    return number


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
