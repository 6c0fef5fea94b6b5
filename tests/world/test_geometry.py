"""Properties of the exact geometry: ray casting, sonar readings and collision."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mbn.world.geometry import cast_rays, collides, rect_segments, sonar_ranges
from mbn.world.robot import SONAR_MAX_RANGE

BOX = np.array([[-1.0, 0.0, -1.0, 5.0], [3.0, 4.0, -1.0, 5.0], [0.0, 3.0, -1.0, 0.0]])


def test_ray_hits_the_nearest_segment_and_misses_read_max_range():
    segs = rect_segments(np.array([[2.0, 3.0, -1.0, 1.0], [6.0, 7.0, -1.0, 1.0]]))
    got = cast_rays(jnp.zeros((3, 2)), jnp.array([0.0, np.pi / 2, np.pi]), segs)
    np.testing.assert_allclose(np.asarray(got), [2.0, SONAR_MAX_RANGE, SONAR_MAX_RANGE])
    tall = rect_segments(np.array([[2.0, 3.0, -3.0, 3.0]]))
    oblique = cast_rays(jnp.zeros(2), jnp.array(np.pi / 4), tall)
    np.testing.assert_allclose(float(oblique), 2.0 * np.sqrt(2.0), rtol=1e-12)


def test_body_against_a_wall():
    wall = np.array([[1.0, 2.0, -1.0, 1.0]])
    # the nose is 0.21085 m ahead of the pose
    assert not bool(collides(jnp.array([1.0 - 0.2109, 0.0, 0.0]), wall))
    assert bool(collides(jnp.array([1.0 - 0.2108, 0.0, 0.0]), wall))
    # facing away: the tail is 0.30015 m behind
    assert not bool(collides(jnp.array([1.0 - 0.3002, 0.0, np.pi]), wall))
    assert bool(collides(jnp.array([1.0 - 0.3001, 0.0, np.pi]), wall))


poses = st.tuples(
    st.floats(0.5, 2.5), st.floats(0.5, 4.5), st.floats(-np.pi, np.pi, allow_subnormal=False)
)


@settings(max_examples=40, deadline=None)
@given(
    pose=poses,
    shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
    quarter_turns=st.integers(0, 3),
)
def test_readings_are_bounded_and_invariant_under_rigid_motion(pose, shift, quarter_turns):
    """Rotating (by quarter turns, so walls stay axis-aligned) and translating the walls and the
    robot together leaves every reading unchanged; readings lie in [0, 5]."""
    p = np.array(pose)
    base = np.asarray(sonar_ranges(jnp.asarray(p), rect_segments(BOX)))
    assert np.all(base >= 0.0) and np.all(base <= SONAR_MAX_RANGE)
    a = quarter_turns * np.pi / 2
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])

    def move(xy):
        return xy @ rot.T + np.array(shift)

    lo = move(BOX[:, [0, 2]])
    hi = move(BOX[:, [1, 3]])
    rects = np.stack(
        [
            np.minimum(lo[:, 0], hi[:, 0]),
            np.maximum(lo[:, 0], hi[:, 0]),
            np.minimum(lo[:, 1], hi[:, 1]),
            np.maximum(lo[:, 1], hi[:, 1]),
        ],
        -1,
    )
    moved = np.concatenate([move(p[:2]), [p[2] + a]])
    again = np.asarray(sonar_ranges(jnp.asarray(moved), rect_segments(rects)))
    np.testing.assert_allclose(again, base, atol=1e-9)
    assert bool(collides(jnp.asarray(p), BOX)) == bool(collides(jnp.asarray(moved), rects))
