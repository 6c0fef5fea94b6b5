"""With maze episodes, the stages choose among candidates on the validation split of the
family they are judged in (``docs/generalization.md``, "Validation on the validation split")."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.experiments.stages import tests as tests_stage
from mbn.experiments.stages.common import (
    _joined,
    _validation_trial,
    validation_maze_names,
    validation_record,
)
from mbn.experiments.stages.settings import EpisodeSettings, ValidationSettings
from mbn.world.mazes import families
from mbn.world.mazes.load import load_maze


class Ctx:
    def __init__(self, episodes: EpisodeSettings | None, validation: ValidationSettings):
        from mbn.experiments.stages.tests import TestsSettings

        self._sections = {"validation": validation, "tests": TestsSettings()}
        if episodes is not None:
            self._sections["episodes"] = episodes
        self.seeds = {"validation_jitter": 4}

    def section(self, cls):
        return self._sections[cls.section]


def test_crossroad_runs_validate_in_the_named_mazes():
    ctx = Ctx(EpisodeSettings(kind="crossroads"), ValidationSettings())
    assert validation_maze_names(ctx) == ["validation", "validation2"]
    assert validation_maze_names(ctx, "tiles", ("x",)) == ["validation", "validation2", "x"]
    # an experiment without [episodes] is a crossroad run
    assert validation_maze_names(Ctx(None, ValidationSettings())) == ["validation", "validation2"]


def test_maze_runs_validate_on_the_first_mazes_of_the_validation_split():
    ctx = Ctx(EpisodeSettings(kind="maze"), ValidationSettings(split_mazes=3))
    first = families.SPLITS["validation"].start
    assert validation_maze_names(ctx) == [f"grid:{first + k}" for k in range(3)]
    # an MBN: the family of its tile kinds
    assert validation_maze_names(ctx, "tiles") == [f"tiles2:{first + k}" for k in range(3)]
    three = families.family("tiles3").tile_rules
    names = validation_maze_names(ctx, "tiles", tile_rules=three)
    assert names == [f"tiles3:{first + k}" for k in range(3)]
    for name in names:
        assert families.split_of(int(name.split(":")[1])) == "validation"
    with pytest.raises(MbnInputError, match="no maze family has tiles for the rules left, right"):
        validation_maze_names(ctx, "tiles", tile_rules=("left", "right"))
    # the trials: split_jitter_per_mark starts per mark, and time for the longest route
    mazes = [load_maze(n) for n in names]
    trial = _validation_trial(ctx, "tiles", "right", mazes, three)
    assert trial.repeats == ValidationSettings().split_jitter_per_mark
    assert trial.tile_rules == three
    assert trial.seconds >= ctx.section(tests_stage.TestsSettings).mbn_seconds


def _verdict(rates: list[int], trials: int = 20) -> dict[str, np.ndarray]:
    per = []
    for successes in rates:
        s = np.zeros(trials, bool)
        s[:successes] = True
        per.append({"success": s, "timed_out": np.zeros(trials, bool)})
    return _joined(per)


@pytest.mark.parametrize(
    ("successes", "meets"),
    [
        ([20] * 10, True),  # every maze at 100 %
        ([20] * 9 + [19], True),  # 19/20 = 95 %: at the target
        ([20] * 9 + [10], True),  # pooled 95 %, and 9 of 10 mazes: the share 0.9
        ([20] * 9 + [5], False),  # 9 of 10 mazes, but pooled 92.5 %
        ([20] * 8 + [18, 18], False),  # pooled 98 %, 8 of 10 mazes at 95 %: under the share
    ],
)
def test_maze_runs_need_the_pooled_rate_and_the_share_of_mazes(successes, meets):
    ctx = Ctx(EpisodeSettings(kind="maze"), ValidationSettings())
    verdict = _verdict(successes)
    verdict.update(
        judged=np.zeros(len(verdict["success"])),
        correct=np.zeros(len(verdict["success"])),
        stall=np.zeros(len(verdict["success"])),
    )
    record = validation_record(ctx, verdict)
    assert record["mazes"] == 10
    assert record["mazes_at_target"] == sum(s >= 19 for s in successes)
    assert record["meets_target"] is meets
    # a crossroad run judges the pooled rate alone
    plain = validation_record(
        Ctx(EpisodeSettings(kind="crossroads"), ValidationSettings()), verdict
    )
    assert "mazes" not in plain
    assert plain["meets_target"] == (sum(successes) / 200 >= 0.95)


def test_the_shipped_paper_config_differs_from_the_defaults_only_in_the_crossroad_protocol():
    """``docs/configs/paper.toml`` is the paper's protocol: the crossroads and the followers'
    generations there, every other setting the default (docs/reproduce.md, "Which protocol")."""
    from pathlib import Path

    from mbn.config import read_toml
    from mbn.experiments.behaviours import NEW_BEHAVIOURS
    from mbn.experiments.reproduce import REPRODUCE

    paper_file = Path(__file__).parents[3] / "docs" / "configs" / "paper.toml"
    for experiment in (REPRODUCE, NEW_BEHAVIOURS):
        default = experiment.config().to_dict()
        paper = experiment.config(document=read_toml(paper_file)).to_dict()
        changed = {
            (section, key): value
            for section, table in paper.items()
            for key, value in table.items()
            if default[section][key] != value
        }
        assert changed == {
            ("episodes", "kind"): "crossroads",
            ("rf", "generations"): 300,
            ("lf", "generations"): 70,
        }
