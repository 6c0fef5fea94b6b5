"""The network side: CTRNNs (paper eq. 1), the multiplier CTRNN and its training (paper 2.1),
programmable networks and their interpreters (paper section 2, eq. 2), and how well an interpreter
emulates the networks it is programmed with.

* :mod:`mbn.networks.ctrnn` — the vector field, Euler and RK4, simulation, the step-stability check;
* :mod:`mbn.networks.multiplier` — the multiplier model, evaluation, file format, shipped ones;
* :mod:`mbn.networks.multiplier_train` — training by backpropagation through time;
* :mod:`mbn.networks.programmable` — the interpreter builder, programs, exact-product mode;
* :mod:`mbn.networks.emulation` — the emulation check of an interpreter.
"""
