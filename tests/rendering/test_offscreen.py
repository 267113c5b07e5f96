"""The offscreen render on VTK alone draws PyVista's pictures, byte for byte.

:class:`geoterrain.rendering.offscreen.OffscreenPlotter` (what ``render``, orbits and
fly-throughs draw with) reproduces the settings of PyVista's ``Plotter`` and
``add_mesh``; here the same views are drawn through both and every pixel compared:
shadings, anti-aliasing modes, a perspective, a low oblique and a map view, a sun with
shadows, the whole-terrain texture, a water surface, a view that sees no terrain. The PNG
writer is checked against imageio's (the same bytes), and a cold render's process
against the libraries it must not import (PyVista among them).
"""

from __future__ import annotations

import io
import subprocess
import sys

import numpy as np
import pytest

import geoterrain
from geoterrain.core.view import View
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.rendering.colours import Palette
from geoterrain.rendering.mapview import map_view
from geoterrain.rendering.scene import TerrainScene, overview
from geoterrain.rendering.shading import Light
from geoterrain.rendering.window import (
    PNG_LEVEL,
    offscreen_plotter,
    pyvista_plotter,
    write_png,
)
from tests.conftest import write_tif

SIZE = (160, 120)
_STORES: dict = {}


def _store(tmp_path_factory, kind: str):
    if kind not in _STORES:
        d = tmp_path_factory.mktemp(f"offscreen_{kind}")
        if kind == "land":
            src = write_geotiff(d / "fbm.tif", generate("fbm", 129, seed=5))
        else:  # a coast: −300 … 700 m, 100 m samples
            z = generate("fbm", (65, 80), seed=4, base=-300.0, relief=1000.0)
            src = write_tif(d / "coast.tif", z.astype(np.float32), spacing=100.0)
        _STORES[kind] = geoterrain.preprocess(src, d / f"{kind}.geoterrain", tile_size=16)
    return geoterrain.open(_STORES[kind])


def _views(t):
    lo, hi = t.scene_box()
    ext = float(hi[0] - lo[0])
    away = View((hi[0] + ext, 0.0, hi[2] + ext), (hi[0] + 3 * ext, 0.0, hi[2] + 2 * ext),
                size=SIZE)  # looking away from the terrain: the sky alone
    return [overview(t, SIZE), overview(t, SIZE, azimuth=60.0, elevation=12.0),
            map_view(t, SIZE), away]


def _same_pictures(t, **kw):
    aa = kw.pop("anti_aliasing", "auto")
    a = TerrainScene(pyvista_plotter(SIZE, aa), t, **kw)
    b = TerrainScene(offscreen_plotter(SIZE, aa), t, **kw)
    try:
        assert (a.water_actor is None) == (b.water_actor is None)
        for k, v in enumerate(_views(t)):
            ia, sa = a.frame(v)
            ib, sb = b.frame(v)
            assert sa["anti_aliasing"] == sb["anti_aliasing"], (kw, k)
            assert ia.shape == ib.shape == (SIZE[1], SIZE[0], 3)
            diff = int((ia != ib).any(-1).sum())
            assert diff == 0, f"{kw} {aa} view {k}: {diff} pixels differ"
            assert a.terrain_fraction() == b.terrain_fraction()
        return a.water_actor is not None
    finally:
        a.plotter.close()
        b.plotter.close()


@pytest.mark.fast
@pytest.mark.parametrize("shading", ["normals", "elevation", "plain"])
@pytest.mark.parametrize("aa", ["auto", "msaa", "none", "fxaa"])
def test_offscreen_draws_pyvistas_pictures(tmp_path_factory, shading, aa):
    _same_pictures(_store(tmp_path_factory, "land"), shading=shading, anti_aliasing=aa)


@pytest.mark.fast
@pytest.mark.parametrize("kw, water", [
    (dict(), True),  # the auto palette's sea: a lit, translucent water surface
    (dict(cmap=Palette("auto", water_level=150.0)), True),
    (dict(cmap="terrain", light=Light(azimuth=250.0, elevation=15.0, shadows=True)), False),
    (dict(textures="global"), True),
    (dict(water=False), False),
], ids=["sea", "water-level", "sun-shadows", "global-texture", "no-water"])
def test_offscreen_draws_pyvistas_water_light_and_textures(tmp_path_factory, kw, water):
    assert _same_pictures(_store(tmp_path_factory, "coast"), **kw) == water


