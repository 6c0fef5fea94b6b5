"""Reports as documents: sections of text, a table and images, written as Markdown (images
linked) and as one self-contained HTML page (images embedded), atomically."""

from __future__ import annotations

import base64
import html
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mbn.io import atomic_open

__all__ = [
    "Section",
    "claims_section",
    "markdown",
    "plain_report",
    "self_contained_html",
    "write_document",
]


@dataclass
class Section:
    """A section: title, paragraphs, an optional table (header, rows) with per-row pass/fail
    status (colours the last column), and images (file under the run folder, caption). A table
    without rows is not drawn (a header over nothing): the paragraphs say why it is empty."""

    title: str
    text: list[str] = field(default_factory=list)
    table: tuple[list[str], list[list[str]]] | None = None
    images: list[tuple[str, str]] = field(default_factory=list)
    status: list[bool | None] | None = None


def claims_section(rows: list[dict[str, Any]]) -> Section:
    """The claims table of a report: each row's ``claim``, ``measured``, ``target`` and
    ``pass`` (True, False, or None where the run cannot judge it: shown as "-")."""
    return Section(
        "Claims",
        table=(
            ["claim", "measured", "target", "holds"],
            [
                [
                    c["claim"],
                    c["measured"],
                    c["target"],
                    "-" if c["pass"] is None else ("yes" if c["pass"] else "no"),
                ]
                for c in rows
            ],
        ),
        status=[c["pass"] for c in rows],
    )


def markdown(title: str, secs: list[Section]) -> str:
    """The document as Markdown (images linked)."""
    lines = [f"# {title}", ""]
    for sec in secs:
        lines += [f"## {sec.title}", ""]
        for p in sec.text:
            lines += [p, ""]
        if sec.table and sec.table[1]:  # a table without rows is left out
            head, rows = sec.table
            lines.append("| " + " | ".join(head) + " |")
            lines.append("|" + "---|" * len(head))
            for r in rows:
                lines.append("| " + " | ".join(c.replace("|", "\\|") for c in r) + " |")
            lines.append("")
        for file, caption in sec.images:
            lines += [f"![{caption}]({file})", "", f"*{caption}*", ""]
    return "\n".join(lines)


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em}h2{margin-top:1.8em;border-bottom:1px solid #ddd;padding-bottom:.2em}
table{border-collapse:collapse;width:100%;font-size:.9em;margin:1em 0}
th,td{border:1px solid #ccc;padding:.35em .5em;vertical-align:top;text-align:left}
th{background:#f3f3f3}tr.pass td:last-child{background:#d9f2d9;font-weight:600}
tr.fail td:last-child{background:#f8d4d4;font-weight:600}
figure{margin:1em 0}img{max-width:100%;border:1px solid #eee}figcaption{color:#555;font-size:.9em}
code{background:#f5f5f5;padding:0 .2em}
"""


def _inline(text: str) -> str:
    """Escape, then the little markdown the report uses: `code` and **bold** / *italics*."""
    out = html.escape(text)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", out)
    return re.sub(r"\*([^*]+)\*", r"<i>\1</i>", out)


def self_contained_html(title: str, secs: list[Section], root: Path) -> str:
    """The document as one HTML page, images embedded (base64) from ``root``."""
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    for sec in secs:
        parts.append(f"<h2>{html.escape(sec.title)}</h2>")
        parts += [f"<p>{_inline(p)}</p>" for p in sec.text]
        if sec.table and sec.table[1]:  # a table without rows is left out
            head, rows = sec.table
            parts.append("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head))
            for k, r in enumerate(rows):
                ok = sec.status[k] if sec.status else None
                cls = "" if ok is None else (" class='pass'" if ok else " class='fail'")
                parts.append(f"<tr{cls}>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>")
            parts.append("</table>")
        for file, caption in sec.images:
            data = base64.b64encode((root / file).read_bytes()).decode("ascii")
            mime = "image/gif" if file.endswith(".gif") else "image/png"
            parts.append(
                f"<figure><img src='data:{mime};base64,{data}' alt='{html.escape(caption)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>"
            )
    parts.append("</body></html>")
    return "\n".join(parts)


def write_document(root: Path, name: str, title: str, secs: list[Section]) -> None:
    """``root/NAME.md`` and ``root/NAME.html``."""
    with atomic_open(root / f"{name}.md") as handle:
        handle.write(markdown(title, secs) + "\n")
    with atomic_open(root / f"{name}.html") as handle:
        handle.write(self_contained_html(title, secs, root) + "\n")


def plain_report(
    root: Path, title: str, summaries: list[tuple[str, str]], results: dict[str, Any]
) -> None:
    """The report of an experiment that writes none of its own (``report.md``, ``report.html``):
    each stage's one-line summary and seconds, the tests of ``results`` (successes of trials)
    and its claims."""
    seconds = results.get("seconds") or {}
    secs = [
        Section(
            "Stages",
            table=(
                ["stage", "summary", "seconds"],
                [[name, line, str(seconds.get(name, "-"))] for name, line in summaries],
            ),
        )
    ]
    tests = results.get("tests") or {}
    if tests:
        rows = [
            [name, f"{t['successes']} / {t['trials']}", f"{100 * t['success_rate']:.1f} %"]
            for name, t in tests.items()
        ]
        secs.append(Section("Tests", table=(["test", "successes", "success"], rows)))
    if results.get("claims"):
        secs.append(claims_section(results["claims"]))
    write_document(root, "report", title, secs)
