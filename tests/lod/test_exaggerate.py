"""View-time vertical exaggeration: measured ρ ≤ τ on the exaggerated surface, N = 1 is
the terrain itself, and the rendering API draws the exaggerated relief."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.exaggerate import exaggerated
from geoterrain.exceptions import UsageError
from tests.lod import test_lod
from tests.lod.test_lod import SLACK, Case, random_view, screen_error

holey, terrains = test_lod.holey, test_lod.terrains  # the LOD tests' terrains (fixtures)

_CASES: dict = {}


def _case(c: Case, n: float) -> Case:
    key = (c.name, n)
    if key not in _CASES:
        _CASES[key] = Case(f"{c.name}×{n:g}", exaggerated(c.t, n))
    return _CASES[key]


@given(data=st.data(), n=st.sampled_from([0.5, 3.0, 10.0]), az=st.floats(0, 2 * np.pi),
       el=st.floats(0.05, 1.5), dist=st.floats(0.05, 3.0), tx=st.floats(-1, 1),
       ty=st.floats(-1, 1), tau=st.sampled_from([0.5, 1.0, 4.0]),
       strategy=st.sampled_from(["rtin", "chunked", "geomipmap", "cdlod"]))
def test_exaggerated_screen_error_is_at_most_tau(terrains, data, n, az, el, dist, tx, ty,
                                                 tau, strategy):
    base = data.draw(st.sampled_from(terrains), label="terrain")
    c = _case(base, n)
    assert np.allclose(c.Z[c.valid], n * base.Z[base.valid])
    view = random_view(c, az, el, dist, tx, ty)
    sel = c.t.select(view, tau, strategy, occlusion=False)  # ρ at every sample in view
    err = screen_error(c, sel, view)  # measured against the exaggerated full-res surface
    assert err.max <= tau * SLACK, (n, err, sel.stats)


@pytest.mark.fast
def test_exaggeration_one_is_the_terrain_and_bad_values_refused(terrains):
    t = terrains[0].t
    assert exaggerated(t, 1.0) is t
    assert exaggerated(exaggerated(t, 2.0), 1.5) is exaggerated(t, 3.0)
    for bad in (0.0, -2.0, float("nan"), "x"):
        with pytest.raises(UsageError):
            exaggerated(t, bad)


@pytest.mark.fast
def test_rendered_exaggeration_is_labelled_and_steeper(tmp_path_factory, tmp_path):
    from click.testing import CliRunner

    from geoterrain.rendering.overlays import compose
    from geoterrain.rendering.scene import overview, render_array
    from tests.rendering.test_render import _cli, synth_store

    t = synth_store(tmp_path_factory, "fbm")
    e = exaggerated(t, 3.0)
    v = overview(e, (480, 320))
    img, st = render_array(t, v, vertical_exaggeration=3.0)
    assert st["terrain_fraction"] > 0.3
    ext: dict = {}
    compose(img, v, e, extents=ext)
    plain: dict = {}
    compose(img, v, t, extents=plain)
    # the VE line makes the scale-bar text taller
    assert (ext["scale_bar"][3] - ext["scale_bar"][1]) > (plain["scale_bar"][3]
                                                          - plain["scale_bar"][1])
    r = CliRunner().invoke(_cli(), ["render", str(t.path), "-o", str(tmp_path / "a.png"),
                                    "-z", "0"])
    assert r.exit_code == 2 and "vertical-exaggeration" in r.output
    r = CliRunner().invoke(_cli(), ["-q", "mesh", str(t.path), "-o", str(tmp_path / "m.ply"),
                                    "-z", "2", "--max-error", "2"])
    assert r.exit_code == 0, r.output


@pytest.mark.fast
@pytest.mark.parametrize("n", [0.5, 4.0])
def test_exaggerated_padded_static_mesh_keeps_its_vertical_error(terrains, n):
    """A padded store's static mesh reads its second δ (δ_edge, edgepad.py) and the
    per-tile maxima that skip tiles: both are vertical, so they scale with the
    exaggeration too, and the mesh keeps its error on the exaggerated surface."""
    from geoterrain.testing.measure import vertical_error

    base = next(c for c in terrains if c.t.edge_max)  # a DEM that leaves padding
    c = _case(base, n)
    assert c.t.edge_max == {k: v * n for k, v in base.t.edge_max.items()}
    for e in (0.5 * n, 2.0 * n):
        sel = c.t.static_selection(e)
        err = vertical_error(np.asarray(sel.ij, float), sel.surface_faces().astype(np.int64),
                             np.asarray(sel.mesh.points)[:, 2], c.Z, c.valid)
        assert err.n_uncovered_valid == 0 and err.max <= e * (1 + 1e-9) + 1e-9, (n, e, err)


@pytest.mark.fast
@pytest.mark.parametrize("strategy", ["geomipmap", "geomipmap_distance"])
def test_exaggerated_block_errors_scale(terrains, strategy):
    """GeoMipMapping's per-block δ_n table is vertical: an exaggerated view scales it
    (it had read the base's table, and ρ reached 3.9 τ at ×4), and geomipmap keeps ρ ≤ τ
    on the exaggerated surface over a fixed set of views."""
    base = terrains[0]
    c = _case(base, 4.0)
    np.testing.assert_array_equal(c.t.block_errors(), 4.0 * base.t.block_errors())
    if strategy != "geomipmap":
        return
    for az, el, dist in ((0.3, 0.6, 0.5), (2.0, 0.25, 0.3), (4.0, 1.2, 1.0), (5.5, 0.1, 0.2)):
        view = random_view(c, az, el, dist, 0.1, -0.2)
        sel = c.t.select(view, 1.0, strategy, occlusion=False)
        assert screen_error(c, sel, view).max <= SLACK, (az, el, dist)
