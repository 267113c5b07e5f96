"""GPU Terrain Rendering (``gtr``, ``gtr_bounded``) and Lauritsen & Nielsen's hybrid:
the blocks' morph targets, eq. 5-2's δ_b, the thesis's switch distances, and skirts that
close every crack.

Surfaces are measured with :mod:`geoterrain.testing.measure` (grid rasterisation) against
triangles written here from the conventions, independently of the strategies' code.
ρ ≤ τ for the bounded ones over random views is also checked by tests/lod/test_lod.py and
tests/test_stress.py, which take the strategies from the registry.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod.gtrtree import block_errors, coarse_target
from geoterrain.lod.tiles import tile_index
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    mesh_heights_on_grid,
    screen_space_error,
    vertical_error,
)


@pytest.fixture(scope="module")
def rough(tmp_path_factory):
    """A 300 × 280 fBm with a nodata hole: padded to 513², 17² tiles, five levels."""
    d = tmp_path_factory.mktemp("gtr")
    z = generate("fbm", (300, 280), seed=3).astype(np.float32) * 3
    yy, xx = np.mgrid[:300, :280]
    z[(yy - 150) ** 2 + (xx - 60) ** 2 < 300] = np.nan
    dem = write_geotiff(d / "rough.tif", z, nodata=np.nan)
    return geoterrain.open(geoterrain.preprocess(dem, d / "rough.geoterrain", tile_size=16,
                                                 root_grid=False))


def union_jack(ij: np.ndarray, s: int) -> np.ndarray:
    """Triangles of the level surface of spacing ``s`` over the samples ``ij`` (K, K, 2),
    written from docs/conventions.md: in each cell the diagonal joins the corner whose
    row/s and column/s are both odd to the opposite corner."""
    K = ij.shape[0]
    idx = np.arange(K * K).reshape(K, K)
    faces = []
    for a in range(K - 1):
        for b in range(K - 1):
            r, c = ij[a, b] // s
            v00, v01, v10, v11 = idx[a, b], idx[a, b + 1], idx[a + 1, b], idx[a + 1, b + 1]
            if (r % 2) == (c % 2):  # the odd/odd corner is (r, c) or (r+1, c+1)
                faces += [(v00, v01, v11), (v00, v10, v11)]
            else:
                faces += [(v00, v01, v10), (v01, v10, v11)]
    return np.array(faces)


def _tile_ij(t, L, x, y):
    g = t.grid
    ii, jj = np.meshgrid(g.tile_rows(L, y), g.tile_cols(L, x), indexing="ij")
    return np.stack([ii, jj], -1)


@pytest.mark.fast
def test_coarse_target_is_the_parent_surface(rough):
    """Every sample's target is the next level's union-jack surface at that sample."""
    g = rough.grid
    rng = np.random.default_rng(0)
    keys = [k for k in rough.tile_keys() if k[0] < g.top_level]
    for L, x, y in [keys[i] for i in rng.choice(len(keys), 12, replace=False)]:
        z = rough.frame.z(rough.tile(L, x, y).heights)
        got = coarse_target(z, x, y, g.t)
        ij = _tile_ij(rough, L, x, y)
        # the parent level's samples of this footprint, and their triangles
        pij = ij[::2, ::2].reshape(-1, 2)
        f = union_jack(ij[::2, ::2], 1 << (L + 1))
        pz = z[::2, ::2].ravel()
        ok = np.isfinite(pz)
        f = f[ok[f].all(1)]
        off = ij[0, 0]
        want, covered = mesh_heights_on_grid(pij - off, f, pz, (ij[-1, -1] - off) + 1)
        a = ij[..., 0] - off[0]
        b = ij[..., 1] - off[1]
        w = want[a, b]
        sel = np.isfinite(got) & covered[a, b]
        np.testing.assert_allclose(got[sel], w[sel], rtol=0, atol=1e-9)


@pytest.mark.fast
def test_delta_b_follows_eq_5_2_and_bounds_every_block(rough):
    """δ_b = max(children) + δ_m (eq. 5-2), and no full-resolution sample of a block's
    footprint is farther than δ_b from the block's surface."""
    be = block_errors(rough)
    index = tile_index(rough)
    g = rough.grid
    X, Y, Z = rough.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    for row in range(len(index.keys)):
        L, x, y = (int(v) for v in index.keys[row])
        kids = [index.row.get((L - 1, 2 * x + dx, 2 * y + dy), -1)
                for dx in (0, 1) for dy in (0, 1)] if L else []
        kids = [k for k in kids if k >= 0]
        if L == 0:
            assert be.delta_b[row] == 0.0
            continue
        if not np.isfinite(be.delta_b[row]):
            assert not np.isfinite(index.error[row])
            continue
        want = max(be.delta_b[k] for k in kids) + max(be.delta_m[k] for k in kids)
        assert be.delta_b[row] == pytest.approx(want, rel=1e-12)
        # the block's uniform surface against every sample of its footprint
        ij = _tile_ij(rough, L, x, y)
        K = ij.shape[0]
        z = rough.frame.z(rough.tile(L, x, y).heights).ravel()
        f = union_jack(ij, 1 << L)
        f = f[np.isfinite(z)[f].all(1)]
        s = 1 << (g.t + L)
        i0, j0 = y * s, x * s
        sub = valid[i0:i0 + s + 1, j0:j0 + s + 1]
        e = vertical_error(ij.reshape(-1, 2) - [i0, j0], f, np.nan_to_num(z),
                           Zt[i0:i0 + s + 1, j0:j0 + s + 1], sub)
        assert e.max <= be.delta_b[row] * (1 + 1e-9) + 1e-9, (L, x, y, K)
        assert be.delta_b[row] >= index.error[row] - 1e-6  # never below the exact error


