"""Controllers in the form the rollouts take: ``(state, observation) -> (state, (v, w))`` for one
robot, pure functions over explicit state (a batch of genomes is a batch of states).

* :mod:`mbn.control.ctrnn` — the motor map, CTRNN and interpreter controllers, shadowed runs;
* :mod:`mbn.control.mbn` — the Multiple Behavior Network: program module + interpreter;
* :mod:`mbn.control.switched` — its baselines: one follower per rule, switched by the tiles
  (the weights swapped, or a gate among followers running side by side).
"""
