"""Geomorphing of rtin (seed 002 §2.10): the band keeps ρ ≤ τ, heights follow eq. 3–4
with the cascade, morph invariants T17–T19, no crack while morphing, and no pop.

The morph factors are recomputed here from the stored δ and r (``Terrain.tile_delta``,
``tile_radius``), not read from the selection.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import write_tif
from geoterrain.bench.harness import extent, glide
from geoterrain.core.view import View
from geoterrain.lod import rtin
from geoterrain.lod.morph import MORPH_START, edge_ends
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    screen_space_change,
    screen_space_error,
)
from tests.lod.test_lod import check_conforming


def _fbm(n: int, seed: int, amp: float) -> np.ndarray:
    from geoterrain.ingest.synth import generate

    z = generate("fbm", (n, n), seed=seed)
    return amp * (z - z.min()) / max(float(np.ptp(z)), 1e-12)


@pytest.fixture(scope="module")
def rough(tmp_path_factory):
    d = tmp_path_factory.mktemp("morph")
    z = _fbm(129, 5, 400.0)
    z[90:110, 10:30] = -9999.0  # a nodata hole: its border vertices never morph
    src = write_tif(d / "m.tif", z, spacing=10.0, nodata=-9999.0)
    return geoterrain.open(geoterrain.preprocess(src, d / "m.geoterrain", tile_size=16))


def _views(t, n, seed):
    X, Y, Z = t.scene_xyz()
    ok = np.isfinite(Z)
    rng = np.random.default_rng(seed)
    c = np.array([X[ok].mean(), Y[ok].mean(), np.nanmean(Z)])
    ext = float(np.ptp(X[ok]))
    out = []
    for _ in range(n):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(0.15, 1.2)
        dist = ext * rng.uniform(0.3, 1.5)
        eye = c + dist * np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
        out.append(View(tuple(eye), tuple(c + rng.normal(0, 0.1 * ext, 3)), size=(480, 270)))
    return out


def _t_of(t, ij, view, tau):
    """Eq. 3 from the stored δ and r at each vertex (1 where δ is infinite or the eye is
    in the sphere), ρ by rtin's metric (:data:`geoterrain.lod.rtin.DEPTH`), and each
    vertex's true scene height."""
    g = t.grid
    S = 1 << g.t
    X, Y, Z = t.scene_xyz()
    out, zt = np.ones(len(ij)), np.empty(len(ij))
    for v, (i, j) in enumerate(np.asarray(ij, np.int64)):
        low = int(i) | int(j)
        L = 0
        while low and not low & (1 << L) and L < g.top_level:
            L += 1
        if low == 0:
            L = g.top_level
        L = min(L, g.top_level)
        li, lj = i >> L, j >> L
        last = (1 << (g.top_level - L)) - 1
        ty, tx = min(li // S, last), min(lj // S, last)
        dl = float(t.tile_delta(L, tx, ty)[li - ty * S, lj - tx * S])
        r = float(t.tile_radius(L, tx, ty)[li - ty * S, lj - tx * S])
        zt[v] = Z[i, j] if i < Z.shape[0] and j < Z.shape[1] else np.nan
        p = np.array([X[min(i, Z.shape[0] - 1), min(j, Z.shape[1] - 1)],
                      Y[min(i, Z.shape[0] - 1), min(j, Z.shape[1] - 1)], zt[v]])
        if rtin.DEPTH:  # the picture's bound: the depth, less δ, and the lift k
            d, lam = float(view.forward @ (p - view.eye)) - dl, view.lam * view.lift
        else:  # LP's eq. 2
            d, lam = float(np.linalg.norm(p - view.eye)), view.lam
        if not np.isfinite(dl) or d <= r or not np.isfinite(zt[v]):
            continue
        rho = lam * dl / (d - r)
        out[v] = np.clip((rho - MORPH_START * tau) / (tau - MORPH_START * tau), 0.0, 1.0)
    return out, zt


def _morphed_rho(t, strategy, seed, tau):
    """A morphed selection of a random view, its surface, and its measured ρ."""
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    view = _views(t, 1, seed)[0]
    sel = t.select(view, tau, strategy, reuse=False, morph=True, occlusion=False)
    f = sel.surface_faces()
    z = np.asarray(sel.mesh.points)[:, 2] if len(f) else np.zeros(0)
    e = screen_space_error(sel.ij, f, z, X, Y, np.where(valid, Z, 0.0), valid, view.eye,
                           view.planes, view.lam)
    return sel, f, z, e


@pytest.mark.fast
@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6), st.sampled_from([0.5, 1.0, 4.0]))
def test_morphed_mesh_keeps_rho_within_tau_and_has_no_crack(rough, seed, tau):
    Z = rough.scene_xyz()[2]
    sel, f, z, e = _morphed_rho(rough, "rtin", seed, tau)
    assert e.max <= tau * (1 + 1e-9), e
    if len(f):  # one height per grid point wherever triangles meet: no crack, no T-junction
        lo, hi = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
        assert np.nan_to_num(hi - lo).max() <= 1e-9 * max(1.0, float(np.nanmax(np.abs(Z))))


