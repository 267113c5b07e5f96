"""Plain numpy oracles for :mod:`geoterrain.analysis` (never imported by it).

Each reads whole full-resolution arrays (as rasterio returns a source raster) and answers
the way the module documents, without a pyramid, a tile or a compiled kernel:

- :func:`bilinear_reference`: the height at points, bilinear on pixel centres;
- :func:`viewshed_reference`: the reference-plane viewshed, cell by cell;
- :func:`triangulated_reference`: areas and volumes on the full triangulation, by GEOS;
- :func:`contour_comparison`: two sets of contour lines, level by level (counts, Hausdorff);
"""

from __future__ import annotations

import numpy as np

__all__ = ["bilinear_reference", "contour_comparison", "triangulated_reference",
           "viewshed_reference"]


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


def triangulated_reference(z: np.ndarray, valid: np.ndarray, transform, to_metres, polygon,
                           base: tuple[float, float, float] = (0.0, 0.0, 0.0),
                           z_to_m: float = 1.0) -> dict:
    """Areas and volumes of a shapely ``polygon`` (in the raster's CRS) on the raster's
    full-resolution triangulation, by GEOS: every triangle cut by ``shapely.intersection``.

    Triangles join pixel centres, each cell split along its union-jack diagonal (through
    the corner whose row and column are both odd); a triangle with a nodata corner is left
    out (its clipped area goes to ``nodata_area``). ``to_metres(x, y)`` places CRS points
    in a metric frame (each triangle is measured through the affine map its corners give);
    heights × ``z_to_m`` are metres; ``base`` (a, b, c) is the plane a·x + b·y + c in the
    raster's units. Returns area_2d, area_3d, cut, fill and nodata_area (m², m³).
    """
    import shapely

    H, W = z.shape
    a, _, c, _, e, f = tuple(transform)[:6]
    x0, y0, x1, y1 = polygon.bounds
    j0 = max(int(np.floor((min(x0, x1) - c) / a - 0.5)) - 1, 0)
    j1 = min(int(np.ceil((max(x0, x1) - c) / a - 0.5)) + 1, W - 1)
    ylo, yhi = sorted(((y0 - f) / e - 0.5, (y1 - f) / e - 0.5))
    i0, i1 = max(int(np.floor(ylo)) - 1, 0), min(int(np.ceil(yhi)) + 1, H - 1)
    ii, jj = np.meshgrid(np.arange(i0, i1), np.arange(j0, j1), indexing="ij")
    ii, jj = ii.ravel(), jj.ravel()
    main = (ii + jj) % 2 == 0
    # each cell's two triangles as (row, col) corners
    c00, c01, c10, c11 = (ii, jj), (ii, jj + 1), (ii + 1, jj), (ii + 1, jj + 1)
    tris = []
    for m, corners in ((True, (c00, c01, c11)), (True, (c00, c11, c10)),
                       (False, (c00, c01, c10)), (False, (c11, c10, c01))):
        sel = main == m
        tris.append(tuple((r[sel], q[sel]) for r, q in corners))
    R = np.concatenate([np.stack([t[k][0] for k in range(3)], 1) for t in tris])
    Q = np.concatenate([np.stack([t[k][1] for k in range(3)], 1) for t in tris])
    X = a * (Q + 0.5) + c
    Y = e * (R + 0.5) + f
    polys = shapely.polygons(np.stack([X, Y], -1))
    pieces = shapely.intersection(polys, polygon)
    area_src = shapely.area(pieces)
    keep = area_src > 0
    R, Q, X, Y, pieces, area_src = R[keep], Q[keep], X[keep], Y[keep], pieces[keep], \
        area_src[keep]
    Xm, Ym = to_metres(X, Y)
    ok = valid[R, Q].all(1)
    Z = np.where(valid[R, Q], z[R, Q], 0.0) * z_to_m
    cross_src = np.abs((X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0])
                       - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0]))
    e1 = np.stack([Xm[:, 1] - Xm[:, 0], Ym[:, 1] - Ym[:, 0], Z[:, 1] - Z[:, 0]], 1)
    e2 = np.stack([Xm[:, 2] - Xm[:, 0], Ym[:, 2] - Ym[:, 0], Z[:, 2] - Z[:, 0]], 1)
    j2 = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / cross_src
    j3 = np.linalg.norm(np.cross(e1, e2), axis=1) / cross_src
    out = {"area_2d": float((area_src * j2)[ok].sum()),
           "area_3d": float((area_src * j3)[ok].sum()),
           "nodata_area": float((area_src * j2)[~ok].sum())}
    # w = (z − base) · z_to_m, linear on each triangle in the CRS's x, y
    w = Z - (base[0] * X + base[1] * Y + base[2]) * z_to_m
    A = np.stack([X, Y, np.ones_like(X)], -1)
    coef = np.linalg.solve(A[ok], w[ok][..., None])[..., 0]  # w = p x + q y + r
    pc, areas, j2o = pieces[ok], area_src[ok], j2[ok]
    Xo, Yo = X[ok], Y[ok]
    L = 4 * (np.ptp(Xo, axis=1) + np.ptp(Yo, axis=1))[:, None]  # beyond the triangle
    mx, my = Xo.mean(1), Yo.mean(1)
    cut = fill = 0.0
    for sign in (1.0, -1.0):
        p, q, r = (sign * coef[:, k] for k in range(3))
        g = np.hypot(p, q)
        gs = np.where(g == 0, 1.0, g)
        n = np.stack([p / gs, q / gs], -1)  # toward the side where sign·w grows
        wm = p * mx + q * my + r  # the line sign·w = 0, near the triangle
        p0 = np.stack([mx, my], -1) - (wm / gs)[:, None] * n
        d = np.stack([-n[:, 1], n[:, 0]], -1)
        quad = np.stack([p0 - L * d, p0 + L * d, p0 + L * d + L * n, p0 - L * d + L * n], 1)
        ws = sign * w[ok]
        whole = (ws >= 0).all(1)  # the triangle is on one side: no cut needed
        none = (ws <= 0).all(1) & ~whole
        cross = ~whole & ~none  # the line runs through the triangle: the quad reaches it
        half = np.where(cross, shapely.intersection(pc, shapely.polygons(quad)), pc)
        ha = np.where(whole, areas, np.where(none, 0.0, shapely.area(half)))
        k = np.flatnonzero(ha > 0)
        cen = shapely.centroid(half[k])
        wv = p[k] * shapely.get_x(cen) + q[k] * shapely.get_y(cen) + r[k]  # sign · w
        part = float(np.sum(ha[k] * wv * j2o[k]))
        if sign > 0:
            cut = part
        else:
            fill = part
    out["cut"], out["fill"] = cut, fill
    return out


