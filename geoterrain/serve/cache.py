"""The server's tile cache: finished responses in memory, least recently used first out,
within a byte budget.

Examples
--------
>>> c = ByteCache(10)
>>> c.put("a", b"12345", {}); c.put("b", b"67890", {}); c.put("c", b"xy", {})
>>> c.get("a") is None, c.get("c")[0], c.used <= c.budget
(True, b'xy', True)
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable

__all__ = ["ByteCache"]


class ByteCache:
    """Response bodies (and their headers) keyed by request, at most ``budget`` bytes of
    bodies in all: a put evicts the least recently used entries until it fits (a body
    larger than the whole budget is not kept). Thread-safe.

    ``used`` is the bytes held now, ``peak`` the most ever held; ``hits``, ``misses`` and
    ``evictions`` count lookups and drops.
    """

    def __init__(self, budget: int):
        self.budget = int(budget)
        self._d: OrderedDict[Hashable, tuple[bytes, dict]] = OrderedDict()
        self._lock = threading.Lock()
        self.used = self.peak = 0
        self.hits = self.misses = self.evictions = 0

    def get(self, key: Hashable) -> tuple[bytes, dict] | None:
        """The cached (body, headers) of ``key``, marked as just used, or None."""
        with self._lock:
            hit = self._d.get(key)
            if hit is None:
                self.misses += 1
                return None
            self._d.move_to_end(key)
            self.hits += 1
            return hit

    def put(self, key: Hashable, body: bytes, headers: dict) -> None:
        """Keep ``body`` (and its headers) under ``key`` within the budget."""
        size = len(body)
        with self._lock:
            old = self._d.pop(key, None)
            if old is not None:
                self.used -= len(old[0])
            if size > self.budget:
                return
            while self.used + size > self.budget and self._d:
                _, (b, _) = self._d.popitem(last=False)
                self.used -= len(b)
                self.evictions += 1
            self._d[key] = (body, headers)
            self.used += size
            self.peak = max(self.peak, self.used)

    def __len__(self) -> int:
        return len(self._d)

    def stats(self) -> dict:
        """The figures as a dict (``/stats.json``)."""
        with self._lock:
            return {"entries": len(self._d), "bytes": self.used, "peak_bytes": self.peak,
                    "budget_bytes": self.budget, "hits": self.hits, "misses": self.misses,
                    "evictions": self.evictions}
