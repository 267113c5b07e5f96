"""Areas and volumes of a polygon on the DEM's triangulated surface, exact at level 0.

The surface is the DEM's own triangulation (docs/conventions.md: every cell of the grid
of sample centres split along its union-jack diagonal), each triangle flat between its
three samples' positions (metres: the scene's on a projected grid; on a geographic grid
pyproj's Lambert azimuthal equal-area projection about the centre of each tile, so each
cell keeps its area on the ellipsoid wherever it lies: the scene's azimuthal-equidistant
frame, centred on the DEM, stretches areas with the distance from that centre, by 0.7 %
11° away and without bound toward its antipode) and heights (metres). The polygon's
edges are straight in the DEM's CRS.
Every triangle is clipped exactly against the polygon (Sutherland–Hodgman, the polygon
cut row by row and cell by cell), so

- ``area_2d`` (planimetric, m²) and ``area_3d`` (the true surface, m²) are the clipped
  triangles' areas in the scene frame and on their tilted planes;
- ``cut`` and ``fill`` (m³) integrate the height above and below the base (a height, a
  plane, or the plane fitted to the ground along the polygon's outline), each triangle
  split exactly where it crosses the base; ``net = cut − fill``;
- ``nodata_area`` (m²) is the polygon's part over cells without data (not counted).

With ``max_error`` (the DEM's vertical unit), each part of the polygon is read at the
coarsest pyramid level whose stored tile error is at most ``max_error`` (a quadtree walk
over the catalog: nothing decoded to choose), and the answer states its bound against the
level-0 answer on the source raster: a volume moves by at most the vertical error times
the area, a surface area by at most its gradient's change, 2√2·error / (cell size), times
the area.

Examples
--------
>>> c, f = t.frame.transform[2], t.frame.transform[5]
>>> square = [(c + 100.0, f - 100.0), (c + 300.0, f - 100.0), (c + 300.0, f - 300.0),
...           (c + 100.0, f - 300.0)]
>>> a = surface_area(t, square)
>>> round(a.area_2d, 6), bool(a.area_3d > a.area_2d), float(a.bound_3d)
(40000.0, True, 0.0)
>>> v = volume(t, square, base=0.0)  # all the ground above sea level: no fill
>>> float(v.fill), bool(v.cut == v.net > 0)
(0.0, True)
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit

from geoterrain.analysis.points import Reads, as_xy, grid_coords, inside, outside_error, to_source
from geoterrain.exceptions import InputError, UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Area", "Plane", "Volume", "polygon_rings", "surface_area", "volume"]


class Plane(NamedTuple):
    """A base plane z = a·x + b·y + c: x, y in the DEM's CRS, z in its vertical unit."""

    a: float
    b: float
    c: float

    @staticmethod
    def through(points: Any) -> Plane:
        """The plane through three points (x, y, z).

        Examples
        --------
        >>> Plane.through([(0, 0, 1), (1, 0, 3), (0, 1, 1)])
        Plane(a=2.0, b=0.0, c=1.0)
        """
        p = np.asarray(points, np.float64)
        if p.shape != (3, 3):
            raise UsageError("a base plane needs three points x, y, z")
        A = np.column_stack([p[:, :2], np.ones(3)])
        if abs(np.linalg.det(A)) < 1e-12 * max(1.0, float(np.abs(A).max()) ** 2):
            raise UsageError("the three base points are on one line: they define no plane")
        a, b, c = np.linalg.solve(A, p[:, 2])
        return Plane(float(a), float(b), float(c))


class Area(NamedTuple):
    """``area_2d`` (planimetric) and ``area_3d`` (surface) in m² over the polygon's data,
    ``nodata_area`` (m²), ``bound_3d`` (|area_3d − its level-0 value on the source| ≤
    bound, m²; 0 when exact), ``levels`` (pyramid level → tiles read there), ``stats``."""

    area_2d: float
    area_3d: float
    nodata_area: float
    bound_3d: float
    levels: dict
    stats: dict


