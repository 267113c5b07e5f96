"""Lossy stores' pictures against the lossless store's: PSNR and triangles (issue 12).

For each real DEM of ``../shared/dems`` (skipped when absent; PNG tiles at 30 m a
pixel), a lossless store and stores at ``--codec-error`` ε are preprocessed into a
temporary folder, and the same three views (azimuth, elevation: (200°, 35°), (90°, 20°),
(330°, 12°)) are rendered from each at τ = 1 px with rtin, 640×360. Reported: the PSNR
of each lossy picture against the lossless store's picture of the view (the codec's
visible error: terraces from heights rounded on their own, or the smoother surface of
residual bins) and the triangles each view drew.

Run from the project root::

    python benchmarks/bench_lossy.py [--codec-error 1 2] [--dems srtm1_japan.tif ...]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import geoterrain  # noqa: E402
from geoterrain.rendering.scene import TerrainScene, default_view
from geoterrain.rendering.window import pyvista_plotter

DEMS = Path(__file__).resolve().parents[2] / "shared" / "dems"
NAMES = ("srtm3_pysheds.tif", "srtm1_japan.tif", "fuji_terrain_rgb.png",
         "st_helens_terrain_rgb.png", "terrarium.png")
VIEWS = ((200, 35), (90, 20), (330, 12))
SIZE = (640, 360)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float(10 * np.log10(255.0**2 / max(mse, 1e-12)))


def pictures(store) -> tuple[list[np.ndarray], list[int]]:
    with geoterrain.open(store) as t:
        scene = TerrainScene(pyvista_plotter(SIZE), t)
        try:
            out = [scene.frame(default_view(t, SIZE, az, el), 1.0, "rtin") for az, el in VIEWS]
        finally:
            scene.plotter.close()
    return [img for img, _ in out], [st["triangles"] for _, st in out]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--codec-error", type=float, nargs="+", default=[1.0, 2.0])
    ap.add_argument("--dems", nargs="+", default=list(NAMES))
    a = ap.parse_args()
    print("| DEM | ε | PSNR against lossless (3 views) | triangles (lossless → lossy) |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.dems:
            path = DEMS / name
            if not path.exists():
                continue
            kw = {"pixel_size": 30.0} if path.suffix == ".png" else {}
            ref, tri0 = pictures(geoterrain.preprocess(path, Path(tmp) / f"{name}.l", **kw))
            for eps in a.codec_error:
                store = geoterrain.preprocess(path, Path(tmp) / f"{name}.{eps}",
                                              codec_error=eps, **kw)
                imgs, tri = pictures(store)
                ps = " / ".join(f"{psnr(x, r):.2f}" for x, r in zip(imgs, ref, strict=True))
                print(f"| {name} | {eps:g} | {ps} | {sum(tri0)} → {sum(tri)} |", flush=True)


if __name__ == "__main__":
    main()
