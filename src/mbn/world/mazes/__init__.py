"""Mazes: the data (:mod:`~mbn.world.mazes.model`), the ``.maze``, TOML and Player/Stage
``.world`` readers, the built-in mazes, generated ones, and :func:`~mbn.world.mazes.load.load_maze`,
which reads any of them by name or file (``docs/mazes.md``)."""
