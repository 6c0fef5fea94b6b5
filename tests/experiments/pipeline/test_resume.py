"""Resuming survives what a kill or a careless hand leaves behind: a truncated or empty
checkpoint (one-line notice, the DE starts again from its first generation, same result), a
finished stage whose output was deleted (run again), temporary files of a killed write (removed)."""

from __future__ import annotations

import json
from typing import Any

import jax.numpy as jnp
import numpy as np
import pytest

from mbn.evolution.de import DEConfig
from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment


class SphereStage(Stage):
    """DE on the sphere, checkpointed per generation; writes its best genome to a record."""

    name = "sphere"
    key_id = 1
    outputs = ("records/best.npz",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        config = DEConfig(
            num_dims=3,
            popsize=8,
            maximize=False,
            lower=-5.0,
            upper=5.0,
            init_low=-5.0,
            init_high=5.0,
        )
        de = ctx.evolve(
            "sphere", config, lambda pop: jnp.sum(pop**2, axis=-1), ctx.key, 6, "sphere"
        )
        ctx.rundir.save_record("best", {"genome": np.asarray(de.data["best_genome"])})
        return de.data


EXPERIMENT = Experiment(name="sphere", kind="mbn.sphere", registry=Registry([SphereStage()]))


def _run(folder, lines, **kw):
    return run_experiment(
        EXPERIMENT, folder, seed=3, config=EXPERIMENT.config(), log=lines.append, **kw
    )


@pytest.fixture
def reference(tmp_path):
    return _run(tmp_path / "reference", [])


@pytest.mark.parametrize("damage", ["truncated", "empty", "garbage"])
def test_a_broken_checkpoint_falls_back_to_the_start_of_its_de(tmp_path, reference, damage):
    folder = tmp_path / "run"
    _run(folder, [])
    (folder / "stages" / "sphere.json").unlink()  # as if killed before the stage finished
    path = folder / "checkpoints" / "sphere.npz"
    data = path.read_bytes()
    path.write_bytes(
        {"truncated": data[: len(data) // 2], "empty": b"", "garbage": b"x" * 99}[damage]
    )
    lines: list[str] = []
    results = _run(folder, lines, resume=True)
    notices = [line for line in lines if line.startswith("notice:")]
    assert len(notices) == 1 and "sphere.npz: unreadable checkpoint" in notices[0]
    assert "starts again from its first generation" in notices[0]
    assert results["stages"] == reference["stages"]


def test_a_finished_stage_whose_output_was_deleted_runs_again(tmp_path, reference):
    folder = tmp_path / "run"
    _run(folder, [])
    (folder / "records" / "best.npz").unlink()
    lines: list[str] = []
    results = _run(folder, lines, resume=True)
    assert "notice: stage sphere: records/best.npz is missing; running it again" in lines
    assert (folder / "records" / "best.npz").exists()
    assert results["stages"] == reference["stages"]


def test_temporary_files_of_a_killed_write_are_removed_on_resume(tmp_path):
    folder = tmp_path / "run"
    _run(folder, [])
    left = [folder / ".results.json.abc.tmp", folder / "checkpoints" / ".sphere.npz.x1.tmp"]
    for p in left:
        p.write_text("half")
    _run(folder, [], resume=True)
    assert not any(p.exists() for p in left)
    assert json.loads((folder / "results.json").read_text())["seed"] == 3
