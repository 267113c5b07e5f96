"""Coarse levels' normal maps averaged from the full-resolution map: what stores held
before each level's map came from its own samples (:func:`~geoterrain.bounds.normals.maps.
level_normal_maps`), kept for comparison (docs/lab/store-size.md).

- :func:`normal_pyramid`: the maps of every pyramid level, each level a 3x3 binomial
  weighted mean (renormalised) of the previous one around its kept samples.
- :func:`level_normals`: the map for one pyramid level L directly from the full map (box
  mean over each sample's footprint, renormalised; summed-area tables, memory-hungry).
"""

from __future__ import annotations

import numpy as np
from numba import prange

from geoterrain.core.threads import parallel_kernel

__all__ = ["level_normals", "normal_pyramid"]


def _box_sum(a: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Sums of ``a`` (N, N, ...) over boxes rows lo[r]..hi[r], cols lo[c]..hi[c] (closed)."""
    cs = np.zeros((a.shape[0] + 1, a.shape[1] + 1, *a.shape[2:]), np.float64)
    np.cumsum(np.cumsum(a, axis=0, dtype=np.float64), axis=1, out=cs[1:, 1:])
    h1 = hi + 1
    return cs[h1][:, h1] - cs[lo][:, h1] - cs[h1][:, lo] + cs[lo][:, lo]


def level_normals(n_full: np.ndarray, level: int, valid: np.ndarray | None = None) -> np.ndarray:
    """Normal map (N_L, N_L, 3) float32 of pyramid level L from the full-resolution map.

    Level-L sample (a, b) sits at full-resolution (a * 2**L, b * 2**L); its footprint is
    the closed box of half-width 2**(L-1) around it (2**L + 1 samples a side for L >= 1,
    clipped to the grid; neighbouring footprints share their border lines). The result
    is the normalised mean of the (valid) full-resolution normals in that box, computed
    with summed-area tables; (0, 0, 1) where the box holds no valid sample.

    Examples
    --------
    >>> n = np.zeros((5, 5, 3), np.float32); n[..., 2] = 1
    >>> level_normals(n, 2).shape
    (2, 2, 3)
    """
    n_full = np.asarray(n_full, dtype=np.float64)
    size = n_full.shape[0]
    s = 1 << level
    if level == 0:
        idx = np.arange(size)
        lo = hi = idx
    else:
        centre = np.arange(0, size, s)
        lo = np.clip(centre - s // 2, 0, size - 1)
        hi = np.clip(centre + s // 2, 0, size - 1)
    w = np.ones(n_full.shape[:2]) if valid is None else np.asarray(valid, np.float64)
    tot = _box_sum(n_full * w[..., None], lo, hi)
    length = np.linalg.norm(tot, axis=-1, keepdims=True)
    ok = length > 1e-12
    out = np.where(ok, tot / np.where(ok, length, 1.0), np.array([0.0, 0.0, 1.0]))
    return out.astype(np.float32)


def normal_pyramid(n_full: np.ndarray, valid: np.ndarray | None, levels: int) -> list[np.ndarray]:
    """Normal maps of pyramid levels 0 .. ``levels - 1``, each (N_L, N_L, 3) float32.

    The fast replacement of :func:`level_normals` for the whole pyramid: level L + 1 is
    computed from level L alone (one pass per level on shrinking arrays), not from the
    full-resolution map. The filter, exactly:

    - level 0: ``n_0 = n_full`` (as float32, not renormalised), weight
      ``w_0 = valid`` (all ones when ``valid`` is None);
    - level L + 1, sample (a, b) (= level-L sample (2a, 2b)):
      ``s = sum over di, dj in {-1, 0, 1} of k[di] * k[dj] * w_L[2a+di, 2b+dj] *
      n_L[2a+di, 2b+dj]`` with ``k = (1, 2, 1)`` (the binomial 3x3 kernel), neighbours
      outside the level-L grid omitted (no renormalisation of the weights at borders:
      the normalisation below makes it irrelevant). ``n_{L+1} = s / |s|``, or (0, 0, 1)
      when ``|s| <= 1e-12`` (no valid sample, or opposite normals cancelling);
      ``w_{L+1}(a, b) = 1`` if any of the 9 weights ``w_L`` is non-zero, else 0.

    Sums are accumulated in float64 from the float32 inputs. The effective footprint of a
    level-L sample is the closed box of half-width ``2**L - 1`` full-resolution samples
    (tent-like weights), a little wider than the ``2**(L-1)`` box of
    :func:`level_normals`, which smooths the coarse maps slightly more (less aliasing).

    Parameters
    ----------
    n_full : (N, N, 3) float
        Full-resolution unit normals (e.g. :func:`normal_map`).
    valid : (N, N) bool or None
        Valid samples; invalid ones carry no weight at any level.
    levels : int
        Number of levels (>= 1); level L has ``(N - 1) // 2**L + 1`` samples a side.

    Returns
    -------
    list of (N_L, N_L, 3) float32

    Examples
    --------
    >>> n = np.zeros((5, 5, 3), np.float32); n[..., 2] = 1
    >>> [a.shape for a in normal_pyramid(n, None, 3)]
    [(5, 5, 3), (3, 3, 3), (2, 2, 3)]
    """
    if levels < 1:
        raise ValueError("levels must be >= 1")
    cur = np.ascontiguousarray(n_full, dtype=np.float32)
    if cur.ndim != 3 or cur.shape[2] != 3:
        raise ValueError("n_full must be (N, M, 3)")
    if valid is None:
        w = np.ones(cur.shape[:2], np.float32)
    else:
        w = np.ascontiguousarray(np.broadcast_to(valid, cur.shape[:2]), dtype=np.float32)
    out = [cur]
    for _ in range(1, levels):
        rows, cols = (cur.shape[0] + 1) // 2, (cur.shape[1] + 1) // 2
        nxt = np.empty((rows, cols, 3), np.float32)
        wn = np.empty((rows, cols), np.float32)
        _reduce_nb(cur, w, nxt, wn)
        out.append(nxt)
        cur, w = nxt, wn
    return out


@parallel_kernel(cache=True, nogil=True)
def _reduce_part_nb(n, w, i0, rows, out, wout, a0):  # pragma: no cover - compiled
    # rows a0 … of the next level from ``n``, ``w``: this level's rows i0 … of ``rows``
    cols = n.shape[1]
    k = (1.0, 2.0, 1.0)
    for ao in prange(out.shape[0]):
        a = a0 + ao
        for b in range(out.shape[1]):
            sx = 0.0
            sy = 0.0
            sz = 0.0
            anyw = False
            for di in range(3):
                i = 2 * a + di - 1
                if i < 0 or i >= rows:
                    continue
                for dj in range(3):
                    j = 2 * b + dj - 1
                    if j < 0 or j >= cols:
                        continue
                    wt = w[i - i0, j]
                    if wt != 0.0:
                        anyw = True
                        f = k[di] * k[dj] * wt
                        sx += f * n[i - i0, j, 0]
                        sy += f * n[i - i0, j, 1]
                        sz += f * n[i - i0, j, 2]
            length = np.sqrt(sx * sx + sy * sy + sz * sz)
            if length > 1e-12:
                out[ao, b, 0] = sx / length
                out[ao, b, 1] = sy / length
                out[ao, b, 2] = sz / length
            else:
                out[ao, b, 0] = 0.0
                out[ao, b, 1] = 0.0
                out[ao, b, 2] = 1.0
            wout[ao, b] = 1.0 if anyw else 0.0


def _reduce_nb(n, w, out, wout):
    _reduce_part_nb(n, w, 0, n.shape[0], out, wout, 0)
