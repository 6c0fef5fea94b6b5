"""A sweep: one reproduction per seed, each ``DIR/seed-K`` a plain run folder written by the
pipeline's :func:`~mbn.experiments.pipeline.runner.run_experiment`, each run a Ray task.

``DIR/sweep.json`` records the sweep's settings (the seeds, ``quick`` and the whole effective
config) and what became of each seed (done, failed with its one-line error, how long it took and
the thread settings its worker saw); a folder holding a sweep with other settings is refused.

Resume: a seed whose ``results.json`` is complete (and whose report was written) is skipped; a
seed folder with a ``run.json`` is resumed from its checkpoints (``--resume`` of ``mbn
reproduce``); any other seed starts afresh. Every seed writes its own folder only, and
``sweep.json`` is rewritten atomically after each seed that ends, so a killed sweep loses no
finished seed.

Threads: each task asks Ray for ``cpus_per_run`` CPUs and runs in a worker whose environment
(set by Ray before the worker process starts, so before JAX is imported there) limits the BLAS
libraries to that many threads, and XLA to one where that is one (:func:`thread_env`).
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future
from concurrent.futures import wait as wait_for
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from mbn._version import __version__
from mbn.errors import MbnInputError
from mbn.experiments.sweep.reaper import GRACE_S, start_reaper
from mbn.experiments.sweep.records import Growth
from mbn.experiments.sweep.seeds import format_seeds
from mbn.io import atomic_open, check_writable, json_text, read_json
from mbn.provenance import code_difference, code_identity, environment

if TYPE_CHECKING:
    from mbn.experiments.pipeline.experiment import Experiment
    from mbn.experiments.pipeline.runconfig import RunConfig

__all__ = [
    "INSTALL_HINT",
    "RESULTS_GZ",
    "SWEEP_FILE",
    "SWEEP_KIND",
    "BatchedExecutor",
    "InlineExecutor",
    "RayExecutor",
    "SweepSettings",
    "check_sweep_dir",
    "divert_ray_notices",
    "finished_results",
    "ray_notice",
    "read_sweep",
    "run_seed",
    "run_sweep",
    "seed_dir",
    "seed_state",
    "settle",
    "thread_env",
    "write_sweep",
]

SWEEP_KIND = "mbn.sweep"
SWEEP_FILE = "sweep.json"
#: How to get Ray (printed when it is missing).
INSTALL_HINT = "mbn sweep needs Ray, which is not installed: pip install 'mbn[sweep]'"
#: Seconds to wait for a Ray cluster's address to answer before giving up.
CONNECT_TIMEOUT_S = 5.0
#: The variable that tells a task's run how many parts to evaluate its populations in.
WORKERS_VARIABLE = "MBN_FITNESS_WORKERS"
#: The environment variables that pin a task's threads (:func:`thread_env`).
THREAD_VARIABLES = (
    "XLA_FLAGS",
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    WORKERS_VARIABLE,
)


def seed_dir(out: Path, seed: int) -> Path:
    """The run folder of ``seed`` in the sweep folder ``out``."""
    return Path(out) / f"seed-{seed}"


@dataclass(frozen=True)
class SweepSettings:
    """What a sweep's results depend on: its seeds and the effective config of every run."""

    seeds: tuple[int, ...]
    config: RunConfig
    #: the experiment every seed runs (:mod:`~mbn.experiments.sweep.specs`); recorded in
    #: ``sweep.json`` unless it is the reproduction, so older sweeps read as before
    experiment: str = "reproduce"

    def to_dict(self) -> dict[str, Any]:
        named = {} if self.experiment == "reproduce" else {"experiment": self.experiment}
        return {
            **named,
            "seeds": list(self.seeds),
            "quick": self.config.quick,
            "config": self.config.to_dict(),
        }


