"""Provenance: the code that made a run (version, commit, dirty tree, the package's content
hash) and the software beside it are recorded in what a run writes; resuming a run made by other
code is refused in one line unless allowed, and then recorded."""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from mbn import __version__, provenance
from mbn.config import Settings, setting
from mbn.errors import MbnInputError
from mbn.experiments.pipeline import Experiment, Registry, Stage, StageContext, run_experiment

TOP = Path(__file__).resolve().parent.parent


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(TOP), *args], capture_output=True, text=True, check=True
    ).stdout


def test_the_version_is_written_once_and_is_the_changelogs_newest_release():
    import re
    import tomllib

    pyproject = tomllib.loads((TOP / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"] and "version" in pyproject["project"]["dynamic"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", __version__)
    changelog = (TOP / "CHANGELOG.md").read_text()
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\] - (\d{4}-\d{2}-\d{2})$", changelog, re.M)
    assert released, "CHANGELOG.md has no released section"
    assert released[0][0] == __version__
    assert changelog.index("## [Unreleased]") < changelog.index(f"## [{__version__}]")


@pytest.mark.skipif(shutil.which("git") is None or not (TOP / ".git").exists(), reason="no git")
def test_from_a_checkout_the_commit_and_the_dirty_flag_are_gits():
    code = provenance.code_identity()
    assert code["source"] == "git"
    assert code["commit"] == _git("rev-parse", "HEAD").strip()
    assert code["dirty"] is bool(_git("status", "--porcelain").strip())
    assert code["version"] == __version__


def test_the_package_hash_follows_its_files_not_its_bytecode(tmp_path):
    copy = tmp_path / "mbn"
    shutil.copytree(provenance.PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert provenance.package_sha256(copy) == provenance.package_sha256()
    (copy / "__pycache__").mkdir(exist_ok=True)
    (copy / "__pycache__" / "x.cpython-311.pyc").write_bytes(b"bytecode")
    provenance.package_sha256.cache_clear()
    assert provenance.package_sha256(copy) == provenance.package_sha256()
    with (copy / "io.py").open("a") as f:
        f.write("\n# an edit\n")
    provenance.package_sha256.cache_clear()
    assert provenance.package_sha256(copy) != provenance.package_sha256()


def test_the_code_differs_only_where_the_package_hash_does():
    now = provenance.code_identity()
    assert provenance.code_difference(now) is None
    assert provenance.code_difference({**now, "commit": "0" * 40}) is None  # docs-only commit
    other = {**now, "package_sha256": "f" * 64, "commit": "abcdef0123" + "0" * 30}
    assert provenance.code_difference(other) == (
        f"made by mbn {now['version']} at commit abcdef0123"
        + (" with uncommitted changes" if now["dirty"] else "")
        + f"; this is {provenance.describe_code(now)}"
    )
    assert "does not record the code" in str(provenance.code_difference(None))
    # one commit with other uncommitted changes: the hashes tell them apart
    a = {"version": "1.0.0", "package_sha256": "a" * 64, "commit": "c" * 40, "dirty": True}
    b = {**a, "package_sha256": "b" * 64}
    assert provenance.code_difference(a, b) == (
        "made by mbn 1.0.0 at commit cccccccccc with uncommitted changes, package aaaaaaaaaa; "
        "this is mbn 1.0.0 at commit cccccccccc with uncommitted changes, package bbbbbbbbbb"
    )


@dataclass(frozen=True)
class CountSettings(Settings):
    """A toy stage's settings."""

    section = "count"
    n: int = setting(3, doc="how many", low=1)


class CountStage(Stage):
    """A stage that records its setting."""

    name = "count"
    key_id = 1
    settings = CountSettings

    def run(self, ctx: StageContext) -> dict[str, Any]:
        return {"n": ctx.settings.n}


TOY = Experiment("toy", "mbn.toy", Registry([CountStage()]))
OTHER = {"version": "0.1.0", "package_sha256": "0" * 64, "source": "package"}


def _run(out: Path, **kw: Any) -> dict[str, Any]:
    return run_experiment(TOY, out, seed=1, config=TOY.config(), log=lambda _: None, **kw)


def test_run_json_and_results_json_record_the_code_and_the_versions(tmp_path):
    results = _run(tmp_path / "run")
    manifest = json.loads((tmp_path / "run" / "run.json").read_text())
    recorded = json.loads((tmp_path / "run" / "results.json").read_text())
    for data in (manifest, recorded, results):
        assert data["code"] == provenance.code_identity()
        assert data["versions"] == provenance.environment()
        assert set(data["versions"]) >= {"mbn", "python", "jax", "numpy", "os", "platform"}
    assert manifest["mbn_version"] == __version__


def test_resuming_a_run_made_by_other_code_is_refused_unless_allowed_and_then_recorded(tmp_path):
    out = tmp_path / "run"
    _run(out, stages=["count"])
    manifest = out / "run.json"
    data = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**data, "code": OTHER}))
    with pytest.raises(
        MbnInputError,
        match=r"run\.json: made by mbn 0\.1\.0 \(package 0000000000\); this is mbn .*; pass "
        r"--allow-other-code to resume it with this code \(run\.json records that you did\)$",
    ):
        _run(out, resume=True)
    assert json.loads(manifest.read_text())["code"] == OTHER  # the refusal wrote nothing
    _run(out, resume=True, allow_other_code=True)
    after = json.loads(manifest.read_text())
    assert after["code"] == OTHER  # the code that started it stays its code
    assert after["other_code"] == [
        {"action": "resume", "recorded": OTHER, "code": provenance.code_identity()}
    ]
    # a run recorded before mbn recorded its code is refused the same way
    manifest.write_text(json.dumps({k: v for k, v in data.items() if k != "code"}))
    with pytest.raises(MbnInputError, match=r"it does not record the code that made it"):
        _run(out, resume=True)


def test_the_cli_gives_its_version_and_allows_other_code_where_runs_resume(capsys):
    from mbn.cli.main import build_parser, main

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"mbn {__version__}"
    parser = build_parser()
    for command in (["reproduce"], ["run", "ablations"], ["sweep", "--seeds", "0", "--out", "x"]):
        args = parser.parse_args([*command, "--allow-other-code"])
        assert args.allow_other_code is True


def test_the_licence_is_mits_and_the_citation_names_this_version_and_the_paper():
    import yaml  # PyYAML comes with the test extras (Ray needs it)

    licence = (TOP / "LICENSE").read_text()
    assert licence.startswith("MIT License") and "WITHOUT WARRANTY OF ANY KIND" in licence
    citation = yaml.safe_load((TOP / "CITATION.cff").read_text())
    assert citation["cff-version"] == "1.2.0" and citation["type"] == "software"
    assert citation["version"] == __version__ and citation["license"] == "MIT"
    (paper,) = citation["references"]
    assert paper["doi"] == "10.1007/978-3-642-20282-7_26"
    assert [a["family-names"] for a in paper["authors"]] == ["Montone", "Donnarumma", "Prevete"]
    assert (paper["year"], paper["start"], paper["end"]) == (2011, 250, 259)
