"""Per-vertex errors δ, nested sphere radii, per-tile error bounds and static RTIN meshes.

Seed 002 (Lindstrom & Pascucci): δ is the object-space error of a vertex (§2.3), saturated
so that δ(parent) ≥ δ(child) (§2.4, L46), and the bounding-sphere radii nest,
r(v) ≥ |p_v − p_c| + r(c) (§2.4, L50–52), so that the screen-space error of LP eq. 2,
ρ = λ δ / (|p − o| − r), is monotone along the vertex DAG.

Unlike the midpoint-only error of the seed (and of Martini), δ here is the exact maximum
of |z − S| over every valid full-resolution sample of the vertex's closed diamond, S being
the two triangles drawn while the vertex is absent, so δ bounds the vertical error of any
mesh extracted with it. Grid and bintree conventions: docs/conventions.md and
:mod:`geoterrain.bintree`.

Invalid samples
---------------
``valid`` is authoritative (a valid sample with a non-finite height is treated as
invalid). Heights of invalid samples are never read for δ or tile errors. A diamond that
mixes valid and invalid samples gets δ = +inf; an all-invalid one gets 0.

For radii the sphere of every vertex must contain those of its children, valid or not, so
invalid positions are replaced by finite *proxy* positions before nesting: z by the
midpoint of the valid height range (so a valid vertex's radius grows by at most about half
the relief near nodata), and non-finite x or y by an affine fit of the finite ones in
(i, j). Nesting then holds on every DAG edge, and radii of valid vertices stay finite.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bintree import base_triangles, triangle_children

__all__ = [
    "TileBounds",
    "saturate",
    "static_mesh",
    "tile_errors",
    "vertex_errors",
    "vertex_errors_reference",
    "vertex_radii",
]


# --------------------------------------------------------------------------- helpers


def _grid_order(N: int) -> int:
    n = int(N - 1).bit_length() - 1
    if N < 3 or (1 << n) + 1 != N:
        raise ValueError(f"grid side must be 2**n + 1 with n >= 1, got {N}")
    return n


def _check(z: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    z = np.asarray(z, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if z.ndim != 2 or z.shape[0] != z.shape[1] or valid.shape != z.shape:
        raise ValueError(f"z and valid must be the same (N, N) shape, got {z.shape}, "
                         f"{valid.shape}")
    n = _grid_order(z.shape[0])
    if valid.all() and np.isfinite(z).all():
        return np.ascontiguousarray(z), np.ascontiguousarray(valid), n
    valid = valid & np.isfinite(z)
    zf = np.where(valid, z, 0.0)  # invalid heights are never read
    return zf, valid, n


def _round_up_f32(a: np.ndarray) -> np.ndarray:
    """float64 → float32, rounding up so the result still bounds the input."""
    f = a.astype(np.float32)
    low = f.astype(np.float64) < a
    f[low] = np.nextafter(f[low], np.float32(np.inf))
    return f


def _pair_slices(N: int, i0: int, j0: int, step: int, oi: int, oj: int):
    """Slices (vertex, vertex + offset) of the lattice ``[i0::step, j0::step]``, keeping
    only the vertices whose offset partner lies inside the N × N grid."""

    def rng(s0: int, o: int):
        lo = max(0, -((s0 + o) // step)) if s0 + o < 0 else 0
        hi = min((N - 1 - s0) // step, (N - 1 - s0 - o) // step)
        if hi < lo:
            return None
        return (slice(s0 + lo * step, s0 + hi * step + 1, step),
                slice(s0 + o + lo * step, s0 + o + hi * step + 1, step))

    ri, rj = rng(i0, oi), rng(j0, oj)
    if ri is None or rj is None:
        return None
    return (ri[0], rj[0]), (ri[1], rj[1])


def _closed_blocks(a: np.ndarray, s: int, op, dtype=None) -> np.ndarray:
    """``op``-reduction of ``a`` over the closed blocks ``[p*s : (p+1)*s + 1]`` (shared
    borders), separably: rows, then columns. Returns (nb, nb)."""
    N = a.shape[0]
    nb = (N - 1) // s
    r = op.reduce(a[:-1].reshape(nb, s, N), axis=1, dtype=dtype)
    r = op(r, a[s::s])
    c = op.reduce(r[:, :-1].reshape(nb, nb, s), axis=2)
    return op(c, r[:, s::s])


# ------------------------------------------------------------- numba δ kernel (exact)
# Every kernel returns (max |z − S|, status) with status 0 = all invalid, 1 = all valid,
# 2 = mixed; +inf is assigned afterwards in numpy (the kernels are compiled with fast
# math, so they never see a non-finite value: invalid heights are zeroed beforehand).

_FM = True
# Threads hurt on small shared machines (a barrier per level waits for a descheduled
# thread); the loops are written with prange so this switch is all it takes.
_PARALLEL = False


@njit(cache=True, fastmath=_FM)
def _edge_err(z, vb, ic, jc, h, rows, N, check):
    # Diamond of an edge midpoint = |di| + |dj| <= h, clipped to the grid; the hypotenuse
    # runs along the rows (rows=True: endpoints (ic ± h, jc)) or along the columns.
    invh = 1.0 / h
    if rows:
        za = z[ic - h, jc]
        zb = z[ic + h, jc]
    else:
        za = z[ic, jc - h]
        zb = z[ic, jc + h]
    zm = 0.5 * (za + zb)
    g = 0.5 * (zb - za) * invh
    lo_ok = (jc - h >= 0) if rows else (ic - h >= 0)
    hi_ok = (jc + h <= N - 1) if rows else (ic + h <= N - 1)
    k_lo = 0.0
    k_hi = 0.0
    if rows:
        if lo_ok:
            k_lo = (z[ic, jc - h] - zm) * invh
        if hi_ok:
            k_hi = (z[ic, jc + h] - zm) * invh
    else:
        if lo_ok:
            k_lo = (z[ic - h, jc] - zm) * invh
        if hi_ok:
            k_hi = (z[ic + h, jc] - zm) * invh
    m = 0.0
    cnt = 0
    tot = 0
    if rows:
        for di in range(-h, h + 1):
            w = h - abs(di)
            i = ic + di
            line = zm + g * di
            jlo = -w if lo_ok else 0
            jhi = w if hi_ok else 0
            for dj in range(jlo, 1):
                if check and not vb[i, jc + dj]:
                    continue
                m = max(m, abs(z[i, jc + dj] - (line - k_lo * dj)))
                cnt += 1
            for dj in range(1, jhi + 1):
                if check and not vb[i, jc + dj]:
                    continue
                m = max(m, abs(z[i, jc + dj] - (line + k_hi * dj)))
                cnt += 1
            tot += jhi - jlo + 1
    else:
        dlo = -h if lo_ok else 0
        dhi = h if hi_ok else 0
        for di in range(dlo, dhi + 1):
            w = h - abs(di)
            i = ic + di
            k = -k_lo * di if di < 0 else k_hi * di
            base = zm + k
            row = z[i, jc - w:jc + w + 1]
            if check:
                vrow = vb[i, jc - w:jc + w + 1]
                for dj in range(2 * w + 1):
                    if vrow[dj]:
                        m = max(m, abs(row[dj] - (base + g * (dj - w))))
                        cnt += 1
            else:
                for dj in range(2 * w + 1):
                    m = max(m, abs(row[dj] - (base + g * (dj - w))))
            tot += 2 * w + 1
    if not check:
        return m, 1
    if cnt == 0:
        return 0.0, 0
    if cnt < tot:
        return 0.0, 2
    return m, 1


@njit(cache=True, parallel=_PARALLEL)
def _block_status_nb(vb):
    # bs[centre of a closed 2h block] = bit 1: holds a valid sample, bit 2: an invalid one;
    # built fine to coarse (a closed 2h block is the union of its four closed h blocks).
    N = vb.shape[0]
    bs = np.zeros((N, N), np.uint8)
    nb = (N - 1) // 2
    for k in prange(nb * nb):
        bi = k // nb
        bj = k - bi * nb
        f = 0
        for di in range(3):
            for dj in range(3):
                f |= 1 if vb[2 * bi + di, 2 * bj + dj] else 2
        bs[2 * bi + 1, 2 * bj + 1] = f
    h = 2
    while h < N - 1:
        s = 2 * h
        nb = (N - 1) // s
        q = h // 2
        for k in prange(nb * nb):
            bi = k // nb
            bj = k - bi * nb
            ci = bi * s + h
            cj = bj * s + h
            bs[ci, cj] = (bs[ci - q, cj - q] | bs[ci - q, cj + q]
                          | bs[ci + q, cj - q] | bs[ci + q, cj + q])
        h *= 2
    return bs


@njit(cache=True, inline="always")
def _cell_rows(z00, z01, z10, z11, fi, inv, main):
    """Row fi of a union-jack cell's two planes: z = b1 + g1·dj left of the diagonal,
    z = b2 + g2·dj right of it (dj in samples, inv = 1/side).

    ``main``: the diagonal joins (0, 0)–(1, 1); otherwise (0, 1)–(1, 0).
    """
    if main:
        return (z00 + (z10 - z00) * fi, (z11 - z10) * inv,
                z00 + (z11 - z01) * fi, (z01 - z00) * inv)
    return (z00 + (z10 - z00) * fi, (z01 - z00) * inv,
            z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11), -(z10 - z11) * inv)


@njit(cache=True)
def _up32(a):
    # float64 → float32 rounded up (the stored value still bounds the exact one)
    # Same result as np.nextafter(f, +inf) when the rounding went down (a >= 0), without
    # a library call: ff * (1 + 2**-24) lies in [f + ulp/2, f + ulp) and rounds to f + ulp
    # unless f is a power of two (tie to even) or subnormal.
    f = np.float32(a)
    ff = np.float64(f)
    if ff >= a:
        return f
    g = np.float32(ff * (1.0 + 2.0 ** -24))
    if g == f:
        g = np.float32(ff * (1.0 + 2.0 ** -23))
        if g == f:
            g = np.float32(ff + 2.0 ** -149)
    return g


@njit(cache=True, fastmath=_FM)
def _centre1(z, ci, cj, main):
    # h = 1 closed form: only the centre and the 4 edge midpoints of the 3×3 block are
    # not vertices; the block edges are triangle legs, the centre lies on the diagonal.
    z00 = z[ci - 1, cj - 1]
    z01 = z[ci - 1, cj + 1]
    z10 = z[ci + 1, cj - 1]
    z11 = z[ci + 1, cj + 1]
    sc = 0.5 * (z00 + z11) if main else 0.5 * (z01 + z10)
    m = abs(z[ci, cj] - sc)
    m = max(m, abs(z[ci - 1, cj] - 0.5 * (z00 + z01)))
    m = max(m, abs(z[ci + 1, cj] - 0.5 * (z10 + z11)))
    m = max(m, abs(z[ci, cj - 1] - 0.5 * (z00 + z10)))
    m = max(m, abs(z[ci, cj + 1] - 0.5 * (z01 + z11)))
    return m


@njit(cache=True, fastmath=_FM)
def _block_sweep(z, i0, j0, s, main):
    """One pass over an all-valid closed block of side s = 2h: the exact max error of its
    centre (surface = the 2 union-jack halves) and of its 4 quarter triangles (surface of
    the next depth: each quarter's diamond is one quarter of each adjacent block).
    Returns (centre, left, right, top, bottom); quarters are closed (diagonals in both)."""
    h = s // 2
    inv = 1.0 / s
    invh = 1.0 / h
    z00 = z[i0, j0]
    z01 = z[i0, j0 + s]
    z10 = z[i0 + s, j0]
    z11 = z[i0 + s, j0 + s]
    zc = z[i0 + h, j0 + h]
    kl = (zc - 0.5 * (z00 + z10)) * invh
    kr = (zc - 0.5 * (z01 + z11)) * invh
    kt = (zc - 0.5 * (z00 + z01)) * invh
    kb = (zc - 0.5 * (z10 + z11)) * invh
    mc = 0.0
    ml = 0.0
    mr = 0.0
    mt = 0.0
    mb = 0.0
    for di in range(s + 1):
        row = z[i0 + di, j0:j0 + s + 1]
        fi = di * inv
        # centre surface: P1 left of the union-jack diagonal, P2 right of it
        b1, g1, b2, g2 = _cell_rows(z00, z01, z10, z11, fi, inv, main)
        upper = di <= h
        lo = di if upper else s - di
        hi = s - di if upper else di
        use1 = (not upper) if main else upper  # plane of the middle segment
        bm = b1 if use1 else b2
        gm = g1 if use1 else g2
        # quarter surfaces along this row
        bl = z00 + (z10 - z00) * fi
        br = z01 + (z11 - z01) * fi + kr * s
        if upper:
            bq = z00 + kt * di
            gq = (z01 - z00) * inv
        else:
            bq = z10 + kb * (s - di)
            gq = (z11 - z10) * inv
        a = 0.0
        q = 0.0
        for dj in range(lo):
            zz = row[dj]
            a = max(a, abs(zz - (b1 + g1 * dj)))
            q = max(q, abs(zz - (bl + kl * dj)))
        ml = max(ml, q)
        q = 0.0
        for dj in range(lo, hi + 1):
            zz = row[dj]
            a = max(a, abs(zz - (bm + gm * dj)))
            q = max(q, abs(zz - (bq + gq * dj)))
        if upper:
            mt = max(mt, q)
        if di >= h:
            mb = max(mb, q)
        q = 0.0
        for dj in range(hi + 1, s + 1):
            zz = row[dj]
            a = max(a, abs(zz - (b2 + g2 * dj)))
            q = max(q, abs(zz - (br - kr * dj)))
        mr = max(mr, q)
        mc = max(mc, a)
        # the two diagonal samples also belong to the left / right quarters
        ml = max(ml, abs(row[lo] - (bl + kl * lo)))
        mr = max(mr, abs(row[hi] - (br - kr * hi)))
    return mc, ml, mr, mt, mb


@njit(cache=True, parallel=_PARALLEL)
def _raw_delta_nb(z, vb, all_valid, hlo=1, hhi=1 << 62):
    """Raw exact δ, float32 rounded up (+inf for mixed diamonds)."""
    N = z.shape[0]
    out = np.zeros((N, N), np.float32)
    if all_valid:
        bs = np.ones((1, 1), np.uint8)
    else:
        bs = _block_status_nb(vb)
    nq = max((N - 1) // 4, 1)
    QL = np.empty((nq, nq))
    QR = np.empty((nq, nq))
    QT = np.empty((nq, nq))
    QB = np.empty((nq, nq))
    h = hlo
    while h < N - 1 and h <= hhi:
        s = 2 * h
        nb = (N - 1) // s
        # centres of the 2h blocks (+ quarter maxima for the edge midpoints, h >= 2)
        for bi in prange(nb):
            for bj in range(nb):
                ci = bi * s + h
                cj = bj * s + h
                f = 1 if all_valid else bs[ci, cj]
                main = (bi + bj) % 2 == 0
                if f == 1:
                    if h == 1:
                        m = _centre1(z, ci, cj, main)
                    else:
                        m, ml, mr, mt, mb = _block_sweep(z, bi * s, bj * s, s, main)
                        QL[bi, bj] = ml
                        QR[bi, bj] = mr
                        QT[bi, bj] = mt
                        QB[bi, bj] = mb
                    out[ci, cj] = _up32(m)
                elif f == 3:
                    out[ci, cj] = np.inf
        # edge midpoints: hypotenuse along the rows (typ 0) or along the columns (typ 1)
        for typ in range(2):
            rows = typ == 0
            na = nb if rows else nb + 1
            nc = nb + 1 if rows else nb
            for a in prange(na):
                for b in range(nc):
                    ic = h + a * s if rows else a * s
                    jc = b * s if rows else h + b * s
                    # adjacent blocks (lo side, hi side) and their status
                    f = 0
                    flo = 0
                    fhi = 0
                    if rows:
                        if jc > 0:
                            flo = 1 if all_valid else bs[ic, jc - h]
                        if jc < N - 1:
                            fhi = 1 if all_valid else bs[ic, jc + h]
                    else:
                        if ic > 0:
                            flo = 1 if all_valid else bs[ic - h, jc]
                        if ic < N - 1:
                            fhi = 1 if all_valid else bs[ic + h, jc]
                    f = flo | fhi
                    if f == 2:
                        continue
                    if f == 1:
                        if h == 1:
                            if rows:
                                m = abs(z[ic, jc] - 0.5 * (z[ic - 1, jc] + z[ic + 1, jc]))
                            else:
                                m = abs(z[ic, jc] - 0.5 * (z[ic, jc - 1] + z[ic, jc + 1]))
                        else:
                            m = 0.0
                            if rows:
                                if flo:
                                    m = max(m, QR[a, b - 1])
                                if fhi:
                                    m = max(m, QL[a, b])
                            else:
                                if flo:
                                    m = max(m, QB[a - 1, b])
                                if fhi:
                                    m = max(m, QT[a, b])
                        out[ic, jc] = _up32(m)
                        continue
                    m, c = _edge_err(z, vb, ic, jc, h, rows, N, True)
                    if c == 2:
                        out[ic, jc] = np.inf
                    elif c == 1:
                        out[ic, jc] = _up32(m)
        h *= 2
    return out


@njit(cache=True)
def _saturate_nb(d):
    # LP §2.4 (L46): push every vertex's δ to its 1–2 parents, depths fine to coarse.
    N = d.shape[0]
    h = 1
    while h < N - 1:
        s = 2 * h
        nb = (N - 1) // s
        for a in range(nb):  # along-rows edges (h + a s, b s) → centres (i, j ± h)
            for b in range(nb + 1):
                i = h + a * s
                j = b * s
                v = d[i, j]
                if j > 0 and d[i, j - h] < v:
                    d[i, j - h] = v
                if j < N - 1 and d[i, j + h] < v:
                    d[i, j + h] = v
        for a in range(nb + 1):  # along-columns edges (a s, h + b s) → centres (i ± h, j)
            for b in range(nb):
                i = a * s
                j = h + b * s
                v = d[i, j]
                if i > 0 and d[i - h, j] < v:
                    d[i - h, j] = v
                if i < N - 1 and d[i + h, j] < v:
                    d[i + h, j] = v
        for a in range(nb):  # centres → the two corners off the split diagonal
            for b in range(nb):
                i = h + a * s
                j = h + b * s
                v = d[i, j]
                sg = 1 if (a + b) % 2 == 0 else -1
                if d[i - h, j + sg * h] < v:
                    d[i - h, j + sg * h] = v
                if d[i + h, j - sg * h] < v:
                    d[i + h, j - sg * h] = v
        h *= 2
    d[0, 0] = 0
    d[0, N - 1] = 0
    d[N - 1, 0] = 0
    d[N - 1, N - 1] = 0
    return d


def _raw_delta(zf: np.ndarray, valid: np.ndarray) -> np.ndarray:
    return _raw_delta_nb(zf, valid.view(np.uint8), bool(valid.all()))


# ----------------------------------------------------------- numpy reference for δ


def _surface_np(zf: np.ndarray, h: int, quarters: bool) -> np.ndarray:
    """Full-grid uniform surface of the cut whose split vertices have half-size ``h``:
    union-jack half-squares of side 2h (``quarters=False``, even depth) or the four
    quarter triangles of each 2h block (``quarters=True``, odd depth)."""
    N = zf.shape[0]
    s = 2 * h
    nb = (N - 1) // s
    ar = np.arange(N)
    bi = np.minimum(ar // s, nb - 1)
    I0 = (bi * s)[:, None]
    J0 = (bi * s)[None, :]
    di = (ar - bi * s)[:, None].astype(np.float64)
    dj = (ar - bi * s)[None, :].astype(np.float64)
    z00 = zf[I0, J0]
    z01 = zf[I0, J0 + s]
    z10 = zf[I0 + s, J0]
    z11 = zf[I0 + s, J0 + s]
    if not quarters:
        main = ((bi[:, None] + bi[None, :]) % 2) == 0
        up = z00 + (z01 - z00) * (dj / s) + (z11 - z01) * (di / s)
        lo = z00 + (z10 - z00) * (di / s) + (z11 - z10) * (dj / s)
        ul = z00 + (z10 - z00) * (di / s) + (z01 - z00) * (dj / s)
        lr = z11 + (z01 - z11) * ((s - di) / s) + (z10 - z11) * ((s - dj) / s)
        return np.where(main, np.where(dj >= di, up, lo), np.where(di + dj <= s, ul, lr))
    zc = zf[I0 + h, J0 + h]
    top = z00 + (z01 - z00) * (dj / s) + (zc - 0.5 * (z00 + z01)) * (di / h)
    bot = z10 + (z11 - z10) * (dj / s) + (zc - 0.5 * (z10 + z11)) * ((s - di) / h)
    lef = z00 + (z10 - z00) * (di / s) + (zc - 0.5 * (z00 + z10)) * (dj / h)
    rig = z01 + (z11 - z01) * (di / s) + (zc - 0.5 * (z01 + z11)) * ((s - dj) / h)
    upper = di <= dj  # above the main diagonal
    upper_left = di + dj <= s  # above the anti-diagonal
    return np.where(upper, np.where(upper_left, top, rig), np.where(upper_left, lef, bot))


def _block_view(a: np.ndarray, s: int) -> np.ndarray:
    nb = (a.shape[0] - 1) // s
    st0, st1 = a.strides
    return np.lib.stride_tricks.as_strided(
        a, shape=(nb, nb, s + 1, s + 1), strides=(s * st0, s * st1, st0, st1), writeable=False)


def vertex_errors_reference(z: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Pure-numpy reference of the raw (unsaturated) exact δ, float64 (N, N).

    One full-grid pass per bintree depth against the uniform surface one depth up; slow
    (about 30 s on 4097²) and memory-hungry, kept to cross-check the compiled kernel.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> vertex_errors_reference(z, np.ones((3, 3), bool))[1, 1]
    np.float64(2.0)
    """
    zf, valid, n = _check(z, valid)
    N = zf.shape[0]
    out = np.zeros((N, N))
    vf = valid.astype(np.float64)
    h = 1
    while h < N - 1:
        s = 2 * h
        # Even depth: centres of the 2h blocks, diamond = closed block.
        E = np.where(valid, np.abs(zf - _surface_np(zf, h, False)), 0.0)
        m = _closed_blocks(E, s, np.maximum)
        av = _closed_blocks(vf, s, np.maximum) > 0
        ai = _closed_blocks(1.0 - vf, s, np.maximum) > 0
        out[h::s, h::s] = np.where(av & ai, np.inf, np.where(av, m, 0.0))
        # Odd depth: edge midpoints; diamond = one quarter triangle of each adjacent block.
        E = np.where(valid, np.abs(zf - _surface_np(zf, h, True)), 0.0)
        di = np.arange(s + 1)[:, None]
        dj = np.arange(s + 1)[None, :]
        masks = {"top": (di <= dj) & (di + dj <= s), "bot": (di >= dj) & (di + dj >= s),
                 "lef": (dj <= di) & (di + dj <= s), "rig": (dj >= di) & (di + dj >= s)}
        Eb, Vb = _block_view(E, s), _block_view(vf, s)
        q = {}
        for key, mk in masks.items():
            q[key] = ((Eb * mk).max(axis=(2, 3)), (Vb * mk).max(axis=(2, 3)) > 0,
                      ((1.0 - Vb) * mk).max(axis=(2, 3)) > 0)
        nb = (N - 1) // s
        for lo, hi, shape, sl_lo, sl_hi, dst in (
            ("rig", "lef", (nb, nb + 1), np.s_[:, 1:], np.s_[:, :-1], np.s_[h::s, ::s]),
            ("bot", "top", (nb + 1, nb), np.s_[1:, :], np.s_[:-1, :], np.s_[::s, h::s]),
        ):
            M = np.zeros(shape)
            AV = np.zeros(shape, bool)
            AI = np.zeros(shape, bool)
            for key, sl in ((lo, sl_lo), (hi, sl_hi)):
                M[sl] = np.maximum(M[sl], q[key][0])
                AV[sl] |= q[key][1]
                AI[sl] |= q[key][2]
            out[dst] = np.where(AV & AI, np.inf, np.where(AV, M, 0.0))
        h *= 2
    return out


# --------------------------------------------------------------------- saturation


def saturate(delta: np.ndarray) -> np.ndarray:
    """Saturate δ over the vertex DAG in place (seed 002 §2.4, L46): δ(parent) ≥ δ(child).

    Processes depths fine to coarse, pushing each vertex's value to its one or two parents
    with strided slices. The four domain corners are reset to 0.

    Examples
    --------
    >>> d = np.zeros((5, 5)); d[1, 0] = 3.0
    >>> saturate(d)[[1, 2], [1, 2]].tolist()
    [3.0, 3.0]
    """
    N = delta.shape[0]
    _grid_order(N)
    h = 1
    while h < N - 1:
        s = 2 * h
        # edge(h) → centres(h): along-rows edges have parents (i, j ± h), along-cols (i ± h, j).
        for i0, j0, offs in ((h, 0, ((0, -h), (0, h))), (0, h, ((-h, 0), (h, 0)))):
            for oi, oj in offs:
                p = _pair_slices(N, i0, j0, s, oi, oj)
                if p is not None:
                    np.maximum(delta[p[1]], delta[p[0]], out=delta[p[1]])
        # centres(h) → 2 corners of their block on the non-split diagonal (union-jack parity)
        for pa in (0, 1):
            for pb in (0, 1):
                if (pa or pb) and (N - 1) // s < 2:
                    continue
                if (pa + pb) % 2 == 0:  # split along the main diagonal
                    offs = ((-h, h), (h, -h))
                else:
                    offs = ((-h, -h), (h, h))
                for oi, oj in offs:
                    p = _pair_slices(N, h + s * pa, h + s * pb, 2 * s, oi, oj)
                    if p is not None:
                        np.maximum(delta[p[1]], delta[p[0]], out=delta[p[1]])
        h *= 2
    delta[:: N - 1, :: N - 1] = 0.0
    return delta


def vertex_errors(z: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Exact, saturated per-vertex errors δ, float32 (N, N) rounded up.

    δ(v) = max over the valid full-resolution samples of v's closed diamond of |z − S|, S
    being the two diamond triangles drawn while v is absent (seed 002 §2.3, but the exact
    maximum, not the midpoint error); +inf if the diamond mixes valid and invalid samples,
    0 if it is all invalid; then saturated so δ(parent) ≥ δ(child) (§2.4, L46). The
    domain corners get 0. Computed by a compiled kernel in O(N² log N).

    Parameters
    ----------
    z : (N, N) float64 heights in scene units, N = 2**n + 1 (invalid values ignored).
    valid : (N, N) bool.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> d = vertex_errors(z, np.ones((3, 3), bool))
    >>> d.dtype, float(d[1, 1]), float(d[0, 1])
    (dtype('float32'), 2.0, 0.0)
    """
    zf, valid, _ = _check(z, valid)
    return _saturate_nb(_raw_delta(zf, valid))


# ---------------------------------------------------------------------------- radii


def _proxy_positions(x, y, z, valid):
    z = np.ascontiguousarray(z, dtype=np.float64)
    valid = np.asarray(valid, dtype=bool)
    if valid.all() and np.isfinite(z).all():
        zp = z
    else:
        valid = valid & np.isfinite(z)
        zv = z[valid]
        fill = 0.5 * (zv.min() + zv.max()) if zv.size else 0.0
        zp = np.where(valid, z, fill)
    out = [zp]
    for c in (x, y):
        c = np.ascontiguousarray(c, dtype=np.float64)
        if not np.isfinite(c).all():
            ok = np.isfinite(c)
            ii, jj = np.nonzero(ok)
            if ii.size:
                A = np.stack([ii, jj, np.ones_like(ii)], 1).astype(np.float64)
                coef = np.linalg.lstsq(A, c[ok], rcond=None)[0]
            else:
                coef = np.zeros(3)
            ii_, jj_ = np.indices(c.shape)
            c = np.where(ok, c, coef[0] * ii_ + coef[1] * jj_ + coef[2])
        out.append(c)
    return out[1], out[2], out[0]


def vertex_radii(x: np.ndarray, y: np.ndarray, z: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Nested bounding-sphere radii (seed 002 §2.4, L50–52), float32 (N, N) rounded up.

    r = 0 for the finest vertices (and the 4 corners); otherwise
    r(v) = max over children c of |p_v − p_c| + r(c) with p = (x, y, z) in 3-D scene
    coordinates (curvilinear x, y are fine), computed coarse-from-fine. Each level is
    rounded up to float32 before its parents use it, so r32(v) ≥ |p_v − p_c| + r32(c)
    holds for the stored values. Invalid positions are replaced by finite proxies (see the
    module docstring), so nesting holds on every DAG edge.

    Examples
    --------
    >>> I, J = np.indices((3, 3)).astype(float)
    >>> r = vertex_radii(J, -I, np.zeros((3, 3)), np.ones((3, 3), bool))
    >>> float(r[1, 1]), float(r[0, 1])
    (1.0, 0.0)
    """
    x, y, z = _proxy_positions(x, y, z, valid)
    _grid_order(z.shape[0])
    return _radii_nb(x, y, z)


@njit(cache=True)
def _relax(x, y, z, r, i, j, oi, oj, best):
    d = np.sqrt((x[i, j] - x[i + oi, j + oj]) ** 2 + (y[i, j] - y[i + oi, j + oj]) ** 2
                + (z[i, j] - z[i + oi, j + oj]) ** 2) + np.float64(r[i + oi, j + oj])
    return max(best, d)


@njit(cache=True, parallel=_PARALLEL)
def _radii_nb(x, y, z):
    # LP §2.4 (L50–52): r(v) = max over children c of |p_v − p_c| + r(c), fine to coarse;
    # each level is rounded up to float32 before its parents read it.
    N = z.shape[0]
    r = np.zeros((N, N), np.float32)
    h = 1
    while h < N - 1:
        s = 2 * h
        nb = (N - 1) // s
        if h >= 2:  # edge(h) → children: centres of the (up to) four h/2 blocks around it
            q = h // 2
            for typ in range(2):
                rows = typ == 0
                na = nb if rows else nb + 1
                nc = nb + 1 if rows else nb
                for a in prange(na):
                    for b in range(nc):
                        i = h + a * s if rows else a * s
                        j = b * s if rows else h + b * s
                        best = 0.0
                        for oi in (-q, q):
                            for oj in (-q, q):
                                if 0 <= i + oi <= N - 1 and 0 <= j + oj <= N - 1:
                                    best = _relax(x, y, z, r, i, j, oi, oj, best)
                        r[i, j] = _up32(best)
        for a in prange(nb):  # centre(h) → its 4 edge(h) midpoints
            for b in range(nb):
                i = h + a * s
                j = h + b * s
                best = _relax(x, y, z, r, i, j, -h, 0, 0.0)
                best = _relax(x, y, z, r, i, j, h, 0, best)
                best = _relax(x, y, z, r, i, j, 0, -h, best)
                best = _relax(x, y, z, r, i, j, 0, h, best)
                r[i, j] = _up32(best)
        h *= 2
    return r


# ---------------------------------------------------------------------- tile errors


class TileBounds(NamedTuple):
    """Bounds of one stored tile, in the column order of the store's tile table."""

    nvalid: int
    zmin: float
    zmax: float
    error: float
    boundary_error: float
    xmin: float
    xmax: float
    ymin: float
    ymax: float


@njit(cache=True)
def _level_field_nb(z, vf, s, E):
    # E = max over the all-valid closed triangles containing a sample of |z − S_L| (0 if
    # none), S_L the union-jack surface of cell size s; and per cell whether one of its
    # two closed triangles mixes valid and invalid samples.
    N = z.shape[0]
    nb = (N - 1) // s
    E[:, :] = 0.0
    mixed = np.zeros((nb, nb), np.bool_)
    inv = 1.0 / s
    for bi in range(nb):
        for bj in range(nb):
            i0 = bi * s
            j0 = bj * s
            main = (bi + bj) % 2 == 0
            tot = 0
            for di in range(s + 1):
                for dj in range(s + 1):
                    tot += vf[i0 + di, j0 + dj]
            if tot == 0:
                continue
            z00 = z[i0, j0]
            z01 = z[i0, j0 + s]
            z10 = z[i0 + s, j0]
            z11 = z[i0 + s, j0 + s]
            if tot == (s + 1) * (s + 1):  # all valid: split each row at the diagonal
                for di in range(s + 1):
                    i = i0 + di
                    fi = di * inv
                    b1, g1, b2, g2 = _cell_rows(z00, z01, z10, z11, fi, inv, main)
                    cut = di if main else s - di + 1
                    for dj in range(cut):
                        e = abs(z[i, j0 + dj] - (b1 + g1 * dj))
                        if e > E[i, j0 + dj]:
                            E[i, j0 + dj] = e
                    for dj in range(cut, s + 1):
                        e = abs(z[i, j0 + dj] - (b2 + g2 * dj))
                        if e > E[i, j0 + dj]:
                            E[i, j0 + dj] = e
                continue
            c1 = 0.0
            c2 = 0.0
            t1 = 0.0
            t2 = 0.0
            for di in range(s + 1):
                for dj in range(s + 1):
                    first = dj >= di if main else di + dj <= s
                    both = dj == di if main else di + dj == s
                    v = np.float64(vf[i0 + di, j0 + dj])
                    if first or both:
                        c1 += v
                        t1 += 1.0
                    if (not first) or both:
                        c2 += v
                        t2 += 1.0
            ok1 = c1 == t1
            ok2 = c2 == t2
            mixed[bi, bj] = (0.0 < c1 < t1) or (0.0 < c2 < t2)
            if not (ok1 or ok2):
                continue
            for di in range(s + 1):
                i = i0 + di
                for dj in range(s + 1):
                    j = j0 + dj
                    if main:
                        first = dj >= di
                        both = dj == di
                    else:
                        first = di + dj <= s
                        both = di + dj == s
                    if both:
                        first = ok1
                    if not (ok1 if first else ok2):
                        continue
                    if main:
                        if first:
                            S = z00 + (z01 - z00) * (dj * inv) + (z11 - z01) * (di * inv)
                        else:
                            S = z00 + (z10 - z00) * (di * inv) + (z11 - z10) * (dj * inv)
                    else:
                        if first:
                            S = z00 + (z10 - z00) * (di * inv) + (z01 - z00) * (dj * inv)
                        else:
                            S = (z11 + (z01 - z11) * ((s - di) * inv)
                                 + (z10 - z11) * ((s - dj) * inv))
                    e = abs(z[i, j] - S)
                    if e > E[i, j]:
                        E[i, j] = e
    return mixed


@njit(cache=True)
def _tile_stats_nb(z, x, y, vb, S):
    # Per closed tile footprint of span S: valid count and the box of the valid samples.
    N = z.shape[0]
    nt = (N - 1) // S
    cnt = np.zeros((nt, nt), np.int64)
    box = np.empty((6, nt, nt))
    for k in range(3):
        box[2 * k] = np.inf
        box[2 * k + 1] = -np.inf
    for i in range(N):
        ty0 = min(i // S, nt - 1)
        ty1 = i // S - 1 if (i % S == 0 and i > 0) else ty0  # border rows: two tiles
        for j in range(N):
            if not vb[i, j]:
                continue
            tx0 = min(j // S, nt - 1)
            tx1 = j // S - 1 if (j % S == 0 and j > 0) else tx0
            for ty in range(ty1, ty0 + 1):
                for tx in range(tx1, tx0 + 1):
                    cnt[ty, tx] += 1
                    box[0, ty, tx] = min(box[0, ty, tx], z[i, j])
                    box[1, ty, tx] = max(box[1, ty, tx], z[i, j])
                    box[2, ty, tx] = min(box[2, ty, tx], x[i, j])
                    box[3, ty, tx] = max(box[3, ty, tx], x[i, j])
                    box[4, ty, tx] = min(box[4, ty, tx], y[i, j])
                    box[5, ty, tx] = max(box[5, ty, tx], y[i, j])
    return cnt, box


def tile_errors(
    z: np.ndarray, valid: np.ndarray, x: np.ndarray, y: np.ndarray, t: int = 6
) -> dict[tuple[int, int, int], TileBounds]:
    """Error bounds of every stored tile ``(L, x, y)`` of the pyramid (docs/conventions.md).

    Returns a dict keyed by ``(L, x, y)`` (x counts columns, y rows) of :class:`TileBounds`
    (a NamedTuple ordered like the store's tile columns) for every tile whose footprint
    holds a valid sample:

    * ``error``: max over the valid footprint samples of |z − S_L|, S_L the union-jack
      uniform surface of level L; +inf if a level-L triangle of the tile (closed, drawn or
      not) mixes valid and invalid samples (level 0 is the data itself: always 0); then
      made monotone up the quadtree (parent ≥ its children).
    * ``boundary_error``: the same max over the samples on the tile's four border lines
      (what a skirt must cover); +inf if a mixed triangle lies in a border cell.
    * ``zmin, zmax, xmin, xmax, ymin, ymax``: box of the valid footprint samples in scene
      coordinates; ``nvalid``: number of valid footprint samples (borders included).

    Examples
    --------
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> tb = tile_errors(I * J, np.ones((5, 5), bool), J, -I, t=1)
    >>> sorted(tb), tb[(1, 0, 0)].error, tb[(1, 0, 0)].nvalid
    ([(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 0)], 1.0, 25)
    """
    zf, valid, n = _check(z, valid)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    N = zf.shape[0]
    te = min(t, n)
    lmax = n - te
    cpt = 1 << te  # cells per tile side
    vb = valid.view(np.uint8)
    xc = np.ascontiguousarray(x)
    yc = np.ascontiguousarray(y)
    E = np.zeros((N, N))
    per_level = []
    for L in range(lmax + 1):
        S = 1 << (te + L)  # tile span in full-resolution samples
        nt = (N - 1) // S
        if L == 0:
            mixed = np.zeros((nt * cpt, nt * cpt), bool)
        else:
            mixed = _level_field_nb(zf, vb, 1 << L, E)
        err = _closed_blocks(E, S, np.maximum)
        m4 = mixed.reshape(nt, cpt, nt, cpt)
        err = np.where(m4.any(axis=(1, 3)), np.inf, err)
        rows = np.maximum.reduce(E[::S, :-1].reshape(nt + 1, nt, S), axis=2)
        rows = np.maximum(rows, E[::S, S::S])
        cols = np.maximum.reduce(E[:-1, ::S].reshape(nt, S, nt + 1), axis=1)
        cols = np.maximum(cols, E[S::S, ::S])
        bnd = np.maximum(np.maximum(rows[:-1], rows[1:]), np.maximum(cols[:, :-1], cols[:, 1:]))
        border = (m4[:, 0].any(axis=2) | m4[:, -1].any(axis=2)
                  | m4[:, :, :, 0].any(axis=1) | m4[:, :, :, -1].any(axis=1))
        bnd = np.where(border, np.inf, bnd)
        nval = _closed_blocks(vb, S, np.add, dtype=np.int64)
        if L == 0:
            box = _tile_stats_nb(zf, xc, yc, vb, S)[1]
        else:  # a parent's closed footprint is the union of its 4 children's
            b4 = per_level[-1][2].reshape(6, nt, 2, nt, 2)
            box = np.empty((6, nt, nt))
            box[0::2] = b4[0::2].min(axis=(2, 4))
            box[1::2] = b4[1::2].max(axis=(2, 4))
        per_level.append((err, bnd, box, nval))
    for L in range(1, lmax + 1):  # monotone up the quadtree
        child = per_level[L - 1][0]
        nt = child.shape[0] // 2
        cmax = child.reshape(nt, 2, nt, 2).max(axis=(1, 3))
        np.maximum(per_level[L][0], cmax, out=per_level[L][0])
    out: dict[tuple[int, int, int], TileBounds] = {}
    for L, (err, bnd, box, nval) in enumerate(per_level):
        for ty, tx in zip(*np.nonzero(nval > 0), strict=True):
            out[(L, int(tx), int(ty))] = TileBounds(
                int(nval[ty, tx]), float(box[0, ty, tx]), float(box[1, ty, tx]),
                float(err[ty, tx]), float(bnd[ty, tx]), float(box[2, ty, tx]),
                float(box[3, ty, tx]), float(box[4, ty, tx]), float(box[5, ty, tx]))
    return out


# ---------------------------------------------------------------------- static mesh


def static_mesh(
    delta: np.ndarray, valid: np.ndarray, max_error: float
) -> tuple[np.ndarray, np.ndarray]:
    """Static RTIN extraction (Martini): refine every triangle whose split vertex has
    δ > ``max_error``, depth by depth on arrays of triangles.

    Emits the leaf triangles whose three corners are valid. With a saturated δ the mesh is
    conforming (no T-junctions) and, δ being exact, its vertical error at every covered
    valid sample is ≤ ``max_error``.

    Returns
    -------
    vertices_ij : (V, 2) int64 (i, j) grid indices, sorted by flat index i*N + j.
    faces : (F, 3) int64 indices into ``vertices_ij``, counter-clockwise seen from above
        with X east and Y north (rows grow southwards).

    Examples
    --------
    >>> v, f = static_mesh(np.zeros((3, 3), np.float32), np.ones((3, 3), bool), 0.1)
    >>> v.tolist(), f.tolist()
    ([[0, 0], [0, 2], [2, 0], [2, 2]], [[0, 3, 1], [3, 0, 2]])
    """
    delta = np.asarray(delta)
    valid = np.asarray(valid, dtype=bool)
    N = delta.shape[0]
    n = _grid_order(N)
    a, b, c = (t.astype(np.int32) for t in base_triangles(n))
    leaves = []
    for _ in range(2 * n):
        m = (a + b) // 2
        split = delta[m[:, 0], m[:, 1]] > max_error
        keep = ~split
        leaves.append((a[keep], b[keep], c[keep]))
        a, b, c = triangle_children(a[split], b[split], c[split])
    leaves.append((a, b, c))
    tri = np.stack([np.concatenate([lv[k] for lv in leaves]) for k in range(3)], axis=1)
    flat = tri[..., 0].astype(np.int64) * N + tri[..., 1]
    ok = valid.ravel()[flat].all(axis=1)
    flat = flat[ok]
    uniq, inv = np.unique(flat, return_inverse=True)
    verts = np.stack([uniq // N, uniq % N], axis=1)
    return verts, inv.reshape(-1, 3).astype(np.int64)
