"""Invariants of the bounds as stored (after float16 rounding) on real and synthetic DEMs."""

import numpy as np
import pytest

import geoterrain
from geoterrain.core.bintree import vertex_children, vertex_depth, vertex_parents
from tests.conftest import REAL_DEMS, real_dem


def _level0(t, kind):
    """Full-resolution array of stored δ or r, each vertex read from every tile holding it
    (coarse levels last): stored tiles at any level must agree on shared vertices."""
    g = t.grid
    out = np.zeros((g.size, g.size), np.float32)
    for (L, x, y) in sorted(t.tile_info):
        a = t.tile_delta(L, x, y) if kind == "delta" else t.tile_radius(L, x, y)
        rows, cols = g.tile_rows(L, y), g.tile_cols(L, x)
        prev = out[np.ix_(rows, cols)]
        written = prev != 0
        assert (prev[written & (a != 0)] == a[written & (a != 0)]).all()
        out[np.ix_(rows, cols)] = np.where(a != 0, a, prev)
    return out


@pytest.mark.parametrize("name", REAL_DEMS)
def test_saturation_and_nesting_of_stored_bounds(tmp_path, name):
    t = geoterrain.open(geoterrain.preprocess(real_dem(name), tmp_path / "s.geoterrain",
                                              root_grid=False))  # the square's arrays
    g = t.grid
    delta, radius = _level0(t, "delta"), _level0(t, "radius")
    X, Y, Z = t.scene_xyz()
    i, j = np.nonzero(np.ones((g.size, g.size), bool))
    d = vertex_depth(i, j, g.n)
    keep = d >= 0
    i, j = i[keep], j[keep]
    par = vertex_parents(i, j, g.n)  # (V, 2, 2)
    for p in range(2):
        pi, pj = par[:, p, 0], par[:, p, 1]
        ok = pi >= 0
        ok[ok] &= vertex_depth(pi[ok], pj[ok], g.n) >= 0  # corners are never split
        # saturation: δ(parent) ≥ δ(child), also after rounding to the stored float16
        assert (delta[pi[ok], pj[ok]] >= delta[i[ok], j[ok]]).all()
    ch = vertex_children(i, j, g.n)  # (V, 4, 2)
    Xp, Yp = t.frame.grid_xy(g.size)
    h, _ = t.level_heights(0)
    Zp = np.where(np.isfinite(h), t.frame.z(h), np.nan)
    for c in range(4):
        ci, cj = ch[:, c, 0], ch[:, c, 1]
        ok = (ci >= 0) & np.isfinite(Zp[i, j])
        ok[ok] &= np.isfinite(Zp[ci[ok], cj[ok]])
        a, b = (i[ok], j[ok]), (ci[ok], cj[ok])
        dist = np.sqrt((Xp[a] - Xp[b]) ** 2 + (Yp[a] - Yp[b]) ** 2 + (Zp[a] - Zp[b]) ** 2)
        # nesting between valid vertices, r(v) ≥ |p_v − p_c| + r(c), on the stored values
        # themselves (the codes are nested after rounding: tileblobs.radius_codes)
        assert (radius[a] >= (dist + radius[b]) * (1 - 1e-12)).all()


@pytest.mark.fast
def test_coarse_tile_reads_no_finer_data(tmp_path):
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=4))
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "s.geoterrain", tile_size=16))
    reads = []
    orig = t.reader.get_blob_version  # every blob read goes through it (get_blob too)
    t.reader.get_blob_version = lambda key, kind, version=True: (
        reads.append((key, kind)), orig(key, kind, version))[1]
    L = t.grid.top_level - 1
    t.tile(L, 1, 0)
    assert {k for k, _ in reads} == {(L, 1, 0), (L + 1, 0, 0)}
    assert all(k[0] >= L for k, _ in reads)
    reads.clear()
    t.tile(0, 5, 7)  # a finest tile reads exactly itself and its ancestors
    assert {k for k, _ in reads} <= {(0, 5, 7), *t.grid.ancestors(0, 5, 7)}
