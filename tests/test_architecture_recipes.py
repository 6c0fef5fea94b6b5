"""The recipes of ``docs/architecture.md`` run as written: the Python blocks of "Adding a stage",
"Adding a maze family or a rule" and "Adding a maze format", saved as the files they name and
imported or run, do what the text says of them. ("Adding a sensor" and "Adding a controller
kind" are run by ``tests/world/test_senses.py`` and ``tests/controllers/test_kinds.py``.)"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mbn.experiments.crossroads import CrossroadTask, rule_arm
from mbn.experiments.maze_task import MazeTask
from mbn.experiments.registry import load_object
from mbn.experiments.stages.common import tile_family, validation_maze_names
from mbn.world.mazes import families
from mbn.world.mazes.load import load_maze, load_mazes
from mbn.world.rules import parse_rule
from tests.registries import isolate

ARCHITECTURE = Path(__file__).parents[1] / "docs" / "architecture.md"
#: A fenced block: its language and its text.
_BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.M | re.S)


def section(title: str) -> str:
    """The text of the ``###`` section ``title``, up to the next heading of its level or
    above (``##`` or ``###``: a ``#`` line in a block is a comment)."""
    text = ARCHITECTURE.read_text()
    start = text.index(f"\n### {title}\n")
    end = re.compile(r"^#{2,3} ", re.M).search(text, start + 5)
    return text[start : end.start() if end else len(text)]


def files(title: str) -> dict[str, str]:
    """The section's Python blocks, by the file each names on its first line (``# NAME.py``):
    every Python block of a recipe is a file."""
    found = {}
    for language, text in _BLOCK.findall(section(title)):
        assert language == "python", language
        first = text.splitlines()[0]
        assert re.fullmatch(r"# [\w.-]+\.py", first), first
        found[first[2:]] = text
    return found


@pytest.fixture
def own(monkeypatch):
    """What the recipes register stays in the test."""
    isolate(monkeypatch)


def _save(tmp_path: Path, title: str, name: str) -> Path:
    recipe = files(title)
    assert list(recipe) == [name]
    path = tmp_path / name
    path.write_text(recipe[name])
    return path


def test_the_family_and_rule_recipe_registers_what_it_says(own, tmp_path):
    with pytest.raises(Exception, match="unknown rule 'u-turn'"):
        parse_rule("u-turn")
    path = _save(tmp_path, "Adding a maze family or a rule", "my_rule.py")
    experiment = load_object(f"{path}:EXPERIMENT")
    # the rule, its fitness, the crossroads' arm of a rule that turns back
    rule = parse_rule("u-turn")
    assert rule.exit(frozenset({"right", "straight", "left"})) == "back"
    assert CrossroadTask(rule="u-turn").fitness == "stay-moving"
    assert CrossroadTask(rule="right").fitness == "branch"
    assert rule_arm("LSR", "u-turn") == "B"
    # the family: generated, named by its own splits, the MBN's tiles finding it
    fam = families.family("uturns")
    maze = families.generate("uturns", 500_000)
    assert families.check(maze, fam) == [] and {t.colors for t in maze.tiles} == {1, 2, 3}
    assert load_maze("uturns:500000").name == "uturns:500000"
    assert len(load_mazes("uturns/test")[0]) == 100
    assert tile_family(("right", "left", "u-turn")) == "uturns"
    # the experiment's settings select them
    config = experiment.config(quick=True)
    assert config["episodes"].family == "uturns" and config["programs"].rules == ("u-turn",)
    assert config["mbn3"].tile_rules == ("right", "left", "u-turn")
    sections = {"episodes": config["episodes"], "validation": config["validation"]}

    class Ctx:
        def section(self, cls):
            return sections[cls.section]

    assert validation_maze_names(Ctx(), "u-turn") == ["uturns:500000", "uturns:500001"]
    assert validation_maze_names(Ctx(), "tiles", tile_rules=("right", "left", "u-turn")) == [
        "uturns:500000",
        "uturns:500001",
    ]
    task = MazeTask(rule="u-turn", family="uturns", pool=4, mazes=2, starts=2, seed=1)
    assert all(s in range(0, 500_000) for s in task.pool_seeds())


def test_the_format_recipe_reads_its_files(own, tmp_path):
    path = _save(tmp_path, "Adding a maze format", "my_format.py")
    load_object(f"{path}:read_rows")  # imported: the format registered
    rows = tmp_path / "corridor.rows"
    rows.write_text("1.2\nxxxxxxx\nxo>ooox\nxxxxxxx\n")
    maze = load_maze(str(rows))
    assert maze.name == "corridor" and len(maze.starts) == 1
    assert np.asarray(maze.grid).shape == (3, 7)
    assert maze.cell == pytest.approx(1.2)


@pytest.mark.slow
def test_the_family_and_rule_recipes_experiment_runs_end_to_end(own, tmp_path):
    """Its quick run: u-turn learned by programs on the family's maze episodes, validated in its
    validation split, and put in force by the MBN's three-colour tile."""
    from mbn.experiments.pipeline import run_experiment

    path = _save(tmp_path, "Adding a maze family or a rule", "my_rule.py")
    experiment = load_object(f"{path}:EXPERIMENT")
    config = experiment.config(quick=True)
    results = run_experiment(experiment, tmp_path / "run", seed=0, config=config, log=print)
    found = results["stages"]["programs"]["rules"]["u-turn"]
    assert found["validation_im"]["trials"] > 0
    assert results["stages"]["mbn3"]["tile_rules"] == ["right", "left", "u-turn"]
    programs = json.loads((tmp_path / "run" / "controllers" / "im_full_programs.json").read_text())
    assert "u-turn" in programs["programs"]


def first_block(heading: str) -> str:
    """The first Python code block of the section ``### heading``."""
    text = ARCHITECTURE.read_text()
    start = text.index(f"### {heading}\n")
    end = text.find("\n## ", start)
    section = text[start : end if end > 0 else len(text)]
    blocks = re.findall(r"^```python\n(.*?)^```", section, re.M | re.S)
    assert blocks, f"no python block under ### {heading}"
    return blocks[0]


def test_the_recipe_finds_the_block_of_its_own_section():
    code = first_block("Adding a stage")
    assert "class ProductCheckStage(Stage[ProductCheck])" in code
    assert "Your own experiment" not in code


def test_adding_a_stage_runs_as_written(tmp_path):
    """The stage of the recipe, in a file of its own, runs after the library's multiplier: its
    typed result lands in ``stages/product_check.json`` in the record's order and in
    ``results.json`` (the same seed giving the same result is the battery's to check)."""
    lab = tmp_path / "my_lab"
    lab.mkdir()
    (lab / "product_check.py").write_text(first_block("Adding a stage"))
    ref = f"{lab / 'product_check.py'}:EXPERIMENT"
    outs = [tmp_path / "run"]
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


def test_extension_modules_make_a_recipe_known_to_every_command(own, tmp_path, monkeypatch, capsys):
    from mbn import extensions
    from mbn.cli.main import main

    monkeypatch.setattr(extensions, "_loaded", set())
    _save(tmp_path, "Adding a maze family or a rule", "my_rule.py")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["mazes", "families", "--json"]) == 0
    assert "uturns" not in json.loads(capsys.readouterr().out)["families"]
    monkeypatch.setenv("MBN_EXTENSIONS", "my_rule")
    assert main(["mazes", "families", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)["families"]
    assert listed["uturns"]["tile_rules"] == ["right", "left", "u-turn"]
    out = tmp_path / "u.maze"
    assert main(["mazes", "generate", "uturns", "--seed", "500000", "--out", str(out)]) == 0
    assert load_maze(str(out)).tiles
    # a module that cannot be imported: one line, exit 2, where it was named
    monkeypatch.setenv("MBN_EXTENSIONS", "my_rule, no_such_lab_module")
    assert main(["mazes"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("mbn: error: MBN_EXTENSIONS: cannot import 'no_such_lab_module'")
    assert len(err.splitlines()) == 1
