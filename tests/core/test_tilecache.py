"""The terrain's caches (geoterrain/core/tilecache.py): the byte-bounded tile cache's
order, byte count, invalidation and threads, and the derived slot's."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core.grid import Grid
from geoterrain.core.tilecache import DerivedSlot, TileCache, nbytes
from geoterrain.terrainlike import Tile

pytestmark = pytest.mark.fast


def value(key: tuple) -> np.ndarray:
    """What a key's make gives: its own bytes, sized by the key (8 to 64 doubles)."""
    k = hash(key) & 0xFFFF
    return np.full(8 + k % 57, float(k))


def exact(c: TileCache) -> int:
    """The bytes the held values count for, added up afresh."""
    return sum(nbytes(c.peek(k)) for k in c.keys())


def test_nbytes_counts_arrays_tiles_and_tuples():
    z = np.zeros((5, 5))
    tile = Tile((0, 0, 0), np.zeros((5, 5), np.int64), z, np.ones((5, 5), bool))
    assert nbytes(tile) == 200 + 200 + 25
    assert nbytes((z, (z.astype(np.float32), tile))) == 200 + 100 + 425
    assert nbytes({"a": z}) == 64


def test_least_recently_used_goes_first_and_peek_keeps_the_order():
    c = TileCache(budget=4 * 80)
    for k in "abcd":
        c.memo((k,), lambda: np.zeros(10))  # 80 bytes each: full
    assert c.lookup(("a",)) is not None  # a: the newest now
    assert c.peek(("b",)) is not None  # b: still the oldest
    c.memo(("e",), lambda: np.zeros(10))
    assert c.keys() == [("c",), ("d",), ("a",), ("e",)]
    c.memo(("f",), lambda: np.zeros(25))  # 200 bytes: c, d and a go
    assert c.keys() == [("e",), ("f",)]
    assert c.used == exact(c) == 280 <= c.budget


def test_a_value_over_the_budget_is_kept_alone():
    c = TileCache(budget=100)
    c.memo(("a",), lambda: np.zeros(4))
    big = c.memo(("big",), lambda: np.zeros(100))
    assert c.keys() == [("big",)] and c.used == 800 and c.peek(("big",)) is big
    c.memo(("a",), lambda: np.zeros(4))
    assert c.keys() == [("a",)] and c.used == 32


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 40), st.booleans()), max_size=60),
       st.integers(100, 3000))
def test_order_and_bytes_against_a_list(ops, budget):
    """Any sequence of memo / lookup against a plain list kept in use order."""
    c, model = TileCache(budget), []
    for k, look in ops:
        key = ("h", k % 3, k, 0)
        if look:
            got = c.lookup(key)
            assert (got is None) == (key not in [m for m, _ in model])
            if got is not None:
                model.append(model.pop([m for m, _ in model].index(key)))
            continue
        v = c.memo(key, lambda key=key: value(key))
        np.testing.assert_array_equal(v, value(key))
        if key in [m for m, _ in model]:
            model.append(model.pop([m for m, _ in model].index(key)))
        else:
            model.append((key, nbytes(v)))
            while sum(s for _, s in model) > budget and len(model) > 1:
                model.pop(0)
    assert c.keys() == [m for m, _ in model]
    assert c.used == exact(c) == sum(s for _, s in model)


def footprint_meets(key, rects, g: Grid) -> bool:
    """The oracle: a tile's closed footprint of level-0 samples against half-open rects."""
    L, x, y = key[-3:]
    r0, c0 = y << (g.t + L), x << (g.t + L)
    r1, c1 = r0 + (g.tile_samples - 1 << L), c0 + (g.tile_samples - 1 << L)
    return any(a <= r1 and c >= r0 + 1 and b <= c1 and d >= c0 + 1 for a, b, c, d in rects)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 15), st.integers(0, 15)),
                max_size=40),
       st.lists(st.tuples(st.integers(0, 128), st.integers(0, 128), st.integers(1, 40),
                          st.integers(1, 40)), min_size=1, max_size=3))
def test_an_edit_drops_the_tiles_it_reaches_and_everything_else(tiles, rects):
    g = Grid.for_shape(129, 129, tile_size=8)  # t = 3, levels 0 … 4
    keys = {("h", L, x % g.tiles_per_side(L), y % g.tiles_per_side(L)) for L, x, y in tiles}
    keys |= {("rgb", "style", *k[1:]) for k in list(keys)[:5]}
    others = [("block_delta",), ("fields", "s", 0, 0), ("h", 9, 0, 0)]  # not a tile's
    c = TileCache(budget=1 << 30)
    for k in [*keys, *others]:
        c.memo(k, lambda: np.zeros(3))
    rects = [(r, q, r + h, q + w) for r, q, h, w in rects]
    c.drop_tiles(rects, g)
    want = sorted(k for k in keys if not footprint_meets(k, rects, g))
    assert sorted(c.keys()) == want
    assert c.used == exact(c) == 24 * len(want)


def test_clear_and_a_drop_keep_nothing_made_meanwhile():
    c = TileCache(budget=1 << 20)
    started, go = threading.Event(), threading.Event()

    def slow():
        started.set()
        go.wait(5)
        return np.zeros(2)

    for drop in (c.clear, lambda: c.drop_tiles([(0, 0, 1, 1)], Grid.for_shape(9, 9, 8))):
        started.clear(), go.clear()
        th = threading.Thread(target=c.memo, args=(("h", 0, 0, 0), slow))
        th.start()
        assert started.wait(5)
        drop()  # the value under way was made from what the drop replaces
        go.set()
        th.join(5)
        assert c.keys() == [] and c.used == 0
        assert c.memo(("h", 0, 0, 0), lambda: np.ones(2)).tolist() == [1.0, 1.0]
        c.clear()


