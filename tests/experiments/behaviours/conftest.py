"""A quick reproduction's folder with the ``im_full`` stage of ``mbn run new-behaviours`` run on
it, shared by the tests of this folder."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from mbn.controllers import read_controller_spec
from mbn.experiments.behaviours import NEW_BEHAVIOURS
from mbn.experiments.pipeline import RunDir
from mbn.experiments.pipeline.runner import replace_section, run_stage
from mbn.experiments.stages.im_full import FULL_CONNECTIONS
from mbn.networks.programmable import differing_connections
from tests.conftest import once


@pytest.fixture(scope="session")
def im_full_run(quick_run, tmp_path_factory, worker_id):
    """The quick reproduction's folder with the ``im_full`` stage run on it (quick settings;
    the stages before it are the reproduction's), made once per session (``once``)."""
    root, data, conns = once(
        tmp_path_factory, worker_id, "im_full", lambda folder: _im_full(quick_run, folder)
    )
    return RunDir(Path(root)), data, conns


def _im_full(quick_run, parent: Path) -> list:
    out, _ = quick_run
    folder = parent / "run"
    shutil.copytree(out, folder)
    rundir = RunDir(folder)
    rf = read_controller_spec(rundir.controller_file("rf")).net
    lf = read_controller_spec(rundir.controller_file("lf")).net
    # a short curve (the connections where LF differs, then one more) and the reproduction's
    # interpreter step (tau/10 at 20 sub-steps, not the default tau/40 at 80) keep it quick
    differ = [str(p.connection) for p in differing_connections(rf, lf, margin=0.0)]
    extra = [c for c in FULL_CONNECTIONS if c not in differ][:1]
    config = NEW_BEHAVIOURS.config(quick=True)
    section = config["im_full"].replace(
        curve=True, connections=(*extra, *differ), tau_ratio=0.1, substeps=20
    )
    # the LF search's candidates narrowed to them too: an interpreter must have every
    # connection LF may re-evolve programmable (here LF has run: its triple is known)
    search = config["lf_search"].replace(candidates=(*extra, *differ))
    config = replace_section(replace_section(config, section), search)
    data = run_stage(NEW_BEHAVIOURS, rundir, "im_full", seed=3, config=config)
    return [str(folder), data, [*extra, *differ]]


@pytest.fixture
def nb_copy(im_full_run, tmp_path):
    """A copy of the ``im_full`` run's folder (a test may change it)."""
    rundir, _, conns = im_full_run
    folder = tmp_path / "run"
    shutil.copytree(rundir.root, folder)
    return RunDir(folder), conns
