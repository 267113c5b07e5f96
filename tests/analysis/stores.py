"""Stores of the real and synthetic DEMs the analysis tests share (made once a session)."""

from __future__ import annotations

import numpy as np

from conftest import DEMS, REAL_DEMS

_STORES: dict = {}


def source_dems() -> list[str]:
    """The shared DEMs, and any other GeoTIFF in the DEM folder (held-out DEMs dropped
    there join every test that reads this list)."""
    extra = sorted(p.name for p in DEMS.glob("*.tif") if p.name not in REAL_DEMS) \
        if DEMS.is_dir() else []
    return REAL_DEMS + extra


def read_source(path) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(heights, valid, transform) of a source DEM as rasterio reads it; PNG tiles decoded
    by their encoding's formula (the shared folder's README), on the store's pixel grid."""
    import rasterio

    with rasterio.open(path) as src:
        if str(path).endswith(".png"):
            rgb = src.read().astype(np.float64)
            R, G, B = rgb[0], rgb[1], rgb[2]
            if "terrarium" in str(path):
                z = R * 256 + G + B / 256 - 32768
            else:
                z = -10000 + (R * 65536 + G * 256 + B) * 0.1
            return z, np.isfinite(z), None
        m = src.read(1, masked=True).astype(np.float64)
        z = np.asarray(m.filled(np.nan))
        valid = ~np.ma.getmaskarray(m) & np.isfinite(z)
        return z, valid, tuple(src.transform)[:6]


def store_of(tmp_path_factory, src, **opts):
    """An open store of DEM ``src`` with preprocess options ``opts``, made once."""
    import geoterrain

    key = (str(src), tuple(sorted(opts.items())))
    if key not in _STORES:
        d = tmp_path_factory.mktemp("analysis")
        p = geoterrain.preprocess(src, d / "s.geoterrain", **opts)
        _STORES[key] = geoterrain.open(p)
    return _STORES[key]