def test_heights_follow_eq_4_with_the_cascade_and_t17(rough):
    """z = t·z_true + (1 − t)·(z_a + z_b)/2 with the ends' *drawn* heights, t by eq. 3;
    t ∈ [0, 1], 1 at ρ ≥ τ_max (T17); some vertices are mid-morph."""
    tau = 1.0
    mid = 0
    for view in _views(rough, 6, 1):
        sel = rough.select(view, tau, "rtin", reuse=False, morph=True, occlusion=False)
        ij = np.asarray(sel.ij, np.int64)
        z = np.asarray(sel.mesh.points)[:, 2]
        tv, zt = _t_of(rough, ij, view, tau)
        assert ((tv >= 0) & (tv <= 1)).all()
        at = {(int(i), int(j)): k for k, (i, j) in enumerate(ij)}
        N = rough.grid.size
        for k, (i, j) in enumerate(ij):
            ends = edge_ends(int(i), int(j), N)
            if ends is None or tv[k] == 1.0 or ends[0] not in at or ends[1] not in at:
                continue
            za, zb = z[at[ends[0]]], z[at[ends[1]]]
            if not np.isfinite(za + zb):
                continue
            want = tv[k] * zt[k] + (1 - tv[k]) * 0.5 * (za + zb)
            assert z[k] == pytest.approx(want, rel=1e-9, abs=1e-6), (i, j, tv[k])
            mid += 0 < tv[k] < 1
    assert mid > 10