class Volume(NamedTuple):
    """``cut`` (ground above the base) and ``fill`` (below it) in m³, ``net = cut − fill``,
    ``bound`` (each of them is within it of its level-0 value on the source, m³), the
    ``base`` used (a :class:`Plane`), the polygon's ``area_2d`` over data and
    ``nodata_area`` (m²), ``levels`` and ``stats``."""

    cut: float
    fill: float
    net: float
    bound: float
    base: Plane
    area_2d: float
    nodata_area: float
    levels: dict
    stats: dict


def polygon_rings(polygon: Any) -> list[list[np.ndarray]]:
    """A polygon as parts of rings, each an (n, 2) array, the first ring of a part its
    outline and the others its holes: from a shapely (Multi)Polygon, a GeoJSON-like
    mapping, WKT, or a sequence of (x, y) (one outline).

    Examples
    --------
    >>> [[r.shape for r in part] for part in polygon_rings("POLYGON ((0 0, 1 0, 1 1, 0 0))")]
    [[(4, 2)]]
    """
    import shapely
    from shapely.geometry import MultiPolygon, Polygon, shape

    geom = polygon
    try:
        if isinstance(polygon, str):
            geom = shapely.from_wkt(polygon)
        elif isinstance(polygon, dict):
            geom = shape(polygon.get("geometry", polygon))
        elif not isinstance(polygon, Polygon | MultiPolygon):
            geom = Polygon(as_xy(polygon))
    except (shapely.errors.ShapelyError, ValueError, TypeError, KeyError) as exc:
        raise UsageError(f"cannot read the polygon ({str(exc).splitlines()[0]}): give WKT, "
                         "GeoJSON or a list of x, y") from None
    if not isinstance(geom, Polygon | MultiPolygon):
        raise UsageError(f"expected a polygon, got a {geom.geom_type}")
    empty = UsageError("the polygon is empty (no area): give at least three distinct "
                       "vertices that enclose an area")
    if geom.is_empty:
        raise empty
    if not geom.is_valid:
        from shapely.validation import explain_validity

        why = explain_validity(geom)
        if not why.startswith("Too few points"):
            raise UsageError(f"the polygon is not valid ({why}): fix it (e.g. shapely's "
                             "make_valid, or QGIS's Fix geometries)")
    if geom.area == 0 or not geom.is_valid:
        raise empty
    parts = geom.geoms if isinstance(geom, MultiPolygon) else [geom]
    return [[np.asarray(p.exterior.coords)[:, :2]] +
            [np.asarray(h.coords)[:, :2] for h in p.interiors] for p in parts]


def _check_base(base: Any) -> Any:
    if isinstance(base, Plane | str):
        if isinstance(base, str) and base != "fit":
            raise UsageError(f"unknown base {base!r}: give a height, a Plane, three points "
                             "or 'fit'")
        return base
    try:
        b = np.asarray(base, np.float64)
    except (TypeError, ValueError):
        raise UsageError(f"cannot read the base {base!r}: give a height, a Plane, three "
                         "points or 'fit'") from None
    if b.shape == ():
        if not np.isfinite(b):
            raise UsageError("the base height must be a finite number")
        return Plane(0.0, 0.0, float(b))
    if b.shape == (3, 3):
        return Plane.through(b)
    raise UsageError(f"cannot read the base {base!r}: give a height, a Plane, three points "
                     "or 'fit'")


# ------------------------------------------------------------------- the clipping kernel


class TileSurface(NamedTuple):
    """One tile's surface as the kernel reads it: heights ``h`` (T, T) in metres (NaN:
    nodata), scene ``X``, ``Y`` (T, T), the base ``w0 + wu·u + wv·v`` (metres, in the
    tile's cell coordinates u down, v right), the parity of its first cell (``p0``) and
    its cells per side ``n``."""

    h: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    w0: float
    wu: float
    wv: float
    p0: int
    n: int


