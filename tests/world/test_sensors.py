"""The paper's 10 sonars on Stage's ring, the normalisation of S, and the inputs of eq. 3."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.robot import SONAR_POSES
from mbn.world.sensors import PAPER_SONARS, SensorConfig, normalize, paper_inputs


def test_paper_sonars_run_from_the_right_side_round_the_front_to_the_left():
    poses = SONAR_POSES[list(PAPER_SONARS)]
    np.testing.assert_array_equal(poses[:, 2], [-90, -90, -50, -30, -10, 10, 30, 50, 90, 90])
    # s1 and s10 are the rear side transducers, s2 and s9 the front ones
    assert poses[0, 0] < 0 < poses[1, 0] and poses[9, 0] < 0 < poses[8, 0]
    # right side has y < 0, left side y > 0
    assert np.all(poses[:5, 1] < 0) and np.all(poses[5:, 1] > 0)


def test_normalisations():
    d = np.array([0.0, 0.5, 1.0, 2.0, 5.0])
    np.testing.assert_allclose(normalize(d, SensorConfig()), [1.0, 0.75, 0.5, 0.0, 0.0])
    np.testing.assert_allclose(
        normalize(d, SensorConfig(normalization="distance", near=0.5, far=1.5)),
        [0.0, 0.0, 0.5, 1.0, 1.0],
    )
    np.testing.assert_allclose(normalize(d, SensorConfig(normalization="metres")), d)


def test_eq3_inputs():
    S = np.arange(1, 11, dtype=float) / 10  # S1..S10 = 0.1..1.0
    inputs = np.asarray(paper_inputs(S))
    np.testing.assert_allclose(
        inputs,
        [
            0.2 * 0.2 + 0.4 * 0.3 + 0.4 * 0.4,
            0.2 * 0.9 + 0.4 * 0.8 + 0.4 * 0.7,
            0.5 * 0.5 + 0.5 * 0.6,
        ],
    )
    with pytest.raises(MbnInputError, match=r"s1\.\.s10"):
        paper_inputs(np.zeros(16))


def test_paper_positions_need_all_ten():
    assert SensorConfig().paper_positions == tuple(range(10))
    assert SensorConfig(sonars=tuple(range(16))).paper_positions == PAPER_SONARS
    assert SensorConfig(sonars=(0, 1, 2)).paper_positions is None
    with pytest.raises(MbnInputError, match="normalization"):
        SensorConfig(normalization="log")  # type: ignore[arg-type]
