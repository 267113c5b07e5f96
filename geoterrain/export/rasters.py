"""Georeferenced 2-D products of a store as Cloud-Optimised GeoTIFFs (rasterio).

- ``hillshade``: gdaldem's hillshade (``gdaldem hillshade``: Horn's gradient of the
  heights, a 0–255 byte, 0 = nodata, flat ground 1 + 254·sin(altitude)), with its sun
  (azimuth, altitude), z-factor, scale and multidirectional variant; edges are computed
  as with ``-compute_edges`` (a missing neighbour takes the centre's height).
- ``shade``: the shading factor the renderer multiplies the colours by
  (:func:`geoterrain.rendering.shading.hillshade` of the stored normal maps: sun from the
  north-west at 45°, ambient 0.35, 1 on flat ground, at most 1.25), float32.
- ``normals``: the stored unit normals (3 bands: east, north, up; scene frame, so
  with the store's vertical exaggeration), float32.
- ``slope``: gdaldem's slope (Horn's gradient) in degrees or percent, float32.
- ``error``: the stored per-vertex error bound δ in metres (δ / z_scale), float32:
  removing that vertex changes the surface by at most δ there (seed 002). A vertex the
  mesh always keeps (an unbounded δ) is nodata, so GIS stretches see finite values only.

``scale`` is gdaldem's ``-s``, the ratio of the vertical unit to the horizontal one;
its default is right for the DEM: 1 for a projected CRS in the heights' unit, and
gdaldem's convention for a geographic DEM, 111 120 (heights in metres; 370 400 in feet).
``z_factor`` multiplies the heights (gdaldem's ``-z``). Both products are computed from
the store's heights without the store's own ``z_scale``.

Level L (``level``) is every 2^L-th sample of the source grid, the pyramid level
of the store; its transform is the source one with 2^L-times larger pixels, placed
so each pixel centre is its sample. Nodata samples are NaN in float products (declared
as nodata) and 0 in the hillshade.

Examples
--------
>>> import tempfile, os, rasterio
>>> p = export_raster(t, "slope", os.path.join(tempfile.mkdtemp(), "slope.tif"), level=1)
>>> with rasterio.open(p) as r:
...     r.count, r.dtypes[0], r.res[0] == 2 * t.frame.transform[0]
(1, 'float32', True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.atomicfiles import partial_path, publish
from geoterrain.core.frame import level_transform
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.rendering.shading import hillshade

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

PRODUCTS = ("hillshade", "shade", "normals", "slope", "error")
SLOPE_UNITS = ("degrees", "percent")
DEGREE_M = 111120.0  # gdaldem's metres per degree for a geographic DEM (its -s 111120)


@dataclass(frozen=True)
class Relief:
    """How ``hillshade`` and ``slope`` are computed, as gdaldem's options: the sun's
    ``azimuth`` and ``altitude`` (degrees; ``-az``, ``-alt``), ``z_factor`` (``-z``),
    ``scale`` (``-s``; None: the DEM's own, see the module docs), ``multidirectional``
    (``-multidirectional``: suns at 225, 270, 315 and 360°, weighted by aspect) and the
    slope's ``slope_units`` (degrees, or percent: ``-p``).

    Examples
    --------
    >>> Relief().azimuth, Relief(slope_units="percent").slope_units
    (315.0, 'percent')
    """

    azimuth: float = 315.0
    altitude: float = 45.0
    z_factor: float = 1.0
    scale: float | None = None
    multidirectional: bool = False
    slope_units: str = "degrees"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.azimuth) and math.isfinite(self.altitude)
                and 0.0 <= self.altitude <= 90.0):
            raise UsageError(f"the sun's altitude must be in [0, 90] degrees, got "
                             f"{self.altitude:g}", cli="--sun AZ,ALT: ALT must be in [0, 90]")
        if not (math.isfinite(self.z_factor) and self.z_factor > 0):
            raise UsageError(f"z_factor must be a finite number > 0, got {self.z_factor}",
                             cli=f"--z-factor must be a number > 0, got {self.z_factor}")
        if self.scale is not None and not (math.isfinite(self.scale) and self.scale > 0):
            raise UsageError(f"scale must be a finite number > 0, got {self.scale}",
                             cli=f"--scale must be a number > 0, got {self.scale}")
        if self.slope_units not in SLOPE_UNITS:
            raise UsageError(f"unknown slope units {self.slope_units!r}; use degrees or "
                             "percent")


def level_shape(terrain: TerrainLike, level: int) -> tuple[int, int]:
    """(rows, cols) of level L within the source extent."""
    s = 1 << level
    return -(-terrain.grid.rows // s), -(-terrain.grid.cols // s)


def _level_normals(terrain: TerrainLike, level: int) -> tuple[np.ndarray, np.ndarray]:
    """Stored normals (H, W, 3) of level L and its valid mask, cropped to the source extent."""
    g = terrain.grid
    T, step = g.tile_samples, 1 << g.t
    n = np.zeros((*g.level_shape(level), 3), np.float32)  # S × S, or a root grid's level
    for (lv, x, y) in terrain.tile_keys(level):
        n[y * step:y * step + T, x * step:x * step + T] = terrain.tile_normals(lv, x, y)
    _, valid = terrain.level_heights(level)
    H, W = level_shape(terrain, level)
    return n[:H, :W], valid[:H, :W]


def level_error(terrain: TerrainLike, level: int) -> np.ndarray:
    """δ (metres) of the level-L samples within the source extent, NaN at nodata and where
    δ is unbounded (a vertex every mesh keeps) (H, W)."""
    H, W = level_shape(terrain, level)
    s = 1 << level
    _, valid = terrain.level_heights(level)
    out = np.full((H, W), np.nan, np.float32)
    rows = max(1, (1 << 22) // max(W, 1))  # about 4 M samples per block
    for r0 in range(0, H, rows):
        i, j = np.meshgrid(np.arange(r0, min(H, r0 + rows)) * s, np.arange(W) * s,
                           indexing="ij")
        d = terrain.gather(i.ravel(), j.ravel(), ("delta",))["delta"].reshape(i.shape)
        out[r0:r0 + len(i)] = d / (terrain.frame.z_scale or 1.0)
    out[~valid[:H, :W] | ~np.isfinite(out)] = np.nan
    return out


def normals_slope(n: np.ndarray, z_scale: float = 1.0) -> np.ndarray:
    """Slope in degrees from the horizontal of unit normals (…, 3) of a surface whose
    heights are × ``z_scale`` (taken out: tan s = |n_xy| / (n_z · z_scale)).

    Examples
    --------
    >>> float(normals_slope(np.array([0.6, 0.0, 0.8]))).__round__(2)
    36.87
    """
    zs = z_scale or 1.0
    return np.degrees(np.arctan2(np.hypot(n[..., 0], n[..., 1]), n[..., 2] * zs))


def slope_degrees(terrain: TerrainLike, level: int, x: int, y: int) -> np.ndarray:
    """Slope (degrees, (T, T) float) of stored tile (level, x, y) from its stored normals:
    the web slope tiles' (``export-raster --what slope`` is gdaldem's, from the heights).

    Examples
    --------
    >>> slope_degrees(t, t.grid.top_level, 0, 0).shape
    (33, 33)
    """
    return normals_slope(terrain.tile_normals(level, x, y), terrain.frame.z_scale)


def default_scale(terrain: TerrainLike) -> float:
    """gdaldem's ``-s`` that is right for the DEM: the horizontal unit in metres over the
    vertical unit in metres; for a geographic DEM gdaldem's 111 120 m per degree.

    Examples
    --------
    >>> default_scale(t)
    1.0
    """
    f = terrain.frame
    horizontal = DEGREE_M if f.kind == "geographic" else f.unit_to_m
    return float(horizontal / f.z_to_m)


def horn_gradient(z: np.ndarray, valid: np.ndarray, xres: float, yres: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Horn's gradient (dz/dx east, dz/dy north) of heights ``z`` (row 0 north) on pixels
    ``xres`` × ``yres`` (in the heights' unit): the 3×3 weights 1-2-1 over 8 pixels, as
    gdaldem's. A neighbour outside the grid or without data takes the centre's height
    (gdaldem's ``-compute_edges``).

    Examples
    --------
    >>> z = np.add.outer(np.zeros(4), 2.0 * np.arange(5))  # rising 2 per pixel eastwards
    >>> p, q = horn_gradient(z, np.ones_like(z, bool), 1.0, 1.0)
    >>> float(p[1, 2]), float(q[1, 2])
    (2.0, 0.0)
    """
    zc = np.where(valid, z, np.nan).astype(np.float64)
    P = np.pad(zc, 1, constant_values=np.nan)
    H, W = z.shape

    def nb(di: int, dj: int) -> np.ndarray:  # the neighbour at (row + di, col + dj)
        a = P[1 + di:1 + di + H, 1 + dj:1 + dj + W]
        return np.where(np.isnan(a), zc, a)

    a, b, c = nb(-1, -1), nb(-1, 0), nb(-1, 1)  # the north row
    d, f = nb(0, -1), nb(0, 1)
    g, h, i = nb(1, -1), nb(1, 0), nb(1, 1)  # the south row
    p = ((c + 2 * f + i) - (a + 2 * d + g)) / (8.0 * xres)
    q = ((a + 2 * b + c) - (g + 2 * h + i)) / (8.0 * yres)
    return p, q


