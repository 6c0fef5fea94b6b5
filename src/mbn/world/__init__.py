"""The simulated robot world: a Stage-faithful Pioneer 3DX with sonars and a tile camera in mazes.

* :mod:`mbn.world.robot` — the Pioneer 3DX as Stage models it (body octagon, 16 sonars, speed
  limits) and its forward-Euler kinematics;
* :mod:`mbn.world.sensors` — the paper's 10 sonars, the normalisation of S, eq. 3, noise settings;
* :mod:`mbn.world.mazes` — mazes: the data (:mod:`~mbn.world.mazes.model`), its checks
  (:mod:`~mbn.world.mazes.validate`), ``.maze``/TOML/Stage files
  (:mod:`~mbn.world.mazes.grid_text`, :mod:`~mbn.world.mazes.toml_maze`,
  :mod:`~mbn.world.mazes.stage`), built-ins (:mod:`~mbn.world.mazes.builtin`), generated corridor
  mazes (:mod:`~mbn.world.mazes.generate`) and the loader (:mod:`~mbn.world.mazes.load`);
* :mod:`mbn.world.junctions` — decision cells, wall-following rule exits, junction passes;
* :mod:`mbn.world.geometry` — exact reference geometry (segment ray casting, polygon collision);
* :mod:`mbn.world.engine` — the fast engine: lattice ray marching with culled windows, cell
  collision, the blob-finding camera;
* :mod:`mbn.world.senses` — what a step senses as one value (:class:`~mbn.world.senses.Senses`),
  the sensors (sonars, camera, tile under the body) and the registry that adds one, the reading;
* :mod:`mbn.world.step` — one robot step (sensing, speed limits, kinematics, the stall rule),
  shared by the rollout and the Gymnasium environment;
* :mod:`mbn.world.rollout` — batched, jitted episodes of controllers in mazes, with their
  statistics and junction passes (:mod:`mbn.world.stats`);
* :mod:`mbn.world.gym_env` — the Gymnasium environment ``mbn/PioneerMaze-v0`` (optional extra).

Pictures of mazes and episodes are drawn by :mod:`mbn.viz`. See ``docs/world.md``,
``docs/mazes.md`` and ``docs/pictures.md``.
"""
