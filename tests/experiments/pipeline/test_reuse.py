"""``--reuse``: a run takes the stages it shares with another run of the same seed and settings,
and ends exactly as the run that ran them itself; what it may not take, it runs; a source of
another seed, other settings, other code or an unknown kind is refused in one line (other code
is taken with ``allow_other_code``, and recorded)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import jax
import numpy as np
import pytest

from mbn.config import Settings, read_toml, setting
from mbn.errors import MbnInputError
from mbn.evolution.de import DEConfig
from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment
from mbn.experiments.pipeline.reuse import read_source, takeable

CALLS: dict[str, int] = {}


@dataclass(frozen=True)
class SphereSettings(Settings):
    """The shared stage's settings."""

    section = "sphere"
    generations: int = setting(5, doc="DE generations", low=1)


class SphereStage(Stage):
    """DE on the sphere (checkpointed), its best genome written to a record."""

    name = "sphere"
    key_id = 1
    settings = SphereSettings
    outputs = ("records/best.npz",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        CALLS["sphere"] = CALLS.get("sphere", 0) + 1
        config = DEConfig(
            num_dims=3,
            popsize=8,
            maximize=False,
            lower=-5.0,
            upper=5.0,
            init_low=-5.0,
            init_high=5.0,
        )
        de = ctx.evolve(
            "sphere",
            config,
            lambda pop: np.sum(np.asarray(pop) ** 2, axis=-1),
            ctx.key,
            ctx.settings.generations,
            "sphere",
        )
        ctx.rundir.save_record("best", {"genome": np.asarray(de.data["best_genome"])})
        return de.data


class NormStage(Stage):
    """Reads the shared stage's record (its need) and draws from its own key."""

    name = "norm"
    key_id = 2
    needs = ("sphere",)

    def run(self, ctx: StageContext) -> dict[str, Any]:
        CALLS["norm"] = CALLS.get("norm", 0) + 1
        best = ctx.rundir.load_record("best")["genome"]
        return {"norm": float(np.linalg.norm(best)), "draw": float(jax.random.uniform(ctx.key))}


class OtherNormStage(NormStage):
    """A stage of the same name and key in another experiment, but another class."""


@dataclass(frozen=True)
class TailSettings(Settings):
    """A section only the second experiment has."""

    section = "tail"
    scale: float = setting(2.0, doc="a factor")


class TailStage(Stage):
    """The second experiment's own stage."""

    name = "tail"
    key_id = 3
    needs = ("sphere",)
    settings = TailSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        CALLS["tail"] = CALLS.get("tail", 0) + 1
        return {"draw": float(jax.random.uniform(ctx.key)) * ctx.settings.scale}


@dataclass(frozen=True)
class OptionalSettings(Settings):
    """A section some experiments have and a stage reads as its defaults where there is none
    (as ``[noise]``)."""

    section = "optional"
    level: float = setting(0.0, doc="a level, off by default")


FIRST = Experiment("first", "mbn.first", Registry([SphereStage(), NormStage()]))
WITH_OPTIONAL = Experiment(
    "with", "mbn.with", Registry([SphereStage(), NormStage()]), shared=(OptionalSettings,)
)
SECOND = Experiment("second", "mbn.second", Registry([SphereStage(), TailStage(), NormStage()]))
ODD = Experiment("odd", "mbn.odd", Registry([SphereStage(), OtherNormStage()]))
KNOWN = {e.kind: e for e in (FIRST, SECOND, ODD, WITH_OPTIONAL)}


def _source(path):
    return read_source(path, KNOWN.get)


def _run(experiment, folder, seed=4, document=None, **kw):
    config = experiment.config(document=document)
    return run_experiment(experiment, folder, seed=seed, config=config, **kw)


@pytest.fixture(autouse=True)
def _count():
    CALLS.clear()


def test_a_run_taking_shared_stages_ends_as_the_run_that_ran_them(tmp_path):
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    alone = _run(SECOND, tmp_path / "alone", log=lambda _: None)
    CALLS.clear()
    lines: list[str] = []
    taken = _run(SECOND, tmp_path / "taken", reuse=_source(tmp_path / "first"), log=lines.append)
    assert taken["stages"] == alone["stages"]
    # the shared stages were copied, not run; the own stage ran
    assert CALLS == {"tail": 1}
    assert f"stages sphere, norm: taken from {tmp_path / 'first'}" in lines
    assert (tmp_path / "taken" / "records" / "best.npz").is_file()
    assert (tmp_path / "taken" / "checkpoints" / "sphere.npz").is_file()
    manifest = json.loads((tmp_path / "taken" / "run.json").read_text())
    source_code = json.loads((tmp_path / "first" / "run.json").read_text())["code"]
    assert manifest["reused"] == [
        {
            "from": str(tmp_path / "first"),
            "stages": ["sphere", "norm"],
            "code": source_code,
            "other_code": False,
        }
    ]


def test_a_stage_of_another_class_or_not_finished_there_is_run(tmp_path):
    _run(ODD, tmp_path / "odd", log=lambda _: None)
    _run(SECOND, tmp_path / "taken", reuse=_source(tmp_path / "odd"), log=lambda _: None)
    assert CALLS == {"sphere": 1, "norm": 2, "tail": 1}  # norm: OtherNormStage in odd
    # a source whose shared stage lost its output: it and what needs it run here
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    (tmp_path / "first" / "records" / "best.npz").unlink()
    assert takeable(SECOND, _rundir(tmp_path / "empty"), _source(tmp_path / "first")) == []


def _rundir(path):
    from mbn.experiments.pipeline.rundir import RunDir

    return RunDir(path)


def test_stages_done_here_are_kept_and_a_resumed_run_takes_the_rest(tmp_path):
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    _run(SECOND, tmp_path / "run", stages=["sphere"], log=lambda _: None)
    CALLS.clear()
    done = _run(
        SECOND,
        tmp_path / "run",
        resume=True,
        reuse=_source(tmp_path / "first"),
        log=lambda _: None,
    )
    assert CALLS == {"tail": 1}
    manifest = json.loads((tmp_path / "run" / "run.json").read_text())
    assert manifest["reused"][0]["stages"] == ["norm"]
    assert done["stages"]["norm"] == _run(FIRST, tmp_path / "again")["stages"]["norm"]


def test_another_seed_or_other_shared_settings_are_refused(tmp_path):
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    with pytest.raises(MbnInputError, match=r"a run of seed 4, not 5$"):
        _run(SECOND, tmp_path / "s5", seed=5, reuse=_source(tmp_path / "first"))
    toml = tmp_path / "more.toml"
    toml.write_text("[sphere]\ngenerations = 6\n")
    with pytest.raises(
        MbnInputError,
        match=r"run\.json: the run there was made with other settings \(sphere\.generations: 5 "
        r"then, 6 now\); nothing is taken from it",
    ):
        _run(SECOND, tmp_path / "g6", document=read_toml(toml), reuse=_source(tmp_path / "first"))
    assert CALLS == {"sphere": 1, "norm": 1}
    # a section only this experiment has may differ: the shared stages never read it
    toml.write_text("[tail]\nscale = 3.0\n")
    _run(SECOND, tmp_path / "t3", document=read_toml(toml), reuse=_source(tmp_path / "first"))
    assert CALLS == {"sphere": 1, "norm": 1, "tail": 1}


def _files(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_a_refused_reuse_writes_nothing_so_the_corrected_command_runs(tmp_path):
    """Refused before the folder is made or its run.json written (before, the run.json left
    behind refused the corrected command as "holds another run"); with --force, before the
    run there is cleared."""
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    source = _source(tmp_path / "first")
    out = tmp_path / "run"
    with pytest.raises(MbnInputError, match=r"a run of seed 4, not 5$"):
        _run(SECOND, out, seed=5, reuse=source)
    assert not out.exists()
    toml = tmp_path / "g6.toml"
    toml.write_text("[sphere]\ngenerations = 6\n")
    with pytest.raises(MbnInputError, match=r"other settings \(sphere\.generations: 5 then"):
        _run(SECOND, out, document=read_toml(toml), reuse=source)
    assert not out.exists()
    CALLS.clear()
    lines: list[str] = []
    _run(SECOND, out, reuse=source, log=lines.append)  # the corrected command
    assert CALLS == {"tail": 1} and f"stages sphere, norm: taken from {source.root}" in lines
    # --force over a run: the refusal leaves that run as it was
    before = _files(out)
    with pytest.raises(MbnInputError, match=r"a run of seed 4, not 5$"):
        _run(SECOND, out, seed=5, force=True, reuse=source)
    assert _files(out) == before


def test_a_source_that_is_no_run_is_refused_in_one_line(tmp_path):
    with pytest.raises(MbnInputError, match=r"--reuse .*nowhere: no such folder$"):
        _source(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(MbnInputError, match=r"--reuse .*empty: no run there \(no run\.json\)$"):
        _source(tmp_path / "empty")
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    manifest = tmp_path / "first" / "run.json"
    data = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**data, "kind": "mbn.unknown"}))
    with pytest.raises(MbnInputError, match=r"kind 'mbn\.unknown' is not an experiment mbn runs"):
        _source(tmp_path / "first")
    manifest.write_text(json.dumps(data))
    with pytest.raises(MbnInputError, match=r"the run's own folder \(use --resume\)$"):
        _run(FIRST, tmp_path / "first", resume=True, reuse=_source(tmp_path / "first"))


