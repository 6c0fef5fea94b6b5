"""The stages of ``mbn reproduce``, one module each; their order is
:data:`mbn.experiments.reproduce.STAGES`."""
