"""The simulated robot world: a Stage-faithful Pioneer 3DX with sonars and a tile camera in mazes.

* :mod:`mbn.world.robot` — the Pioneer 3DX as Stage models it (body octagon, 16 sonars, speed
  limits) and its forward-Euler kinematics;
* :mod:`mbn.world.sensors` — the paper's 10 sonars, the normalisation of S, eq. 3, noise settings;
* :mod:`mbn.world.mazes.model`, :mod:`~mbn.world.mazes.load`, :mod:`~mbn.world.mazes.stage`,
  :mod:`~mbn.world.mazes.builtin`, :mod:`~mbn.world.mazes.generate` — mazes: data,
  ``.maze``/TOML/Stage files, built-ins, generated corridor mazes;
* :mod:`mbn.world.junctions` — decision cells, wall-following rule exits, junction passes;
* :mod:`mbn.world.geometry` — exact reference geometry (segment ray casting, polygon collision);
* :mod:`mbn.world.engine` — the fast engine: lattice ray marching with culled windows, cell
  collision, the blob-finding camera;
* :mod:`mbn.world.step` — one robot step (sensing, speed limits, kinematics, the stall rule),
  shared by the rollout and the Gymnasium environment;
* :mod:`mbn.world.rollout` — batched, jitted episodes of controllers in mazes, with their
  statistics and junction passes (:mod:`mbn.world.stats`);
* :mod:`mbn.viz.render` — pictures of mazes and episodes, animated GIFs;
* :mod:`mbn.world.gym_env` — the Gymnasium environment ``mbn/PioneerMaze-v0`` (optional extra).

See ``docs/world.md``, ``docs/mazes.md`` and ``docs/pictures.md``.
"""
