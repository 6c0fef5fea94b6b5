"""The local Ray of a sweep: its processes end with the sweep however it ends (``kill -9``
too: :mod:`mbn.experiments.sweep.reaper`), Ray's notice of a worker that died is one warning
line on stderr and never reaches stdout, and a seed whose worker aborted is done or failed in
``sweep.json``, not both. The reaper is tested on plain processes; the slow tests start Ray."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mbn.experiments.sweep.reaper import descendants

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")

#: A parent that starts the reaper, a child, and a grandchild of its child (as the raylet starts
#: Ray's agents), prints ``child grandchild`` and waits.
PARENT = """\
import subprocess, sys, time
from mbn.experiments.sweep.reaper import start_reaper

inner = "import subprocess, sys, time; p = subprocess.Popen([sys.executable, '-c', "
inner += "'import time; time.sleep(300)']); print(p.pid, flush=True); time.sleep(300)"
child = subprocess.Popen([sys.executable, "-c", inner], stdout=subprocess.PIPE, text=True)
grandchild = int(child.stdout.readline())
reaper = start_reaper()
time.sleep(1.5)  # the reaper has noted them
print(child.pid, grandchild, reaper.pid, flush=True)
if sys.argv[1] == "close":
    reaper.stdin.close()
    reaper.wait(timeout=30)
    print("closed", flush=True)
time.sleep(300)
"""


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _gone_within(pids, seconds: float) -> list[int]:
    end = time.monotonic() + seconds
    while time.monotonic() < end and any(_alive(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if _alive(p)]


def _start(script: str, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.Popen(
        [sys.executable, "-c", script, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def _kill(pids) -> None:
    for pid in pids:
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)


def test_the_reaper_ends_what_a_killed_parent_left_even_orphans_of_its_children():
    parent = _start(PARENT, "kill")
    assert parent.stdout is not None
    child, grandchild, reaper = map(int, parent.stdout.readline().split())
    try:
        parent.kill()  # kill -9: no clean-up of its own
        parent.wait()
        os.kill(child, signal.SIGKILL)  # as the raylet dies with the sweep: an orphaned agent
        assert _alive(grandchild)
        assert _gone_within([grandchild, reaper], 15) == []
    finally:
        _kill([child, grandchild, reaper])


def test_a_reaper_closed_by_its_parent_ends_the_descendants_and_not_the_parent():
    parent = _start(PARENT, "close")
    assert parent.stdout is not None
    child, grandchild, reaper = map(int, parent.stdout.readline().split())
    try:
        assert parent.stdout.readline().strip() == "closed"
        assert _gone_within([child, grandchild, reaper], 15) == []
        assert parent.poll() is None  # the parent itself runs on
    finally:
        parent.kill()
        _kill([child, grandchild, reaper])


def test_rays_driver_notices_are_one_warning_line_on_stderr(capsys):
    pytest.importorskip("ray")
    import ray._private.worker as ray_worker

    from mbn.experiments.sweep.run import divert_ray_notices

    original = ray_worker.print_to_stdstream
    undo = divert_ray_notices()
    try:
        notice = (
            "A worker died or was killed while executing a task by an unexpected system error. "
            "To troubleshoot the problem, check the logs for the dead worker. Worker PID: 6149"
        )
        ray_worker.print_to_stdstream({"lines": [notice], "pid": "raylet", "is_err": False}, False)
    finally:
        undo()
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == (
        "mbn: warning: Ray (raylet): A worker died or was killed while executing a task by an "
        "unexpected system error\n"
    )
    assert ray_worker.print_to_stdstream is original


#: A sweep on a local Ray of two seeds whose workers abort: seed 0 after writing a complete run,
#: seed 1 at once. Prints the runs of sweep.json.
ABORTING_SWEEP = """\
import json, os, sys, warnings
from pathlib import Path
from mbn.experiments.reproduce import REPRODUCE
from mbn.experiments.sweep.run import RayExecutor, SweepSettings, run_sweep, seed_dir

