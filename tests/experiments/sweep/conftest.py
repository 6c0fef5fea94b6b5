"""Fake sweep folders: seed folders shaped as `mbn reproduce` writes them (run.json,
results.json, report.html, stages with DE histories), with success rates chosen by the test."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mbn.experiments.stages.protocol import TEST_NAMES
from mbn.experiments.sweep.run import SWEEP_KIND, seed_dir

TRIALS = {"": 10, "_jitter": 200, "_heldout": 204}


def _trials(name: str) -> int:
    for suffix in ("_jitter", "_heldout"):
        if name.endswith(suffix):
            return TRIALS[suffix]
    return TRIALS[""]


def fake_run(
    out: Path,
    seed: int,
    config: dict,
    successes: dict[str, int],
    agree: dict[str, int],
    claims: dict[str, bool | None],
    curve: list[float],
) -> Path:
    """A finished seed folder: every test passes all its trials unless ``successes`` says
    otherwise; the agreement tables likewise; DE curves ``curve`` (+ seed) for rf, lf, pm."""
    folder = seed_dir(out, seed)
    (folder / "stages").mkdir(parents=True)
    tests = {}
    for name in TEST_NAMES:
        n = _trials(name)
        k = successes.get(name, n)
        tests[name] = {"trials": n, "successes": k, "success_rate": k / n}
    agreement = {}
    for name in ("im_rf", "im_lf"):
        for suffix in ("", "_jitter", "_heldout"):
            n = _trials(suffix or "x")
            k = agree.get(name + suffix, n)
            agreement[name + suffix] = {"trials": n, "same_branches": k, "rate": k / n}
    results = {
        "seed": seed,
        "seeds": {"seed": seed},
        "quick": True,
        "config": config,
        "versions": dict.fromkeys(
            ("mbn", "python", "jax", "jaxlib", "numpy", "optax", "matplotlib", "os", "platform"),
            "test",
        ),
        "stages": {"tests": {"agreement": agreement}},
        "tests": tests,
        "claims": [
            {"claim": c, "paper": "", "measured": "", "pass": ok, "criterion": f"crit {c}"}
            for c, ok in claims.items()
        ],
    }
    (folder / "run.json").write_text(
        json.dumps({"kind": "mbn.reproduce", "seed": seed, "config": config})
    )
    (folder / "results.json").write_text(json.dumps(results))
    (folder / "report.html").write_text("<html></html>")
    for name in ("rf", "lf", "pm"):
        h = [x + seed for x in curve]
        (folder / "stages" / f"{name}.json").write_text(
            json.dumps({"history": {"best": h, "mean": h}})
        )
    (folder / "stages" / "lf_search.json").write_text(json.dumps({"chosen_index": 0}))
    return folder


def fake_sweep(out: Path, seeds: list[int], config: dict, runs: dict | None = None) -> None:
    """``sweep.json`` of a sweep over ``seeds`` with ``config``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "sweep.json").write_text(
        json.dumps(
            {
                "kind": SWEEP_KIND,
                "settings": {"seeds": seeds, "quick": True, "config": config},
                "runs": runs or {str(s): {"state": "done", "seconds": 60.0} for s in seeds},
                "seconds": 125.0,
            }
        )
    )


@pytest.fixture(scope="session")
def quick_config():
    from mbn.experiments.reproduce import REPRODUCE

    return REPRODUCE.config(quick=True)