OTHER_CODE = {
    "version": "0.1.0",
    "package_sha256": "0" * 64,
    "source": "git",
    "commit": "1234567890abcdef1234567890abcdef12345678",
    "dirty": False,
}


def test_a_source_made_by_other_code_is_refused_unless_allowed_and_then_recorded(tmp_path):
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    manifest = tmp_path / "first" / "run.json"
    data = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**data, "code": OTHER_CODE}))
    CALLS.clear()
    with pytest.raises(
        MbnInputError,
        match=r"first/run\.json: made by mbn 0\.1\.0 at commit 1234567890; this is mbn .*; "
        r"nothing is taken from it \(pass --allow-other-code",
    ):
        _run(SECOND, tmp_path / "refused", reuse=_source(tmp_path / "first"))
    assert CALLS == {}
    # a run made before mbn recorded its code is other code too
    manifest.write_text(json.dumps({k: v for k, v in data.items() if k != "code"}))
    with pytest.raises(MbnInputError, match=r"it does not record the code that made it"):
        _run(SECOND, tmp_path / "old", reuse=_source(tmp_path / "first"))
    manifest.write_text(json.dumps({**data, "code": OTHER_CODE}))
    _run(
        SECOND,
        tmp_path / "taken",
        reuse=_source(tmp_path / "first"),
        allow_other_code=True,
        log=lambda _: None,
    )
    assert CALLS == {"tail": 1}
    reused = json.loads((tmp_path / "taken" / "run.json").read_text())["reused"]
    assert reused[0]["code"] == OTHER_CODE and reused[0]["other_code"] is True


