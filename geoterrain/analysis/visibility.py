"""Line of sight and viewsheds, read from the store's tiles only where the terrain can
reach the sight lines.

Both lower every height by Earth's curvature and the air's refraction as
``gdal_viewshed`` does: z − c·d²/(2a), d the ground distance from the observer, a the
semi-major axis of the DEM's ellipsoid and c the curvature coefficient (0.85714 by
default: refraction bends sight lines back by a seventh of the curvature; 0 switches
both off). Observer and target heights are metres above the ground; the ground is the
DEM's (in metres, whatever its vertical unit).

- :func:`viewshed` is Wang, Robinson & White's reference-plane sweep (2000) as
  ``gdal_viewshed`` runs it (:mod:`geoterrain.analysis.sweep`), on the DEM's full
  resolution: each cell is decided exactly as a sweep over the source raster decides
  it, or marked uncertain where the store's codec error ε could change the answer. A
  tile whose box lies below every sight line that reaches it is never decoded
  (:mod:`geoterrain.analysis.window`). After the observer's row, the rows north and
  south of it depend only on that row: the two halves are swept on two threads where
  there are two cores (the same answer as one after the other). The tiles are read in
  one read transaction of the store (:meth:`~geoterrain.terrain.Terrain.snapshot`).
- :func:`line_of_sight` follows one ray exactly over the bilinear surface (the surface
  :func:`~geoterrain.analysis.heights.height_at` samples): in each cell the ray crosses,
  the clearance is a quadratic in the distance and its least value is found in closed
  form. Tiles whose box lies below the ray are not decoded.

A nodata void neither hides anything nor is seen (it has no answer); an observer (or
target) in nodata or outside the data is refused with a one-line error.

Examples
--------
>>> c, f = t.frame.transform[2], t.frame.transform[5]
>>> vs = viewshed(t, (c + 640.0, f - 640.0), radius=400.0, height=2.0)
>>> vs.codes.dtype.name, int(vs.codes[vs.observer_cell]), vs.stats["uncertain"]
('uint8', 1, 0)
>>> los = line_of_sight(t, (c + 640.0, f - 640.0), (c + 700.0, f - 640.0), 2.0, 0.0)
>>> los.visible == (los.clearance >= 0), los.distance
(True, 60.0)
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from geoterrain.analysis.heights import _bilinear, cell_corners
from geoterrain.analysis.points import (
    Reads,
    as_xy,
    frame_geod,
    grid_coords,
    inside,
    outside_error,
    source_xy,
    to_source,
)
from geoterrain.analysis.sweep import (
    HIDDEN,
    MODES,
    NEED_NONE,
    NO_ANSWER,
    UNCERTAIN,
    VISIBLE,
    SweepGeometry,
    SweepState,
    SweepTiles,
    count_codes,
    sweep_rows,
)
from geoterrain.analysis.window import Half, Window
from geoterrain.exceptions import InputError, UsageError, WriteError, exists_error

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["CURVATURE", "LineOfSight", "Viewshed", "line_of_sight", "viewshed",
           "write_viewshed"]

CURVATURE = 0.85714  # gdal_viewshed's default -cc: curvature less a seventh for refraction
PALETTE = {HIDDEN: (40, 40, 48, 255), VISIBLE: (255, 214, 0, 255),
           UNCERTAIN: (230, 0, 230, 255), NO_ANSWER: (0, 0, 0, 0)}


class Viewshed(NamedTuple):
    """A viewshed on the source grid: ``codes`` (rows, cols) uint8 over the window of the
    DEM that the radius reaches (0 hidden, 1 visible, 255 uncertain, 254 no answer:
    outside the radius or nodata), its ``transform`` (rasterio Affine, the source's pixel
    size) and ``crs_wkt``; ``observer_cell`` (row, col) in ``codes``; ``observer`` (x, y in
    the source CRS, ground and eye heights in metres); ``stats`` (tiles decoded and
    skipped, bytes read, seconds, the count of each code)."""

    codes: np.ndarray
    transform: Any
    crs_wkt: str | None
    observer_cell: tuple[int, int]
    observer: tuple[float, float, float, float]
    stats: dict


class LineOfSight(NamedTuple):
    """Whether the target sees the observer: ``visible`` (on the stored heights),
    ``certain`` (False when the codec error ε could change it), ``clearance`` (the least
    height of the sight line above the terrain between them, metres, after curvature;
    negative when blocked), ``obstruction`` (x, y in the source CRS and ground height in
    metres of the first point that blocks the sight line; None when visible), ``distance``
    (ground metres) and ``stats``."""

    visible: bool
    certain: bool
    clearance: float
    obstruction: tuple[float, float, float] | None
    distance: float
    stats: dict


def _check(name: str, v: float, positive: bool = False) -> float:
    v = float(v)
    if not math.isfinite(v) or (positive and v <= 0):
        need = "a finite number > 0" if positive else "a finite number"
        flag = name.replace("_", "-")
        raise UsageError(f"{name} must be {need}, got {v:g}", cli=f"--{flag} must be {need}, "
                         f"got {v:g}")
    return v


def _semi_major(terrain: TerrainLike) -> float:
    """The DEM's ellipsoid semi-major axis (metres); WGS 84's without a CRS."""
    from pyproj import CRS

    f = terrain.frame
    if f.crs_wkt:
        ell = CRS.from_wkt(f.crs_wkt).ellipsoid
        if ell is not None and ell.semi_major_metre:
            return float(ell.semi_major_metre)
    return 6378137.0


def _row_geometry(terrain: TerrainLike, rows: np.ndarray, orow: int, ocol: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per grid row: ground metres per column step and the north-south offset from the
    observer's row (metres). Geographic grids: geodesics along the parallel and the
    meridian (pyproj); others: the pixel size in metres."""
    f = terrain.frame
    a, _, c, _, e, top = f.transform[:6]
    if f.kind != "geographic":
        mx = np.full(len(rows), abs(a) * f.unit_to_m)
        ny = (rows - orow) * abs(e) * f.unit_to_m
        return mx, ny
    geod = frame_geod(terrain.frame)
    lon = c + a * (ocol + 0.5)
    lat = np.clip(top + e * (rows + 0.5), -90.0, 90.0)
    lat0 = top + e * (orow + 0.5)
    n = len(rows)
    _, _, mx = geod.inv(np.full(n, lon), lat, np.full(n, lon + a), lat)
    _, _, d = geod.inv(np.full(n, lon), np.full(n, lat0), np.full(n, lon), lat)
    return np.asarray(mx, np.float64), np.asarray(d, np.float64) * np.sign(rows - orow)


