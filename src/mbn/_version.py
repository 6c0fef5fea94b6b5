"""The version of ``mbn``: the one place it is written (``pyproject.toml`` reads it from here).

Versions follow semantic versioning; each released version has its section in ``CHANGELOG.md``
and a git tag ``vX.Y.Z`` (``docs/provenance.md``, "Releasing").
"""

__version__ = "0.2.0"
