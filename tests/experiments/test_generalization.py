"""Judging controllers across a family's splits (``docs/generalization.md``): the helpers of
:mod:`mbn.experiments.generalization`, and the ``generalization`` stage of the session's quick
reproduction."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mbn.experiments.generalization import (
    GeneralizationResult,
    JudgedRecord,
    failure_causes,
    generalization_claims,
    junction_kind,
    junction_kinds,
    meets_generalization,
    performance_profile,
)
from mbn.world.mazes import families
from mbn.world.rules import open_mask
from tests.split_records import split_record_of


@pytest.mark.parametrize(
    ("exits", "kind"),
    [
        (("left", "straight", "right"), "plus"),
        (("left", "right"), "T left-right"),
        (("straight", "right"), "T straight-right"),
        (("left", "straight"), "T left-straight"),
        (("right",), "corner right"),
        (("left",), "corner left"),
        (("straight",), "straight"),
        ((), "dead end"),
        (("back", "left"), "corner left"),  # the way back is not an exit of the kind
    ],
)
def test_junction_kinds_are_named_by_their_open_exits(exits, kind):
    assert junction_kind(open_mask(exits)) == kind


def test_passes_are_counted_by_kind_and_correctness():
    plus, t = open_mask(["left", "straight", "right"]), open_mask(["left", "right"])
    verdict = {
        "open": np.array([[plus, t, -1], [plus, plus, t]]),
        "exits": np.array([[1, 3, -1], [2, 1, 1]]),
        "expected": np.array([[1, 1, -1], [1, 1, 1]]),
    }
    assert junction_kinds(verdict) == {
        "T left-right": {"passes": 2, "correct": 1},
        "plus": {"passes": 3, "correct": 2},
    }


def test_failures_are_counted_once_by_their_first_cause():
    verdict = {
        "success": np.array([True, False, False, False, False]),
        "correct": np.array([3, 2, 3, 3, 1]),
        "judged": np.array([3, 3, 3, 2, 1]),
        "stall": np.array([0.0, 0.5, 0.3, 0.0, 0.01]),
        "timed_out": np.array([False, False, False, True, True]),
    }
    # trial 2: wrong exit (and stalled: counted as wrong exit); 3: stalled; 4 and 5: timed out
    assert failure_causes(verdict) == {"failed": 4, "wrong_exit": 1, "stalled": 1, "timed_out": 2}


@pytest.mark.parametrize(
    ("successes", "meets"),
    [
        ([10] * 10, True),
        ([10] * 9 + [5], True),  # pooled 95 %, 9 of 10 mazes
        ([10] * 9 + [4], False),  # pooled 94 %
        ([10] * 8 + [9, 9], False),  # pooled 98 %, 8 of 10 mazes at 95 %
    ],
)
def test_the_generalization_targets_are_the_pooled_rate_and_the_share_of_mazes(successes, meets):
    assert meets_generalization(split_record_of(successes)) is meets
    assert (
        meets_generalization(split_record_of(successes).to_json()) is meets
    )  # as results.json has it


def test_the_performance_profile_is_the_share_of_mazes_at_each_rate():
    out = performance_profile([1.0, 0.9, 0.5, 0.95], xs=np.array([0.5, 0.9, 0.95, 1.0]))
    assert out["fraction"] == [1.0, 0.75, 0.5, 0.25]


def test_the_quick_run_judges_its_controllers_on_every_split(quick_run):
    out, _ = quick_run
    results = json.loads((out / "results.json").read_text())
    assert results["maze_splits"] == {
        name: [r.start, r.stop - 1] for name, r in families.SPLITS.items()
    }
    assert results["mazes_looked_into"] == {"tiles3": [2_000_078]}
    config = results["config"]["generalization"]
    data = results["stages"]["generalization"]["controllers"]
    assert list(data) == ["rf", "lf", "im_rf", "im_lf", "mbn"]
    for name, rec in data.items():
        family = "tiles2" if name == "mbn" else "grid"
        assert rec["family"] == family
        splits = rec["splits"]
        assert list(splits) == ["train", "validation", "test", "zero-shot"]
        test = [m["maze"] for m in splits["test"]["mazes"]]
        first = families.SPLITS["test"].start
        assert test == [f"{family}:{first + k}" for k in range(config["test_mazes"])]
        for split in ("train", "validation"):
            seeds = [int(m["maze"].split(":")[1]) for m in splits[split]["mazes"]]
            assert len(seeds) == config["gap_mazes"]
            assert {families.split_of(s) for s in seeds} == {split}
        zero = [m["maze"] for m in splits["zero-shot"]["mazes"]]
        assert zero == list(families.ZERO_SHOT[family])
        for record in splits.values():
            p = record["pooled"]
            assert p["successes"] == sum(m["successes"] for m in record["mazes"])
            assert p["wilson95"][0] <= p["success_rate"] <= p["wilson95"][1]
            assert record["failures"]["failed"] == p["trials"] - p["successes"]
        assert "worst_test_maze" not in rec  # the quick preset: no rerun
    # the MBN's passes by the tile's distance: the same passes as by junction kind
    test = data["mbn"]["splits"]["test"]
    assert sum(v["passes"] for v in test["tile_distances"].values()) == sum(
        v["passes"] for v in test["junction_kinds"].values()
    )
    assert "tile_distances" not in data["rf"]["splits"]["test"]
    # a claims row per controller, judged by the test split
    rows = generalization_claims(results["stages"]["generalization"])
    assert len(rows) == 5
    claims = {c["claim"]: c for c in results["claims"]}
    for row in rows:
        assert claims[row.claim]["pass"] == row.passed
    report = (out / "report.md").read_text()
    assert "## Generalization: mazes drawn from the family" in report
    assert (out / "figures" / "generalization_profile.png").stat().st_size > 0


def test_tile_distances_count_the_free_cells_back_to_the_nearest_tile():
    from mbn.experiments.generalization import tile_distance, tile_distances
    from mbn.world.junctions import cell_of

    maze = families.generate("tiles2", 5)  # a train maze
    # every tile that lies k cells before a T or plus crossing (families.tile_places) is found
    # k cells back from that crossing, entered along the tile's corridor (unless another tile
    # lies nearer to it)
    steps = ((-1, 0), (0, 1), (1, 0), (0, -1))
    for tile, place in zip(maze.tiles, families.tile_places(maze), strict=True):
        r, c = cell_of(maze, tile.x, tile.y)
        for k in place["before"]:
            seen = [
                tile_distance(maze, (r + dr * (k + 1), c + dc * (k + 1)), h)
                for h, (dr, dc) in enumerate(steps)
                if 0 <= r + dr * (k + 1) < maze.grid.shape[0]
                and 0 <= c + dc * (k + 1) < maze.grid.shape[1]
            ]
            # k, or a nearer tile of the same corridor (the nearest counts)
            assert k in seen or min(d for d in seen if d is not None) < k, (tile, place)
    # a crossing entered from a corridor without a tile: none
    grid = np.asarray(maze.grid)
    assert tile_distance(maze, (6, 6), 0) is None and grid[7, 6] != "#"
    # passes are counted by distance, correct where the exit is the rule's
    verdict = {
        "cells": np.array([[[1, 12], [6, 6], [-1, -1]]]),
        "headings": np.array([[3, 0, -1]]),
        "exits": np.array([[1, 2, -1]]),
        "expected": np.array([[1, 1, -1]]),
    }
    assert tile_distances([maze], {maze.name: verdict}) == {
        "0": {"passes": 1, "correct": 1},
        "none": {"passes": 1, "correct": 0},
    }
    # with the stretches before each pass recorded: their steps and stalled moves too
    verdict["stretch_steps"] = np.array([[120, 80, -1]])
    verdict["stretch_stalls"] = np.array([[6, 0, -1]])
    assert tile_distances([maze], {maze.name: verdict}) == {
        "0": {"passes": 1, "correct": 1, "steps": 120, "stalled": 6},
        "none": {"passes": 1, "correct": 0, "steps": 80, "stalled": 0},
    }


def test_a_tile_on_the_corner_a_corridor_begins_at_is_a_switch_in_the_turn():
    from mbn.experiments.generalization import tile_distance
    from mbn.world.mazes.grid_text import parse_maze_text

    corner = """#########