def _observer(terrain: TerrainLike, point: Any, crs: Any, what: str = "observer"
              ) -> tuple[np.ndarray, float, float]:
    """(x, y) in the source CRS and its fractional grid coordinates, checked inside."""
    xy = to_source(terrain.frame, as_xy(point), crs)
    if xy.shape[0] != 1:
        raise UsageError(f"the {what} is one point (x, y), got {xy.shape[0]}")
    fi, fj = grid_coords(terrain.frame, xy)
    if not inside(terrain.grid, fi, fj)[0]:
        raise outside_error(terrain.frame, terrain.grid, as_xy(point), crs,
                            np.array([True]), what)
    return xy[0], float(fi[0]), float(fj[0])


def viewshed(terrain: TerrainLike, observer: Any, radius: float, height: float = 2.0, *,
             target_height: float = 0.0, curvature: float = CURVATURE, mode: str = "edge",
             level: int = 0, crs: Any = None) -> Viewshed:
    """The cells within ``radius`` metres of ``observer`` that an eye ``height`` metres
    above the ground there sees (a target ``target_height`` metres above each cell).

    Parameters
    ----------
    terrain : an open store.
    observer : (x, y) in the DEM's CRS (or ``crs``; ``"lonlat"``); the observer stands on
        the sample of the pixel holding the point, as in ``gdal_viewshed``.
    radius : ground metres (the disc the cells' centres lie in).
    height, target_height : metres above the ground.
    curvature : the curvature-and-refraction coefficient c (heights drop by c·d²/(2a)).
    mode : how a cell's sight line is interpolated from its neighbours toward the
        observer: ``edge`` (gdal_viewshed's), ``diagonal``, ``max`` or ``min``.
    level : 0 (exact on the full-resolution heights) or a coarser pyramid level L: the
        tiles that must be read are read at level L (4^L times fewer samples), each
        cell's height taken as the level-L surface there within the tile's stored error
        bound (a tile touching nodata is read at level 0); the cells that bound could
        change are marked uncertain (255), the others decided as at level 0.

    Returns
    -------
    Viewshed
        codes 0 hidden, 1 visible, 255 uncertain, 254 no answer, on the window of the
        source grid the disc covers.

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> vs = viewshed(t, (c + 100.0, f - 100.0), radius=300.0)
    >>> vs.stats["visible"] + vs.stats["hidden"] > 0, vs.stats["tiles_read"] > 0
    (True, True)
    """
    radius = _check("radius", radius, positive=True)
    height = _check("height", height)
    target_height = _check("target_height", target_height)
    curvature = _check("curvature", curvature)
    if mode not in MODES:
        raise UsageError(f"unknown viewshed mode {mode!r}; use one of {', '.join(MODES)}")
    g, f = terrain.grid, terrain.frame
    if not (isinstance(level, int | np.integer) and 0 <= level <= g.top_level):
        raise UsageError(f"level must be an integer in 0..{g.top_level}, got {level}",
                         cli=f"--level must be in 0..{g.top_level}, got {level}")
    # one read transaction: the store's version checked once, not per tile
    with Reads(terrain) as reads, terrain.snapshot():
        xy, fi, fj = _observer(terrain, observer, crs)
        orow = min(max(int(math.floor(fi + 0.5)), 0), g.rows - 1)
        ocol = min(max(int(math.floor(fj + 0.5)), 0), g.cols - 1)
        # the window: rows and columns within the radius (the disc is measured with the
        # observer row's column step, so it is convex on the grid)
        all_rows = np.arange(g.rows)
        mx_all, ny_all = _row_geometry(terrain, all_rows, orow, ocol)
        rows = np.flatnonzero(np.abs(ny_all) <= radius)
        r0, r1 = int(rows.min()), int(rows.max()) + 1
        mx0 = float(mx_all[orow])
        span = int(math.floor(radius / mx0)) if mx0 > 0 else 0
        c0, c1 = max(ocol - span, 0), min(ocol + span, g.cols - 1) + 1
        eps = float(terrain.quantizer.codec_error) * f.z_to_m
        win = Window(terrain, r0, r1, c0, c1, eps, int(level))
        wr, wc = r1 - r0, c1 - c0
        whole = win.half(0, wr)
        ty, tx = _tile_index(whole.tiles, orow - r0, ocol - c0)
        while whole.tiles.status[ty, tx] != 1:
            whole.read(ty, tx, 0)  # the observer's ground, exactly
        zg = win.height(orow - r0, ocol - c0)
        if not np.isfinite(zg):
            raise InputError(f"the observer ({xy[0]:.10g}, {xy[1]:.10g}) stands on nodata: "
                             "move it onto the data")
        eye = zg + height
        geo = SweepGeometry(orow - r0, ocol - c0, mx_all[r0:r1].copy(), mx0,
                            ny_all[r0:r1].copy(), radius * radius,
                            curvature / (2.0 * _semi_major(terrain)), eye - eps, eye + eps,
                            target_height, eps, MODES.index(mode), eps > 0 or level > 0)
        codes = np.full((wr, wc), NO_ANSWER, np.uint8)
        first = _state(codes)
        asked = _sweep(geo, whole, first, geo.orow, geo.orow + 1, 1)  # the observer's row
        # then the rows north and south of it, each from the observer's row, on two
        # threads where there are two cores: each half writes only its own rows
        halves = []
        for part, start, stop, step in ((win.half(0, geo.orow, whole), geo.orow - 1, -1, -1),
                                        (win.half(geo.orow + 1, wr, whole), geo.orow + 1, wr,
                                         1)):
            st = _state(codes)
            st.last_lo[:], st.last_hi[:] = first.last_lo, first.last_hi
            halves.append((part, st, start, stop, step))
        asked += _sweep_halves(geo, halves)
    from rasterio.transform import Affine

    a, _, c, _, e, top = f.transform[:6]
    window_tr = Affine(a, 0.0, c + a * c0, 0.0, e, top + e * r0)
    stored = win.status != 2
    read = np.zeros(stored.shape, bool)
    bounded = np.zeros(stored.shape, bool)
    for part in [whole] + [h[0] for h in halves]:
        read |= part.tiles.status == 1
        bounded |= part.tiles.status == 3
    n = dict(zip((HIDDEN, VISIBLE, UNCERTAIN, NO_ANSWER), count_codes(codes), strict=True))
    stats = reads.stats(
        tiles_in_window=int(stored.sum()), tiles_read=int(read.sum()),
        tiles_skipped=int((stored & ~read).sum()), tiles_bounded=int((bounded & ~read).sum()),
        waits=asked, visible=n[VISIBLE], hidden=n[HIDDEN], uncertain=n[UNCERTAIN],
        cells=codes.size - n[NO_ANSWER], radius=radius,
        window=(r0, c0, r1 - r0, wc))
    return Viewshed(codes, window_tr, f.crs_wkt, (geo.orow, geo.ocol),
                    (float(xy[0]), float(xy[1]), float(zg), float(eye)), stats)