@pytest.mark.fast
def test_png_bytes_are_imageios(tmp_path):
    import imageio.v3 as iio

    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    img[:10] = 200  # runs as well as noise
    out = tmp_path / "a.png"
    write_png(out, img)
    ref = io.BytesIO()
    iio.imwrite(ref, img, extension=".png", compress_level=PNG_LEVEL)
    assert out.read_bytes() == ref.getvalue()
    assert np.array_equal(iio.imread(out), img)


@pytest.mark.fast
def test_render_help_imports_no_vtk():
    code = ("import sys; from geoterrain.cli.main import cli\n"
            "try:\n    cli(['render', '--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numba', 'vtk', 'vtkmodules', 'pyvista', 'matplotlib')"
            " if m in sys.modules]\n"
            "print('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "HEAVY []" in out


@pytest.mark.fast
@pytest.mark.parametrize("kind, args", [
    ("land", []),
    ("coast", ["--map"]),  # the sea's water surface, a map's graticule
    ("coast", ["--water-level", "150", "--strategy", "chunked", "--shading", "plain"]),
], ids=["default", "map-sea", "water-level-chunked-plain"])
def test_a_render_never_imports_pyvista(tmp_path_factory, tmp_path, kind, args):
    """A render's process imports no PyVista (its selection's mesh is a TriMesh, drawn on
    VTK alone), nor pyplot, imageio or the whole of VTK; the API still hands callers a
    ``pyvista.PolyData``."""
    _store(tmp_path_factory, kind)
    code = ("import sys; from geoterrain.cli.main import cli\n"
            f"try:\n    cli(['-q', 'render', {str(_STORES[kind])!r}, '-o', "
            f"{str(tmp_path / 'v.png')!r}, '--size', '160x120', *{args!r}])\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "print('LOADED', sorted(m for m in ('pyvista', 'matplotlib.pyplot', "
            "'imageio', 'vtk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "LOADED []" in out, out
    assert (tmp_path / "v.png").stat().st_size > 0


@pytest.mark.fast
def test_the_api_still_hands_out_pyvista_meshes(tmp_path_factory):
    import pyvista as pv

    t = _store(tmp_path_factory, "land")
    sel = t.select(overview(t, SIZE))
    assert isinstance(sel.mesh, pv.PolyData) and sel.mesh is t.select(overview(t, SIZE)).mesh
    # the same arrays as the mesh the render draws, not copies
    assert np.shares_memory(np.asarray(sel.mesh.points), sel.vtk_mesh.points)
    assert sel.mesh.n_cells == sel.vtk_mesh.n_cells > 0
    np.testing.assert_array_equal(sel.mesh.regular_faces, sel.vtk_mesh.regular_faces)
    for k in ("grid_ij", "elevation"):
        np.testing.assert_array_equal(sel.mesh.point_data[k], sel.vtk_mesh.point_data[k])
    assert sel.mesh.active_scalars_name == sel.vtk_mesh.active_scalars_name == "elevation"
    assert isinstance(t.mesh(5.0), pv.PolyData)


@pytest.mark.fast
def test_the_command_lines_start_draws_the_same_picture(tmp_path_factory, tmp_path):
    """``geoterrain``'s entry point (``main``: geoterrain/core/startup.py installed) loads
    its cached kernels without numba's context refresh (none of the modules only the
    refresh imports, nor numba's array implementations its kernels' environments name),
    without coverage.py where no coverage runs, and writes the same PNG
    bytes as the command run without it (a second run: every kernel cached)."""
    _store(tmp_path_factory, "land")
    args = ["-q", "render", str(_STORES["land"]), "--size", "160x120", "--overwrite", "-o"]
    plain = ("import sys; from geoterrain.cli.main import cli\n"
             f"try:\n    cli({args + [str(tmp_path / 'a.png')]!r})\n"
             "except SystemExit as e:\n    assert not e.code, e.code\n")
    started = ("import sys; had = 'coverage' in sys.modules\n"
               f"sys.argv = ['geoterrain', *{args + [str(tmp_path / 'b.png')]!r}]\n"
               "from geoterrain.cli.main import main\n"
               "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
               "import numba.misc.coverage_support as c\n"
               "print('REFRESHED', 'numba.misc.gdb_hook' in sys.modules,\n"
               "      'numba.np.polynomial.polynomial_core' in sys.modules,\n"
               "      'numba.np.arrayobj' in sys.modules)\n"
               "print('COVERAGE', had, c.coverage_available, 'coverage' in sys.modules)")
    for code in (plain, started):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout
    assert "REFRESHED False False False" in out, out
    had = "COVERAGE True" in out  # a measured test run: coverage in every process
    assert f"COVERAGE {had} {had} {had}" in out, out
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