#....1###
#.###.###
#.###....
#^###.###
#########
"""
    # the T junction at row 3, column 5, entered from the north (heading south, 2)
    assert tile_distance(parse_maze_text(corner, "corner"), (3, 5), 2) == "turn"
    straight = corner.replace("#....1###", "#.....###").replace(
        "#.###.###\n#.###....", "#.###1###\n#.###...."
    )
    assert tile_distance(parse_maze_text(straight, "straight"), (3, 5), 2) == 0


def test_the_worst_test_maze_is_run_again_with_its_steps_recorded(quick_run, tmp_path):
    """``[generalization] worst_maze``: the test maze with the fewest successes run again,
    every other step recorded, the same verdicts; the report draws its trials."""
    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.stages.generalization import (
        WORST_FIELDS,
        WORST_RECORD,
        _worst_maze,
        generalization_sections,
    )
    from mbn.experiments.trials import TrialSpec
    from mbn.world.mazes.load import load_mazes

    out, _ = quick_run
    loaded = make_controller(read_controller_spec(out / "controllers" / "lf.json"), None)
    mazes, _ = load_mazes("grid/test:0-2")
    trial = TrialSpec(behavior="left")
    result = evaluate_mazes(mazes, trial, loaded, seconds=60.0, verdicts=True)
    maze, trajectory, record = _worst_maze(mazes, result, trial, loaded, None)
    rates = [r["success_rate"] for r in result["mazes"]]
    assert maze.name == record.maze == mazes[int(np.argmin(rates))].name
    assert (
        record.details["success"] == result["verdicts"][maze.name]["success"].astype(int).tolist()
    )
    assert np.asarray(trajectory.pose).shape[:1] == (len(record.details["success"]),)
    # the report's picture of it
    rundir = RunDir(tmp_path)
    (tmp_path / "figures").mkdir()
    (tmp_path / "records").mkdir()
    rundir.save_trajectories(WORST_RECORD, {"lf": trajectory}, WORST_FIELDS)
    judged = JudgedRecord(
        file="controllers/lf.json",
        behavior="left",
        program=None,
        family="grid",
        splits={},
        worst_test_maze=record,
    )
    data = GeneralizationResult(controllers={"lf": judged}, noise=None)
    sections = generalization_sections(rundir, data)
    # as results.json keeps it, the same sections
    assert [x.title for x in generalization_sections(rundir, data.to_json())] == [
        x.title for x in sections
    ]
    assert sections[-1].title == "Generalization: the worst test maze"
    assert (tmp_path / "figures" / "generalization_worst_lf.png").stat().st_size > 0


def test_the_zero_shot_suite_is_judged_in_a_batch_of_its_own():
    """``[generalization] zero_shot_batch``: the generated splits in one batch, the zero-shot
    suite in another (each under its own longest time limit), in the columns' order; off: one
    batch; no empty batch."""
    from mbn.experiments.stages.generalization import judging_batches

    parts = [("train", ["a"], True), ("test", ["b", "c"], False), ("zero-shot", ["z"], False)]
    assert judging_batches(parts, True) == [parts[:2], parts[2:]]
    assert judging_batches(parts, False) == [parts]
    assert judging_batches(parts[:2], True) == [parts[:2]]
    assert judging_batches(parts[2:], True) == [parts[2:]]
    assert judging_batches([], True) == judging_batches([], False) == []


@pytest.mark.slow  # the stage run again on a copy of the quick run (about 2 min on 2 cores)
def test_the_stage_judges_the_zero_shot_suite_under_its_own_time_limit(quick_run, tmp_path):
    """With ``zero_shot_batch`` the generated mazes run under the longest of their own time
    limits, the zero-shot suite under the longest of its own, each maze's row what judging its
    batch alone gives."""
    import shutil

    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.generalization import evaluate_mazes
    from mbn.experiments.pipeline.rundir import RunDir
    from mbn.experiments.pipeline.runner import run_stage
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.experiments.trials import TrialSpec, route_seconds
    from mbn.world.mazes.load import load_mazes

    out, _ = quick_run
    folder = tmp_path / "run"
    shutil.copytree(out, folder)
    rundir = RunDir(folder)
    manifest = rundir.read_manifest()
    table = manifest["config"]["generalization"]
    table.update(zero_shot_batch=True, splits=["validation", "zero-shot"], gap_mazes=2)
    config = REPRODUCE.config_from_dict(manifest["config"], "test")
    rundir.stage_file("generalization").unlink()
    data = run_stage(REPRODUCE, rundir, "generalization", seed=manifest["seed"], config=config)
    splits = data["controllers"]["lf"]["splits"]
    assert set(splits) == {"validation", "zero-shot"}
    spec = TrialSpec(behavior="left")
    validation, _ = load_mazes("grid/validation:0-1")
    zero, _ = load_mazes("grid/zero-shot")
    assert splits["validation"]["seconds"] == max(route_seconds(m, spec) for m in validation)
    assert splits["zero-shot"]["seconds"] == max(route_seconds(m, spec) for m in zero)
    assert splits["zero-shot"]["seconds"] > splits["validation"]["seconds"]
    loaded = make_controller(read_controller_spec(folder / "controllers" / "lf.json"), None)
    alone = evaluate_mazes(zero, spec, loaded)
    keys = ("maze", "trials", "successes", "timed_out")
    assert splits["zero-shot"]["mazes"] == [{k: r[k] for k in keys} for r in alone["mazes"]]
