"""Stages a run takes from another run of the same seed (``--reuse DIR``).

Every experiment starts with the reproduction's first stages: the multiplier, RF, the LF search
and LF (the noise and ablation experiments the IM and the PM too; new behaviours and programs
against dynamics the fully programmable IM). A stage's result depends only on the run's seed,
the stage's key number and the settings it reads, so where another run of the same seed ran the
same stage under the same settings, its files are the files this run would write: copying them
saves that stage's time (RF, the LF search and LF take 6-28 min a seed on two cores).

A stage is taken from the source run when:

- the source's experiment has the same stage (the same class and key number), and the source
  finished it (its ``stages/NAME.json`` and every output file it declares are there);
- every stage it needs is taken too, or was already done here;
- it has not run here.

The two runs must have the same seed and agree on every section of the config both have; a
shared section only one of them has must hold its defaults (a stage reads an optional section,
such as ``[noise]``, as its defaults where the experiment has none). Otherwise nothing is taken
and the run is refused in one line naming the first difference. The files taken are the stage's
file, its declared outputs and its checkpoints (``checkpoints/NAME.npz`` and ``NAME_*`` where no
longer stage name claims the file; for the DE curves of reports), each copied atomically, the
stage's file last: a copy interrupted leaves the stage not done. ``run.json`` records what was
taken and from where (``reused``), with the code that made the source. The source must have
been made by the same code (:mod:`mbn.provenance`: its ``run.json`` records the package's content
hash, version and commit); a run made by other code is refused in one line unless
``--allow-other-code`` is given, and ``reused`` then says so (``other_code``).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mbn.errors import MbnInputError
from mbn.experiments.pipeline.runconfig import first_difference
from mbn.experiments.pipeline.rundir import RunDir
from mbn.io import atomic_open, write_json_atomic
from mbn.provenance import code_difference

if TYPE_CHECKING:
    from mbn.experiments.pipeline.experiment import Experiment
    from mbn.experiments.pipeline.runconfig import RunConfig

__all__ = [
    "ReuseSource",
    "check_agreement",
    "checkpoint_owner",
    "read_source",
    "settings_disagreement",
    "shared_defaults",
    "stage_checkpoints",
    "take_stages",
    "takeable",
]


@dataclass(frozen=True)
class ReuseSource:
    """A finished or part-finished run to take stages from: its folder, its experiment, its
    seed, its config (as its experiment reads it) and the code that made it (as recorded;
    :mod:`mbn.provenance`)."""

    root: Path
    experiment: Experiment
    seed: int
    config: dict[str, Any]
    code: Any = None


def read_source(path: Path, find: Callable[[str], Experiment | None]) -> ReuseSource:
    """The run in ``path`` (``run.json``), its experiment found by kind with ``find``; one line
    when there is no run or its kind is unknown (the code that made it is compared when stages
    are taken: :func:`take_stages`)."""
    rundir = RunDir(Path(path))
    if not rundir.root.is_dir():
        raise MbnInputError(f"--reuse {path}: no such folder")
    if not rundir.manifest.exists():
        raise MbnInputError(f"--reuse {path}: no run there (no run.json)")
    data = rundir.read_manifest()
    kind = data.get("kind")
    experiment = find(kind) if isinstance(kind, str) else None
    if experiment is None:
        raise MbnInputError(f"{rundir.manifest}: kind {kind!r} is not an experiment mbn runs")
    seed = data.get("seed")
    if not isinstance(seed, int) or isinstance(seed, bool):
        raise MbnInputError(f"{rundir.manifest}: seed: expected an integer, got {seed!r}")
    config = experiment.config_from_dict(data.get("config"), str(rundir.manifest)).to_dict()
    return ReuseSource(rundir.root, experiment, seed, config, data.get("code"))


def shared_defaults(experiment: Experiment, quick: bool) -> dict[str, Any]:
    """The default values of ``experiment``'s sections that are not a stage's own (``[run]``
    and its shared sections), with the quick preset where ``quick``."""
    own = {stage.settings.section for stage in experiment.registry if stage.settings is not None}
    return {k: v for k, v in experiment.config(quick=quick).to_dict().items() if k not in own}


def settings_disagreement(
    ours: dict[str, Any],
    our_defaults: dict[str, Any],
    theirs: dict[str, Any],
    their_defaults: dict[str, Any],
) -> str | None:
    """Where two runs' configs (``section -> values``) disagree for the stages they share, as
    one line (``rf.generations: 300 then, 500 now``), or None. A section both have must be the
    same; a shared section (not a stage's own) only one has must hold that experiment's
    defaults (``*_defaults``: :func:`shared_defaults`), since a stage of the other runs as with
    its defaults (``[noise]``: a stage without one runs without noise)."""
    for name, values in ours.items():
        if name in theirs:
            if theirs[name] != values:
                return first_difference({name: theirs[name]}, {name: values})
        elif name in our_defaults and values != our_defaults[name]:
            diff = first_difference({name: our_defaults[name]}, {name: values})
            return f"{diff}; the run there has no [{name}] section: it ran as with its defaults"
    for name, values in theirs.items():
        if name not in ours and name in their_defaults and values != their_defaults[name]:
            diff = first_difference({name: values}, {name: their_defaults[name]})
            return f"{diff}; this run has no [{name}] section: it runs as with its defaults"
    return None


def check_agreement(
    experiment: Experiment,
    source: ReuseSource,
    seed: int,
    config: RunConfig,
    *,
    allow_other_code: bool = False,
) -> str | None:
    """Refuse (one line) a source of another seed, other settings or, unless
    ``allow_other_code``, other code; returns how its code differs (None: the same code)."""
    where = RunDir(source.root).manifest
    if source.seed != seed:
        raise MbnInputError(f"--reuse {source.root}: a run of seed {source.seed}, not {seed}")
    diff = settings_disagreement(
        config.to_dict(),
        shared_defaults(experiment, config.quick),
        source.config,
        shared_defaults(source.experiment, config.quick),
    )
    if diff is not None:
        raise MbnInputError(
            f"{where}: the run there was made with other settings ({diff}); nothing is taken "
            "from it"
        )
    other = code_difference(source.code)
    if other is not None and not allow_other_code:
        raise MbnInputError(
            f"{where}: {other}; nothing is taken from it (pass --allow-other-code to take its "
            "stages all the same; run.json records that you did)"
        )
    return other


def takeable(experiment: Experiment, rundir: RunDir, source: ReuseSource) -> list[str]:
    """The stages of ``experiment`` that :func:`take_stages` would copy into ``rundir``, in
    order (the seed and settings aside, which it checks first)."""
    src = RunDir(source.root)
    theirs = {stage.name: stage for stage in source.experiment.registry}
    taken: list[str] = []
    for stage in experiment.registry:
        if rundir.stage_done(stage.name):
            continue
        other = theirs.get(stage.name)
        if other is None or type(other) is not type(stage) or other.key_id != stage.key_id:
            continue
        if not src.stage_done(stage.name):
            continue
        if any(not (src.root / f).is_file() for f in stage.outputs):
            continue
        if any(n not in taken and not rundir.stage_done(n) for n in stage.needs):
            continue
        taken.append(stage.name)
    return taken


def _copy_atomic(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    with src.open("rb") as source, atomic_open(dst, "wb") as target:
        shutil.copyfileobj(source, target)


def checkpoint_owner(filename: str, names: list[str]) -> str | None:
    """The stage a checkpoint file belongs to: the longest stage name that is its stem or a
    prefix of it followed by ``_`` (``lf_search_03.npz``: ``lf_search``, not ``lf``)."""
    stem = filename.split(".", 1)[0]
    mine = [n for n in names if stem == n or stem.startswith(f"{n}_")]
    return max(mine, key=len) if mine else None


def stage_checkpoints(src: RunDir, name: str, names: list[str]) -> list[Path]:
    """The checkpoint files of stage ``name`` in ``src`` (``names``: the stages there)."""
    folder = src.root / "checkpoints"
    if not folder.is_dir():
        return []
    return sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and not p.name.startswith(".") and checkpoint_owner(p.name, names) == name
    )


def take_stages(
    experiment: Experiment,
    rundir: RunDir,
    seed: int,
    config: RunConfig,
    source: ReuseSource,
    *,
    allow_other_code: bool = False,
) -> list[str]:
    """Copy into ``rundir`` (whose ``run.json`` exists) the stages it can take from ``source``
    (module docstring); returns their names and records them in ``run.json``, with the code
    that made them (and ``other_code: true`` where it was not this code, ``allow_other_code``)."""
    other = check_agreement(experiment, source, seed, config, allow_other_code=allow_other_code)
    names = takeable(experiment, rundir, source)
    src = RunDir(source.root)
    stages = list(source.experiment.registry.names)
    for name in names:
        stage = experiment.registry[name]
        for rel in stage.outputs:
            _copy_atomic(src.root / rel, rundir.root / rel)
        for path in stage_checkpoints(src, name, stages):  # a partial one of this run's is replaced
            _copy_atomic(path, rundir.root / "checkpoints" / path.name)
        _copy_atomic(src.stage_file(name), rundir.stage_file(name))
    if names:
        manifest = rundir.read_manifest()
        before = manifest.get("reused")
        entries = list(before) if isinstance(before, list) else []
        entries.append(
            {
                "from": str(source.root),
                "stages": names,
                "code": source.code,
                "other_code": other is not None,
            }
        )
        write_json_atomic(rundir.manifest, {**manifest, "reused": entries})
    return names
