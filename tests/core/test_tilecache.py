"""The terrain's caches (geoterrain/core/tilecache.py): the byte-bounded tile cache's
order, byte count and invalidation, and the derived slot's."""

from __future__ import annotations

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
