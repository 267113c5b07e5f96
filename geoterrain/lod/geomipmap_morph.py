"""Geomorphing of GeoMipMapping (seed 000 §2.4: de Boer's trilinear geomipmapping, eq.
4-12/4-13, with Wagner's cases A/B/C and the neighbours' factors): no pop, ρ ≤ τ kept.

Each block gets a **continuous level** L = n + t: it draws its geomipmap n with the
vertices that vanish at n + 1 slid by t towards the level-(n + 1) surface (eq. 4-13,
z' = z − t·(z − m), m the midpoint of the vanishing vertex's two ends: case A left/right,
case C up/down, case B the union-jack diagonal). At t = 1 the block *is* its level n + 1
(the union-jack grids nest), so the switch from (n, 1) to (n + 1, 0) changes nothing.

- **The band** (eq. 4-12 with switch distances in place of D_n). E_m = λ·δ_m/τ is the
  distance from which level m keeps ρ ≤ τ. The morph towards m runs over
  [A_m, B_m], A_m = max(E_m, B_{m−1}), B_m = A_m/``MORPH_START``, with
  t = (D_min − A_m)/(B_m − A_m): both ends of the blend keep ρ ≤ τ, so the blend does
  ((1 − t)·δ_{m−1} + t·δ_m ≥ |z − drawn|). A level is fully reached at ρ_m ≤ 0.75 τ, as
  rtin's band. Choice: distances rather than seed 000's D_n = δ·C from the block
  centre, so that the bound holds for any view direction.
- **Neighbours** (Wagner's neighbours' factors). A shared edge is drawn at the larger of
  its two blocks' levels, L_e = max(L_A, L_B): one height per vertex, and the finer block
  stitches to it as without morphing (fig. 4-21). The finer block's border strip then
  differs from its own blend by at most (L_e − L_A)·δ_{⌊s⌋+1} integrated over the levels
  s between (an edge vertex moves by at most |z − Lin_{k+1}| per level of the edge, ≤ the
  δ_{k+1} of either block: both hold the edge).
  So each block A allows a neighbour at most κ_A levels more, κ_A the largest excess
  whose strip error still fits A's slack τ·D_min/λ − (A's own blend error), capped at 1
  (a restricted quadtree: ratio 2 at most, every fan nests in the next level's
  triangles). The levels are then L_B = min over blocks A of (ℓ_A + the cheapest path of
  κ from A to B): a shortest path over the block grid, computed for every stored block
  (drawn or not) from continuous quantities, so L is a continuous function of the camera
  and a block entering the frustum changes nothing.

Examples
--------
>>> d = np.array([[0.0, 1.0, 4.0]])  # δ_0, δ_1, δ_2 of one block
>>> continuous_levels(d, np.array([50.0]), 100.0, 1.0).round(3).tolist()  # E_1 = 100
[0.0]
>>> continuous_levels(d, np.array([120.0]), 100.0, 1.0).round(3).tolist()  # in band 1
[0.6]
"""

from __future__ import annotations

import numpy as np

from geoterrain.lod.morph import MORPH_START

__all__ = ["NEIGHBOUR", "continuous_levels", "blend_error", "neighbour_allowance", "restrict",
           "next_level_diagonals", "morph_block_heights"]


