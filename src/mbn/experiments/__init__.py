"""The paper's experiment (section 3) and the machinery experiments run on: the crossroad task and
its fitness, the one jitter, genomes and evolution, the program module, the test protocol;
:mod:`~mbn.experiments.pipeline` (stages, registry, run folder, runner) and
:mod:`~mbn.experiments.reproduce` (`mbn reproduce`)."""
