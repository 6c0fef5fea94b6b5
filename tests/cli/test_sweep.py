"""``mbn sweep`` on the command line: bad input is one line and exit status 2 with nothing
touched, Ray missing says how to install it, a sweep on a real local Ray (in CI its seeds do not
simulate; ``-m slow`` runs two quick seeds end to end), then rerun."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mbn.cli.main import main


def _run(capsys, *argv):
    code = main(["sweep", *argv])
    err = capsys.readouterr().err.strip()
    return code, err


@pytest.mark.parametrize(
    ("seeds", "says"),
    [
        ("5-2", "runs backwards"),
        ("a-b", "not a seed or a range"),
        ("", "empty"),
        ("-1", "seeds are >= 0"),
        ("0-1000", "more than 1000 seeds"),
    ],
)
def test_bad_seeds(capsys, tmp_path, seeds, says):
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--seeds", seeds, "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2
    assert says in err and "--seeds" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s").exists()


def test_out_is_a_file(capsys, tmp_path):
    (tmp_path / "f").write_text("keep")
    code, err = _run(capsys, "--seeds", "0", "--out", str(tmp_path / "f"), "--quick")
    assert code == 2 and err == f"mbn: error: --out {tmp_path / 'f'}: is a file, not a folder"
    assert (tmp_path / "f").read_text() == "keep"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_out_not_writable(capsys, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        code, err = _run(capsys, "--seeds", "0", "--out", str(ro / "s"), "--quick")
    finally:
        ro.chmod(0o755)
    assert code == 2 and "cannot write" in err and len(err.splitlines()) == 1


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_out_where_nothing_can_be_created(capsys):
    code, err = _run(capsys, "--seeds", "0", "--out", "/proc/self/sweep", "--quick")
    assert code == 2 and err.startswith("mbn: error: --out /proc/self/sweep: cannot write in")
    assert len(err.splitlines()) == 1


def test_out_holding_another_sweep(capsys, tmp_path, monkeypatch):
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.experiments.sweep.run import SWEEP_KIND

    out = tmp_path / "s"
    out.mkdir()
    config = REPRODUCE.config(quick=True).to_dict()
    text = json.dumps(
        {"kind": SWEEP_KIND, "settings": {"seeds": [0, 1], "quick": True, "config": config}}
    )
    (out / "sweep.json").write_text(text)
    code, err = _run(capsys, "--seeds", "1-2", "--out", str(out), "--quick")
    assert code == 2 and "has seeds 0, which --seeds leaves out" in err
    code, err = _run(capsys, "--seeds", "0-1", "--out", str(out))
    assert code == 2 and "other settings (quick: true then, false now)" in err
    assert (out / "sweep.json").read_text() == text and os.listdir(out) == ["sweep.json"]


def test_ray_missing_says_how_to_install_it(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    code, err = _run(capsys, "--seeds", "0-1", "--out", str(tmp_path / "s"), "--quick")
    assert code == 2
    assert (
        err == "mbn: error: mbn sweep needs Ray, which is not installed: pip install 'mbn[sweep]'"
    )
    assert not (tmp_path / "s").exists()


def test_unreachable_address_fails_fast(capsys, tmp_path):
    pytest.importorskip("ray")
    with socket.socket() as sock:  # a port nothing listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    t0 = time.perf_counter()
    code, err = _run(
        capsys, "--seeds", "0", "--out", str(tmp_path / "s"), "--address", f"127.0.0.1:{port}"
    )
    assert time.perf_counter() - t0 < 10
    assert code == 2 and f"--address 127.0.0.1:{port}: no Ray cluster answers there" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "s").exists()
    code, err = _run(capsys, "--seeds", "0", "--out", str(tmp_path / "s"), "--address", "nohost")
    assert code == 2 and "expected HOST:PORT" in err


def test_seeds_required_unless_summarize(capsys, tmp_path):
    code, err = _run(capsys, "--out", str(tmp_path / "s"))
    assert code == 2 and "--seeds is required" in err
    code, err = _run(capsys, "--summarize", "--out", str(tmp_path / "s"))
    assert code == 2 and "no sweep there" in err


def test_a_bad_named_setting_is_one_line_before_ray_or_any_seed(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # refused before Ray is needed
    config = tmp_path / "s.toml"
    config.write_text('[validation]\nmaze = "heldout"\n')
    out = tmp_path / "s"
    code, err = _run(capsys, "--seeds", "0-1", "--out", str(out), "--config", str(config))
    assert code == 2
    assert err == (
        f"mbn: error: {config}:2: validation.maze: 'heldout' is a test maze ([tests] "
        "heldout_maze); a maze that validates candidates during evolution must be one no test uses"
    )
    assert not out.exists()


#: Budgets under the quick preset's, for the tiny sweep of CI.
TINY = """\
[followers]
episode_seconds = 10.0

