"""The tile-table rules of storecheck, on whole arrays: the first tile (in table order)
that breaks a rule is named with the first rule it breaks, as the per-tile loop of
schema 3 did."""

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.exceptions import StoreError
from geoterrain.store.check import check_store

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    from geoterrain.ingest.synth import generate, write_geotiff

    d = tmp_path_factory.mktemp("check")
    dem = write_geotiff(d / "d.tif", generate("fbm", 129, seed=3))
    p = geoterrain.preprocess(dem, d / "s.geoterrain", tile_size=16)
    with geoterrain.open(p) as t:
        return p, t.meta, t.tile_info, t.grid


# (field, value, the rule's words); None: a tile outside the grid is added
_BREAKS = [
    (None, None, "lies outside the grid"),
    ("nvalid", 0, "nvalid is out of range"),
    ("nvalid", 10**9, "nvalid is out of range"),
    ("zmin", float("nan"), "zmin must be a finite number"),
    ("xmax", float("inf"), "xmax must be a finite number"),
    ("ymin", None, "ymin must be a finite number"),
    ("error", float("nan"), "error must be a number"),
    ("radius_max", -1.0, "radius_max is out of range"),
    ("zmin", 1e7, "box is inverted"),
    ("zmax", 1e12, "zmax must be a finite number within"),  # beyond any scene
]


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_the_first_broken_tile_and_rule_are_named(store, data):
    path, meta, tiles, g = store
    keys = [k for k in tiles if k != (g.top_level, 0, 0)]  # the top tile's box is its own rule
    picks = sorted(data.draw(st.lists(st.integers(0, len(keys) - 1), min_size=1, max_size=3,
                                      unique=True)))
    broken = copy.deepcopy(tiles)
    named = []
    for i in picks:
        field, value, words = data.draw(st.sampled_from(_BREAKS))
        k = keys[i]
        if field is None:  # a copy of the tile, one grid's width east (moving the tile
            #                itself would orphan its children, earlier in the table)
            k = (k[0], k[1] + (1 << (g.top_level - k[0])), k[2])
            broken[k] = copy.deepcopy(broken[keys[i]])
        else:
            broken[k][field] = value
        named.append((k, words))
    order = list(broken)
    first_key, words = min(named, key=lambda kw: order.index(kw[0]))
    with pytest.raises(StoreError) as ex:
        check_store(path, meta, broken)
    msg = str(ex.value)
    assert f"tile {first_key}" in msg
    if len({order.index(k) for k, _ in named}) == len(named):
        # one break per tile: its rule is the one named (several breaks on one tile name
        # the first rule in the check's order)
        assert words in msg


def test_a_tile_without_its_parent_is_named(store):
    path, meta, tiles, g = store
    broken = dict(tiles)
    parent = (1, 0, 0)
    del broken[parent]
    with pytest.raises(StoreError, match=r"tile \(0, [01], [01]\) has no parent tile"):
        check_store(path, meta, broken)


def test_a_sound_table_passes(store):
    path, meta, tiles, g = store
    assert check_store(path, meta, tiles)[0] == g
    assert np.isfinite([v["zmin"] for v in tiles.values()]).all()


@pytest.mark.parametrize("q, ok", [
    ({"mode": "quantized", "step": 0.1, "offset": -10000.0, "codec_error": 0.5, "bins": 9},
     True),
    ({"mode": "quantized", "step": 0.9, "offset": 0.0, "codec_error": 0.5}, True),  # no bins
    ({"mode": "quantized", "step": 0.1, "offset": 0.0, "codec_error": 0.5, "bins": 8}, False),
    ({"mode": "quantized", "step": 0.1, "offset": 0.0, "codec_error": 0.5, "bins": 13}, False),
    ({"mode": "quantized", "step": 0.1, "offset": 0.0, "codec_error": 0.5, "bins": 3}, False),
    ({"mode": "quantized", "step": 0.1, "offset": 0.0, "codec_error": 0.5, "bins": "9"}, False),
    ({"mode": "quantized", "step": 0.1, "offset": 0.0, "codec_error": 0.5, "bins": 2**40},
     False),
    ({"mode": "int", "step": 1.0, "offset": 0.0, "codec_error": 0.0, "bins": 3}, False),
])
def test_residual_bins_must_fit_the_bound(store, q, ok):
    """A stranger's quantizer: the bins W must be an odd integer whose half-width
    (W - 1) / 2 codes stays within ε and whose W + 1 codes exceed it, and only a lossy
    (quantized) quantizer has them."""
    path, meta, tiles, g = store
    m = copy.deepcopy(meta)
    m["quantizer"] = q
    if ok:
        assert check_store(path, m, tiles)[2].bins == q.get("bins", 1)
    else:
        with pytest.raises(StoreError, match="quantizer"):
            check_store(path, m, tiles)
