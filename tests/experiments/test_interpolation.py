"""The switch between programs (stage ``interpolation``, ``mbn run switch``)."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.experiments.stages.interpolation import (
    AlphaPoint,
    InterpolationResult,
    PairSweep,
    crossing,
    probes,
)
from mbn.experiments.switch.report import claims
from mbn.world.sensors import SensorConfig


def test_crossing_interpolates_the_first_rise_through_a_level():
    alphas = [0.0, 0.25, 0.5, 0.75, 1.0]
    assert crossing(alphas, [0.0, 0.0, 0.4, 0.8, 1.0], 0.5) == pytest.approx(0.5625)
    assert crossing(alphas, [0.0, 0.2, 0.2, 0.2, 0.2], 0.5) is None  # never reaches it
    assert crossing(alphas, [0.6, 0.2, 0.7, 1.0, 1.0], 0.5) is None  # starts above it
    # alphas without a differing pass are skipped
    assert crossing(alphas, [0.0, None, None, 1.0, 1.0], 0.5) == pytest.approx(0.375)


def test_the_probes_read_the_crossroads_walls():
    inputs = probes(SensorConfig())
    right, left, front = range(3)  # I1 right, I2 left, I3 front (eq. 3)
    corridor = inputs["corridor"]
    assert corridor[right] == pytest.approx(corridor[left], abs=0.02) and corridor[left] > 0.3
    assert corridor[front] < 0.05  # the south arm, the junction and the north arm ahead
    # at a junction's centre the side sonars see the corners of the arms: an open side reads
    # nearer than nothing, but farther than a wall
    lsr = inputs["LSR"]
    assert lsr[front] < 0.05 and lsr[right] == pytest.approx(lsr[left], abs=0.02)
    assert lsr[left] < corridor[left] - 0.1
    # the right-only crossroad has walls left and ahead
    r = inputs["R"]
    assert r[left] > r[right] + 0.1 and r[front] > 0.3
    ls = inputs["LS"]
    assert ls[right] > ls[left] + 0.1 and ls[front] < 0.05
    assert inputs["LR"][front] > 0.3


def _point(alpha, first, second, trials=10, first_exits=0, second_exits=0):
    return AlphaPoint(
        alpha=alpha,
        trials=trials,
        as_first=first,
        as_second=second,
        both=0,
        neither=trials - first - second,
        stalled=0,
        differing=first_exits + second_exits,
        first_exits=first_exits,
        second_exits=second_exits,
    )


def _stage(width, ends=(10, 10)):
    pair = PairSweep(
        first="right",
        second="left",
        points=[_point(0.0, 0, ends[1], second_exits=20), _point(1.0, ends[0], 0, first_exits=20)],
        alpha_half=0.5 if width is not None else None,
        width=width,
    )
    data = InterpolationResult(
        sha256="0" * 64, mazes=["grid:1"], trials_per_program=10, seconds=60.0, probes={},
        pairs={"right:left": pair},
    )  # fmt: skip
    return {"interpolation": data.to_json()}


@pytest.mark.parametrize(
    ("width", "ends", "verdicts"),
    [
        (0.1, (10, 10), [True, True]),
        (0.3, (10, 10), [True, False]),  # a switch wider than 0.25 in alpha
        (None, (10, 10), [True, False]),  # never crosses from 10 % to 90 %
        (0.1, (9, 10), [False, True]),  # P1 passes 90 % < 95 %
    ],
)
def test_the_claims_state_their_criteria_and_judge_by_them(width, ends, verdicts):
    rows = claims(_stage(width, ends))
    assert [r["pass"] for r in rows] == verdicts
    assert rows[0]["target"] == ">= 95% each" and rows[1]["target"] == "width <= 0.25"
    assert f"{ends[0]}/10" in rows[0]["measured"]


def test_a_point_s_share_is_of_the_differing_passes():
    assert _point(0.5, 0, 0, first_exits=3, second_exits=1).first_share == 0.75
    assert _point(0.5, 0, 0).first_share is None
    data = InterpolationResult.from_json(_stage(0.1)["interpolation"])
    assert np.isclose(data.pairs["right:left"].points[1].first_share, 1.0)


@pytest.mark.parametrize(
    ("pairs", "message"),
    [
        (("right:right",), "pairs a program with itself"),
        (("right-left",), "is not FIRST:SECOND"),
        (("right:up",), r"'right:up': unknown rule 'up'"),
        ((), "at least one pair"),
    ],
)
def test_bad_pairs_are_refused_before_any_stage_runs(pairs, message):
    from mbn.errors import MbnInputError
    from mbn.experiments.stages.interpolation import InterpolationSettings

    with pytest.raises(MbnInputError, match=message):
        InterpolationSettings(pairs=pairs)


def test_a_pair_needs_programs_the_run_makes(tmp_path):
    import subprocess
    import sys

    config = tmp_path / "bad.toml"
    config.write_text('[interpolation]\npairs = ["right:right-left"]\n')
    done = subprocess.run(
        [sys.executable, "-m", "mbn", "run", "switch", "--quick", "--config", str(config),
         "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2
    assert "interpolation.pairs[0]: right-left has no program" in done.stderr
    assert done.stderr.count("\n") == 1 and not (tmp_path / "run").exists()
