"""Tests of the ``im_full`` stage of ``mbn run new-behaviours``: the fully programmable
interpreter built from a run's RF, its file, its tests and the agreement curve. The tests on
the stage's run are slow (left out of CI, run with ``pytest -m slow``); the stage's helpers are
checked in CI."""

from __future__ import annotations

import numpy as np
import pytest

from mbn.controllers import CTRNNControllerSpec, make_controller, read_controller_spec
from mbn.errors import MbnInputError
from mbn.experiments.behaviours import NEW_BEHAVIOURS
from mbn.experiments.stages.im_full import (
    FULL_CONNECTIONS,
    IMFullSettings,
    nested_sets,
    reference_controller,
)
from mbn.experiments.trials import agreement
from mbn.networks.ctrnn import make_ctrnn
from mbn.networks.programmable import Connection


def test_the_stages_before_im_full_are_the_reproductions_with_their_keys():
    from mbn.experiments.reproduce import STAGES as REPRODUCE_STAGES

    names = NEW_BEHAVIOURS.registry.names
    assert names[:4] == ("multiplier", "rf", "lf_search", "lf")
    for n in names[:4]:
        assert NEW_BEHAVIOURS.registry[n].key_id == REPRODUCE_STAGES[n].key_id
    assert NEW_BEHAVIOURS.registry["im_full"].key_id not in {s.key_id for s in REPRODUCE_STAGES}


def test_nested_sets_grow_one_connection_at_a_time_from_the_papers_set():
    c = [Connection.parse(x) for x in ("W[1,2]", "WE[1,0]", "W[0,0]", "W[1,1]")]
    sets = nested_sets([c[0], c[1]], [c[2], c[0], c[3], c[1]])
    assert [len(s) for s in sets] == [2, 3, 4]
    assert sets[0] == [c[0], c[1]] and sets[-1] == [c[0], c[1], c[2], c[3]]


def test_agreement_counts_trials_with_every_exit_the_same():
    a = {"exits": np.array([[0, 1, 2], [0, 1, 2], [2, 2, -1]])}
    b = {"exits": np.array([[0, 1, 2], [0, 2, 2], [2, 2, -1]])}
    assert agreement(a, b) == {"trials": 3, "same_branches": 2, "rate": 2 / 3}


def test_settings_refuse_bad_connections():
    with pytest.raises(MbnInputError, match=r"im_full\.connections"):
        IMFullSettings(connections=("W[1,1]", "V[0,0]"))
    with pytest.raises(MbnInputError, match="listed twice"):
        IMFullSettings(connections=("W[1,1]", "W[1,1]"))
    assert len(FULL_CONNECTIONS) == 14  # the default: the genome's 12 and the turning neuron's
    assert IMFullSettings().connections == FULL_CONNECTIONS
    # the default step: multipliers at tau/80, 160 sub-steps (h / tau_m = 0.1)
    assert (IMFullSettings().tau_ratio, IMFullSettings().substeps) == (0.0125, 160)


def test_a_stiff_lf_is_compared_with_as_the_runs_judge_it():
    # an LF whose turning neuron needs 181 sub-steps at its 20 (as one evolved LF of a run of
    # seed 22 did): the stage compares the interpreter with it rather than end the run
    net = make_ctrnn(np.diag([1.0, -800.0, 1.0]), np.eye(3), [0.5, 0.5, 0.5])
    with pytest.raises(MbnInputError, match="stability limit"):
        make_controller(CTRNNControllerSpec(net=net, behavior="left"), None)
    loaded = reference_controller(net, "left")
    assert loaded.dt == pytest.approx(0.1)


@pytest.mark.slow
def test_im_full_writes_a_programmable_interpreter_of_rf(im_full_run):
    rundir, data, conns = im_full_run
    spec = read_controller_spec(rundir.controller_file("im_full"))
    interp = spec.interpreter
    assert [str(c) for c in interp.connections] == conns
    assert interp.num_neurons == 3 + len(conns) * 6 == data["neurons"]
    np.testing.assert_allclose(np.asarray(interp.lower), -20.0)
    np.testing.assert_allclose(np.asarray(interp.upper), 20.0)
    assert spec.simulation == "blocks" and spec.substeps == 20  # the fixture's
    assert spec.metadata["sha256"] == interp.digest() == data["sha256"]
    # its programs are RF's and LF's weights, encoded (eq. 2)
    rf = read_controller_spec(rundir.controller_file("rf")).net
    lf = read_controller_spec(rundir.controller_file("lf")).net
    np.testing.assert_allclose(spec.programs["right"], np.asarray(interp.program_of(rf)))
    np.testing.assert_allclose(spec.programs["left"], np.asarray(interp.program_of(lf)))
    decoded = np.asarray(interp.decode(np.asarray(spec.programs["left"])))
    np.testing.assert_allclose(decoded, [c.value(lf) for c in interp.connections], atol=1e-5)


@pytest.mark.slow
def test_im_full_records_tests_agreement_and_the_curve(im_full_run):
    _, data, conns = im_full_run
    for short in ("rf", "lf"):
        for suffix in ("", "_jitter", "_heldout"):
            t = data["tests"][f"im_full_{short}{suffix}"]
            a = data["agreement"][f"im_full_{short}{suffix}"]
            assert t["trials"] == a["trials"] > 0
            assert 0 <= a["same_branches"] <= a["trials"]
    curve = data["curve"]
    sizes = [len(r["connections"]) for r in curve]
    assert sizes == list(range(len(conns) - 1, len(conns) + 1))  # LF's set, then one more
    # the full set's row is the stage's own interpreter (its connections in another order: the
    # same network, summed in another order) on the jittered test
    full = data["agreement"]["im_full_lf_jitter"]["same_branches"]
    assert abs(curve[-1]["agreement_lf"]["same_branches"] - full) <= 1
    assert data["step"] == pytest.approx(0.1 / 20)  # the fixture's settings
    assert data["multiplier_tau"] == pytest.approx(0.1 * 0.5)