@njit(cache=True, nogil=True)
def _clip(pu, pv, n, a, b, c, ou, ov):
    """Sutherland–Hodgman: the polygon (pu, pv)[:n] cut to a·u + b·v + c ≥ 0, into
    (ou, ov); returns its vertex count. A subject of any shape is clipped against a
    half-plane with its winding numbers kept, so areas and moments stay exact."""
    m = 0
    if n == 0:
        return 0
    su, sv = pu[n - 1], pv[n - 1]
    sd = a * su + b * sv + c
    for k in range(n):
        eu, ev = pu[k], pv[k]
        ed = a * eu + b * ev + c
        if ed >= 0:
            if sd < 0:
                t = sd / (sd - ed)
                ou[m] = su + t * (eu - su)
                ov[m] = sv + t * (ev - sv)
                m += 1
            ou[m] = eu
            ov[m] = ev
            m += 1
        elif sd >= 0:
            t = sd / (sd - ed)
            ou[m] = su + t * (eu - su)
            ov[m] = sv + t * (ev - sv)
            m += 1
        su, sv, sd = eu, ev, ed
    return m


@njit(cache=True, nogil=True)
def _moments(pu, pv, n):
    """Signed area and first moments (∫u, ∫v) of the polygon (pu, pv)[:n]."""
    A = 0.0
    mu = 0.0
    mv = 0.0
    for k in range(n):
        u0, v0 = pu[k], pv[k]
        u1, v1 = pu[(k + 1) % n], pv[(k + 1) % n]
        cr = u0 * v1 - u1 * v0
        A += cr
        mu += (u0 + u1) * cr
        mv += (v0 + v1) * cr
    return 0.5 * A, mu / 6.0, mv / 6.0


@njit(cache=True, nogil=True)
def _triangle(surf, acc, pu, pv, n, ia, ib, ic):
    """Add a clipped piece (pu, pv)[:n] of the triangle on samples ia, ib, ic (each (row,
    col) in the tile) to ``acc``: [area_2d, area_3d, cut, fill, nodata, scratch...]."""
    A, mu, mv = _moments(pu, pv, n)
    if A == 0.0:
        return
    h, X, Y = surf.h, surf.X, surf.Y
    za, zb, zc = h[ia[0], ia[1]], h[ib[0], ib[1]], h[ic[0], ic[1]]
    # the triangle's affine map from cell coordinates to the scene: its three corners
    xa, ya = X[ia[0], ia[1]], Y[ia[0], ia[1]]
    e1x, e1y = X[ib[0], ib[1]] - xa, Y[ib[0], ib[1]] - ya
    e2x, e2y = X[ic[0], ic[1]] - xa, Y[ic[0], ic[1]] - ya
    du1, dv1 = ib[0] - ia[0], ib[1] - ia[1]
    du2, dv2 = ic[0] - ia[0], ic[1] - ia[1]
    jidx = du1 * dv2 - du2 * dv1  # the triangle's (signed) area × 2 in cell coordinates
    j2 = abs(e1x * e2y - e1y * e2x) / abs(jidx)
    if np.isnan(za) or np.isnan(zb) or np.isnan(zc):
        acc[4] += A * j2
        return
    e1z, e2z = zb - za, zc - za
    cx = e1y * e2z - e1z * e2y
    cy = e1z * e2x - e1x * e2z
    cz = e1x * e2y - e1y * e2x
    j3 = math.sqrt(cx * cx + cy * cy + cz * cz) / abs(jidx)
    acc[0] += A * j2
    acc[1] += A * j3
    # z − base, linear in (u, v): from the corners' values
    wa = za - (surf.w0 + surf.wu * ia[0] + surf.wv * ia[1])
    wb = zb - (surf.w0 + surf.wu * ib[0] + surf.wv * ib[1])
    wc = zc - (surf.w0 + surf.wu * ic[0] + surf.wv * ic[1])
    gu = ((wb - wa) * dv2 - (wc - wa) * dv1) / jidx
    gv = ((wc - wa) * du1 - (wb - wa) * du2) / jidx
    c0 = wa - gu * ia[0] - gv * ia[1]
    lo = min(wa, wb, wc)
    hi = max(wa, wb, wc)
    if lo >= 0.0:  # wholly above the base
        acc[2] += (c0 * A + gu * mu + gv * mv) * j2
        return
    if hi <= 0.0:
        acc[3] -= (c0 * A + gu * mu + gv * mv) * j2
        return
    qu = np.empty(2 * n + 4)
    qv = np.empty(2 * n + 4)
    m = _clip(pu, pv, n, gu, gv, c0, qu, qv)  # where the ground is above the base
    A1, mu1, mv1 = _moments(qu, qv, m)
    acc[2] += (c0 * A1 + gu * mu1 + gv * mv1) * j2
    m = _clip(pu, pv, n, -gu, -gv, -c0, qu, qv)
    A2, mu2, mv2 = _moments(qu, qv, m)
    acc[3] -= (c0 * A2 + gu * mu2 + gv * mv2) * j2


