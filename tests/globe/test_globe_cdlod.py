"""The planetary CDLOD on the globe: a closed surface without cracks, and the precision
scheme (float64 positions, node-relative float32 meshes, drawn relative to the eye)."""

from __future__ import annotations

import numpy as np
import pytest

from geoterrain.globe import Globe


@pytest.fixture(scope="module")
def planet() -> Globe:
    g = Globe(model="wgs84", base="procedural", node_cells=8, sync=True)
    yield g
    g.close()


def _gaps(world: np.ndarray, faces: np.ndarray) -> tuple[int, int, float]:
    """(edges shared by more than two triangles, boundary edges, the largest distance from a
    boundary edge's ends and midpoint to the nearest other boundary edge), in float64 world
    positions. On a closed surface drawn with T-junctions every boundary edge lies on
    others: a crack or a gap shows as a distance."""
    q = np.round(world / 1e-3).astype(np.int64)  # one vertex per millimetre cell
    _, inv = np.unique(q, axis=0, return_inverse=True)
    inv = inv.ravel()
    P = np.zeros((inv.max() + 1, 3))
    P[inv] = world
    F = inv[faces]
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    u, c = np.unique(E, axis=0, return_counts=True)
    B = u[c == 1]
    A, Bq = P[B[:, 0]], P[B[:, 1]]
    ab = Bq - A
    pts = np.concatenate([A, Bq, (A + Bq) / 2])
    worst = 0.0
    for s in range(0, len(pts), 400):
        p = pts[s:s + 400]
        t = (np.einsum("pj,ej->pe", p, ab) - (A * ab).sum(1)[None]) / (ab * ab).sum(1)[None]
        near = A[None] + np.clip(t, 0, 1)[..., None] * ab[None]
        dist = np.linalg.norm(p[:, None] - near, axis=-1)
        dist[np.arange(len(p)), np.arange(s, s + len(p)) % len(B)] = np.inf
        worst = max(worst, float(dist.min(1).max()))
    return int((c > 2).sum()), len(B), worst


def test_the_whole_planet_is_closed_no_crack_no_gap_after_morphing(planet):
    v = planet.camera(10.0, 45.0, 3.0e6, 0.0, -40.0, size=(320, 240))
    sel = planet.select(v, 4.0, wait=True, frustum=False, horizon=False)
    assert sel.stats["max_depth"] >= 3 and sel.stats["partial_nodes"] > 0
    assert 0 < sel.k.max() <= 1  # some vertices are mid-morph
    over, boundary, worst = _gaps(sel.world, sel.faces)
    assert over == 0 and boundary > 0  # T-junctions between levels, nothing else
    assert worst < 1e-4  # metres: every T-junction's vertex lies on the coarser edge


def test_the_mesh_is_node_relative_float32_drawn_relative_to_the_eye(planet):
    v = planet.camera(30.0, -20.0, 2.0e5, 90.0, -30.0, size=(160, 120))
    sel = planet.select(v, 4.0, wait=True)
    assert sel.points.dtype == np.float32 and sel.world.dtype == np.float64
    assert np.array_equal(sel.origin, np.asarray(v.eye))
    ex = sel.world - sel.origin
    err = np.linalg.norm(sel.points - ex, axis=1)
    assert (err <= 1e-6 * np.linalg.norm(ex, axis=1) + 1e-6).all()
    assert planet.payloads.rel.dtype == np.float32


def test_precision_2_m_above_the_ground_at_6371_km_jitter_below_1_mm():
    # seed 001 §2.8: a camera 2 m above the surface of a 6 371 km planet. Positions are
    # float64, meshes node-relative float32, drawn relative to the eye: the vertices the
    # camera sees move by well under 1 mm as the eye moves; with float32 world positions
    # (the eye subtracted after rounding) they jump by tenths of a metre and more
    g = Globe(model="sphere", base="procedural", node_cells=8, sync=True)
    try:
        lon, lat = 10.0, 45.0
        ground = float(g.surface.heights(np.array([lon]), np.array([lat]), g.max_depth)[0])
        ours, f32 = [], []
        for step in range(6):  # the eye slides 7 mm a frame
            v = g.camera(lon + step * 1e-7, lat, ground + 2.0, 0.0, -20.0, size=(96, 72))
            sel = g.select(v, 4.0, wait=True)
            ex = sel.world - sel.origin  # camera space, exact (float64)
            near = np.linalg.norm(ex, axis=1) < 1000.0
            assert near.sum() > 100 and np.linalg.norm(ex, axis=1).min() < 10.0
            ours.append(np.linalg.norm(sel.points[near] - ex[near], axis=1).max())
            w32 = (sel.world[near].astype(np.float32).astype(np.float64)
                   - sel.origin.astype(np.float32).astype(np.float64))
            f32.append(np.linalg.norm(w32 - ex[near], axis=1).max())
        assert max(ours) < 1e-3  # below 1 mm in camera space
        assert max(f32) > 0.2  # float32 world positions: tenths of metres to metres
    finally:
        g.close()


def test_a_frame_installs_finished_payloads_within_its_budget_and_the_rest_later():
    """Seed 001's per-frame budgets on the main thread: a frame installs finished payloads
    until ``INSTALL_MS`` has passed (one at least); the rest stay counted as pending and go
    in on the next frames, or all at once when a converged mesh is asked for."""
    import time

    from geoterrain.globe import globe as globe_module

    g = Globe(model="sphere", base="procedural", node_cells=8, sync=True)
    try:
        v = g.camera(10.0, 45.0, 30_000.0, 0.0, -30.0, size=(96, 72))
        g.select(v, 1.0)  # requests, generated at dispatch (sync): all finished
        g.select(v, 1.0)
        waiting = g.queue.in_flight
        assert waiting >= 4
        real = g._install

        def slow(row, p):  # an install that waits 20 ms, as one behind busy threads may
            time.sleep(0.02)
            real(row, p)

        g._install = slow
        t0 = time.perf_counter()
        n = g.install_finished(budget_ms=30.0)
        took = (time.perf_counter() - t0) * 1e3
        assert 1 <= n <= 2 and g.uninstalled == waiting - n
        assert took < 30.0 + 2 * 20.0 + 15.0  # the budget, one install past it, slack
        assert g.install_finished(budget_ms=0.0) == 1  # one at least, however tight
        g._install = real
        sel = g.select(v, 1.0)  # the default budget: what is left counts as pending
        assert sel.stats["pending"] >= g.uninstalled
        assert globe_module.INSTALL_MS == 40.0
        g.generate_pending(wait=True)  # a converged mesh takes every one
        assert g.uninstalled == 0
    finally:
        g.close()
