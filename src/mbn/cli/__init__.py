"""The ``mbn`` command line (:func:`mbn.cli.main.main`), one module per command group."""
