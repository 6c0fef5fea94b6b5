"""Inputs a reliability campaign found crashing, running without end or accepted in silence:
each now runs (where it is valid) or ends in one line and exit status 2 (``docs/bad-input.md``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from mbn.cli.main import main
from mbn.controllers import CTRNNControllerSpec, save_controller
from mbn.networks.ctrnn import make_ctrnn

TRIAL = ("--maze", "fig4", "--behavior", "right")


def run(capsys, *args):
    status = main([str(a) for a in args])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def one_line_error(status, out, err, message):
    """Exit status 2, nothing on stdout, one line on stderr that holds ``message``."""
    assert status == 2, (out, err)
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("mbn") and "Traceback" not in err, err
    assert message in lines[0], err


def straight_spec(**changes) -> CTRNNControllerSpec:
    """A 3-neuron controller that drives straight ahead (speed neuron biased on)."""
    net = make_ctrnn(np.zeros((3, 3)), np.zeros((3, 3)), 0.5, bias=[0.0, 0.0, 3.0])
    return CTRNNControllerSpec(net, behavior="right", **changes)


def write_json(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data))
    return path


# -------------------------------------------------------------------------------------------
# 1. a large controller: the step-stability check in bounded memory
# -------------------------------------------------------------------------------------------


def test_a_1000_neuron_controller_is_checked_and_evaluated(tmp_path, capsys):
    """A 1000-neuron controller (weakly coupled: its 5 ms step is far within the stability
    limit) is checked and runs: exit 0 and the trials of fig4's 10 start marks (the check once
    stacked 1026 Jacobians of 1000 x 1000: a MemoryError)."""
    n = 1000
    rng = np.random.default_rng(0)
    net = make_ctrnn(
        rng.normal(0.0, 1.0, (n, n)) / np.sqrt(n),
        rng.normal(0.0, 1.0, (n, 3)),
        0.5,
        bias=np.r_[0.0, 0.0, 3.0, np.zeros(n - 3)],
    )
    path = tmp_path / "big.json"
    save_controller(path, CTRNNControllerSpec(net, behavior="right"))
    status, out, err = run(
        capsys, "evaluate", "--controller", path, *TRIAL, "--seconds", "1", "--json"
    )
    assert status == 0, err
    result = json.loads(out)
    assert result["trials"] == 10 and result["seconds"] == 1.0