def thread_env(cpus: int, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment of a task given ``cpus`` CPUs: for one CPU, XLA's Eigen threading off
    (``--xla_cpu_multi_thread_eigen=false``); OpenMP/OpenBLAS/MKL at that many threads; and the
    run's DE populations evaluated in that many parts at once (``WORKERS_VARIABLE``, as
    ``mbn reproduce --threads``). ``base``'s ``XLA_FLAGS`` (the caller's own flags) are kept in
    front; with none of its own and more than one CPU, ``XLA_FLAGS`` is not set.

    XLA has no flag that holds its CPU thread pool to N > 1 threads (it sizes the pool from the
    cores the process may run on); a value of ``XLA_FLAGS`` that does not start with ``--`` is
    read as a file name and kills the process, which is what the ``intra_op_parallelism_threads=N``
    this function once wrote did for N > 1."""
    flags = "--xla_cpu_multi_thread_eigen=false" if cpus == 1 else ""
    own = (base or {}).get("XLA_FLAGS", "").strip()
    xla = f"{own} {flags}".strip()
    return {
        **({"XLA_FLAGS": xla} if xla else {}),
        "OMP_NUM_THREADS": str(cpus),
        "OPENBLAS_NUM_THREADS": str(cpus),
        "MKL_NUM_THREADS": str(cpus),
        WORKERS_VARIABLE: str(cpus),
    }


def task_env(cpus: int, base: Mapping[str, str]) -> dict[str, str]:
    """A Ray task's environment: :func:`thread_env`, and the caller's choice of compilation
    cache (``MBN_COMPILE_CACHE``, :mod:`mbn.compile_cache`) where it made one."""
    from mbn.compile_cache import VARIABLE

    env = thread_env(cpus, base)
    if base.get(VARIABLE):
        env[VARIABLE] = base[VARIABLE]
    return env


# -- the sweep folder ----------------------------------------------------------------------------


def read_sweep(out: Path) -> dict[str, Any]:
    """``DIR/sweep.json`` (one line naming the file when it is missing or not a sweep)."""
    path = Path(out) / SWEEP_FILE
    if not path.exists():
        raise MbnInputError(f"--out {out}: no sweep there ({SWEEP_FILE} is missing)")
    data = read_json(path)
    if not isinstance(data, dict) or data.get("kind") != SWEEP_KIND:
        raise MbnInputError(f"{path}: not a sweep file (kind {SWEEP_KIND!r} expected)")
    if not isinstance(data.get("settings"), dict):
        raise MbnInputError(f"{path}: settings: missing")
    return data


def write_sweep(out: Path, data: dict[str, Any]) -> None:
    """``DIR/sweep.json``, atomically (values that are not finite become ``null``)."""
    with atomic_open(Path(out) / SWEEP_FILE) as handle:
        handle.write(json_text(data, indent=2) + "\n")


def _nearest_existing(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_sweep_dir(out: Path, settings: SweepSettings) -> dict[str, Any] | None:
    """Refuse, touching nothing, an ``--out`` the sweep cannot use: a file, a folder that cannot
    be written, a folder holding other files and no sweep, or one holding a sweep with other
    settings (naming the first that differs). A sweep may gain seeds (the same settings
    otherwise, every seed it had still asked for), never lose one: a seed left out of a sweep
    that ran it would be a seed picked by hand. Returns the ``sweep.json`` found, if any."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise MbnInputError(f"--out {out}: is a file, not a folder")
    if not out.exists():
        base = _nearest_existing(out)
        if not base.is_dir():
            raise MbnInputError(f"--out {out}: {base} is a file, not a folder")
        try:  # a real try, as check_writable does: permissions, read-only or odd file systems
            os.rmdir(tempfile.mkdtemp(prefix=".mbn-sweep.", dir=base))
        except OSError as exc:
            raise MbnInputError(
                f"--out {out}: cannot write in {base} ({exc.strerror or exc})"
            ) from None
        return None
    check_writable(out / SWEEP_FILE, "--out")
    if not (out / SWEEP_FILE).exists():
        if any(out.iterdir()):
            raise MbnInputError(
                f"--out {out}: the folder holds other files and no sweep ({SWEEP_FILE}); choose "
                "an empty or new folder"
            )
        return None
    old = read_sweep(out)
    mine = settings.to_dict()
    if old["settings"] != mine:
        from mbn.experiments.pipeline.runconfig import first_difference

        before = {k: v for k, v in old["settings"].items() if k != "seeds"}
        now = {k: v for k, v in mine.items() if k != "seeds"}
        had = old["settings"].get("seeds", [])
        dropped = sorted(set(had) - set(mine["seeds"]))
        if before == now:
            if not dropped:
                return old  # the same sweep, grown by seeds
            raise MbnInputError(
                f"{out / SWEEP_FILE}: the sweep there has seeds {format_seeds(dropped)}, which "
                "--seeds leaves out; a sweep may gain seeds, never lose one (use another --out)"
            )
        diff = first_difference(old["settings"], mine, root="settings")
        raise MbnInputError(
            f"{out / SWEEP_FILE}: the folder holds a sweep with other settings ({diff}); use "
            "another --out or the same --quick and --config (--seeds may add seeds)"
        )
    return old


