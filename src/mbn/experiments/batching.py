"""Seeds run side by side in one process, their population evaluations merged into one call
(``mbn sweep --batched``).

Each seed runs in a thread of its own, as a member of one :class:`Batcher`. When a DE run of a
seed evaluates a population whose fitness can be merged (an
:class:`~mbn.experiments.evolve.OwnedFitness`: the followers' crossroads, in the rf, lf_search and
lf stages), it hands the population to the batcher and waits. The batcher evaluates the waiting
populations of one signature (task, time constant, shapes) in one call of one compiled program,
each genome with its own seed's base network, connections, perturbations and starts, as soon as
every member waits or the first of them has waited :attr:`Batcher.patience` seconds, and gives
each population its values.

Each genome's value depends on its own row only (bit for bit: XLA computes the rows alike in
any batch, which ``tests/experiments/test_batching.py`` checks), so a seed's run is the same
whichever seeds it was batched with and whenever the batcher fired: its ``results.json`` is
byte for byte that of the seed run alone (``tests/experiments/sweep/test_batched.py``). Merged
batches are padded to a power of two of genomes and of owners, so that a sweep compiles a few
shapes only; the padding rows repeat the first genome and are dropped.

Everything else a seed does (its validation, tests, report; the program module's evolution,
whose fitness is not merged) runs in its own thread, side by side with the others.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mbn.experiments.evolve import OwnedFitness, split_fitness

__all__ = ["Batcher", "current"]

_local = threading.local()


def current() -> Batcher | None:
    """The batcher this thread evaluates through (None: it evaluates alone)."""
    return getattr(_local, "batcher", None)


@dataclass(eq=False)
class _Request:
    fitness: OwnedFitness
    population: np.ndarray
    owner: np.ndarray
    since: float = field(default_factory=time.monotonic)
    values: np.ndarray | None = None
    error: BaseException | None = None


class _Membership:
    """A member's thread evaluates through its batcher inside ``with`` (:meth:`Batcher.enrol`)."""

    def __init__(self, batcher: Batcher) -> None:
        self.batcher = batcher

    def __enter__(self) -> Batcher:
        _local.batcher = self.batcher
        return self.batcher

    def __exit__(self, *exc: object) -> None:
        _local.batcher = None


def _bucket(n: int) -> int:
    """The padded size of ``n`` rows: the next power of two."""
    return 1 << max(0, n - 1).bit_length()


def _padded(x: np.ndarray, n: int) -> np.ndarray:
    """``x`` with its first row repeated until it has ``n`` rows."""
    if len(x) == n:
        return x
    return np.concatenate([x, np.repeat(x[:1], n - len(x), axis=0)])


class Batcher:
    """Merges the population evaluations of the threads that are its members (the seeds of a
    batched sweep): see the module. A population waits for those of the other members that are
    evolving (:meth:`evolving`), at most ``patience`` seconds; ``workers``: threads that
    evaluate parts of a merged batch side by side (on a CPU, XLA runs one call on about one
    core)."""

    def __init__(self, workers: int = 1, patience: float = 5.0) -> None:
        self.workers = max(1, int(workers))
        self.patience = float(patience)
        self._cond = threading.Condition()
        self._members = 0
        self._pending: list[_Request] = []
        #: calls made and populations they evaluated (for the sweep's record)
        self.calls = 0
        self.populations = 0

    def enrol(self) -> _Membership:
        """A membership: inside ``with`` it, a thread evaluates through the batcher."""
        return _Membership(self)

    def member(self) -> _Membership:
        """:meth:`enrol`, for a thread that enrols itself."""
        return self.enrol()

    @contextmanager
    def evolving(self) -> Iterator[None]:
        """The block evaluates populations through the batcher (a DE run or group, from its
        first generation to its last): while it runs, the others' populations wait for this
        one's (up to :attr:`patience`). A member doing other work holds up nobody."""
        with self._cond:
            self._members += 1
        try:
            yield
        finally:
            with self._cond:
                self._members -= 1
                self._cond.notify_all()  # the others may all be waiting now

    def evaluate(self, fitness: OwnedFitness, population: Any, owner: Any) -> np.ndarray:
        """``fitness(population, owner)``, evaluated with the other members' waiting
        populations; counted on this thread's tally of robot-steps."""
        population = np.asarray(population)
        fitness.count(len(population))
        request = _Request(fitness, population, np.asarray(owner))
        with self._cond:
            self._pending.append(request)
            self._cond.notify_all()
            while request.values is None and request.error is None:
                waited = time.monotonic() - self._pending[0].since if self._pending else 0.0
                if request in self._pending and (
                    len(self._pending) >= self._members or waited >= self.patience
                ):
                    batch, self._pending = self._pending, []
                    self._cond.release()
                    try:
                        self._run(batch)
                    finally:
                        self._cond.acquire()
                        self._cond.notify_all()
                else:
                    self._cond.wait(timeout=max(0.01, self.patience - waited))
        if request.error is not None:
            raise request.error
        assert request.values is not None
        return request.values

    def _run(self, batch: Sequence[_Request]) -> None:
        groups: dict[Any, list[_Request]] = {}
        for r in batch:
            groups.setdefault(r.fitness.signature, []).append(r)
        for requests in groups.values():
            try:
                values = self._merged(requests)
            except BaseException as exc:  # every waiting seed hears of it
                for r in requests:
                    r.error = exc
                continue
            start = 0
            for r in requests:
                r.values = values[start : start + len(r.population)]
                start += len(r.population)

    def _merged(self, requests: Sequence[_Request]) -> np.ndarray:
        first = requests[0].fitness
        population, owner, owned = OwnedFitness.merged(
            [(r.fitness, r.population, r.owner) for r in requests]
        )
        n, r = len(population), len(owned[0])
        population = _padded(population, _bucket(n))
        owner = _padded(owner, _bucket(n))
        owned = tuple(_padded(a, _bucket(r)) for a in owned)
        call = split_fitness(
            lambda p, o: first.evaluate(p, o, owned), self.workers, parts=self.workers
        )
        values = np.asarray(call(population, owner))[:n]
        with self._cond:
            self.calls += 1
            self.populations += len(requests)
        return values
