"""Sweeps in installments (``mbn.experiments.sweep.combine``): ``--keep`` keeps what a summary
reads of the finished seeds, ``--combine`` makes one sweep of several installments and
summarizes it, with the figures of the same seeds summarized in one folder."""

from __future__ import annotations

import gzip
import json

import pytest

from mbn.cli.main import main
from mbn.errors import MbnInputError
from mbn.experiments.sweep.combine import combine_sweeps, keep_sweep
from mbn.experiments.sweep.report import summarize_folder
from mbn.io import read_json
from tests.experiments.sweep.conftest import fake_run, fake_sweep

CURVE = [0.0, 1.0, 2.0]


def _sweep(out, config, seeds, failed=(), lf_jitter=None):
    """A fake sweep over ``seeds`` (those in ``failed`` failed); ``lf_jitter``: seed -> the
    successes of LF's jittered test."""
    runs = {
        str(s): {"state": "failed", "error": "RuntimeError: boom"}
        if s in failed
        else {"state": "done", "seconds": 60.0 + s}
        for s in seeds
    }
    fake_sweep(out, list(seeds), config, runs=runs)
    for s in seeds:
        if s not in failed:
            k = (lf_jitter or {}).get(s)
            fake_run(
                out, s, config, {} if k is None else {"lf_jitter": k}, {}, {"A": s != 1}, CURVE
            )
            (out / f"seed-{s}" / "timings.json").write_text(json.dumps({"total_seconds": 60 + s}))
    return out


@pytest.fixture
def config(quick_config):
    return quick_config.to_dict()


def test_keep_holds_the_finished_seeds_results_compressed_and_summarizes_as_the_whole(
    tmp_path, config
):
    whole = _sweep(tmp_path / "whole", config, [0, 1, 2, 3], failed=(3,), lf_jitter={1: 150})
    kept = keep_sweep(whole, tmp_path / "kept")
    assert kept == [0, 1, 2]
    folder = tmp_path / "kept"
    assert sorted(p.name for p in folder.iterdir()) == ["seed-0", "seed-1", "seed-2", "sweep.json"]
    assert sorted(p.name for p in (folder / "seed-1").iterdir()) == [
        "results.json.gz",
        "run.json",
        "timings.json",
    ]
    # the results, byte for byte, compressed (and the same bytes each time: mtime 0)
    raw = (whole / "seed-1" / "results.json").read_bytes()
    packed = (folder / "seed-1" / "results.json.gz").read_bytes()
    assert gzip.decompress(packed) == raw and packed == gzip.compress(raw, mtime=0)
    head = read_json(folder / "sweep.json")
    assert head["settings"]["seeds"] == [0, 1, 2] and sorted(head["runs"]) == ["0", "1", "2"]
    assert head["kept"] == {"from": str(whole), "seeds_not_finished": [3]}
    # the kept folder's summary is the whole one's over the finished seeds
    a = summarize_folder(whole)["summary"]
    b = summarize_folder(folder)["summary"]
    assert b["finished"] == a["finished"] == 3 and b["failed"] == [] and a["failed"] == [3]
    assert b["tests"]["lf_jitter"] == a["tests"]["lf_jitter"]
    assert b["tests"]["lf_jitter"]["pooled"]["successes"] == 550
    with pytest.raises(MbnInputError, match="exists and is not empty"):
        keep_sweep(whole, folder)


def test_combined_installments_summarize_as_one_sweep_of_their_seeds(tmp_path, config):
    one = _sweep(tmp_path / "one", config, [0, 1], lf_jitter={1: 150})
    two = _sweep(tmp_path / "two", config, [2, 3, 4], failed=(4,), lf_jitter={3: 100})
    keep_sweep(one, tmp_path / "one-kept")
    data = combine_sweeps([tmp_path / "one-kept", two], tmp_path / "all")
    s = data["summary"]
    assert data["settings"]["seeds"] == [0, 1, 2, 3] and s["finished"] == 4
    assert s["tests"]["lf_jitter"]["pooled"]["successes"] == 200 + 150 + 200 + 100
    assert [c["seeds"] for c in data["combined"]] == [[0, 1], [2, 3]]
    assert data["executor"] == "combined"
    # the same seeds made in one sweep give the same statistics
    same = _sweep(tmp_path / "same", config, [0, 1, 2, 3], lf_jitter={1: 150, 3: 100})
    whole = summarize_folder(same)["summary"]
    assert s["tests"] == whole["tests"] and s["targets"] == whole["targets"]
    md = (tmp_path / "all" / "sweep.md").read_text()
    assert "Combined from installments: seeds 0-1 from" in md and "; seeds 2-3 from" in md
    # a combined sweep is itself an installment for the next one
    three = _sweep(tmp_path / "three", config, [5])
    again = combine_sweeps([tmp_path / "all", three], tmp_path / "all2")
    assert "; seed 5 from" in (tmp_path / "all2" / "sweep.md").read_text()
    assert again["summary"]["finished"] == 5
    # ... listing the installments it was made of, not the combined folder
    assert [(c["folder"], c["seeds"]) for c in again["combined"]] == [
        (str(tmp_path / "one-kept"), [0, 1]),
        (str(two), [2, 3]),
        (str(three), [5]),
    ]


def test_installments_that_differ_or_overlap_are_refused_in_one_line(tmp_path, config):
    one = _sweep(tmp_path / "one", config, [0, 1])
    two = _sweep(tmp_path / "two", config, [1, 2])
    with pytest.raises(MbnInputError, match=r"^--combine: seed 1 is in both .*one and .*two$"):
        combine_sweeps([one, two], tmp_path / "x")
    other = {**config, "seed_offset_for_this_test": 1}
    three = _sweep(tmp_path / "three", other, [5])
    with pytest.raises(MbnInputError, match=r"three has another config than .*one"):
        combine_sweeps([one, three], tmp_path / "x")
    with pytest.raises(MbnInputError, match="at least two sweeps"):
        combine_sweeps([one], tmp_path / "x")
    assert not (tmp_path / "x").exists()  # nothing left behind


def test_the_command_keeps_combines_and_refuses_settings(tmp_path, config, capsys):
    one = _sweep(tmp_path / "one", config, [0])
    two = _sweep(tmp_path / "two", config, [1])
    kept = tmp_path / "kept"
    assert main(["sweep", "--out", str(one), "--keep", str(kept)]) == 0
    assert f"kept seeds 0 of {one} in {kept}" in capsys.readouterr().out
    out = tmp_path / "all"
    assert main(["sweep", "--quiet", "--out", str(out), "--combine", str(kept), str(two)]) == 0
    assert capsys.readouterr().out.startswith("sweep: ")
    assert (out / "sweep.html").exists()
    for argv, message in (
        (["--combine", str(kept), str(two), "--seeds", "0-1"], "--combine reads the settings"),
        (["--keep", str(tmp_path / "k2"), "--summarize"], "--summarize and --keep do not go"),
    ):
        assert main(["sweep", "--out", str(tmp_path / "new"), *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1


def test_a_results_file_that_is_not_gzip_is_one_line(tmp_path):
    bad = tmp_path / "results.json.gz"
    bad.write_text("{}")
    with pytest.raises(MbnInputError, match=r"results.json.gz: not gzip-compressed"):
        read_json(bad)
