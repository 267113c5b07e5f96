"""Heights and normals at points, straight from the store.

Level 0 (the default) is the DEM itself: the height at a point is the bilinear
interpolation of the four samples around it (sample (i, j) at the centre of source pixel
(i, j); within half a cell of the raster's edge the outermost samples are extended), in
the DEM's own vertical unit, exactly what a bilinear read of the source raster gives
(within the store's codec error ε, 0 for a lossless store). A point whose interpolation
needs a nodata sample (one with a weight above 0) gets NaN, never a number; a point
outside the raster's extent gets NaN too (:func:`height_at` says how many). A whole-globe
grid (its columns span 360°, :attr:`~geoterrain.core.frame.Frame.columns_per_turn`) has no
edge east or west: a point between its last column and its first (across 180°)
interpolates the two, and any longitude (190° is −170°) lies on it.

At a coarser pyramid level L the answer reads only level-L tiles: the level-L surface
(the union-jack triangulation of every 2^L-th sample, the surface a static mesh of the
level draws) sampled at the four DEM samples around the point and interpolated as at
level 0. Its error against the level-0 answer is at most the largest error of that
surface at those samples, which the store bounds: the level-L tile's error (the max of
|z − S_L| over its samples, :mod:`geoterrain.bounds.tilebounds`) or, where that tile
touches nodata, the per-vertex δ of the cell's centre (seed 002's δ, the exact max over
its diamond, which is the level-L cell). Each answer comes with that bound (plus ε, so it
holds against the source raster) and the level it was read at: a point whose level-L cell
touches nodata (its bound is +inf) is read one level finer, down to level 0.

Normals are those of the level-0 bilinear surface, in metres (east, north, up, unit
length), with the slope (degrees) and aspect (degrees clockwise from north, the way the
slope faces; NaN on flat ground) that ``gdaldem`` reports.

Examples
--------
>>> c, f = t.frame.transform[2], t.frame.transform[5]
>>> pts = np.array([[c + 15.0, f - 15.0], [c + 333.0, f - 777.0]])
>>> z = height_at(t, pts)
>>> h = t.tile(0, 0, 0).heights
>>> bool(z.height[0] == h[1, 1]), z.bound.tolist(), z.level.tolist()
(True, [0.0, 0.0], [0, 0])
>>> coarse = height_at(t, pts, level=2)
>>> bool(np.all(np.abs(coarse.height - z.height) <= coarse.bound))
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from geoterrain.analysis.points import (
    Reads,
    as_xy,
    frame_geod,
    inside,
    source_xy,
    to_source,
    turn_coords,
)
from geoterrain.exceptions import UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Heights", "Normals", "cell_corners", "height_at", "normal_at"]


class Heights(NamedTuple):
    """Heights at points: ``height`` (source vertical unit; NaN at nodata or outside the
    data), ``bound`` (|height − the source raster's bilinear height| ≤ bound, same unit),
    ``level`` (the pyramid level each was read at), ``stats`` (tiles decoded, bytes read,
    seconds, points outside the data)."""

    height: np.ndarray
    bound: np.ndarray
    level: np.ndarray
    stats: dict


class Normals(NamedTuple):
    """Unit normals (…, 3: east, north, up; metres on both axes) of the level-0 bilinear
    surface at points, the slope (degrees from horizontal), the aspect (degrees clockwise
    from north that the slope faces; NaN where flat) and the read stats. NaN at nodata."""

    normal: np.ndarray
    slope: np.ndarray
    aspect: np.ndarray
    stats: dict


def cell_corners(terrain: TerrainLike, level: int, ci: np.ndarray, cj: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Heights (n, 4) (source units) and valid flags (n, 4) of the corners of level-L cells
    (row ``ci``, column ``cj`` in level-L samples), in the order (0, 0), (0, 1), (1, 0),
    (1, 1). Decodes each level-L tile holding one once (every cell lies in one tile);
    a tile that is not stored (no data) gives invalid corners.

    Examples
    --------
    >>> h, ok = cell_corners(t, 0, np.array([0]), np.array([0]))
    >>> bool(h[0, 3] == t.tile(0, 0, 0).heights[1, 1]), ok.tolist()
    (True, [[True, True, True, True]])
    """
    g = terrain.grid
    ci, cj = np.asarray(ci, np.int64), np.asarray(cj, np.int64)
    n = ci.shape[0]
    h = np.full((n, 4), np.nan)
    ok = np.zeros((n, 4), bool)
    if n == 0:
        return h, ok
    across = g.tiles(level)[0]  # 2^(top − L), or a root grid's tiles across
    ty, tx = ci >> g.t, cj >> g.t
    key = ty * across + tx
    order = np.argsort(key, kind="stable")
    ks = key[order]
    cuts = np.flatnonzero(np.diff(ks)) + 1
    a_all, b_all = ci - (ty << g.t), cj - (tx << g.t)
    for grp in np.split(order, cuts):  # one decode per tile, never per point
        k = int(key[grp[0]])
        tkey = (level, k % across, k // across)
        if tkey not in terrain.tile_info:
            continue
        tile = terrain.tile(*tkey)
        a, b = a_all[grp], b_all[grp]
        for c, (da, db) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
            h[grp, c] = tile.heights[a + da, b + db]
            ok[grp, c] = tile.valid[a + da, b + db]
    return h, ok


def _level0_cells(terrain: TerrainLike, fi: np.ndarray, fj: np.ndarray):
    """Each point's level-0 cell (i0, j0) and its fractions (u down, v right) in [0, 1],
    the outermost samples extended over the half cell beyond them. On a whole-globe grid
    (``fj`` from :func:`turn_coords`) the columns wrap instead: a point across 180° gets
    the cell j0 = cols − 1, whose right-hand corners are column 0's (:func:`_corners0`)."""
    g = terrain.grid
    fi = np.clip(fi, 0.0, g.rows - 1.0)
    i0 = np.minimum(np.floor(fi), max(g.rows - 2, 0)).astype(np.int64)
    if terrain.frame.columns_per_turn:
        fj = np.mod(fj, g.cols)
        j0 = np.minimum(np.floor(fj), g.cols - 1).astype(np.int64)
    else:
        fj = np.clip(fj, 0.0, g.cols - 1.0)
        j0 = np.minimum(np.floor(fj), max(g.cols - 2, 0)).astype(np.int64)
    return i0, j0, fi - i0, fj - j0


def _corners0(terrain: TerrainLike, i0: np.ndarray, j0: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cell_corners` at level 0 for :func:`_level0_cells`' cells: a whole-globe
    grid's wrapping cell (j0 = cols − 1) takes its left corners from the last column and
    its right corners from the first."""
    last = terrain.grid.cols - 1
    wrap = j0 >= last
    if not wrap.any():
        return cell_corners(terrain, 0, i0, j0)
    h, ok = cell_corners(terrain, 0, i0, np.where(wrap, last - 1, j0))
    w = np.flatnonzero(wrap)
    h0, ok0 = cell_corners(terrain, 0, i0[w], np.zeros(w.size, np.int64))
    h[w, 0], h[w, 2], ok[w, 0], ok[w, 2] = h[w, 1], h[w, 3], ok[w, 1], ok[w, 3]
    h[w, 1], h[w, 3], ok[w, 1], ok[w, 3] = h0[:, 0], h0[:, 2], ok0[:, 0], ok0[:, 2]
    return h, ok


def _weights(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear weights (n, 4) of the corners (0, 0), (0, 1), (1, 0), (1, 1)."""
    return np.stack([(1 - u) * (1 - v), (1 - u) * v, u * (1 - v), u * v], axis=1)


def _bilinear(h: np.ndarray, ok: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of corner values (n, 4); NaN where a corner with a weight
    above 0 is not valid. Evaluated as two lerps along the rows, then one down."""
    need = _weights(u, v) > 0
    bad = (need & ~ok).any(axis=1)
    hz = np.where(ok, h, 0.0)
    top = hz[:, 0] * (1 - v) + hz[:, 1] * v
    bot = hz[:, 2] * (1 - v) + hz[:, 3] * v
    z = top * (1 - u) + bot * u
    z[bad] = np.nan
    return z


def _union_jack(zc: np.ndarray, main: np.ndarray, di: np.ndarray, dj: np.ndarray
                ) -> np.ndarray:
    """The level-L union-jack surface in a cell (corner heights ``zc`` (n, 4), ``main``:
    split along (0, 0)–(1, 1), else (0, 1)–(1, 0)) at cell fractions di (down), dj (right)
    in [0, 1] (docs/conventions.md)."""
    z00, z01, z10, z11 = (zc[:, k:k + 1] for k in range(4))
    m = main[:, None]
    up = z00 + (z01 - z00) * dj + (z11 - z01) * di
    lo = z00 + (z10 - z00) * di + (z11 - z10) * dj
    ul = z00 + (z10 - z00) * di + (z01 - z00) * dj
    lr = z11 + (z01 - z11) * (1 - di) + (z10 - z11) * (1 - dj)
    return np.where(m, np.where(dj >= di, up, lo), np.where(di + dj <= 1, ul, lr))


def _coarse(terrain: TerrainLike, level: int, i0, j0, u, v):
    """Heights at level L (as the module says) and their bound in scene units (inf where
    the level cannot answer: a corner without data, or a cell mixing data and nodata)."""
    g = terrain.grid
    s = 1 << level
    rows, cols = g.level_shape(level)  # S × S, or a root grid's level
    ci, cj = np.minimum(i0 >> level, rows - 2), np.minimum(j0 >> level, cols - 2)
    zc, okc = cell_corners(terrain, level, ci, cj)
    main = ((ci + cj) % 2) == 0
    # the four DEM samples around the point, as fractions of the level-L cell
    di = ((i0 - ci * s)[:, None] + np.array([0, 0, 1, 1])) / s
    dj = ((j0 - cj * s)[:, None] + np.array([0, 1, 0, 1])) / s
    surf = _union_jack(zc, main, di, dj)
    ok4 = okc.all(axis=1)
    z = _bilinear(surf, np.repeat(ok4[:, None], 4, axis=1), u, v)
    # the bound: the level-L tile's error, else (nodata in the tile) the cell centre's δ
    across = g.tiles(level)[0]
    keys = zip((ci >> g.t).tolist(), (cj >> g.t).tolist(), strict=True)
    err = np.array([terrain.tile_info.get((level, x % across, y), {}).get("error", np.inf)
                    for y, x in keys], np.float64)
    err = np.where(np.isfinite(err) & ok4, err, np.inf)
    need = ok4 & ~np.isfinite(err)
    if need.any() and level >= 2:  # level 1's centres are level-0 vertices: their δ is
        # rebuilt from level-0 heights on read, which costs what level 0 would
        d = terrain.gather(ci[need] * s + s // 2, cj[need] * s + s // 2, ("delta",))["delta"]
        err[need] = d
    return z, err


def height_at(terrain: TerrainLike, points: Any, level: int = 0, *, crs: Any = None
              ) -> Heights:
    """Heights at ``points`` (an (N, 2) array of x, y, or one point), bilinear on the DEM's
    own samples at level 0, or from pyramid level ``level`` with a guaranteed bound.

    Parameters
    ----------
    terrain : an open store (:func:`geoterrain.open`).
    points : x, y in the DEM's CRS, or in ``crs`` (``"lonlat"``: longitude, latitude in
        degrees; any EPSG code, PROJ string or WKT that pyproj reads).
    level : pyramid level (0: full resolution). A point whose level-L cell touches nodata
        is read at the finest level it needs (``level`` of the answer).

    Returns
    -------
    Heights
        ``height`` (N,) in the DEM's vertical unit (NaN at nodata and outside the data),
        ``bound`` (N,) with |height − bilinear height of the source| ≤ bound (the codec
        error ε at level 0, so 0 for a lossless store), ``level`` (N,), ``stats``.

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> height_at(t, (c + 10.0, f - 10.0)).height.shape
    (1,)
    """
    top = terrain.grid.top_level
    if not (isinstance(level, int | np.integer) and 0 <= level <= top):
        raise UsageError(f"level must be an integer in 0..{top}, got {level}",
                         cli=f"--level must be in 0..{top}, got {level}")
    with Reads(terrain) as reads:
        xy = to_source(terrain.frame, as_xy(points), crs)
        fi, fj = turn_coords(terrain.frame, xy)
        ins = inside(terrain.grid, fi, fj)
        i0, j0, u, v = _level0_cells(terrain, fi, fj)
        wraps = j0 >= terrain.grid.cols - 1  # across 180° on a whole-globe grid: level 0
        n = xy.shape[0]
        z = np.full(n, np.nan)
        bound = np.full(n, np.nan)
        lev = np.zeros(n, np.int8)
        zunit = terrain.frame.z_to_m * terrain.frame.z_scale  # scene units per source unit
        eps = float(terrain.quantizer.codec_error)
        todo = np.flatnonzero(ins & ~wraps)
        for L in range(int(level), 0, -1):
            if todo.size == 0:
                break
            zl, err = _coarse(terrain, L, i0[todo], j0[todo], u[todo], v[todo])
            done = np.isfinite(err) & np.isfinite(zl)
            z[todo[done]] = zl[done]
            bound[todo[done]] = err[done] / zunit + eps
            lev[todo[done]] = L
            todo = todo[~done]
        todo = np.union1d(todo, np.flatnonzero(ins & wraps))
        if todo.size:
            h, ok = _corners0(terrain, i0[todo], j0[todo])
            z[todo] = _bilinear(h, ok, u[todo], v[todo])
            bound[todo] = np.where(np.isfinite(z[todo]), eps, np.nan)
            lev[todo] = 0
    return Heights(z, bound, lev, reads.stats(points=n, outside=int((~ins).sum())))


def _ground_corners(frame, i0: np.ndarray, j0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Metres east (n, 4) and north (n, 4) of the corners (0, 0), (0, 1), (1, 0), (1, 1) of
    level-0 cells. A projected grid's come from its CRS (grid north, as gdaldem's). On a
    geographic grid each corner is placed from the cell's first corner by the geodesic's
    length and azimuth (pyproj's ``Geod``): east and north are the ground's there, where
    the scene's plane (azimuthal equidistant about the DEM's centre) turns away from north
    and stretches across the azimuth far from its centre."""
    di, dj = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
    if frame.kind != "geographic":
        return frame.xy(i0[:, None] + di, j0[:, None] + dj)
    lon, lat = source_xy(frame, (i0[:, None] + di).ravel(), (j0[:, None] + dj).ravel()).T
    lon, lat = lon.reshape(-1, 4), np.clip(lat, -90.0, 90.0).reshape(-1, 4)
    lon0, lat0 = np.repeat(lon[:, :1], 4, axis=1), np.repeat(lat[:, :1], 4, axis=1)
    az, _, d = frame_geod(frame).inv(lon0, lat0, lon, lat)
    az = np.radians(np.asarray(az, np.float64))
    d = np.asarray(d, np.float64)
    return d * np.sin(az), d * np.cos(az)


def normal_at(terrain: TerrainLike, points: Any, *, crs: Any = None) -> Normals:
    """Unit normals, slope and aspect of the level-0 bilinear surface at ``points``.

    The gradient of the bilinear interpolation at the point (in its cell; on a cell edge,
    the cell below and to the right), in metres on all three axes: heights × the DEM's
    vertical unit, and the cell's ground size: its CRS's on a projected grid (aspect from
    grid north, as gdaldem's), geodesic lengths and azimuths on a geographic grid (aspect
    from true north, anywhere on the globe), without vertical exaggeration.

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> nrm = normal_at(t, [(c + 100.0, f - 200.0)])
    >>> bool(np.isclose(np.linalg.norm(nrm.normal[0]), 1.0)), bool(0 <= nrm.slope[0] < 90)
    (True, True)
    """
    f = terrain.frame
    with Reads(terrain) as reads:
        xy = to_source(f, as_xy(points), crs)
        fi, fj = turn_coords(f, xy)
        ins = inside(terrain.grid, fi, fj)
        i0, j0, u, v = _level0_cells(terrain, fi, fj)
        h, ok = _corners0(terrain, i0, j0)
        z = _bilinear(h, ok, u, v)
        good = ins & np.isfinite(z) & ok.all(axis=1)
        hm = np.where(ok, h, 0.0) * f.z_to_m
        dz_di = (1 - v) * (hm[:, 2] - hm[:, 0]) + v * (hm[:, 3] - hm[:, 1])
        dz_dj = (1 - u) * (hm[:, 1] - hm[:, 0]) + u * (hm[:, 3] - hm[:, 2])
        # the cell's ground Jacobian (metres east and north per row and per column)
        X, Y = _ground_corners(f, i0, j0)
        dX_di = (1 - v) * (X[:, 2] - X[:, 0]) + v * (X[:, 3] - X[:, 1])
        dX_dj = (1 - u) * (X[:, 1] - X[:, 0]) + u * (X[:, 3] - X[:, 2])
        dY_di = (1 - v) * (Y[:, 2] - Y[:, 0]) + v * (Y[:, 3] - Y[:, 1])
        dY_dj = (1 - u) * (Y[:, 1] - Y[:, 0]) + u * (Y[:, 3] - Y[:, 2])
        det = dX_di * dY_dj - dX_dj * dY_di
        # [dz/dX, dz/dY] = J^-T [dz/di, dz/dj]
        gx = (dY_dj * dz_di - dY_di * dz_dj) / det
        gy = (-dX_dj * dz_di + dX_di * dz_dj) / det
        nrm = np.stack([-gx, -gy, np.ones_like(gx)], axis=1)
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        slope = np.degrees(np.arctan(np.hypot(gx, gy)))
        flat = (gx == 0) & (gy == 0)
        aspect = np.where(flat, np.nan, np.degrees(np.arctan2(-gx, -gy)) % 360.0)
        nrm[~good] = np.nan
        slope[~good] = np.nan
        aspect[~good] = np.nan
    return Normals(nrm, slope, aspect, reads.stats(points=len(xy), outside=int((~ins).sum())))
