"""``docs/tutorial.md`` as a new user follows it: its file written where it says, its commands
run in order in a folder of their own. The whole tutorial (two quick seeds) is a slow test;
the file, its settings and the commands that compute nothing are in CI."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from mbn.experiments.registry import load_object

TUTORIAL = Path(__file__).parents[1] / "docs" / "tutorial.md"
#: A fenced block: its language and its text.
_BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.M | re.S)


def blocks() -> list[tuple[str, str]]:
    """The tutorial's fenced blocks, ``(language, text)``, in order."""
    return [(m[1], m[2]) for m in _BLOCK.finditer(TUTORIAL.read_text())]


def files() -> dict[str, str]:
    """The files the tutorial has the reader save: a Python block whose first line is
    ``# NAME.py``."""
    found = {}
    for language, text in blocks():
        first = text.splitlines()[0]
        if language == "python" and re.fullmatch(r"# [\w.-]+\.py", first):
            found[first[2:]] = text
    return found


def commands() -> list[str]:
    """The tutorial's shell commands, one per line of its ``bash`` blocks, in order."""
    return [
        line
        for language, text in blocks()
        if language == "bash"
        for line in text.splitlines()
        if line.strip()
    ]


def _folder(tmp_path: Path) -> Path:
    for name, text in files().items():
        (tmp_path / name).write_text(text)
    return tmp_path


def _run(line: str, cwd: Path) -> subprocess.CompletedProcess:
    """A command line as a shell runs it, ``mbn`` being this interpreter's."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    return subprocess.run(
        ["bash", "-c", f"set -o pipefail; {line}"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )


def test_the_tutorial_has_its_file_and_its_commands():
    assert list(files()) == ["my_behaviour.py"]
    lines = commands()
    assert any(c.startswith("mbn run my_behaviour.py:EXPERIMENT --quick") for c in lines)
    assert any(c.startswith("mbn sweep --experiment my_behaviour.py:EXPERIMENT") for c in lines)
    # every command is mbn's or reads what mbn wrote
    assert all(re.match(r"(mbn|grep|cat) ", c) for c in lines), lines


def test_the_tutorials_experiment_learns_its_rule_and_adds_it_to_an_mbn(tmp_path):
    folder = _folder(tmp_path)
    experiment = load_object(f"{folder / 'my_behaviour.py'}:EXPERIMENT")
    for quick in (False, True):
        config = experiment.config(quick=quick)
        assert config["programs"].rules == ("right-left",)
        assert config["mbn3"].tile_rules == ("right", "left", "right-left")
    assert experiment.config(quick=True)["programs"].generations == 10
    names = [stage.name for stage in experiment.registry]
    assert names[-4:] == ["im_full", "programs", "mbn3", "tests3"]


def test_the_tutorials_look_before_you_run_shows_the_rule(tmp_path):
    folder = _folder(tmp_path)
    look = [c for c in commands() if "--print-config" in c or c.startswith("grep")]
    assert len(look) == 2
    for line in look:
        done = _run(line, folder)
        assert done.returncode == 0, done.stderr
    assert 'rules = ["right-left"]' in done.stdout


@pytest.mark.slow  # two quick seeds of the new behaviour: minutes
def test_the_whole_tutorial_runs(tmp_path):
    folder = _folder(tmp_path)
    for line in commands():
        done = _run(line, folder)
        assert done.returncode == 0, f"{line}\n{done.stdout}\n{done.stderr}"
    sweep = json.loads((folder / "runs" / "right-left-sweep" / "sweep.json").read_text())
    assert sorted(sweep["runs"]) == ["0", "1"]
    assert all(run["state"] == "done" for run in sweep["runs"].values())
    results = json.loads((folder / "runs" / "right-left" / "results.json").read_text())
    assert "right-left" in results["config"]["programs"]["rules"]
