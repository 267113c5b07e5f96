"""Georeferenced 2-D products of a store as Cloud-Optimised GeoTIFFs (rasterio).

- ``hillshade``: the shading factor the renderer multiplies the colours by
  (:func:`geoterrain.rendering.shading.hillshade` of the stored normal maps: sun from the
  north-west at 45°, ambient 0.35, 1 on flat ground, at most 1.25), float32.
- ``normals``: the stored unit normals (3 bands: east, north, up; scene frame, so
  with the store's vertical exaggeration), float32.
- ``slope``: degrees from the horizontal, from the normals with the exaggeration
  taken out (tan s = |n_xy| / (n_z · z_scale)), float32.
- ``error``: the stored per-vertex error bound δ in metres (δ / z_scale), float32:
  removing that vertex changes the surface by at most δ there (seed 002).

Level L (``level``) is every 2^L-th sample of the source grid, the pyramid level
of the store; its transform is the source one with 2^L-times larger pixels, placed
so each pixel centre is its sample. Nodata samples are NaN (declared as nodata).

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
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.frame import level_transform
from geoterrain.exceptions import UsageError, WriteError, exists_error
from geoterrain.rendering.shading import hillshade

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

PRODUCTS = ("hillshade", "normals", "slope", "error")


def level_shape(terrain: TerrainLike, level: int) -> tuple[int, int]:
    """(rows, cols) of level L within the source extent."""
    s = 1 << level
    return -(-terrain.grid.rows // s), -(-terrain.grid.cols // s)


def _level_normals(terrain: TerrainLike, level: int) -> tuple[np.ndarray, np.ndarray]:
    """Stored normals (H, W, 3) of level L and its valid mask, cropped to the source extent."""
    g = terrain.grid
    S, T, step = g.level_size(level), g.tile_samples, 1 << g.t
    n = np.zeros((S, S, 3), np.float32)
    for (lv, x, y) in terrain.tile_keys(level):
        n[y * step:y * step + T, x * step:x * step + T] = terrain.tile_normals(lv, x, y)
    _, valid = terrain.level_heights(level)
    H, W = level_shape(terrain, level)
    return n[:H, :W], valid[:H, :W]


def level_error(terrain: TerrainLike, level: int) -> np.ndarray:
    """δ (metres) of the level-L samples within the source extent, NaN at nodata (H, W)."""
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
    out[~valid[:H, :W]] = np.nan
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
    """Slope (degrees, (T, T) float) of stored tile (level, x, y) from its stored normals,
    as ``export-raster --what slope`` computes it (the web slope tiles use it too).

    Examples
    --------
    >>> slope_degrees(t, t.grid.top_level, 0, 0).shape
    (33, 33)
    """
    return normals_slope(terrain.tile_normals(level, x, y), terrain.frame.z_scale)


def product(terrain: TerrainLike, what: str, level: int = 0) -> np.ndarray:
    """The (bands, H, W) float32 array of product ``what`` at level L (NaN = nodata).

    Examples
    --------
    >>> product(t, "hillshade", 2).shape
    (1, 33, 33)
    """
    if what not in PRODUCTS:
        raise UsageError(f"unknown raster {what!r}; use one of {', '.join(PRODUCTS)}")
    top = terrain.grid.top_level
    if not (isinstance(level, int | np.integer) and 0 <= level <= top):
        raise UsageError(f"level must be an integer in 0..{top}, got {level}",
                         cli=f"--level must be in 0..{top}, got {level}")
    if what == "error":
        return level_error(terrain, level)[None]
    n, valid = _level_normals(terrain, level)
    if what == "hillshade":
        out = hillshade(n)[None]
    elif what == "normals":
        out = np.moveaxis(n, 2, 0).copy()
    else:
        out = normals_slope(n, terrain.frame.z_scale)[None]
    out = out.astype(np.float32)
    out[:, ~valid] = np.nan
    return out


def export_raster(terrain: TerrainLike, what: str, path: str | Path, *, level: int = 0,
                  overwrite: bool = False) -> Path:
    """Write product ``what`` (:data:`PRODUCTS`) of level L to ``path`` as a COG GeoTIFF.

    Same CRS as the source, transform :func:`level_transform`; NaN is the nodata
    value; band descriptions name the product. Written under a hidden name and
    renamed into place when complete.
    """
    import rasterio

    out = Path(path)
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise UsageError(f"{out}: a GeoTIFF export needs a .tif or .tiff name")
    if out.exists() and not overwrite:
        raise exists_error(out)
    f = terrain.frame
    if f.kind == "pixel":
        raise UsageError("the DEM has no georeference (pixel units); a GeoTIFF needs a CRS")
    data = product(terrain, what, level)
    names = {"normals": ("normal_east", "normal_north", "normal_up")}.get(what, (what,))
    profile = dict(driver="COG", height=data.shape[1], width=data.shape[2], count=len(data),
                   dtype="float32", crs=f.crs_wkt, transform=level_transform(f.transform, level),
                   nodata=math.nan, compress="deflate", predictor=3)
    tmp = out.with_name(f".{out.name}.partial.tif")
    try:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(data)
            for k, name in enumerate(names, 1):
                dst.set_band_description(k, name)
            dst.update_tags(product=what, level=level, units={
                "hillshade": "shading factor (1 = flat ground)", "normals": "unit vector",
                "slope": "degrees", "error": "metres"}[what])
        tmp.replace(out)
    except (OSError, rasterio.errors.RasterioIOError) as exc:
        raise WriteError(f"{out}: cannot write the GeoTIFF ({exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