[rf]
generations = 4
restarts = 1

[lf]
generations = 4
members = 1

[pm]
generations = 4

[tests]
jitter_per_mark = 1
heldout_repeats = 1
seconds = 30.0
mbn_seconds = 40.0
"""


def _tiny_sweep(tmp_path, seeds: list[int]) -> None:
    """Quick seeds on a local Ray through the command line, then the same command. A config
    trims the quick budgets further (every stage still runs, and the report)."""
    pytest.importorskip("ray")
    out = tmp_path / "sweep"
    tiny = tmp_path / "tiny.toml"
    tiny.write_text(TINY)
    text = f"{seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else str(seeds[0])
    cmd = [sys.executable, "-m", "mbn", "sweep", "--seeds", text, "--quick", "--out", str(out)]
    cmd += ["--config", str(tiny)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "sweep: " in proc.stdout and "seeds meet every target" in proc.stdout
    for s in seeds:
        folder = out / f"seed-{s}"
        for f in (
            "results.json",
            "report.html",
            "run.json",
            "controllers/mbn.json",
            "stages/tests.json",
        ):
            assert (folder / f).is_file(), f"seed {s}: {f}"
        assert json.loads((folder / "results.json").read_text())["seed"] == s
    for f in ("sweep.json", "sweep.md", "sweep.html"):
        assert (out / f).is_file()
    data = json.loads((out / "sweep.json").read_text())
    assert data["settings"]["seeds"] == seeds and data["settings"]["quick"] is True
    assert data["summary"]["finished"] == len(seeds)
    for s in seeds:
        run = data["runs"][str(s)]
        assert run["state"] == "done"
        env = run["worker"]["env"]  # what the Ray worker saw: threads pinned to 1
        assert env["XLA_FLAGS"].split() == ["--xla_cpu_multi_thread_eigen=false"]
        assert env["OMP_NUM_THREADS"] == env["OPENBLAS_NUM_THREADS"] == "1"
    results = {s: (out / f"seed-{s}" / "results.json").read_bytes() for s in seeds}
    t0 = time.perf_counter()
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-3000:]
    n = len(seeds)
    assert f"{n} of {n} seeds were finished before: kept" in again.stdout
    assert time.perf_counter() - t0 < 60  # no Ray, no stage: only the report
    assert {s: (out / f"seed-{s}" / "results.json").read_bytes() for s in seeds} == results


@pytest.mark.slow  # 5-10 min on 2 cores; CI drives a real Ray with seeds that do not simulate
def test_tiny_sweep_on_local_ray_then_rerun_skips_both(tmp_path):
    """2 quick seeds side by side on a local Ray, end to end, then the same command."""
    _tiny_sweep(tmp_path, [0, 1])


@pytest.mark.slow
def test_a_local_ray_runs_each_seed_in_a_pinned_worker_and_a_rerun_keeps_them(tmp_path):
    """CI: ``mbn sweep`` on a real local Ray whose tasks write finished seed folders without
    simulating (``tests/cli/sweep_tasks.py``; the seed's run itself is the quick reproduction's
    tests): every seed ran in a Ray worker with its threads pinned, the sweep's files
    are written, and the same command again keeps both seeds without starting Ray."""
    pytest.importorskip("ray")
    root = Path(__file__).resolve().parents[2]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])),
    }
    out = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "tests.cli.sweep_tasks", "sweep", "--seeds", "0-1", "--quick"]
    cmd += ["--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=root)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.splitlines()[-1].startswith("sweep: 2/2 seeds meet every target")
    data = json.loads((out / "sweep.json").read_text())
    for s in (0, 1):
        run = data["runs"][str(s)]
        assert run["state"] == "done"
        env_seen = run["worker"]["env"]  # what the Ray worker saw: threads pinned to 1
        assert env_seen["XLA_FLAGS"].split() == ["--xla_cpu_multi_thread_eigen=false"]
        assert env_seen["OMP_NUM_THREADS"] == env_seen["OPENBLAS_NUM_THREADS"] == "1"
        assert json.loads((out / f"seed-{s}" / "results.json").read_text())["seed"] == s
    for f in ("sweep.json", "sweep.md", "sweep.html"):
        assert (out / f).is_file()
    results = {s: (out / f"seed-{s}" / "results.json").read_bytes() for s in (0, 1)}
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env, cwd=root)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "2 of 2 seeds were finished before: kept" in again.stdout
    assert {s: (out / f"seed-{s}" / "results.json").read_bytes() for s in (0, 1)} == results


def test_a_reuse_folder_that_is_no_sweep_is_one_line_before_any_work(capsys, tmp_path):
    code, err = _run(
        capsys, "--seeds", "0", "--out", str(tmp_path / "s"), "--reuse", str(tmp_path / "no")
    )
    assert code == 2 and err == f"mbn: error: --reuse {tmp_path / 'no'}: no such folder"
    (tmp_path / "run").mkdir()
    code, err = _run(
        capsys, "--seeds", "0", "--out", str(tmp_path / "s"), "--reuse", str(tmp_path / "run")
    )
    assert code == 2
    assert err == f"mbn: error: --reuse {tmp_path / 'run'}: not a sweep folder (no sweep.json)"
    assert not (tmp_path / "s").exists()
    code, err = _run(capsys, "--summarize", "--out", str(tmp_path / "s"), "--reuse", "x")
    assert code == 2 and "--summarize reads the settings" in err


def test_run_with_a_reuse_folder_that_holds_no_run_is_one_line(capsys, tmp_path):
    (tmp_path / "empty").mkdir()
    argv = ["run", "new-behaviours", "--quick", "--out", str(tmp_path / "r")]
    code = main([*argv, "--reuse", str(tmp_path / "empty")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err == f"mbn: error: --reuse {tmp_path / 'empty'}: no run there (no run.json)"
    assert not (tmp_path / "r").exists()
    code = main(["reproduce", "--quick", "--out", str(tmp_path / "q"), "--reuse", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err == f"mbn: error: --reuse {tmp_path}: no run there (no run.json)"
    assert not (tmp_path / "q").exists()


#: What each seed of the fake sweep records in its timings.json: seconds and robot-steps.
FAKE_TIMINGS = {
    0: ({"rf": 100.0, "lf": 10.0}, {"rf": 400_000_000, "lf": 0}),
    1: ({"rf": 300.0, "lf": 30.0}, {"rf": 1_200_000_000, "lf": 50_000_000}),
}


def _fake_seed(out, seed, config, resume, *rest):
    """A Ray task's stand-in: a finished seed folder (no simulation) with a timings.json."""
    from pathlib import Path

    from mbn.experiments.pipeline import RunDir
    from tests.experiments.sweep.conftest import fake_run

    folder = fake_run(Path(out), seed, config.to_dict(), {}, {}, {"claim A": True}, [0.0, 1.0])
    RunDir(folder).write_timings(*FAKE_TIMINGS[seed])
    return {"seed": seed, "state": "done", "error": None, "seconds": 1.0}


