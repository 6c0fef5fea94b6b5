"""Exact 2-D geometry of the world: ray casting against wall segments and body-wall collision.

Walls are axis-aligned rectangles ``(xmin, xmax, ymin, ymax)``; sonars see their edges as line
segments ``(x1, y1, x2, y2)``. Everything here is pure JAX and broadcasts over leading axes.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from mbn.world.robot import BODY, SONAR_MAX_RANGE, SONAR_POSES

__all__ = [
    "body_polygon",
    "cast_rays",
    "collides",
    "rect_segments",
    "sonar_ranges",
    "sonar_rays",
]


def rect_segments(rects: ArrayLike) -> np.ndarray:
    """The 4 edges of each rectangle ``(K, 4)`` as segments ``(4 K, 4)`` (NumPy, at the edge)."""
    r = np.asarray(rects, dtype=float).reshape(-1, 4)
    x0, x1, y0, y1 = r.T
    edges = [
        np.stack([x0, y0, x1, y0], -1),
        np.stack([x1, y0, x1, y1], -1),
        np.stack([x1, y1, x0, y1], -1),
        np.stack([x0, y1, x0, y0], -1),
    ]
    return np.concatenate(edges, axis=0)


def _cross(ax: Array, ay: Array, bx: Array, by: Array) -> Array:
    return ax * by - ay * bx


def cast_rays(
    origins: ArrayLike,
    angles: ArrayLike,
    segments: ArrayLike,
    max_range: float = SONAR_MAX_RANGE,
) -> Array:
    """Distance along each ray to the first segment it meets, or ``max_range`` if none within it.

    Args:
        origins: ray origins ``(..., 2)``.
        angles: ray headings ``(...)`` in radians.
        segments: ``(S, 4)`` as ``(x1, y1, x2, y2)``; may carry matching leading axes
            ``(..., S, 4)`` (e.g. one segment set per maze) that broadcast with the rays'.
        max_range: cut-off; a miss reads exactly this.

    Returns:
        Ranges ``(...)``, in [0, max_range].
    """
    o = jnp.asarray(origins)[..., None, :]
    a = jnp.asarray(angles)[..., None]
    seg = jnp.asarray(segments)
    dx, dy = jnp.cos(a), jnp.sin(a)
    px, py = seg[..., 0], seg[..., 1]
    ex, ey = seg[..., 2] - px, seg[..., 3] - py
    wx, wy = px - o[..., 0], py - o[..., 1]
    denom = _cross(dx, dy, ex, ey)
    ok = jnp.abs(denom) > 1e-12
    safe = jnp.where(ok, denom, 1.0)
    t = _cross(wx, wy, ex, ey) / safe  # along the ray
    s = _cross(wx, wy, dx, dy) / safe  # along the segment
    hit = ok & (t >= 0.0) & (s >= 0.0) & (s <= 1.0)
    dist = jnp.min(jnp.where(hit, t, jnp.inf), axis=-1)
    return jnp.minimum(dist, max_range)


def sonar_rays(pose: ArrayLike, sonar_poses: ArrayLike = SONAR_POSES) -> tuple[Array, Array]:
    """World-frame origins ``(..., k, 2)`` and headings ``(..., k)`` of the sonars at ``pose``."""
    pose = jnp.asarray(pose)
    sp = jnp.asarray(sonar_poses, dtype=pose.dtype)
    x, y, th = pose[..., 0:1], pose[..., 1:2], pose[..., 2:3]
    c, s = jnp.cos(th), jnp.sin(th)
    ox = x + c * sp[:, 0] - s * sp[:, 1]
    oy = y + s * sp[:, 0] + c * sp[:, 1]
    return jnp.stack([ox, oy], -1), th + jnp.deg2rad(sp[:, 2])


def sonar_ranges(
    pose: ArrayLike,
    segments: ArrayLike,
    sonar_poses: ArrayLike = SONAR_POSES,
    max_range: float = SONAR_MAX_RANGE,
) -> Array:
    """Readings of the sonars at ``pose (..., 3)``: one exact ray each, ``(..., k)`` metres."""
    origins, angles = sonar_rays(pose, sonar_poses)
    seg = jnp.asarray(segments)
    return cast_rays(origins, angles, seg[..., None, :, :], max_range)


def body_polygon(pose: ArrayLike, body: ArrayLike = BODY) -> Array:
    """World-frame vertices ``(..., 8, 2)`` of the body octagon at ``pose (..., 3)``."""
    pose = jnp.asarray(pose)
    b = jnp.asarray(body, dtype=pose.dtype)
    x, y, th = pose[..., 0:1], pose[..., 1:2], pose[..., 2:3]
    c, s = jnp.cos(th), jnp.sin(th)
    return jnp.stack([x + c * b[:, 0] - s * b[:, 1], y + s * b[:, 0] + c * b[:, 1]], -1)


def _body_normals(body: np.ndarray) -> np.ndarray:
    """Unit normals of the body polygon's edges, one per direction (parallel edges merged)."""
    edges = np.roll(body, -1, axis=0) - body
    normals = np.stack([-edges[:, 1], edges[:, 0]], -1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    unique: list[np.ndarray] = []
    for n in normals:
        if not any(abs(abs(float(n @ u)) - 1.0) < 1e-9 for u in unique):
            unique.append(n)
    return np.array(unique)


def collides(pose: ArrayLike, rects: ArrayLike, body: ArrayLike = BODY) -> Array:
    """Whether the body at ``pose (..., 3)`` overlaps any wall rectangle ``(K, 4)`` (or
    ``(..., K, 4)``); touching is not overlapping. Separating-axis test: the two rectangle axes
    and the body's edge normals."""
    pose = jnp.asarray(pose)
    poly = body_polygon(pose, body)  # (..., 8, 2)
    r = jnp.asarray(rects)
    normals = jnp.asarray(_body_normals(np.asarray(body)))  # NumPy, once per trace
    px, py = poly[..., 0], poly[..., 1]
    # rectangle axes: compare bounding intervals
    sep_x = (jnp.max(px, -1)[..., None] <= r[..., 0]) | (jnp.min(px, -1)[..., None] >= r[..., 1])
    sep_y = (jnp.max(py, -1)[..., None] <= r[..., 2]) | (jnp.min(py, -1)[..., None] >= r[..., 3])
    separated = sep_x | sep_y  # (..., K)
    th = pose[..., 2]
    c, s = jnp.cos(th)[..., None], jnp.sin(th)[..., None]
    nx = c * normals[:, 0] - s * normals[:, 1]  # (..., A) world-frame normals
    ny = s * normals[:, 0] + c * normals[:, 1]
    proj_body = px[..., None, :] * nx[..., :, None] + py[..., None, :] * ny[..., :, None]
    bmin, bmax = jnp.min(proj_body, -1), jnp.max(proj_body, -1)  # (..., A)
    corners_x = jnp.stack([r[..., 0], r[..., 1], r[..., 1], r[..., 0]], -1)  # (..., K, 4)
    corners_y = jnp.stack([r[..., 2], r[..., 2], r[..., 3], r[..., 3]], -1)
    proj_rect = (
        corners_x[..., None, :] * nx[..., None, :, None]
        + corners_y[..., None, :] * ny[..., None, :, None]
    )  # (..., K, A, 4)
    rmin, rmax = jnp.min(proj_rect, -1), jnp.max(proj_rect, -1)
    sep_axes = (bmax[..., None, :] <= rmin) | (bmin[..., None, :] >= rmax)  # (..., K, A)
    separated = separated | jnp.any(sep_axes, -1)
    return ~jnp.all(separated, -1)
