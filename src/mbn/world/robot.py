"""The Pioneer 3DX as Player/Stage 4.3 models it (``worlds/pioneer.inc``).

All lengths in metres, angles in radians, headings counter-clockwise from +x. The pose
``(x, y, theta)`` is Stage's position-model pose: the centre of rotation (wheel axle centre); the
body octagon sits 0.04465 m behind it. Figures are those of ``docs/world.md``, which records where
each comes from.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

__all__ = [
    "BODY",
    "MAX_ANGULAR_SPEED",
    "MAX_LINEAR_SPEED",
    "SONAR_MAX_RANGE",
    "SONAR_POSES",
    "WHEEL_BASE",
    "clip_command",
    "integrate_pose",
    "normalize_angle",
]

#: Body octagon in the robot frame (x forward, y left), counter-clockwise; Stage stretches the
#: polygon of ``pioneer.inc`` to 0.511 m x 0.4 m and shifts it by the model origin x = -0.04465.
BODY = np.array(
    [
        [0.21085, -0.09393],
        [0.21085, 0.09393],
        [0.10865, 0.2],
        [-0.19795, 0.2],
        [-0.30015, 0.09393],
        [-0.30015, -0.09393],
        [-0.19795, -0.2],
        [0.10865, -0.2],
    ]
)

#: The 16 sonar transducers ``(x, y, heading in degrees)`` in Stage's order: s00..s07 the front
#: arc from left to right, s08..s15 the rear arc from right rear to left rear. s14's x of -0.103
#: (symmetry would give -0.203) is what Stage's file says and simulates; it is kept.
SONAR_POSES = np.array(
    [
        [0.069, 0.136, 90.0],
        [0.114, 0.119, 50.0],
        [0.148, 0.078, 30.0],
        [0.166, 0.027, 10.0],
        [0.166, -0.027, -10.0],
        [0.148, -0.078, -30.0],
        [0.114, -0.119, -50.0],
        [0.069, -0.136, -90.0],
        [-0.157, -0.136, -90.0],
        [-0.203, -0.119, -130.0],
        [-0.237, -0.078, -150.0],
        [-0.255, -0.027, -170.0],
        [-0.255, 0.027, 170.0],
        [-0.237, 0.078, 150.0],
        [-0.103, 0.119, 130.0],
        [-0.157, 0.136, 90.0],
    ]
)

#: Range of every sonar; a ray that hits nothing within it reads exactly this value.
SONAR_MAX_RANGE = 5.0
#: Distance between the two drive wheels' contact lines (m), the figure commonly given for the
#: P3-DX (its overall width of about 0.38 m less one wheel's tread of about 0.05 m). Stage drives
#: ``(v, w)`` directly and needs none; only the noise's wheel bias (``NoiseConfig.wheel_bias``,
#: ``docs/noise.md``) reads it.
WHEEL_BASE = 0.33
#: Speed limits of Stage's P3DX in velocity-control mode (m/s, rad/s); no acceleration limits.
MAX_LINEAR_SPEED = 0.5
MAX_ANGULAR_SPEED = math.radians(90.0)


def normalize_angle(a: ArrayLike) -> Array:
    """Angle wrapped to [-pi, pi] as Stage does (``atan2(sin a, cos a)``)."""
    a = jnp.asarray(a)
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


def clip_command(v: ArrayLike, w: ArrayLike) -> tuple[Array, Array]:
    """The command ``(v, w)`` Stage applies: each clipped to the P3DX's speed limits."""
    return (
        jnp.clip(jnp.asarray(v), -MAX_LINEAR_SPEED, MAX_LINEAR_SPEED),
        jnp.clip(jnp.asarray(w), -MAX_ANGULAR_SPEED, MAX_ANGULAR_SPEED),
    )


def integrate_pose(pose: ArrayLike, v: ArrayLike, w: ArrayLike, dt: ArrayLike) -> Array:
    """One forward-Euler step of Stage's kinematics with the heading at the start of the step.

    ``pose (..., 3)``; ``v``, ``w`` the applied (already limited) speeds; returns the new pose with
    the heading normalised to [-pi, pi]. Collisions are not checked here
    (:func:`mbn.world.geometry.collides`).
    """
    pose = jnp.asarray(pose)
    x, y, theta = pose[..., 0], pose[..., 1], pose[..., 2]
    v, w = jnp.asarray(v), jnp.asarray(w)
    return jnp.stack(
        [
            x + v * dt * jnp.cos(theta),
            y + v * dt * jnp.sin(theta),
            normalize_angle(theta + w * dt),
        ],
        axis=-1,
    )
