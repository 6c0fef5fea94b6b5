"""Pictures: mazes, trajectories, episodes, GIF animations, the multiplier's error map and the
figures of a run report. The only package of ``mbn`` that imports matplotlib (lazily, inside the
functions that draw)."""