def _state(codes: np.ndarray) -> SweepState:
    return SweepState(*(np.zeros(codes.shape[1]) for _ in range(4)), codes,
                      np.zeros(3, np.int64), np.full(4, -1.0))


def _sweep(geo: SweepGeometry, part: Half, st: SweepState, first: int, stop: int,
           step: int) -> int:
    """Sweep rows ``first`` … ``stop`` (excluded) of one part, reading each tile the
    sweep asks for; returns how many times it asked."""
    asked, r = 0, first
    run = _entry(sweep_rows, geo, part.tiles, st, r, stop, step)
    while True:
        st.probe[0] = -1.0
        r, need = run(geo, part.tiles, st, r, stop, step)
        if need == NEED_NONE:
            return asked
        part.read(need >> 16, need & 0xFFFF, probe=(r, *st.probe) if st.probe[0] >= 0 else None)
        asked += 1


def _entry(fn, *args):
    """Compiled ``fn``'s code for these arguments' types, to be called without numba's
    dispatcher, which types each field of a named tuple in Python at every call (4.3 of
    a call's 4.3 µs against 0.9 µs, sweep_rows' arguments); ``fn`` itself where that
    code is not at hand (not compiled yet for them)."""
    try:
        return fn.overloads[tuple(fn.typeof_pyval(a) for a in args)].entry_point
    except (AttributeError, KeyError):
        return fn