def _grown(old: dict[str, Any], settings: SweepSettings) -> dict[str, Any]:
    """``grown``: each time a sweep gained seeds, the seeds it had before and when (kept as
    continued); empty for a sweep that never grew. The same seeds in another order are no
    growth."""
    grown = list(old.get("grown", []))
    had = old.get("settings", {}).get("seeds")
    if had is not None and set(settings.seeds) - set(had):
        at = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        grown.append(Growth(seeds_before=list(had), at=at).to_json())
    return {"grown": grown} if grown else {}


#: A seed's ``results.json`` as a kept installment holds it (``mbn sweep --keep``).
RESULTS_GZ = "results.json.gz"


def finished_results(
    out: Path, seed: int, config: RunConfig | dict[str, Any]
) -> dict[str, Any] | None:
    """The seed's ``results.json`` where it is complete for this seed and config (what a
    summary reads of a run), else None; a kept installment's seed holds it gzip-compressed
    (:data:`RESULTS_GZ`). ``config``: the run's config, or its recorded form (``sweep.json``'s,
    which a later version of ``mbn`` may read with settings it did not have)."""
    expected = config if isinstance(config, dict) else config.to_dict()
    folder = seed_dir(out, seed)
    data: Any = None
    try:
        if (folder / "results.json").exists():
            data = read_json(folder / "results.json")
        elif (folder / RESULTS_GZ).exists():
            data = read_json(folder / RESULTS_GZ)
    except MbnInputError:
        data = None
    if (
        isinstance(data, dict)
        and data.get("seed") == seed
        and data.get("config") == expected
        and "tests" in data
        and "claims" in data
    ):
        return data
    return None


def seed_state(out: Path, seed: int, config: RunConfig | dict[str, Any]) -> str:
    """``"done"`` (a complete ``results.json`` of this seed and config, :func:`finished_results`,
    and its report), ``"resume"`` (a ``run.json``: an interrupted run) or ``"new"``."""
    folder = seed_dir(out, seed)
    if (
        (folder / "results.json").exists()
        and (folder / "report.html").exists()
        and finished_results(out, seed, config) is not None
    ):
        return "done"
    return "resume" if (folder / "run.json").exists() else "new"


def settle(out: Path, seed: int, config: RunConfig, result: Mapping[str, Any]) -> dict[str, Any]:
    """A seed's record in ``sweep.json`` once its task ended: its state is one thing, done or
    failed, as its folder says (what a rerun of the sweep goes by, :func:`seed_state`). A task
    reported failed whose run is complete (its ``results.json`` and report written: its worker
    died after the run's last file) is done, the failure kept as a notice; ``error`` is set only
    for a failed seed."""
    state, error = str(result["state"]), result.get("error")
    notices = list(result.get("notices") or [])
    if state != "done" and seed_state(out, seed, config) == "done":
        notices.append(
            f"notice: the run was complete when its worker ended abnormally ({error}); kept"
        )
        state, error = "done", None
    elif state != "done":
        state = "failed"
    return {
        "state": state,
        "error": error if state == "failed" else None,
        "seconds": result.get("seconds"),
        **({"worker": result["worker"]} if "worker" in result else {}),
        **({"notices": notices} if notices else {}),
    }


