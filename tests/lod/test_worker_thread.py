"""A selection and its atlas made on a worker thread make no VTK object.

The viewer selects and textures the next frame on a worker thread while the UI thread
draws and frees VTK objects; a VTK object made on the worker then can deadlock the two
(VTK's garbage collector's lock and the GIL taken in opposite orders). So every
strategy hands back :class:`~geoterrain.lod.mesh.MeshParts` (numpy arrays), the atlas
reads only those, and VTK's mesh is made by the thread that asks for ``vtk_mesh``.
These tests record every call into the mesh module's VTK constructors and fail on one
made off the main thread; the meshes equal the ones selected on the main thread.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import geoterrain
from geoterrain import lod
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import mesh as lodmesh
from geoterrain.lod.registry import STRATEGIES

_T: dict = {}


def _terrain(tmp_path_factory):
    """A fresh terrain (its own caches: ROAM's meshes carry over from frame to frame)."""
    if "p" not in _T:
        z = generate("fbm", 129, seed=3)
        z[20:40, 60:90] = np.nan  # nodata too
        d = tmp_path_factory.mktemp("w")
        dem = write_geotiff(d / "d.tif", z)
        _T["p"] = geoterrain.preprocess(dem, d / "d.geoterrain", tile_size=16)
    return geoterrain.open(_T["p"])


def _view(t) -> geoterrain.View:
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    r = float(np.linalg.norm(hi[:2] - lo[:2]))
    eye = c + r * np.array([0.6, -0.5, 0.45])
    return geoterrain.View(tuple(eye), tuple(c), size=(320, 180))


@pytest.fixture
def vtk_calls(monkeypatch):
    """The threads that called the mesh module's VTK constructors."""
    seen: list[str] = []
    for name in ("polydata", "_add", "numpy_to_vtk", "numpy_to_vtkIdTypeArray"):
        real = getattr(lodmesh, name)

        def spy(*a, _real=real, **k):
            seen.append(threading.current_thread().name)
            return _real(*a, **k)

        monkeypatch.setattr(lodmesh, name, spy)
    return seen


def _same(a, b) -> None:
    assert (a.n_points, a.n_cells) == (b.n_points, b.n_cells)
    np.testing.assert_array_equal(np.asarray(a.points), np.asarray(b.points))
    np.testing.assert_array_equal(np.asarray(a.regular_faces, np.int64),
                                  np.asarray(b.regular_faces, np.int64))
    for k in ("grid_ij", "elevation"):
        if a.n_points:
            np.testing.assert_array_equal(np.asarray(a.point_data[k]),
                                          np.asarray(b.point_data[k]))
    for k in ("skirt", "level"):
        if a.n_cells and k in b.cell_data:
            np.testing.assert_array_equal(np.asarray(a.cell_data[k]),
                                          np.asarray(b.cell_data[k]))


@pytest.mark.fast
@pytest.mark.parametrize("strategy", STRATEGIES)
def test_a_selection_on_a_worker_thread_makes_no_vtk_object(tmp_path_factory, vtk_calls,
                                                            strategy):
    t = _terrain(tmp_path_factory)
    view = _view(t)
    with ThreadPoolExecutor(1, thread_name_prefix="worker") as ex:
        sel = ex.submit(lod.select, t, view, 1.0, strategy, reuse=False).result()
    assert isinstance(sel.parts, lodmesh.MeshParts)
    assert not [n for n in vtk_calls if n.startswith("worker")], vtk_calls
    assert sel.stats["vertices"] == sel.parts.n_points
    main = lod.select(_terrain(tmp_path_factory), view, 1.0, strategy, reuse=False)
    _same(sel.parts, main.parts)
    vm = sel.vtk_mesh  # made here, on the main thread, once
    assert vm is sel.vtk_mesh
    assert isinstance(vm, lodmesh.TriMesh)
    _same(vm, main.parts)
    if vm.n_points:
        assert vm.active_scalars_name == "elevation"


@pytest.mark.fast
def test_the_atlas_on_a_worker_thread_makes_no_vtk_object(tmp_path_factory, vtk_calls):
    from geoterrain.rendering.tileshader import TileShader
    from geoterrain.rendering.tiletextures import build_view_texture

    t = _terrain(tmp_path_factory)
    view = _view(t)

    def work():
        sel = lod.select(t, view, 1.0, reuse=False)
        return sel, build_view_texture(t, sel, view, TileShader(t))

    with ThreadPoolExecutor(1, thread_name_prefix="worker") as ex:
        sel, vtex = ex.submit(work).result()
    assert not vtk_calls, vtk_calls  # nothing made a VTK mesh yet, on any thread
    assert len(vtex.faces) == sel.parts.n_cells > 0
    again = build_view_texture(t, sel, view, TileShader(t))
    np.testing.assert_array_equal(vtex.image, again.image)
    np.testing.assert_array_equal(vtex.points, again.points)