def _views(t, n, seed):
    X, Y, Z = t.scene_xyz()
    ok = np.isfinite(Z)
    lo = np.array([X[ok].min(), Y[ok].min(), Z[ok].min()])
    hi = np.array([X[ok].max(), Y[ok].max(), Z[ok].max()])
    c, r = 0.5 * (lo + hi), float(np.linalg.norm(hi[:2] - lo[:2]))
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(0.03, 1.2)
        d = r * rng.uniform(0.1, 1.2)
        eye = c + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        at = c + rng.normal(0, 0.2 * r, 3) * [1, 1, 0]
        out.append(View(tuple(eye), tuple(at), size=(640, 360), fov_y_deg=40))
    return out


def _hanging_below(sel, Z) -> bool:
    """Every skirt's hanging vertex lies below the lowest surface any block draws at its
    sample: a step between neighbours never shows a gap."""
    if not len(sel.faces):
        return True
    skirt = np.asarray(sel.mesh.cell_data["skirt"]) == 1
    z = np.asarray(sel.mesh.points)[:, 2]
    f = sel.surface_faces()
    lo, _ = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
    hanging = np.setdiff1d(sel.faces[skirt].ravel(), f.ravel())
    if not len(hanging):
        return True
    ij = np.asarray(sel.ij, np.int64)[hanging]
    under = lo[ij[:, 0], ij[:, 1]]
    ok = np.isfinite(under)
    return bool((z[hanging][ok] <= under[ok] + 1e-9).all())


@pytest.mark.fast
@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10**6), tau=st.sampled_from([1.0, 4.0, 8.0]),
       strategy=st.sampled_from(["gtr", "gtr_bounded", "lauritsen_nielsen"]),
       morph=st.booleans())
def test_skirts_close_every_crack_and_the_bounded_keep_tau(rough, seed, tau, strategy, morph):
    X, Y, Z = rough.scene_xyz()
    valid = np.isfinite(Z)
    view = _views(rough, 1, seed)[0]
    sel = rough.select(view, tau, strategy, reuse=False, occlusion=False, morph=morph)
    assert _hanging_below(sel, Z)
    f = sel.surface_faces()
    if strategy != "gtr" and len(f):
        e = screen_space_error(sel.ij, f, np.asarray(sel.mesh.points)[:, 2], X, Y,
                               np.where(valid, Z, 0.0), valid, view.eye, view.planes, view.lam)
        assert e.max <= tau * (1 + 1e-9), (strategy, morph, e.max)


@pytest.mark.fast
def test_gtr_accepts_a_block_at_its_switch_distance(rough):
    """The thesis's rule: each drawn block above level 0 is at least D_n = δ_b·λ/τ from the
    eye (to its centre), and its parent, refined, was nearer than its own D_n."""
    index = tile_index(rough)
    be = block_errors(rough)
    for view in _views(rough, 4, 1):
        tau = 4.0
        sel = rough.select(view, tau, "gtr", reuse=False, occlusion=False, morph=False)
        C = view.lam / tau
        lv = np.asarray(sel.mesh.cell_data["level"])
        ij = np.asarray(sel.ij, np.int64)
        f = sel.surface_faces()
        sk = np.asarray(sel.mesh.cell_data["skirt"]) == 0
        s = (1 << (rough.grid.t + lv[sk])).astype(np.int64)
        corner = ij[f].min(1)  # a triangle's block: its cell's tile at its level
        keys = {(int(L), int(c[1] // q), int(c[0] // q))
                for L, c, q in zip(lv[sk], corner, s, strict=True)}
        for key in keys:
            row = index.row[key]
            d = np.linalg.norm(0.5 * (index.lo[row] + index.hi[row]) - view.eye)
            assert d >= be.delta_b[row] * C * (1 - 1e-12)
            p = be.parent[row]
            if p >= 0:
                dp = np.linalg.norm(0.5 * (index.lo[p] + index.hi[p]) - view.eye)
                assert dp < be.delta_b[p] * C


@pytest.mark.fast
def test_a_fully_morphed_block_draws_its_parent(rough):
    """At t = 1 a block's vanishing vertices lie on its parent's surface (eq. 5-6)."""
    from geoterrain.lod.gtrtree import block_mesh

    index = tile_index(rough)
    g = rough.grid
    rows = np.flatnonzero((index.keys[:, 0] == 1) & np.isfinite(index.error))[:3]
    mesh = block_mesh(rough, index, rows, np.ones(len(rows)), np.zeros(len(rows)))
    ij = np.asarray(mesh.point_data["grid_ij"], np.int64)
    z = np.asarray(mesh.points)[:, 2]
    for row in rows.tolist():
        L, x, y = (int(v) for v in index.keys[row])
        pij = _tile_ij(rough, L, x, y)[::2, ::2]
        pz = rough.frame.z(rough.tile(L, x, y).heights)[::2, ::2].ravel()
        f = union_jack(pij, 1 << (L + 1))
        want, cov = mesh_heights_on_grid(pij.reshape(-1, 2), f, pz, (g.size, g.size))
        s = 1 << (g.t + L)
        inside = ((ij[:, 0] >= y * s) & (ij[:, 0] <= (y + 1) * s)
                  & (ij[:, 1] >= x * s) & (ij[:, 1] <= (x + 1) * s))
        w = want[ij[inside, 0], ij[inside, 1]]
        np.testing.assert_allclose(z[inside], w, rtol=0, atol=1e-9)