def test_a_failed_make_keeps_nothing_and_a_waiter_makes_it_itself():
    c = TileCache(budget=1 << 20)
    started, go = threading.Event(), threading.Event()

    def fails():
        started.set()
        go.wait(5)
        raise OSError("read failed")

    errors, got = [], []
    th = threading.Thread(target=lambda: errors.append(
        pytest.raises(OSError, c.memo, ("k",), fails)))
    th.start()
    assert started.wait(5)
    waiter = threading.Thread(target=lambda: got.append(c.memo(("k",), lambda: np.ones(1))))
    waiter.start()
    time.sleep(0.05)  # the waiter waits for the first make
    go.set()
    th.join(5), waiter.join(5)
    assert errors and got[0].tolist() == [1.0]
    assert c.keys() == [("k",)] and c.used == 8


def test_a_make_that_asks_for_its_own_key_raises():
    c = TileCache(budget=1 << 20)
    with pytest.raises(RuntimeError, match="while it is made"):
        c.memo(("k",), lambda: c.memo(("k",), lambda: 1))
    assert c.keys() == [] and c.memo(("k",), lambda: 2) == 2


def test_threads_asking_at_once_make_each_value_once():
    c = TileCache(budget=1 << 30)
    made: dict[tuple, int] = {}
    count = threading.Lock()
    barrier = threading.Barrier(8)
    keys = [("h", 0, k, 0) for k in range(30)]

    def make(key):
        with count:
            made[key] = made.get(key, 0) + 1
        time.sleep(0.001)  # long enough that the others ask meanwhile
        return value(key)

    got: list[list] = [[] for _ in range(8)]

    def run(n):
        barrier.wait()
        for key in keys:
            got[n].append(c.memo(key, lambda key=key: make(key)))

    threads = [threading.Thread(target=run, args=(n,)) for n in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(30)
    assert made == dict.fromkeys(keys, 1)
    for n in range(1, 8):  # one object per key, whoever asked
        assert all(a is b for a, b in zip(got[0], got[n], strict=True))
    assert c.used == exact(c) == sum(nbytes(value(k)) for k in keys)


def test_threads_hammering_an_evicting_cache_keep_its_bytes_exact():
    """Eight threads, 200 keys, a budget of about a fifth of them: every value is its
    key's, and the byte count is the held values' exactly, within the budget."""
    keys = [("h", k % 4, k, k % 7) for k in range(200)]
    budget = sum(nbytes(value(k)) for k in keys) // 5
    c = TileCache(budget)
    wrong, barrier = [], threading.Barrier(8)

    def nested(key):  # a make that reads another key first, as a tile reads its parent
        if key[2] % 3 == 0:
            c.memo(("parent", key[2] // 3), lambda: np.zeros(4))
        return value(key)

    def run(seed):
        rng = np.random.default_rng(seed)
        barrier.wait()
        for k in rng.integers(0, len(keys), 3000):
            key = keys[k]
            v = c.lookup(key) if k % 5 == 0 else c.memo(key, lambda key=key: nested(key))
            if v is not None and not np.array_equal(v, value(key)):
                wrong.append(key)

    threads = [threading.Thread(target=run, args=(s,)) for s in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(60)
    assert not any(th.is_alive() for th in threads)
    assert wrong == []
    assert c.used == exact(c) <= budget
    assert all(np.array_equal(c.peek(k), value(k)) for k in c.keys() if k[0] == "h")


def test_a_terrain_read_from_threads_decodes_what_one_thread_does(tmp_path):
    """A store's tiles read by four threads at once through a cache that evicts: every
    tile's heights are those of a terrain read on one thread, the bytes exact."""
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 129, seed=5))
    store = geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=16)
    with geoterrain.open(store) as one:
        keys = one.tile_keys()
        want = {k: one.tile(*k).heights for k in keys}
    with geoterrain.open(store, cache_bytes=20 * 17 * 17 * 17) as t:
        bad, barrier = [], threading.Barrier(4)

        def run(n):
            barrier.wait()
            for k in keys[n::2] + keys[::-1]:
                if not np.array_equal(t.tile(*k).heights, want[k], equal_nan=True):
                    bad.append(k)
                t.tile_delta(*k)

        threads = [threading.Thread(target=run, args=(n,)) for n in range(4)]
        for th in threads:
            th.start()
        for th in threads:
            th.join(120)
        assert bad == []
        assert t.tile_cache.used == exact(t.tile_cache) <= t.tile_cache.budget


def test_the_derived_slot_hands_every_thread_one_object():
    s = DerivedSlot()
    barrier, got = threading.Barrier(8), []

    def make():
        time.sleep(0.002)  # the others ask meanwhile
        return object()

    def run():
        barrier.wait()
        got.append(s.get("owner", make))

    threads = [threading.Thread(target=run) for _ in range(8)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(10)
    assert len(got) == 8 and all(g is got[0] for g in got)


def test_the_derived_slot_tells_what_takes_an_edit_in_and_drops_the_rest():
    class Stats:
        news = None

        def edited(self, news):
            self.news = news

    s = DerivedSlot()
    st_, table = s.get("stats", Stats), s.get("table", dict)
    s.edited([{"n": 2}])
    assert s.get("stats", Stats) is st_ and st_.news == [{"n": 2}]
    assert s.get("table", dict) is not table
    s.edited(None)  # where the edit reached is not known: everything goes
    assert s.get("stats", Stats) is not st_
