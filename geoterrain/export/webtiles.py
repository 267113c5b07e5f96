"""Web Mercator (XYZ) raster tiles of a store, cut on request: Terrain-RGB and Terrarium
heights for MapLibre GL JS and deck.gl, and imagery (colour relief × hillshade, hillshade,
slope, the error bound δ).

A tile (z, x, y) is 256 × 256 pixels of EPSG:3857, y counted from the north (XYZ; a TMS
row is ``2^z − 1 − y``). Each pixel's position goes through pyproj to the source CRS, then
through the inverse geotransform to a fractional sample of pyramid level L, the coarsest
level whose sample spacing is at most the pixel's ground size (level 0 from
:meth:`WebTiler.max_zoom` on). Only the stored tiles of level L under the web tile are
decoded (:func:`level_window`).

- **Heights** (``terrain-rgb``, ``terrarium``): the level's heights, bilinear between its
  four samples around the point, in metres, rounded to the encoding's step (0.1 m;
  1/256 m). A DEM tile's pixel k sits at k/256 of the tile, its top-left corner: the
  convention of MapLibre's ``raster-dem`` (it interpolates pixel k at k/256 and backfills
  pixel 256 from the neighbour's pixel 0), so the two coincide on a shared edge. Where a
  neighbour sample is nodata, or outside the DEM, the pixel is 0 m.
- **Imagery** (``relief``, ``hillshade``, ``slope``, ``error``): pixel centres, RGBA with
  alpha 0 where there is no data. ``relief`` is the stored tiles' shading as ``render``
  shades them (:class:`geoterrain.rendering.tileshader.TileShader`, the ``auto`` palette ×
  the default hillshade), sampled bilinearly; ``hillshade`` the shading factor alone
  (:func:`geoterrain.rendering.shading.tile_hillshade`, grey = factor / 1.25); ``slope``
  degrees from the stored normals (:func:`geoterrain.export.rasters.slope_degrees`) on a
  white → yellow → red → purple ramp over 0–60°; ``error`` the stored δ in metres on a
  log ramp (viridis, 1 cm to 100 m).

Examples
--------
>>> tiles = WebTiler(t)
>>> z = tiles.max_zoom
>>> x, y = tiles.tile_range(z)[0][0], tiles.tile_range(z)[1][0]
>>> tiles.exists(z, x, y), tiles.exists(z, x + 10**6, y)
(True, False)
>>> rgba = tiles.image("relief", z, x, y)
>>> rgba.shape, rgba.dtype.name
((256, 256, 4), 'uint8')
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from pyproj import CRS, Transformer

from geoterrain.exceptions import UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike, TileKey

__all__ = ["ENCODINGS", "IMAGERY", "PRODUCTS", "WebTiler", "encode_heights", "decode_heights",
           "encode_image", "level_window", "merc_tile_bounds"]

TILE = 256
R_MERC = 6378137.0  # EPSG:3857's sphere
HALF = math.pi * R_MERC  # half the world's width in Mercator metres
MAX_LAT = 85.0511287798066
ENCODINGS = ("terrain-rgb", "terrarium")
IMAGERY = ("relief", "hillshade", "slope", "error")
PRODUCTS = ENCODINGS + IMAGERY
STEP = {"terrain-rgb": 0.1, "terrarium": 1.0 / 256.0}  # metres per code
SLOPE_MAX = 60.0  # degrees at the slope ramp's end
ERROR_RANGE = (0.01, 100.0)  # metres, the error ramp's ends (log)
MAX_WEB_ZOOM = 24  # the finest web zoom served (finer tiles only magnify)


def merc_tile_bounds(z: int, x: int, y: int) -> tuple[float, float, float, float]:
    """(west, south, east, north) in EPSG:3857 metres of XYZ tile (z, x, y).

    Examples
    --------
    >>> [round(v) for v in merc_tile_bounds(1, 1, 0)]
    [0, 0, 20037508, 20037508]
    """
    size = 2 * HALF / (1 << z)
    return -HALF + x * size, HALF - (y + 1) * size, -HALF + (x + 1) * size, HALF - y * size


# ------------------------------------------------------------------ height encodings
def encode_heights(h: np.ndarray, encoding: str) -> np.ndarray:
    """RGB uint8 (…, 3) of heights ``h`` (metres; NaN → 0 m) in a web-map encoding,
    rounded to the encoding's step.

    - Terrain-RGB: ``h = −10000 + (R·65536 + G·256 + B) · 0.1``
    - Terrarium: ``h = R·256 + G + B/256 − 32768``

    Examples
    --------
    >>> rgb = encode_heights(np.array([1234.56, -10.0]), "terrain-rgb")
    >>> np.round(decode_heights(rgb, "terrain-rgb"), 2).tolist()
    [1234.6, -10.0]
    >>> decode_heights(encode_heights(np.array([3776.2]), "terrarium"), "terrarium").tolist()
    [3776.19921875]
    """
    h = np.nan_to_num(np.asarray(h, np.float64), nan=0.0)
    if encoding == "terrain-rgb":
        v = np.clip(np.round((h + 10000.0) * 10.0), 0, (1 << 24) - 1).astype(np.int64)
        return np.stack([v >> 16, (v >> 8) & 255, v & 255], -1).astype(np.uint8)
    if encoding == "terrarium":
        v = np.clip(np.round((h + 32768.0) * 256.0), 0, (1 << 24) - 1).astype(np.int64)
        return np.stack([v >> 16, (v >> 8) & 255, v & 255], -1).astype(np.uint8)
    raise UsageError(f"unknown height encoding {encoding!r}; use {' or '.join(ENCODINGS)}")


def decode_heights(rgb: np.ndarray, encoding: str) -> np.ndarray:
    """Heights (metres, float64) of web-map encoded pixels (…, 3 or 4): the inverse of
    :func:`encode_heights`."""
    r, g, b = (np.asarray(rgb)[..., k].astype(np.float64) for k in range(3))
    if encoding == "terrain-rgb":
        return -10000.0 + (r * 65536.0 + g * 256.0 + b) * 0.1
    return r * 256.0 + g + b / 256.0 - 32768.0


def encode_image(rgba: np.ndarray, fmt: str = "png") -> bytes:
    """PNG (lossless, as DEM tiles need) or WebP (lossless) bytes of an RGB(A) uint8 image.

    Examples
    --------
    >>> encode_image(np.zeros((2, 2, 4), np.uint8))[:4]
    b'\\x89PNG'
    """
    from PIL import Image

    img = Image.fromarray(np.ascontiguousarray(rgba))
    buf = io.BytesIO()
    if fmt == "png":
        img.save(buf, "PNG", compress_level=6)
    elif fmt == "webp":
        img.save(buf, "WEBP", lossless=True, quality=80, method=2, exact=True)
    else:
        raise UsageError(f"unknown image format {fmt!r}; use png or webp")
    return buf.getvalue()


# ------------------------------------------------------------------ level windows
def level_window(terrain: TerrainLike, level: int, rows: tuple[int, int],
                 cols: tuple[int, int], fields: Callable[[Sequence[TileKey]], list],
                 channels: int = 1, fill: float = np.nan) -> np.ndarray:
    """Rows ``rows[0]..rows[1]`` × cols ``cols[0]..cols[1]`` (inclusive) of level L as a
    (h, w, channels) float64 array, pasted from the per-tile arrays ``fields(keys)`` of
    the stored tiles that hold them (only those are read); ``fill`` where no tile is
    stored. Tiles share their border samples, so any tile's copy of a border will do.

    Examples
    --------
    >>> top = t.grid.top_level
    >>> w = level_window(t, top, (0, 3), (0, 3), lambda ks: [t.tile(*k).heights for k in ks])
    >>> w.shape, bool(np.allclose(w[..., 0], t.tile(top, 0, 0).heights[:4, :4]))
    ((4, 4, 1), True)
    """
    g = terrain.grid
    step, T, (across, down) = 1 << g.t, g.tile_samples, g.tiles(level)
    r0, r1 = rows
    c0, c1 = cols
    out = np.full((r1 - r0 + 1, c1 - c0 + 1, channels), fill, np.float64)
    ty0, ty1 = max(r0 // step, 0), min(r1 // step, down - 1)
    tx0, tx1 = max(c0 // step, 0), min(c1 // step, across - 1)
    keys = [(level, x, y) for y in range(ty0, ty1 + 1) for x in range(tx0, tx1 + 1)
            if (level, x, y) in terrain.tile_info]
    if not keys:
        return out
    for (_, x, y), arr in zip(keys, fields(keys), strict=True):
        a = np.asarray(arr, np.float64).reshape(T, T, channels)
        ys, xs = y * step, x * step
        i0, i1 = max(r0, ys), min(r1, ys + T - 1)
        j0, j1 = max(c0, xs), min(c1, xs + T - 1)
        if i0 <= i1 and j0 <= j1:
            out[i0 - r0:i1 - r0 + 1, j0 - c0:j1 - c0 + 1] = a[i0 - ys:i1 - ys + 1,
                                                              j0 - xs:j1 - xs + 1]
    return out


def wrapped_window(terrain: TerrainLike, level: int, rows: tuple[int, int],
                   cols: tuple[int, int], fields: Callable[[Sequence[TileKey]], list],
                   channels: int = 1, period: int | None = None) -> np.ndarray:
    """:func:`level_window` whose columns run modulo ``period`` (the level's columns of a
    whole-globe grid, :attr:`Frame.columns_per_turn`): column ``c`` of any integer range
    is column ``c mod period``, so a window may run past either end (the columns beyond
    the last are the first again). ``period=None``: :func:`level_window` itself.

    Examples
    --------
    >>> top, f = t.grid.top_level, lambda ks: [t.tile(*k).heights for k in ks]
    >>> w = wrapped_window(t, top, (0, 1), (-1, 1), f, period=3)  # columns 2, 0, 1
    >>> bool(np.array_equal(w[:, :1], level_window(t, top, (0, 1), (2, 2), f)))
    True
    """
    if period is None:
        return level_window(terrain, level, rows, cols, fields, channels)
    pieces, c = [], cols[0]
    while c <= cols[1]:
        g = c % period
        n = min(cols[1] - c + 1, period - g)
        pieces.append(level_window(terrain, level, rows, (g, g + n - 1), fields, channels))
        c += n
    return np.concatenate(pieces, axis=1)


def wrap_columns(j: np.ndarray, period: int, level: int, turn: int) -> np.ndarray:
    """Level-``level`` fractional columns of level-0 fractional columns ``j`` (any turn)
    of a grid of ``turn`` columns a turn: that level's lattice columns sit every 2^level
    samples from column 0, and the last of them reaches column 0 of the next turn across
    the shorter gap left (``turn`` need not divide by 2^level). ``period``: the level's
    columns a turn (⌈turn / 2^level⌉); columns ``k·period + c`` are column c.

    >>> wrap_columns(np.array([0.0, 8.0, 9.0, 10.0, 11.0]), 3, 2, 10).tolist()
    [0.0, 2.0, 2.5, 3.0, 3.25]
    """
    s = 1 << level
    last = (period - 1) * s  # the level's last lattice column, in level-0 samples
    k = np.floor(j / turn)
    r = j - k * turn
    return k * period + np.where(r <= last, r / s, (period - 1) + (r - last) / (turn - last))


def _bilinear(win: np.ndarray, fi: np.ndarray, fj: np.ndarray) -> np.ndarray:
    """Bilinear samples (n, C) of ``win`` (h, w, C) at fractional (fi, fj) inside it; NaN
    where a neighbour with a non-zero weight is NaN."""
    h, w = win.shape[:2]
    i0 = np.clip(np.floor(fi).astype(np.int64), 0, max(h - 2, 0))
    j0 = np.clip(np.floor(fj).astype(np.int64), 0, max(w - 2, 0))
    u, v = (fi - i0)[:, None], (fj - j0)[:, None]
    i1, j1 = np.minimum(i0 + 1, h - 1), np.minimum(j0 + 1, w - 1)

    def term(a, wgt):  # a corner that does not count (weight 0) may be NaN
        return np.where(wgt == 0, 0.0, a * wgt)

    return (term(win[i0, j0], (1 - u) * (1 - v)) + term(win[i0, j1], (1 - u) * v)
            + term(win[i1, j0], u * (1 - v)) + term(win[i1, j1], u * v))


def _ramp(stops: list[tuple[float, tuple[int, int, int]]], x: np.ndarray) -> np.ndarray:
    xs = np.array([s for s, _ in stops])
    cs = np.array([c for _, c in stops], np.float64)
    return np.stack([np.interp(x, xs, cs[:, k]) for k in range(3)], -1)


SLOPE_RAMP = [(0.0, (255, 255, 255)), (0.25, (255, 237, 160)), (0.5, (253, 141, 60)),
              (0.75, (215, 25, 28)), (1.0, (84, 39, 136))]


class WebTiler:
    """Web Mercator tiles of one terrain (see the module docs).

    ``cmap`` is the relief's palette (``auto``: render's default tints and sea).
    Not thread-safe: the terrain's cache is not; a server holds a lock per terrain.
    """

    def __init__(self, terrain: TerrainLike, cmap: str = "auto"):
        f = terrain.frame
        if f.kind == "pixel" or f.crs_wkt is None:
            raise UsageError(f"{terrain.path}: web tiles need a georeferenced DEM and this one "
                             "has no CRS; preprocess one with its CRS (a web-map PNG tile: "
                             "preprocess --tile Z/X/Y)")
        self.terrain, self.cmap = terrain, cmap
        self.crs = CRS.from_wkt(f.crs_wkt)
        self.merc_to_src = Transformer.from_crs("EPSG:3857", self.crs, always_xy=True)
        self.src_to_geo = Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)
        a, b, c, d, e, ff = f.transform[:6]
        det = a * e - b * d
        if det == 0:
            raise UsageError(f"{terrain.path}: the DEM's geotransform is singular")
        self._inv = (e / det, -b / det, -d / det, a / det, c, ff)
        self.decoded_windows = 0  # level windows read (each decodes only its tiles)

    # ----------------------------------------------------------------- where
    def _pixel(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional level-0 sample (i, j) of source-CRS points (centres at integers)."""
        ia, ib, id_, ie, c, f = self._inv
        # points the source CRS cannot hold come back from pyproj as inf: NaN here, and
        # the callers count non-finite samples as outside the DEM
        with np.errstate(invalid="ignore"):
            dx, dy = np.asarray(x) - c, np.asarray(y) - f
            return id_ * dx + ie * dy - 0.5, ia * dx + ib * dy - 0.5

    @cached_property
    def _span(self) -> tuple[float, float, float, float]:
        """(west, south, east, north) in degrees of the DEM's samples (border densified),
        its longitudes as the grid runs (170…190 for a grid past the antimeridian)."""
        g, f = self.terrain.grid, self.terrain.frame
        t = np.linspace(0.0, 1.0, 65)
        i = np.concatenate([t * 0, t, t * 0 + 1, t]) * (g.rows - 1)
        j = np.concatenate([t, t * 0, t, t * 0 + 1]) * (g.cols - 1)
        lon, lat = self.src_to_geo.transform(*f.crs_xy(i, j))
        lon, lat = np.asarray(lon), np.clip(np.asarray(lat), -MAX_LAT, MAX_LAT)
        return float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())

    @cached_property
    def bounds(self) -> tuple[float, float, float, float]:
        """(west, south, east, north) in degrees of the DEM's samples, longitudes in
        [-180°, 180°]; a DEM across the antimeridian spans every longitude (a web map's
        bounds cannot cross it)."""
        w, s, e, n = self._span
        if self.terrain.frame.columns_per_turn:  # a whole-globe grid: every longitude
            return -180.0, s, 180.0, n
        if -180.0 <= w and e <= 180.0:
            return w, s, e, n
        fw, fe = fold_lon(w), fold_lon(e)
        return (fw, s, fe, n) if fw <= fe and e - w < 360.0 else (-180.0, s, 180.0, n)

    @cached_property
    def center(self) -> tuple[float, float]:
        """(lon, lat) of the DEM's centre (longitude in [-180°, 180°])."""
        lon, lat = self._centre
        return fold_lon(lon), lat

    @cached_property
    def _centre(self) -> tuple[float, float]:
        g, f = self.terrain.grid, self.terrain.frame
        lon, lat = self.src_to_geo.transform(*f.crs_xy(np.array([(g.rows - 1) / 2]),
                                                       np.array([(g.cols - 1) / 2])))
        return float(np.asarray(lon)[0]), float(np.asarray(lat)[0])

    @cached_property
    def spacing(self) -> float:
        """Ground metres between level-0 samples at the centre (the smaller axis)."""
        g, f = self.terrain.grid, self.terrain.frame
        ci, cj = (g.rows - 1) / 2, (g.cols - 1) / 2
        x, y = f.xy(np.array([ci, ci + 1, ci]), np.array([cj, cj, cj + 1]))
        return float(min(math.hypot(x[1] - x[0], y[1] - y[0]),
                         math.hypot(x[2] - x[0], y[2] - y[0])))

    def ground_pixel(self, z: int) -> float:
        """Ground metres of a web pixel at zoom ``z`` at the DEM's centre latitude."""
        return 2 * HALF * math.cos(math.radians(self.center[1])) / (TILE << z)

    @cached_property
    def max_zoom(self) -> int:
        """The first zoom whose pixels are at most the DEM's sample spacing."""
        for z in range(MAX_WEB_ZOOM + 1):
            if self.ground_pixel(z) <= self.spacing * (1 + 1e-9):
                return z
        return MAX_WEB_ZOOM

    @cached_property
    def min_zoom(self) -> int:
        """The coarsest zoom served: 0 (a whole-world tile holds the DEM as a few pixels)."""
        return 0

    def level_for(self, z: int) -> int:
        """The coarsest pyramid level whose spacing is at most a zoom-z pixel."""
        ratio = self.ground_pixel(z) / self.spacing
        L = int(math.floor(math.log2(ratio) + 1e-9)) if ratio >= 1 else 0
        return min(max(L, 0), self.terrain.grid.top_level)

    def tile_range(self, z: int) -> tuple[range | list[int], range]:
        """XYZ columns and rows of zoom ``z`` that the DEM's bounds touch (the columns a
        list where the DEM runs past the antimeridian and they wrap)."""
        w, s, e, n = self.bounds
        n_ = 1 << z

        def col(lon):
            return min(max(int(math.floor((lon + 180.0) / 360.0 * n_)), 0), n_ - 1)

        def row(lat):
            phi = math.radians(lat)
            v = (1 - math.log(math.tan(phi) + 1 / math.cos(phi)) / math.pi) / 2 * n_
            return min(max(int(math.floor(v)), 0), n_ - 1)

        w0, e0 = self._span[0], self._span[2]
        if not (-180.0 <= w0 and e0 <= 180.0):  # past the antimeridian: the columns wrap
            first = int(math.floor((w0 + 180.0) / 360.0 * n_))
            last = int(math.floor((e0 + 180.0) / 360.0 * n_))
            cols = list(dict.fromkeys(c % n_ for c in range(first, last + 1)))[:n_]
            return cols, range(row(n), row(s) + 1)
        return range(col(w), col(e) + 1), range(row(n), row(s) + 1)

    def exists(self, z: int, x: int, y: int) -> bool:
        """Whether XYZ tile (z, x, y) is a tile of the world that touches the DEM's bounds."""
        if not (0 <= z <= MAX_WEB_ZOOM and 0 <= x < (1 << z) and 0 <= y < (1 << z)):
            return False
        xs, ys = self.tile_range(z)
        return x in xs and y in ys

    # ----------------------------------------------------------------- sampling
    def _positions(self, z: int, x: int, y: int, corner: bool) -> tuple[np.ndarray, np.ndarray]:
        """Level-0 fractional (i, j) of the tile's 256² pixels (corners or centres)."""
        w, _, _, n = merc_tile_bounds(z, x, y)
        res = 2 * HALF / (TILE << z)
        k = np.arange(TILE) + (0.0 if corner else 0.5)
        mx, my = np.meshgrid(w + k * res, n - k * res)
        sx, sy = self.merc_to_src.transform(mx.ravel(), my.ravel())
        sx = np.asarray(sx)
        if self.crs.is_geographic:  # whole turns added: within 180° of the DEM's centre
            sx = sx + 360.0 * np.round((self._centre[0] - sx) / 360.0)
        return self._pixel(sx, np.asarray(sy))

    def sample(self, z: int, x: int, y: int, level: int, fields, channels: int,
               corner: bool = False) -> np.ndarray:
        """(256·256, channels) bilinear samples of per-tile ``fields`` of ``level`` at the
        tile's pixels; NaN where a neighbour sample is missing or outside the grid."""
        i, j = self._positions(z, x, y, corner)
        s = float(1 << level)
        g = self.terrain.grid
        H, W = -(-g.rows // (1 << level)), -(-g.cols // (1 << level))
        turn = self.terrain.frame.columns_per_turn
        fi = i / s
        if turn:  # a whole-globe grid: the columns wrap, the tile's own turn kept whole
            ref = np.nanmedian(j) if np.isfinite(j).any() else 0.0
            fj = wrap_columns(ref + np.mod(j - ref + turn / 2, turn) - turn / 2, W, level, turn)
            inside = np.isfinite(fi) & np.isfinite(fj) & (fi >= 0) & (fi <= H - 1)
        else:
            fj = j / s
            inside = np.isfinite(fi) & np.isfinite(fj) & (fi >= 0) & (fi <= H - 1) \
                & (fj >= 0) & (fj <= W - 1)
        out = np.full((TILE * TILE, channels), np.nan)
        if not inside.any():
            return out
        r0, r1 = int(np.floor(fi[inside].min())), int(np.ceil(fi[inside].max()))
        c0, c1 = int(np.floor(fj[inside].min())), int(np.ceil(fj[inside].max()))
        win = wrapped_window(self.terrain, level, (r0, r1), (c0, c1), fields, channels,
                             W if turn else None)
        self.decoded_windows += 1
        out[inside] = _bilinear(win, fi[inside] - r0, fj[inside] - c0)
        return out

    def _heights(self, keys) -> list[np.ndarray]:
        t = self.terrain
        return [t.tile(*k).heights * t.frame.z_to_m for k in keys]

    def heights(self, z: int, x: int, y: int, corner: bool = True) -> np.ndarray:
        """(256, 256) heights in metres (NaN: no data) at the tile's pixels."""
        level = self.level_for(z)
        return self.sample(z, x, y, level, self._heights, 1, corner).reshape(TILE, TILE)

    def dem_tile(self, encoding: str, z: int, x: int, y: int) -> np.ndarray:
        """RGB uint8 (256, 256, 3) of the tile's heights in ``encoding`` (nodata: 0 m)."""
        return encode_heights(self.heights(z, x, y), encoding)

    def image(self, what: str, z: int, x: int, y: int) -> np.ndarray:
        """RGBA uint8 (256, 256, 4) imagery ``what`` (:data:`IMAGERY`) of the tile."""
        from geoterrain.export.rasters import slope_degrees
        from geoterrain.rendering.shading import SHADE_CEILING, tile_hillshade
        from geoterrain.rendering.tileshader import TileShader

        t, level = self.terrain, self.level_for(z)

        def masked(make):  # per tile, NaN where the sample is nodata
            def fields(keys):
                return [np.where(t.tile(*k).valid[..., None] if a.ndim == 3 else
                                 t.tile(*k).valid, a, np.nan)
                        for k, a in zip(keys, make(keys), strict=True)]
            return fields

        if what == "relief":
            shader = TileShader(t, "normals", self.cmap)
            v = self.sample(z, x, y, level, masked(lambda ks: shader(ks)), 3)
            rgb = v
        elif what == "hillshade":
            v = self.sample(z, x, y, level,
                            masked(lambda ks: [tile_hillshade(t, *k) for k in ks]), 1)
            rgb = np.repeat(np.clip(v / SHADE_CEILING, 0, 1) * 255.0, 3, axis=1)
        elif what == "slope":
            v = self.sample(z, x, y, level,
                            masked(lambda ks: [slope_degrees(t, *k) for k in ks]), 1)
            rgb = _ramp(SLOPE_RAMP, np.clip(v[:, 0] / SLOPE_MAX, 0, 1))
        elif what == "error":
            m = t.frame.z_to_m / (t.frame.z_scale or 1.0)
            v = self.sample(z, x, y, level,
                            masked(lambda ks: [t.tile_delta(*k) * m for k in ks]), 1)
            import matplotlib

            lo, hi = np.log10(ERROR_RANGE[0]), np.log10(ERROR_RANGE[1])
            e = np.log10(np.maximum(np.nan_to_num(v[:, 0], nan=ERROR_RANGE[0]), 1e-12))
            rgb = matplotlib.colormaps["viridis"](np.clip((e - lo) / (hi - lo), 0, 1))[:, :3]
            rgb = rgb * 255.0
        else:
            raise UsageError(f"unknown imagery {what!r}; use one of {', '.join(IMAGERY)}")
        ok = np.isfinite(v).all(1)
        out = np.zeros((TILE * TILE, 4), np.uint8)
        out[ok, :3] = np.clip(np.round(np.asarray(rgb)[ok]), 0, 255).astype(np.uint8)
        out[ok, 3] = 255
        return out.reshape(TILE, TILE, 4)


def fold_lon(lon: float) -> float:
    """``lon`` in [-180°, 180°] (unchanged when it is already).

    >>> fold_lon(190.0), fold_lon(-10.0), fold_lon(180.0), fold_lon(-190.0)
    (-170.0, -10.0, 180.0, 170.0)
    """
    return lon if -180.0 <= lon <= 180.0 else lon - 360.0 * math.floor((lon + 180.0) / 360.0)