def test_a_section_only_one_run_has_must_hold_its_defaults(tmp_path):
    _run(FIRST, tmp_path / "first", log=lambda _: None)
    # at its defaults, the section changes nothing: the stages are taken
    _run(WITH_OPTIONAL, tmp_path / "same", reuse=_source(tmp_path / "first"), log=lambda _: None)
    assert CALLS == {"sphere": 1, "norm": 1}
    toml = tmp_path / "on.toml"
    toml.write_text("[optional]\nlevel = 1.0\n")
    with pytest.raises(
        MbnInputError,
        match=r"other settings \(optional\.level: 0\.0 then, 1\.0 now; the run there has no "
        r"\[optional\] section: it ran as with its defaults\)",
    ):
        _run(
            WITH_OPTIONAL,
            tmp_path / "on",
            document=read_toml(toml),
            reuse=_source(tmp_path / "first"),
        )
    _run(WITH_OPTIONAL, tmp_path / "with-on", document=read_toml(toml), log=lambda _: None)
    with pytest.raises(
        MbnInputError,
        match=r"other settings \(optional\.level: 1\.0 then, 0\.0 now; this run has no "
        r"\[optional\] section: it runs as with its defaults\)",
    ):
        _run(FIRST, tmp_path / "plain", reuse=_source(tmp_path / "with-on"))


def test_a_checkpoint_belongs_to_the_longest_stage_name_it_starts_with():
    from mbn.experiments.pipeline.reuse import checkpoint_owner as _owner

    names = ["rf", "lf_search", "lf"]
    assert _owner("lf_search_03.npz", names) == "lf_search"
    assert _owner("lf.npz", names) == _owner("lf_attempt0_1.npz", names) == "lf"
    assert _owner("rf_restart1.npz", names) == "rf"
    assert _owner("rfx.npz", names) is None
