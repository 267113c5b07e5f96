"""Prints and 3-D models with a base: `export --base-height/--print-size` closes every format
into a solid (the surface, walls and a flat bottom), `-z N` exaggerates it, textures cover
the data only, and the command says what it wrote (words, or --json).

Each file is read back by trimesh (vertices merged, as a slicer does) and measured there.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from geoterrain.exaggerate import exaggerated
from geoterrain.export.formats import estimate_bytes, export_mesh

trimesh = pytest.importorskip("trimesh")

PRINT = 120.0  # mm


def run(*args):
    from geoterrain.cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def terr(tmp_path_factory):
    """A 97 × 129 fBm (not square, padded in the store) with a nodata notch."""
    from geoterrain.ingest.synth import generate
    from tests.conftest import write_tif

    d = tmp_path_factory.mktemp("solids")
    z = generate("fbm", 129, seed=11)[:97].astype(np.float32) * 0.5 + 200.0
    z[:10, :12] = -9999.0
    dem = write_tif(d / "dem.tif", z, nodata=-9999.0)
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32))
    yield t
    t.close()


def _load(path) -> trimesh.Trimesh:
    """The file as one mesh with coincident vertices merged (a glTF keeps its surface and its
    walls in two primitives), in its own axes (glTF: Y up)."""
    got = trimesh.load(path, force="mesh", process=False)
    got.merge_vertices(merge_tex=True, merge_norm=True)
    return got


def _up(ext: str) -> int:
    return 1 if ext in (".glb", ".gltf") else 2


@pytest.mark.parametrize("ext", [".glb", ".stl", ".obj", ".ply"])
def test_a_solid_is_watertight_with_a_flat_bottom(terr, tmp_path, ext):
    out = export_mesh(terr, terr.static_selection(2.0), tmp_path / f"s{ext}",
                      print_size=PRINT, base_height=4.0)
    s = _load(out)
    assert s.is_watertight and s.is_winding_consistent and s.volume > 0
    unit = 1e-3 if ext in (".glb", ".gltf") else 1.0  # glTF in metres
    up = _up(ext)
    lo, hi = s.bounds
    horiz = [k for k in range(3) if k != up]
    assert max(hi[horiz] - lo[horiz]) == pytest.approx(PRINT * unit, rel=1e-6)
    # the bottom: every vertex on the lowest plane lies within 1e-6 × the print size of it
    z = s.vertices[:, up]
    bottom = z < lo[up] + 1e-3 * PRINT * unit
    assert bottom.sum() >= 3
    assert np.ptp(z[bottom]) <= 1e-6 * PRINT * unit
    assert lo[up] == pytest.approx(0.0, abs=1e-6 * PRINT * unit)
    # the base: 4 mm under the lowest point of the surface
    top = z[~bottom]
    assert top.min() - lo[up] == pytest.approx(4.0 * unit, rel=1e-4)


@pytest.mark.parametrize("ext", [".glb", ".stl"])
def test_z3_triples_the_relief(terr, tmp_path, ext):
    """The same print size at -z 1 and -z 3 (every sample kept, so both meshes hold the same
    highest and lowest points): the relief above the base is exactly three times."""
    reliefs = []
    for n in (1.0, 3.0):
        e = exaggerated(terr, n)
        out = export_mesh(e, e.static_selection(0.0), tmp_path / f"z{n:g}{ext}",
                          print_size=PRINT, base_height=3.0)
        z = _load(out).vertices[:, _up(ext)]
        reliefs.append(float(z.max() - z.min()) - 3.0 * (1e-3 if ext == ".glb" else 1.0))
    assert reliefs[1] == pytest.approx(3 * reliefs[0], rel=1e-5)


def test_glb_solid_keeps_its_texture_and_plain_walls(terr, tmp_path):
    import pygltflib

    out = export_mesh(terr, terr.static_selection(2.0), tmp_path / "w.glb", base_height=20.0)
    doc = pygltflib.GLTF2.load(str(out))
    prims = doc.meshes[0].primitives
    assert len(prims) == 2
    assert prims[0].attributes.TEXCOORD_0 is not None and prims[1].attributes.TEXCOORD_0 is None
    walls = doc.materials[prims[1].material]
    assert walls.pbrMetallicRoughness.baseColorTexture is None
    assert walls.pbrMetallicRoughness.baseColorFactor[:3] == pytest.approx((0.62, 0.58, 0.52))
    # without a print size the solid is in metres: the base 20 m under the lowest point
    geo = json.loads(out.with_name("w.glb.json").read_text())
    assert geo["base_height"] == 20.0 and geo["scale"] == 1.0


@pytest.mark.fast
def test_texture_is_cropped_to_the_data(terr, tmp_path):
    from PIL import Image

    from geoterrain.export.meshdata import mesh_arrays

    sel = terr.static_selection(2.0)
    out = export_mesh(terr, sel, tmp_path / "c.obj")
    img = Image.open(out.with_suffix(".png"))
    assert img.size == (terr.grid.cols, terr.grid.rows)  # 129 × 97, not the padded 129²
    uv = trimesh.load(out, process=False).visual.uv
    ij = mesh_arrays(terr, sel).ij
    # each vertex's texel is its own sample's (OBJ's v from the bottom)
    assert np.allclose(uv[:, 0], (ij[:, 1] + 0.5) / terr.grid.cols, atol=1e-6)
    assert np.allclose(1 - uv[:, 1], (ij[:, 0] + 0.5) / terr.grid.rows, atol=1e-6)


def test_estimate_is_within_a_third_of_the_file(terr, tmp_path):
    for ext, closed in ((".glb", False), (".stl", True), (".obj", False), (".ply", False)):
        sel = terr.static_selection(0.5)
        info = {}
        export_mesh(terr, sel, tmp_path / f"e{ext}", stats=info)
        texels = terr.grid.rows * terr.grid.cols if ext in (".glb", ".obj") else 0
        guess = estimate_bytes(sel, ext, texels=texels, closed=closed)
        assert 0.67 < guess / info["bytes"] < 1.5, (ext, guess, info["bytes"])


def test_export_command_says_what_it_wrote(terr, tmp_path):
    out = tmp_path / "p.glb"
    res = run("export", terr.path, "-o", out, "--max-error", "2", "--print-size", "150", "-z",
              "2")
    assert res.exit_code == 0, res.output
    text = res.output
    assert "wrote" in text and "triangles" in text and "solid" in text and "× 2" in text
    assert not text.lstrip().startswith("{")
    res = run("export", terr.path, "-o", out, "--max-error", "2", "--overwrite", "--json")
    got = json.loads(res.stdout)
    from pathlib import Path

    assert got["files"][0] == str(out) and got["triangles"] > 0 and "texture" in got
    assert got["bytes"] == sum(Path(f).stat().st_size for f in got["files"])


def test_large_export_is_announced(terr, tmp_path, monkeypatch):
    import geoterrain.cli.export as E

    monkeypatch.setattr(E, "LARGE", 1000)
    res = run("export", terr.path, "-o", tmp_path / "big.obj", "--max-error", "0")
    assert res.exit_code == 0, res.output
    # the first line after the one a cold kernel cache prints (compiling kernels ...)
    first = [ln for ln in res.stderr.splitlines() if not ln.startswith("compiling")][0]
    assert first.startswith("writing about") and "--max-error" in first
    res = run("-q", "export", terr.path, "-o", tmp_path / "q.obj", "--max-error", "0")
    assert res.output == "" and res.stderr == ""


def test_preview_shows_the_model_with_its_base(terr, tmp_path):
    """`export --preview`: the solid on a white ground, its walls in their plain grey (a
    grey, unsaturated band under the coloured surface)."""
    import imageio.v3 as iio

    png = tmp_path / "p.png"
    res = run("-q", "export", terr.path, "-o", tmp_path / "p.stl", "--max-error", "2",
              "--print-size", "100", "-z", "3", "--preview", png)
    assert res.exit_code == 0, res.output
    img = iio.imread(png).astype(int)
    ground = (img == 255).all(-1)
    # the model fills the frame: its box spans most of the height or of the width (this
    # fBm at -z 3 is a tall block, its box 0.92 of the height), inside the picture
    ys, xs = np.nonzero(~ground)
    span = max((ys.max() - ys.min() + 1) / img.shape[0], (xs.max() - xs.min() + 1) / img.shape[1])
    assert 0.8 < span <= 0.95, span
    assert ys.min() > 0 and xs.min() > 0 and ys.max() < img.shape[0] - 1
    assert xs.max() < img.shape[1] - 1
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    grey = ~ground & (np.abs(r - g) < 12) & (np.abs(g - b) < 12) & (r < 200)
    assert grey.mean() > 0.01  # the walls
    res = run("export", terr.path, "-o", tmp_path / "q.stl", "--preview", tmp_path / "q.jpg")
    assert res.exit_code == 2 and not (tmp_path / "q.stl").exists()
