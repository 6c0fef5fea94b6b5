"""Sweeps made in installments: on machines that keep nothing from one session to the next, on
several clusters, or over weeks.

``mbn sweep --keep DIR --out SWEEP`` keeps, of each finished seed of ``SWEEP``, what a summary
reads (``run.json``, ``timings.json`` and ``results.json``, the last gzip-compressed), and the
sweep's ``sweep.json``: a few tens of kB a seed, small enough for a project's records.

``mbn sweep --combine A B ... --out SWEEP`` makes one sweep of the finished seeds of several
installments (whole sweep folders or kept ones) of the same experiment and settings, their seeds
disjoint, and summarizes it as ``--summarize`` does. Its ``sweep.json`` lists the installments
(``combined``: each one's folder, code, seeds and wall time); each seed's ``run.json`` records the
code that made it. The combined folder holds only the kept files, so it can itself be kept, and
combined again with the next installment.
"""

from __future__ import annotations

import gzip
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mbn._version import __version__
from mbn.errors import MbnInputError
from mbn.experiments.sweep.records import SweepHead
from mbn.experiments.sweep.report import summarize_folder
from mbn.experiments.sweep.run import (
    RESULTS_GZ,
    SWEEP_FILE,
    SWEEP_KIND,
    finished_results,
    read_sweep,
    seed_dir,
    write_sweep,
)
from mbn.io import atomic_open, read_text
from mbn.provenance import code_identity, environment

__all__ = ["KEPT_FILES", "combine_sweeps", "keep_sweep", "packed_results"]

#: A seed's files an installment keeps besides its results (``results.json``, compressed).
KEPT_FILES = ("run.json", "timings.json")


def _finished(out: Path, data: dict[str, Any]) -> tuple[SweepHead, list[int]]:
    head = SweepHead.pick(data, str(out / SWEEP_FILE))
    if head.settings is None:
        raise MbnInputError(f"{out / SWEEP_FILE}: records no settings")
    config = dict(head.settings.config or {})
    seeds = [int(s) for s in head.settings.seeds]
    return head, [s for s in seeds if finished_results(out, s, config) is not None]


def _write_seed(src: Path, dst: Path, seed: int) -> None:
    """Seed ``seed``'s kept files from sweep folder ``src`` into sweep folder ``dst``."""
    a, b = seed_dir(src, seed), seed_dir(dst, seed)
    b.mkdir(parents=True)
    for name in KEPT_FILES:
        if (a / name).exists():
            shutil.copyfile(a / name, b / name)
    if (a / RESULTS_GZ).exists():
        shutil.copyfile(a / RESULTS_GZ, b / RESULTS_GZ)
    else:
        with atomic_open(b / RESULTS_GZ, "wb") as handle:
            handle.write(packed_results(a / "results.json"))


def packed_results(path: Path) -> bytes:
    """A ``results.json`` gzip-compressed as a kept seed holds it (:data:`RESULTS_GZ`): mtime
    0, so the same results give the same bytes."""
    return gzip.compress(read_text(path).encode(), mtime=0)


def _fill(out: Path, build: Any) -> None:
    """Build a new folder ``out`` (which must not exist, or be empty) in a temporary folder
    beside it, then move it into place: an interrupted keep or combine leaves nothing."""
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise MbnInputError(f"{out}: exists and is not empty (a kept or combined sweep is new)")
    parent = out.absolute().parent
    if not parent.is_dir():
        raise MbnInputError(f"{out}: folder {parent} does not exist")
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    try:
        build(tmp)
        if out.exists():
            out.rmdir()
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def keep_sweep(src: Path, dst: Path) -> list[int]:
    """Keep the finished seeds of the sweep in ``src`` in a new folder ``dst`` (see the
    module's docstring); returns the seeds kept. ``dst``'s ``sweep.json`` is ``src``'s, its
    seeds and runs those kept, its summary left out (``--summarize`` or ``--combine`` writes
    one)."""
    src = Path(src)
    data = read_sweep(src)
    head, done = _finished(src, data)
    if not done:
        raise MbnInputError(f"--out {src}: no finished seed to keep")
    assert head.settings is not None
    others = [int(s) for s in head.settings.seeds if int(s) not in done]

    def build(tmp: Path) -> None:
        for s in done:
            _write_seed(src, tmp, s)
        kept = {k: v for k, v in data.items() if k != "summary"}
        kept["settings"] = {**data["settings"], "seeds": done}
        kept["runs"] = {str(s): data["runs"][str(s)] for s in done if str(s) in data["runs"]}
        kept["kept"] = {"from": str(src), "seeds_not_finished": others}
        write_sweep(tmp, kept)

    _fill(dst, build)
    return done


def _installments(src: Path, data: dict[str, Any], done: list[int]) -> list[dict[str, Any]]:
    """``src``'s entries for a combined sweep's ``combined``: its own (folder, code, seeds,
    wall seconds), or, for a sweep combined before, the installments it was made of."""
    if data.get("combined"):
        return [
            {**c, "seeds": [s for s in c.get("seeds", []) if s in done]}
            for c in data["combined"]
            if any(s in done for s in c.get("seeds", []))
        ]
    return [
        {
            "folder": str(src),
            "code": data.get("code"),
            "seeds": done,
            "seconds": data.get("seconds"),
        }
    ]


#: What installments must share, as ``sweep.json`` records it.
_SAME = ("experiment", "quick", "config")


def combine_sweeps(sources: Sequence[Path], out: Path) -> dict[str, Any]:
    """One sweep in the new folder ``out`` of the finished seeds of ``sources`` (sweep folders,
    whole or kept): the same experiment, ``quick`` and config as recorded, the seeds disjoint
    (one line naming the first installment that differs). Summarized as ``--summarize`` does;
    returns its ``sweep.json``."""
    if len(sources) < 2:
        raise MbnInputError("--combine: name at least two sweeps (installments) to combine")
    parts: list[tuple[Path, dict[str, Any], list[int]]] = []
    first: dict[str, Any] | None = None
    owner: dict[int, Path] = {}
    for src in map(Path, sources):
        data = read_sweep(src)
        _, done = _finished(src, data)
        settings = data["settings"]
        if first is None:
            first = settings
        for key in _SAME:
            if settings.get(key) != first.get(key):
                raise MbnInputError(
                    f"--combine: {src} has another {key} than {parts[0][0]} (installments of "
                    "one sweep share the experiment and its settings)"
                )
        for s in done:
            if s in owner:
                raise MbnInputError(f"--combine: seed {s} is in both {owner[s]} and {src}")
            owner[s] = src
        parts.append((src, data, done))
    assert first is not None
    seeds = sorted(owner)
    if not seeds:
        raise MbnInputError("--combine: the installments hold no finished seed")

    def build(tmp: Path) -> None:
        runs: dict[str, Any] = {}
        for src, data, done in parts:
            for s in done:
                _write_seed(src, tmp, s)
                runs[str(s)] = data.get("runs", {}).get(str(s), {"state": "done"})
        combined = {
            "kind": SWEEP_KIND,
            "mbn_version": __version__,
            "code": code_identity(),  # what combined them; each installment's below
            "versions": dict(environment()),
            "settings": {**first, "seeds": seeds},
            "executor": "combined",
            "runs": runs,
            "combined": [
                entry for src, data, done in parts for entry in _installments(src, data, done)
            ],
        }
        write_sweep(tmp, combined)

    _fill(out, build)
    return summarize_folder(out)
