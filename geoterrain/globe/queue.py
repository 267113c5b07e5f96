"""Seed 001 §3.5.1: the asynchronous payload queue.

A node whose payload is wanted goes into a request queue. Each frame dispatches at most
``budget`` requests (the seed's per-frame dispatch budget, 8), nearest first, and never
lets more than ``concurrent`` generations run at once (the seed's cap, 32), so a fast
flight cannot flood the machine; the frame never waits for them. Results are collected at
the start of the next frames (the seed: usually ready in 1–3 frames); meanwhile the
parent is drawn in the children's place (:mod:`geoterrain.globe.cdlod`). Generations run
on a thread pool (pyproj, numpy and the compiled noise release the GIL).

``sync=True`` generates every request at dispatch, in the caller's thread (tests, and
pictures that must show the converged mesh).

Examples
--------
>>> q = RequestQueue(lambda key: key * 2, budget=2, sync=True)
>>> q.request(1, 10, 0.0); q.request(2, 20, 5.0); q.request(3, 30, 1.0)
>>> q.dispatch(), sorted(q.collect())
(2, [(1, 20), (3, 60)])
"""

from __future__ import annotations

import heapq
import itertools
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

__all__ = ["RequestQueue"]


class RequestQueue:
    """Requests (a row, a key, a priority: lower first) → ``generate(key)`` results.

    Attributes: ``budget`` (dispatches per frame), ``concurrent`` (most generations at once),
    ``in_flight`` (generations running), and after each :meth:`dispatch` and
    :meth:`collect`: ``dispatched``, ``collected``, ``generation_ms`` (the collected jobs'
    own time, summed) and ``stall_ms`` (time the caller spent in generation: all of it in
    sync mode, none otherwise).
    """

    def __init__(self, generate: Callable[[Any], Any], budget: int = 8, concurrent: int = 32,
                 workers: int = 2, sync: bool = False):
        self.generate = generate
        self.budget, self.concurrent, self.sync = int(budget), int(concurrent), bool(sync)
        self._heap: list = []
        self._queued: dict[int, Any] = {}
        self._running: dict[int, Future] = {}
        self._done: list = []
        self._count = itertools.count()
        self._pool = None if sync else ThreadPoolExecutor(max(1, int(workers)),
                                                          thread_name_prefix="globe-payload")
        self.dispatched = self.collected = 0
        self.generation_ms = self.stall_ms = 0.0

    @property
    def in_flight(self) -> int:
        return len(self._running)

    @property
    def queued(self) -> int:
        return len(self._queued)

    def pending(self, row: int) -> bool:
        """Whether ``row`` is queued or being generated."""
        return row in self._queued or row in self._running

    def request(self, row: int, key: Any, priority: float) -> None:
        """Ask for ``key``'s payload (for node ``row``); a repeat only updates the priority."""
        if row in self._running:
            return
        self._queued[row] = key
        heapq.heappush(self._heap, (float(priority), next(self._count), row, key))

    def cancel(self, row: int) -> None:
        """Forget a queued request (a running one finishes and is dropped by the caller)."""
        self._queued.pop(row, None)

    def _run(self, key):
        t0 = time.perf_counter()
        out = self.generate(key)
        return out, (time.perf_counter() - t0) * 1e3

    def dispatch(self) -> int:
        """Start up to ``budget`` requests, nearest first, within ``concurrent``; returns how
        many started."""
        n = 0
        self.stall_ms = 0.0
        while self._heap and n < self.budget and len(self._running) < self.concurrent:
            _, _, row, key = heapq.heappop(self._heap)
            if self._queued.get(row) != key:
                continue  # cancelled, or an older entry of a re-prioritised request
            del self._queued[row]
            if self.sync:
                t0 = time.perf_counter()
                out, ms = self._run(key)
                self.stall_ms += (time.perf_counter() - t0) * 1e3
                f: Future = Future()
                f.set_result((out, ms))
                self._running[row] = f
            else:
                self._running[row] = self._pool.submit(self._run, key)
            n += 1
        self.dispatched = n
        return n

    def collect(self) -> list[tuple[int, Any]]:
        """The finished generations since the last call: (row, result)."""
        out = []
        self.generation_ms = 0.0
        for row, f in list(self._running.items()):
            if f.done():
                del self._running[row]
                res, ms = f.result()
                self.generation_ms += ms
                out.append((row, res))
        self.collected = len(out)
        return out

    def drain(self) -> list[tuple[int, Any]]:
        """Dispatch and wait until nothing is queued or running (no budget); every result."""
        out = []
        budget = self.budget
        self.budget = 1 << 30
        try:
            while self._queued or self._running:
                self.dispatch()
                for f in list(self._running.values()):
                    f.result()
                out += self.collect()
        finally:
            self.budget = budget
        return out

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
