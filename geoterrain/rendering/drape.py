"""Drape a georeferenced image (an orthophoto, a map) over the terrain as its texture.

The image is reprojected by rasterio (``rasterio.warp.reproject``, GDAL's warper,
pyproj-compatible CRSs) onto the pyramid level's grid in the DEM's own CRS, so
texel (r, c) of the result lies over sample (r·2^L, c·2^L) of the DEM: the same
layout as :func:`geoterrain.rendering.textures.texture_image`, and the same texture
coordinates. Texels the image does not cover keep the colour × hillshade texture.

- RGB(A) images: the first three bands; uint8 as is, other types stretched from
  their valid minimum to maximum.
- One band: grey, stretched the same way (a palette-indexed band uses its colours).

Examples
--------
>>> import tempfile, os, rasterio
>>> from rasterio.transform import from_bounds
>>> f = t.frame; a, _, c, _, e, top = f.transform
>>> box = (c, top + e * t.grid.rows, c + a * t.grid.cols, top)  # the DEM's extent
>>> p = os.path.join(tempfile.mkdtemp(), "ortho.tif")
>>> with rasterio.open(p, "w", driver="GTiff", width=64, height=64, count=3, dtype="uint8",
...                    crs=f.crs_wkt, transform=from_bounds(*box, 64, 64)) as dst:
...     dst.write(np.full((3, 64, 64), 200, np.uint8))
>>> img = drape_image(t, p, 0)
>>> img.shape[2], img.dtype.name, int(img[5, 5, 0])
(3, 'uint8', 200)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.frame import level_transform
from geoterrain.core.paths import input_problem
from geoterrain.exceptions import InputError, UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


def _read_rgb(src) -> tuple[np.ndarray, np.ndarray]:
    """(3, H, W) float32 bands in 0..255 and the (H, W) valid mask of an open dataset."""
    colormap = None
    if src.count == 1:
        try:
            colormap = src.colormap(1)
        except ValueError:
            colormap = None
    bands = src.read(masked=True)
    mask = np.ma.getmaskarray(bands).any(0)
    if src.count >= 4 and src.colorinterp[3].name == "alpha":
        mask |= np.asarray(bands[3]) == 0
    if colormap:
        lut = np.zeros((256, 3), np.float32)
        for k, rgba in colormap.items():
            if 0 <= k < 256:
                lut[k] = rgba[:3]
        idx = np.clip(np.asarray(bands[0].filled(0)), 0, 255).astype(np.int64)
        return np.moveaxis(lut[idx], -1, 0), mask
    rgb = np.asarray(bands[:3].filled(0), np.float64)
    if rgb.shape[0] == 1:
        rgb = np.repeat(rgb, 3, axis=0)
    elif rgb.shape[0] == 2:
        rgb = np.concatenate([rgb, rgb[:1]])
    if src.dtypes[0] != "uint8":
        v = rgb[:, ~mask]
        lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
        rgb = (rgb - lo) / ((hi - lo) or 1.0) * 255.0
    return np.clip(rgb, 0, 255).astype(np.float32), mask


def drape_image(terrain: TerrainLike, path: str | Path, level: int,
                base: np.ndarray | None = None) -> np.ndarray:
    """The image at ``path`` on the level-``level`` grid: RGB uint8 (rows, cols, 3) of
    ``grid.level_shape(level)`` (S × S on a square grid), row 0 on top.

    ``base`` (rows, cols, 3) fills the texels the image does not cover (black otherwise).
    Errors (one line each): the DEM or the image is not georeferenced, the image is
    unreadable, or it does not overlap the DEM.
    """
    from rasterio.crs import CRS
    from rasterio.enums import Resampling
    from rasterio.warp import reproject


    f = _georeferenced(terrain)
    p = Path(path)
    rgb, mask, src_crs, src_tr = _source(str(p))
    shape = terrain.grid.level_shape(level)
    dst_tr, dst_crs = level_transform(f.transform, level), CRS.from_wkt(f.crs_wkt)
    out = np.zeros((3, *shape), np.float32)
    cover = np.zeros(shape, np.float32)
    kw = dict(src_transform=src_tr, src_crs=src_crs, dst_transform=dst_tr, dst_crs=dst_crs)
    reproject(rgb, out, resampling=Resampling.bilinear, src_nodata=None, dst_nodata=0, **kw)
    reproject((~mask).astype(np.float32), cover, resampling=Resampling.nearest, dst_nodata=0,
              **kw)
    rows = -(-terrain.grid.rows // (1 << level))
    cols = -(-terrain.grid.cols // (1 << level))
    inside = cover[:rows, :cols] > 0.5
    if not inside.any():
        raise InputError(f"{p}: the drape image does not overlap the DEM (check both CRSs "
                         "and extents with `gdalinfo`)")
    img = np.zeros((*shape, 3), np.uint8) if base is None else np.array(base, np.uint8,
                                                                         copy=True)
    on = cover > 0.5
    img[on] = np.clip(np.moveaxis(out, 0, -1)[on] + 0.5, 0, 255).astype(np.uint8)
    return img


@dataclass(frozen=True)
class Drape:
    """A drape for the view-dependent textures: the image ``path`` over the colour map
    with ``opacity`` (1: in place of it; below 1: blended with it). Where the image has
    no data, the colour map shows."""

    path: str
    opacity: float = 1.0

    def __post_init__(self):
        if not (0.0 <= self.opacity <= 1.0):
            raise UsageError(f"the drape opacity must be in [0, 1], got {self.opacity:g}",
                             cli=f"--drape-opacity must be in [0, 1], got {self.opacity:g}")
        if (why := input_problem(self.path, utf8=True)) is not None:  # before any work
            raise InputError(f"{self.path}: {why}; give a georeferenced image")


_SOURCES: dict = {}


def _georeferenced(terrain: TerrainLike):
    """The terrain's frame; a UsageError when the DEM has no CRS to drape in."""
    f = terrain.frame
    if f.kind == "pixel" or not f.crs_wkt:
        raise UsageError("the DEM has no CRS: an image can be draped over georeferenced DEMs "
                         "only")
    return f


