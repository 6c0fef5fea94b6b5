"""The paper's sensors: 10 of the Pioneer's 16 sonars, their normalisation, and the inputs of eq. 3.

The paper (section 3.1, Fig. 4) numbers 10 sonars s1..s10 from the right side round the front to
the left side: s1, s2 right side; s3, s4 right-front; s5, s6 front; s7, s8 left-front; s9, s10 left
side. On Stage's ring (s00..s15, see :mod:`mbn.world.robot`) that is

====  =====  ========  ====  =====  ========
paper Stage  heading   paper Stage  heading
====  =====  ========  ====  =====  ========
s1    s08    -90 rear  s6    s03    +10
s2    s07    -90       s7    s02    +30
s3    s06    -50       s8    s01    +50
s4    s05    -30       s9    s00    +90
s5    s04    -10       s10   s15    +90 rear
====  =====  ========  ====  =====  ========

Sonars return distances; the paper's networks read a value S that grows as the wall comes near
(its fitness rewards high S on the followed side). ``mbn`` uses, by default, proximity
``S = clip((far - d) / (far - near), 0, 1)`` with ``near = 0`` and ``far = 2 m``; "distance"
(``clip((d - near) / (far - near), 0, 1)``) and raw metres are available.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from mbn.errors import MbnInputError
from mbn.world.robot import SONAR_MAX_RANGE

__all__ = [
    "ALL_SONARS",
    "PAPER_SONARS",
    "NoiseConfig",
    "SensorConfig",
    "normalize",
    "paper_inputs",
]

#: Stage transducer index of the paper's s1..s10.
PAPER_SONARS: tuple[int, ...] = (8, 7, 6, 5, 4, 3, 2, 1, 0, 15)
#: All 16 transducers in Stage's order.
ALL_SONARS: tuple[int, ...] = tuple(range(16))

#: Eq. 3 as a (3, 10) matrix over the paper's S1..S10.
_EQ3 = (
    (0.0, 0.2, 0.4, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.4, 0.4, 0.2, 0.0),
    (0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0),
)


@dataclass(frozen=True)
class SensorConfig:
    """Which sonars are cast (Stage indices, in observation order) and how S is computed.

    ``normalization``: "proximity" (default; 1 at ``near`` or closer, 0 at ``far`` or beyond),
    "distance" (0 at ``near``, 1 at ``far``), or "metres" (S is the range itself).
    """

    sonars: tuple[int, ...] = PAPER_SONARS
    normalization: Literal["proximity", "distance", "metres"] = "proximity"
    near: float = 0.0
    far: float = 2.0

    def __post_init__(self) -> None:
        if not self.sonars or any(not 0 <= s < 16 for s in self.sonars):
            raise MbnInputError(f"sonars must be Stage indices 0..15, got {self.sonars!r}")
        if len(set(self.sonars)) != len(self.sonars):
            raise MbnInputError(f"sonars must not repeat, got {self.sonars!r}")
        if self.normalization not in ("proximity", "distance", "metres"):
            raise MbnInputError(
                f"normalization must be proximity, distance or metres, got {self.normalization!r}"
            )
        if not (0.0 <= self.near < self.far <= SONAR_MAX_RANGE):
            raise MbnInputError(
                f"need 0 <= near < far <= {SONAR_MAX_RANGE} m, got near={self.near!r}, "
                f"far={self.far!r}"
            )

    @property
    def paper_positions(self) -> tuple[int, ...] | None:
        """Positions of the paper's s1..s10 in the observation, or None if some are not cast."""
        if not set(PAPER_SONARS) <= set(self.sonars):
            return None
        return tuple(self.sonars.index(s) for s in PAPER_SONARS)


@dataclass(frozen=True)
class NoiseConfig:
    """Gaussian noise, off by default: sonar ranges (metres, clipped to [0, 5]), and the linear
    (m/s) and angular (rad/s) speeds commanded, before Stage's speed limits."""

    sonar_std: float = 0.0
    v_std: float = 0.0
    w_std: float = 0.0

    def __post_init__(self) -> None:
        for name in ("sonar_std", "v_std", "w_std"):
            value = getattr(self, name)
            if not (value >= 0.0):
                raise MbnInputError(f"noise {name} must be >= 0, got {value!r}")

    @property
    def enabled(self) -> bool:
        return self.sonar_std > 0 or self.v_std > 0 or self.w_std > 0


def normalize(ranges: ArrayLike, config: SensorConfig) -> Array:
    """S from ranges (metres) as ``config`` says."""
    d = jnp.asarray(ranges)
    if config.normalization == "metres":
        return d
    span = config.far - config.near
    if config.normalization == "proximity":
        return jnp.clip((config.far - d) / span, 0.0, 1.0)
    return jnp.clip((d - config.near) / span, 0.0, 1.0)


def paper_inputs(S: ArrayLike) -> Array:
    """The paper's inputs (eq. 3) ``(..., 3)`` from S over s1..s10 ``(..., 10)``:
    I1 = 0.2 S2 + 0.4 S3 + 0.4 S4 (right), I2 = 0.2 S9 + 0.4 S8 + 0.4 S7 (left),
    I3 = 0.5 S5 + 0.5 S6 (front)."""
    S = jnp.asarray(S)
    if S.shape[-1] != 10:
        raise MbnInputError(f"paper_inputs needs S for s1..s10 (last axis 10), got {S.shape}")
    m = jnp.asarray(_EQ3, S.dtype)
    return (
        m[:, 1] * S[..., 1:2]
        + m[:, 2] * S[..., 2:3]
        + m[:, 3] * S[..., 3:4]
        + m[:, 4] * S[..., 4:5]
        + m[:, 5] * S[..., 5:6]
        + m[:, 6] * S[..., 6:7]
        + m[:, 7] * S[..., 7:8]
        + m[:, 8] * S[..., 8:9]
    )
