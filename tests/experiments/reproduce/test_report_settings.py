"""Every number the report, the claims and the console lines state about a run's settings is the
run's own (its recorded config or stage data), never a default: one quick run with a settings
file that changes them (the interpreter's time constant and steps, DE, the followers' evolution,
the multiplier, every stage's generations, the tests), its ``report.md``, ``report.html``,
claims and stage lines checked against the file, and against the defaults and the quick
preset, which must appear nowhere in their place.

The tests on the run are slow (a quick run of its own, about 1.5 min on 2 cores: left out of
CI, run with ``pytest -m slow``)."""

from __future__ import annotations

import html
import json
import re
import subprocess
import sys
from collections.abc import Callable
from typing import Any

import pytest

from mbn.experiments.reproduce import REPRODUCE

#: The run's settings file: every value differs from the default and from the quick preset.
SETTINGS = """\
[de]
popsize = 4
F = 0.7
CR = 0.3

[followers]
weight_bound = 15.0
episode_seconds = 12.0
perturbation_copies = 0
perturbation_sigma = 0.2

[interpreter]
tau_ratio = 0.05
substeps = 40

[multiplier]
neurons = 3

[validation]
extra_mazes = []
jitter_per_mark = 1
attempts = 1

[rf]
generations = 2
restarts = 1
variants = 1

[lf_search]
candidates = ["W[1,2]", "WE[1,0]", "WE[1,1]"]
generations = 1
variants = 1

[lf]
generations = 3
finalists = 1
rounds = 1
members = 1
variants = 1
approaches = ["south"]

[pm]
generations = 4
camera_range = 0.9

[tests]
seconds = 25.0
mbn_seconds = 30.0
jitter_per_mark = 1
heldout_repeats = 1
"""


def _plural(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


#: ``(section.key, how the report writes its value)``: the phrases of report.md (and, without
#: the backquotes, of report.html) that state a setting.
REPORTED: tuple[tuple[str, Callable[[Any], str]], ...] = (
    ("interpreter.tau_ratio", lambda v: f"at tau/{1 / v:g} (tau_m = {v:g} tau)"),
    ("interpreter.substeps", lambda v: f"integrated in {v} steps per robot step"),
    ("de.popsize", lambda v: f"population {v},"),
    ("de.F", lambda v: f"F {v:g},"),
    ("de.CR", lambda v: f"CR {v:g};"),
    ("followers.weight_bound", lambda v: f"genes in [-{v:g}, {v:g}]"),
    ("followers.episode_seconds", lambda v: f"crossroad episodes of {v:g} s"),
    ("followers.perturbation_copies", lambda v: f"and {v} copies perturbed"),
    ("followers.perturbation_sigma", lambda v: f"N(0, {v:g}²)"),
    ("multiplier.neurons", lambda v: f"{v}-neuron multiplier, shipped"),
    ("rf.generations", lambda v: f"RF: {_plural(v, 'generation')}"),
    ("lf_search.generations", lambda v: f"evolved {_plural(v, 'generation')} each"),
    ("lf.generations", lambda v: f"each; re-evolved for {_plural(v, 'generation')},"),
    ("pm.generations", lambda v: f"PM: {_plural(v, 'generation')}"),
    ("pm.camera_range", lambda v: f"camera range {v:g} m"),
    ("tests.seconds", lambda v: f"; {v:g} s per trial"),
    ("tests.mbn_seconds", lambda v: f"({v:g} s for the MBN"),
    ("tests.jitter_per_mark", lambda v: f"`_jitter`: {v} per start mark"),
    ("tests.heldout_repeats", lambda v: f"each start mark, then {v - 1} jittered"),
    ("tests.maze", lambda v: f"the start marks of `{v}`"),
    ("tests.heldout_maze", lambda v: f"`_heldout`: maze `{v}`"),
)


def _value(config: dict[str, Any], path: str) -> Any:
    section, key = path.split(".")
    return config[section][key]


@pytest.fixture(scope="session")
def settings_run(tmp_path_factory):
    """``(folder, stdout)`` of ``mbn reproduce --quick --config SETTINGS`` (stage lines on)."""
    folder = tmp_path_factory.mktemp("settings")
    config = folder / "settings.toml"
    config.write_text(SETTINGS)
    out = folder / "run"
    command = ["reproduce", "--quick", "--config", str(config), "--out", str(out), "--seed", "1"]
    proc = subprocess.run(
        [sys.executable, "-m", "mbn", *command],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout


def _texts(out) -> dict[str, str]:
    """report.md, and report.html as text (tags and embedded images out, backquotes gone)."""
    page = re.sub(r'src="data:[^"]+"', "", (out / "report.html").read_text())
    return {
        "report.md": (out / "report.md").read_text(),
        "report.html": html.unescape(re.sub(r"<[^>]+>", "", page)),
    }


@pytest.mark.slow
def test_the_run_recorded_the_settings_file(settings_run):
    out, _ = settings_run
    recorded = json.loads((out / "results.json").read_text())["config"]
    assert recorded["interpreter"] == {"tau_ratio": 0.05, "substeps": 40}
    assert recorded["de"] == {"popsize": 4, "F": 0.7, "CR": 0.3}
    assert json.loads((out / "run.json").read_text())["config"] == recorded


@pytest.mark.slow
def test_every_setting_the_report_states_is_the_runs_and_no_default_stands_in(settings_run):
    out, _ = settings_run
    recorded = json.loads((out / "results.json").read_text())["config"]
    defaults = REPRODUCE.config().to_dict()
    quick = REPRODUCE.config(quick=True).to_dict()
    for file, text in _texts(out).items():
        for path, phrase in REPORTED:
            value = _value(recorded, path)
            said = phrase(value)
            if file == "report.html":
                said = said.replace("`", "")
            assert said in text, f"{file}: {path} = {value!r} not stated ({said!r})"
            for other in (_value(defaults, path), _value(quick, path)):
                if other == value:
                    continue  # a setting the file leaves (the mazes): nothing to tell apart
                wrong = phrase(other)
                if file == "report.html":
                    wrong = wrong.replace("`", "")
                assert wrong not in text, f"{file}: {path}: the default {other!r} stated"
        # the defaults in the words the report used before it read them from the run
        for wrong in ("tau/40", "tau/10", "in 80 steps", "in 20 steps", "6-neuron"):
            assert wrong not in text, f"{file}: {wrong!r}"


@pytest.mark.slow
def test_the_claims_state_the_runs_multiplier(settings_run):
    out, _ = settings_run
    claims = json.loads((out / "results.json").read_text())["claims"]
    row = next(c for c in claims if c["claim"].startswith("The multiplier the pipeline embeds"))
    assert "(3 neurons)" in row["claim"] and "this run uses 3" in row["paper"]
    assert "uses 6" not in json.dumps(claims)
    assert row["measured"].startswith("3-neuron multiplier")


@pytest.mark.slow
def test_the_stage_lines_state_the_runs_generations(settings_run):
    _, stdout = settings_run
    lines = {line.split(":")[0]: line for line in stdout.splitlines() if line.startswith("stage ")}
    assert "after 2 generations" in lines["stage rf"]
    assert "after 3 generations (W_23, WE_21, WE_22)" in lines["stage lf"]
    assert "after 4 generations" in lines["stage pm"]
    assert lines["stage lf_search"].endswith("chose W_23, WE_21, WE_22")
    assert lines["stage multiplier"].startswith("stage multiplier: shipped (multiplier_3.json)")
    assert "programmable W_23, WE_21, WE_22" in lines["stage im"]
