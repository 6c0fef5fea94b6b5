"""The maze data: merging solid cells into rectangles."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.mazes.model import merge_cells, merge_grid


def test_merge_cells_with_rectangular_cells_and_an_origin():
    solid = np.array([[True, False], [True, True]])
    np.testing.assert_allclose(
        merge_cells(solid, 2.0, 0.5, origin=(1.0, -1.0)),
        [[1.0, 3.0, -0.5, 0.0], [1.0, 5.0, -1.0, -0.5]],
    )
    np.testing.assert_allclose(merge_cells(solid, 1.0), [[0, 1, 1, 2], [0, 2, 0, 1]])
    with pytest.raises(MbnInputError, match="needs 3 x edges"):
        merge_grid(solid, np.arange(4.0), np.arange(3.0))
