"""What a robot step senses, as one value: the :class:`Senses`, the :class:`Sensor` protocol and
its registry, and the :class:`Reading` a step produces.

A step's senses are one frozen value, built in one place (:meth:`Senses.build`, from a
controller's :class:`~mbn.world.sensors.SensorConfig`, the camera's settings, the noise and the
sonar reach; :attr:`mbn.world.rollout.RolloutConfig.senses` for a rollout): which sonars are cast
and how far, the camera or None, the sensing channels of the noise, and the sensors of one's own
read besides the built-in ones. :func:`mbn.world.step.sense` reads them all at a place, in one
pure JAX function over a flat batch ``(B, ...)`` of robots, and returns one :class:`Reading`:
every channel by name, in the order read.

A sensor is a small object registered by name (:func:`register_sensor`): its ``name``, its
``width`` (the columns it adds to :meth:`Reading.vector`) and ``read``, which returns its
channels at a place. The built-in ones are registered the same way, and read first, always:

* ``"sonars"`` (:class:`Sonars`): channel ``ranges (B, k)``, the sonars asked for (metres, in
  the order asked for), exact lattice rays (optionally drawn within a cone about each axis, and
  scaled with the episode's maze) with optional Gaussian noise (clipped to [0, 5] m) and
  dropouts; width k;
* ``"camera"`` (:class:`Camera`): channels ``camera (B,)``, the colours (0 none, 1 to 6) of
  the nearest tile in view, and ``blobs (B,)``, the blobs in view (both 0 with the camera off),
  with optional missed and false blobs; width 2;
* ``"tile"`` (:class:`TileUnder`): channel ``under (B,)``, the colours of the tile under the
  middle of the body (0 none); width 1.

A new sensor is one module that defines it and registers it (``docs/architecture.md``, "Adding
a sensor"); a rollout reads it when its config names it
(:attr:`~mbn.world.rollout.RolloutConfig.extra_sensors`), and its channels reach the controller in
:attr:`~mbn.world.rollout.Observation.extra`. Noise keys: :func:`mbn.world.step.sense` hands
every sensor the step's key (None without noise); the sonars fold it with 0 (ranges), 2
(dropouts) and 6 (the cone's rays), the camera with 3 (1 and 4 are the command's, 5 the
controller's, 7 and 8 the episode's draws, :func:`mbn.world.step.draw_episode`), so a sensor of
one's own that draws noise folds a number of its own, 100 or more. A sensor of one's own that
measures lengths reads them ``Place.scale`` times (the episode's maze scale), as the sonars do.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, NamedTuple, Protocol, runtime_checkable
from typing import cast as typed

import jax
import jax.numpy as jnp
from jax import Array
from jax.typing import DTypeLike

from mbn.errors import MbnInputError
from mbn.world.engine import (
    BASE_BLOBS,
    CameraConfig,
    MazeConstants,
    World,
    cast,
    see_tiles,
    tile_under,
)
from mbn.world.geometry import sonar_rays
from mbn.world.robot import SONAR_MAX_RANGE, SONAR_POSES
from mbn.world.sensors import ALL_SONARS, NoiseConfig, SensorConfig

__all__ = [
    "BUILT_IN_CHANNELS",
    "BUILT_IN_SENSORS",
    "Camera",
    "Place",
    "Reading",
    "Senses",
    "Sensor",
    "Sonars",
    "TileUnder",
    "camera_noise",
    "find_sensor",
    "register_sensor",
    "registered_sensors",
    "unregister_sensor",
]

#: The sensors every step reads, first and in this order.
BUILT_IN_SENSORS: tuple[str, ...] = ("sonars", "camera", "tile")
#: Their channels, in the order read.
BUILT_IN_CHANNELS: tuple[str, ...] = ("ranges", "camera", "blobs", "under")
#: The noise channels the built-in sensors draw from the step's key
#: (:class:`~mbn.world.sensors.NoiseConfig`).
_SENSING = ("sonar_std", "sonar_dropout", "camera_miss", "camera_false", "sonar_cone")
#: The noise channels :attr:`Senses.noise` keeps: those, and the maze's scale per episode (drawn
#: once, :func:`mbn.world.step.draw_episode`, and carried by :attr:`Place.scale`).
_KEPT = (*_SENSING, "corridor_scale")
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class Place(NamedTuple):
    """Where robots are: ``pose (B, 3)`` = (x, y, theta) and the lattice cell holding (x, y) with
    its packed window of the cells around it (:func:`mbn.world.engine.window_words`):
    ``words (B, n_words)`` uint32, cell indices ``ci``, ``cj (B,)`` int32. On the engine's segment
    path the cell is a culling cell and ``words (B, 1)`` its table row (int32).

    ``scale (B,)``: the factor by which each robot's world is its compiled maze scaled this
    episode (the noise's ``corridor_scale``, :func:`mbn.world.step.draw_episode`), None for 1.
    The pose and the cells stay in the compiled maze's coordinates; a sensor that measures
    lengths reads them ``scale`` times (the sonars do).
    """

    pose: Array
    words: Array
    ci: Array
    cj: Array
    scale: Array | None = None


@dataclass(frozen=True)
class Senses:
    """What a step senses: one frozen value (hashable, so a static argument of a jitted function).

    Attributes:
        sonars: Stage indices (0..15) of the sonars to cast, in reading order.
        camera: the blob finder's settings; None switches it off (it then reads 0).
        reach: cast the sonars only this far (metres; :func:`mbn.world.engine.cast`): a wall
            within it reads exactly, one beyond reads its distance or the 5 m miss. None: the
            sonars' whole range.
        noise: the sensing channels of :class:`~mbn.world.sensors.NoiseConfig` (the others are
            not read here; :meth:`build` keeps these alone): ``sonar_std`` (Gaussian, metres,
            clipped to [0, 5] m), ``sonar_dropout`` (a reading returns 5 m), ``sonar_cone``
            (each ray drawn within the cone about its axis), ``camera_miss`` and
            ``camera_false`` (the nearest tile reads one colour less or one more, at most 3 or
            the world's most colours),
            and ``corridor_scale`` (the range of :attr:`Place.scale`, which the sonars read).
        extra: the registered sensors (:func:`register_sensor`) read after the built-in ones,
            in this order.
    """

    sonars: tuple[int, ...] = ALL_SONARS
    camera: CameraConfig | None = None
    reach: float | None = None
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    extra: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        sonars = tuple(int(s) for s in self.sonars)
        if not sonars or any(not 0 <= s < len(SONAR_POSES) for s in sonars):
            raise MbnInputError(f"sonars must be Stage indices 0..15, got {self.sonars!r}")
        if len(set(sonars)) != len(sonars):
            raise MbnInputError(f"sonars must not repeat, got {self.sonars!r}")
        object.__setattr__(self, "sonars", sonars)
        if self.camera is not None and not isinstance(self.camera, CameraConfig):
            raise MbnInputError(f"camera must be a CameraConfig or None, got {self.camera!r}")
        if self.reach is not None and not (0.0 < self.reach <= SONAR_MAX_RANGE):
            raise MbnInputError(
                f"sonar reach must be in (0, {SONAR_MAX_RANGE}] m or None, got {self.reach!r}"
            )
        if not isinstance(self.noise, NoiseConfig):
            raise MbnInputError(f"noise must be a NoiseConfig, got {self.noise!r}")
        extra = tuple(self.extra)
        if len(set(extra)) != len(extra):
            raise MbnInputError(f"extra sensors must not repeat, got {self.extra!r}")
        for name in extra:
            if name in BUILT_IN_SENSORS:
                raise MbnInputError(f"sensor {name!r} is read always: leave it out of extra")
            find_sensor(name)
        object.__setattr__(self, "extra", extra)

    @classmethod
    def build(
        cls,
        sensors: SensorConfig,
        camera: CameraConfig | None = None,
        noise: NoiseConfig | None = None,
        reach: float | None = None,
        extra: Sequence[str] = (),
    ) -> Senses:
        """The senses of a controller: the sonars of ``sensors`` (in its order), the camera
        (None: off), the sensing channels of ``noise`` (None: none), the sonar ``reach`` and
        the ``extra`` registered sensors."""
        noise = NoiseConfig() if noise is None else noise
        sensing = NoiseConfig(**{name: getattr(noise, name) for name in _KEPT})
        return cls(sensors.sonars, camera, reach, sensing, tuple(extra))

    @property
    def names(self) -> tuple[str, ...]:
        """Every sensor read, in reading order: the built-in ones, then :attr:`extra`."""
        return (*BUILT_IN_SENSORS, *self.extra)

    @property
    def sensors(self) -> tuple[Sensor, ...]:
        """The registered sensors of :attr:`names`, in reading order."""
        return tuple(find_sensor(name) for name in self.names)

    @property
    def noisy(self) -> bool:
        """Whether a sensing channel drawn per step of :attr:`noise` is on (a step then needs a
        key; the maze's scale is drawn per episode and comes with the :class:`Place`)."""
        return any(getattr(self.noise, name) > 0 for name in _SENSING)

    @property
    def widths(self) -> dict[str, int]:
        """Each sensor's columns in :meth:`Reading.vector`, by name, in reading order."""
        return {s.name: int(s.width(self)) for s in self.sensors}

    @property
    def width(self) -> int:
        """The columns of :meth:`Reading.vector`: the sum of every sensor's width."""
        return sum(self.widths.values())


@runtime_checkable
class Sensor(Protocol):
    """A sensor: what a robot reads at a place, registered by name (:func:`register_sensor`).

    ``name``: its name in the registry and in :attr:`Senses.extra` (lower case, digits and
    ``_``). ``width(senses)``: the columns its channels take in :meth:`Reading.vector` (a
    ``(B,)`` channel is one column, a ``(B, n)`` one n). ``read(world, mc, maze_index, place,
    senses, key)``: its channels, ``{channel name: (B,) or (B, n) array}``, for robots at
    ``place`` (the arguments of :func:`mbn.world.step.sense`, which calls it; ``key`` is the
    step's key or None without noise). It must be a pure JAX function of them.
    """

    @property
    def name(self) -> str: ...

    def width(self, senses: Senses) -> int: ...

    def read(
        self,
        world: World,
        mc: MazeConstants,
        maze_index: Array,
        place: Place,
        senses: Senses,
        key: Array | None,
    ) -> Mapping[str, Array]: ...


_REGISTRY: dict[str, Sensor] = {}


def register_sensor(sensor: Sensor) -> Sensor:
    """Register ``sensor`` under its name (a name registered already is refused: take it back
    first with :func:`unregister_sensor`) and return it."""
    if not isinstance(sensor, Sensor):
        raise MbnInputError(
            f"a sensor needs a name, width(senses) and read(...), got {type(sensor).__name__}"
        )
    name = sensor.name
    if not isinstance(name, str) or not _NAME.match(name):
        raise MbnInputError(f"sensor name {name!r}: lower case letters, digits and _ (compass)")
    if name in _REGISTRY:
        raise MbnInputError(f"sensor {name!r} is registered already")
    _REGISTRY[name] = sensor
    return sensor


def unregister_sensor(name: str) -> None:
    """Take the sensor ``name`` out of the registry (the built-in ones stay)."""
    if name in BUILT_IN_SENSORS:
        raise MbnInputError(f"sensor {name!r} is built in: it stays registered")
    if _REGISTRY.pop(name, None) is None:
        raise MbnInputError(f"sensor {name!r} is not registered")


def find_sensor(name: str) -> Sensor:
    """The registered sensor ``name``; an unknown name is refused in one line naming the
    registered ones."""
    found = _REGISTRY.get(name)
    if found is None:
        known = ", ".join(sorted(_REGISTRY))
        raise MbnInputError(
            f"sensor {name!r} is not registered ({known}): import the module that registers it"
        )
    return found


def registered_sensors() -> Mapping[str, Sensor]:
    """Every registered sensor by name, in the order registered (the built-in ones first)."""
    return MappingProxyType(_REGISTRY)


@jax.tree_util.register_pytree_node_class
class Reading(Mapping[str, Array]):
    """What robots sense at a place: every sensor's channels by name, in the order read (a
    mapping, and a JAX pytree whose leaves are the channels in that order).

    The built-in channels are also attributes: ``ranges (B, k)`` the sonars asked for (metres,
    in the order asked for); ``camera (B,)`` the colours (0 none, 1 to 6) of the nearest tile in
    view and ``blobs (B,)`` the blobs in view (both 0 with the camera off); ``under (B,)`` the
    colours of the tile under the middle of the body (0 none). A sensor of one's own is read by
    its channels' names: ``reading["compass"]``.
    """

    __slots__ = ("_channels",)

    def __init__(self, channels: Mapping[str, Any]) -> None:
        self._channels = dict(channels)

    def __getitem__(self, name: str) -> Array:
        return typed(Array, self._channels[name])

    def __iter__(self) -> Iterator[str]:
        return iter(self._channels)

    def __len__(self) -> int:
        return len(self._channels)

    def __repr__(self) -> str:
        return f"Reading({self._channels!r})"

    @property
    def ranges(self) -> Array:
        """The sonars asked for ``(B, k)``, metres."""
        return self["ranges"]

    @property
    def camera(self) -> Array:
        """The colours of the nearest tile in view ``(B,)`` (0 none or camera off)."""
        return self["camera"]

    @property
    def blobs(self) -> Array:
        """The blobs in view ``(B,)`` (0 with the camera off)."""
        return self["blobs"]

    @property
    def under(self) -> Array:
        """The colours of the tile under the middle of the body ``(B,)`` (0 none)."""
        return self["under"]

    def vector(self, dtype: DTypeLike | None = None) -> Array:
        """Every channel as columns of one array ``(B, width)``, in the order read (a ``(B,)``
        channel one column, a ``(B, n)`` one n), in ``dtype`` (default: the channels' common
        type, the ranges' float type with the built-in ones)."""
        values = [jnp.asarray(v) for v in self._channels.values()]
        dtype = jnp.result_type(*values) if dtype is None else dtype
        return jnp.concatenate([v.reshape(v.shape[0], -1).astype(dtype) for v in values], -1)

    def tree_flatten(self) -> tuple[tuple[Any, ...], tuple[str, ...]]:
        return tuple(self._channels.values()), tuple(self._channels)

    @classmethod
    def tree_unflatten(cls, names: tuple[str, ...], values: Sequence[Any]) -> Reading:
        return cls(dict(zip(names, values, strict=True)))


# ---------------------------------------------------------------------------------------------
# the built-in sensors


@dataclass(frozen=True)
class Sonars:
    """The sonars of :attr:`Senses.sonars`: channel ``ranges (B, k)`` in the pose's precision,
    exact lattice rays cast :attr:`Senses.reach` far; with the noise's ``sonar_cone`` each ray's
    heading is the transducer's plus an angle uniform in ``[-cone/2, cone/2]`` (the key folded
    with 6, one per reading); in a scaled maze (:attr:`Place.scale` ``s``) a wall read at ``d``
    in the compiled maze reads ``s d`` (a miss, or ``s d`` beyond 5 m, reads the 5 m miss; the
    rays are cast ``reach / (1 - corridor_scale)`` far so that a wall within ``reach`` of the
    scaled world reads exactly); then ``sonar_std`` (the key folded with 0; clipped to
    [0, 5] m) and ``sonar_dropout`` (folded with 2)."""

    name: str = "sonars"

    def width(self, senses: Senses) -> int:
        return len(senses.sonars)

    def read(
        self,
        world: World,
        mc: MazeConstants,
        maze_index: Array,
        place: Place,
        senses: Senses,
        key: Array | None,
    ) -> Mapping[str, Array]:
        noise = senses.noise
        scaled = noise.corridor_scale > 0
        if scaled != (place.scale is not None):
            raise MbnInputError(
                "corridor_scale is on: locate the robots with their episode's scale "
                "(mbn.world.step.draw_episode)"
                if scaled
                else "the place has a maze scale but the senses' corridor_scale is 0"
            )
        origins, angles = sonar_rays(place.pose, SONAR_POSES[list(senses.sonars)])
        if noise.sonar_cone > 0:
            u = jax.random.uniform(
                jax.random.fold_in(typed(Array, key), 6), angles.shape, angles.dtype, -0.5, 0.5
            )
            angles = angles + math.radians(noise.sonar_cone) * u
        reach = senses.reach
        if scaled and reach is not None:
            wide = reach / (1.0 - noise.corridor_scale)  # the compiled maze's metres
            reach = wide if wide < SONAR_MAX_RANGE else None
        ranges = cast(
            world,
            mc,
            place.words,
            place.ci,
            place.cj,
            origins[..., 0],
            origins[..., 1],
            angles,
            reach=reach,
        )
        if scaled:
            miss = jnp.asarray(SONAR_MAX_RANGE, ranges.dtype)
            s = typed(Array, place.scale).astype(ranges.dtype)[:, None]
            ranges = jnp.where(ranges >= miss, miss, jnp.minimum(ranges * s, miss))
        if noise.sonar_std > 0:
            nk = jax.random.fold_in(typed(Array, key), 0)
            ranges = jnp.clip(
                ranges + noise.sonar_std * jax.random.normal(nk, ranges.shape, ranges.dtype),
                0.0,
                SONAR_MAX_RANGE,
            )
        if noise.sonar_dropout > 0:
            lost = jax.random.bernoulli(
                jax.random.fold_in(typed(Array, key), 2), noise.sonar_dropout, ranges.shape
            )
            ranges = jnp.where(lost, jnp.asarray(SONAR_MAX_RANGE, ranges.dtype), ranges)
        return {"ranges": ranges}


@dataclass(frozen=True)
class Camera:
    """The blob finder of :attr:`Senses.camera` (:func:`mbn.world.engine.see_tiles`): channels
    ``camera (B,)`` (the colours of the nearest tile in view) and ``blobs (B,)``, int32, both 0
    with the camera off; the noise's ``camera_miss`` and ``camera_false`` (:func:`camera_noise`,
    the key folded with 3)."""

    name: str = "camera"

    def width(self, senses: Senses) -> int:
        return 2

    def read(
        self,
        world: World,
        mc: MazeConstants,
        maze_index: Array,
        place: Place,
        senses: Senses,
        key: Array | None,
    ) -> Mapping[str, Array]:
        pose, noise = place.pose, senses.noise
        if senses.camera is not None:
            seen = see_tiles(
                world, mc, maze_index, place.words, place.ci, place.cj, pose, senses.camera
            )
            nearest, blobs = seen.nearest, seen.blobs
            if noise.camera_miss > 0 or noise.camera_false > 0:
                nearest, blobs = camera_noise(
                    nearest,
                    blobs,
                    noise,
                    jax.random.fold_in(typed(Array, key), 3),
                    most=world.n_blobs,
                )
        else:
            nearest = blobs = jnp.zeros(pose.shape[:1], jnp.int32)
        return {"camera": nearest, "blobs": blobs}


@dataclass(frozen=True)
class TileUnder:
    """The tile under the middle of the body (:func:`mbn.world.engine.tile_under`): channel
    ``under (B,)``, its colours (0 none)."""

    name: str = "tile"

    def width(self, senses: Senses) -> int:
        return 1

    def read(
        self,
        world: World,
        mc: MazeConstants,
        maze_index: Array,
        place: Place,
        senses: Senses,
        key: Array | None,
    ) -> Mapping[str, Array]:
        return {"under": tile_under(world, maze_index, place.pose)}


def camera_noise(
    nearest: Array, blobs: Array, noise: NoiseConfig, key: Array, *, most: int = BASE_BLOBS
) -> tuple[Array, Array]:
    """The blob finder's reading ``(nearest, blobs) (B,)`` with a missed blob (probability
    ``noise.camera_miss``: one colour less, where a tile is in view) or a false one
    (``noise.camera_false``: one colour more, where the nearest tile reads fewer than ``most``
    colours), drawn independently per robot; a miss and a false blob in the same step cancel.
    ``most`` (static): :attr:`mbn.world.engine.World.n_blobs`, which :class:`Camera` passes: 3,
    or the most colours of any tile of a world whose tiles have more."""
    km, kf = jax.random.split(key)
    shape = nearest.shape
    miss = jax.random.bernoulli(km, noise.camera_miss, shape) & (nearest > 0)
    false = jax.random.bernoulli(kf, noise.camera_false, shape) & (nearest < most)
    change = false.astype(nearest.dtype) - miss.astype(nearest.dtype)
    return nearest + change, jnp.maximum(blobs + change, 0)


register_sensor(Sonars())
register_sensor(Camera())
register_sensor(TileUnder())
