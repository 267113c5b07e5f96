"""Tests of geoterrain.bounds.delta and geoterrain.bounds.tilebounds: exact δ, saturation, nested
radii,
tile bounds; and of the numpy oracles of geoterrain.testing.reference (δ, static mesh), which the
compiled kernels are re-checked against.

Every error measurement here uses brute-force routines written in this file (barycentric
interpolation triangle by triangle), never code from geoterrain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoterrain.bounds.delta import _raw_delta, vertex_errors
from geoterrain.bounds.radii import vertex_radii
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.core.bintree import vertex_children, vertex_depth, vertex_parents
from geoterrain.core.grid import footprint_counts
from geoterrain.core.rounding import round_up
from geoterrain.testing.reference import static_mesh, vertex_errors_reference
from tests.conftest import real_dem

EPS = np.finfo(np.float64).eps

# ------------------------------------------------------------------ brute-force helpers


def tri_samples(a, b, c):
    """Grid samples (i, j) inside or on the triangle, with barycentric weights."""
    pts = np.array([a, b, c], dtype=np.float64)
    lo = np.floor(pts.min(0)).astype(int)
    hi = np.ceil(pts.max(0)).astype(int)
    (ai, aj), (bi, bj), (ci, cj) = pts
    det = (bi - ai) * (cj - aj) - (ci - ai) * (bj - aj)
    out = []
    for i in range(lo[0], hi[0] + 1):
        for j in range(lo[1], hi[1] + 1):
            wb = ((i - ai) * (cj - aj) - (ci - ai) * (j - aj)) / det
            wc = ((bi - ai) * (j - aj) - (i - ai) * (bj - aj)) / det
            wa = 1.0 - wb - wc
            if min(wa, wb, wc) >= -1e-12:
                out.append((i, j, wa, wb, wc))
    return out


def mesh_deviation(verts, faces, z, valid):
    """Max |z − mesh| over valid samples covered by the mesh, and the covered mask."""
    worst = 0.0
    covered = np.zeros(z.shape, bool)
    for f in faces:
        a, b, c = (tuple(verts[k]) for k in f)
        za, zb, zc = z[a], z[b], z[c]
        for i, j, wa, wb, wc in tri_samples(a, b, c):
            covered[i, j] = True
            if valid[i, j]:
                worst = max(worst, abs(z[i, j] - (wa * za + wb * zb + wc * zc)))
    return worst, covered


def full_res_triangles(N):
    """Union-jack unit triangles (level 0), written independently of the library."""
    tris = []
    for a in range(N - 1):
        for b in range(N - 1):
            c00, c01, c10, c11 = (a, b), (a, b + 1), (a + 1, b), (a + 1, b + 1)
            # diagonal joins the corner whose row and column are both odd
            if (a % 2 == 1) == (b % 2 == 1):  # (a,b) or (a+1,b+1) is odd/odd
                tris += [(c00, c01, c11), (c00, c10, c11)]
            else:
                tris += [(c01, c00, c10), (c01, c11, c10)]
    return tris


def uniform_surface_brute(z, valid, L):
    """|z − S_L| per valid sample (0 elsewhere), and per closed triangle mixed flags,
    for the level-L union-jack surface, by barycentric interpolation."""
    N = z.shape[0]
    s = 1 << L
    err = np.zeros(z.shape)
    tris = []
    for a in range(0, (N - 1) // s):
        for b in range(0, (N - 1) // s):
            i0, j0 = a * s, b * s
            c00, c01, c10, c11 = (i0, j0), (i0, j0 + s), (i0 + s, j0), (i0 + s, j0 + s)
            if (a % 2 == 1) == (b % 2 == 1):
                pair = [(c00, c01, c11), (c00, c10, c11)]
            else:
                pair = [(c01, c00, c10), (c01, c11, c10)]
            for t in pair:
                samp = tri_samples(*t)
                vs = [valid[i, j] for i, j, *_ in samp]
                mixed = any(vs) and not all(vs)
                tris.append((a, b, mixed))
                if all(vs):
                    za, zb, zc = (z[p] for p in t)
                    for i, j, wa, wb, wc in samp:
                        err[i, j] = max(err[i, j], abs(z[i, j] - (wa * za + wb * zb + wc * zc)))
    return err, tris


def dag_pairs(N):
    """All (vertex, child) pairs of the DAG, corners excluded, as two (K, 2) arrays."""
    n = int(math.log2(N - 1))
    II, JJ = np.indices((N, N))
    II, JJ = II.ravel(), JJ.ravel()
    d = vertex_depth(II, JJ, n)
    keep = d >= 0
    II, JJ = II[keep], JJ[keep]
    ch = vertex_children(II, JJ, n)
    v = np.repeat(np.stack([II, JJ], 1), 4, axis=0)
    c = ch.reshape(-1, 2)
    ok = c[:, 0] >= 0
    return v[ok], c[ok]


def random_dem(data, N):
    seed = data.draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = data.draw(st.sampled_from(["noise", "smooth", "int"]))
    if kind == "noise":
        z = rng.normal(0, 10, (N, N))
    elif kind == "smooth":
        z = np.cumsum(np.cumsum(rng.normal(0, 1, (N, N)), 0), 1)
    else:
        z = rng.integers(-50, 50, (N, N)).astype(np.float64)
    density = data.draw(st.sampled_from([1.0, 1.0, 0.95, 0.7, 0.3]))
    valid = rng.random((N, N)) < density
    if data.draw(st.booleans()):  # a block of nodata, like padding
        k = data.draw(st.integers(0, N - 1))
        valid[:, k:] = False
    return z, valid


SIZES = st.sampled_from([3, 5, 9, 17, 33])
HSET = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------------------ analytic


@pytest.mark.fast
@pytest.mark.parametrize("N", [3, 9, 33])
def test_flat_and_affine(N):
    II, JJ = np.indices((N, N)).astype(np.float64)
    valid = np.ones((N, N), bool)
    flat = np.full((N, N), 1234.5)
    assert not vertex_errors(flat, valid).any()
    v, f = static_mesh(vertex_errors(flat, valid), valid, 0.0)
    assert len(f) == 2 and len(v) == 4
    rng = np.random.default_rng(N)
    for _ in range(5):
        a, b, c = rng.normal(0, 100, 3)
        z = a * II + b * JJ + c * 1000
        d = vertex_errors(z, valid)
        # Each plane value takes ~6 roundings of numbers up to max|z|, so a δ of an
        # affine surface is pure rounding noise bounded by a few ulps of max|z|.
        tol = 64 * EPS * np.abs(z).max()
        assert d.max() <= tol
        assert np.abs(vertex_errors_reference(z, valid)).max() <= tol
        v, f = static_mesh(d, valid, tol)
        assert len(f) == 2


@pytest.mark.fast
def test_xy_analytic():
    # Seed 002 §2.3: z = x·y; span-s block centres δ = s²/4; after propagation the edge
    # midpoints of span-s blocks (s ≥ 4) are s²/16. Our δ is the exact diamond maximum,
    # so the raw edge value is already s²/16 (the seed's midpoint-only raw value is 0);
    # the finest edge midpoints (s = 2) have only vertices in their diamond: 0.
    N = 65
    n = 6
    II, JJ = np.indices((N, N)).astype(np.float64)
    valid = np.ones((N, N), bool)
    z = II * JJ
    raw = vertex_errors_reference(z, valid)
    d = vertex_errors(z, valid)
    dep = vertex_depth(II.astype(int), JJ.astype(int), n)
    for depth in range(2 * n):
        s = 2 << (n - depth // 2 - 1)
        sel = dep == depth
        if depth % 2 == 0:
            expect = s * s / 4
        else:
            expect = s * s / 16 if s >= 4 else 0.0
        np.testing.assert_allclose(raw[sel], expect, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(d[sel], expect, rtol=1e-6, atol=1e-9)
    # flat unit-spacing terrain: seed T7, root radius = (m − 1) + (m − 2)/√2
    m = 64
    r = vertex_radii(JJ, -II, np.zeros((N, N)), valid)
    assert r[32, 32] == pytest.approx((m - 1) + (m - 2) / math.sqrt(2), rel=1e-6)
    assert r[32, 32] == r.max()


# ------------------------------------------------------------------------- random


@given(data=st.data(), N=SIZES)
@HSET
def test_kernel_matches_reference(data, N):
    z, valid = random_dem(data, N)
    zz = np.where(valid, z, 0.0)
    vv = valid.copy()
    a = _raw_delta(zz, vv)
    b = round_up(vertex_errors_reference(z, valid))
    np.testing.assert_array_equal(np.isinf(a), np.isinf(b))
    np.testing.assert_array_equal(a == 0, b == 0)
    fin = np.isfinite(a)
    np.testing.assert_allclose(a[fin], b[fin], rtol=1e-6, atol=1e-12)


@pytest.mark.fast
@given(data=st.data(), N=SIZES)
@HSET
def test_saturation_and_nesting(data, N):
    z, valid = random_dem(data, N)
    z = np.where(valid, z, np.nan)
    n = int(math.log2(N - 1))
    d = vertex_errors(z, valid)
    assert d.dtype == np.float32 and (d >= 0).all()
    assert d[0, 0] == d[0, -1] == d[-1, 0] == d[-1, -1] == 0
    v, c = dag_pairs(N)
    corner = vertex_depth(v[:, 0], v[:, 1], n) < 0
    assert not corner.any()
    assert (d[v[:, 0], v[:, 1]] >= d[c[:, 0], c[:, 1]]).all()
    # every non-corner's parents are ≥ (parents() is a separate code path from children())
    II, JJ = np.indices((N, N))
    keep = vertex_depth(II.ravel(), JJ.ravel(), n) >= 0
    II, JJ = II.ravel()[keep], JJ.ravel()[keep]
    par = vertex_parents(II, JJ, n)
    for k in range(2):
        pi, pj = par[:, k, 0], par[:, k, 1]
        ok = (pi >= 0) & (vertex_depth(pi, pj, n) >= 0)
        assert (d[pi[ok], pj[ok]] >= d[II[ok], JJ[ok]]).all()
    # nested spheres in 3-D with curvilinear x, y
    Ii, Jj = np.indices((N, N)).astype(np.float64)
    x = 30 * Jj + 0.05 * Ii**2
    y = -30 * Ii + 2 * np.sin(Jj)
    r = vertex_radii(x, y, z, valid)
    assert r.dtype == np.float32 and np.isfinite(r).all()
    leaves = vertex_depth(np.indices((N, N))[0], np.indices((N, N))[1], n) == 2 * n - 1
    assert not r[leaves].any()
    both = valid[v[:, 0], v[:, 1]] & valid[c[:, 0], c[:, 1]]
    p = np.stack([x, y, z], -1)
    dist = np.linalg.norm(p[v[:, 0], v[:, 1]] - p[c[:, 0], c[:, 1]], axis=1)
    rv = r[v[:, 0], v[:, 1]].astype(np.float64)
    rc = r[c[:, 0], c[:, 1]].astype(np.float64)
    assert (rv[both] >= (dist[both] + rc[both]) * (1 - 1e-12)).all()


def check_mesh(verts, faces, valid):
    N = valid.shape[0]
    V = verts.astype(np.float64)
    if len(faces) == 0:
        return
    a, b, c = V[faces[:, 0]], V[faces[:, 1]], V[faces[:, 2]]
    # CCW seen from above, X east = j, Y north = −i
    cross = (b[:, 1] - a[:, 1]) * (-(c[:, 0] - a[:, 0])) - (c[:, 1] - a[:, 1]) * (
        -(b[:, 0] - a[:, 0]))
    assert (cross > 0).all()
    # covers exactly the valid domain
    area = 0.5 * cross.sum()
    full = sum(all(valid[p] for p in t) for t in full_res_triangles(N)) * 0.5
    assert area == pytest.approx(full)
    # manifold and conforming: each directed edge once; an interior edge appears in both
    # directions; no mesh vertex lies strictly inside any edge (no T-junction)
    edges = {}
    for f in faces:
        for k in range(3):
            e = (int(f[k]), int(f[(k + 1) % 3]))
            assert e not in edges
            edges[e] = True
    vset = {tuple(p) for p in verts.tolist()}
    for (p, q) in edges:
        (pi, pj), (qi, qj) = verts[p], verts[q]
        g = math.gcd(abs(int(qi - pi)), abs(int(qj - pj)))
        for k in range(1, g):
            pt = (int(pi + (qi - pi) // g * k), int(pj + (qj - pj) // g * k))
            assert pt not in vset, f"T-junction at {pt}"


@pytest.mark.fast
@given(data=st.data(), N=st.sampled_from([3, 5, 9, 17]))
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_static_mesh_bound(data, N):
    z, valid = random_dem(data, N)
    d = vertex_errors(np.where(valid, z, np.nan), valid)
    for e in (0.5, 1.0, 5.0, 20.0):
        verts, faces = static_mesh(d, valid, e)
        check_mesh(verts, faces, valid)
        worst, covered = mesh_deviation(verts, faces, z, valid)
        assert worst <= e + 1e-9
        # every valid sample touching a full-res triangle with 3 valid corners is covered
        for t in full_res_triangles(N):
            if all(valid[p] for p in t):
                assert all(covered[p] for p in t)


# ------------------------------------------------------------------------ tiles


@pytest.mark.fast
@pytest.mark.parametrize("seed", range(4))
def test_tile_errors_brute(seed):
    rng = np.random.default_rng(seed)
    N, t = 17, 2
    n = 4
    z = np.cumsum(rng.normal(0, 1, (N, N)), 0) + rng.normal(0, 0.5, (N, N))
    valid = np.ones((N, N), bool)
    if seed >= 1:
        valid[:, 13:] = False
    if seed >= 2:
        valid[rng.random((N, N)) < 0.05] = False
    if seed == 3:
        valid[:8, :] = False
    Ii, Jj = np.indices((N, N)).astype(np.float64)
    x, y = 10 * Jj + 0.1 * Ii, -10 * Ii
    tb, blocks = tile_and_block_errors(np.where(valid, z, np.nan), valid, x, y, t)
    assert tile_and_block_errors(np.where(valid, z, np.nan), valid, x, y, t,
                                 counts=footprint_counts(valid, t))[0] == tb  # counts given
    lmax = n - t
    raw = {}
    for L in range(lmax + 1):
        S = 1 << (t + L)
        if L == 0:
            err = np.zeros((N, N))
            tris = []
        else:
            err, tris = uniform_surface_brute(z, valid, L)
        cpt = 1 << t
        if L < blocks.shape[2]:  # seed 000 §2.4's δ_L of every block (level-0 tile)
            c = cpt >> L  # level-L cells per block side
            for by in range(N // cpt):
                for bx in range(N // cpt):
                    sl = np.s_[by * cpt:by * cpt + cpt + 1, bx * cpt:bx * cpt + cpt + 1]
                    mixed = [m for (a, b, m) in tris if a // c == by and b // c == bx and m]
                    want = np.inf if mixed else err[sl].max()
                    assert blocks[by, bx, L] == pytest.approx(want, abs=1e-9)
        for ty in range(N // S):
            for tx in range(N // S):
                sl = np.s_[ty * S:ty * S + S + 1, tx * S:tx * S + S + 1]
                vm = valid[sl]
                key = (L, tx, ty)
                if not vm.any():
                    assert key not in tb
                    continue
                got = tb[key]
                assert got.nvalid == vm.sum()
                assert got.zmin == z[sl][vm].min() and got.zmax == z[sl][vm].max()
                assert got.xmin == x[sl][vm].min() and got.xmax == x[sl][vm].max()
                assert got.ymin == y[sl][vm].min() and got.ymax == y[sl][vm].max()
                mixed = [m for (a, b, m) in tris
                         if a // cpt == ty and b // cpt == tx and m]
                e = np.inf if mixed else err[sl].max()
                border = [m for (a, b, m) in tris if a // cpt == ty and b // cpt == tx and m
                          and (a % cpt in (0, cpt - 1) or b % cpt in (0, cpt - 1))]
                es = err[sl]
                be = max(es[0].max(), es[-1].max(), es[:, 0].max(), es[:, -1].max())
                assert got.boundary_error == (np.inf if border else pytest.approx(be, abs=1e-9))
                raw[key] = e
    env = {}
    for key in sorted(raw):  # monotone envelope of the brute-force values, fine to coarse
        L, tx, ty = key
        kids = [env.get((L - 1, 2 * tx + a, 2 * ty + b), 0.0)
                for a in (0, 1) for b in (0, 1)] if L else []
        env[key] = max([raw[key], *kids])
        got = tb[key].error
        assert (np.isinf(got) and np.isinf(env[key])) or got == pytest.approx(env[key],
                                                                              abs=1e-9)
    for (L, tx, ty), v in tb.items():  # monotone up the quadtree
        if L > 0:
            for a in (0, 1):
                for b in (0, 1):
                    k = (L - 1, 2 * tx + a, 2 * ty + b)
                    if k in tb:
                        assert v.error >= tb[k].error


# ------------------------------------------------------------------------ real DEM


def read_fuji():
    iio = pytest.importorskip("imageio.v3")
    rgb = iio.imread(real_dem("fuji_terrain_rgb.png"))[..., :3].astype(np.float64)
    h = -10000 + (rgb[..., 0] * 65536 + rgb[..., 1] * 256 + rgb[..., 2]) * 0.1
    H, W = h.shape
    N = 513
    z = np.full((N, N), np.nan)
    valid = np.zeros((N, N), bool)
    z[:H, :W] = h
    valid[:H, :W] = True  # padding row/column is invalid (conventions)
    return z, valid


def mesh_deviation_np(verts, faces, z, valid):
    """Vectorised barycentric check: max |z − mesh| over valid samples in each triangle."""
    V = verts.astype(np.float64)
    A, B, C = V[faces[:, 0]], V[faces[:, 1]], V[faces[:, 2]]
    lo = np.minimum(np.minimum(A, B), C).astype(int)
    ext = (np.maximum(np.maximum(A, B), C) - lo).astype(int).max(1)
    worst = 0.0
    zz = np.where(valid, z, np.nan)
    for size in np.unique(ext):
        k = ext == size
        oi, oj = np.indices((size + 1, size + 1))
        oi, oj = oi.ravel(), oj.ravel()
        Pi = lo[k, 0:1] + oi[None]
        Pj = lo[k, 1:2] + oj[None]
        a, b, c = A[k], B[k], C[k]
        det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        wb = ((Pi - a[:, :1]) * (c[:, 1:] - a[:, 1:]) - (c[:, :1] - a[:, :1]) * (Pj - a[:, 1:]))
        wc = ((b[:, :1] - a[:, :1]) * (Pj - a[:, 1:]) - (Pi - a[:, :1]) * (b[:, 1:] - a[:, 1:]))
        wb, wc = wb / det[:, None], wc / det[:, None]
        wa = 1 - wb - wc
        inside = (wa >= -1e-12) & (wb >= -1e-12) & (wc >= -1e-12)
        Pi_c = np.clip(Pi, 0, z.shape[0] - 1)
        Pj_c = np.clip(Pj, 0, z.shape[1] - 1)
        za = z[a[:, 0].astype(int), a[:, 1].astype(int)][:, None]
        zb = z[b[:, 0].astype(int), b[:, 1].astype(int)][:, None]
        zc = z[c[:, 0].astype(int), c[:, 1].astype(int)][:, None]
        dev = np.abs(zz[Pi_c, Pj_c] - (wa * za + wb * zb + wc * zc))
        dev = np.where(inside, dev, np.nan)
        if np.isfinite(dev).any():
            worst = max(worst, float(np.nanmax(dev)))
    return worst


@pytest.mark.fast
def test_mesh_deviation_np_agrees_with_loops():
    rng = np.random.default_rng(5)
    N = 17
    z = rng.normal(0, 5, (N, N))
    valid = np.ones((N, N), bool)
    valid[:, 15:] = False
    d = vertex_errors(z, valid)
    v, f = static_mesh(d, valid, 2.0)
    assert mesh_deviation_np(v, f, z, valid) == pytest.approx(
        mesh_deviation(v, f, z, valid)[0], abs=1e-12)


def test_fuji_static_mesh_bound():
    z, valid = read_fuji()
    d = vertex_errors(z, valid)
    assert np.isinf(d).any() and np.isfinite(d[:256, :256]).all()
    for e in (0.5, 1.0, 5.0, 20.0):
        v, f = static_mesh(d, valid, e)
        e1 = (v[f[:, 1]] - v[f[:, 0]]).astype(float)
        e2 = (v[f[:, 2]] - v[f[:, 0]]).astype(float)
        check_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
        assert check_area == pytest.approx(511 * 511)
        assert mesh_deviation_np(v, f, z, valid) <= e + 1e-9