def check_reuse_dir(
    reuse: Path,
    out: Path,
    settings: SweepSettings | None = None,
    experiment: Experiment | None = None,
) -> None:
    """Refuse a ``--reuse`` that is not another sweep's folder, or (with ``settings``) one whose
    runs were made with other settings than the stages they share need
    (:func:`~mbn.experiments.pipeline.reuse.settings_disagreement`; one line naming the first).
    ``experiment``: the sweep's own, where the caller has it. Each seed checks its own run again
    as it takes its stages (:func:`mbn.experiments.pipeline.reuse.take_stages`)."""
    if not reuse.is_dir():
        raise MbnInputError(f"--reuse {reuse}: no such folder")
    if not (reuse / SWEEP_FILE).exists():
        raise MbnInputError(f"--reuse {reuse}: not a sweep folder (no {SWEEP_FILE})")
    if out.exists() and reuse.resolve() == out.resolve():
        raise MbnInputError(f"--reuse {reuse}: the sweep's own folder")
    if settings is None:
        return
    from mbn.experiments.pipeline.reuse import settings_disagreement, shared_defaults
    from mbn.experiments.sweep.specs import sweep_spec

    recorded = read_sweep(reuse).get("settings", {})
    raw = recorded.get("config") if isinstance(recorded, dict) else None
    if not isinstance(raw, dict):
        return
    name = recorded.get("experiment", "reproduce")
    mine = experiment or sweep_spec(settings.experiment).load()
    other = mine if name == settings.experiment else sweep_spec(name).load()
    where = str(reuse / SWEEP_FILE)
    theirs = other.config_from_dict(raw, where).to_dict()
    quick = settings.config.quick
    diff = settings_disagreement(
        settings.config.to_dict(),
        shared_defaults(mine, quick),
        theirs,
        shared_defaults(other, quick),
    )
    if diff is not None:
        raise MbnInputError(
            f"{where}: its runs were made with other settings ({diff}); nothing can be taken "
            "from them"
        )


def _reuse_seed(reuse: Path | None, seed: int) -> str | None:
    """The run of ``seed`` in the sweep folder ``reuse``, where there is one."""
    if reuse is None:
        return None
    folder = seed_dir(reuse, seed)
    return str(folder) if (folder / "run.json").exists() else None


