"""Every ``mbn`` command's ``--help``: an example of the command itself that the parser accepts,
and no run time of its own (how long a run takes is the README's, Set-up)."""

from __future__ import annotations

import argparse
import re
import shlex

import pytest

from mbn.cli.main import build_parser


def _commands() -> dict[tuple[str, ...], argparse.ArgumentParser]:
    """Every command and command group of ``mbn`` (the words after ``mbn``) -> its parser."""
    found: dict[tuple[str, ...], argparse.ArgumentParser] = {(): build_parser()}
    todo = [()]
    while todo:
        words = todo.pop()
        for action in found[words]._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, parser in action.choices.items():
                    found[(*words, name)] = parser
                    todo.append((*words, name))
    return found


COMMANDS = _commands()


def _examples(text: str) -> list[list[str]]:
    """The command lines of a help text's examples (``  mbn ...``, a description after two or
    more spaces left out; a line ending in a backslash goes on on the next)."""
    lines, out, pending = text.splitlines(), [], ""
    for line in lines:
        if pending:
            line, pending = pending + " " + line.strip(), ""
        if not line.startswith("  mbn "):
            continue
        if line.endswith("\\"):
            pending = line[:-1]
            continue
        command = re.split(r"\s{2,}", line.strip())[0]
        out.append(shlex.split(command.split(" > ")[0])[1:])
    return out


def test_the_commands_are_all_found():
    names = {" ".join(w) for w in COMMANDS}
    assert {"mul", "mul train", "pnn", "pnn check", "mazes", "reproduce", "run", "sweep"} <= names


@pytest.mark.parametrize("words", sorted(COMMANDS), ids=lambda w: " ".join(w) or "mbn")
def test_every_help_page_has_an_example_of_its_own_command_that_parses(words):
    text = COMMANDS[words].format_help()
    assert re.search(r"^examples?:", text, re.M), f"mbn {' '.join(words)} --help: no example"
    examples = [e for e in _examples(text) if tuple(e[: len(words)]) == words]
    assert examples, f"mbn {' '.join(words)} --help: no example of mbn {' '.join(words)}"
    for argv in _examples(text):
        build_parser().parse_args(argv)  # exits (status 2) on an unknown option or bad value


@pytest.mark.parametrize("words", sorted(COMMANDS), ids=lambda w: " ".join(w) or "mbn")
def test_no_help_page_gives_a_run_time_of_its_own(words):
    text = " ".join(COMMANDS[words].format_help().split())
    assert not re.search(r"about (a|an|\d+) ?(minute|min|hour|h)\b", text), text
    if words in ((), ("reproduce",)):
        assert "README, Set-up" in text
