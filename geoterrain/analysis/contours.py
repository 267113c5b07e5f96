"""Contour lines from the store, as ``gdal_contour`` draws them, written through OGR.

The lines are GDAL's marching squares (alg/marching_squares, GDAL 3.x) run on the grid
of sample centres: a value within 10⁻⁶ of a level counts as above it (GDAL's fudge), a
saddle always takes the same of its two configurations, crossings are interpolated
linearly along cell edges, and the grid is extended by a border of nodata so that lines
reach the raster's outer edge; a cell with nodata corners is split into quarters around
its valid ones, so lines stop half a cell from the voids. Crossings shared by two cells
are computed once each way with the same arithmetic, so segments join exactly: each
level's segments are chained into lines, closed rings where they come back to their
start (GDAL's SegmentMerger joins them at any shared end, whichever way they run).

At level 0 the lines are those of the DEM itself (within the codec error ε of the
source's, 0 when lossless). With ``max_error`` (the DEM's vertical unit) they are traced
on the coarsest pyramid level whose tile errors are at most that: every vertex then
lies where the full-resolution surface is within the stated ``bound`` of the line's
height (the level's surface and the full one are both linear along the cell edges the
vertices lie on, and differ by at most the tile error at the samples there). Tiles whose
height range holds no contour level are not decoded.

Examples
--------
>>> c = contours(t, interval=100.0)
>>> len(c.lines) == len(c.heights) == len(c.closed), c.level, c.bound
(True, 0, 0.0)
>>> bool(np.all(np.mod(c.heights, 100.0) == 0))
True
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit

from geoterrain.analysis.points import Reads
from geoterrain.core.frame import level_transform
from geoterrain.exceptions import UsageError, WriteError, exists_error

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Contours", "contours", "scene_lines", "write_contours"]

TOL = 1e-6  # GDAL's fudge: a value this close to a level counts as above it
MAX_LEVELS = 100_000  # GDAL's own limit


class Contours(NamedTuple):
    """Contour lines: ``lines`` (each an (n, 2) array in the DEM's CRS), ``heights`` (each
    line's level, the DEM's vertical unit), ``closed`` (a ring: its last vertex is its
    first), the pyramid ``level`` traced, its vertical ``bound`` (see the module), the
    ``unbounded`` tiles (touching nodata: no stated bound there; 0 at level 0) and
    ``stats`` (tiles decoded and skipped, seconds)."""

    lines: list
    heights: np.ndarray
    closed: np.ndarray
    level: int
    bound: float
    unbounded: int
    stats: dict


class Marching(NamedTuple):
    """The grid the squares run on: ``z`` (rows, cols; NaN nodata), which tiles to run
    (``run``, by tile row and column; tile size 2^``t``) and the sorted levels."""

    z: np.ndarray
    run: np.ndarray
    t: int
    levels: np.ndarray


@njit(cache=True, inline="always")
def _fudge(level, value):
    return value + TOL if abs(level - value) < TOL else value


@njit(cache=True, inline="always")
def _interp(level, x1, x2, y1, y2, need_split):
    """GDAL's interpolate_: the crossing of ``level`` between positions x1, x2 of values
    y1, y2; an unsplit edge goes through its middle as a split one would, so both give
    the same bits."""
    if need_split:
        xm = 0.5 * (x1 + x2)
        ym = 0.5 * (y1 + y2)
        fy1 = _fudge(level, y1)
        fym = _fudge(level, ym)
        if (fy1 < level < fym) or (fy1 > level > fym):
            x2 = xm
            y2 = ym
        else:
            x1 = xm
            y1 = ym
    fy1 = _fudge(level, y1)
    ratio = (level - fy1) / (_fudge(level, y2) - fy1)
    return x1 * (1.0 - ratio) + x2 * ratio


@njit(cache=True, inline="always")
def _border(b, level, q, split):
    """The crossing on border b (0 left, 1 lower, 2 right, 3 upper) of square q = (ULx,
    ULy, ULv, URx, URy, URv, LLx, LLy, LLv, LRx, LRy, LRv)."""
    ulx, uly, ulv, urx, ury, urv, llx, lly, llv, lrx, lry, lrv = q
    ns = not split
    if b == 0:
        return ulx, _interp(level, lly, uly, llv, ulv, ns)
    if b == 1:
        return _interp(level, llx, lrx, llv, lrv, ns), lly
    if b == 2:
        return urx, _interp(level, lry, ury, lrv, urv, ns)
    return _interp(level, ulx, urx, ulv, urv, ns), uly


# case (bits UL 1, LL 2, LR 4, UR 8) → segments as (from border, to border) pairs
_CASES = np.array([
    [-1, -1, -1, -1], [3, 0, -1, -1], [0, 1, -1, -1], [3, 1, -1, -1],
    [1, 2, -1, -1], [0, 1, 2, 3], [0, 2, -1, -1], [3, 2, -1, -1],
    [2, 3, -1, -1], [2, 0, -1, -1], [0, 1, 2, 3], [2, 1, -1, -1],
    [1, 3, -1, -1], [1, 0, -1, -1], [0, 3, -1, -1], [-1, -1, -1, -1]], np.int64)


@njit(cache=True)
def _square(q, split, levels, cases, out, n, fill):
    """Segments of one NaN-free square for every level it spans (GDAL's Square::process):
    written into ``out`` (x0, y0, x1, y1, level index) from row n when ``fill``; returns
    the new count."""
    vmin = min(q[2], q[5], q[8], q[11])
    vmax = max(q[2], q[5], q[8], q[11])
    k = np.searchsorted(levels, vmin - 2 * TOL)
    while k < levels.shape[0] and levels[k] <= vmax + 2 * TOL:
        lv = levels[k]
        case = ((1 if lv < _fudge(lv, q[2]) else 0) | (2 if lv < _fudge(lv, q[8]) else 0)
                | (4 if lv < _fudge(lv, q[11]) else 0) | (8 if lv < _fudge(lv, q[5]) else 0))
        for s in range(2):
            b0 = cases[case, 2 * s]
            if b0 < 0:
                break
            if fill:
                x0, y0 = _border(b0, lv, q, split)
                x1, y1 = _border(cases[case, 2 * s + 1], lv, q, split)
                out[n, 0] = x0
                out[n, 1] = y0
                out[n, 2] = x1
                out[n, 3] = y1
                out[n, 4] = k
            n += 1
        k += 1
    return n


@njit(cache=True, inline="always")
def _mid(a, b):
    if np.isnan(a):
        return b
    if np.isnan(b):
        return a
    return 0.5 * (a + b)


@njit(cache=True)
def march(grid, out, fill):
    """GDAL's marching squares over the grid extended by a nodata border: every square
    of a tile marked to run (its squares lie within one tile); returns the segment count
    (and writes them into ``out`` when ``fill``)."""
    z, run, t, levels = grid.z, grid.run, grid.t, grid.levels
    H, W = z.shape
    tl_r, tl_c = run.shape[0] - 1, run.shape[1] - 1
    cases = _CASES
    n = 0
    for r in range(H + 1):
        ty = min(max(r - 1, 0) >> t, tl_r)
        for c in range(-1, W):
            if not run[ty, min(max(c, 0) >> t, tl_c)]:
                continue
            ul = z[r - 1, c] if r >= 1 and c >= 0 else np.nan
            ur = z[r - 1, c + 1] if r >= 1 and c + 1 < W else np.nan
            ll = z[r, c] if r < H and c >= 0 else np.nan
            lr = z[r, c + 1] if r < H and c + 1 < W else np.nan
            nan = np.isnan(ul) + np.isnan(ur) + np.isnan(ll) + np.isnan(lr)
            if nan == 4:
                continue
            x0, x1, y0, y1 = c + 0.5, c + 1.5, r - 0.5, r + 0.5
            if nan == 0:
                q = (x0, y0, ul, x1, y0, ur, x0, y1, ll, x1, y1, lr)
                n = _square(q, False, levels, cases, out, n, fill)
                continue
            # split in four around the valid corners (GDAL's upperLeftSquare() …)
            xm, ym = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
            cv = ((0.0 if np.isnan(ll) else ll) + (0.0 if np.isnan(ul) else ul)
                  + (0.0 if np.isnan(lr) else lr) + (0.0 if np.isnan(ur) else ur)) / (4 - nan)
            up, lo = _mid(ul, ur), _mid(ll, lr)
            le, ri = _mid(ul, ll), _mid(ur, lr)
            if not np.isnan(ul):
                n = _square((x0, y0, ul, xm, y0, up, x0, ym, le, xm, ym, cv), True, levels,
                            cases, out, n, fill)
            if not np.isnan(ur):
                n = _square((xm, y0, up, x1, y0, ur, xm, ym, cv, x1, ym, ri), True, levels,
                            cases, out, n, fill)
            if not np.isnan(ll):
                n = _square((x0, ym, le, xm, ym, cv, x0, y1, ll, xm, y1, lo), True, levels,
                            cases, out, n, fill)
            if not np.isnan(lr):
                n = _square((xm, ym, cv, x1, ym, ri, xm, y1, lo, x1, y1, lr), True, levels,
                            cases, out, n, fill)
    return n


@njit(cache=True)
def _chain(a, b, npts):
    """Join segments (point ids ``a`` – ``b``) into lines as GDAL's SegmentMerger does, at
    any shared end (a point belongs to at most two segments): first the lines from each
    point with one segment, then the rings left. Returns (point ids in order, line starts,
    closed flags)."""
    m = a.shape[0]
    inc = np.full((npts, 2), -1, np.int64)
    deg = np.zeros(npts, np.int64)
    for s in range(m):
        for p in (a[s], b[s]):
            if deg[p] < 2:
                inc[p, deg[p]] = s
            deg[p] += 1
    seen = np.zeros(m, np.bool_)
    pts = np.empty(2 * m + 1, np.int64)
    starts = np.empty(m + 1, np.int64)
    closed = np.empty(m, np.bool_)
    k = 0
    nl = 0
    for phase in range(2):
        for s0 in range(m):
            if seen[s0]:
                continue
            if phase == 0:  # a line starts at a point with a single segment
                if deg[a[s0]] == 1:
                    p = a[s0]
                elif deg[b[s0]] == 1:
                    p = b[s0]
                else:
                    continue
            else:
                p = a[s0]
            starts[nl] = k
            closed[nl] = phase == 1
            nl += 1
            s = s0
            while s >= 0 and not seen[s]:
                seen[s] = True
                pts[k] = p
                k += 1
                p = b[s] if a[s] == p else a[s]  # across the segment
                t = inc[p, 0] if inc[p, 0] != s else inc[p, 1]
                s = t
            pts[k] = p
            k += 1
    starts[nl] = k
    return pts[:k], starts[:nl + 1], closed[:nl]


def _lines(seg: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Chain segments (x0, y0, x1, y1, level) into lines: (vertex arrays in grid
    coordinates, each line's level index, closed flags)."""
    seg = seg[(seg[:, 0] != seg[:, 2]) | (seg[:, 1] != seg[:, 3])]  # GDAL drops these
    if len(seg) == 0:
        return [], np.zeros(0, np.int64), np.zeros(0, bool)
    # segments meet where their ends have the same level and the same bits
    keys = np.concatenate([seg[:, [4, 0, 1]], seg[:, [4, 2, 3]]])
    order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
    ks = keys[order]
    new = np.ones(len(ks), bool)
    new[1:] = (ks[1:] != ks[:-1]).any(axis=1)
    ids = np.empty(len(ks), np.int64)
    ids[order] = np.cumsum(new) - 1
    uniq = ks[new]
    m = len(seg)
    pts, starts, closed = _chain(ids[:m], ids[m:], len(uniq))
    lines = [uniq[pts[a:b], 1:] for a, b in zip(starts[:-1], starts[1:], strict=True)]
    return lines, uniq[pts[starts[:-1]], 0].astype(np.int64), closed


def _levels(interval: float | None, base: float, levels: Any, lo: float, hi: float
            ) -> np.ndarray:
    if levels is not None:
        lv = np.unique(np.asarray(levels, np.float64).ravel())
        if lv.size == 0 or not np.isfinite(lv).all():
            raise UsageError("levels must be finite numbers")
        return lv
    if interval is None or not (math.isfinite(interval) and interval > 0):
        raise UsageError(f"interval must be a finite number > 0, got {interval}",
                         cli=f"--interval must be a finite number > 0, got {interval}")
    if not math.isfinite(base):
        raise UsageError("the base level must be finite", cli="--base must be finite")
    q0, q1 = (lo - 2 * TOL - base) / interval, (hi + 2 * TOL - base) / interval
    if not (math.isfinite(q0) and math.isfinite(q1)) or q1 - q0 > MAX_LEVELS:
        raise UsageError(f"interval {interval:g} makes too many levels over the data's "
                         f"{lo:g} … {hi:g}: give a larger interval")
    k0, k1 = math.ceil(q0), math.floor(q1)
    if k1 - k0 > MAX_LEVELS:
        raise UsageError(f"interval {interval:g} makes {k1 - k0} levels over the data's "
                         f"{lo:g} … {hi:g}: give a larger interval")
    return base + interval * np.arange(k0, k1 + 1, dtype=np.float64)


def _choose_level(terrain: TerrainLike, max_error: float | None) -> tuple[int, float, int]:
    """The coarsest level whose finite tile errors are all ≤ max_error, that bound, and
    how many of its tiles have none (they touch nodata)."""
    g, f = terrain.grid, terrain.frame
    zs = (f.z_scale or 1.0) * f.z_to_m
    if max_error is None:
        return 0, 0.0, 0
    if not (math.isfinite(max_error) and max_error >= 0):
        raise UsageError(f"max_error must be a finite number ≥ 0, got {max_error}",
                         cli=f"--max-error must be a finite number ≥ 0, got {max_error}")
    best = (0, 0.0, 0)
    for L in range(1, g.top_level + 1):
        errs = np.array([v["error"] for k, v in terrain.tile_info.items() if k[0] == L])
        fin = errs[np.isfinite(errs)] / zs
        if fin.size == 0 or fin.max() > max_error:
            break
        best = (L, float(fin.max()), int((~np.isfinite(errs)).sum()))
    return best


def contours(terrain: TerrainLike, interval: float | None = None, base: float = 0.0, *,
             levels: Any = None, max_error: float | None = None) -> Contours:
    """Contour lines every ``interval`` (offset ``base``) or at the given ``levels``, in
    the DEM's vertical unit, as ``gdal_contour -i interval -off base`` draws them.

    Parameters
    ----------
    terrain : an open store.
    interval, base : levels base + k · interval over the data's range.
    levels : explicit levels instead (``gdal_contour -fl``).
    max_error : trace the coarsest pyramid level whose tile errors are at most this;
        ``bound`` is then the largest of them (plus ε).

    Examples
    --------
    >>> c = contours(t, levels=[1000.0])
    >>> set(c.heights.tolist()) <= {1000.0}, all(len(line) >= 2 for line in c.lines)
    (True, True)
    """
    g, f = terrain.grid, terrain.frame
    zs = (f.z_scale or 1.0) * f.z_to_m
    with Reads(terrain) as reads:
        L, bound, unbounded = _choose_level(terrain, max_error)
        keys = terrain.tile_keys(L)
        lo = min(terrain.tile_info[k]["zmin"] for k in keys) / zs
        hi = max(terrain.tile_info[k]["zmax"] for k in keys) / zs
        lv = _levels(interval, base, levels, lo, hi)
        s = 1 << L
        H, W = -(-g.rows // s), -(-g.cols // s)  # the level's samples within the DEM
        (across, down), span = g.tiles(L), 1 << g.t
        z = np.full((H, W), np.nan)
        run = np.zeros((down, across), bool)
        skipped = 0
        for (_, x, y) in keys:
            info = terrain.tile_info[(L, x, y)]
            zlo, zhi = info["zmin"] / zs, info["zmax"] / zs
            i = np.searchsorted(lv, zlo - 2 * TOL)
            if i >= len(lv) or lv[i] > zhi + 2 * TOL:  # no level crosses the tile
                skipped += 1
                continue
            tile = terrain.tile(L, x, y)
            r0, c0 = y * span, x * span
            if r0 >= H or c0 >= W:
                continue
            r1, c1 = min(r0 + span + 1, H), min(c0 + span + 1, W)
            h = np.where(tile.valid, tile.heights, np.nan)
            z[r0:r1, c0:c1] = h[:r1 - r0, :c1 - c0]
            run[y, x] = True
        grid = Marching(z, run, g.t, lv)
        n = march(grid, np.empty((0, 5)), False)
        seg = np.empty((n, 5))
        march(grid, seg, True)
        lines, li, closed = _lines(seg)
        # grid coordinates (pixels of the level, corner origin) → the DEM's CRS
        A = level_transform(f.transform, L)
        for k, p in enumerate(lines):
            lines[k] = np.column_stack([A.a * p[:, 0] + A.c, A.e * p[:, 1] + A.f])
    eps = float(terrain.quantizer.codec_error)
    return Contours(lines, lv[li], closed, L, bound + eps, unbounded,
                    reads.stats(tiles_skipped=skipped, segments=int(n)))


def write_contours(c: Contours, path: str | Path, crs_wkt: str | None, *,
                   overwrite: bool = False, field: str = "elev") -> Path:
    """Write contour lines as a GeoPackage (``.gpkg``) or GeoJSON (``.geojson``, ``.json``)
    through OGR (pyogrio): one LineString feature a line with its height in ``field``
    (``gdal_contour -a elev``) and whether it is closed; written whole or not at all.

    Examples
    --------
    >>> import tempfile, os, pyogrio
    >>> p = write_contours(contours(t, 250.0), os.path.join(tempfile.mkdtemp(), "c.gpkg"),
    ...                    t.frame.crs_wkt)
    >>> pyogrio.read_info(p)["fields"].tolist()
    ['elev', 'closed']
    """
    import pyogrio
    import shapely
    from pyogrio.raw import write

    from geoterrain.core.atomicfiles import partial_path, publish

    out = Path(path)
    driver = {".gpkg": "GPKG", ".geojson": "GeoJSON", ".json": "GeoJSON"}.get(
        out.suffix.lower())
    if driver is None:
        raise UsageError(f"{out}: write contours as .gpkg (GeoPackage) or .geojson")
    if out.exists() and not overwrite:
        raise exists_error(out)
    tmp = Path(f"{partial_path(out)}{out.suffix}")  # OGR picks the format by the name
    if c.lines:
        idx = np.repeat(np.arange(len(c.lines)), [len(p) for p in c.lines])
        geoms = shapely.to_wkb(shapely.linestrings(np.concatenate(c.lines), indices=idx))
    else:
        geoms = np.array([], object)
    try:
        write(str(tmp), geoms, [np.asarray(c.heights, np.float64),
                                        np.asarray(c.closed, np.int32)],
                      [field, "closed"], layer="contour", driver=driver,
                      geometry_type="LineString", crs=crs_wkt)
        publish(tmp, out, overwrite)
    except (OSError, pyogrio.errors.DataSourceError, pyogrio.errors.DataLayerError) as exc:
        raise WriteError(f"{out}: cannot write the contours ({exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out


def scene_lines(terrain: TerrainLike, c: Contours, major: int = 5
                ) -> tuple[list[np.ndarray], list[float]]:
    """Contour lines in the scene frame ((n, 3): x, y, the level's height as drawn) for
    :func:`geoterrain.render`'s ``lines``, and their widths: every ``major``-th level of
    the interval (an index contour) twice as wide.

    Examples
    --------
    >>> lines, widths = scene_lines(t, contours(t, 200.0))
    >>> lines[0].shape[1], sorted(set(widths)) <= [1.0, 2.0]
    (3, True)
    """
    f = terrain.frame
    out, widths = [], []
    hs = np.asarray(c.heights, np.float64)
    step = np.min(np.diff(np.unique(hs))) if len(np.unique(hs)) > 1 else 0.0
    for p, h in zip(c.lines, hs.tolist(), strict=True):
        X, Y = f.crs_to_scene(p[:, 0], p[:, 1])
        out.append(np.column_stack([X, Y, np.full(len(p), h * f.z_to_m * f.z_scale)]))
        idx = step > 0 and abs(h / (step * major) - round(h / (step * major))) < 1e-9
        widths.append(2.0 if idx else 1.0)
    return out, widths