def test_morph_closure_t18(rough):
    """Child t > 0 ⇒ each DAG parent's t > 0; child t = 1 ⇒ the parent's t = 1 (seed 002
    T18). The parents of a vertex are the right-angle corners of the two triangles whose
    hypotenuse it splits."""
    tau, N, checked = 1.0, rough.grid.size, 0
    for view in _views(rough, 6, 2):
        sel = rough.select(view, tau, "rtin", reuse=False, morph=True, occlusion=False)
        ij = np.asarray(sel.ij, np.int64)
        tv, _ = _t_of(rough, ij, view, tau)
        at = {(int(i), int(j)): k for k, (i, j) in enumerate(ij)}
        for k, (i, j) in enumerate(ij):
            ends = edge_ends(int(i), int(j), N)
            if ends is None or tv[k] == 0:
                continue
            (ai, aj), (bi, bj) = ends
            # the other diagonal of the square (a, b) spans: its two corners
            for p in (((ai + bi) // 2 + (aj - bj) // 2, (aj + bj) // 2 - (ai - bi) // 2),
                      ((ai + bi) // 2 - (aj - bj) // 2, (aj + bj) // 2 + (ai - bi) // 2)):
                if p in at and edge_ends(*p, N) is not None:  # (a domain corner is fixed)
                    checked += 1
                    assert tv[at[p]] > 0
                    assert tv[k] < 1 or tv[at[p]] == 1
    assert checked > 100


@pytest.mark.fast
def test_static_meshes_hold_every_split_edge_end(rough):
    """The cascade needs both ends of the edge each vertex splits: present in any
    conforming rtin mesh (static meshes at several bounds)."""
    N = rough.grid.size
    Z = rough.scene_xyz()[2]
    ok = np.zeros((N, N), bool)
    ok[:Z.shape[0], :Z.shape[1]] = np.isfinite(Z)
    n = 0
    for e in (0.5, 5.0, 50.0):
        sel = rough.static_selection(e)
        at = {tuple(map(int, p)) for p in np.asarray(sel.ij, np.int64)}
        for i, j in at:
            ends = edge_ends(i, j, N)
            if ends is not None and ok[ends[0]] and ok[ends[1]]:  # (nodata ends: no morph)
                assert ends[0] in at and ends[1] in at, ((i, j), ends, e)
                n += 1
    assert n > 1000


def _glide_pops(t, strategy, tau):
    """The largest pop (px) along the issue's glide, with and without morphing."""
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    views = [v for _, v in glide(*extent(X, Y, Z), n_frames=25, size=(480, 270))]
    pops = {}
    for morph in (True, False):
        prev, out = None, []
        for v in views:
            sel = t.select(v, tau, strategy, reuse=False, morph=morph, occlusion=False)
            f = sel.surface_faces()
            s = (sel.ij, f, np.asarray(sel.mesh.points)[:, 2] if len(f) else np.zeros(0))
            if prev is not None:
                out.append(screen_space_change(prev[0], s, X, Y, Zt, valid, v.eye, v.planes,
                                               v.lam, prev[1]).max)
            prev = (s, v.planes)
        pops[morph] = max(out)
    return pops


@pytest.mark.fast
def test_morphing_does_not_pop_along_a_glide(rough):
    """The issue's flight (1 % of the height per frame): pop ≤ 0.25 τ with morphing,
    and up to τ without it (the figure reported beside it)."""
    pops = _glide_pops(rough, "rtin", 1.0)
    assert pops[True] <= 0.25
    assert pops[False] > pops[True]


# ---------------------------------------------------------------- chunked: to the parent
@pytest.mark.fast
@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10**6), st.sampled_from([0.5, 1.0, 4.0]))
def test_morphing_chunks_keep_rho_within_tau(rough, seed, tau):
    """chunked with morphing: every chunk mid-slide still keeps measured ρ ≤ τ at every
    valid sample in view (the surface, skirts left out), nodata hole included."""
    e = _morphed_rho(rough, "chunked", seed, tau)[3]
    assert e.max <= tau * (1 + 1e-9), e


@pytest.mark.fast
def test_a_chunk_at_t0_draws_its_parent_exactly(rough):
    """Each chunk refines its parent's mesh, so its vertices placed on the parent's
    surface (the weights the morph uses) draw the parent's surface at every sample of
    the chunk's footprint (rasterised independently): a chunk that appears does not pop.
    """
    from geoterrain.lod.chunks import chunk, parent_weights, parents
    from geoterrain.lod.tiles import tile_index
    from geoterrain.testing.measure import mesh_heights_on_grid

    index = tile_index(rough)
    par = parents(rough, index)
    shape = rough.scene_xyz()[2].shape
    checked = 0
    for row in np.flatnonzero(par >= 0):
        ch, pa = chunk(rough, index, row), chunk(rough, index, int(par[row]))
        if not len(ch.faces) or not len(pa.faces):
            continue
        ids, w = parent_weights(rough, index, row)
        on = ids[:, 0] >= 0
        zp = (w * pa.xyz[:, 2][np.maximum(ids, 0)]).sum(1)
        # the parent's own surface, and the child's mesh at its t = 0 heights
        hp, okp = mesh_heights_on_grid(pa.ij, pa.faces, pa.xyz[:, 2], shape)
        keep = on[ch.faces].all(1)
        hc, okc = mesh_heights_on_grid(ch.ij, ch.faces[keep], np.where(on, zp, 0.0), shape)
        both = okp & okc
        assert both.sum() > 0
        assert np.abs(hc[both] - hp[both]).max() <= 1e-9 * max(1.0, float(np.abs(hp[both]).max()))
        # every vertex the child shares with a parent triangle is located
        assert on.mean() > 0.5
        checked += 1
    assert checked > 10


@pytest.mark.fast
def test_morphing_chunks_do_not_pop_along_a_glide(rough):
    """The issue's flight: chunked pops as chunks split (τ = 16 px, so that chunks do
    switch on this small, rough grid); morphing each chunk to its parent keeps the surface's
    jump ≤ 0.25 τ a frame."""
    tau = 16.0
    pops = _glide_pops(rough, "chunked", tau)
    assert pops[True] <= 0.25 * tau, pops
    assert pops[False] > 0.25 * tau, pops  # (or the flight tests nothing)


@pytest.mark.fast
@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10**6), st.sampled_from([1.0, 4.0, 16.0]))
def test_skirts_reach_below_every_morphing_neighbour(rough, seed, tau):
    """Chunks of different t meet with a step; each skirt's hanging vertex must lie below
    the lowest surface any chunk draws at its sample, so the step never shows a gap."""
    Z = rough.scene_xyz()[2]
    view = _views(rough, 1, seed)[0]
    sel = rough.select(view, tau, "chunked", reuse=False, morph=True, occlusion=False)
    if not len(sel.faces):
        return
    skirt = np.asarray(sel.mesh.cell_data["skirt"]) == 1
    z = np.asarray(sel.mesh.points)[:, 2]
    f = sel.surface_faces()
    lo, _ = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
    hanging = np.setdiff1d(sel.faces[skirt].ravel(), f.ravel())
    if not len(hanging):
        return
    ij = np.asarray(sel.ij, np.int64)[hanging]
    under = lo[ij[:, 0], ij[:, 1]]
    ok = np.isfinite(under)
    assert (z[hanging][ok] <= under[ok] + 1e-9).all()


