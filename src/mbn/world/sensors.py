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

from dataclasses import dataclass, fields
from typing import Literal

import jax.numpy as jnp
from jax import Array
from jax.typing import ArrayLike

from mbn.config import Settings, setting
from mbn.errors import MbnInputError
from mbn.world.robot import SONAR_MAX_RANGE

__all__ = [
    "ALL_SONARS",
    "PAPER_SONARS",
    "NoiseConfig",
    "SensorConfig",
    "normalize",
    "paper_inputs",
    "parse_noise",
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


_DOC = "docs/noise.md"


@dataclass(frozen=True)
class NoiseConfig(Settings):
    """Noise per channel, all off by default (``docs/noise.md``). Every draw comes from the
    rollout's PRNG key folded with the step and the channel, so a seed gives the same noise.

    World channels (:mod:`mbn.world.step`):

    - ``sonar_std``: Gaussian on each sonar range (metres), clipped to [0, 5];
    - ``sonar_dropout``: probability per reading that a sonar returns the 5 m miss;
    - ``camera_miss``: probability per step that the camera misses one blob of the nearest tile
      in view (a one-colour tile is then not seen, a two-colour one reads as one colour);
    - ``camera_false``: probability per step of a false blob: the nearest tile reads one colour
      more (nothing in view reads as a one-colour tile), at most three (in a world with tiles of
      more colours, at most its most);
    - ``wheel_std``: relative Gaussian on the commanded speeds, ``v (1 + e_v)``, ``w (1 + e_w)``;
    - ``v_std``, ``w_std``: absolute Gaussian on the commanded speeds (m/s, rad/s);
    - ``sonar_cone`` (degrees): each sonar reading is cast along a ray offset from the
      transducer's axis by an angle drawn uniformly in ``[-cone/2, cone/2]``, per reading and step.

    World channels drawn once per episode (per robot, at the start; "Jakobi's envelope": the
    details of the world a controller must not rely on):

    - ``corridor_scale``: the maze is scaled by ``s``, uniform in ``[1 - x, 1 + x]``: the sonars
      read ``s`` times the compiled maze's ranges and a metre driven covers ``1 / s`` of its metres
      (the robot's size, for collisions and the camera, scales with it: ``docs/noise.md``);
    - ``wheel_bias``: the left wheel turns ``1 + b`` times its speed, the right ``1 - b`` times,
      ``b ~ N(0, wheel_bias)`` clipped to [-1, 1]: ``v - b w L / 2``, ``w - 2 b v / L`` for the
      command ``(v, w)`` and the wheel base ``L`` (:data:`mbn.world.robot.WHEEL_BASE`).

    Controller channels (drawn by the controller from ``Observation.key``):

    - ``neuron_std``: Gaussian added to every neuron's potential once per robot step (every
      network of the controller, multipliers included);
    - ``program_std``: Gaussian on the program lines into an interpreter (an MBN's program
      module's output, or a fixed program), clipped to [0, 1].
    """

    section = "noise"

    sonar_std: float = setting(
        0.0, doc="Gaussian on each sonar range", unit="m", low=0.0, high=5.0, source=_DOC
    )
    sonar_dropout: float = setting(
        0.0, doc="probability per reading of the 5 m miss", low=0.0, high=1.0, source=_DOC
    )
    camera_miss: float = setting(
        0.0, doc="probability per step of a missed blob", low=0.0, high=1.0, source=_DOC
    )
    camera_false: float = setting(
        0.0, doc="probability per step of a false blob", low=0.0, high=1.0, source=_DOC
    )
    wheel_std: float = setting(
        0.0, doc="relative Gaussian on the commanded v and w", low=0.0, high=10.0, source=_DOC
    )
    v_std: float = setting(
        0.0, doc="absolute Gaussian on the commanded v", unit="m/s", low=0.0, high=10.0, source=_DOC
    )
    w_std: float = setting(
        0.0,
        doc="absolute Gaussian on the commanded w",
        unit="rad/s",
        low=0.0,
        high=10.0,
        source=_DOC,
    )
    sonar_cone: float = setting(
        0.0,
        doc="width of the cone a sonar's ray is drawn in, per reading (uniform about the axis)",
        unit="deg",
        low=0.0,
        high=60.0,
        source=_DOC,
    )
    corridor_scale: float = setting(
        0.0,
        doc="per episode, the maze scaled by s uniform in [1 - x, 1 + x] (0.1: corridors +-10 %)",
        low=0.0,
        high=0.5,
        source=_DOC,
    )
    wheel_bias: float = setting(
        0.0,
        doc="per episode, std of the wheels' bias b: left speed x (1 + b), right x (1 - b)",
        low=0.0,
        high=0.5,
        source=_DOC,
    )
    neuron_std: float = setting(
        0.0,
        doc="Gaussian on every neuron's potential per robot step",
        low=0.0,
        high=100.0,
        source=_DOC,
    )
    program_std: float = setting(
        0.0,
        doc="Gaussian on the program lines (clipped to [0, 1])",
        low=0.0,
        high=10.0,
        source=_DOC,
    )

    @property
    def world_enabled(self) -> bool:
        """Whether a world channel (sonars, camera, wheels, the maze's scale) is on."""
        return any(getattr(self, name) > 0 for name in _WORLD)

    @property
    def episode_enabled(self) -> bool:
        """Whether a channel drawn once per episode (corridor scale, wheel bias) is on."""
        return any(getattr(self, name) > 0 for name in _EPISODE)

    @property
    def controller_enabled(self) -> bool:
        """Whether a controller channel (neurons, program lines) is on."""
        return self.neuron_std > 0 or self.program_std > 0

    @property
    def enabled(self) -> bool:
        return self.world_enabled or self.controller_enabled

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


_WORLD = (
    "sonar_std",
    "sonar_dropout",
    "camera_miss",
    "camera_false",
    "wheel_std",
    "v_std",
    "w_std",
    "sonar_cone",
    "corridor_scale",
    "wheel_bias",
)
#: The world channels drawn once per episode (:func:`mbn.world.step.draw_episode`).
_EPISODE = ("corridor_scale", "wheel_bias")


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


def parse_noise(text: str) -> NoiseConfig:
    """Noise settings from the command line: ``KEY=VALUE[,KEY=VALUE...]`` (e.g.
    ``sonar_std=0.02,sonar_dropout=0.01``), or a TOML file (``.toml``) whose ``[noise]`` table
    holds them (a run's settings file). Errors: one line naming the key (and file and line)."""
    from mbn.config import from_mapping, read_toml

    if text.endswith(".toml"):
        doc = read_toml(text)
        table = doc.data.get("noise")
        if table is None:
            raise MbnInputError(f"{doc.path}: no [noise] table")
        return from_mapping(NoiseConfig, table, where=lambda key: doc.where("noise", key))
    values: dict[str, float] = {}
    for item in text.split(","):
        key, sep, value = item.strip().partition("=")
        if not sep or not key:
            raise MbnInputError(
                f"noise {item.strip()!r}: expected KEY=VALUE (e.g. sonar_std=0.02) or a .toml file"
            )
        try:
            values[key.strip()] = float(value)
        except ValueError:
            raise MbnInputError(f"noise {key.strip()}: not a number: {value.strip()!r}") from None
    return from_mapping(NoiseConfig, values, where=lambda key: f"noise {key}" if key else "noise")
