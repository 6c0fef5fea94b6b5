"""Fingerprints of what a run computed: the sha256 of its ``results.json`` and of each controller
file, with the code's identity left out (the package hash and commit that every file records,
which change with every commit even when nothing computed changes).

A move of code that changes where things live and not what they compute leaves every
fingerprint as it was: record them before, compare after.

    python scripts/fingerprint.py RUN_DIR [RUN_DIR ...] [--json out.json]
    python scripts/fingerprint.py RUN_DIR ... --against before.json   # exit 1 on any change

The record kept in ``evidence/fingerprints/quick-seed3.json`` holds the quick runs of seed 3 of
every registered experiment (``mbn reproduce --quick --seed 3 --out D/reproduce``, ``mbn run
NAME --quick --seed 3 --out D/NAME``), made before the experiments moved into one registry and
stage library; the folders' names are the experiments' names.

The code's identity is every ``"code"`` object that holds a ``package_sha256`` (``results.json``
at its top, a controller file under ``provenance``); each is replaced by ``null`` before hashing.
Everything else, the versions of the libraries included, is hashed as it was written: a record
compares with runs made where it was made (the same library versions and operating system).
Elsewhere, make the quick runs at the recording commit too (a git worktree, ``PYTHONPATH`` at
its ``src``) and compare the two sets of runs with each other.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any


def _without_code(value: Any) -> Any:
    if isinstance(value, dict):
        return {
            k: None
            if k == "code" and isinstance(v, dict) and "package_sha256" in v
            else _without_code(v)
            for k, v in value.items()
        }
    if isinstance(value, list):
        return [_without_code(v) for v in value]
    return value


def fingerprint(path: Path) -> str:
    """sha256 of the JSON file at ``path`` written back (sorted keys, no spaces) without the
    code's identity."""
    data = _without_code(json.loads(path.read_text()))
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def run_fingerprints(run: Path) -> dict[str, str]:
    """``{relative path: fingerprint}`` of a run folder's ``results.json`` and controllers."""
    files = [run / "results.json", *sorted((run / "controllers").glob("*.json"))]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise SystemExit(f"{run}: no {', '.join(missing)} (not a finished run)")
    return {str(f.relative_to(run)): fingerprint(f) for f in files}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders")
    parser.add_argument("--json", type=Path, help="write the fingerprints here")
    parser.add_argument("--against", type=Path, help="fingerprints recorded before: compare")
    args = parser.parse_args(argv)
    now = {run.name: run_fingerprints(run) for run in args.runs}
    if args.json:
        tmp = args.json.with_suffix(".tmp")
        tmp.write_text(json.dumps(now, indent=2, sort_keys=True) + "\n")
        tmp.replace(args.json)
    if args.against is None:
        for name, prints in now.items():
            for f, h in prints.items():
                print(f"{h}  {name}/{f}")
        return 0
    before = json.loads(args.against.read_text())
    before = before.get("runs", before)  # a kept record: {"commit", "command", "runs"}
    changed = 0
    for name, prints in now.items():
        if name not in before:
            print(f"{name}: not in {args.against}")
            changed += 1
            continue
        for f in sorted(set(prints) | set(before[name])):
            was, is_ = before[name].get(f), prints.get(f)
            mark = "same" if was == is_ else "CHANGED"
            changed += was != is_
            print(f"{mark:8s} {name}/{f}")
    print(f"{changed} changed" if changed else "every fingerprint as before")
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
