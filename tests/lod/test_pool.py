"""The tile pool: per-tile arrays loaded once, evicted under a budget, never wrong."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain import lod
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import pool as pool_mod

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def _views(t, n=6):
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    r = float(np.linalg.norm(hi[:2] - lo[:2]))
    out = []
    for k in range(n):
        az = 2 * np.pi * k / n
        eye = c + [0.6 * r * np.cos(az), 0.6 * r * np.sin(az), 0.3 * r]
        out.append(geoterrain.View(tuple(eye), tuple(c), size=(640, 360)))
    return out


def test_a_tiny_pool_gives_the_same_meshes(tmp_path):
    dem = write_geotiff(tmp_path / "d.tif", generate("fbm", 257, seed=11))
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=16))
    views = _views(t)
    ref = [lod.select(t, v, 1.0, "rtin", reuse=False).mesh for v in views]
    ref_static = lod.static(t, 2.0).mesh
    big = pool_mod.tile_pool(t)
    assert big.capacity >= 100  # the default budget holds every tile touched
    small = pool_mod.TilePool(t, budget_bytes=1)  # 16 slots: evicts on every request
    t.forget("geoterrain.lod.pool")  # the next selections take this pool
    assert t.derived("geoterrain.lod.pool", lambda: small) is small
    for v, m in zip(views, ref, strict=True):
        got = lod.select(t, v, 1.0, "rtin", reuse=False).mesh
        np.testing.assert_array_equal(np.asarray(got.points), np.asarray(m.points))
        np.testing.assert_array_equal(np.asarray(got.faces), np.asarray(m.faces))
    got = lod.static(t, 2.0).mesh
    np.testing.assert_array_equal(np.asarray(got.faces), np.asarray(ref_static.faces))
    # it only grew beyond its budget for a request that needed more tiles at once
    assert small.capacity < big.capacity
    held = small.key_of[small.key_of >= 0]
    assert len(np.unique(held)) == len(held)  # no tile in two slots
    assert (small.slot_of[held] == np.flatnonzero(small.key_of >= 0)).all()
