"""What a store's bytes are spent on, against the lossless GeoTIFF a GIS user already has.

The reference is the store's own level-0 heights written losslessly by rasterio as a
GeoTIFF with ``COMPRESS=DEFLATE`` and the horizontal predictor (``PREDICTOR=2`` for
integers, ``3`` for floats), in the source's sample type (float32 for PNG encodings),
nodata written as the source's nodata value (NaN for floats without one).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

COMPONENTS = ("heights", "delta", "radius", "normals")


def component_bytes(t: TerrainLike, info: dict | None = None) -> dict[str, int]:
    """Bytes per component: the blob kinds (``delta`` with the optional second δ and
    block δ_n table), and ``index/other`` (SQLite pages, tile rows, metadata: the file
    size less the blobs). ``info``: ``t.info()`` when the caller has it (it reads every
    leaf page of the blob table).

    Examples
    --------
    >>> b = component_bytes(t)
    >>> sum(b.values()) == t.info()["size_bytes"]
    True
    """
    kinds = (info or t.info())["bytes_by_kind"]
    out = {k: int(kinds.get(k, 0)) for k in COMPONENTS}
    out["delta"] += int(kinds.get("delta_edge", 0)) + int(kinds.get("block_delta", 0))
    out["index/other"] = os.path.getsize(t.path) - sum(out.values())
    return out


def reference_dtype(source_dtype: str) -> str:
    """The GeoTIFF sample type of the reference: the source's, float32 for PNG encodings."""
    return "float32" if source_dtype in ("uint8", "int8") else source_dtype


def deflate_geotiff_bytes(heights: np.ndarray, valid: np.ndarray, dtype: str,
                          nodata: float | None = None) -> int:
    """Size of ``heights`` written as a DEFLATE + predictor GeoTIFF (2: ints, 3: floats).

    Examples
    --------
    >>> h = np.add.outer(np.arange(64.0), np.arange(64.0))
    >>> 0 < deflate_geotiff_bytes(h, h >= 0, "int16") < h.size * 2
    True
    """
    import rasterio

    dt = np.dtype(dtype)
    is_float = np.issubdtype(dt, np.floating)
    if nodata is None or (not is_float and not np.isfinite(nodata)):
        nodata = float("nan") if is_float else float(np.iinfo(dt).min)
    fill = np.where(valid, heights, nodata)
    data = (fill if is_float else np.rint(fill)).astype(dt)
    prof = dict(driver="GTiff", height=data.shape[0], width=data.shape[1], count=1,
                dtype=dt.name, nodata=nodata, compress="deflate",
                predictor=3 if is_float else 2)
    fd, path = tempfile.mkstemp(suffix=".tif")
    os.close(fd)
    try:
        with warnings.catch_warnings():  # no georeference needed for a size
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(path, "w", **prof) as d:
                d.write(data, 1)
        return os.path.getsize(path)
    finally:
        os.unlink(path)


def size_report(t: TerrainLike) -> dict:
    """Bytes per component, the DEFLATE + predictor GeoTIFF of the same heights, and the
    ratio store / GeoTIFF (decodes every level-0 tile: seconds on a large store).

    Examples
    --------
    >>> r = size_report(t)
    >>> r["store_bytes"] == sum(r["components"].values()), r["ratio"] > 0
    (True, True)
    """
    g, m = t.grid, t.meta
    h, v = t.level_heights(0)
    h, v = h[: g.rows, : g.cols], v[: g.rows, : g.cols]
    dtype = reference_dtype(m["source_dtype"])
    ref = deflate_geotiff_bytes(h, v, dtype, m.get("source_nodata"))
    comp = component_bytes(t)
    total = sum(comp.values())
    return {"components": comp, "store_bytes": total, "geotiff_deflate_bytes": ref,
            "geotiff_dtype": dtype, "ratio": total / ref}
