"""The recipes of ``docs/architecture.md`` run as they are written: each section's code block is
taken from the document, saved in a folder outside the checkout, and run."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"


def recipe(heading: str) -> str:
    """The first Python code block of the section ``### heading``."""
    text = DOC.read_text()
    start = text.index(f"### {heading}\n")
    end = text.find("\n## ", start)
    section = text[start : end if end > 0 else len(text)]
    blocks = re.findall(r"^```python\n(.*?)^```", section, re.M | re.S)
    assert blocks, f"no python block under ### {heading}"
    return blocks[0]


def test_the_recipe_finds_the_block_of_its_own_section():
    code = recipe("Adding a stage")
    assert "class ProductCheckStage(Stage[ProductCheck])" in code
    assert "Your own experiment" not in code


def test_adding_a_stage_runs_as_written(tmp_path):
    """The stage of the recipe, in a file of its own, runs after the library's multiplier: its
    typed result lands in ``stages/product_check.json`` in the record's order and in
    ``results.json``; the same seed gives the same result."""
    lab = tmp_path / "my_lab"
    lab.mkdir()
    (lab / "product_check.py").write_text(recipe("Adding a stage"))
    ref = f"{lab / 'product_check.py'}:EXPERIMENT"
    outs = [tmp_path / "run", tmp_path / "again"]
    for out in outs:
        command = [sys.executable, "-m", "mbn", "run", ref, "--quick", "--seed", "4"]
        proc = subprocess.run(
            [*command, "--out", str(out), "--quiet"],
            capture_output=True,
            text=True,
            timeout=600,
            cwd=tmp_path,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
    stage = json.loads((outs[0] / "stages" / "product_check.json").read_text())
    assert list(stage) == ["neurons", "pairs", "max_abs_error"]
    assert stage["pairs"] == 20  # the quick preset
    assert stage["neurons"] == 6  # the library's default multiplier
    assert 0.0 < stage["max_abs_error"] < 0.02  # it multiplies (the reproduction's claim)
    results = [json.loads((o / "results.json").read_text()) for o in outs]
    assert results[0]["stages"]["product_check"] == stage
    assert results[0]["config"]["product_check"] == {"pairs": 20}
    assert results[0]["stages"] == results[1]["stages"]
