"""What the settings name — mazes, connections, rules — is checked before a run does any work
(``Settings.check_names``, called by the runner's ``prepare`` for every section): a bad value is
one line naming the file, line and setting, exit status 2, and nothing is written, so the
corrected command runs (before, a run was refused when the stage reading the setting began, after
the evolution before it, and its folder blocked the corrected command)."""

from __future__ import annotations

import importlib.resources
import json
import re

import pytest

from mbn.cli.main import main
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import prepare, replace_section, run_experiment
from mbn.experiments.registry import find, registered
from mbn.experiments.reproduce import REPRODUCE

EXPERIMENTS = tuple(registered())


def _experiment(name):
    return find(name).load()


def _argv(name, config, out):
    command = ["reproduce"] if name == "reproduce" else ["run", name]
    return [*command, "--config", str(config), "--out", str(out), "--quiet"]


@pytest.mark.parametrize("name", EXPERIMENTS)
@pytest.mark.parametrize("quick", [False, True])
def test_every_experiments_defaults_and_quick_preset_pass_the_checks(name, quick):
    _experiment(name).config(quick=quick).check()


#: ``(experiment, settings file, what the one line says after "mbn: error: s.toml:")``
BAD = [
    ("reproduce", '[tests]\nmaze = "fig5"\n', r"2: tests\.maze: unknown maze 'fig5': neither a"),
    ("reproduce", '[tests]\nmaze = "tiles3"\n', r"2: tests\.maze: maze 'tiles3' has 3-colour"),
    (
        "noise",
        '[tests]\nheldout_maze = "cross_L"\n',
        r"2: tests\.heldout_maze: maze 'cross_L' has no tiles, and an MBN is tested in it",
    ),
    (
        "new-behaviours",
        '[tests3]\nmaze = "gone.maze"\n',
        r"2: tests3\.maze: gone\.maze: no such file$",
    ),
    (
        "programs-vs-dynamics",
        '[tests3]\n\nheldout_maze = "x"\n',
        r"3: tests3\.heldout_maze: unknown maze 'x'",
    ),
    (
        "reproduce",
        '[lf_search]\ncandidates = ["W[1,0]", "W[1,1]", "W[5,2]"]\n',
        r"2: lf_search\.candidates\[2\]: W\[5,2\] is not a connection of the followers' "
        r"network \(3 neurons, 3 inputs",
    ),
    (
        "reproduce",
        '[lf_search]\ncandidates = ["W[1,0]", "W[1,1]", "W[1,0]"]\n',
        r"2: lf_search\.candidates\[2\]: W\[1,0\] is listed twice$",
    ),
    (
        "new-behaviours",
        '[im_full]\nconnections = ["W[1,0]", "W[1,1]", "W[1,2]"]\n',
        r"2: im_full\.connections: WE\[1,0\] is not listed, and LF may re-evolve it "
        r"\(\[lf_search\] candidates\)",
    ),
    (
        "reproduce",
        "[multiplier]\nneurons = 5\n",
        r"2: multiplier\.neurons: the shipped multipliers have 3 or 6 neurons, not 5; set "
        r"\[multiplier\] retrain = true",
    ),
    (
        "reproduce",
        '[noise]\nsonar_std = 0.02\n[pm]\nreward = "memory"\n',
        r"4: pm\.reward = 'memory': a PM evolved on robot episodes under \[noise\]",
    ),
    (
        "new-behaviours",
        '[programs]\nrules = ["SRL"]\n[mbn3]\ntile_rules = ["right", "left", "straight-left"]\n',
        r"4: mbn3\.tile_rules: straight-left has no program: right and left are RF's and LF's, "
        r"\[programs\] rules learns straight-right$",
    ),
    # a test maze named as a validation maze (before: accepted in silence)
    (
        "reproduce",
        '[validation]\nmaze = "fig4"\n',
        r"2: validation\.maze: 'fig4' is a test maze \(\[tests\] maze\); a maze that validates "
        r"candidates during evolution must be one no test uses$",
    ),
    (
        "ablations",
        '[validation]\nextra_mazes = ["validation2", "heldout"]\n',
        r"2: validation\.extra_mazes\[1\]: 'heldout' is a test maze \(\[tests\] heldout_maze\)",
    ),
    (
        "new-behaviours",
        '[programs]\nvalidation_mazes = ["tiles3_heldout"]\n',
        r"2: programs\.validation_mazes\[0\]: 'tiles3_heldout' is a test maze "
        r"\(\[tests3\] heldout_maze\)",
    ),
    # [programs] rules = [] (before: accepted in silence)
    (
        "new-behaviours",
        "[programs]\nrules = []\n",
        r"2: programs\.rules: no rule: the stage learns at least one new rule by programs$",
    ),
]