def gdal_hillshade(p: np.ndarray, q: np.ndarray, relief: Relief = Relief()) -> np.ndarray:
    """gdaldem's hillshade (float, 1–255; NaN where ``p`` is) of Horn gradients ``p``
    (east) and ``q`` (north) already divided by the scale, × ``relief.z_factor``.

    Single sun: 1 + 254·max(0, n·l) with n the unit normal of (−zp, −zq, 1) and l toward
    the sun. Multidirectional (gdaldem's, after Mark 1992): suns at 225, 270, 315 and 360°,
    each clipped at 0, weighted by sin²(aspect − azimuth) (weights summing to 2), over
    √(1 + z²(p² + q²)), + 1; flat ground is 1 + 254·sin(altitude).

    Examples
    --------
    >>> flat = np.zeros((1, 1))
    >>> round(float(gdal_hillshade(flat, flat)[0, 0]), 3)  # 1 + 254·sin 45°
    180.605
    """
    zf = relief.z_factor
    alt = math.radians(relief.altitude)
    zp, zq = zf * p, zf * q
    norm = np.sqrt(1.0 + zp * zp + zq * zq)
    if not relief.multidirectional:
        az = math.radians(relief.azimuth)
        cang = (math.sin(alt) - math.cos(alt) * (zp * math.sin(az) + zq * math.cos(az))) / norm
        return 1.0 + 254.0 * np.maximum(cang, 0.0)
    acc = np.zeros(p.shape)
    rr = p * p + q * q
    for az, w in ((225.0, 0.5 * rr + p * q), (270.0, p * p), (315.0, 0.5 * rr - p * q),
                  (360.0, q * q)):
        a = math.radians(az)
        v = math.sin(alt) - math.cos(alt) * (zp * math.sin(a) + zq * math.cos(a))
        acc += w * np.maximum(v, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = 1.0 + 127.0 * acc / rr / norm
    return np.where(rr == 0, 1.0 + 254.0 * math.sin(alt), out)


def gdal_slope(p: np.ndarray, q: np.ndarray, relief: Relief = Relief()) -> np.ndarray:
    """gdaldem's slope of Horn gradients (already divided by the scale), × z-factor: degrees
    atan(|∇z|), or percent 100·|∇z|.

    Examples
    --------
    >>> one = np.ones((1, 1))
    >>> float(gdal_slope(one, 0 * one)[0, 0]), float(gdal_slope(one, 0 * one,
    ...                                                Relief(slope_units="percent"))[0, 0])
    (45.0, 100.0)
    """
    m = relief.z_factor * np.hypot(p, q)
    return np.degrees(np.arctan(m)) if relief.slope_units == "degrees" else 100.0 * m


def _relief_gradient(terrain: TerrainLike, level: int, relief: Relief
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horn's gradient (east, north) of level L's heights on its pixels, divided by the
    scale, and the valid mask, cropped to the source extent."""
    h, valid = terrain.level_heights(level)
    H, W = level_shape(terrain, level)
    h, valid = h[:H, :W], valid[:H, :W]
    a, _, _, _, e, _ = terrain.frame.transform[:6]
    s = float(1 << level)
    scale = default_scale(terrain) if relief.scale is None else float(relief.scale)
    p, q = horn_gradient(h, valid, abs(a) * s * scale, abs(e) * s * scale)
    return p, q, valid


def product(terrain: TerrainLike, what: str, level: int = 0, relief: Relief = Relief()
            ) -> np.ndarray:
    """The (bands, H, W) array of product ``what`` at level L: uint8 for the hillshade (0 =
    nodata), float32 otherwise (NaN = nodata). ``relief``: the hillshade's and slope's
    options (:class:`Relief`).

    Examples
    --------
    >>> product(t, "shade", 2).shape
    (1, 33, 33)
    >>> hs = product(t, "hillshade", 1)
    >>> hs.dtype.name, int(hs.min()) >= 1  # every sample has data here
    ('uint8', True)
    """
    if what not in PRODUCTS:
        raise UsageError(f"unknown raster {what!r}; use one of {', '.join(PRODUCTS)}")
    top = terrain.grid.top_level
    if not (isinstance(level, int | np.integer) and 0 <= level <= top):
        raise UsageError(f"level must be an integer in 0..{top}, got {level}",
                         cli=f"--level must be in 0..{top}, got {level}")
    if what == "error":
        return level_error(terrain, level)[None]
    if what in ("hillshade", "slope"):
        p, q, valid = _relief_gradient(terrain, level, relief)
        if what == "hillshade":
            v = gdal_hillshade(p, q, relief)
            # gdaldem writes its float result into a byte band: rounded to nearest
            out = np.clip(np.floor(np.nan_to_num(v, nan=0.0) + 0.5), 1, 255).astype(np.uint8)
            out[~valid] = 0
            return out[None]
        out = gdal_slope(p, q, relief).astype(np.float32)
        out[~valid] = np.nan
        return out[None]
    n, valid = _level_normals(terrain, level)
    if what == "shade":
        out = hillshade(n)[None]
    else:
        out = np.moveaxis(n, 2, 0).copy()
    out = out.astype(np.float32)
    out[:, ~valid] = np.nan
    return out


UNITS = {"hillshade": "0-255 (0 = nodata), gdaldem hillshade",
         "shade": "shading factor (1 = flat ground)", "normals": "unit vector",
         "error": "metres"}


def export_raster(terrain: TerrainLike, what: str, path: str | Path, *, level: int = 0,
                  overwrite: bool = False, relief: Relief = Relief()) -> Path:
    """Write product ``what`` (:data:`PRODUCTS`) of level L to ``path`` as a COG GeoTIFF.

    Same CRS as the source, transform :func:`level_transform`; nodata is 0 in the
    hillshade and NaN in the others; band descriptions name the product. Written under a
    hidden name and renamed into place when complete. ``relief``: the hillshade's and
    slope's options (:class:`Relief`, gdaldem's).

    Examples
    --------
    >>> import tempfile, os
    >>> out = os.path.join(tempfile.mkdtemp(), "hs.tif")
    >>> export_raster(t, "hillshade", out, relief=Relief(azimuth=300, altitude=30)).name
    'hs.tif'
    """
    import rasterio

    out = Path(path)
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise UsageError(f"{out}: a GeoTIFF export needs a .tif or .tiff name")
    check_output(out, overwrite, inputs=[terrain.path])  # core/paths.py
    f = terrain.frame
    if f.kind == "pixel":
        raise UsageError("the DEM has no georeference (pixel units); a GeoTIFF needs a CRS")
    data = product(terrain, what, level, relief)
    names = {"normals": ("normal_east", "normal_north", "normal_up")}.get(what, (what,))
    byte = data.dtype == np.uint8
    profile = dict(driver="COG", height=data.shape[1], width=data.shape[2], count=len(data),
                   dtype=data.dtype.name, crs=f.crs_wkt,
                   transform=level_transform(f.transform, level),
                   nodata=0 if byte else math.nan, compress="deflate",
                   predictor=2 if byte else 3)
    units = UNITS.get(what, relief.slope_units)
    tmp = partial_path(out)
    tmp = tmp.with_name(tmp.name + ".tif")
    try:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(data)
            for k, name in enumerate(names, 1):
                dst.set_band_description(k, name)
            tags = dict(product=what, level=level, units=units)
            if what in ("hillshade", "slope"):
                scale = default_scale(terrain) if relief.scale is None else relief.scale
                tags.update(z_factor=relief.z_factor, scale=scale)
            if what == "hillshade":
                tags.update(sun="multidirectional" if relief.multidirectional else
                            f"{relief.azimuth:g},{relief.altitude:g}")
            dst.update_tags(**tags)
        publish(tmp, out, overwrite)
    except (OSError, rasterio.errors.RasterioIOError) as exc:
        raise WriteError(f"{out}: cannot write the GeoTIFF ({exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
