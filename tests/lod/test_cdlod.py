"""CDLOD (seed 001): no gap at any morph k, ρ ≤ τ with morphing on and off, k = 1 is the
parent, the crack-free range constraint; and the popping metric of measure.py.

Gaps and errors are measured on the mesh alone (positions and grid samples) or with
geoterrain.testing.measure, never with the selection's own numbers.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core.view import View
from geoterrain.ingest.synth import generate
from geoterrain.lod import cdlod
from geoterrain.lod.tiles import tile_geometry, tile_index
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    mesh_heights_on_grid,
    screen_space_change,
)
from tests.lod.test_lod import SLACK, Case, _store, random_view, screen_error, surface


def view(c, az, el, dist):
    """A 128×72 view (λ ≈ 134 px): a coarse screen makes CDLOD's ranges short."""
    v = random_view(c, az, el, dist, 0.1, -0.1)
    return View(v.look_from, v.look_at, fov_y_deg=30, size=(128, 72))


@pytest.fixture(scope="module")
def smooth(tmp_path_factory):
    """A gentle 129² fBm (relief ~40 m over ~1.3 km), tiles of 16; seen in small images
    (:func:`view`) its ranges are short enough for several levels, partial nodes and
    morph zones in one view."""
    z = (generate("fbm", 129, seed=4) * 0.02).astype(np.float32)
    return Case("smooth", _store(tmp_path_factory, "smooth", z, tile_size=16))