def task(out, seed, config, resume, *rest):
    folder = seed_dir(Path(out), seed)
    if seed == 0:
        folder.mkdir(parents=True)
        results = {"seed": seed, "config": config.to_dict(), "tests": {}, "claims": []}
        (folder / "results.json").write_text(json.dumps(results))
        (folder / "report.html").write_text("<html></html>")
    os.abort()

warnings.simplefilter("ignore")  # as `mbn` shows only its own warnings (not JAX's at fork)
settings = SweepSettings((0, 1), REPRODUCE.config(quick=True))
data = run_sweep(Path(sys.argv[1]), settings, lambda: RayExecutor(None, 1, task=task))
print(json.dumps(data["runs"]))
"""


@pytest.mark.slow
def test_an_aborting_worker_on_a_real_ray_is_one_state_and_stays_off_stdout(tmp_path):
    pytest.importorskip("ray")
    proc = _start(ABORTING_SWEEP, str(tmp_path / "sweep"))
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-3000:]
    assert len(out.splitlines()) == 1  # sweep.json's runs, nothing of Ray's
    runs = json.loads(out)
    assert runs["0"]["state"] == "done" and runs["0"]["error"] is None
    assert "ended abnormally" in runs["0"]["notices"][-1]
    assert runs["1"]["state"] == "failed" and "WorkerCrashedError" in runs["1"]["error"]
    lines = err.strip().splitlines()
    assert lines and all(line.startswith("mbn: warning: Ray (raylet): ") for line in lines), err


#: A sweep on a local Ray of one CPU and three seeds, each writing a complete run that records
#: its worker's process id. Prints the ids.
PIDS_SWEEP = """\
import json, os, sys, warnings
from pathlib import Path
from mbn.experiments.reproduce import REPRODUCE
from mbn.experiments.sweep.run import RayExecutor, SweepSettings, run_sweep, seed_dir

def task(out, seed, config, resume, *rest):
    folder = seed_dir(Path(out), seed)
    folder.mkdir(parents=True)
    results = {"seed": seed, "config": config.to_dict(), "tests": {}, "claims": [],
               "pid": os.getpid()}
    (folder / "results.json").write_text(json.dumps(results))
    (folder / "report.html").write_text("<html></html>")
    return {"seed": seed, "state": "done", "error": None, "seconds": 0.0}

warnings.simplefilter("ignore")
settings = SweepSettings((0, 1, 2), REPRODUCE.config(quick=True))
run_sweep(Path(sys.argv[1]), settings, lambda: RayExecutor(None, 1, task=task))
print(json.dumps([json.loads((seed_dir(Path(sys.argv[1]), s) / "results.json").read_text())["pid"]
                  for s in (0, 1, 2)]))
"""


@pytest.mark.slow
def test_each_seed_runs_in_a_fresh_worker_process(tmp_path):
    """A worker reused for the next seed kept every program the last one compiled: a second
    noise run in one worker passed the kernel's limit on memory maps and died."""
    pytest.importorskip("ray")
    proc = _start(PIDS_SWEEP, str(tmp_path / "sweep"))
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err[-3000:]
    pids = json.loads(out.strip().splitlines()[-1])
    assert len(set(pids)) == 3, pids


#: A sweep's executor on a local Ray with a task that sleeps; prints READY once it runs.
SLEEPING = """\
import os, time
from mbn.experiments.sweep.run import RayExecutor

def task(*args):
    time.sleep(300)

ex = RayExecutor(None, 1, task=task)
ex.submit(0, ())
time.sleep(5)
print("READY", flush=True)
time.sleep(300)
"""


@pytest.mark.slow
def test_rays_processes_end_when_the_sweep_is_killed():
    """Before the reaper, the dashboard and runtime-env agents outlived a ``kill -9`` of the
    sweep (some 60 s, waiting on the dead GCS)."""
    pytest.importorskip("ray")
    proc = _start(SLEEPING)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "READY"
    ray = descendants(proc.pid)
    names = {Path(f"/proc/{p}/cmdline").read_bytes().split(b"\0")[0] for p in ray if _alive(p)}
    assert b"ray::DashboardAgent" in names and b"ray::RuntimeEnvAgent" in names
    try:
        proc.kill()
        proc.wait()
        assert _gone_within(list(ray), 20) == []
    finally:
        _kill(list(ray))