def _source(path: str):
    """The drape image's bands, valid mask, CRS and transform, read once per file."""
    import rasterio

    p = Path(path)
    if (why := input_problem(p, utf8=True)) is not None:
        raise InputError(f"{p}: {why}; give a georeferenced image")
    key = (str(p.resolve()), p.stat().st_mtime_ns)
    if key not in _SOURCES:
        try:
            with rasterio.open(p) as src:
                if src.crs is None or src.transform.is_identity:
                    raise InputError(f"{p}: the drape image is not georeferenced (no CRS or "
                                     "no geotransform); georeference it first "
                                     "(gdal_translate -a_srs -a_ullr)")
                rgb, mask = _read_rgb(src)
                _SOURCES.clear()  # one image at a time: it may be large
                _SOURCES[key] = (rgb, mask, src.crs, src.transform)
        except rasterio.errors.RasterioIOError as exc:
            raise InputError(f"{p}: cannot read the drape image "
                             f"({str(exc).splitlines()[0]})") from None
    return _SOURCES[key]


def drape_tile(terrain: TerrainLike, drape: Drape, level: int, x: int, y: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """The drape over stored tile (level, x, y): RGB float32 (T, T, 3) in 0..1 and the
    (T, T) mask of the samples it covers. Only the tile's window is reprojected.

    Examples
    --------
    >>> import tempfile, os, rasterio
    >>> from rasterio.transform import from_bounds
    >>> f = t.frame; a, _, c, _, e, top = f.transform
    >>> box = (c, top + e * t.grid.rows, c + a * t.grid.cols, top)
    >>> p = os.path.join(tempfile.mkdtemp(), "ortho.tif")
    >>> with rasterio.open(p, "w", driver="GTiff", width=32, height=32, count=3,
    ...                    dtype="uint8", crs=f.crs_wkt, transform=from_bounds(*box, 32, 32)
    ...                    ) as dst:
    ...     dst.write(np.full((3, 32, 32), 51, np.uint8))
    >>> rgb, on = drape_tile(t, Drape(p), t.grid.top_level, 0, 0)
    >>> round(float(rgb[2, 2, 0]), 3), bool(on[2, 2])
    (0.2, True)
    """
    from rasterio.crs import CRS
    from rasterio.enums import Resampling
    from rasterio.transform import Affine
    from rasterio.warp import reproject


    f = _georeferenced(terrain)
    rgb, mask, src_crs, src_tr = _source(drape.path)
    T = terrain.grid.tile_samples
    n = T - 1
    dst_tr = level_transform(f.transform, level) @ Affine.translation(x * n, y * n)
    kw = dict(src_transform=src_tr, src_crs=src_crs, dst_transform=dst_tr,
              dst_crs=CRS.from_wkt(f.crs_wkt))
    out = np.zeros((3, T, T), np.float32)
    cover = np.zeros((T, T), np.float32)
    reproject(rgb, out, resampling=Resampling.bilinear, src_nodata=None, dst_nodata=0, **kw)
    reproject((~mask).astype(np.float32), cover, resampling=Resampling.nearest, dst_nodata=0,
              **kw)
    return np.moveaxis(out, 0, -1) / 255.0, cover > 0.5