# --------------------------------------------- geomipmap: trilinear geomipmapping
@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6), st.sampled_from([0.5, 1.0, 4.0, 16.0]))
def test_morphing_geomipmap_keeps_rho_within_tau_conforming_and_crack_free(rough, seed, tau):
    """Continuous block levels, neighbours' edges at the larger level: measured ρ ≤ τ at
    every sample in view, one height per grid point, and the mesh conforming (no
    T-junction, no edge used more than twice), nodata hole included. (The mesh keeps
    one vertex per sample, so whether the blocks agree on it is checked before the
    merge, below.)"""
    Z = rough.scene_xyz()[2]
    sel, f, z, e = _morphed_rho(rough, "geomipmap", seed, tau)
    assert e.max <= tau * (1 + 1e-9), (e, sel.stats)
    if len(f):
        lo, hi = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
        assert np.nan_to_num(hi - lo).max() <= 1e-9 * max(1.0, float(np.nanmax(np.abs(Z))))
        check_conforming(sel, np.isfinite(Z))


def _raster(K, faces, Z, n, shape):
    """A block's local level-n grid surface on the full-resolution samples it covers."""
    from geoterrain.testing.measure import mesh_heights_on_grid

    a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
    ij = np.stack([a.ravel() << n, b.ravel() << n], 1)
    return mesh_heights_on_grid(ij, faces, Z.ravel(), shape)


