"""The stages of ``mbn run noise`` beyond the reproduction's."""
