"""GeoMipMapping stitching templates and the restricted quadtree (seeds 000 §2.4, 003).

The strategies' ρ ≤ τ (bounded ones), conformity and coverage run in test_lod.py and
test_stress.py, which take the strategy list and its promises from the registry.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoterrain.lod.geomipmap import strip_bounds, template
from geoterrain.lod.quadtree import paint as _paint
from geoterrain.lod.quadtree import restrict_leaves as _restrict


def _area(local: np.ndarray, f: np.ndarray) -> float:
    p = local[f].astype(float)
    return float(0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                              - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])).sum())


@pytest.mark.fast
def test_stitch_templates_tile_the_block_and_keep_only_coarse_edge_vertices():
    for K in (2, 4, 8):
        a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
        local = np.stack([a.ravel(), b.ravel()], 1)
        rs = [r for r in (1, 2, 4, 8) if r <= K]
        for ratios in itertools.product(rs, repeat=4):
            f = template(K, ratios)
            assert _area(local, f) == K * K, (K, ratios)  # no hole, no overlap
            e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
            _, cnt = np.unique(e, axis=0, return_counts=True)
            assert cnt.max() <= 2
            used = np.zeros(len(local), bool)
            used[f] = True
            for q, (i, j) in enumerate([(a[0], b[0]), (a[K], b[K]),
                                        (a[:, 0], b[:, 0]), (a[:, K], b[:, K])]):
                along = j if q < 2 else i
                on = used[i * (K + 1) + j]
                assert (on == (along % ratios[q] == 0)).all(), (K, ratios, q)


@pytest.mark.fast
def test_strip_bounds_bound_each_segment():
    """r ≥ 4: the segment's height range (rows 0–1 over r + 1 columns); r = 2: the
    largest distance of an omitted edge vertex from its neighbours' midpoint; inf where a
    segment holds no-data."""
    rng = np.random.default_rng(0)
    Z = rng.random((3, 9, 9))
    B = strip_bounds(Z, 4)
    for r, k in ((4, 2), (8, 3)):
        want = max(np.ptp(Z[:, 0:2, u:u + r + 1], axis=(1, 2)).max() for u in range(0, 8, r))
        assert B[:, 0, k].max() == want
    want = np.abs(Z[:, 0, 1::2] - 0.5 * (Z[:, 0, 0:-1:2] + Z[:, 0, 2::2])).max(1)
    assert np.allclose(B[:, 0, 1], want)
    Z[1, 0, 3] = np.nan
    assert np.isinf(strip_bounds(Z, 4)[1, 0, 1]) and np.isfinite(strip_bounds(Z, 4)[0, 0, 1])


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.sampled_from([2, 4, 8, 16]), st.integers(0, 3),
       st.sampled_from([2, 4]))
def test_a_stitched_strip_moves_the_surface_by_at_most_its_bound(seed, K, e, r):
    """Rasterised on a 4× finer lattice, the block stitched at ratio r on edge e differs
    from its plain union-jack surface by at most strip_bounds' B (and at r = 2 by exactly
    B: the bound is attained at the omitted vertex)."""
    from geoterrain.testing.measure import mesh_heights_on_grid

    if r > K:
        return
    Z = np.random.default_rng(seed).normal(0, 10, (1, K + 1, K + 1))
    a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
    ij = np.stack([a.ravel() * 4, b.ravel() * 4], 1)
    shape = (4 * K + 1, 4 * K + 1)
    ratios = tuple(r if q == e else 1 for q in range(4))
    h0, ok0 = mesh_heights_on_grid(ij, template(K, (1, 1, 1, 1)), Z.ravel(), shape)
    h1, ok1 = mesh_heights_on_grid(ij, template(K, ratios), Z.ravel(), shape)
    assert ok0.all() and ok1.all()
    B = strip_bounds(Z, int(K).bit_length())[0, e, r.bit_length() - 1]
    diff = np.abs(h1 - h0).max()
    assert diff <= B * (1 + 1e-9) + 1e-9
    if r == 2:
        assert diff >= B * (1 - 1e-9) - 1e-9


@pytest.mark.fast
@given(st.lists(st.tuples(st.integers(0, 4), st.floats(0, 1), st.floats(0, 1)), max_size=6))
def test_restricted_quadtree_levels_differ_by_at_most_one(points):
    # random quadtree: split the leaf under each point down to the given depth
    leaves = {(0, 0, 0)}
    for depth, u, v in points:
        for k in range(depth):
            x, y = int(u * (1 << k)), int(v * (1 << k))
            if (k, x, y) in leaves:
                leaves.remove((k, x, y))
                leaves |= {(k + 1, 2 * x + dx, 2 * y + dy) for dx in (0, 1) for dy in (0, 1)}
    by = {}
    for k, x, y in leaves:
        by.setdefault(k, []).append((x, y))
    lv = [(k, np.array([p[0] for p in v]), np.array([p[1] for p in v])) for k, v in by.items()]
    out, D, dmax = _restrict(lv)
    assert (D >= 0).all()  # the leaves still tile the whole square
    assert np.abs(np.diff(D, axis=0)).max(initial=0) <= 1
    assert np.abs(np.diff(D, axis=1)).max(initial=0) <= 1
    assert (D >= _paint(lv, dmax)).all()  # only ever refined


def _mixes(faces: np.ndarray, K: int, step: int, ok: np.ndarray) -> bool:
    """Whether a triangle of ``faces`` (indices into a (K+1)² vertex grid of spacing
    ``step`` samples) holds, in its closed area, both samples where ``ok`` and not."""
    a, b = np.divmod(faces, K + 1)  # vertex (row, col) on the block's level grid
    ii, jj = np.indices(ok.shape)
    for (a0, a1, a2), (b0, b1, b2) in zip(a * step, b * step, strict=True):
        det = (a1 - a0) * (b2 - b0) - (a2 - a0) * (b1 - b0)
        u = ((ii - a0) * (b2 - b0) - (a2 - a0) * (jj - b0)) / det
        v = ((a1 - a0) * (jj - b0) - (ii - a0) * (b1 - b0)) / det
        inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9)
        if ok[inside].any() and not ok[inside].all():
            return True
    return False


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), size=st.sampled_from([33, 65, 50]),
       tile=st.sampled_from([4, 8, 16]), holes=st.booleans())
def test_stored_block_delta_is_each_blocks_exact_error(tmp_path, seed, size, tile, holes):
    """Seed 000 §2.4's δ_n, stored per block at preprocess: for every block and level n,
    the table holds the largest |z − mesh| over the block's samples of the block drawn
    alone at geomipmap n (rasterised by geoterrain.testing.measure, not by the selection code),
    rounded up to float32; +inf exactly where a level-n triangle of the block mixes data
    and nodata (then some of its samples are nodata)."""
    import geoterrain
    from geoterrain.ingest.synth import generate
    from geoterrain.lod.geomipmap import _assemble
    from geoterrain.lod.tiles import tile_index
    from geoterrain.testing.measure import mesh_heights_on_grid
    from tests.conftest import write_tif

    z = generate("fbm", size, seed=seed).astype(np.float32)
    if holes:
        rng = np.random.default_rng(seed)
        for _ in range(3):
            i, j = rng.integers(0, size, 2)
            z[i:i + rng.integers(1, 9), j:j + rng.integers(1, 9)] = -9999.0
    src = write_tif(tmp_path / f"d{seed}_{size}_{tile}_{holes}.tif", z, nodata=-9999.0)
    with geoterrain.open(geoterrain.preprocess(src, tmp_path / f"s{seed}_{size}_{tile}"
                                               f"_{holes}.geoterrain", tile_size=tile,
                                               overwrite=True, root_grid=False)) as t:
        table = t.block_errors()
        g = t.grid
        assert table is not None and table.shape[2] == min(g.t, g.top_level) + 1
        _, _, Z0 = t.scene_xyz()
        Z = np.full((g.size, g.size), np.nan)  # the padding (past the DEM) is nodata
        Z[:Z0.shape[0], :Z0.shape[1]] = Z0
        index = tile_index(t)
        blocks = np.flatnonzero(index.keys[:, 0] == 0)
        xy = index.keys[blocks, 1:]
        s = 1 << g.t
        tol = 1e-9 * (1.0 + np.nanmax(np.abs(Z)))
        for n in range(table.shape[2]):
            mesh = _assemble(t, index, xy, np.full(len(xy), n), np.ones((len(xy), 4), int))
            zm, cov = mesh_heights_on_grid(np.asarray(mesh.point_data["grid_ij"]),
                                           mesh.regular_faces, np.asarray(mesh.points)[:, 2],
                                           Z.shape)
            for (bx, by) in xy.tolist():
                win = np.s_[by * s: by * s + s + 1, bx * s: bx * s + s + 1]
                zb, cb = Z[win], cov[win]
                stored = table[by, bx, n]
                if n == 0:
                    assert stored == 0.0
                    continue
                # +inf exactly where a closed level-n triangle of the block mixes data
                # and nodata (the block's own template, rasterised here)
                K = 1 << (g.t - n)
                par = ((bx ^ by) & 1) if n == g.t else 0
                assert np.isinf(stored) == _mixes(template(K, (1, 1, 1, 1), par), K, 1 << n,
                                                  np.isfinite(zb))
                if np.isinf(stored):
                    continue
                ok = np.isfinite(zb)
                assert cb[ok].all()  # every sample of data lies on a drawn triangle
                err = float(np.abs(zb[ok] - zm[win][ok]).max()) if ok.any() else 0.0
                assert err - tol <= stored <= err * (1 + 2.0 ** -22) + tol


@pytest.mark.fast
def test_a_damaged_block_table_is_refused_in_one_line(tmp_path):
    """The block δ_n table comes from a file that may come from a stranger: a table
    that decodes to NaN (under a valid checksum) or to too few values is refused in one
    line when geomipmap reads it, and a store without one uses the covering tiles."""
    import sqlite3

    import zstandard

    import geoterrain
    from geoterrain.core.view import View
    from geoterrain.exceptions import StoreCorruptError
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.store.schema import blob_crc
    from tests.store.storesql import read_meta, remove_blob, update_blob, write_meta

    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 65, seed=4))
    p = geoterrain.preprocess(dem, tmp_path / "d.geoterrain", tile_size=16)
    view = View((0, -900, 500), (0, 0, 0))
    with geoterrain.open(p) as t:
        key = (t.grid.top_level, 0, 0)
        shape = t.block_errors().shape
        good = t.select(view, 2.0, strategy="geomipmap").mesh.n_cells
    for bad in (np.full(shape, np.nan, "<f4"), np.zeros(shape[0], "<f4")):
        data = zstandard.ZstdCompressor().compress(bad.tobytes())
        con = sqlite3.connect(p)
        update_blob(con, (*key, "block_delta"), data=data,
                    crc32=blob_crc(key, "block_delta", data))
        con.commit()
        con.close()
        with geoterrain.open(p) as t, pytest.raises(StoreCorruptError, match="block") as ex:
            t.select(view, 2.0, strategy="geomipmap")
        assert "\n" not in str(ex.value)
    # an older store: no table (its blob and metadata key gone, the metadata checksum
    # made consistent): it opens, and geomipmap takes the covering tiles' bound
    con = sqlite3.connect(p)
    remove_blob(con, (*key, "block_delta"))
    meta = read_meta(con)
    del meta["block_delta_levels"]
    write_meta(con, meta)
    con.commit()
    con.close()
    with geoterrain.open(p) as t:
        assert t.block_errors() is None
        assert t.select(view, 2.0, strategy="geomipmap").mesh.n_cells >= good
