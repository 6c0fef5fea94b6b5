"""The evidence a reader can inspect: every run the documentation cites is kept under
``evidence/runs/`` (its summary files) or listed in ``evidence/README.md`` as not kept, every
``evidence/`` path cited exists, and the folder stays small."""

from __future__ import annotations

import re
from pathlib import Path

TOP = Path(__file__).resolve().parent.parent
EVIDENCE = TOP / "evidence"
#: Where figures are cited.
DOCUMENTS = sorted([TOP / "README.md", TOP / "benchmarks" / "README.md", *TOP.glob("docs/*.md")])
#: The evidence folder's size limit (bytes): summaries, not runs.
LIMIT = 5_000_000

_FENCE = re.compile(r"^```.*?^```", re.M | re.S)
_SPAN = re.compile(r"`([^`]+)`", re.S)
_RUN = re.compile(r"(?<![\w/.-])runs/([A-Za-z0-9_-]+(?:\.[A-Za-z0-9_-]+)*)")
_EVIDENCE_PATH = re.compile(r"(?<![\w/.-])(evidence/[A-Za-z0-9_./-]*[A-Za-z0-9_/-])")


def _is_command(span: str) -> bool:
    """An inline code span that is a command to type (its ``--out runs/X`` names a folder to
    make, not one cited)."""
    return span.lstrip().startswith(("mbn ", "python ", "python3 ", "pytest", "bash "))


def cited_runs(text: str) -> set[str]:
    """The ``runs/NAME`` folders a document cites: outside code blocks and typed commands."""
    text = _FENCE.sub("", text)
    names: set[str] = set()
    for span in _SPAN.findall(text):
        if not _is_command(span):
            names |= set(_RUN.findall(span))
    names |= set(_RUN.findall(_SPAN.sub("", text)))
    return {n.split("/")[0] for n in names}


def not_kept() -> set[str]:
    """The runs ``evidence/README.md`` lists as not kept (``| `runs/NAME` | ...``)."""
    text = (EVIDENCE / "README.md").read_text()
    return set(re.findall(r"^\| `runs/([A-Za-z0-9_.-]+)` \|", text, re.M))


def test_the_parser_tells_citations_from_commands():
    text = (
        "Measured in `runs/pvd` and runs/nb-sweep (see `runs/abl-s0/sweep.md`).\n"
        "`mbn sweep --seeds 0-9 --out runs/made --reuse\nruns/also-made`\n"
        "```bash\nmbn reproduce --out runs/fenced\n```\n"
    )
    assert cited_runs(text) == {"pvd", "nb-sweep", "abl-s0"}


def _kept() -> set[str]:
    folder = EVIDENCE / "runs"
    assert folder.is_dir(), "evidence/runs is missing (is it in .gitignore?)"
    return {p.name for p in folder.iterdir() if p.is_dir()}


def test_every_cited_run_is_kept_or_listed_as_not_kept():
    listed = not_kept()
    kept = _kept()
    assert not listed & kept, f"listed as not kept but kept: {sorted(listed & kept)}"
    for doc in DOCUMENTS:
        missing = cited_runs(doc.read_text()) - listed - kept
        assert not missing, f"{doc.relative_to(TOP)} cites runs/{sorted(missing)[0]}, neither kept "
        "under evidence/runs nor listed as not kept in evidence/README.md"


def test_a_document_citing_a_run_not_kept_says_so():
    listed = not_kept()
    for doc in DOCUMENTS:
        text = doc.read_text()
        if cited_runs(text) & listed:
            assert "evidence/README.md" in text, (
                f"{doc.relative_to(TOP)} cites runs that are not kept without pointing to "
                "evidence/README.md"
            )


def test_every_evidence_path_cited_exists():
    for doc in [*DOCUMENTS, EVIDENCE / "README.md"]:
        for path in _EVIDENCE_PATH.findall(doc.read_text()):
            assert (TOP / path).exists(), f"{doc.relative_to(TOP)} cites {path}, which is not there"


def test_each_kept_run_holds_its_summary_files_and_the_folder_stays_small():
    runs = [EVIDENCE / "runs" / name for name in sorted(_kept())]
    assert runs, "no run is kept"
    for run in runs:
        names = {p.name for p in run.rglob("*.json")}
        assert names & {"run.json", "sweep.json"}, f"{run}: neither run.json nor sweep.json"
        assert not list(run.rglob("*.npz")), f"{run}: checkpoints or records are not evidence"
    size = sum(p.stat().st_size for p in EVIDENCE.rglob("*") if p.is_file())
    assert size < LIMIT, f"evidence/ holds {size / 1e6:.1f} MB (limit {LIMIT / 1e6:.0f} MB)"