def one_line(exc: BaseException) -> str:
    """An exception as one line (its type unless it is an input error, its message's first
    line, at most 300 characters)."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if not isinstance(exc, MbnInputError):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def _check_sweep_code(out: Path, found: dict[str, Any] | None, allow: bool) -> list[dict[str, Any]]:
    """The ``other_code`` entries of a sweep continued in ``out`` (``found``: its
    ``sweep.json``, None for a new sweep): refused in one line when it was made by other code,
    unless ``allow``, which adds an entry."""
    if found is None:
        return []
    diff = code_difference(found.get("code"))
    if diff is None:
        before = found.get("other_code")
        return list(before) if isinstance(before, list) else []
    if not allow:
        raise MbnInputError(
            f"{out / SWEEP_FILE}: {diff}; pass --allow-other-code to continue it with this code "
            "(sweep.json records that you did)"
        )
    from mbn.experiments.pipeline.runner import with_other_code

    return with_other_code(found, "continue")


# -- one seed (the body of a task) -----------------------------------------------------------------


def run_seed(
    out: str,
    seed: int,
    config: RunConfig,
    resume: bool,
    experiment: Experiment | str | None = None,
    reuse: str | None = None,
    allow_other_code: bool = False,
) -> dict[str, Any]:
    """Run (or resume) the run of ``seed`` into ``out/seed-K``, as ``mbn reproduce --seed K
    --out out/seed-K [--resume]`` does (or ``mbn run NAME``: ``experiment``, by name or itself;
    default the reproduction), taking the stages it can from the run in ``reuse`` (``mbn run
    --reuse``), with ``--allow-other-code`` where ``allow_other_code``; never raises: a crash
    is returned as ``{"state": "failed", "error": one line}``."""
    t0 = time.perf_counter()
    worker = {
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "jax_imported_before": "jax" in sys.modules,
        "env": {k: os.environ.get(k) for k in THREAD_VARIABLES},
    }
    notices: list[str] = []
    try:
        from mbn import compile_cache, extensions
        from mbn.experiments.pipeline.runner import run_experiment
        from mbn.precision import ROBOT, scope

        worker["compile_cache"] = str(compile_cache.enable() or "off")
        extensions.load()  # a worker process imports the lab's extensions as the command did

        if experiment is None or isinstance(experiment, str):
            from mbn.experiments.sweep.specs import sweep_spec

            experiment = sweep_spec(experiment).load()
        source = None
        if reuse is not None:
            from mbn.experiments.pipeline.reuse import read_source
            from mbn.experiments.registry import of_kind

            mine = experiment
            source = read_source(Path(reuse), lambda kind: of_kind(kind, also=mine))
        with scope(ROBOT):  # as the command line runs `mbn reproduce`
            run_experiment(
                experiment,
                seed_dir(Path(out), seed),
                seed=seed,
                config=config,
                resume=resume,
                workers=max(1, int(os.environ.get(WORKERS_VARIABLE, "1"))),
                progress=False,
                log=lambda m: notices.append(m) if m.startswith(("notice", "stages")) else None,
                reuse=source,
                allow_other_code=allow_other_code,
            )
        state, error = "done", None
    except Exception as exc:  # a crash of one seed is reported, the others go on
        state, error = "failed", one_line(exc)
    return {
        "seed": seed,
        "state": state,
        "error": error,
        "seconds": round(time.perf_counter() - t0, 2),
        "worker": worker,
        "notices": notices,
    }


# -- executors -------------------------------------------------------------------------------------


class Executor(Protocol):
    def submit(self, seed: int, args: tuple[Any, ...]) -> Any: ...

    def wait(self, handles: Sequence[Any], timeout: float) -> list[Any]: ...

    def result(self, handle: Any) -> dict[str, Any]: ...

    def close(self) -> None: ...


class InlineExecutor:
    """Runs each seed in this process, one after the other (no Ray; tests and debugging)."""

    def __init__(self, task: Callable[..., dict[str, Any]] = run_seed) -> None:
        self.task = task
        self._results: dict[int, dict[str, Any]] = {}
        self._args: dict[int, tuple[Any, ...]] = {}

    def submit(self, seed: int, args: tuple[Any, ...]) -> int:
        self._args[seed] = args
        return seed

    def wait(self, handles: Sequence[Any], timeout: float) -> list[Any]:
        if not handles:
            return []
        h = handles[0]
        self._results[h] = self.task(*self._args.pop(h))
        return [h]

    def result(self, handle: Any) -> dict[str, Any]:
        return self._results.pop(handle)

    def close(self) -> None:
        pass


class BatchedExecutor:
    """Every seed in a thread of this process, side by side, their population evaluations
    merged into one call each (:mod:`mbn.experiments.batching`; ``mbn sweep --batched``): a
    seed's results are those of its run alone, bit for bit. ``workers``: threads evaluating
    parts of a merged batch (default every core); each seed counts its own robot-steps."""

    def __init__(
        self, task: Callable[..., dict[str, Any]] = run_seed, workers: int | None = None
    ) -> None:
        from mbn.experiments.batching import Batcher

        self.task = task
        self.batcher = Batcher(workers or os.cpu_count() or 1)

    def _run(self, future: Future[dict[str, Any]], membership: Any, args: tuple[Any, ...]) -> None:
        from mbn.world.rollout import own_tally

        own_tally()  # this seed's robot-steps, not the process's
        try:
            with membership:
                future.set_result(self.task(*args))
        except BaseException as exc:  # run_seed returns its errors; anything else is reported
            future.set_exception(exc)

    def submit(self, seed: int, args: tuple[Any, ...]) -> Any:
        future: Future[dict[str, Any]] = Future()
        future.set_running_or_notify_cancel()
        # a daemon: an interrupted sweep ends without waiting for its seeds (they resume)
        # enrolled now, before the next seed starts: the first do not go on without the others
        membership = self.batcher.enrol()
        threading.Thread(
            target=self._run,
            args=(future, membership, args),
            name=f"mbn-seed-{seed}",
            daemon=True,
        ).start()
        return future

    def wait(self, handles: Sequence[Any], timeout: float) -> list[Any]:
        done, _ = wait_for(list(handles), timeout=timeout, return_when=FIRST_COMPLETED)
        return [h for h in handles if h in done]

    def result(self, handle: Any) -> dict[str, Any]:
        return handle.result()

    def close(self) -> None:
        pass


def _probe(address: str, timeout: float) -> None:
    """Fail fast on an address nothing answers at (one line)."""
    if address == "auto":
        return
    hostport = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise MbnInputError(f"--address {address!r}: expected HOST:PORT (e.g. head-node:6379)")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise MbnInputError(
            f"--address {address}: no Ray cluster answers there ({reason} after at most "
            f"{timeout:g} s); start one with `ray start --head` on that machine"
        ) from None


def auth_hint(address: str | None, env: Mapping[str, str]) -> str:
    """What to try when joining a cluster fails and token authentication may be why.

    Since Ray 2.59, ``ray start --head`` turns token authentication on for a cluster on one
    machine, while a driver that joins it by an explicit address authenticates only with
    ``RAY_AUTH_MODE=token`` set: without it the connection is refused after some 20 s of
    retries (found joining a one-machine cluster started with ``ray start --head``).
    """
    if address is None or address == "auto" or env.get("RAY_AUTH_MODE"):
        return ""
    return (
        "; if the cluster uses token authentication (Ray >= 2.59 turns it on for `ray start "
        "--head`), set RAY_AUTH_MODE=token and give this machine the cluster's token "
        "(`ray get-auth-token`, or RAY_AUTH_TOKEN)"
    )


def ray_notice(data: Mapping[str, Any], ignore_prefix: bool = False) -> None:
    """Print one of Ray's driver-side notices (its raylet's: a worker that died, ...) as one
    warning line per message on stderr: the first sentence, the rest being in Ray's session logs
    (``/tmp/ray/session_*/logs``). Ray itself prints them on the driver's stdout, which is the
    sweep's progress and summary."""
    for line in data.get("lines", ()):
        text = " ".join(str(line).split())
        first = text.split(". ", 1)[0].rstrip(".")
        if first:
            who = data.get("pid") or "ray"
            print(f"mbn: warning: Ray ({who}): {first[:300]}", file=sys.stderr, flush=True)