@njit(cache=True, nogil=True)
def integrate_tile(surf, ru, rv, starts, acc):
    """Add the rings (ru, rv) (ring k: ``starts[k]`` … ``starts[k+1]``, in the tile's cell
    coordinates; an outline's signed area positive, a hole's negative) clipped to each of
    the tile's triangles to ``acc`` (see :func:`_triangle`)."""
    n = surf.n
    for k in range(starts.shape[0] - 1):
        s0, s1 = starts[k], starts[k + 1]
        m = s1 - s0
        # a half-plane cuts an n-gon into at most 1.5 n + 2 vertices (each run of outside
        # vertices becomes two crossings): the buffers below hold every stage's output
        cap = 6 * m + 16
        au, av = np.empty(cap), np.empty(cap)
        bu, bv = np.empty(cap), np.empty(cap)
        # the ring cut to the tile
        m = _clip(ru[s0:s1], rv[s0:s1], m, 1.0, 0.0, 0.0, au, av)
        m = _clip(au, av, m, -1.0, 0.0, float(n), bu, bv)
        m = _clip(bu, bv, m, 0.0, 1.0, 0.0, au, av)
        m = _clip(au, av, m, 0.0, -1.0, float(n), bu, bv)
        if m < 3:
            continue
        umin, umax = bu[:m].min(), bu[:m].max()
        row_u, row_v = np.empty(3 * m + 16), np.empty(3 * m + 16)
        tmp_u, tmp_v = np.empty(6 * m + 32), np.empty(6 * m + 32)
        cel_u, cel_v = np.empty(6 * m + 32), np.empty(6 * m + 32)
        tri_u, tri_v = np.empty(9 * m + 64), np.empty(9 * m + 64)
        for a in range(max(int(math.floor(umin)), 0), min(int(math.ceil(umax)), n)):
            q = _clip(bu, bv, m, 1.0, 0.0, -float(a), tmp_u, tmp_v)
            q = _clip(tmp_u, tmp_v, q, -1.0, 0.0, float(a + 1), row_u, row_v)
            if q < 3:
                continue
            vmin, vmax = row_v[:q].min(), row_v[:q].max()
            for b in range(max(int(math.floor(vmin)), 0), min(int(math.ceil(vmax)), n)):
                p = _clip(row_u, row_v, q, 0.0, 1.0, -float(b), tmp_u, tmp_v)
                p = _clip(tmp_u, tmp_v, p, 0.0, -1.0, float(b + 1), cel_u, cel_v)
                if p < 3:
                    continue
                if (a + b + surf.p0) % 2 == 0:  # main diagonal (a, b)–(a+1, b+1)
                    # upper: v − b ≥ u − a (corners (a,b), (a,b+1), (a+1,b+1))
                    t = _clip(cel_u, cel_v, p, -1.0, 1.0, float(a - b), tri_u, tri_v)
                    _triangle(surf, acc, tri_u, tri_v, t, (a, b), (a, b + 1), (a + 1, b + 1))
                    t = _clip(cel_u, cel_v, p, 1.0, -1.0, float(b - a), tri_u, tri_v)
                    _triangle(surf, acc, tri_u, tri_v, t, (a, b), (a + 1, b + 1), (a + 1, b))
                else:  # anti-diagonal (a, b+1)–(a+1, b)
                    # upper-left: (u − a) + (v − b) ≤ 1
                    t = _clip(cel_u, cel_v, p, -1.0, -1.0, float(a + b + 1), tri_u, tri_v)
                    _triangle(surf, acc, tri_u, tri_v, t, (a, b), (a, b + 1), (a + 1, b))
                    t = _clip(cel_u, cel_v, p, 1.0, 1.0, -float(a + b + 1), tri_u, tri_v)
                    _triangle(surf, acc, tri_u, tri_v, t, (a + 1, b + 1), (a + 1, b),
                              (a, b + 1))


