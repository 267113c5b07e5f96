"""Build the globe pictures of docs/globe.md: a synthetic whole-globe raster (0.25°,
EPSG:4326, −180…180° × −90…90°) and srtm1_japan on one WGS 84 globe, from space, from
1 000 km and from 2 m above the ground.

The real DEM is ``../shared/dems/srtm1_japan.tif`` beside the project (or the folder in
``GEOTERRAIN_TEST_DEMS``).

Usage (from the project root): ``python docs/gallery/make_globe.py``
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import rasterio
from rasterio.transform import from_origin

import geoterrain
from geoterrain.globe import Globe
from geoterrain.rendering.globescene import render_globe

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "gallery"
DEMS = Path(os.environ.get("GEOTERRAIN_TEST_DEMS") or ROOT.parent / "shared" / "dems")
LON, LAT = 139.25, 35.35  # Sagami Bay, in srtm1_japan


def world_tif(path: Path) -> Path:
    """A smooth synthetic whole-globe raster: 720 × 1440 cells of 0.25°."""
    H, W = 720, 1440
    lat = np.radians(90 - (np.arange(H) + 0.5) * 0.25)[:, None]
    lon = np.radians(-180 + (np.arange(W) + 0.5) * 0.25)[None, :]
    z = 2000 * np.sin(3 * lon) * np.cos(2 * lat) + 1000 * np.cos(5 * lat + lon)
    with rasterio.open(path, "w", driver="GTiff", height=H, width=W, count=1,
                       dtype="float32", crs="EPSG:4326",
                       transform=from_origin(-180, 90, 0.25, 0.25)) as ds:
        ds.write(z.astype(np.float32), 1)
    return path


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        world = geoterrain.preprocess(world_tif(tmp / "world.tif"), tmp / "world.geoterrain")
        japan = geoterrain.preprocess(DEMS / "srtm1_japan.tif", tmp / "japan.geoterrain")
        with Globe([world, japan], node_cells=32, sync=True) as g:
            ground = float(g.surface.heights(np.array([LON]), np.array([LAT]),
                                             g.max_depth)[0])
            for stem, view in (
                    ("globe_space", g.camera(LON, LAT, 2.0e7, 0.0, -90.0, (640, 480))),
                    ("globe_1000km", g.camera(LON, LAT - 9.0, 1.0e6, 0.0, -35.0, (640, 480))),
                    ("globe_2m", g.camera(LON, LAT, ground + 2.0, 300.0, -8.0, (640, 480)))):
                render_globe(g, view, OUT / f"{stem}.png", pixel_error=1.5, overwrite=True)
                print(stem, view.eye)


if __name__ == "__main__":
    main()
