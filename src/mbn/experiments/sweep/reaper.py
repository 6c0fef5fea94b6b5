"""The local Ray a sweep starts ends with the sweep, however the sweep ends (``kill -9`` too).

``ray.init()`` starts Ray's processes as children of the sweep: the GCS and the raylet die with
it (Ray has them killed when their parent dies), but the raylet's own children — the dashboard
agent and the runtime-env agent — only notice the raylet is gone by polling, and then wait up
to a minute on the dead GCS before they exit; workers may outlive it too. So the sweep starts a
reaper (:func:`start_reaper`): a small process in a session of its own that notes, every
:data:`POLL_S` seconds, every process descended from the sweep, and when the sweep's end of a
pipe closes (the sweep closed it, exited or was killed), ends each of them that is still the
process it noted (SIGTERM, then SIGKILL after :data:`GRACE_S`), and exits. Linux only (it reads
``/proc``); elsewhere no reaper is started.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["GRACE_S", "POLL_S", "descendants", "reap", "start_reaper", "watch"]

#: How often the reaper notes the sweep's descendants (s).
POLL_S = 0.5
#: How long the processes have to end after SIGTERM before SIGKILL (s).
GRACE_S = 3.0
_PROC = Path("/proc")


def _stat(pid: int) -> tuple[int, int] | None:
    """``(parent pid, start time)`` of a process, or None when it is gone."""
    try:
        text = (_PROC / str(pid) / "stat").read_text()
    except OSError:
        return None
    fields = text[text.rfind(")") + 2 :].split()  # the name may hold spaces and parentheses
    return int(fields[1]), int(fields[19])


def descendants(root: int) -> dict[int, int]:
    """Every process descended from ``root`` (not itself): ``pid -> start time``."""
    children: dict[int, list[int]] = {}
    started: dict[int, int] = {}
    for entry in _PROC.iterdir():
        if not entry.name.isdigit():
            continue
        stat = _stat(int(entry.name))
        if stat is not None:
            children.setdefault(stat[0], []).append(int(entry.name))
            started[int(entry.name)] = stat[1]
    out: dict[int, int] = {}
    todo = list(children.get(root, []))
    while todo:
        pid = todo.pop()
        if pid in out or pid not in started:
            continue
        out[pid] = started[pid]
        todo.extend(children.get(pid, []))
    return out


def _alive(noted: dict[int, int]) -> list[int]:
    """The processes of ``noted`` still running as the process noted (not a reused pid)."""
    alive = []
    for pid, start in noted.items():
        stat = _stat(pid)
        if stat is not None and stat[1] == start:
            alive.append(pid)
    return alive


def reap(noted: dict[int, int], grace: float = GRACE_S) -> None:
    """End the processes of ``noted`` (``pid -> start time``) that still run, and what they
    started since: SIGTERM, then SIGKILL to those left after ``grace`` seconds."""
    for pid in _alive(dict(noted)):
        noted.update(descendants(pid))
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 0.0)):
        for pid in _alive(noted):
            with contextlib.suppress(OSError):
                os.kill(pid, sig)
        end = time.monotonic() + wait
        while _alive(noted) and time.monotonic() < end:
            time.sleep(0.05)


def watch(parent: int, fd: int = 0, poll: float = POLL_S) -> None:
    """Note ``parent``'s descendants every ``poll`` seconds until ``fd`` reads end of file,
    then :func:`reap` them."""
    me = os.getpid()
    child = os.getppid() == parent  # started by it: its end makes another process our parent
    noted: dict[int, int] = {}
    while True:
        if child and os.getppid() != parent:
            break  # it is gone (and its pid may be reused): end what was noted
        noted.update({p: s for p, s in descendants(parent).items() if p != me})
        ready, _, _ = select.select([fd], [], [], poll)
        if ready:
            try:
                data = os.read(fd, 4096)
            except OSError:
                data = b""
            if not data:
                break
    noted.pop(me, None)
    reap(noted)


def start_reaper() -> subprocess.Popen[bytes] | None:
    """Start the reaper of this process's descendants (None where there is no ``/proc``). Close
    its ``stdin`` (or exit) to have them ended."""
    if not (_PROC / "self" / "stat").exists():
        return None
    return subprocess.Popen(
        [sys.executable, "-m", "mbn.experiments.sweep.reaper", str(os.getpid())],
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # a Ctrl-C on the terminal does not end it before its work
    )


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch(int(sys.argv[1]))
