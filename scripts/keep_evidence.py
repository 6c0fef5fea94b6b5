"""Keep a run's or a sweep's summary files as evidence: ``evidence/runs/NAME/``.

The documentation cites runs for its figures; their folders (checkpoints, records, figures) stay
out of the repository, but the files the figures are read from are kept under ``evidence/``, so
that a reader can check every cited number (``evidence/README.md``):

- a run folder: ``run.json``, ``results.json`` (without indentation), ``timings.json``,
  ``report.md``;
- a sweep folder: ``sweep.json``, ``sweep.md`` and, for each ``seed-K``, the run files above,
  its ``results.json`` gzip-compressed as ``mbn sweep --keep`` keeps it (a tenth the size;
  ``mbn sweep --summarize`` and ``--combine`` read it).

Usage::

    python scripts/keep_evidence.py runs/pvd              # -> evidence/runs/pvd/
    python scripts/keep_evidence.py runs/s0 --name reproduce-s0
    python scripts/keep_evidence.py runs/s0 --name s0-times --only run.json,timings.json

Existing files of that name are replaced; the total size kept is printed (keep it to a few MB:
``tests/test_evidence.py`` checks the folder's size).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

from mbn.experiments.sweep.combine import packed_results
from mbn.experiments.sweep.run import RESULTS_GZ

TOP = Path(__file__).resolve().parent.parent
EVIDENCE = TOP / "evidence" / "runs"
RUN_FILES = ("run.json", "results.json", "timings.json", "report.md")
SWEEP_FILES = ("sweep.json", "sweep.md")


def summary_files(folder: Path) -> list[Path]:
    """The summary files of a run or sweep folder, relative to it (none: not a run or sweep)."""
    found = [Path(n) for n in (*RUN_FILES, *SWEEP_FILES) if (folder / n).is_file()]
    for seed in sorted(folder.glob("seed-*")):
        if seed.is_dir():
            found += [seed.relative_to(folder) / n for n in RUN_FILES if (seed / n).is_file()]
    return found


def keep(
    folder: Path, name: str, evidence: Path = EVIDENCE, only: tuple[str, ...] | None = None
) -> tuple[Path, int]:
    """Copy the summary files of ``folder`` to ``evidence/NAME`` (``only``: those of these
    names, in the folder and in each seed's); returns it and the bytes."""
    files = summary_files(folder)
    if only is not None:
        files = [f for f in files if f.name in only]
    if not any(f.name in ("run.json", "sweep.json") for f in files):
        raise SystemExit(f"keep_evidence: {folder}: neither a run (run.json) nor a sweep")
    target = evidence / name
    if target.exists():
        shutil.rmtree(target)
    size = 0
    for rel in files:
        (target / rel).parent.mkdir(parents=True, exist_ok=True)
        if rel.name == "results.json" and rel.parent.name.startswith("seed-"):
            packed = packed_results(folder / rel)
            rel = rel.with_name(RESULTS_GZ)
            (target / rel).write_bytes(packed)
        elif rel.name == "results.json":  # the same data without indentation (a third the size)
            data = json.loads((folder / rel).read_text())
            (target / rel).write_text(json.dumps(data, separators=(",", ":")) + "\n")
        else:
            shutil.copyfile(folder / rel, target / rel)
        size += (target / rel).stat().st_size
    return target, size


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="a run or sweep folder")
    parser.add_argument("--name", help="the name under evidence/runs (default: the folder's)")
    parser.add_argument(
        "--only",
        help="keep only these files, comma-separated (e.g. run.json,timings.json for a run "
        "whose times alone are cited)",
    )
    args = parser.parse_args(argv)
    only = None
    if args.only:
        only = tuple(n.strip() for n in args.only.split(","))
        unknown = sorted(set(only) - set(RUN_FILES) - set(SWEEP_FILES))
        if unknown:
            known = ", ".join(RUN_FILES + SWEEP_FILES)
            parser.error(f"--only: {', '.join(unknown)} not a summary file ({known})")
    target, size = keep(args.folder, args.name or args.folder.name, only=only)
    total = sum(p.stat().st_size for p in EVIDENCE.rglob("*") if p.is_file())
    print(
        f"{target.relative_to(TOP)}: {size / 1e3:.0f} kB kept; "
        f"evidence/runs in all {total / 1e6:.2f} MB"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