# ------------------------------------------------------------------------------ the API


def _tiles_for(terrain: TerrainLike, box: tuple[float, float, float, float],
               max_error: float | None) -> list[tuple[int, int, int]]:
    """The tiles the polygon's box (fi0, fi1, fj0, fj1) reaches, each at the coarsest
    level whose stored error is at most ``max_error`` (level 0 without it): a walk down
    the quadtree over the catalog."""
    g = terrain.grid
    zs = (terrain.frame.z_scale or 1.0) * terrain.frame.z_to_m  # scene units per DEM unit
    out: list[tuple[int, int, int]] = []
    across, down = g.roots  # the top tile, or every root of a root grid
    stack = [(g.top_level, x, y) for y in range(down) for x in range(across)]
    while stack:
        L, x, y = stack.pop()
        span = g.tile_span(L)
        if (y * span > box[1] or (y + 1) * span < box[0] or x * span > box[3]
                or (x + 1) * span < box[2]):
            continue
        info = terrain.tile_info.get((L, x, y))
        err = np.inf if info is None else info["error"]
        if L == 0 or (max_error is not None and err / zs <= max_error):
            out.append((L, x, y))
        else:
            stack += g.children(L, x, y)  # four, or fewer past a root grid's edge
    return out


def _measure(terrain: TerrainLike, polygon: Any, base: Any, max_error: float | None,
             crs: Any) -> dict:
    """Everything :func:`surface_area` and :func:`volume` report."""
    f, g = terrain.frame, terrain.grid
    if max_error is not None and not (math.isfinite(max_error) and max_error >= 0):
        raise UsageError(f"max_error must be a finite number ≥ 0, got {max_error}",
                         cli=f"--max-error must be a finite number ≥ 0, got {max_error}")
    base = _check_base(base)
    with Reads(terrain) as reads:
        parts = polygon_rings(polygon)
        rings, signs = [], []
        for part in parts:
            for k, ring in enumerate(part):
                src = to_source(f, ring, crs)
                fi, fj = grid_coords(f, src)
                out = ~inside(g, fi, fj)
                if out.any():
                    raise outside_error(f, g, ring, crs, out, "polygon vertex")
                uv = np.column_stack([fi, fj])
                # outlines positive, holes negative, in (row, column) coordinates
                area = 0.5 * np.sum(uv[:-1, 0] * uv[1:, 1] - uv[1:, 0] * uv[:-1, 1])
                if (area < 0) == (k == 0):
                    uv = uv[::-1]
                rings.append(uv[:-1] if np.array_equal(uv[0], uv[-1]) else uv)
                signs.append(k == 0)
        allv = np.concatenate(rings)
        box = (allv[:, 0].min(), allv[:, 0].max(), allv[:, 1].min(), allv[:, 1].max())
        if base == "fit":
            base = _fit_base(terrain, parts[0][0], crs)
        # the base in grid coordinates: z = a x + b y + c, x, y affine in (row, column)
        A_, _, C_, _, E_, F_ = f.transform[:6]
        b0 = base.a * (A_ * 0.5 + C_) + base.b * (E_ * 0.5 + F_) + base.c
        bi, bj = base.b * E_, base.a * A_
        tiles = _tiles_for(terrain, box, max_error)
        acc_all = np.zeros(8)
        vol_bound = area_bound = 0.0
        levels: dict[int, int] = {}
        eps = float(terrain.quantizer.codec_error)
        zs = (f.z_scale or 1.0) * f.z_to_m
        for L, x, y in tiles:
            acc = np.zeros(8)
            surf, org, spacing = _surface(terrain, L, x, y, (b0, bi, bj))
            s = float(1 << L)
            ru = np.concatenate([(r[:, 0] - org[0]) / s for r in rings])
            rv = np.concatenate([(r[:, 1] - org[1]) / s for r in rings])
            starts = np.cumsum([0] + [len(r) for r in rings]).astype(np.int64)
            integrate_tile(surf, ru, rv, starts, acc)
            if acc[0] == 0 and acc[4] == 0:
                continue
            levels[L] = levels.get(L, 0) + 1
            acc_all += acc
            info = terrain.tile_info.get((L, x, y))
            err = 0.0 if L == 0 or info is None else info["error"] / zs
            e_m = (err + eps) * f.z_to_m
            vol_bound += e_m * acc[0]
            if e_m > 0:
                area_bound += (2 * math.sqrt(2) * e_m / spacing * acc[0] if spacing > 0
                               else math.inf)
    area2, area3, cut, fill, nod = (float(v) for v in acc_all[:5])
    if area2 == 0 and nod == 0:
        raise InputError("the polygon covers no cell of the DEM (it lies within half a cell "
                         "of its edge): draw it over the data")
    return dict(area_2d=area2, area_3d=area3, cut=cut, fill=fill, nodata_area=nod,
                vol_bound=vol_bound, area_bound=area_bound, base=base, levels=levels,
                stats=reads.stats(tiles=len(tiles)))


