"""Build the before/after pictures of docs/editing.md: a crater edited into the bundled
sample DEM with ``geoterrain edit``, each picture made by the command printed under it.

The patch is a GeoTIFF on the DEM's own grid (30 m pixels, UTM 33N): a bowl 350 m deep
and 1.8 km across inside a raised rim, added to the heights (``--mode add``). Both
pictures share the camera and the colour range.

Usage (from the project root): ``python docs/gallery/make_edit_example.py``
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "gallery"
DEM = ROOT / "sample_dems" / "fbm_513.tif"
SIZE = "480x270"
ROW, COL, R = 400, 130, 30  # the crater's centre (DEM row, column) and radius (samples)


def geoterrain(*args: str) -> str:
    cmd = [sys.executable, "-m", "geoterrain.cli.main", *args]
    return subprocess.run(cmd, check=True, cwd=ROOT, capture_output=True, text=True).stdout


def crater(size: int) -> np.ndarray:
    """The crater's height change (m) on a size × size window centred on it."""
    i, j = np.indices((size, size)) - size // 2
    r = np.hypot(i, j) / R
    bowl = np.where(r < 1.0, -350.0 * (1.0 - r * r), 0.0)
    rim = 90.0 * np.exp(-(((r - 1.0) / 0.2) ** 2))
    return np.round(bowl + rim, 2)


def main() -> None:
    import rasterio

    from geoterrain.ingest.synth import write_geotiff

    work = ROOT / "out" / "edit_example"
    work.mkdir(parents=True, exist_ok=True)
    store = work / "fbm_513.geoterrain"
    geoterrain("-q", "preprocess", str(DEM), "-o", str(store), "--overwrite")
    with rasterio.open(DEM) as ds:
        a, _, x0, _, e, y0 = tuple(ds.transform)[:6]
        z = ds.read(1)
    size = 4 * R + 1
    r0, c0 = ROW - size // 2, COL - size // 2
    patch = write_geotiff(work / "crater.tif", crater(size), crs="EPSG:32633",
                          origin=(x0 + c0 * a, y0 + r0 * e), spacing=a)
    # the camera: north-east of the crater, looking at its centre (source-CRS metres)
    cx, cy = x0 + (COL + 0.5) * a, y0 + (ROW + 0.5) * e
    cz = float(z[ROW, COL])
    look = ["--crs-coords", "--look-from", f"{cx + 1100:.0f},{cy + 1900:.0f},{cz + 2000:.0f}",
            "--look-at", f"{cx:.0f},{cy:.0f},{cz - 100:.0f}", "--clim", "0,2000"]
    before = store.with_name("before.geoterrain")
    shutil.copy(store, before)
    report = geoterrain("edit", str(store), "--patch", str(patch), "--mode", "add").strip()
    lines = []
    for stem, s in (("edit_before", before), ("edit_after", store)):
        png = OUT / f"{stem}.png"
        geoterrain("-q", "render", str(s), "-o", str(png), "--size", SIZE, "--overwrite",
                   "--title", "Before" if stem == "edit_before" else "After", *look)
        lines.append(" ".join(shlex.quote(v) for v in [
            "geoterrain", "render", "fbm_513.geoterrain", "-o", png.name, "--size", SIZE,
            "--title", "Before" if stem == "edit_before" else "After", *look]))
    print("\n".join([report.replace(str(work) + "/", ""), *lines]))


if __name__ == "__main__":
    main()