@pytest.mark.fast
@pytest.mark.parametrize("K", [2, 4, 8])
def test_a_geomipmap_block_at_t1_draws_its_next_level(K):
    """Eq. 4-13 at t = 1 with Wagner's cases (and every edge at the next level too):
    the block's level-n mesh equals its level-(n+1) mesh at every full-resolution sample,
    for blocks of both parities, plain and with a ratio-2 stitched edge mid-morph (the
    fans nest in the next level's triangles); at t = 0 it is its own level."""
    from geoterrain.lod.geomipmap import template
    from geoterrain.lod.geomipmap_morph import morph_block_heights, next_level_diagonals

    rng = np.random.default_rng(K)
    n = 1
    S = K << n
    for x, y in ((0, 0), (1, 0), (0, 1), (3, 5)):
        full = rng.normal(0, 10, (S + 1, S + 1))
        Zn = full[:: 1 << n, :: 1 << n][None]
        Zc = full[:: 2 << n, :: 2 << n][None]
        diag = next_level_diagonals(np.array([[x, y]]), K)
        for top in (1.0, 1.5):  # the top edge plain at n + 1, or stitched, half-way to n + 2
            rel = np.array([[top, 1.0, 1.0, 1.0]])
            ratios = (2 if top > 1 else 1, 1, 1, 1)
            zm = morph_block_heights(Zn, np.array([1.0]), rel, diag)[0]
            h1, ok1 = _raster(K, template(K, ratios), zm, n, full.shape)
            zc = morph_block_heights(Zc, np.array([0.0]), rel - 1.0,
                                     next_level_diagonals(np.array([[x, y]]), K // 2)
                                     if K >= 4 else np.ones((1, 0, 0), bool))[0]
            par = (x ^ y) & 1 if K == 2 else 0
            h2, ok2 = _raster(K // 2, template(K // 2, (1, 1, 1, 1), par), zc, n + 1,
                              full.shape)
            assert ok1.all() and ok2.all()
            assert np.abs(h1 - h2).max() <= 1e-9, (x, y, top)
        z0 = morph_block_heights(Zn, np.array([0.0]), np.zeros((1, 4)), diag)[0]
        assert np.array_equal(z0, Zn[0])


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0, 5), min_size=3, max_size=5), st.floats(0, 4),
       st.floats(0, 20), st.floats(0, 1))
def test_neighbour_allowance_is_the_largest_excess_within_the_slack(steps, level, slack, x):
    """κ = max{x ≤ 1 : ∫_ℓ^{ℓ+x} ε(⌊s⌋+1) ds ≤ slack}, checked by integrating ε
    directly (ε extended past the last level with its last value)."""
    from geoterrain.lod.geomipmap_morph import neighbour_allowance

    eps = np.concatenate([[0.0], np.cumsum(steps)])  # saturated: nondecreasing
    M = len(eps) - 1
    level = min(level, M)
    k = neighbour_allowance(np.repeat(eps[None, None], 4, 1),
                            np.array([level]), np.array([slack]))[0]
    assert np.allclose(k, k[0]) and 0 <= k[0] <= 1

    def integral(a, b):
        s = np.linspace(a, b, 20001)
        e = eps[np.minimum(np.floor(s).astype(int) + 1, M)]
        return float(np.trapezoid(e, s)) if b > a else 0.0

    assert integral(level, level + k[0]) <= slack + 1e-3 * (1 + slack)
    if k[0] < 1:  # maximal: a little more breaks the slack
        assert integral(level, level + min(1.0, k[0] + 0.01)) >= slack - 1e-3 * (1 + slack)


def _dijkstra(ell, kap, present):
    """The largest field ≤ ℓ under L_B ≤ L_A + κ_A: shortest paths, written here."""
    import heapq

    ny, nx = ell.shape
    steps = ((0, -1), (0, 1), (-1, 0), (1, 0))
    best = np.where(present, ell, np.inf)
    heap = [(best[y, x], y, x) for y in range(ny) for x in range(nx) if present[y, x]]
    heapq.heapify(heap)
    while heap:
        d, y, x = heapq.heappop(heap)
        if d > best[y, x]:
            continue
        for e, (dx, dy) in enumerate(steps):
            v, u = y + dy, x + dx
            if 0 <= v < ny and 0 <= u < nx and present[v, u] and d + kap[y, x, e] < best[v, u]:
                best[v, u] = d + kap[y, x, e]
                heapq.heappush(heap, (best[v, u], v, u))
    return best


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(1, 5), st.integers(1, 5), st.integers(0, 10**6))
def test_restricted_levels_are_the_largest_field_within_the_allowances(ny, nx, seed):
    """L ≤ ℓ, L_B ≤ L_A + κ_A across every edge, and L is the largest such field: each
    block's L is ℓ of some block plus the cheapest κ path to it (Dijkstra)."""
    from geoterrain.lod.geomipmap_morph import restrict

    rng = np.random.default_rng(seed)
    ell = rng.uniform(0, 4, (ny, nx))
    kap = rng.uniform(0, 1, (ny, nx, 4))
    present = rng.random((ny, nx)) > 0.2
    L = restrict(ell, kap, present)
    best = _dijkstra(ell, kap, present)
    assert np.allclose(L[present], best[present])
    assert np.isinf(L[~present]).all()


