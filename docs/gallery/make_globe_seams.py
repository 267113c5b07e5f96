"""Build the seam pictures of docs/globe.md: a synthetic store across the antimeridian
(170°E … 170°W, 6°S … 6°N, 0.05° cells) and a polar cap (every longitude, 80°N … 90°N,
0.25° cells) on one WGS 84 globe, heights × 20: the seams of
``tests/globe/test_antimeridian_poles.py``, on finer and wider stores.

Usage (from the project root): ``python docs/gallery/make_globe_seams.py``
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import rasterio
from rasterio.transform import from_origin

import geoterrain
from geoterrain.globe import Globe
from geoterrain.rendering.globescene import render_globe

OUT = Path(__file__).resolve().parent


def tif(path: Path, z: np.ndarray, west: float, north: float, step: float) -> Path:
    with rasterio.open(path, "w", driver="GTiff", height=z.shape[0], width=z.shape[1],
                       count=1, dtype="float32", crs="EPSG:4326",
                       transform=from_origin(west, north, step, step)) as ds:
        ds.write(z.astype(np.float32), 1)
    return path


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # finer and wider than the test's stores (so their 32-sample feathered edges
        # leave most of them drawn as they are), one colour range for both
        lat = 6.0 - (np.arange(240) + 0.5) * 0.05
        lon = 170.0 + (np.arange(400) + 0.5) * 0.05
        z = 1000 + 600 * np.sin(np.radians(lon[None] - 170) * 60) * np.cos(
            np.radians(lat[:, None]) * 60)
        dl = geoterrain.preprocess(tif(tmp / "dl.tif", z, 170.0, 6.0, 0.05),
                                   tmp / "dateline.geoterrain")
        lat = 90.0 - (np.arange(40) + 0.5) * 0.25
        lon = -180.0 + (np.arange(1440) + 0.5) * 0.25
        c = 90.0 - lat[:, None]
        z = 1000 + 60 * c * np.sin(np.radians(lon[None]) * 6)
        cap = geoterrain.preprocess(tif(tmp / "cap.tif", z, -180.0, 90.0, 0.25),
                                    tmp / "cap.geoterrain")
        with Globe([dl, cap], node_cells=32, sync=True, vertical_exaggeration=20.0) as g:
            for stem, view in (
                    ("globe_antimeridian", g.camera(180.0, -14.0, 1.2e6, 0.0, -45.0,
                                                    (640, 480))),
                    ("globe_pole", g.camera(0.0, 72.0, 1.6e6, 0.0, -50.0, (640, 480)))):
                render_globe(g, view, OUT / f"{stem}.png", pixel_error=1.5, overwrite=True,
                             title="×20 heights", colorbar=True)
                print(stem)


if __name__ == "__main__":
    main()
