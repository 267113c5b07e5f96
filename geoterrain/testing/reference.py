"""Slow numpy oracles: the references that tests and benchmarks check the pipeline against.

Never imported by the pipeline (no module of :mod:`geoterrain` imports this one): each
function here is a plain, vectorised re-statement of a rule that production computes in
a compiled kernel, kept only so that the kernels can be compared with it.

- :func:`vertex_errors_reference`: the raw exact δ of :func:`geoterrain.bounds.delta.vertex_errors`
  (before saturation), one full-grid pass per bintree depth;
- :func:`saturate`: saturation δ(parent) ≥ δ(child) with strided slices;
- :func:`static_mesh`: static RTIN (Martini) extraction at one vertical error;
- :func:`normal_map_reference`: :func:`geoterrain.bounds.normals.normal_map` in numpy.
"""

from __future__ import annotations

import numpy as np

from geoterrain.bounds.delta import check_grid, grid_order
from geoterrain.core.bintree import base_triangles, triangle_children

__all__ = ["normal_map_reference", "saturate", "static_mesh", "vertex_errors_reference",
           "visible_samples"]


# ------------------------------------------------------------------------------ δ


def _surface_np(zf: np.ndarray, h: int, quarters: bool) -> np.ndarray:
    """Full-grid uniform surface of the cut whose split vertices have half-size ``h``:
    union-jack half-squares of side 2h (``quarters=False``, even depth) or the four
    quarter triangles of each 2h block (``quarters=True``, odd depth). The grid may be
    a rectangle of whole blocks (a root grid's extent)."""
    R, C = zf.shape
    s = 2 * h
    bi = np.minimum(np.arange(R) // s, (R - 1) // s - 1)
    bj = np.minimum(np.arange(C) // s, (C - 1) // s - 1)
    I0 = (bi * s)[:, None]
    J0 = (bj * s)[None, :]
    di = (np.arange(R) - bi * s)[:, None].astype(np.float64)
    dj = (np.arange(C) - bj * s)[None, :].astype(np.float64)
    z00 = zf[I0, J0]
    z01 = zf[I0, J0 + s]
    z10 = zf[I0 + s, J0]
    z11 = zf[I0 + s, J0 + s]
    if not quarters:
        main = ((bi[:, None] + bj[None, :]) % 2) == 0
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
    nr, nc = ((k - 1) // s for k in a.shape)
    st0, st1 = a.strides
    return np.lib.stride_tricks.as_strided(
        a, shape=(nr, nc, s + 1, s + 1), strides=(s * st0, s * st1, st0, st1), writeable=False)


def _closed_blocks(a: np.ndarray, s: int, op) -> np.ndarray:
    """``op``-reduction over the closed s-blocks of a rectangle of whole blocks."""
    return op.reduce(op.reduce(_block_view(a, s), axis=3), axis=2)


def vertex_errors_reference(z: np.ndarray, valid: np.ndarray, span: int | None = None
                            ) -> np.ndarray:
    """Pure-numpy reference of the raw (unsaturated) exact δ, float64 (N, N), or of a
    root grid's extent with roots of side ``span`` (the vertices of half-span below it).

    One full-grid pass per bintree depth against the uniform surface one depth up; slow
    (about 30 s on 4097²) and memory-hungry, kept to cross-check the compiled kernel.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
    >>> vertex_errors_reference(z, np.ones((3, 3), bool))[1, 1]
    np.float64(2.0)
    """
    zf, valid, n = check_grid(z, valid, span)
    R, C = zf.shape
    out = np.zeros((R, C))
    vf = valid.astype(np.float64)
    h = 1
    while h < 1 << n:
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
        nr, nc = (R - 1) // s, (C - 1) // s
        for lo, hi, shape, sl_lo, sl_hi, dst in (
            ("rig", "lef", (nr, nc + 1), np.s_[:, 1:], np.s_[:, :-1], np.s_[h::s, ::s]),
            ("bot", "top", (nr + 1, nc), np.s_[1:, :], np.s_[:-1, :], np.s_[::s, h::s]),
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


def _pair_slices(shape: tuple[int, int], i0: int, j0: int, step: int, oi: int, oj: int):
    """Slices (vertex, vertex + offset) of the lattice ``[i0::step, j0::step]``, keeping
    only the vertices whose offset partner lies inside the (rows, cols) grid."""

    def rng(N: int, s0: int, o: int):
        lo = max(0, -((s0 + o) // step)) if s0 + o < 0 else 0
        hi = min((N - 1 - s0) // step, (N - 1 - s0 - o) // step)
        if hi < lo:
            return None
        return (slice(s0 + lo * step, s0 + hi * step + 1, step),
                slice(s0 + o + lo * step, s0 + o + hi * step + 1, step))

    ri, rj = rng(shape[0], i0, oi), rng(shape[1], j0, oj)
    if ri is None or rj is None:
        return None
    return (ri[0], rj[0]), (ri[1], rj[1])


def saturate(delta: np.ndarray, span: int | None = None) -> np.ndarray:
    """Saturate δ over the vertex DAG in place (seed 002 §2.4, L46): δ(parent) ≥ δ(child).

    Processes depths fine to coarse, pushing each vertex's value to its one or two parents
    with strided slices. The four domain corners are reset to 0 (every root's corners on
    a root grid of root side ``span``).

    Examples
    --------
    >>> d = np.zeros((5, 5)); d[1, 0] = 3.0
    >>> saturate(d)[[1, 2], [1, 2]].tolist()
    [3.0, 3.0]
    """
    R, C = delta.shape
    span = R - 1 if span is None else span
    grid_order(span + 1)
    h = 1
    while h < span:
        s = 2 * h
        # edge(h) → centres(h): along-rows edges have parents (i, j ± h), along-cols (i ± h, j).
        for i0, j0, offs in ((h, 0, ((0, -h), (0, h))), (0, h, ((-h, 0), (h, 0)))):
            for oi, oj in offs:
                p = _pair_slices((R, C), i0, j0, s, oi, oj)
                if p is not None:
                    np.maximum(delta[p[1]], delta[p[0]], out=delta[p[1]])
        # centres(h) → 2 corners of their block on the non-split diagonal (union-jack parity)
        for pa in (0, 1):
            for pb in (0, 1):
                if (pa and (R - 1) // s < 2) or (pb and (C - 1) // s < 2):
                    continue
                if (pa + pb) % 2 == 0:  # split along the main diagonal
                    offs = ((-h, h), (h, -h))
                else:
                    offs = ((-h, -h), (h, h))
                for oi, oj in offs:
                    p = _pair_slices((R, C), h + s * pa, h + s * pb, 2 * s, oi, oj)
                    if p is not None:
                        np.maximum(delta[p[1]], delta[p[0]], out=delta[p[1]])
        h *= 2
    delta[::span, ::span] = 0.0
    return delta


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
    n = grid_order(N)
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


# --------------------------------------------------------------------- normal map


def _axis_tangent(p: np.ndarray, v: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-index tangent dP/d(index) along ``axis`` and whether one exists.

    Central difference (P[k+1] - P[k-1]) / 2 where both neighbours are valid, one-sided
    difference where only one is, none (zero, flag False) where neither is.
    """
    n = p.shape[axis]
    pp = np.moveaxis(p, axis, 0)
    vv = np.moveaxis(v, axis, 0)
    fwd = np.zeros_like(pp)
    bwd = np.zeros_like(pp)
    hf = np.zeros(vv.shape, bool)
    hb = np.zeros(vv.shape, bool)
    if n > 1:
        fwd[:-1] = pp[1:] - pp[:-1]
        hf[:-1] = vv[1:] & vv[:-1]
        bwd[1:] = fwd[:-1]
        hb[1:] = hf[:-1]
    both = hf & hb
    tan = np.where(both[..., None], 0.5 * (fwd + bwd), np.where(hf[..., None], fwd, bwd))
    has = hf | hb
    tan = np.where(has[..., None], tan, 0.0)
    return np.moveaxis(tan, 0, axis), np.moveaxis(has, 0, axis)


def _horn_smooth(tan: np.ndarray, has: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Horn / Sobel: 1-2-1 weighted mean of the tangents of the neighbouring lines."""
    tt = np.moveaxis(tan, axis, 0)
    hh = np.moveaxis(has, axis, 0).astype(np.float64)
    acc = 2.0 * tt * hh[..., None]
    wsum = 2.0 * hh
    acc[1:] += tt[:-1] * hh[:-1, ..., None]
    wsum[1:] += hh[:-1]
    acc[:-1] += tt[1:] * hh[1:, ..., None]
    wsum[:-1] += hh[1:]
    out = np.where(wsum[..., None] > 0, acc / np.maximum(wsum, 1.0)[..., None], 0.0)
    return np.moveaxis(out, 0, axis), np.moveaxis(wsum > 0, 0, axis)


def normal_map_reference(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    valid: np.ndarray | None = None,
    kernel: str = "central",
) -> np.ndarray:
    """Vectorised reference of :func:`geoterrain.bounds.normals.normal_map`, same formulas (row
    blocks with a 1-row halo)."""
    if kernel not in ("central", "horn"):
        raise ValueError(f"unknown kernel {kernel!r}")
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (x, y, z))
    v = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    if valid is not None:
        v &= np.asarray(valid, bool)
    out = np.empty((*v.shape, 3), np.float32)
    rows = v.shape[0]
    for r0 in range(0, rows, _BLOCK_ROWS):  # row blocks with a 1-row halo: exact, bounded memory
        r1 = min(r0 + _BLOCK_ROWS, rows)
        a, b = max(r0 - 1, 0), min(r1 + 1, rows)
        blk = _normal_block(x[a:b], y[a:b], z[a:b], v[a:b], kernel)
        out[r0:r1] = blk[r0 - a : r0 - a + (r1 - r0)]
    return out


_BLOCK_ROWS = 256


def _normal_block(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, v: np.ndarray, kernel: str
) -> np.ndarray:
    p = np.stack([x, y, z], axis=-1)
    p = np.where(v[..., None], p, 0.0)
    tj, hj = _axis_tangent(p, v, 1)  # along a row (column index j)
    ti, hi = _axis_tangent(p, v, 0)  # along a column (row index i)
    if kernel == "horn":
        tj, hj = _horn_smooth(tj, hj, 0)
        ti, hi = _horn_smooth(ti, hi, 1)
    # a missing tangent: horizontal and perpendicular to the other one
    perp_j = np.stack([-tj[..., 1], tj[..., 0], np.zeros_like(tj[..., 0])], axis=-1)
    perp_i = np.stack([ti[..., 1], -ti[..., 0], np.zeros_like(ti[..., 0])], axis=-1)
    ti = np.where((hj & ~hi)[..., None], perp_j, ti)
    tj = np.where((hi & ~hj)[..., None], perp_i, tj)
    nrm = np.cross(tj, ti)
    nrm = np.where(nrm[..., 2:3] < 0, -nrm, nrm)
    length = np.linalg.norm(nrm, axis=-1, keepdims=True)
    scale = np.max(np.abs(np.concatenate([tj, ti], axis=-1)), axis=-1, keepdims=True)
    ok = v[..., None] & (length > 1e-12 * np.maximum(scale, 1e-300) ** 2) & (hi | hj)[..., None]
    up = np.array([0.0, 0.0, 1.0])
    out = np.where(ok, nrm / np.where(ok, length, 1.0), up)
    return out.astype(np.float32)


def shadow_reference(z: np.ndarray, valid: np.ndarray, spacing: float, azimuth: float,
                     elevation: float, step: float = 0.25) -> np.ndarray:
    """Cast shadows by a plain ray march per sample (the oracle of
    :func:`geoterrain.rendering.shading.shadow_mask`; it shares no code with it).

    From each valid sample, walk toward the sun in steps of ``step`` samples; the
    sample is in shadow if the bilinearly interpolated terrain (valid cells only)
    rises above the ray anywhere before the ray clears the highest sample.
    """
    z = np.asarray(z, np.float64)
    R, C = z.shape
    az, el = np.radians(azimuth), np.radians(elevation)
    di, dj = -np.cos(az), np.sin(az)  # toward the sun: north is −row, east is +column
    rise = np.tan(el) * spacing * step
    zmax = np.nanmax(np.where(valid, z, np.nan))
    ii, jj = np.nonzero(valid)
    h0 = z[ii, jj]
    out = np.zeros(len(ii), bool)
    alive = np.ones(len(ii), bool)
    k = 0
    zz = np.where(valid, z, np.nan)
    while alive.any():
        k += 1
        pi, pj = ii + di * step * k, jj + dj * step * k
        ray = h0 + rise * k
        inside = (pi >= 0) & (pi <= R - 1) & (pj >= 0) & (pj <= C - 1)
        alive &= inside & (ray <= zmax)
        if not alive.any():
            break
        i0 = np.clip(np.floor(pi).astype(np.int64), 0, R - 2) if R > 1 else np.zeros_like(ii)
        j0 = np.clip(np.floor(pj).astype(np.int64), 0, C - 2) if C > 1 else np.zeros_like(jj)
        wi, wj = pi - i0, pj - j0
        t = ((1 - wi) * (1 - wj) * zz[i0, j0] + (1 - wi) * wj * zz[i0, j0 + 1]
             + wi * (1 - wj) * zz[i0 + 1, j0] + wi * wj * zz[i0 + 1, j0 + 1])
        hit = alive & (t > ray)  # NaN (a cell touching nodata) never hits
        out |= hit
        alive &= ~hit
    mask = np.zeros((R, C), bool)
    mask[ii, jj] = out
    return mask


# ------------------------------------------------------------------------ visibility
def _uj_height(z: np.ndarray, valid: np.ndarray, pi: np.ndarray, pj: np.ndarray) -> np.ndarray:
    """The full-resolution surface (union-jack triangles, as drawn) at fractional
    indices; NaN over a cell with an invalid corner or outside the grid."""
    R, C = z.shape
    a = np.clip(np.floor(pi).astype(np.int64), 0, R - 2)
    b = np.clip(np.floor(pj).astype(np.int64), 0, C - 2)
    wi, wj = pi - a, pj - b
    z00, z01, z10, z11 = z[a, b], z[a, b + 1], z[a + 1, b], z[a + 1, b + 1]
    ok = (valid[a, b] & valid[a, b + 1] & valid[a + 1, b] & valid[a + 1, b + 1]
          & (pi >= 0) & (pi <= R - 1) & (pj >= 0) & (pj <= C - 1))
    # the diagonal joins the cell corner whose row and column are both odd to its opposite
    main = ((a % 2 == 1) == (b % 2 == 1))
    up = wj >= wi  # diagonal 00–11: triangles (00, 01, 11) and (00, 10, 11)
    h_main = np.where(up, z00 + wj * (z01 - z00) + wi * (z11 - z01),
                      z00 + wi * (z10 - z00) + wj * (z11 - z10))
    lower = wi + wj <= 1  # diagonal 01–10: triangles (00, 01, 10) and (11, 01, 10)
    h_anti = np.where(lower, z00 + wj * (z01 - z00) + wi * (z10 - z00),
                      z11 + (1 - wj) * (z10 - z11) + (1 - wi) * (z01 - z11))
    return np.where(ok, np.where(main, h_main, h_anti), np.nan)


def visible_samples(z: np.ndarray, valid: np.ndarray, eye_ij: tuple[float, float],
                    eye_z: float, candidates: np.ndarray, step: float = 0.5) -> np.ndarray:
    """Which ``candidates`` (a boolean mask of samples) the eye sees, by a plain ray
    march per sample over the drawn full-resolution surface (the oracle of horizon
    culling, :mod:`geoterrain.lod.occlusion`; it shares no code with it).

    ``z`` are scene heights on the grid and ``eye_ij`` the eye's fractional (row,
    column) indices; the ray runs straight in index space (exact on affine frames).
    From each sample, walk toward the eye in steps of ``step`` cells. The sample is
    hidden if the ray crosses the surface on the way: the ray's side of the surface
    (above or below) changes between two steps with surface under both and no hole
    between, as a depth render sees it (a ray may pass under a sheet of terrain through
    a gap in the data, and a sample on a cliff's edge may be seen from below). The walk
    ends at the eye, or when the ray is above every sample.

    Examples
    --------
    >>> z = np.zeros((5, 9)); z[:, 4] = 10.0  # a wall across the middle
    >>> vis = visible_samples(z, np.ones_like(z, bool), (2.0, 0.0), 1.0, np.ones_like(z, bool))
    >>> bool(vis[2, 2]), bool(vis[2, 7])
    (True, False)
    """
    z = np.asarray(z, np.float64)
    ii, jj = np.nonzero(candidates & valid)
    zz = np.where(valid, z, np.nan)
    zmax = float(np.nanmax(zz)) if valid.any() else 0.0
    di, dj = eye_ij[0] - ii, eye_ij[1] - jj
    n = np.maximum(np.ceil(np.maximum(np.abs(di), np.abs(dj)) / step), 1).astype(np.int64)
    h0 = z[ii, jj]
    dz = eye_z - h0
    hidden = np.zeros(len(ii), bool)
    alive = np.ones(len(ii), bool)
    side = np.zeros(len(ii), np.int8)  # +1 above, −1 below the surface, 0 unknown (a hole)
    k = 0
    while alive.any():
        k += 1
        alive &= k <= n  # the eye itself is reached at k = n (a last crossing just there)
        s = k / n
        ray = h0 + s * dz
        alive &= (ray <= zmax) | (side < 0)  # above every sample: nothing left to cross
        if not alive.any():
            break
        idx = np.flatnonzero(alive)
        t = _uj_height(zz, valid, ii[idx] + s[idx] * di[idx], jj[idx] + s[idx] * dj[idx])
        now = np.where(np.isnan(t), 0, np.sign(ray[idx] - t)).astype(np.int8)
        cross = (now != 0) & (side[idx] != 0) & (now != side[idx])
        hidden[idx[cross]] = True
        alive[idx[cross]] = False
        side[idx] = np.where(now == 0, np.where(np.isnan(t), 0, side[idx]), now)
    out = np.zeros(z.shape, bool)
    out[ii[~hidden], jj[~hidden]] = True
    return out
