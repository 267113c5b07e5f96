"""Notebook conventions: the HTML summary, plot, top-level names and the docs notebook."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import geoterrain

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.fast
def test_top_level_names():
    from geoterrain.rendering import animation, cameras

    assert geoterrain.default_view is cameras.default_view
    assert geoterrain.orbit is animation.orbit
    assert {"default_view", "orbit"} <= set(dir(geoterrain))


@pytest.mark.fast
def test_repr_html_summarises_the_terrain(tmp_path, fbm_tif):
    import base64
    import io
    import re

    from PIL import Image

    t = geoterrain.open(geoterrain.preprocess(fbm_tif, tmp_path / "a.geoterrain", tile_size=32))
    h = t._repr_html_()
    info = t.info()
    for word in ("UTM", "km", f"{info['levels']} levels", info["codec"], "129 × 129"):
        assert word in h, word
    png = re.search(r"data:image/png;base64,([A-Za-z0-9+/=]+)", h).group(1)
    img = Image.open(io.BytesIO(base64.b64decode(png)))
    assert img.size == (129, 129)  # the data, not the padding
    import numpy as np

    assert len(np.unique(np.asarray(img).reshape(-1, 3), axis=0)) > 100  # shaded, not blank
    t.close()


def test_plot_without_a_notebook_backend_is_an_image(tmp_path, fbm_tif):
    import numpy as np

    t = geoterrain.open(geoterrain.preprocess(fbm_tif, tmp_path / "a.geoterrain", tile_size=32))
    img = t.plot(size=(320, 180))
    assert img.size == (320, 180)
    a = np.asarray(img)
    assert (np.abs(a.astype(int) - a[0, 0]).sum(-1) > 30).mean() > 0.1  # terrain is drawn
    t.close()


def test_docs_notebook_runs(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    nb = nbformat.read(ROOT / "docs" / "quickstart.ipynb", as_version=4)
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outs if o.output_type == "error"]
    assert any("text/html" in o.get("data", {}) for o in outs)  # the Terrain summary
    # the default render, the map, water, a drape and the print's preview
    assert sum("image/png" in o.get("data", {}) for o in outs) == 5
    text = "".join(o.get("text", "") for o in outs)
    assert "relief.stl" in text and "terrain.glb" in text and "uint8" in text
    assert "True True" in text


def test_analysis_notebook_runs(tmp_path, monkeypatch):
    """docs/analysis.ipynb: a profile, a viewshed draped in 3-D, contours over the render."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    nb = nbformat.read(ROOT / "docs" / "analysis.ipynb", as_version=4)
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    outs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outs if o.output_type == "error"]
    assert sum("image/png" in o.get("data", {}) for o in outs) == 3  # profile, drape, lines
    text = "".join(o.get("text", "") for o in outs)
    assert "visible" in text and "contours.gpkg" in text and "±" in text


@pytest.mark.parametrize("backend", ["server", "client"])
def test_plot_with_trame_rendering_in_the_kernel_follows_the_camera(tmp_path, fbm_tif,
                                                                    monkeypatch, backend):
    """``plot(interactive=True)`` through a trame backend that renders in the kernel:
    the viewer's controller is on the plotter, and a camera move ended by the mouse's
    release re-selects the LOD; "client" (vtk.js in the page) keeps one selection."""
    import numpy as np
    import pyvista as pv

    from geoterrain.rendering import notebook

    monkeypatch.setattr(notebook, "notebook_backend", lambda: backend)
    shown = {}

    def show(self, jupyter_backend=None, **kw):
        shown["backend"] = jupyter_backend
        return self

    monkeypatch.setattr(pv.Plotter, "show", show)
    t = geoterrain.open(geoterrain.preprocess(fbm_tif, tmp_path / "a.geoterrain", tile_size=32))
    p = t.plot(size=(480, 270), interactive=True)
    try:
        assert shown["backend"] == backend
        ctl = getattr(p, "_geoterrain_viewer", None)
        if backend == "client":
            assert ctl is None
            return
        first, n = ctl.stats["triangles"], ctl.selections
        assert first > 0
        c = p.camera  # down to the ground: the near terrain needs finer triangles
        c.position = tuple(np.add(c.focal_point, np.subtract(c.position, c.focal_point) / 6))
        p.iren.interactor.InvokeEvent("EndInteractionEvent")
        assert ctl.selections > n
        assert ctl.stats["triangles"] != first
        assert "space freeze" not in ctl._hud.GetText(2)  # no key hints: no keys here
    finally:
        if getattr(p, "_geoterrain_viewer", None) is not None:
            p._geoterrain_viewer.close()
        p.close()
        t.close()


@pytest.mark.fast
def test_docs_notebook_is_stored_with_its_pictures():
    """The stored notebook carries its outputs (its page shows the pictures), made from the
    real DEM, small enough for the repository, with no machine path in them."""
    nbformat = pytest.importorskip("nbformat")
    path = ROOT / "docs" / "quickstart.ipynb"
    nb = nbformat.read(path, as_version=4)
    outs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert sum("image/png" in o.get("data", {}) for o in outs) == 5
    text = path.read_text()
    assert "srtm1_japan" in text and "/tmp/" not in text and "/work/" not in text
    assert path.stat().st_size < 1_500_000