def _two_threads() -> bool:
    """Whether the halves run on two threads: where there are two cores or more, busy or
    not. On a saturated machine the second thread once lost to the hand-offs of the lock
    and the GIL (2 cores at load 18: 1.18× one thread's time); with the sweep's Python
    overhead cut it gains there too (2 cores at load 11–12, same-run medians: 0.88×,
    1.00× and 0.93× one thread's wall time, docs/lab/analysis.md)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return cores >= 2


def _sweep_halves(geo: SweepGeometry, halves: list) -> int:
    """The north and south halves: the south one on a second thread while this one sweeps
    the north (the compiled sweep and the decoders release the GIL; the store is read
    under the window's lock), or one after the other."""
    if any(h[2] == h[3] for h in halves) or not _two_threads():
        return sum(_sweep(geo, *h) for h in halves)
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="viewshed") as pool:
        south = pool.submit(_sweep, geo, *halves[1])
        return _sweep(geo, *halves[0]) + south.result()


def _tile_index(tiles: SweepTiles, r: int, c: int) -> tuple[int, int]:
    ty = min((r + tiles.r0) >> tiles.t, tiles.tlast_y) - tiles.ty0
    tx = min((c + tiles.c0) >> tiles.t, tiles.tlast_x) - tiles.tx0
    return ty, tx


