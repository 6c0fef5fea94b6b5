"""What a step senses, as one value (mbn.world.senses): the built-in sensors registered as any
other, and a sensor added from outside the package, the recipe of ``docs/architecture.md``
("Adding a sensor") run as it stands there, read through ``sense`` and through a rollout."""

from __future__ import annotations

import math
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mbn.errors import MbnInputError
from mbn.world.engine import CameraConfig, compile_mazes, maze_constants
from mbn.world.mazes.model import Maze, Tile, merge_cells
from mbn.world.rollout import RolloutConfig, rollout
from mbn.world.senses import (
    BUILT_IN_CHANNELS,
    BUILT_IN_SENSORS,
    Reading,
    Senses,
    Sensor,
    find_sensor,
    register_sensor,
    registered_sensors,
    unregister_sensor,
)
from mbn.world.sensors import NoiseConfig, SensorConfig
from mbn.world.step import locate, sense, undo_stalled

ARCHITECTURE = Path(__file__).parents[2] / "docs" / "architecture.md"
CELL = 1.2


def recipe() -> str:
    """The Python block of the section "Adding a sensor" of ``docs/architecture.md``."""
    text = ARCHITECTURE.read_text()
    section = re.split(r"^#{2,3} ", text.split("### Adding a sensor\n", 1)[1], flags=re.M)[0]
    blocks = re.findall(r"^```python\n(.*?)^```", section, re.M | re.S)
    assert len(blocks) == 1, "the section holds one Python block, the recipe"
    return blocks[0]


@pytest.fixture
def compass():
    """The recipe's module, run as it stands in the doc (its sensor registered), and taken out
    of the registry again afterwards."""
    code = recipe()
    assert code.startswith("# my_lab/compass.py\n")
    namespace: dict = {"__name__": "my_lab.compass"}
    exec(compile(code, "my_lab/compass.py", "exec"), namespace)
    try:
        yield namespace["Compass"]
    finally:
        unregister_sensor("compass")


@pytest.fixture(scope="module")
def corridor() -> Maze:
    """A corridor along x: free for x in [1.2, 14.4], y in [1.2, 2.4]; a two-colour tile across
    it at x = 6."""
    grid = np.array([list("#############"), list("#...........#"), list("#############")])
    return Maze(
        name="corridor",
        walls=merge_cells(grid == "#", CELL),
        bounds=(0.0, 13 * CELL, 0.0, 3 * CELL),
        tiles=(Tile(6.0, 1.8, 2, heading=0.0),),
        starts=[[2.0, 1.8, 0.0], [14.15, 1.8, 0.0]],
    )


def in_maze(maze: Maze, n: int):
    world = compile_mazes([maze])
    mi = jnp.zeros((n,), jnp.int32)
    return world, maze_constants(world, mi), mi


def test_the_built_in_sensors_are_registered_as_any_other():
    sensors = registered_sensors()
    assert tuple(sensors)[:3] == BUILT_IN_SENSORS == ("sonars", "camera", "tile")
    for name in BUILT_IN_SENSORS:
        assert isinstance(sensors[name], Sensor) and sensors[name].name == name
        assert find_sensor(name) is sensors[name]
    senses = Senses(sonars=(8, 0, 15))
    assert senses.names == BUILT_IN_SENSORS
    assert senses.widths == {"sonars": 3, "camera": 2, "tile": 1} and senses.width == 6
    with pytest.raises(MbnInputError, match="built in"):
        unregister_sensor("camera")
    with pytest.raises(MbnInputError, match="registered already"):
        register_sensor(find_sensor("sonars"))


def test_senses_are_built_in_one_place_from_a_controllers_sensors():
    noise = NoiseConfig(sonar_std=0.01, camera_miss=0.1, v_std=0.2, neuron_std=0.3)
    camera = CameraConfig()
    senses = Senses.build(SensorConfig(), camera, noise, 2.0)
    assert senses == Senses(
        SensorConfig().sonars, camera, 2.0, NoiseConfig(sonar_std=0.01, camera_miss=0.1)
    )
    assert senses.noisy and not Senses().noisy
    hash(senses)  # a static argument of a jitted function
    config = RolloutConfig(sensors=SensorConfig(), camera=camera, noise=noise, sonar_reach=2.0)
    assert config.senses == senses
    with pytest.raises(MbnInputError, match="not registered"):
        Senses(extra=("no_such_sensor",))
    with pytest.raises(MbnInputError, match="not registered"):
        RolloutConfig(extra_sensors=("no_such_sensor",))
    with pytest.raises(MbnInputError, match="read always"):
        Senses(extra=("camera",))
    with pytest.raises(MbnInputError, match="Stage indices"):
        Senses(sonars=(16,))


