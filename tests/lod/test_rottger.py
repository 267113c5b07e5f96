"""Röttger's quadtree (``rottger``): eq. 4-4's roughness, eq. 4-6's propagation, eq. 4-5's
subdivision, and the bound pass. ρ ≤ τ and conformity over random views are checked by
tests/lod/test_lod.py and tests/test_stress.py (from the registry)."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import rottger


@pytest.fixture(scope="module")
def rough(tmp_path_factory):
    d = tmp_path_factory.mktemp("rottger")
    z = generate("fbm", (120, 129), seed=6).astype(np.float32) * 3
    z[40:50, 60:75] = np.nan
    dem = write_geotiff(d / "r.tif", z, nodata=np.nan)
    return geoterrain.open(geoterrain.preprocess(dem, d / "r.geoterrain", tile_size=16))


@pytest.mark.fast
def test_roughness_is_eq_4_4_propagated_by_eq_4_6(rough):
    tb = rottger.tables(rough)
    Z = tb.Z
    n = tb.n
    K = rottger.C_MIN / (2 * (rottger.C_MIN - 1))
    rng = np.random.default_rng(2)
    for k in (n - 1, n - 2, n - 4):
        h = 1 << (n - k - 1)
        M = 1 << k
        for _ in range(30):
            y, x = (int(v) for v in rng.integers(0, M, 2))
            ci, cj = (2 * y + 1) * h, (2 * x + 1) * h
            win = Z[ci - h:ci + h + 1, cj - h:cj + h + 1]
            if np.isnan(win).any():
                assert np.isnan(win).all() or tb.d2[k][y, x] == np.inf
                continue
            w = win[::h, ::h]  # the node's 3 × 3: corners, edge midpoints, centre

            def z(a, b, w=w):
                return w[1 + a, 1 + b]

            dh = [abs(z(-1, 0) - (z(-1, -1) + z(-1, 1)) / 2),
                  abs(z(1, 0) - (z(1, -1) + z(1, 1)) / 2),
                  abs(z(0, -1) - (z(-1, -1) + z(1, -1)) / 2),
                  abs(z(0, 1) - (z(-1, 1) + z(1, 1)) / 2),
                  abs(z(0, 0) - (z(-1, -1) + z(1, 1)) / 2),
                  abs(z(0, 0) - (z(-1, 1) + z(1, -1)) / 2)]
            local = max(dh) / (2 * h * tb.dx)
            assert tb.d2[k][y, x] >= local * (1 - 1e-12)
            if k < n - 1:  # ≥ K × every finer node inside or across its edges
                F = tb.d2[k + 1]
                a0, b0 = 2 * y, 2 * x
                cells = [(a0 + a, b0 + b) for a in (0, 1) for b in (0, 1)]  # children
                cells += [(a0 - 1, b0), (a0 - 1, b0 + 1), (a0 + 2, b0), (a0 + 2, b0 + 1),
                          (a0, b0 - 1), (a0 + 1, b0 - 1), (a0, b0 + 2), (a0 + 1, b0 + 2)]
                adj = max(F[a, b] for a, b in cells if 0 <= a < 2 * M and 0 <= b < 2 * M)
                assert tb.d2[k][y, x] >= K * adj * (1 - 1e-12)


@pytest.mark.fast
def test_the_seed_rule_and_the_bound_pass(rough):
    lo, hi = rough.scene_box()
    c = 0.5 * (lo + hi)
    for tau in (1.0, 8.0):
        view = View(tuple(c + [0.0, -6 * (hi[1] - lo[1]), 3 * (hi[1] - lo[1])]), tuple(c),
                    size=(640, 360))
        sel = rough.select(view, tau, "rottger", reuse=False, occlusion=False)
        st = sel.stats
        assert st["leaves"] >= st["seed_leaves"] and st["triangles"] > 0
        # the bound pass only adds detail: a larger τ never draws more
    fine = rough.select(view, 1.0, "rottger", reuse=False).stats["triangles"]
    coarse = rough.select(view, 8.0, "rottger", reuse=False).stats["triangles"]
    assert coarse < fine


@pytest.mark.fast
def test_the_eq_4_7_blend_moves_vertices_within_the_bound(rough):
    """With ``morph`` the leaves' new vertices slide towards the parent's surface (each
    by at most its δ) where the bound allows; the measured ρ stays ≤ τ."""
    from geoterrain.testing.measure import screen_space_error

    X, Y, Z = rough.scene_xyz()
    valid = np.isfinite(Z)
    lo, hi = rough.scene_box()
    c = 0.5 * (lo + hi)
    w = float(hi[1] - lo[1])
    moved = 0
    for k, tau in enumerate((1.0, 4.0, 16.0)):
        view = View(tuple(c + [0.1 * k * w, -1.2 * w, 0.5 * w]), tuple(c), size=(640, 360))
        still = rough.select(view, tau, "rottger", reuse=False, occlusion=False, morph=False)
        sel = rough.select(view, tau, "rottger", reuse=False, occlusion=False, morph=True)
        assert sel.stats["triangles"] == still.stats["triangles"]
        moved += sel.stats["morphing_vertices"]
        z = np.asarray(sel.mesh.points)[:, 2]
        z0 = np.asarray(still.mesh.points)[:, 2]
        ij = sel.ij.astype(np.int64)
        delta = rottger.tables(rough).delta[ij[:, 0], ij[:, 1]]
        assert (np.abs(z - z0) <= delta + 1e-9).all()
        e = screen_space_error(sel.ij, sel.surface_faces(), z, X, Y, np.where(valid, Z, 0.0),
                               valid, view.eye, view.planes, view.lam)
        assert e.max <= tau * (1 + 1e-9)
    assert moved > 0