def write_viewshed(vs: Viewshed, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a viewshed as a GeoTIFF on the source grid (uint8: 0 hidden, 1 visible, 255
    uncertain; 254 is nodata), with a colour table (visible yellow, hidden dark,
    uncertain magenta, no answer transparent) so that it drapes as it is
    (``geoterrain render --drape``). Written whole or not at all.

    Examples
    --------
    >>> import tempfile, os, rasterio
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> p = write_viewshed(viewshed(t, (c + 100.0, f - 100.0), 200.0),
    ...                    os.path.join(tempfile.mkdtemp(), "vs.tif"))
    >>> with rasterio.open(p) as r:
    ...     r.nodata, r.colormap(1)[1][:3]
    (254.0, (255, 214, 0))
    """
    import rasterio

    from geoterrain.core.atomicfiles import partial_path, publish

    out = Path(path)
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise UsageError(f"{out}: a viewshed is written as a GeoTIFF: give a .tif name")
    if out.exists() and not overwrite:
        raise exists_error(out)
    if vs.crs_wkt is None:
        raise UsageError("the DEM has no CRS (pixel units): a GeoTIFF viewshed needs one; "
                         "use the API's codes instead")
    tmp = partial_path(out)
    prof = dict(driver="GTiff", height=vs.codes.shape[0], width=vs.codes.shape[1], count=1,
                dtype="uint8", crs=vs.crs_wkt, transform=vs.transform, nodata=NO_ANSWER,
                compress="deflate", tiled=vs.codes.shape[0] >= 256 and vs.codes.shape[1] >= 256)
    try:
        with rasterio.open(tmp, "w", **prof) as dst:
            dst.write(vs.codes, 1)
            dst.write_colormap(1, PALETTE)
            dst.set_band_description(1, "viewshed: 0 hidden, 1 visible, 255 uncertain")
            x, y, zg, eye = vs.observer
            dst.update_tags(observer_x=repr(x), observer_y=repr(y), ground_m=repr(zg),
                            eye_m=repr(eye), values="0 hidden, 1 visible, 255 uncertain, "
                            "254 no answer (outside the radius or nodata)")
        publish(tmp, out, overwrite)
    except (OSError, rasterio.errors.RasterioIOError) as exc:
        raise WriteError(f"{out}: cannot write the viewshed ({exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out


# ------------------------------------------------------------------------- line of sight


def _ground(terrain: TerrainLike, fi: float, fj: float) -> float:
    """The bilinear ground height (metres) at a fractional grid point; NaN on nodata."""
    g = terrain.grid
    i = min(max(fi, 0.0), g.rows - 1.0)
    j = min(max(fj, 0.0), g.cols - 1.0)
    i0, j0 = min(int(math.floor(i)), max(g.rows - 2, 0)), min(int(math.floor(j)),
                                                              max(g.cols - 2, 0))
    h, ok = cell_corners(terrain, 0, np.array([i0]), np.array([j0]))
    z = _bilinear(h, ok, np.array([i - i0]), np.array([j - j0]))[0]
    return float(z) * terrain.frame.z_to_m


def line_of_sight(terrain: TerrainLike, a: Any, b: Any, observer_height: float = 2.0,
                  target_height: float = 0.0, *, curvature: float = CURVATURE,
                  crs: Any = None) -> LineOfSight:
    """Whether an eye ``observer_height`` metres above the ground at ``a`` sees a point
    ``target_height`` metres above the ground at ``b``, over the bilinear surface.

    The sight line runs straight from eye to target (on the grid: straight in the DEM's
    CRS); the terrain under it is the bilinear surface, lowered by curvature and
    refraction. The target is visible when the sight line stays at or above the terrain
    everywhere between them.

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> los = line_of_sight(t, (c + 100.0, f - 100.0), (c + 100.0, f - 140.0), 2.0, 1.0)
    >>> los.visible, los.obstruction is not None, round(los.distance, 6)
    (False, True, 40.0)
    >>> line_of_sight(t, (c + 100.0, f - 100.0), (c + 100.0, f - 140.0), 50.0, 1.0).visible
    True
    """
    observer_height = _check("observer_height", observer_height)
    target_height = _check("target_height", target_height)
    curvature = _check("curvature", curvature)
    f = terrain.frame
    with Reads(terrain) as reads:
        xa, fia, fja = _observer(terrain, a, crs, "observer")
        xb, fib, fjb = _observer(terrain, b, crs, "target")
        za, zb = _ground(terrain, fia, fja), _ground(terrain, fib, fjb)
        for z, p, what in ((za, xa, "observer"), (zb, xb, "target")):
            if not np.isfinite(z):
                raise InputError(f"the {what} ({p[0]:.10g}, {p[1]:.10g}) stands on nodata: "
                                 "move it onto the data")
        D = _ground_distance(terrain, xa, xb, fia, fja, fib, fjb)
        k = curvature / (2.0 * _semi_major(terrain))
        eps = float(terrain.quantizer.codec_error) * f.z_to_m
        eye, tgt = za + observer_height, zb + target_height - k * D * D
        seg = _segments(terrain, fia, fja, fib, fjb)
        lo_clear, t_block, skipped = _clearance(terrain, seg, eye, tgt, D, k, eps)
    visible = bool(lo_clear >= -1e-9 * max(1.0, abs(eye)))
    certain = eps == 0 or abs(lo_clear) > 2 * eps
    obstruction = None
    if not visible:
        ti, tj = fia + (fib - fia) * t_block, fja + (fjb - fja) * t_block
        p = source_xy(f, np.array([ti]), np.array([tj]))[0]
        obstruction = (float(p[0]), float(p[1]), _ground(terrain, ti, tj))
    return LineOfSight(visible, bool(certain), float(lo_clear), obstruction, float(D),
                       reads.stats(tiles_skipped=skipped))


def _ground_distance(terrain, xa, xb, fia, fja, fib, fjb) -> float:
    f = terrain.frame
    if f.kind == "geographic":
        _, _, d = frame_geod(terrain.frame).inv(xa[0], xa[1], xb[0], xb[1])
        return float(d)
    a, _, _, _, e, _ = f.transform[:6]
    return float(math.hypot((fjb - fja) * a, (fib - fia) * e) * f.unit_to_m)


def _segments(terrain: TerrainLike, fia, fja, fib, fjb) -> dict[str, np.ndarray]:
    """The ray cut at every grid line it crosses: per piece its parameters t0 < t1 and
    its level-0 cell (row, column)."""
    g = terrain.grid
    ts = [np.array([0.0, 1.0])]
    for p, q in ((fia, fib), (fja, fjb)):
        if p != q:
            lo, hi = sorted((p, q))
            k = np.arange(math.ceil(lo), math.floor(hi) + 1, dtype=np.float64)
            ts.append((k - p) / (q - p))
    t = np.unique(np.clip(np.concatenate(ts), 0.0, 1.0))
    t0, t1 = t[:-1], t[1:]
    tm = 0.5 * (t0 + t1)
    mi = np.clip(fia + (fib - fia) * tm, 0.0, g.rows - 1.0)
    mj = np.clip(fja + (fjb - fja) * tm, 0.0, g.cols - 1.0)
    ci = np.minimum(np.floor(mi), max(g.rows - 2, 0)).astype(np.int64)
    cj = np.minimum(np.floor(mj), max(g.cols - 2, 0)).astype(np.int64)
    return {"t0": t0, "t1": t1, "ci": ci, "cj": cj,
            "p": np.array([fia, fja, fib, fjb])}


def _clearance(terrain: TerrainLike, seg: dict, eye: float, tgt: float, D: float, k: float,
               eps: float) -> tuple[float, float, int]:
    """The least clearance of the sight line over the pieces (metres), the first t where
    it is below the terrain, and how many tiles were left undecoded.

    A tile is read when its box could reach the sight line, or when its box leaves less
    room than the least clearance found elsewhere (so the clearance is exact); the
    others are not decoded."""
    g, f = terrain.grid, terrain.frame
    t0, t1, ci, cj = seg["t0"], seg["t1"], seg["ci"], seg["cj"]
    across, down = g.tiles(0)  # level 0's tiles (a square's, or a root grid's)
    tyx = np.minimum(ci >> g.t, down - 1) * across + np.minimum(cj >> g.t, across - 1)
    zs = f.z_scale or 1.0
    keys, inv = np.unique(tyx, return_inverse=True)
    top = np.array([(terrain.tile_info.get((0, int(u % across), int(u // across)))
                     or {"zmax": -np.inf})["zmax"] for u in keys.tolist()], np.float64)
    top = top / zs * (1 + 1e-12) + 1e-9 + eps
    sight_lo = eye - eps + (tgt - eye) * np.where(tgt >= eye, t0, t1)
    room = sight_lo - (top[inv] - k * (D * t0) ** 2)  # a lower bound of the clearance
    tile_room = np.full(len(keys), np.inf)
    np.minimum.at(tile_room, inv, room)
    first = tile_room <= 0
    first[[inv[0], inv[-1]]] = True  # the ends' tiles are read for the ground anyway
    best, t_block = _exact_clearance(terrain, seg, np.flatnonzero(first[inv]), eye, tgt, D, k)
    more = ~first & (tile_room < best)
    if more.any():
        b2, _ = _exact_clearance(terrain, seg, np.flatnonzero(more[inv]), eye, tgt, D, k)
        best = min(best, b2)
    return best, t_block, int((~first & ~more).sum())


def _exact_clearance(terrain: TerrainLike, seg: dict, idx: np.ndarray, eye: float,
                     tgt: float, D: float, k: float) -> tuple[float, float]:
    """The least clearance over pieces ``idx`` (their tiles decoded) and the first t where
    the sight line is below the terrain (1 when it never is)."""
    f = terrain.frame
    t0, t1, ci, cj = seg["t0"], seg["t1"], seg["ci"], seg["cj"]
    fia, fja, fib, fjb = seg["p"]
    h, ok = cell_corners(terrain, 0, ci[idx], cj[idx])
    h = h * f.z_to_m
    void = ~ok.all(axis=1)  # a piece over nodata is transparent
    # the ray in the cell's fractions: u = u0 + du t, v = v0 + dv t
    du, dv = fib - fia, fjb - fja
    u0, v0 = fia - ci[idx], fja - cj[idx]
    h00, h01, h10, h11 = (np.where(ok[:, c], h[:, c], 0.0) for c in range(4))
    q = h00 - h01 - h10 + h11
    # the bilinear surface along the ray: z(t) = c0 + c1 t + c2 t²
    c0 = h00 + (h10 - h00) * u0 + (h01 - h00) * v0 + q * u0 * v0
    c1 = (h10 - h00) * du + (h01 - h00) * dv + q * (u0 * dv + v0 * du)
    c2 = q * du * dv
    # clearance s(t) − (z(t) − k D² t²), with s(t) = eye + (tgt − eye) t
    A = -c2 + k * D * D
    B = (tgt - eye) - c1
    C = eye - c0
    a0, a1 = t0[idx], t1[idx]

    def clear(t):
        return (A * t + B) * t + C

    best = np.minimum(clear(a0), clear(a1))
    tv = np.where(A > 0, -B / np.where(A > 0, 2 * A, 1.0), -1.0)
    inner = (tv > a0) & (tv < a1)
    best = np.where(inner, np.minimum(best, clear(np.where(inner, tv, a0))), best)
    best = np.where(void, np.inf, best)
    tol = 1e-9 * max(1.0, abs(eye))
    blocked = np.flatnonzero(best < -tol)
    low = float(best.min(initial=np.inf))
    if blocked.size == 0:
        return low, 1.0
    m = blocked[np.argmin(a0[blocked])]  # the first blocked piece along the ray
    return low, _first_below(A[m], B[m], C[m], a0[m], a1[m], tol)


def _first_below(A: float, B: float, C: float, t0: float, t1: float, tol: float) -> float:
    """The first t in [t0, t1] where A t² + B t + C < −tol (there is one)."""
    if (A * t0 + B) * t0 + C < -tol:
        return float(t0)
    Cs = C + tol
    if A == 0:
        return float(min(max(-Cs / B, t0), t1)) if B != 0 else float(t0)
    disc = max(B * B - 4 * A * Cs, 0.0)
    roots = sorted(((-B - math.sqrt(disc)) / (2 * A), (-B + math.sqrt(disc)) / (2 * A)))
    inside = [r for r in roots if t0 <= r <= t1]
    return float(inside[0]) if inside else float(t0)
