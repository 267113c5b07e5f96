"""Plain numpy oracles for :mod:`geoterrain.analysis` (never imported by it).

Each reads whole full-resolution arrays (as rasterio returns a source raster) and answers
the way the module documents, without a pyramid, a tile or a compiled kernel:

- :func:`bilinear_reference`: the height at points, bilinear on pixel centres;
- :func:`viewshed_reference`: the reference-plane viewshed, cell by cell;
"""

from __future__ import annotations

import numpy as np

__all__ = ["bilinear_reference", "viewshed_reference"]


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


def viewshed_reference(z: np.ndarray, r2: np.ndarray, orow: int, ocol: int, eye: float,
                       target: float, kcurv: float, r2max: float, mode: str = "edge",
                       r2_range: np.ndarray | None = None) -> np.ndarray:
    """The reference-plane viewshed (Wang, Robinson & White 2000) as ``gdal_viewshed``
    sweeps it, cell by cell in plain Python over a whole raster: no tiles, no bounds.

    ``z`` (H, W) heights in metres (NaN: a void, transparent and without an answer),
    ``r2`` (H, W) each cell's squared ground distance from the observer (metres²; the
    radius test and the curvature drop ``kcurv`` · r2 use it; ``r2_range``, when given,
    is the one the radius test uses), the observer's cell, its eye and the target height
    (metres). Codes: 0 hidden, 1 visible, 254 no answer.
    """
    H, W = z.shape
    out = np.full((H, W), 254, np.uint8)
    zadj = z - kcurv * r2
    inr = (r2 if r2_range is None else r2_range) <= r2max

    def line(i, za):
        return za if i == 1 else (za - eye) / (i - 1) + za

    def edge(i, j, za, zb):
        return line(i, za) if i == j else ((za - eye) * i + (zb - eye) * (j - i)) / (j - 1) + eye

    def diag(i, j, za, zb):
        return ((za - eye) * i + (zb - eye) * j) / (i + j - 1) + eye

    def los(i, j, this_prev, last, last_prev):
        e = edge(j, i, last_prev, this_prev) if i >= j else edge(i, j, last_prev, last)
        d = diag(i, j, this_prev, last)
        return {"edge": e, "diagonal": d, "max": max(e, d), "min": min(e, d)}[mode]

    def decide(r, c, sight, row):
        if np.isnan(z[r, c]):
            row[c] = sight
            return
        out[r, c] = 1 if zadj[r, c] + target >= sight else 0
        row[c] = max(zadj[r, c], sight)

    # the observer's row: itself and its neighbours visible, then along the row
    first = np.full(W, np.nan)
    first[ocol] = z[orow, ocol]
    out[orow, ocol] = 1
    for c in (ocol - 1, ocol + 1):
        if 0 <= c < W:
            first[c] = -np.inf if np.isnan(z[orow, c]) else zadj[orow, c]
            out[orow, c] = 254 if np.isnan(z[orow, c]) or not inr[orow, c] else 1
    for side in (-1, 1):
        c = ocol + 2 * side
        while 0 <= c < W and inr[orow, c]:
            decide(orow, c, line(abs(c - ocol), first[c - side]), first)
            c += side
    for step in (-1, 1):
        last = first.copy()
        r = orow + step
        while 0 <= r < H and inr[r, ocol]:
            j = abs(r - orow)
            row = np.full(W, np.nan)
            decide(r, ocol, line(j, last[ocol]), row)
            for side in (-1, 1):
                c = ocol + side
                while 0 <= c < W and inr[r, c]:
                    p = c - side
                    decide(r, c, los(abs(c - ocol), j, row[p], last[c], last[p]), row)
                    c += side
            last = row
            r += step
    return out
