"""Chunked LOD's simplified chunks and the reused per-frame selection buffers.

The chunk error is checked by :func:`geoterrain.testing.measure.vertical_error`, which
interpolates the chunk's triangles at every valid full-resolution sample of the
tile's footprint: code independent of the chunk builder.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain import lod
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod.chunks import chunk, chunk_errors
from geoterrain.lod.tiles import tile_index
from geoterrain.testing.measure import screen_space_error, vertical_error


def _store(tmp_path, seed: int, tile: int, hole: bool):
    z = generate("fbm", 129, seed=seed)
    if hole:
        rng = np.random.default_rng(seed)
        i, j = rng.integers(10, 100, 2)
        z[i:i + 17, j:j + 9] = np.nan
    dem = write_geotiff(tmp_path / f"d{seed}{tile}{int(hole)}.tif", z, nodata=np.nan)
    return geoterrain.open(geoterrain.preprocess(dem, tile_size=tile))


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10_000), tile=st.sampled_from([16, 32]), hole=st.booleans())
def test_every_chunk_is_within_its_error(tmp_path, seed, tile, hole):
    t = _store(tmp_path, seed, tile, hole)
    index = tile_index(t)
    err, _ = chunk_errors(index)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    T = t.grid.tile_samples
    for row in range(len(index.keys)):
        L, x, y = (int(v) for v in index.keys[row])
        ch = chunk(t, index, row)
        assert len(ch.faces) <= 2 * (T - 1) ** 2
        if not len(ch.faces):
            continue
        # measure over the tile's footprint only (the chunk covers just that)
        s = 1 << L
        i0, j0 = y * (T - 1) * s, x * (T - 1) * s
        i1, j1 = min(i0 + (T - 1) * s, Z.shape[0] - 1), min(j0 + (T - 1) * s, Z.shape[1] - 1)
        sub = np.zeros_like(valid)
        sub[i0:i1 + 1, j0:j1 + 1] = valid[i0:i1 + 1, j0:j1 + 1]
        ij = ch.ij - [i0, j0]
        zz = Z[i0:i1 + 1, j0:j1 + 1]
        m = vertical_error(ij, ch.faces, ch.xyz[:, 2], zz, sub[i0:i1 + 1, j0:j1 + 1])
        assert m.max <= err[row] + 1e-9, (L, x, y, m.max, err[row])


@pytest.mark.fast
def test_chunks_are_smaller_than_uniform_tiles(tmp_path):
    t = _store(tmp_path, 5, 32, False)
    index = tile_index(t)
    T = t.grid.tile_samples
    coarse = np.flatnonzero(index.keys[:, 0] > 0)
    n = sum(len(chunk(t, index, r).faces) for r in coarse.tolist())
    assert n < 0.6 * len(coarse) * 2 * (T - 1) ** 2


def test_reused_flags_give_the_same_mesh_after_wrapping(tmp_path):
    """The per-frame flags are generation stamps cleared every 255 frames: a view
    selected again after 300 other frames gives the identical mesh."""
    t = _store(tmp_path, 9, 16, True)
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    r = float(np.linalg.norm(hi[:2] - lo[:2]))
    views = []
    for k in range(301):
        az = 2 * np.pi * k / 37
        eye = c + [0.5 * r * np.cos(az), 0.5 * r * np.sin(az), (0.1 + 0.3 * (k % 5) / 4) * r]
        views.append(geoterrain.View(tuple(eye), tuple(c), size=(320, 180)))
    first = lod.select(t, views[0], 1.0, "rtin", reuse=False).mesh
    for v in views[1:]:
        lod.select(t, v, 1.0, "rtin", reuse=False)
    again = lod.select(t, views[0], 1.0, "rtin", reuse=False).mesh
    assert first.n_cells > 0
    np.testing.assert_array_equal(np.asarray(again.points), np.asarray(first.points))
    np.testing.assert_array_equal(np.asarray(again.faces), np.asarray(first.faces))


@pytest.fixture(scope="module")
def oblique_store(tmp_path_factory):
    """A 513² fbm store with 32² tiles: five levels of chunks, so views draw skirts."""
    d = tmp_path_factory.mktemp("oblique")
    dem = write_geotiff(d / "fbm.tif", generate("fbm", 513, seed=3))
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32))
    return t, t.scene_xyz()


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(u=st.floats(0, 1), w=st.floats(0, 1), az=st.floats(0, 2 * np.pi),
       dist=st.floats(0.1, 0.5), pitch=st.floats(3, 60), morph=st.booleans())
def test_oblique_views_keep_the_bound_and_the_counts(oblique_store, u, w, az, dist, pitch,
                                                     morph):
    """The views of benchmarks/bench_chunked.py (a target anywhere, 0.1–0.5 of the extent
    away, pitch 3–60°): ρ ≤ τ at every sample in the frustum (independent measure), none
    uncovered; the triangle counts and elevations the assembly fills in are what the
    mesh holds (a pass over it would give the same)."""
    t, (X, Y, Z) = oblique_store
    lo, hi = t.scene_box()
    ext = float(max(hi[:2] - lo[:2]))
    at = np.array([lo[0] + u * (hi[0] - lo[0]), lo[1] + w * (hi[1] - lo[1]),
                   0.5 * (lo[2] + hi[2])])
    p = np.radians(pitch)
    eye = at + dist * ext * np.array([np.cos(p) * np.cos(az), np.cos(p) * np.sin(az), np.sin(p)])
    eye[2] = max(eye[2], hi[2] + 0.002 * ext)
    view = geoterrain.View(tuple(eye), tuple(at), size=(640, 360))
    sel = t.select(view, 1.0, "chunked", reuse=False, occlusion=False, morph=morph)
    skirt = np.asarray(sel.mesh.cell_data["skirt"])
    assert sel.stats["triangles"] == int((skirt == 0).sum())
    assert sel.stats["skirt_triangles"] == int((skirt == 1).sum())
    assert "elevated" not in sel.stats
    z = np.asarray(sel.mesh.points)[:, 2]
    want = np.empty(len(z), np.float32)
    np.multiply(z, 1.0 / t.frame.z_scale, out=want, casting="unsafe")
    np.testing.assert_array_equal(np.asarray(sel.mesh.point_data["elevation"]), want)
    assert sel.mesh.active_scalars_name == "elevation"
    e = screen_space_error(sel.ij, sel.surface_faces(), z, X, Y, Z, np.isfinite(Z), view.eye,
                           view.planes, view.lam)
    assert e.max <= 1.0 + 1e-9 and e.n_uncovered == 0, (e, sel.stats)