def test_the_sweep_prints_its_stage_times_at_the_end_and_not_with_quiet(
    capsys, tmp_path, monkeypatch
):
    import mbn.experiments.sweep.run as sweep_run

    monkeypatch.setattr(
        sweep_run, "RayExecutor", lambda address, cpus: sweep_run.InlineExecutor(_fake_seed)
    )
    out = tmp_path / "s"
    assert main(["sweep", "--seeds", "0-1", "--quick", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    start = lines.index(f"time and robot-steps per stage over the seeds ({out}):")
    table = [line.split() for line in lines[start + 1 :]]
    assert table[0] == ["stage", "seeds", "median", "s", "max", "s", "robot-steps/s"]
    assert table[1] == ["rf", "2", "200.00", "300.00", "4.00", "M/s"]  # 1.6e9 over 400 s
    assert table[2] == ["lf", "2", "20.00", "30.00", "1.25", "M/s"]  # 5e7 over 40 s
    assert table[4] == ["all", "stages", "2", "220.00", "330.00", "3.75", "M/s"]
    wall = json.loads((out / "sweep.json").read_text())["seconds"]
    assert lines[start + 6].startswith("sweep wall time: ")
    assert lines[start + 6].endswith(f" ({wall:.1f} s)")
    assert lines[-1].startswith("sweep: 2/2 seeds meet every target")
    # --summarize prints it too, from the folders; --quiet leaves only the summary line
    assert main(["sweep", "--summarize", "--out", str(out)]) == 0
    assert f"time and robot-steps per stage over the seeds ({out}):" in capsys.readouterr().out
    assert main(["sweep", "--summarize", "--out", str(out), "--quiet"]) == 0
    assert capsys.readouterr().out.splitlines() == [lines[-1]]
    quiet = tmp_path / "q"
    assert main(["sweep", "--seeds", "0-1", "--quick", "--out", str(quiet), "--quiet"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert len(printed) == 1 and printed[0].startswith("sweep: 2/2 seeds meet every target")
