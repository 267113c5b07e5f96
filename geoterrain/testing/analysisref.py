"""Plain numpy oracles for :mod:`geoterrain.analysis` (never imported by it).

Each reads whole full-resolution arrays (as rasterio returns a source raster) and answers
the way the module documents, without a pyramid, a tile or a compiled kernel:

- :func:`bilinear_reference`: the height at points, bilinear on pixel centres;
"""

from __future__ import annotations

import numpy as np

__all__ = ["bilinear_reference"]


def bilinear_reference(z: np.ndarray, valid: np.ndarray, transform, xy: np.ndarray
                       ) -> np.ndarray:
    """Bilinear heights of a source raster at points (N, 2) in its CRS.

    ``z`` (H, W) heights, ``valid`` (H, W) its data mask, ``transform`` its affine
    (rasterio's (a, b, c, d, e, f), north-up). Samples sit at pixel centres; within half a
    pixel of the edge the outermost ones extend; a point outside the extent, or one whose
    interpolation gives a nodata sample a weight above 0, is NaN.
    """
    H, W = z.shape
    a, _, c, _, e, f = tuple(transform)[:6]
    col = (xy[:, 0] - c) / a - 0.5
    row = (xy[:, 1] - f) / e - 0.5
    out = np.full(len(xy), np.nan)
    inside = (row >= -0.5) & (row <= H - 0.5) & (col >= -0.5) & (col <= W - 0.5)
    r = np.clip(row, 0, H - 1)
    q = np.clip(col, 0, W - 1)
    r0 = np.minimum(np.floor(r).astype(int), max(H - 2, 0))
    q0 = np.minimum(np.floor(q).astype(int), max(W - 2, 0))
    u, v = r - r0, q - q0
    r1, q1 = np.minimum(r0 + 1, H - 1), np.minimum(q0 + 1, W - 1)
    corners = [(r0, q0, (1 - u) * (1 - v)), (r0, q1, (1 - u) * v),
               (r1, q0, u * (1 - v)), (r1, q1, u * v)]
    bad = ~inside
    vals = []
    for rr, qq, w in corners:
        bad |= (w > 0) & ~valid[rr, qq]
        vals.append(np.where(valid[rr, qq], z[rr, qq], 0.0))
    top = vals[0] * (1 - v) + vals[1] * v
    bot = vals[2] * (1 - v) + vals[3] * v
    res = top * (1 - u) + bot * u
    out[~bad] = res[~bad]
    return out
