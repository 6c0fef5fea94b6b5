"""The reports of the experiments built on the reproduction state what each run recorded, not a
default of the code: the ablations' time constants and sub-steps, the realistic noise's levels
(one run's report and a sweep's)."""

from __future__ import annotations

from mbn.experiments.ablations.report import claims as ablation_claims
from mbn.experiments.ablations.report import what
from mbn.experiments.noise.over_runs import noise_over_runs
from mbn.experiments.noise.report import claims as noise_claims
from mbn.experiments.noise.report import levels_text
from mbn.experiments.stages.ablations import Variant


def _rate(rate: float, trials: int = 20) -> dict:
    """A test as the noise levels and the ablations record it."""
    return {
        "successes": round(rate * trials),
        "trials": trials,
        "rate": rate,
        "wilson95": [0.0, 1.0],
    }


def _ablation(what_text: str, tau_ratio: float | None, substeps: int | None) -> dict:
    """A variant as ``stages/ablations.json`` records it."""
    row: dict = {"what": what_text, "mbn_jitter": _rate(1.0), "mbn_heldout": _rate(1.0)}
    if tau_ratio is not None:
        row["interpreter"] = {
            "tau_ratio": tau_ratio,
            "substeps": substeps,
            "multiplier_neurons": 6,
        }
        row["agreement"] = {
            "rf_jitter": 1.0,
            "lf_jitter": 1.0,
            "rf_heldout": 1.0,
            "lf_heldout": 1.0,
        }
    return row


def test_the_ablations_state_the_time_constant_each_variant_ran_at():
    rows = {
        "as_run": _ablation("the run's MBN (no change)", 0.05, 40),
        "tau_10": _ablation("multipliers at τ/10, the paper's (20 sub-steps)", 0.1, 25),
        "wrong_program": _ablation("the tiles swapped", None, None),
    }
    typed = {name: Variant.from_json(row) for name, row in rows.items()}
    assert what("as_run", typed["as_run"]) == (
        "the run's MBN (no change); multipliers at τ/20, 40 sub-steps"
    )
    # the sub-steps the variant ran with, not the words written when it was defined
    assert what("tau_10", typed["tau_10"]) == "multipliers at τ/10, 25 sub-steps, the paper's"
    assert what("wrong_program", typed["wrong_program"]) == "the tiles swapped"
    rows["tau_10"]["interpreter"]["tau_ratio"] = 0.125  # as if a run had recorded another
    stage = {
        "variants": rows,
        "networks": {"rf_jitter": _rate(1.0)},
        "trials": {"jitter_per_mark": 2, "heldout_repeats": 1},
    }
    row = next(c for c in ablation_claims({"ablations": stage}) if "τ/10)" in c["claim"])
    assert row["target"].endswith("at τ/8") and row["measured"].startswith("multipliers at τ/8,")


def _point(rate: float) -> dict:
    """A controller at one noise level, as ``stages/noise_levels.json`` records it."""
    return {"level": 0.0, "jitter": _rate(rate), "heldout": _rate(rate)}


LEVELS = {"sonar_std": 0.03, "sonar_dropout": 0.0, "wheel_std": 0.07, "camera_miss": 0.1}


def test_the_noise_claim_states_the_realistic_levels_the_run_recorded():
    realistic = {"noise": LEVELS, **{n: _point(0.9) for n in ("rf", "im_rf", "im_lf", "mbn")}}
    data = {
        "channels": [],
        "levels": {},
        "curves": {},
        "realistic": realistic,
        "trials": {"jitter_per_mark": 2, "heldout_repeats": 1},
        "evolved_under": {},
    }
    row = noise_claims({"noise_levels": data})[0]
    assert "(sonar_std = 0.03, wheel_std = 0.07, camera_miss = 0.1)" in row["measured"]
    assert "2 cm" not in row["measured"] and "5 %" not in row["measured"]
    assert levels_text({"sonar_std": 0.0}) == "every channel off"


def test_a_noise_sweep_states_the_realistic_levels_its_runs_recorded(tmp_path):
    runs = {s: {"realistic": {"noise": LEVELS}, "tests": {}, "levels": {}} for s in (0, 1)}
    _, sections, _ = noise_over_runs(tmp_path, runs)
    text = " ".join(" ".join(s.text) for s in sections)
    assert "sonar_std = 0.03, wheel_std = 0.07, camera_miss = 0.1" in text
