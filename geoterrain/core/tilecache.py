"""A terrain's caches: :class:`TileCache`, decoded arrays bounded in bytes, and
:class:`DerivedSlot`, what other modules derive from the terrain once; both safe to call
from several threads.

:class:`~geoterrain.terrain.Terrain` holds one of each (its ``memo``, ``lookup``,
``peek``, ``cache_keys``, ``clear_cache``, ``derived`` and ``forget`` are theirs), and
:class:`~geoterrain.exaggerate.Exaggerated` its own derived slot. Threads call them: the
overlapped flight selects the next frame on a worker thread while the main thread
shades (``rendering/scene.py``), the viewer selects on one, a viewshed reads on two.

Examples
--------
>>> c = TileCache(budget=100)
>>> a = c.memo(("h", 0, 0, 0), lambda: np.zeros(8))  # 64 bytes
>>> b = c.memo(("h", 0, 1, 0), lambda: np.zeros(8))  # 128 > 100: the oldest goes
>>> c.keys(), c.used
([('h', 0, 1, 0)], 64)
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

if TYPE_CHECKING:
    from geoterrain.core.grid import Grid

__all__ = ["DerivedSlot", "TileCache", "nbytes"]

_T = TypeVar("_T")


def nbytes(v: object) -> int:
    """The bytes a cached value is counted for: an array's, a decoded tile's
    (:class:`~geoterrain.terrainlike.Tile`: its codes, heights and valid arrays), a
    tuple's members' summed, 64 for anything else.

    Examples
    --------
    >>> nbytes((np.zeros(4), np.zeros(2, np.float32))), nbytes("x")
    (40, 64)
    """
    if isinstance(v, np.ndarray):
        return v.nbytes
    if isinstance(v, tuple):
        return sum(nbytes(x) for x in v)
    arrays = [getattr(v, a, None) for a in _TILE_ARRAYS]
    if all(isinstance(a, np.ndarray) for a in arrays):  # a Tile (core does not import it)
        return sum(a.nbytes for a in arrays)
    return 64


_TILE_ARRAYS = ("codes", "heights", "valid")


class _Making:
    """A value one thread is making: the others asking for its key wait on ``done``
    (held by the maker until the value is there, or its make failed)."""

    __slots__ = ("done", "owner", "stale", "value", "ok")

    def __init__(self) -> None:
        self.done = threading.Lock()
        self.done.acquire()
        self.owner = threading.get_ident()
        self.stale = False  # dropped while it was made: handed out, not kept
        self.value: Any = None
        self.ok = False


class TileCache:
    """Values kept by key, least recently used first out once their bytes
    (:func:`nbytes`) exceed ``budget`` (the newest is always kept, whatever its size).

    :meth:`memo` makes a missing value once per key, even when several threads ask for it
    at once: the first makes it, outside the lock (a decode takes milliseconds and reads
    other keys: a tile its parent's), the others wait for it. One lock guards every
    change of the table and of the byte count, so it stays exact under any interleaving;
    a hit takes no lock (it changes neither).

    Examples
    --------
    >>> c = TileCache(budget=1 << 20)
    >>> c.memo(("n", 0, 0, 0), lambda: np.ones(3)).tolist(), c.used
    ([1.0, 1.0, 1.0], 24)
    >>> c.memo(("n", 0, 0, 0), lambda: 1 / 0).tolist()  # a hit makes nothing
    [1.0, 1.0, 1.0]
    """

    def __init__(self, budget: int) -> None:
        self.budget = int(budget)
        self._table: OrderedDict[tuple, tuple[Any, int]] = OrderedDict()
        self._used = 0
        self._lock = threading.Lock()
        self._making: dict[tuple, _Making] = {}

    @property
    def used(self) -> int:
        """The bytes the values held count for (:func:`nbytes`)."""
        return self._used

    def __len__(self) -> int:
        return len(self._table)

    def memo(self, key: tuple, make: Callable[[], _T]) -> _T:
        """The value held under ``key``, marked as just used; on a miss, made by ``make``
        (once: a thread asking while another makes it waits for that value), kept, and
        the least recently used values dropped until the bytes fit the budget. A make
        that raises keeps nothing, and a thread that waited for it makes the value
        itself.

        Examples
        --------
        >>> c = TileCache(budget=1 << 20)
        >>> c.memo(("a",), lambda: np.zeros(2)) is c.memo(("a",), lambda: np.ones(2))
        True
        """
        hit = self._hit(key)
        if hit is not None:
            return hit[0]
        with self._lock:
            hit = self._table.get(key)  # kept meanwhile by another thread
            if hit is not None:
                self._table.move_to_end(key)
                return hit[0]
            job = self._making.get(key)
            if job is None:
                job = self._making[key] = _Making()
                mine = True
            else:
                mine = False
        if not mine:
            if job.owner == threading.get_ident():
                raise RuntimeError(f"the value of {key} is asked for while it is made")
            with job.done:  # the maker's value, or its make failed: make it here
                pass
            return job.value if job.ok else self.memo(key, make)
        try:
            val = make()
        except BaseException:
            with self._lock:
                del self._making[key]
            job.done.release()
            raise
        size = nbytes(val)
        with self._lock:
            del self._making[key]
            if not job.stale:
                table = self._table
                table[key] = (val, size)
                self._used += size
                while self._used > self.budget and len(table) > 1:
                    _, (_, sz) = table.popitem(last=False)
                    self._used -= sz
        job.value, job.ok = val, True
        job.done.release()
        return val

    def lookup(self, key: tuple) -> Any:
        """The value held under ``key``, marked as just used, or None (nothing is made).

        Examples
        --------
        >>> c = TileCache(budget=1 << 20); _ = c.memo(("a",), lambda: 1.5)
        >>> c.lookup(("a",)), c.lookup(("b",))
        (1.5, None)
        """
        hit = self._hit(key)
        return None if hit is None else hit[0]

    def _hit(self, key: tuple) -> tuple[Any, int] | None:
        # without the lock: a hit changes no byte count, and each OrderedDict call is
        # whole under the GIL; a value evicted between the two by another thread is
        # still its key's (the order then has nothing to mark)
        hit = self._table.get(key)
        if hit is not None:
            try:
                self._table.move_to_end(key)
            except KeyError:
                pass
        return hit

    def peek(self, key: tuple) -> Any:
        """The value held under ``key``, or None; the order is left as it is.

        Examples
        --------
        >>> c = TileCache(budget=1 << 20); _ = c.memo(("a",), lambda: 1.5)
        >>> _ = c.memo(("b",), lambda: 2.5); c.peek(("a",)), c.keys()
        (1.5, [('a',), ('b',)])
        """
        hit = self._table.get(key)  # one dict read, whole under the GIL: no lock
        return None if hit is None else hit[0]

    def keys(self) -> list[tuple]:
        """The keys held, least recently used first.

        Examples
        --------
        >>> c = TileCache(budget=1 << 20)
        >>> _ = c.memo(("a",), lambda: 1); _ = c.memo(("b",), lambda: 2); _ = c.lookup(("a",))
        >>> c.keys()
        [('b',), ('a',)]
        """
        with self._lock:
            return list(self._table)

    def clear(self) -> None:
        """Drop every value (and keep none being made now).

        Examples
        --------
        >>> c = TileCache(budget=1 << 20); _ = c.memo(("a",), lambda: 1); c.clear()
        >>> c.keys(), c.used
        ([], 0)
        """
        with self._lock:
            self._table.clear()
            self._used = 0
            for job in self._making.values():
                job.stale = True

    def drop_tiles(self, rects: Sequence[Sequence[int]], grid: Grid) -> None:
        """Drop the values of tiles whose footprint on ``grid`` meets ``rects`` (level-0
        samples (r0, c0, r1, c1), ends excluded), and every value that is not a tile's (a
        key not ending in a tile's (level, x, y)): what an edit of those samples reached.
        Values being made now are not kept.

        Examples
        --------
        >>> from geoterrain.core.grid import Grid
        >>> c = TileCache(budget=1 << 20); g = Grid.for_shape(33, 33, tile_size=8)
        >>> for k in [("h", 0, 0, 0), ("h", 0, 3, 3), ("rgb", "s", 1, 0, 0), ("sky",)]:
        ...     _ = c.memo(k, lambda: 0)
        >>> c.drop_tiles([(0, 0, 2, 2)], g); c.keys()
        [('h', 0, 3, 3)]
        """
        R = np.array(rects, np.int64).reshape(-1, 4)
        with self._lock:
            for job in self._making.values():
                job.stale = True
            for key in list(self._table):
                tk = key[-3:]
                if len(key) >= 4 and all(isinstance(v, int | np.integer) for v in tk):
                    L, x, y = (int(v) for v in tk)
                    if 0 <= L <= grid.top_level:
                        span = grid.tile_span(L)
                        i0, j0 = y * span, x * span
                        hit = ((R[:, 0] <= i0 + span) & (R[:, 2] > i0)
                               & (R[:, 1] <= j0 + span) & (R[:, 3] > j0)).any()
                        if not hit:
                            continue
                _, size = self._table.pop(key)
                self._used -= size


class DerivedSlot:
    """What modules derive from a terrain once (their tables, pools, scratch), by owner,
    kept as long as the terrain, outside the byte-bounded :class:`TileCache`.

    Two threads deriving for the same owner at once may both make it; the first kept is
    the one every caller gets (the other is dropped unused: a make only reads the
    terrain), so no two callers ever hold different objects for one owner.

    Examples
    --------
    >>> s = DerivedSlot()
    >>> s.get("example", dict) is s.get("example", dict)
    True
    """

    def __init__(self) -> None:
        self._made: dict[str, Any] = {}

    def get(self, owner: str, make: Callable[[], _T]) -> _T:
        """What ``owner`` derived, made by ``make`` on first use."""
        got = self._made.get(owner)
        if got is None:
            got = self._made.setdefault(owner, make())  # atomic: the first kept wins
        return got

    def forget(self, owner: str | None = None) -> None:
        """Drop what ``owner`` derived (every owner's with None).

        Examples
        --------
        >>> s = DerivedSlot(); a = s.get("x", dict); s.forget("x"); s.get("x", dict) is a
        False
        """
        if owner is None:
            self._made.clear()
        else:
            self._made.pop(owner, None)

    def edited(self, news: list | None) -> None:
        """An edit was taken in: what knows how to take it in (an object with an
        ``edited(news)`` method, given the edit log's new entries) is told, the rest
        dropped; everything dropped when ``news`` is None (where the edit reached is not
        known).

        Examples
        --------
        >>> class Stats:
        ...     def edited(self, news): self.news = news
        >>> s = DerivedSlot(); st = s.get("stats", Stats); _ = s.get("table", dict)
        >>> s.edited([{"n": 1}]); s.get("stats", Stats) is st, st.news, "table" in s._made
        (True, [{'n': 1}], False)
        """
        for owner, got in list(self._made.items()):
            hook = getattr(got, "edited", None)
            if hook is None or news is None:
                self._made.pop(owner, None)
            else:
                hook(news)
