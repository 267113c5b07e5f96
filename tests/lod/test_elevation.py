"""Every mesh carries ``elevation``: metres, without vertical exaggeration, every strategy."""

from __future__ import annotations

import numpy as np
import pytest

import geoterrain
from geoterrain import lod
from geoterrain.exaggerate import exaggerated
from geoterrain.ingest.synth import generate, write_geotiff

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

FT = 0.3048


@pytest.fixture(scope="module")
def terrain(tmp_path_factory):
    # Heights in feet and a stored z_scale of 2: elevation must undo both.
    d = tmp_path_factory.mktemp("elev")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 129, seed=11))
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32, z_units="ft", z_scale=2.0))
    yield t
    t.close()


def view(t):
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    return geoterrain.View(tuple(c + [0.0, -1.2 * (hi[1] - lo[1]), 2 * hi[2]]), tuple(c))


def check(t, sel, n: float = 1.0) -> None:
    m = sel.mesh
    assert m.n_points > 0 and m.active_scalars_name == "elevation"
    e = np.asarray(m.point_data["elevation"], np.float64)
    # Against the stored heights of each vertex's sample (independent of the scene Z).
    ij = sel.ij.astype(np.int64)
    on = np.zeros(m.n_points, bool)
    on[np.unique(sel.surface_faces())] = True
    h = t.gather(ij[on, 0], ij[on, 1], ("height",))["height"] * FT
    assert np.isfinite(h).all()
    assert np.allclose(e[on], h, rtol=0, atol=1e-4 * max(1.0, np.abs(h).max()))
    # Every vertex (skirts too): its own scene Z without the exaggeration.
    z = np.asarray(m.points)[:, 2] / (t.frame.z_scale * n)
    assert np.allclose(e, z, rtol=1e-6, atol=1e-4)


@pytest.mark.parametrize("strategy", lod.STRATEGIES)
def test_every_strategy_mesh_has_elevation_in_metres(terrain, strategy):
    tau = 16.0 if strategy == "chunked" else 2.0  # coarse enough for chunked to mix levels
    # (without morphing, whose vertices leave their samples' heights by design)
    sel = lod.select(terrain, view(terrain), tau, strategy, reuse=False,
                     morph=False if lod.strategy_info(strategy).morphs else None)
    check(terrain, sel)
    if strategy == "chunked":  # skirt vertices hang below their samples
        assert sel.stats["skirt_triangles"] > 0
        skirt = np.unique(sel.faces[np.asarray(sel.mesh.cell_data["skirt"]) == 1])
        top = terrain.gather(*sel.ij[skirt].astype(np.int64).T, ("height",))["height"] * FT
        assert (sel.mesh.point_data["elevation"][skirt] <= top + 1e-3).all()
    reused = lod.select(terrain, view(terrain), tau, strategy)
    assert "elevation" in reused.mesh.point_data


def test_static_mesh_and_exaggerated_views_have_elevation(terrain):
    check(terrain, terrain.static_selection(2.0))
    assert terrain.mesh(2.0).active_scalars_name == "elevation"
    e = exaggerated(terrain, 3.0)
    for strategy in ("rtin", "chunked"):
        check(terrain, lod.select(e, view(e), 16.0, strategy, reuse=False), n=3.0)
