"""The stages of ``mbn run ablations`` beyond the reproduction's."""
