"""The ``--seeds`` syntax of ``mbn sweep``: a comma-separated list of seeds and inclusive ranges
(``0-9``, ``3``, ``0,2,5-7``)."""

from __future__ import annotations

import re

from mbn.errors import MbnInputError

__all__ = ["MAX_SEEDS", "SEED_LIMIT", "format_seeds", "parse_seeds"]

#: The most seeds one sweep may hold (more is almost surely a typo: ``0-10000``).
MAX_SEEDS = 1000
#: Seeds are in ``[0, SEED_LIMIT)``, as ``mbn reproduce --seed`` takes them.
SEED_LIMIT = 2**32

_PART = re.compile(r"^(\d+)(?:-(\d+))?$")


def parse_seeds(text: str) -> tuple[int, ...]:
    """The seeds of ``text``, in the order written, without repeats.

    Raises:
        MbnInputError: one line naming what is wrong (an empty list or part, a part that is not
            a seed or a range ``LOW-HIGH`` with ``LOW <= HIGH``, a negative seed, a seed
            ``>= 2**32``, more than :data:`MAX_SEEDS` seeds).
    """
    if not text.strip():
        raise MbnInputError("--seeds: empty (expected e.g. 0-9, 3 or 0,2,5-7)")
    seeds: dict[int, None] = {}
    for raw in text.split(","):
        part = raw.strip()
        if not part:
            raise MbnInputError(f"--seeds {text!r}: an empty part (expected e.g. 0,2,5-7)")
        if part.startswith("-"):
            raise MbnInputError(f"--seeds {text!r}: {part!r}: seeds are >= 0")
        m = _PART.match(part)
        if m is None:
            raise MbnInputError(
                f"--seeds {text!r}: {part!r} is not a seed or a range LOW-HIGH of seeds"
            )
        low = int(m.group(1))
        high = int(m.group(2)) if m.group(2) is not None else low
        if high < low:
            raise MbnInputError(f"--seeds {text!r}: range {part!r} runs backwards ({low} > {high})")
        if high >= SEED_LIMIT:
            raise MbnInputError(f"--seeds {text!r}: seed {high} is not below 2**32")
        if high - low + 1 > MAX_SEEDS:  # before expanding it
            raise MbnInputError(f"--seeds {text!r}: more than {MAX_SEEDS} seeds")
        for s in range(low, high + 1):
            seeds[s] = None
        if len(seeds) > MAX_SEEDS:
            raise MbnInputError(f"--seeds {text!r}: more than {MAX_SEEDS} seeds")
    return tuple(seeds)


def format_seeds(seeds: tuple[int, ...] | list[int]) -> str:
    """The shortest ``--seeds`` text for ``seeds`` (runs of consecutive seeds as ranges)."""
    out: list[str] = []
    ordered = list(seeds)
    k = 0
    while k < len(ordered):
        j = k
        while j + 1 < len(ordered) and ordered[j + 1] == ordered[j] + 1:
            j += 1
        out.append(str(ordered[k]) if j == k else f"{ordered[k]}-{ordered[j]}")
        k = j + 1
    return ",".join(out)
