"""``mbn sweep --batched``: every seed in one process, their populations evaluated together; each
seed's ``results.json`` is byte for byte that of its run alone, and a batched sweep killed with
SIGKILL resumes to the same files.

They are slow (left out of CI, run with ``pytest -m slow``): a batched quick sweep of two seeds
takes about 2 min on 2 cores; ``tests/experiments/test_batching.py`` checks the batching itself
in CI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mbn.cli.main import main
from tests.conftest import kill_when_written, once

SEEDS = "3-4"


def _sweep(out: Path, *more: str) -> list[str]:
    return [sys.executable, "-m", "mbn", "sweep", "--batched", "--quick", "--seeds", SEEDS,
            "--out", str(out), "--quiet", *more]  # fmt: skip


@pytest.fixture(scope="session")
def batched(tmp_path_factory, worker_id):
    """``(folder, stdout)`` of ``mbn sweep --batched --quick --seeds 3-4``."""

    def build(folder: Path) -> list[str]:
        out = folder / "sweep"
        proc = subprocess.run(_sweep(out), capture_output=True, text=True, timeout=1200)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return [str(out), proc.stdout]

    out, stdout = once(tmp_path_factory, worker_id, "batched", build)
    return Path(out), stdout


@pytest.mark.slow
def test_a_batched_seed_gives_the_results_of_its_run_alone_byte_for_byte(batched, quick_run):
    """Seed 3 batched with seed 4 against ``mbn reproduce --quick --seed 3`` (the session's
    quick run): the same results.json, byte for byte; both seeds ran and were summarized."""
    out, stdout = batched
    alone, _ = quick_run
    assert (out / "seed-3" / "results.json").read_bytes() == (alone / "results.json").read_bytes()
    assert stdout.splitlines()[-1].startswith("sweep: ")
    data = json.loads((out / "sweep.json").read_text())
    assert data["executor"] == "batched"
    for s in (3, 4):
        assert data["runs"][str(s)]["state"] == "done"
        results = json.loads((out / f"seed-{s}" / "results.json").read_text())
        assert results["seed"] == s
        # each seed counted its own robot-steps (not the process's), as its run alone does
        timings = json.loads((out / f"seed-{s}" / "timings.json").read_text())
        assert timings["robot_steps"]["rf"] > 0
    own = json.loads((alone / "timings.json").read_text())["robot_steps"]
    assert json.loads((out / "seed-3" / "timings.json").read_text())["robot_steps"] == own


def test_batched_takes_no_ray_settings(capsys, tmp_path):
    for flag in (["--address", "localhost:6379"], ["--cpus-per-run", "2"]):
        code = main(["sweep", "--batched", "--seeds", "0", "--out", str(tmp_path / "s"), *flag])
        err = capsys.readouterr().err.strip()
        assert code == 2
        assert (
            err == f"mbn: error: --batched runs every seed in this process: it takes no {flag[0]}"
        )
        assert not (tmp_path / "s").exists()


@pytest.mark.slow  # two more quick sweeps (about 6 min on 2 cores)
def test_a_batched_sweep_killed_resumes_to_the_same_files(batched, quick_run, tmp_path):
    """SIGKILL while both seeds evolve their LF search, then the same command: each seed
    resumes from its checkpoints (written every generation, as a run alone writes them) and its
    results.json is the uninterrupted batched sweep's; seed 4 is also the same as its run
    alone."""
    reference, _ = batched
    out = tmp_path / "sweep"
    targets = [out / f"seed-{s}" / "checkpoints" / "lf_search_00.npz" for s in (3, 4)]
    kill_when_written(_sweep(out), targets, timeout=900, settle=0.5)
    assert not any((out / f"seed-{s}" / "results.json").exists() for s in (3, 4))
    again = subprocess.run(_sweep(out), capture_output=True, text=True, timeout=1200)
    assert again.returncode == 0, again.stderr[-3000:]
    data = json.loads((out / "sweep.json").read_text())
    assert all(data["runs"][str(s)]["resumed"] for s in (3, 4))
    for s in (3, 4):
        a = (reference / f"seed-{s}" / "results.json").read_bytes()
        assert (out / f"seed-{s}" / "results.json").read_bytes() == a, s
    alone = tmp_path / "alone"
    proc = subprocess.run(
        [sys.executable, "-m", "mbn", "reproduce", "--quick", "--seed", "4", "--out", str(alone),
         "--quiet"], capture_output=True, text=True, timeout=1200,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (alone / "results.json").read_bytes() == (out / "seed-4" / "results.json").read_bytes()