@pytest.mark.fast
@pytest.mark.parametrize("n", [9, 21, 31])
def test_restricted_levels_follow_a_winding_path_to_its_end(n):
    """Stored blocks in a serpentine between no-data rows: the shortest path from the one
    fine block runs hundreds of hops (more than any pass count set by the grid's sides)
    and must still reach every block."""
    from geoterrain.lod.geomipmap_morph import restrict

    present = np.zeros((n, n), bool)
    present[0::2] = True
    for r in range(1, n, 2):
        present[r, n - 1 if (r // 2) % 2 == 0 else 0] = True
    ell = np.full((n, n), 5.0)
    ell[0, 0] = 0.0
    kap = np.full((n, n, 4), 0.01)
    L = restrict(ell, kap, present)
    assert np.allclose(L[present], _dijkstra(ell, kap, present)[present])


@pytest.mark.fast
def test_blocks_agree_on_every_shared_vertex_before_the_merge(rough, monkeypatch):
    """Each block's morphed heights, recorded before ``_assemble`` keeps one vertex per
    sample: every sample two drawn blocks both use gets the same height from both (so
    the merge hides no disagreement), for views where blocks morph and stitch."""
    from geoterrain.lod import geomipmap

    seen: list[tuple[np.ndarray, np.ndarray]] = []
    orig = geomipmap._assemble

    def recording(terrain, index, xy, n, ratios, heights=None):
        g = terrain.grid

        def rec(sel, lv, K, Z):
            out = heights(sel, lv, K, Z)
            a, b = np.meshgrid(np.arange(K + 1), np.arange(K + 1), indexing="ij")
            for q, blk in enumerate(sel.tolist()):
                par = (int(xy[blk, 0]) ^ int(xy[blk, 1])) & 1 if lv == g.t else 0
                used = np.unique(geomipmap.template(K, tuple(ratios[blk].tolist()), par))
                i = (int(xy[blk, 1]) << g.t) + (a.ravel() << lv)
                j = (int(xy[blk, 0]) << g.t) + (b.ravel() << lv)
                seen.append((i[used] * g.size + j[used], out[q].ravel()[used]))
            return out

        return orig(terrain, index, xy, n, ratios, rec if heights is not None else None)

    monkeypatch.setattr(geomipmap, "_assemble", recording)
    shared = 0
    for view in _views(rough, 8, 3):
        for tau in (1.0, 4.0, 16.0):
            seen.clear()
            sel = rough.select(view, tau, "geomipmap", reuse=False, morph=True,
                               occlusion=False)
            if not seen:
                continue
            key = np.concatenate([k for k, _ in seen])
            z = np.concatenate([v for _, v in seen])
            ok = np.isfinite(z)
            key, z = key[ok], z[ok]
            o = np.argsort(key, kind="stable")
            same = key[o][1:] == key[o][:-1]
            shared += int(same.sum()) if sel.stats["morphing_blocks"] else 0
            assert (z[o][1:][same] == z[o][:-1][same]).all()
    assert shared > 100


@pytest.mark.fast
def test_morphing_geomipmap_does_not_pop_along_a_glide(rough):
    """The issue's flight: geomipmap pops as blocks switch (τ = 16 px, so that blocks do
    switch on this small, rough grid); continuous levels keep the jump ≤ 0.25 τ."""
    tau = 16.0
    pops = _glide_pops(rough, "geomipmap", tau)
    assert pops[True] <= 0.25 * tau, pops
    assert pops[False] > 0.1 * tau, pops  # (or the flight tests nothing)
