"""The simulated robot world: a Stage-faithful Pioneer 3DX with sonars in mazes of walls.

* :mod:`mbn.world.robot` — the Pioneer 3DX as Stage models it (body octagon, 16 sonars, speed
  limits) and its forward-Euler kinematics;
* :mod:`mbn.world.geometry` — exact ray casting against wall segments and body-wall collision.
"""
