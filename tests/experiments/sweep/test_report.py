"""The sweep's report from a fake folder of seed runs (no Ray, no simulation)."""

from __future__ import annotations

import base64
import json
import re

import pytest

from mbn.experiments.sweep.report import summarize_folder, summary_line
from tests.experiments.sweep.conftest import fake_run, fake_sweep


@pytest.fixture
def folder(tmp_path, quick_config, monkeypatch):
    import mbn.world.rollout as rollout

    def no_simulation(*a, **k):
        raise AssertionError("the report simulated")

    for name in dir(rollout):
        if name.startswith("rollout"):
            monkeypatch.setattr(rollout, name, no_simulation)
    config = quick_config.to_dict()
    out = tmp_path / "sweep"
    fake_sweep(
        out,
        [0, 1, 2, 3],
        config,
        runs={
            "0": {"state": "done", "seconds": 61.0},
            "1": {"state": "done", "seconds": 62.0},
            "2": {"state": "done", "seconds": 63.0},
            "3": {"state": "failed", "error": "RuntimeError: stage pm exploded"},
        },
    )
    curve = [0.0, 1.0, 2.0, 3.0]
    # claim C: run 1 cannot judge it (verdict None: e.g. an ablation of an MBN that fails)
    fake_run(out, 0, config, {}, {}, {"claim A": True, "claim B": True, "claim C": True}, curve)
    fake_run(
        out,
        1,
        config,
        {"lf_jitter": 150, "mbn": 9},
        {},
        {"claim A": True, "claim B": False, "claim C": None},
        curve,
    )
    fake_run(
        out,
        2,
        config,
        {},
        {"im_lf_jitter": 190},
        {"claim A": True, "claim B": False, "claim C": True},
        curve,
    )
    return out


def test_summary_of_a_fake_folder(folder):
    data = summarize_folder(folder)
    s = data["summary"]
    assert s["finished"] == 3 and s["failed"] == [3] and s["meet_every_target"] == 1
    assert s["per_seed"]["1"]["missed"] == ["mbn", "lf_jitter"]
    assert s["per_seed"]["2"]["missed"] == ["agreement_im_lf_jitter"]
    lf = s["tests"]["lf_jitter"]
    assert lf["pooled"] == {
        "successes": 550,
        "trials": 600,
        "wilson95": pytest.approx([0.89181, 0.93622], abs=5e-5),
    }
    assert lf["median"] == pytest.approx(1.0) and lf["min"] == pytest.approx(0.75)
    assert s["targets"]["lf_jitter"]["seeds_meeting"] == 2
    on_disk = json.loads((folder / "sweep.json").read_text())
    assert on_disk["summary"]["meet_every_target"] == 1
    line = summary_line(data)
    assert line.startswith(
        "sweep: 1/4 seeds meet every target, 0/4 every generalization target, 1 failed (seed 3: "
        "RuntimeError"
    )
    assert line.endswith("2 min 05 s")


def test_report_files_name_failures_claims_and_embed_figures(folder):
    summarize_folder(folder)
    md = (folder / "sweep.md").read_text()
    html = (folder / "sweep.html").read_text()
    assert "| claim A | crit claim A | 3 of 3 |" in md
    assert "| claim B | crit claim B | 1 of 3 |" in md
    assert "| claim C | crit claim C | 2 of 2 judged (1 not testable) |" in md
    assert "| 1 | done | mbn, lf_jitter |" in md
    assert "| 3 | failed | RuntimeError: stage pm exploded |" in md
    assert "| lf_jitter | >= 95% | 2/3 | 100.0% [87.5%, 100.0%] | 75.0% | 550/600 |" in md
    images = re.findall(r"src='data:image/png;base64,([^']+)'", html)
    assert len(images) == 2  # the DE bands and the box plots, embedded
    assert all(base64.b64decode(i)[:8] == b"\x89PNG\r\n\x1a\n" for i in images)
    assert "src='figures/" not in html
    assert (folder / "figures" / "sweep_de.png").stat().st_size > 10_000


def test_summarize_without_a_sweep_is_one_line(tmp_path):
    from mbn.errors import MbnInputError

    with pytest.raises(MbnInputError, match="no sweep there"):
        summarize_folder(tmp_path)


def test_a_sweep_recorded_before_a_setting_existed_is_summarized_as_recorded(
    tmp_path, quick_config
):
    """A later version of mbn that has a settings section the sweep's runs did not have still
    counts their finished seeds: they are compared with the config the sweep recorded."""
    config = quick_config.to_dict()
    old = {k: v for k, v in config.items() if k != "validation"}
    assert old != config  # the section exists now
    out = tmp_path / "old"
    fake_sweep(out, [0, 1], old)
    for s in (0, 1):
        fake_run(out, s, old, {}, {}, {"claim A": True}, [0.0, 1.0])
    data = summarize_folder(out)
    assert data["summary"]["meet_every_target"] == 2


@pytest.mark.parametrize("analysis", [False, True])
def test_a_sweep_without_per_run_targets_counts_finished_runs_not_targets_met(analysis):
    """The ablations (no analysis over runs) and the noise levels or the contest (with one) have
    no per-run target: their line counts finished runs, never "meet every target"."""
    summ = {
        "seeds": [0, 1, 2],
        "finished": 2,
        "failed": [],
        "meet_every_target": 2,
        "per_seed": {"0": {"state": "done"}, "1": {"state": "done"}, "2": {"state": "missing"}},
        "tests": {},
        "targets": {},
        "claims": [],
        **({"analysis": {}} if analysis else {}),
    }
    line = summary_line({"summary": summ, "runs": {}})
    assert line == "sweep: 2/3 seeds finished (no per-run targets), 1 not run"


def test_a_sweep_that_gained_seeds_says_so(folder):
    """A sweep continued with more seeds (`sweep.json` ``grown``) says in its first section
    which seeds it held before, and when; a sweep that never grew says nothing of it."""
    summarize_folder(folder)
    assert "The sweep grew" not in (folder / "sweep.md").read_text()
    data = json.loads((folder / "sweep.json").read_text())
    data["grown"] = [
        {"seeds_before": [0, 1], "at": "2026-12-07T20:00:00+0000"},
        {"seeds_before": [0, 1, 2], "at": "2026-12-08T09:30:00+0000"},
    ]
    (folder / "sweep.json").write_text(json.dumps(data))
    summarize_folder(folder)
    assert (
        "The sweep grew: it held seeds 0-1 until 2026-12-07T20:00:00+0000; then seeds 0-2 until "
        "2026-12-08T09:30:00+0000." in (folder / "sweep.md").read_text()
    )
