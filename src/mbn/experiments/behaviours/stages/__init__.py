"""The stages of the new-behaviours experiment that ``mbn reproduce`` does not have."""