def continuous_levels(delta: np.ndarray, dmin: np.ndarray, lam: float, tau: float,
                      start: float = MORPH_START) -> np.ndarray:
    """Each block's natural continuous level ℓ = n + t (eq. 4-12 over the bands
    [A_m, B_m]) from its saturated δ (B, M+1) and D_min (B,)."""
    with np.errstate(invalid="ignore", over="ignore"):
        E = delta * (lam / tau)
    A = np.zeros_like(E)
    for m in range(1, E.shape[1]):  # A_m = max(E_m, B_{m−1}); B = A / start
        A[:, m] = np.maximum(E[:, m], A[:, m - 1] / start)
    A, B = A[:, 1:], A[:, 1:] / start
    d = dmin[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(d >= B, 1.0, np.where(d > A, (d - A) / (B - A), 0.0))
    return np.nan_to_num(t, nan=0.0).sum(1)


def blend_error(delta: np.ndarray, level: np.ndarray) -> np.ndarray:
    """The bound (1 − t)·δ_n + t·δ_{n+1} of |z − drawn| inside a block at level n + t:
    ``delta`` (B, M+1) read at the continuous levels (B,), linear between levels."""
    M = delta.shape[1] - 1
    n = np.clip(np.floor(level).astype(np.int64), 0, M)
    t = level - n
    r = np.arange(len(n))
    lo, hi = delta[r, n], delta[r, np.minimum(n + 1, M)]
    with np.errstate(invalid="ignore"):
        return np.where(t > 0, (1 - t) * lo + t * hi, lo)


def neighbour_allowance(edge_delta: np.ndarray, level: np.ndarray, slack: np.ndarray
                        ) -> np.ndarray:
    """κ (B, 4): the largest x ∈ [0, 1] with ∫_ℓ^{ℓ+x} ε(s) ds ≤ slack, where
    ε(s) = ``edge_delta``[⌊s⌋ + 1] (B, 4, M+1) bounds how far an edge vertex moves per
    level of the edge above the block, extended past M with ε_M (so κ is continuous in
    ℓ and slack; a larger ε only tightens); ``slack`` (B,) = τ·D_min/λ − the block's
    blend error.

    Examples
    --------
    >>> e = np.array([[[0.0, 1.0, 2.0]] * 4])  # ε = 1 on [0, 1], then 2 from level 1 on
    >>> neighbour_allowance(e, np.array([0.5]), np.array([1.5]))[0].tolist()
    [1.0, 1.0, 1.0, 1.0]
    >>> neighbour_allowance(e, np.array([0.5]), np.array([1.0]))[0].tolist()
    [0.75, 0.75, 0.75, 0.75]
    """
    B, _, M1 = edge_delta.shape
    M = M1 - 1
    # slope on [k, k+1] is ε_{k+1} for k = 0 … M−1, and ε_M on [M, M+1]
    slope = np.concatenate([edge_delta[:, :, 1:], edge_delta[:, :, -1:]], -1)  # (B, 4, M+1)
    with np.errstate(invalid="ignore", over="ignore"):
        F = np.concatenate([np.zeros((B, 4, 1)), np.cumsum(slope, -1)], -1)  # at 0 … M+1
    lv = np.broadcast_to(level[:, None], (B, 4))
    n = np.clip(np.floor(lv).astype(np.int64), 0, M)
    frac = lv - n
    s_n = np.take_along_axis(slope, n[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore", over="ignore"):
        F_l = np.take_along_axis(F, n[..., None], -1)[..., 0] + np.where(frac > 0, frac * s_n,
                                                                          0.0)
        T = F_l + np.maximum(slack, 0.0)[:, None]
    k = np.clip((F <= T[..., None]).sum(-1) - 1, 0, M + 1)  # the last knot at or below T
    Fk = np.take_along_axis(F, k[..., None], -1)[..., 0]
    sk = np.take_along_axis(slope, np.minimum(k, M)[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(k > M, np.inf, k + np.where(sk > 0, (T - Fk) / sk, np.inf))
        x = np.nan_to_num(s - lv, nan=0.0, posinf=1.0)
    return np.clip(x, 0.0, 1.0)


# (dx, dy) of each block edge's neighbour: top, bottom, left, right (geomipmap.EDGES)
NEIGHBOUR = np.array([[0, -1], [0, 1], [-1, 0], [1, 0]])


def restrict(ell: np.ndarray, kappa: np.ndarray, present: np.ndarray) -> np.ndarray:
    """L on the block grid (ny, nx): the largest field ≤ ℓ with L_B ≤ L_A + κ_A[e] for
    every block A and its neighbour B across edge e (κ (ny, nx, 4)); absent blocks
    neither constrain nor get constrained (L = +inf there). Relaxed on whole arrays
    until nothing changes (Bellman-Ford: a shortest path has fewer hops than there are
    blocks, so at most that many passes; a few on real views).

    Examples
    --------
    >>> ell = np.array([[0.0, 3.0, 3.0]])
    >>> restrict(ell, np.full((1, 3, 4), 0.5), np.ones((1, 3), bool)).tolist()
    [[0.0, 0.5, 1.0]]
    """
    ny, nx = ell.shape
    big = np.inf
    L = np.where(present, ell, big)
    P = np.full((ny + 2, nx + 2), big)
    kap = np.zeros((ny + 2, nx + 2, 4))
    kap[1:-1, 1:-1] = kappa
    for _ in range(int(present.sum()) + 1):
        P[1:-1, 1:-1] = L
        new = L.copy()
        for e, (dx, dy) in enumerate(NEIGHBOUR.tolist()):
            # block B at (y, x) receives from A at (y − dy, x − dx), across A's edge e
            src = P[1 - dy: 1 - dy + ny, 1 - dx: 1 - dx + nx]
            k = kap[1 - dy: 1 - dy + ny, 1 - dx: 1 - dx + nx, e]
            new = np.minimum(new, src + k)
        new = np.where(present, new, big)
        if np.array_equal(new, L):
            break
        L = new
    return L


def next_level_diagonals(xy: np.ndarray, K: int) -> np.ndarray:
    """(B, K/2, K/2): True where the level-(n+1) cell of blocks ``xy`` (x, y) drawn with
    K level-n cells per side has the main diagonal (row and column both increasing), by
    the union-jack rule on global level-(n+1) cells (``union_jack_faces``; for K = 2 the
    one-cell template's parity (x ^ y) & 1).

    Examples
    --------
    >>> next_level_diagonals(np.array([[0, 0], [1, 0]]), 2)[:, 0, 0].tolist()
    [True, False]
    """
    h = K // 2
    p = np.arange(h)
    yb, xb = xy[:, 1][:, None, None], xy[:, 0][:, None, None]
    return (yb * h + p[None, :, None] + xb * h + p[None, None, :]) % 2 == 0


def morph_block_heights(Z: np.ndarray, t: np.ndarray, edge_rel: np.ndarray,
                        diag_main: np.ndarray) -> np.ndarray:
    """Morphed heights of blocks drawn at one level: ``Z`` (B, K+1, K+1) true heights,
    ``t`` (B,) the blocks' own factors, ``edge_rel`` (B, 4) each edge's level above the
    block's grid (L_e − n ∈ [0, 2)), ``diag_main`` (B, K/2, K/2) True where the level-
    (n+1) cell's diagonal is the main one. Edges first (level-n then level-(n+1) odd
    vertices), then the interior's vanishing vertices with the edges' drawn heights as
    ends (eq. 4-13 and Wagner's cases; a vertex whose end has no data keeps its height).

    Examples
    --------
    >>> Z = np.zeros((1, 3, 3)); Z[0, 1, 1] = 4.0
    >>> out = morph_block_heights(Z, np.array([0.5]), np.zeros((1, 4)), np.ones((1, 1, 1), bool))
    >>> float(out[0, 1, 1])  # half-way to the diagonal's midpoint (case B)
    2.0
    """
    Zm = Z.copy()
    K = Z.shape[1] - 1
    if K < 2:
        return Zm

    def slide(z, target, w):
        with np.errstate(invalid="ignore"):
            out = (1.0 - w) * z + w * target
        return np.where(np.isfinite(target) & (w > 0), out, z)

    for e in range(4):
        line = (Zm[:, 0, :], Zm[:, K, :], Zm[:, :, 0], Zm[:, :, K])[e]  # views into Zm
        r = edge_rel[:, e][:, None]
        w1 = np.clip(r, 0.0, 1.0)
        line[:, 1::2] = slide(line[:, 1::2], 0.5 * (line[:, 0:-1:2] + line[:, 2::2]), w1)
        if K >= 4:
            w2 = np.clip(r - 1.0, 0.0, 1.0)
            line[:, 2::4] = slide(line[:, 2::4], 0.5 * (line[:, 0:-1:4] + line[:, 4::4]), w2)
            line[:, 1::2] = np.where(w2 > 0, 0.5 * (line[:, 0:-1:2] + line[:, 2::2]),
                                     line[:, 1::2])  # omitted at ratio 2: on the edge
    w = t[:, None, None]
    if not (w > 0).any():
        return Zm
    # case C (odd row, even column): up/down; case A (even row, odd column): left/right
    Zm[:, 1:K:2, 2:K - 1:2] = slide(Zm[:, 1:K:2, 2:K - 1:2],
                                    0.5 * (Zm[:, 0:K - 1:2, 2:K - 1:2] + Zm[:, 2::2, 2:K - 1:2]), w)
    Zm[:, 2:K - 1:2, 1:K:2] = slide(Zm[:, 2:K - 1:2, 1:K:2],
                                    0.5 * (Zm[:, 2:K - 1:2, 0:K - 1:2] + Zm[:, 2:K - 1:2, 2::2]), w)
    # case B (odd row, odd column): along the level-(n+1) cell's union-jack diagonal
    c00, c11 = Zm[:, 0:K - 1:2, 0:K - 1:2], Zm[:, 2::2, 2::2]
    c01, c10 = Zm[:, 0:K - 1:2, 2::2], Zm[:, 2::2, 0:K - 1:2]
    target = np.where(diag_main, 0.5 * (c00 + c11), 0.5 * (c01 + c10))
    Zm[:, 1:K:2, 1:K:2] = slide(Zm[:, 1:K:2, 1:K:2], target, w)
    return Zm