def _surface(terrain: TerrainLike, L: int, x: int, y: int, base: tuple[float, float, float]
             ) -> tuple[TileSurface, tuple[int, int], float]:
    """Tile (L, x, y) for the kernel (heights in metres, NaN: nodata), its first sample's
    full-resolution (row, column), and its least ground spacing between level-0 samples
    (metres)."""
    f, g = terrain.frame, terrain.grid
    T, s = g.tile_samples, 1 << L
    rows, cols = g.tile_rows(L, y), g.tile_cols(L, x)
    if (L, x, y) in terrain.tile_info:
        tile = terrain.tile(L, x, y)
        h = np.where(tile.valid, tile.heights * f.z_to_m, np.nan)
    else:
        h = np.full((T, T), np.nan)
    ii, jj = np.meshgrid(rows, cols, indexing="ij")
    X, Y = tile_positions(f, ii, jj)
    b0, bi, bj = base
    w0 = (b0 + bi * rows[0] + bj * cols[0]) * f.z_to_m
    surf = TileSurface(h, np.ascontiguousarray(X), np.ascontiguousarray(Y), w0,
                       bi * s * f.z_to_m, bj * s * f.z_to_m, int((y * (T - 1) + x * (T - 1)) % 2),
                       T - 1)
    # the level-0 cell's least side on the ground (the surface-area bound's h)
    # (samples past a pole, clamped to it, coincide: their zero steps are no cell's)
    d = np.concatenate([np.hypot(np.diff(X, axis=1), np.diff(Y, axis=1)).ravel(),
                        np.hypot(np.diff(X, axis=0), np.diff(Y, axis=0)).ravel()])
    d = d[d > 0]
    return surf, (int(rows[0]), int(cols[0])), float(d.min()) / s if d.size else 0.0


