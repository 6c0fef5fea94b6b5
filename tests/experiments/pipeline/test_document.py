"""Reports as documents: what the Markdown and HTML writers draw of a section."""

from __future__ import annotations

from mbn.experiments.pipeline.document import Section, markdown, self_contained_html


def _sections(rows: list[list[str]]) -> list[Section]:
    return [
        Section(
            "Tests over seeds",
            ["No run has a per-run target here."],
            table=(["test", "seeds meeting"], rows),
            status=[True] * len(rows),
        )
    ]


def test_a_table_with_rows_is_drawn_in_both_formats(tmp_path):
    secs = _sections([["rf", "3/3"]])
    md = markdown("t", secs)
    assert "| test | seeds meeting |" in md and "| rf | 3/3 |" in md
    page = self_contained_html("t", secs, tmp_path)
    assert "<th>test</th>" in page and "<tr class='pass'><td>rf</td>" in page


def test_a_table_without_rows_is_left_out_and_its_text_kept(tmp_path):
    """A sweep of an experiment with no per-run tests (the switch) drew a header over nothing."""
    secs = _sections([])
    md = markdown("t", secs)
    assert "No run has a per-run target here." in md
    assert "| test |" not in md and "---|" not in md
    page = self_contained_html("t", secs, tmp_path)
    assert "No run has a per-run target here." in page and "<table" not in page