def divert_ray_notices() -> Callable[[], None]:
    """Send Ray's driver-side notices to :func:`ray_notice` instead of stdout; returns what
    undoes it. Ray offers no option for this (``log_to_driver=False`` covers the workers' output
    only): its thread that listens for the raylet's errors prints them through
    ``ray._private.worker.print_to_stdstream``, which is replaced while the sweep runs. Where a
    version of Ray has no such function, nothing is changed."""
    try:
        import ray._private.worker as ray_worker
    except ImportError:
        return lambda: None
    original = getattr(ray_worker, "print_to_stdstream", None)
    if original is None:
        return lambda: None
    ray_worker.print_to_stdstream = ray_notice

    def undo() -> None:
        ray_worker.print_to_stdstream = original

    return undo


def import_ray() -> Any:
    """The ``ray`` module, or one line saying how to install it."""
    try:
        import ray
    except ImportError:
        raise MbnInputError(INSTALL_HINT) from None
    return ray


class RayExecutor:
    """One Ray task per seed, each asking for ``cpus_per_run`` CPUs, its threads pinned.

    Without ``address``, a local Ray is started on this machine with as many CPUs as it has
    cores, and ends with the sweep however the sweep ends (:mod:`~mbn.experiments.sweep.reaper`);
    with one, the sweep joins that cluster (whose workers must see ``--out`` at the same path: a
    shared file system). Ray's notices on the driver (a worker that died) go to stderr as one
    warning line each (:func:`divert_ray_notices`), not to stdout.
    """

    def __init__(
        self,
        address: str | None,
        cpus_per_run: int,
        task: Callable[..., dict[str, Any]] = run_seed,
        connect_timeout: float = CONNECT_TIMEOUT_S,
    ) -> None:
        ray = import_ray()
        self.ray = ray
        if address is not None:
            _probe(address, connect_timeout)
        kw: dict[str, Any] = {
            "log_to_driver": False,
            "logging_level": "ERROR",
            "ignore_reinit_error": True,
        }
        try:
            if address is None:
                ray.init(num_cpus=os.cpu_count() or 1, include_dashboard=False, **kw)
            else:
                ray.init(address=address, **kw)
        except Exception as exc:  # Ray's own errors: still one line
            raise MbnInputError(
                f"--address {address or '(local)'}: cannot start or join Ray ({one_line(exc)})"
                + auth_hint(address, os.environ)
            ) from None
        # Ray's processes started here end with this process, even when it is killed
        self._reaper = start_reaper() if address is None else None
        self._undo_notices = divert_ray_notices()
        total = int(ray.cluster_resources().get("CPU", 0))
        if cpus_per_run > total:
            self.close()
            raise MbnInputError(
                f"--cpus-per-run {cpus_per_run}: the Ray cluster has only {total} CPUs"
            )
        self.cpus = total
        # a fresh worker process for each seed (max_calls, which .options() does not take): a
        # worker reused for the next seed kept every program the last one compiled, and a noise
        # run's hundreds of them took it past the kernel's limit on memory maps (LLVM: "Cannot
        # allocate memory", SIGABRT)
        self._remote = ray.remote(max_calls=1)(task).options(
            num_cpus=cpus_per_run,
            max_retries=0,
            runtime_env={"env_vars": task_env(cpus_per_run, os.environ)},
        )
        self._seed: dict[Any, int] = {}

    def submit(self, seed: int, args: tuple[Any, ...]) -> Any:
        ref = self._remote.remote(*args)
        self._seed[ref] = seed
        return ref

    def wait(self, handles: Sequence[Any], timeout: float) -> list[Any]:
        if not handles:
            return []
        done, _ = self.ray.wait(list(handles), num_returns=len(handles), timeout=timeout)
        return list(done)

    def result(self, handle: Any) -> dict[str, Any]:
        seed = self._seed.pop(handle)
        try:
            return dict(self.ray.get(handle))
        except Exception as exc:  # the worker died (killed, out of memory): a failed seed
            cause = getattr(exc, "cause", None) or exc
            return {"seed": seed, "state": "failed", "error": one_line(cause), "seconds": None}

    def close(self) -> None:
        self.ray.shutdown()
        self._undo_notices()
        if self._reaper is not None:  # what ray.shutdown() left ends now
            assert self._reaper.stdin is not None
            self._reaper.stdin.close()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._reaper.wait(timeout=2 * GRACE_S + 5)
            self._reaper = None


