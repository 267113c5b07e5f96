"""GeoMipMapping stitching templates and the restricted quadtree (seeds 000 §2.4, 003).

The strategies' ρ ≤ τ (bounded ones), conformity and coverage run in test_lod.py and
test_stress.py, which take the strategy list and its promises from the registry.
"""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.lod.geomipmap import strip_ranges, template
from geoterrain.lod.quadtree import _paint, _restrict


def _area(local: np.ndarray, f: np.ndarray) -> float:
    p = local[f].astype(float)
    return float(0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                              - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])).sum())


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


def test_strip_ranges_bound_each_segment():
    rng = np.random.default_rng(0)
    Z = rng.random((3, 9, 9))
    B = strip_ranges(Z, 4)
    for r, k in ((2, 1), (4, 2), (8, 3)):
        want = max(np.ptp(Z[:, 0:2, u:u + r + 1], axis=(1, 2)).max() for u in range(0, 8, r))
        assert B[:, 0, k].max() == want
    Z[1, 0, 3] = np.nan
    assert np.isinf(strip_ranges(Z, 4)[1, 0, 1]) and np.isfinite(strip_ranges(Z, 4)[0, 0, 1])


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