def test_a_sensor_added_from_outside_is_read_through_sense(compass, corridor):
    world, mc, mi = in_maze(corridor, 4)
    pose = jnp.asarray([[4.8, 1.8, 0.0], [6.0, 1.7, 0.3], [8.0, 1.9, 3.0], [9.5, 1.9, -2.0]])
    place = locate(world, mc, pose)
    assert isinstance(find_sensor("compass"), compass)
    plain = Senses(camera=CameraConfig())
    senses = Senses(camera=CameraConfig(), extra=("compass",))
    read = jax.jit(sense, static_argnums=(4,))
    r = read(world, mc, mi, place, senses)
    assert isinstance(r, Reading)
    assert list(r) == [*BUILT_IN_CHANNELS, "compass"]  # after the built-in channels
    theta = np.asarray(pose[:, 2])
    np.testing.assert_allclose(r["compass"], np.stack([np.cos(theta), np.sin(theta)], -1))
    # the built-in channels read as without it, bit for bit
    without = read(world, mc, mi, place, plain)
    for channel in BUILT_IN_CHANNELS:
        np.testing.assert_array_equal(r[channel], without[channel])
    np.testing.assert_array_equal(r.camera, [2, 0, 2, 0])
    # its width: two columns of the reading's vector, at its place
    assert senses.widths == {"sonars": 16, "camera": 2, "tile": 1, "compass": 2}
    assert senses.width == plain.width + 2 == 21
    vector = r.vector()
    assert vector.shape == (4, senses.width) and vector.dtype == r.ranges.dtype
    np.testing.assert_array_equal(vector[:, :16], r.ranges)
    np.testing.assert_array_equal(vector[:, 16:19], np.stack([r.camera, r.blobs, r.under], -1))
    np.testing.assert_array_equal(vector[:, 19:], r["compass"])
    # a reading is one pytree: a stalled robot keeps all of it
    stalled = jnp.asarray([True, False, True, False])
    kept = undo_stalled(stalled, without, Reading({**without, "ranges": without.ranges + 1}))
    np.testing.assert_array_equal(kept.ranges[0], without.ranges[0])
    np.testing.assert_array_equal(kept.ranges[1], without.ranges[1] + 1)


# slow: a second path; CI reads the sensor through sense(), the one path a rollout takes
@pytest.mark.slow
def test_a_sensor_added_from_outside_reaches_the_controller_in_a_rollout(compass, corridor):
    world, _, _ = in_maze(corridor, 2)

    def controller(state, obs):
        """Keeps the compass it reads; turns while driving slowly along the corridor."""
        v = 0.1 + 0.0 * obs.t
        return obs.extra["compass"], (v, 0.5 + 0.0 * obs.t)

    config = RolloutConfig(steps=12, record_every=1, record_controller=True)
    poses = jnp.asarray([[3.0, 1.8, 0.0], [9.0, 1.8, math.pi / 2]])
    mi = jnp.zeros((2,), jnp.int32)
    state = jnp.zeros((2, 2))
    with pytest.raises(KeyError):  # not read unless the config names it
        rollout(world, controller, state, poses, mi, config)
    config = RolloutConfig(
        steps=12, record_every=1, record_controller=True, extra_sensors=["compass"]
    )
    assert config.extra_sensors == ("compass",) and config.senses.extra == ("compass",)
    result = rollout(world, controller, state, poses, mi, config)
    traj = result.trajectory
    theta = np.asarray(traj.pose[:, :, 2])
    seen = np.stack([np.cos(theta), np.sin(theta)], -1)
    # the state recorded at a step is the one before it: the compass of the step before
    np.testing.assert_allclose(traj.controller[:, 1:], seen[:, :-1], atol=1e-12)
    np.testing.assert_allclose(result.controller_state, seen[:, -1], atol=1e-12)
    assert np.ptp(theta[0]) > 0.5  # it turned: the compass followed


def test_a_sensor_is_held_to_its_width_and_its_channels(corridor):
    world, mc, mi = in_maze(corridor, 2)
    place = locate(world, mc, jnp.asarray([[4.8, 1.8, 0.0], [6.0, 1.7, 0.3]]))

    class Liar:
        name = "liar"

        def width(self, senses):
            return 3

        def read(self, world, mc, maze_index, place, senses, key):
            return {"liar": place.pose[:, :2]}

    class Thief:
        name = "thief"

        def width(self, senses):
            return 1

        def read(self, world, mc, maze_index, place, senses, key):
            return {"under": place.pose[:, 0]}

    register_sensor(Liar())
    register_sensor(Thief())
    try:
        with pytest.raises(MbnInputError, match="fill 2 columns, its width is 3"):
            sense(world, mc, mi, place, Senses(extra=("liar",)))
        with pytest.raises(MbnInputError, match="'under' is read already"):
            sense(world, mc, mi, place, Senses(extra=("thief",)))
        with pytest.raises(MbnInputError, match="registered already"):
            register_sensor(Liar())
    finally:
        unregister_sensor("liar")
        unregister_sensor("thief")
    with pytest.raises(MbnInputError, match="not registered"):
        find_sensor("liar")
    with pytest.raises(MbnInputError, match="needs a name"):
        register_sensor(object())  # type: ignore[arg-type]
    with pytest.raises(MbnInputError, match="key"):
        sense(world, mc, mi, place, Senses(noise=NoiseConfig(camera_false=0.5)))
