"""Strategy ``tessellation``: seed 004's tessellation driven by a height acceleration
map (HAM), the GPU quad-domain tessellator emulated on the CPU, on arrays.

- **Patches** are the stored level-0 tiles (2^t sample intervals a side; t = 6 gives the
  seed's 64-texel patches, one quad per texel at T = 64).
- **HAM** = |Sobel |Sobel h|| (eq. 5-8): the unnormalised 3×3 Sobel magnitude of the
  heights, applied twice, edge-replicate padding at the map's border, unit spacing,
  heights in metres. On a plane it is 0, on a·x² it is 128·a, and a step of height h
  peaks at 16·h (tested). A patch's statistics (HAM_max, h_max and where it is, L175)
  are those of the whole map's HAM over the patch's samples: the kernel applied twice
  reads two samples around each, so they come from the patch's full-resolution heights
  and a two-sample halo of its neighbours' (:class:`HamStats`), computed the first time
  the patch is in view, then kept. When the store is edited, only the patches within
  two samples of the edit are computed again (seed 004 H16), which equals computing
  every patch again (tested).
- **T_max = g(HAM_max)** (eq. 5-2), g = ``HAM_SCALE``·√HAM_max, clipped to [1, 64]. The
  seed leaves g open ("a reasonable proportion"); the square root keeps a cliff from
  saturating every patch.
- **T_min** (eq. 5-3/5-4, sign-corrected as the seed's notes say): ĥ/ε with ĥ the
  patch's height range projected at its nearest point (λ·Δh / D_min, pixels) and ε = τ,
  clipped to [1, T_max].
- **Distance law** (eq. 5-5…5-7): T = T_max below d_max, T_max·d_max²/d² beyond, and
  never below T_min (d_min = √(T_max/T_min)·d_max). The seed leaves d_max open; here
  d_max = λ·w/(64·τ), w the patch width: closer than that, a full-resolution quad spans
  more than τ pixels. It is the same for every patch whatever its HAM, so the HAM only
  ever lowers a factor: T ≤ the straight view-dependent law's (T_max = 64), seed 004's
  H13 ordering, tested. (An earlier d_max = λ·w/(T_max·τ) made a smoother patch finer
  far away: 2.9× the straight law's triangles at τ = 4 on a 2049² fBm.)
- **Edge factors** use the larger T_max and T_min of the two patches and the distance
  to the edge's midpoint, so both patches compute the same value (L104); the centre
  factor uses the patch's own. The patch takes the largest of its five factors.
- **Partitioning: powers of two.** A factor is rounded up to 1, 2, 4 … 64, so every
  vertex falls on a stored sample (heights come from the pyramid) and a patch at factor
  T is exactly GeoMipMapping's level t − log₂T. Integer or fractional partitioning
  would place vertices between samples.
- **Nodata:** a patch never goes coarser than its coarsest level whose stored error is
  finite (no cell mixing data and nodata), so valid samples in view are always drawn.
- **Cracks:** where two patches differ, the finer one keeps only the coarser one's edge
  vertices and re-links its border strip (GeoMipMapping's stitching,
  :mod:`geoterrain.lod.geomipmap`), so the mesh is conforming.

HAM gives no error bound: ρ is measured (``bounded=False`` in the registry).

Examples
--------
>>> from geoterrain.core.view import View
>>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 1.0)
>>> stats["patches"] > 0 and 1 <= stats["mean_factor"] <= 64
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.core.view import View
from geoterrain.lod.geomipmap import _NEIGHBOUR, _assemble, _stitch, tables, visible_blocks
from geoterrain.lod.mesh import empty_parts

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

T_LIMIT = 64  # the tessellator's largest factor (Fig. 5.3)
HAM_SCALE = 1.0  # g(HAM) = HAM_SCALE · √HAM (eq. 5-2)



@njit(cache=True, nogil=True)
def _sobel_magnitude(h):
    R, C = h.shape
    out = np.empty((R, C))
    for i in range(R):
        for j in range(C):
            # edge-replicate padding: clamp the neighbours' indices
            im, ip = max(i - 1, 0), min(i + 1, R - 1)
            jm, jp = max(j - 1, 0), min(j + 1, C - 1)
            dx = (h[ip, jm] + 2.0 * h[ip, j] + h[ip, jp]) - (h[im, jm] + 2.0 * h[im, j]
                                                              + h[im, jp])
            dy = (h[im, jp] + 2.0 * h[i, jp] + h[ip, jp]) - (h[im, jm] + 2.0 * h[i, jm]
                                                              + h[ip, jm])
            out[i, j] = np.sqrt(dx * dx + dy * dy)  # eq. 5-8
    return out


def sobel_magnitude(h: np.ndarray) -> np.ndarray:
    """√(D_x² + D_y²) of the unnormalised 3×3 Sobel kernels (eq. 5-8), edge-replicate
    padding, unit spacing.

    Examples
    --------
    >>> i, j = np.indices((5, 5)).astype(float)
    >>> round(float(sobel_magnitude(0.3 * j + 0.7 * i)[2, 2]), 4)  # 8·|∇h|
    6.0926
    """
    return _sobel_magnitude(np.asarray(h, np.float64))


def ham(h: np.ndarray) -> np.ndarray:
    """The height acceleration map |Sobel |Sobel h|| (seed 004 §5.6.1).

    Examples
    --------
    >>> x = np.tile(np.arange(9.0), (9, 1))
    >>> round(float(ham(0.01 * x * x)[4, 4]), 6)  # 128·a
    1.28
    """
    return sobel_magnitude(sobel_magnitude(h))


def tess_factor(d: np.ndarray, t_max: np.ndarray, t_min: np.ndarray,
                d_max: np.ndarray) -> np.ndarray:
    """The camera-distance law (eq. 5-5…5-7): T_max below ``d_max``, T_max·d_max²/d²
    beyond, never below T_min (reached at d_min = √(T_max/T_min)·d_max).

    Examples
    --------
    >>> tess_factor(np.array([50.0, 200.0, 400.0, 900.0]), 64.0, 4.0, 100.0).tolist()
    [64.0, 16.0, 4.0, 4.0]
    """
    d = np.maximum(np.asarray(d, np.float64), 1e-300)
    with np.errstate(over="ignore"):  # the eye on a reference point: T_max, by the clip
        t = np.asarray(t_max, np.float64) * (np.asarray(d_max, np.float64) / d) ** 2
    return np.clip(t, t_min, t_max)


def _power_of_two(t: np.ndarray) -> np.ndarray:
    return np.exp2(np.ceil(np.log2(np.clip(t, 1.0, T_LIMIT) - 1e-9))).clip(1, T_LIMIT)


HALO = 2  # the 3×3 kernel applied twice reads two samples around each (seed 004 H16)


class HamStats:
    """Seed 004's per-patch statistics (L175) of a terrain's level-0 tiles, computed on
    first use and kept in the terrain's :meth:`~geoterrain.terrainlike.TerrainLike.derived`
    slot: ``stats[y, x]`` = (HAM_max, h_max, x_argmax, y_argmax), NaN until computed;
    x, y count samples from the patch's north-west corner, h in metres.

    A patch's statistics read its samples and a :data:`HALO` of two around them (the map's
    HAM at the patch), so an edit of the heights changes only the patches within two
    samples of it: :meth:`edited` drops those (seed 004 H16), and the next use computes
    them again. Nodata samples take the mean of the valid ones of the patch and its halo
    (no false cliff at a void's edge).

    Examples
    --------
    >>> hs = HamStats(t)
    >>> s = hs.stats(np.array([0, 1]), np.array([0, 0]))
    >>> s.shape, bool((s[:, 0] >= 0).all())
    ((2, 4), True)
    """

    def __init__(self, terrain: TerrainLike):
        self.terrain = terrain
        across, down = terrain.grid.tiles(0)
        self.values = np.full((down, across, 4), np.nan)
        self.computed = 0  # patches computed (the tests count them)

    def stats(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """(len(xs), 4) statistics of the level-0 patches (xs, ys), computing the
        missing ones."""
        xs, ys = np.asarray(xs, np.int64), np.asarray(ys, np.int64)
        for x, y in zip(xs.tolist(), ys.tolist(), strict=True):
            if np.isnan(self.values[y, x, 0]):
                self.values[y, x] = patch_stats(self.terrain, x, y)
                self.computed += 1
        return self.values[ys, xs]

    def edited(self, edits: list) -> None:
        """An edit of the store changed the heights of ``edits``' windows (the store's
        edit log entries, each with its ``window`` (row, col, rows, cols)): drop the
        patches within :data:`HALO` samples of them."""
        g = self.terrain.grid
        S, (across, down) = 1 << g.t, g.tiles(0)
        for e in edits:
            r, c, h, w = e["window"]
            y0, y1 = max((r - HALO - 1) // S, 0), min((r + h - 1 + HALO) // S, down - 1)
            x0, x1 = max((c - HALO - 1) // S, 0), min((c + w - 1 + HALO) // S, across - 1)
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    if y * S - HALO <= r + h - 1 and y * S + S + HALO >= r and \
                            x * S - HALO <= c + w - 1 and x * S + S + HALO >= c:
                        self.values[y, x] = np.nan


def patch_heights(terrain: TerrainLike, x: int, y: int, halo: int = HALO
                  ) -> tuple[np.ndarray, int, int]:
    """Level-0 heights (metres, NaN where not valid) of patch (x, y) and ``halo`` samples
    around it within the map, and the patch's first row and column in that array."""
    g = terrain.grid
    S, (across, down), (R, C) = 1 << g.t, g.tiles(0), g.shape  # the level-0 lattice
    i0, j0 = max(y * S - halo, 0), max(x * S - halo, 0)
    i1, j1 = min(y * S + S + halo, R - 1), min(x * S + S + halo, C - 1)
    h = np.full((i1 - i0 + 1, j1 - j0 + 1), np.nan)
    for ty in range(max(i0 // S, 0), min(i1 // S, down - 1) + 1):
        for tx in range(max(j0 // S, 0), min(j1 // S, across - 1) + 1):
            if (0, tx, ty) not in terrain.tile_info:
                continue
            a0, a1 = max(i0, ty * S), min(i1, ty * S + S)
            b0, b1 = max(j0, tx * S), min(j1, tx * S + S)
            h[a0 - i0:a1 - i0 + 1, b0 - j0:b1 - j0 + 1] = terrain.tile(0, tx, ty).heights[
                a0 - ty * S:a1 - ty * S + 1, b0 - tx * S:b1 - tx * S + 1]
    return h * terrain.frame.z_to_m, y * S - i0, x * S - j0


def patch_stats(terrain: TerrainLike, x: int, y: int) -> np.ndarray:
    """(HAM_max, h_max, x_argmax, y_argmax) of level-0 patch (x, y): the map's HAM (eq.
    5-8) over the patch's samples, from its heights and a two-sample halo."""
    S = 1 << terrain.grid.t
    h, a, b = patch_heights(terrain, x, y)
    ok = np.isfinite(h)
    if not ok.any():
        return np.zeros(4)
    if not ok.all():  # nodata: the mean of the valid samples (no false cliff)
        h = np.where(ok, h, float(h[ok].mean()))
    hp = h[a:a + S + 1, b:b + S + 1]
    okp = ok[a:a + S + 1, b:b + S + 1]
    hm = np.where(okp, hp, -np.inf)
    k = int(np.argmax(hm))
    return np.array([float(ham(h)[a:a + S + 1, b:b + S + 1].max()),
                     float(hm.flat[k]) if okp.any() else 0.0, k % (S + 1), k // (S + 1)])


def ham_max(terrain: TerrainLike, index, rows: np.ndarray) -> np.ndarray:
    """HAM_max of the level-0 patches ``rows`` of ``index`` (:class:`HamStats`, kept per
    terrain; a patch is computed the first time it is asked for)."""
    hs = terrain.derived(__name__, lambda: HamStats(terrain))
    keys = index.keys[rows]
    return hs.stats(keys[:, 1], keys[:, 2])[:, 0]


def factors(terrain: TerrainLike, index, leaves: np.ndarray, view: View, tau: float, *,
            ham: bool = True) -> np.ndarray:
    """The tessellation factor (a power of two in [1, 64]) of each visible patch.

    ``ham=False`` is seed 004's "straight view-dependent LOD" (Fig. 5.8's middle
    curve): T_max = 64 for every patch, so only the distance law and T_min act."""
    g = terrain.grid
    lo, hi = index.lo[leaves], index.hi[leaves]
    lam = view.lam
    eye = np.asarray(view.eye, np.float64)
    # eq. 5-2: the upper bound from the height acceleration
    if ham:
        tmax = np.clip(HAM_SCALE * np.sqrt(ham_max(terrain, index, leaves)), 1.0, T_LIMIT)
    else:
        tmax = np.full(len(leaves), float(T_LIMIT))
    # eq. 5-3/5-4 (sign-corrected): the projected height range against ε = τ
    dbox = np.linalg.norm(np.maximum(np.maximum(lo - eye, 0.0), eye - hi), axis=1)
    dh = hi[:, 2] - lo[:, 2]
    tmin = np.clip(lam * dh / (np.maximum(dbox, 1e-9) * tau), 1.0, tmax)
    width = np.maximum(hi[:, 0] - lo[:, 0], hi[:, 1] - lo[:, 1])
    # neighbours across the four edges (−1: none drawn), on the level-0 patch grid
    across, down = g.tiles(0)
    G = np.full((down + 2, across + 2), -1, np.int64)
    xy = index.keys[leaves, 1:]
    G[xy[:, 1] + 1, xy[:, 0] + 1] = np.arange(len(leaves))
    mid = 0.5 * (lo + hi)
    out = tess_factor(np.linalg.norm(mid - eye, axis=1), tmax, tmin,
                      lam * width / (T_LIMIT * tau))  # T_5: the centre (L66)
    S = 1 << g.t
    for dx, dy in _NEIGHBOUR:
        nb = G[xy[:, 1] + 1 + dy, xy[:, 0] + 1 + dx]
        has = nb >= 0
        q = np.where(has, nb, np.arange(len(leaves)))
        TM = np.maximum(tmax, tmax[q])  # L104: the larger of the two patches' values
        Tm = np.maximum(tmin, tmin[q])
        wd = np.maximum(width, width[q])
        # the edge's middle sample and a height both patches agree on: one distance
        i = xy[:, 1] * S + (S // 2 if dx else (S if dy > 0 else 0))
        j = xy[:, 0] * S + (S // 2 if dy else (S if dx > 0 else 0))
        ex, ey = terrain.frame.xy(i, j)
        ez = 0.5 * (np.minimum(lo[:, 2], lo[q, 2]) + np.maximum(hi[:, 2], hi[q, 2]))
        d = np.linalg.norm(np.stack([ex, ey, ez], 1) - eye, axis=1)
        out = np.maximum(out, tess_factor(d, TM, Tm, lam * wd / (T_LIMIT * tau)))
    return _power_of_two(out)


def select(terrain: TerrainLike, view: View, tau: float, *, occlusion: bool = True,
           morph: bool | None = None, ham: bool = True):
    """The HAM-driven tessellation of ``view`` at pixel tolerance ``tau``, and its stats.

    Unbounded (seed 004 gives no error bound): ``geoterrain bench`` measures ρ.
    ``stats["factor_counts"]`` counts the drawn patches per factor 1, 2, 4 … 64 (seed
    004's factor histogram); ``ham=False`` drops the HAM cap (see :func:`factors`);
    ``occlusion``: cull patches hidden behind nearer terrain (``morph`` is ignored).
    """
    index, leaves, stats = visible_blocks(terrain, view, occlusion=occlusion)
    if not len(leaves):
        return empty_parts(), stats
    g = terrain.grid
    T = factors(terrain, index, leaves, view, tau, ham=ham)
    tb = tables(terrain, index)
    n = (g.t - np.log2(T).astype(np.int64)).clip(0, tb.nmax)
    # near nodata a coarse patch would drop triangles over valid samples (a triangle needs
    # three valid corners): keep the levels whose stored error is finite (no mixed cell)
    finite = np.isfinite(tb.delta[tb.pos[leaves]]).sum(1) - 1
    n = np.minimum(n, finite)
    xy = index.keys[leaves, 1:]
    delta = np.zeros((len(leaves), g.t + 1))
    ratios, stitched = _stitch(terrain, index, view, tau, xy, n, delta,
                               np.ones(len(leaves)), g.t, bounded=False)
    mesh = _assemble(terrain, index, xy, n, ratios)
    drawn = 1 << (g.t - n)
    stats.update(patches=len(leaves), stitched_edges=stitched,
                 mean_factor=float(drawn.mean()),
                 factor_counts=np.bincount(np.log2(drawn).astype(np.int64),
                                           minlength=7)[:7].tolist())
    return mesh, stats