def tile_positions(f: Any, ii: np.ndarray, jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (metres) of one tile's samples (ii, jj) for measuring areas on it: the
    scene's (:meth:`Frame.xy`) on a projected or pixel grid; on a geographic grid a
    Lambert azimuthal equal-area projection on the CRS's ellipsoid about the tile's
    centre (an equal-area map: a cell's area is its area on the ellipsoid, to the
    second order of its size, wherever the tile lies).

    Examples
    --------
    >>> from pyproj import CRS
    >>> from geoterrain.core.frame import Frame
    >>> f = Frame.from_raster((1.0, 0, 170.0, 0, -1.0, 2.0), CRS.from_epsg(4326).to_wkt(), 3, 3)
    >>> X, Y = tile_positions(f, *np.meshgrid(np.arange(3), np.arange(3), indexing="ij"))
    >>> round(float(X[1, 2] - X[1, 0]) / 1000, 1)  # 2° of longitude at 0.5° N, in km
    222.6
    """
    if f.kind != "geographic":
        return f.xy(ii, jj)
    lon, lat = f.crs_xy(ii, jj)
    lat = np.clip(lat, -90.0, 90.0)  # padding rows may run past a pole
    c = tuple(s // 2 for s in np.shape(ii))
    proj = _equal_area(f.crs_wkt, float(lat[c]), float(lon[c]))
    X, Y = proj.transform(lon, lat)
    return np.asarray(X, np.float64), np.asarray(Y, np.float64)


@lru_cache(maxsize=64)
def _ellipsoid(crs_wkt: str) -> str:
    """The PROJ ellipsoid parameters of a CRS's datum (+a, +rf; +R for a sphere)."""
    from pyproj import CRS

    ell = CRS.from_wkt(crs_wkt).ellipsoid
    a = ell.semi_major_metre if ell is not None else 6378137.0
    rf = ell.inverse_flattening if ell is not None else 298.257223563
    return f"+a={a!r} +rf={rf!r}" if rf else f"+R={a!r}"


@lru_cache(maxsize=256)
def _equal_area(crs_wkt: str, lat0: float, lon0: float) -> Any:
    """A pyproj transformer from (longitude, latitude) in degrees to a Lambert azimuthal
    equal-area projection about (lat0, lon0) on the CRS's ellipsoid (a PROJ pipeline:
    0.2 ms to build, against 150 ms through a projected CRS object)."""
    from pyproj import Transformer

    return Transformer.from_pipeline(
        "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
        f"+step +proj=laea +lat_0={lat0!r} +lon_0={lon0!r} {_ellipsoid(crs_wkt)}")


def _fit_base(terrain: TerrainLike, ring: np.ndarray, crs: Any) -> Plane:
    """The least-squares plane through the ground along the outline (every cell's
    length), the base of a stockpile's volume."""
    from geoterrain.analysis.profile import profile

    p = profile(terrain, ring, crs=crs)
    src = to_source(terrain.frame, p.xy, crs)
    ok = np.isfinite(p.height)
    if ok.sum() < 3:
        raise InputError("the polygon's outline crosses too little data to fit a base plane")
    A = np.column_stack([src[ok], np.ones(ok.sum())])
    a, b, c = np.linalg.lstsq(A, p.height[ok], rcond=None)[0]
    return Plane(float(a), float(b), float(c))


def surface_area(terrain: TerrainLike, polygon: Any, *, max_error: float | None = None,
                 crs: Any = None) -> Area:
    """Planimetric and true (3-D) area of ``polygon`` on the DEM's triangulated surface.

    Parameters
    ----------
    polygon : a shapely (Multi)Polygon, GeoJSON mapping, WKT, or (N, 2) outline, in the
        DEM's CRS or ``crs``. Holes are left out.
    max_error : read each part at the coarsest level whose tile error is at most this
        (the DEM's vertical unit); the answer's ``bound_3d`` says how far that can move
        the surface area.

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> tri = [(c + 100.0, f - 100.0), (c + 900.0, f - 100.0), (c + 100.0, f - 900.0)]
    >>> coarse = surface_area(t, tri, max_error=100.0)
    >>> exact = surface_area(t, tri)
    >>> bool(abs(coarse.area_3d - exact.area_3d) <= coarse.bound_3d), max(coarse.levels) > 0
    (True, True)
    """
    m = _measure(terrain, polygon, 0.0, max_error, crs)
    return Area(m["area_2d"], m["area_3d"], m["nodata_area"], m["area_bound"], m["levels"],
                m["stats"])


def volume(terrain: TerrainLike, polygon: Any, base: Any = 0.0, *,
           max_error: float | None = None, crs: Any = None) -> Volume:
    """Cut and fill volumes (m³) of the ground above and below ``base`` within
    ``polygon``, exact on the DEM's triangulated surface.

    Parameters
    ----------
    polygon : as :func:`surface_area`'s.
    base : a height (the DEM's vertical unit), a :class:`Plane`, three points (x, y, z)
        it passes through, or ``"fit"``: the least-squares plane through the ground along
        the polygon's outline (a stockpile's or a pit's base).
    max_error : as :func:`surface_area`'s; ``bound`` is then the vertical error times the
        area (plus the codec error's share).

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> sq = [(c + 100.0, f - 100.0), (c + 300.0, f - 100.0), (c + 300.0, f - 300.0),
    ...       (c + 100.0, f - 300.0)]
    >>> v = volume(t, sq, base="fit")
    >>> v.cut >= 0 and v.fill >= 0 and abs(v.net - (v.cut - v.fill)) < 1e-6
    True
    """
    m = _measure(terrain, polygon, base, max_error, crs)
    return Volume(m["cut"], m["fill"], m["cut"] - m["fill"], m["vol_bound"], m["base"],
                  m["area_2d"], m["nodata_area"], m["levels"], m["stats"])