def contour_comparison(lines_a: list, heights_a, lines_b: list, heights_b) -> dict:
    """Per level, the closed and open line counts of two sets of contour lines and the
    symmetric Hausdorff distance between them (every vertex and segment quarter of each
    set to the other's nearest segment, by GEOS), in the lines' units:
    ``{level: (counts_a, counts_b, hausdorff)}`` with counts (closed, open); a line is
    closed when its last vertex is its first."""

    def split(lines, heights):
        out: dict = {}
        for line, h in zip(lines, np.asarray(heights, np.float64).tolist(), strict=True):
            p = np.asarray(line)[:, :2]
            out.setdefault(h, []).append((p, bool(np.array_equal(p[0], p[-1]))))
        return out

    a, b = split(lines_a, heights_a), split(lines_b, heights_b)
    res = {}
    for h in sorted(set(a) | set(b)):
        la, lb = a.get(h, []), b.get(h, [])
        ca = (sum(c for _, c in la), sum(not c for _, c in la))
        cb = (sum(c for _, c in lb), sum(not c for _, c in lb))
        d = np.inf
        if la and lb:
            d = max(_directed(la, lb), _directed(lb, la))
        res[h] = (ca, cb, d)
    return res


def _directed(la: list, lb: list) -> float:
    """The largest distance from a point of lines ``la`` (their vertices and the points
    at quarters of their segments) to lines ``lb`` (an STR tree of its segments)."""
    import shapely

    pa = np.concatenate([p for p, _ in la])
    qa = np.concatenate([p[:-1] + f * (p[1:] - p[:-1]) for p, _ in la if len(p) > 1
                         for f in (0.25, 0.5, 0.75)] or [pa[:0]])
    segs = np.concatenate([np.stack([p[:-1], p[1:]], 1) for p, _ in lb if len(p) > 1])
    tree = shapely.STRtree(shapely.linestrings(segs))
    pts = shapely.points(np.concatenate([pa, qa]))
    _, dist = tree.query_nearest(pts, return_distance=True, all_matches=False)
    return float(dist.max())