def coarser_edge_gaps(sel) -> tuple[float, int]:
    """Largest distance (relative to the mesh's extent) of a vertex lying strictly inside
    another triangle's edge, in grid terms, from that edge's segment; and how many."""
    ij = sel.ij.astype(np.int64)
    P = np.asarray(sel.mesh.points)
    f = sel.surface_faces()
    e = np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1), axis=0)
    N = int(ij.max()) + 1
    key = ij[:, 0] * N + ij[:, 1]
    order = np.argsort(key)
    sk = key[order]
    d = ij[e[:, 1]] - ij[e[:, 0]]
    g = np.gcd(np.abs(d[:, 0]), np.abs(d[:, 1]))
    worst, count = 0.0, 0
    for s in range(1, int(g.max(initial=1))):
        on = g > s
        a, b, gg = e[on, 0], e[on, 1], g[on]
        q = ij[a] + s * (d[on] // gg[:, None])
        qk = q[:, 0] * N + q[:, 1]
        pos = np.minimum(np.searchsorted(sk, qk), len(sk) - 1)
        hit = sk[pos] == qk
        if not hit.any():
            continue
        v = order[pos[hit]]
        w = (s / gg[hit])[:, None]
        line = (1 - w) * P[a[hit]] + w * P[b[hit]]
        worst = max(worst, float(np.abs(P[v] - line).max()))
        count += int(hit.sum())
    scale = float(np.abs(P).max(initial=1.0))
    return worst / scale, count


@settings(max_examples=12, deadline=None)
@given(az=st.floats(0, 2 * np.pi), el=st.floats(0.05, 1.2), dist=st.floats(0.1, 6.0),
       tau=st.sampled_from([0.5, 1.0, 4.0]), frac=st.sampled_from([0.0, 0.25, 0.5, 0.9]))
def test_no_gap_at_any_morph_k_and_error_within_tau(smooth, az, el, dist, tau, frac):
    c = smooth
    v = view(c, az, el, dist)
    # every sample in the frustum drawn (culling: its own tests)
    mesh, stats = cdlod.select(c.t, v, tau, occlusion=False, morph_fraction=frac)

    class Sel:  # the two accessors the helpers read
        pass
    sel = Sel()
    sel.mesh = mesh
    sel.ij = np.asarray(mesh.point_data["grid_ij"]) if mesh.n_points else np.zeros((0, 2))
    sel.surface_faces = lambda: (mesh.faces.reshape(-1, 4)[:, 1:] if mesh.n_cells
                                 else np.zeros((0, 3), np.int64))
    if not mesh.n_cells:
        return
    gap, _ = coarser_edge_gaps(sel)
    assert gap <= 1e-9, (gap, stats)
    ij, f, z = surface(sel)
    lo, hi = mesh_height_range_on_grid(ij, f, z, c.Z.shape)  # independent: any crack
    spread = np.nanmax(hi - lo)
    assert spread <= 1e-9 * float(np.nanmax(np.abs(c.Z))), spread
    err = screen_error(c, sel, v)
    assert err.max <= tau * SLACK and err.n_uncovered == 0, (err, stats)


@pytest.mark.fast
def test_far_view_morphs_and_meets_coarser_edges(smooth):
    """A view whose mesh has level changes and vertices mid-morph (0 < k < 1): the gap
    test above does see T-junction vertices on coarser edges."""
    c = smooth
    v = view(c, 0.7, 0.5, 1.0)
    sel = c.t.select(v, 1.0, "cdlod", reuse=False)
    levels = np.unique(np.asarray(sel.mesh.cell_data["level"]))
    gap, n_on_edges = coarser_edge_gaps(sel)
    assert len(levels) >= 3 and n_on_edges > 0 and sel.stats["morphing_vertices"] > 0
    assert sel.stats["partial_nodes"] > 0
    assert gap <= 1e-9
    off, _ = coarser_edge_gaps_without_morph(c, v)
    assert off > 1e-6  # without the morph the same selection has gaps: the test can fail


def coarser_edge_gaps_without_morph(c, view):
    """The same regions with the odd vertices left at their samples (k ≡ 0)."""
    m = cdlod.morph_positions
    try:
        cdlod.morph_positions = lambda terrain, key, xyz, *a: (xyz, 0)
        mesh, _ = cdlod.select(c.t, view, 1.0)
    finally:
        cdlod.morph_positions = m

    class Sel:
        pass
    sel = Sel()
    sel.mesh, sel.ij = mesh, np.asarray(mesh.point_data["grid_ij"])
    sel.surface_faces = lambda: mesh.faces.reshape(-1, 4)[:, 1:]
    return coarser_edge_gaps(sel)


@pytest.mark.fast
def test_at_k_one_a_node_matches_its_parent(smooth):
    """Every odd vertex fully morphed: a level-L tile's surface is its parent's surface
    on the tile's footprint (seed 001 §2.7)."""
    t = smooth.t
    ix = tile_index(t)
    N = t.grid.size
    top = t.grid.top_level
    for L in range(top):
        row = int(np.flatnonzero(ix.keys[:, 0] == L)[0])
        key, xyz, faces, _ = cdlod._parts(t, ix, row)
        r = np.full(top + 1, 1e-12)
        m = np.zeros(top + 1)
        r[top] = m[top] = np.inf
        # k = 1 for the odd vertices of level L only (the coarser levels keep k = 0)
        r[L + 1:top] = m[L + 1:top] = np.inf
        P, moved = cdlod.morph_positions(t, key, xyz, np.array([1e9, 1e9, 1e9]), r, m)
        assert moved > 0
        ij = np.stack([key // N, key % N], 1)
        child, _ = mesh_heights_on_grid(ij, faces, P[:, 2], (N, N))
        L1, x, y = L + 1, ix.keys[row, 1] >> 1, ix.keys[row, 2] >> 1
        pij, pxyz, _, pf = tile_geometry(t, ix, ix.row[(L1, int(x), int(y))])
        parent, _ = mesh_heights_on_grid(pij, pf, pxyz[:, 2], (N, N))
        both = np.isfinite(child) & np.isfinite(parent)
        assert both.sum() >= len(key)
        np.testing.assert_allclose(child[both], parent[both], rtol=0, atol=1e-9)


@pytest.mark.fast
def test_ranges_hold_the_crack_free_constraint(smooth):
    t = smooth.t
    tb = cdlod._tables(t, tile_index(t))
    for f in (0.0, 0.5, 0.9):
        r, m = cdlod.ranges(tb, 1500.0, 1.0, f)
        fin = r[:-1]
        assert np.all(np.diff(fin) > 0) and np.all(m[:-1] <= fin)
        # seed 001 L407: each range holds a whole node's diagonal beyond the previous one
        assert np.all((1 - f) * np.diff(fin) >= tb.diag[: len(fin) - 1])
        assert np.all(fin >= 1500.0 * tb.e[1:] / 1.0)


@pytest.mark.fast
def test_popping_metric_sees_a_jump_and_ignores_a_still_surface(smooth):
    c = smooth
    view = random_view(c, 0.7, 0.5, 1.0, 0.0, 0.0)
    a = c.t.select(view, 1.0, "cdlod", reuse=False)
    same = screen_space_change(surface(a), surface(a), c.X, c.Y, c.Z, c.valid, view.eye,
                               view.planes, view.lam)
    assert same.max == 0 and same.n_samples > 0
    ij, f, z = surface(a)
    z2 = z.copy()
    z2[len(z2) // 2] += 10.0
    jump = screen_space_change((ij, f, z), (ij, f, z2), c.X, c.Y, c.Z, c.valid, view.eye,
                               view.planes, view.lam)
    i, j = ij[len(z2) // 2].astype(int)
    d = np.linalg.norm(np.array([c.X[i, j], c.Y[i, j], c.Z[i, j]]) - view.eye)
    if view.points_inside(np.array([[c.X[i, j], c.Y[i, j], c.Z[i, j]]]))[0]:
        assert jump.max == pytest.approx(view.lam * 10.0 / d)
