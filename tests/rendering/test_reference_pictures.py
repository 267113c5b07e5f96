"""Rendered pictures against stored references, by PSNR (as PyVista tests its images).

One small picture per shading mode and overlay layout, rendered from a seeded synthetic
store, is compared with ``tests/reference/<name>.png``. Regenerate them after an
intended change with ``GEOTERRAIN_UPDATE_REFERENCE=1 pytest
tests/rendering/test_reference_pictures.py``
and look at them before committing.

The threshold (``MIN_PSNR``) was chosen by measurement against ``normals.png``: the same
render repeats bit for bit on one machine (PSNR ∞), while material changes score
14.7 dB (VE 1.3), 17.7 dB (the gist_earth palette), 19.4 dB (the sun moved 90°),
20.1 dB (no hillshade) and 26.5 dB (τ = 4 instead of 1); the subtler multidirectional
hillshade scores 31.8 dB and is not caught. 30 dB leaves room for another software
renderer's rasterisation.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import geoterrain
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering.scene import default_view, render
from geoterrain.rendering.shading import Light

REF = Path(__file__).parent / "reference"
MIN_PSNR = 30.0
SIZE = (240, 180)

CASES = {
    "normals": dict(),
    "elevation": dict(shading="elevation"),
    "plain": dict(shading="plain"),
    "shadows": dict(light=Light(250, 25, shadows=True, ambient_occlusion=True)),
    "top_down": dict(view=("top",)),
    "exaggerated_title": dict(vertical_exaggeration=3.0, title="VE"),
}


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0**2 / mse)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    dem = write_geotiff(d / "ref.tif", generate("fbm", 257, seed=21), spacing=30.0)
    return geoterrain.preprocess(dem, d / "ref.geoterrain")


def _render(store, name: str, out: Path) -> np.ndarray:
    import imageio.v3 as iio

    kw = dict(CASES[name])
    with geoterrain.open(store) as t:
        view = None
        if kw.pop("view", None):
            view = default_view(t, SIZE, 180.0, 90.0)
        render(t, view if view is not None else default_view(t, SIZE, 200.0, 35.0), out,
               **kw)
    return iio.imread(out)[..., :3]


@pytest.mark.fast
@pytest.mark.parametrize("name", list(CASES))
def test_picture_matches_its_reference(store, name, tmp_path):
    import imageio.v3 as iio

    img = _render(store, name, tmp_path / f"{name}.png")
    ref = REF / f"{name}.png"
    if os.environ.get("GEOTERRAIN_UPDATE_REFERENCE") == "1":
        REF.mkdir(exist_ok=True)
        iio.imwrite(ref, img)
        pytest.skip(f"reference {ref.name} written")
    assert ref.exists(), f"no reference {ref}: run with GEOTERRAIN_UPDATE_REFERENCE=1"
    want = iio.imread(ref)[..., :3]
    assert img.shape == want.shape
    assert psnr(img, want) >= MIN_PSNR, f"{name}: {psnr(img, want):.1f} dB"
