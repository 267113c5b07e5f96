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
from geoterrain.store.schema import ROOTS_SCHEMA_VERSION, SCHEMA_VERSION

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


@pytest.fixture(scope="module")
def wide_store(tmp_path_factory):
    from geoterrain.ingest.synth import generate, write_geotiff

    d = tmp_path_factory.mktemp("check_wide")
    dem = write_geotiff(d / "w.tif", generate("fbm", (65, 129), seed=4))
    p = geoterrain.preprocess(dem, d / "w.geoterrain", tile_size=16, root_grid=False)
    with geoterrain.open(p) as t:
        return p, t.meta, t.tile_info, t.grid


def _as_roots(meta, tiles, g):
    """The square store's metadata and table as the 2 × 1 root grid of the same raster
    holds them: the square's tiles that the root grid has (the square also stores the
    tiles whose footprint holds only a shared border row of data, beyond the roots')."""
    from geoterrain.core.grid import Grid

    r = Grid.for_shape(g.rows, g.cols, g.tile_samples - 1, roots=True)
    assert r.roots == (2, 1) and r.top_level == g.top_level - 1
    m = dict(meta, grid=r.to_json(), schema_version=ROOTS_SCHEMA_VERSION)
    m["block_delta_levels"] = min(r.t, r.top_level) + 1
    if "normals_derived" in m and m["normals_derived"] != [0]:
        m["normals_derived"] = list(r.levels)
    inside = {k: v for k, v in tiles.items()
              if k[0] <= r.top_level and k[1] < r.tiles(k[0])[0] and k[2] < r.tiles(k[0])[1]}
    return m, inside, r


def test_a_root_grid_store_passes_its_checks(wide_store):
    path, meta, tiles, g = wide_store
    m, t, r = _as_roots(meta, tiles, g)
    assert m["grid"]["layout"] == "roots"
    assert check_store(path, m, t)[0] == r  # read since the reader draws it (issue 45)
    # inside the square grid, outside the root grid: level 0 holds 8 × 4 tiles, not 16 × 16
    for k in ((0, 8, 0), (0, 0, 4), (r.top_level, 2, 0)):
        broken = dict(t)
        broken[k] = dict(t[(0, 0, 0)])
        with pytest.raises(StoreError, match=rf"tile \({k[0]}, {k[1]}, {k[2]}\) lies outside"):
            check_store(path, m, broken)
    # a grid whose n does not fit its shape, or the square layout spelled out
    for grid in (dict(m["grid"], n=m["grid"]["n"] + 1), dict(m["grid"], layout="square")):
        with pytest.raises(StoreError, match="invalid metadata"):
            check_store(path, dict(m, grid=grid), t)
    # the schema version follows the layout: 24 for root grids, 23 for squares
    for mm, tt in ((dict(m, schema_version=SCHEMA_VERSION), t),
                   (dict(meta, schema_version=ROOTS_SCHEMA_VERSION), tiles)):
        with pytest.raises(StoreError, match=r"invalid metadata \(a (root|square) grid is "
                                             r"written in schema version 2[34], not 2[34]\)"):
            check_store(path, mm, tt)
    # the square store itself is still read
    assert meta["schema_version"] == SCHEMA_VERSION == 23
    assert check_store(path, meta, tiles)[0] == g
    # before 23: its frame holds aeqd_wkt (and before 20 its δ and r blobs are not 20's)
    for old in (14, 15, 17, 18, 20, 21, 22):
        with pytest.raises(StoreError, match=f"written in schema version 23, not {old}"):
            check_store(path, dict(meta, schema_version=old), tiles)


def test_the_writer_puts_a_root_grid_in_schema_version_24_and_the_reader_opens_both(
        tmp_path, wide_store):
    from geoterrain.store.reader import StoreReader
    from geoterrain.store.writer import StoreWriter

    _, meta, tiles, g = wide_store
    m, _, r = _as_roots(meta, tiles, g)
    for name, grid, version in (("roots", r.to_json(), 24), ("square", g.to_json(), 23)):
        with StoreWriter(tmp_path / f"{name}.geoterrain") as w:
            w.put_metadata({"grid": grid, "schema_version": 1})  # the writer's to set
            w.put_blob((0, 0, 0), "heights", b"x")
            w.commit()
        assert StoreReader(tmp_path / f"{name}.geoterrain").metadata["schema_version"] == version


def test_a_frame_lattice_is_schema_25_and_checked(tmp_path):
    """A geographic root grid past its lattice (frame.lattice, proxy positions past it):
    written in schema 25 and read; its lattice anywhere but that grid's level-0 shape, on
    another frame, or in another schema, is refused in one line, and the same store
    without the lattice in schema 24 (a root grid without it) reads with pyproj's
    positions everywhere."""
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.store.schema import LATTICE_SCHEMA_VERSION

    dem = write_geotiff(tmp_path / "g.tif", generate("fbm", 129, seed=3)[:40, :117].copy(),
                        crs="EPSG:4326", origin=(24.0, 61.0), spacing=1 / 1200)
    p = geoterrain.preprocess(dem, tmp_path / "g.geoterrain", tile_size=16)
    with geoterrain.open(p) as t:
        meta, tiles, g = t.meta, t.tile_info, t.grid
    assert meta["schema_version"] == LATTICE_SCHEMA_VERSION == 25
    assert meta["frame"]["lattice"] == list(g.shape) and g.extent != g.shape
    grid, frame = check_store(p, meta, tiles)[:2]
    assert grid == g and frame.lattice == g.shape
    fr = meta["frame"]
    for bad, words in (
            (dict(meta, frame=dict(fr, lattice=[g.shape[0] + 1, g.shape[1]])), "frame.lattice"),
            (dict(meta, frame=dict(fr, lattice=[float(v) for v in g.shape])), "frame.lattice"),
            (dict(meta, frame=dict(fr, lattice=list(g.extent))), "frame.lattice"),
            (dict(meta, frame=dict(fr, lattice=None)), "written in schema version 24, not 25"),
            (dict(meta, frame=dict(fr, lattice="x")), "frame.lattice"),
            (dict(meta, schema_version=ROOTS_SCHEMA_VERSION),
             "a frame with a lattice is written in schema version 25, not 24"),
            ({**meta, "frame": {k: v for k, v in fr.items() if k != "lattice"}},
             "a root grid is written in schema version 24, not 25")):
        with pytest.raises(StoreError, match="invalid metadata") as ex:
            check_store(p, bad, tiles)
        assert words in str(ex.value) and "\n" not in str(ex.value)
    old = {**meta, "frame": {k: v for k, v in fr.items() if k != "lattice"},
           "schema_version": ROOTS_SCHEMA_VERSION}
    assert check_store(p, old, tiles)[1].lattice is None