@pytest.mark.parametrize(("name", "text", "says"), BAD)
def test_a_bad_named_setting_is_one_line_at_the_start_and_leaves_nothing(
    capsys, tmp_path, name, text, says
):
    config = tmp_path / "s.toml"
    config.write_text(text)
    out = tmp_path / "run"
    code = main(_argv(name, config, out))
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2 and len(lines) == 1, captured.err
    assert lines[0].startswith(f"mbn: error: {config}:")
    assert re.search(says, lines[0].removeprefix(f"mbn: error: {config}:")), lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    assert not out.exists()  # no folder, no run.json: the corrected command is not blocked


def test_a_copy_of_a_test_maze_under_another_name_is_a_test_maze(capsys, tmp_path):
    copy = tmp_path / "mine.maze"
    copy.write_text(importlib.resources.files("mbn.data").joinpath("mazes/fig4.maze").read_text())
    config = tmp_path / "s.toml"
    config.write_text(f'[validation]\nmaze = "{copy}"\n')
    code = main(_argv("reproduce", config, tmp_path / "run"))
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == (
        f"mbn: error: {config}:2: validation.maze: '{copy}' is a test maze ([tests] maze); a maze "
        "that validates candidates during evolution must be one no test uses"
    )


def test_a_refused_config_leaves_the_run_in_out_as_it_was_and_the_corrected_one_runs(
    capsys, tmp_path
):
    """``--force`` with a bad setting clears nothing; a fresh ``--out`` is not made, so the
    corrected command starts (its ``prepare`` writes ``run.json``) without --resume or
    --force."""
    out = tmp_path / "run"
    prepare(REPRODUCE, RunDir(out), 0, REPRODUCE.config(), resume=False, force=False)
    (out / "stages" / "rf.json").write_text("{}")
    before = {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    bad = tmp_path / "bad.toml"
    bad.write_text('[tests]\nmaze = "fig5"\n')
    for flag in ("--force", "--resume"):
        assert main([*_argv("reproduce", bad, out), flag]) == 2
        assert "tests.maze: unknown maze 'fig5'" in capsys.readouterr().err
        assert {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    fresh = tmp_path / "fresh"
    assert main(_argv("reproduce", bad, fresh)) == 2 and not fresh.exists()
    good = tmp_path / "good.toml"
    good.write_text('[tests]\nmaze = "fig4"\n')
    from mbn.cli.reproduce import effective_config

    prepare(REPRODUCE, RunDir(fresh), 0, effective_config(good, False), resume=False, force=False)
    assert json.loads((fresh / "run.json").read_text())["config"]["tests"]["maze"] == "fig4"


def test_a_config_made_in_code_is_checked_too_and_named_without_a_file(tmp_path):
    config = REPRODUCE.config(quick=True)
    config = replace_section(config, config["tests"].replace(heldout_maze="nowhere"))
    with pytest.raises(MbnInputError, match=r"^tests\.heldout_maze: unknown maze 'nowhere'"):
        run_experiment(REPRODUCE, tmp_path / "run", seed=0, config=config, log=lambda _: None)
    assert not (tmp_path / "run").exists()


def test_retrain_is_applied_before_the_multiplier_size_is_checked(tmp_path):
    from mbn.cli.reproduce import effective_config

    path = tmp_path / "m.toml"
    path.write_text("[multiplier]\nneurons = 5\n")
    effective_config(path, False, retrain=True).check()  # trains one of 5 neurons: accepted
    with pytest.raises(MbnInputError, match=r"m\.toml:2: multiplier\.neurons: the shipped"):
        effective_config(path, False).check()
