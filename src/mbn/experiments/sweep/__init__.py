"""``mbn sweep``: one reproduction per seed, each a task on Ray, resumable, and a report over the
seeds (``docs/sweep.md``).

* :mod:`~mbn.experiments.sweep.seeds` — the ``--seeds`` syntax (``0-9``, ``3``, ``0,2,5-7``);
* :mod:`~mbn.experiments.sweep.targets` — the per-run targets that define "a seed meets every
  target", in one table;
* :mod:`~mbn.experiments.sweep.specs` — the experiments a sweep runs (the reproduction, by
  default, and ``new-behaviours``), each with its targets, tests and DE curves;
* :mod:`~mbn.experiments.sweep.run` — the sweep folder (``sweep.json``), which seeds are done,
  to resume or to run, and the scheduling of one ``run_experiment`` per seed on Ray;
* :mod:`~mbn.experiments.sweep.monitor` — the live table of seeds x stages, read from the seed
  folders;
* :mod:`~mbn.experiments.sweep.summary` — the statistics over seeds (median [IQR], Wilson
  intervals, targets met, claims reproduced);
* :mod:`~mbn.experiments.sweep.report` — ``sweep.md`` and a self-contained ``sweep.html``,
  rendered from the folder alone.

Every seed folder ``DIR/seed-K`` is a plain run folder of its experiment (the pipeline's
:func:`~mbn.experiments.pipeline.runner.run_experiment` writes it).
"""