# -- the sweep -------------------------------------------------------------------------------------


class Monitor(Protocol):
    def __enter__(self) -> Monitor: ...

    def __exit__(self, *exc: Any) -> None: ...

    def mark(self, seed: int, state: str, error: str | None = None) -> None: ...

    def poll(self) -> None: ...


class _Silent:
    def __enter__(self) -> _Silent:
        return self

    def __exit__(self, *exc: Any) -> None:
        pass

    def mark(self, seed: int, state: str, error: str | None = None) -> None:
        pass

    def poll(self) -> None:
        pass


def run_sweep(
    out: Path,
    settings: SweepSettings,
    executor: Callable[[], Executor],
    *,
    monitor: Monitor | None = None,
    experiment: Experiment | None = None,
    poll_s: float = 1.0,
    finish: Callable[[Path], Any] | None = None,
    reuse: Path | None = None,
    allow_other_code: bool = False,
    executor_name: str = "ray",
) -> dict[str, Any]:
    """Run every seed of ``settings`` not yet done into ``out``; returns ``sweep.json``.

    ``sweep.json`` records the code and the versions it runs with (:mod:`mbn.provenance`); a
    sweep made by other code is continued only with ``allow_other_code`` (then recorded in
    ``other_code``, and each seed's run resumes or takes stages with it).

    ``reuse``: another sweep folder; the run of seed K takes the stages it can from
    ``reuse/seed-K`` where that holds a run (:mod:`~mbn.experiments.pipeline.reuse`).

    ``executor`` makes the executor (called only when some seed is left to run, after the folder
    was checked: Ray is neither needed nor started for a finished sweep), ``executor_name``
    says which in ``sweep.json`` (``ray``, ``batched``: the last that ran seeds); ``finish``
    (the summary and report) runs at the end on the folder.
    """
    out = Path(out)
    t0 = time.perf_counter()
    found = check_sweep_dir(out, settings)
    other_code = _check_sweep_code(out, found, allow_other_code)
    settings.config.check()  # what the settings name, before any seed runs (each checks again)
    if reuse is not None:
        check_reuse_dir(Path(reuse), out, settings, experiment)
    states = {s: seed_state(out, s, settings.config) for s in settings.seeds}
    todo = [s for s in settings.seeds if states[s] != "done"]
    ex = executor() if todo else None
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if ex is not None:
            ex.close()
        raise MbnInputError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    old = read_sweep(out) if (out / SWEEP_FILE).exists() else {}
    runs: dict[str, Any] = {}
    for s in settings.seeds:
        before = old.get("runs", {}).get(str(s), {})
        if states[s] == "done":
            runs[str(s)] = {**before, "state": "done", "error": None}
            runs[str(s)].setdefault("seconds", None)
        else:
            runs[str(s)] = {
                "state": "waiting",
                "error": None,
                "seconds": None,
                "resumed": states[s] == "resume",
            }
    data: dict[str, Any] = {
        "kind": SWEEP_KIND,
        "mbn_version": __version__,
        "code": old.get("code", code_identity()) if old else code_identity(),
        "versions": dict(environment()),
        **({"other_code": other_code} if other_code else {}),
        **_grown(old, settings),
        "settings": settings.to_dict(),
        "executor": executor_name if todo else old.get("executor", executor_name),
        "runs": runs,
        "skipped": [s for s in settings.seeds if states[s] == "done"],
    }
    write_sweep(out, data)
    mon = monitor or _Silent()
    try:
        with mon:
            for s in settings.seeds:
                mon.mark(s, "done" if states[s] == "done" else "waiting")
            handles = []
            if ex is not None:
                # the experiment itself where the caller gave one, else its name (a task
                # loads it), none for the reproduction
                chosen: Experiment | str | None = experiment or (
                    None if settings.experiment == "reproduce" else settings.experiment
                )
                for s in todo:
                    args: tuple[Any, ...] = (str(out), s, settings.config, states[s] == "resume")
                    source = _reuse_seed(reuse, s)
                    if allow_other_code:
                        args = (*args, chosen, source, True)
                    elif source is not None:
                        args = (*args, chosen, source)
                    elif chosen:
                        args = (*args, chosen)
                    handles.append(ex.submit(s, args))
                    mon.mark(s, "queued")
            while handles:
                done = ex.wait(handles, poll_s) if ex is not None else []
                for h in done:
                    handles.remove(h)
                    r = ex.result(h) if ex is not None else {}
                    s = int(r["seed"])
                    record = settle(out, s, settings.config, r)
                    runs[str(s)] = {**record, "resumed": states[s] == "resume"}
                    write_sweep(out, data)  # a finished seed is recorded at once
                    mon.mark(s, record["state"], record["error"])
                mon.poll()
    finally:
        if ex is not None:
            ex.close()
    data["seconds"] = round(time.perf_counter() - t0, 1)
    write_sweep(out, data)
    if finish is not None:
        finish(out)
    return read_sweep(out)
