"""The LOD seam: one registry, one select(), layers that only look down."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

import geoterrain
from geoterrain import lod
from geoterrain.exceptions import UsageError
from geoterrain.ingest.synth import generate, write_geotiff
from geoterrain.lod import registry

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


@pytest.fixture(scope="module")
def terrain(tmp_path_factory):
    d = tmp_path_factory.mktemp("seam")
    dem = write_geotiff(d / "dem.tif", generate("fbm", 129, seed=5))
    t = geoterrain.open(geoterrain.preprocess(dem, tile_size=32))
    yield t
    t.close()


def view(t):
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    return geoterrain.View(tuple(c + [0.0, -1.5 * (hi[1] - lo[1]), hi[2]]), tuple(c))


def test_every_registered_strategy_selects_through_the_seam(terrain):
    v = view(terrain)
    for name in lod.STRATEGIES:
        assert callable(registry.strategy_info(name).load())
        sel = lod.select(terrain, v, 1.0, name, reuse=False)
        assert sel.stats["strategy"] == name and sel.stats["triangles"] > 0
        assert not sel.stats["reused"] and sel.stats["select_ms"] > 0


def test_a_new_strategy_is_one_registry_line(terrain, monkeypatch):
    entry = registry.StrategyInfo("every-tile", "geoterrain.lod.bruteforce", "test", "test",
                                   True)
    monkeypatch.setitem(registry.REGISTRY, entry.name, entry)
    sel = lod.select(terrain, view(terrain), 2.0, "every-tile")
    assert sel.stats["strategy"] == "every-tile" and sel.stats["triangles"] > 0


def test_reuse_is_an_option(terrain):
    v = view(terrain)
    a = lod.select(terrain, v, 1.0, "rtin", reuse=False)
    b = lod.select(terrain, v, 1.0, "rtin")
    c = lod.select(terrain, v, 1.0, "rtin", reuse=False)
    assert b.stats["reused"] and b.mesh is a.mesh and b.stats["select_ms"] == 0
    assert not c.stats["reused"] and c.mesh is not a.mesh
    np.testing.assert_array_equal(np.asarray(a.mesh.points), np.asarray(c.mesh.points))


@pytest.mark.parametrize("tau", [0.0, -1.0, float("nan"), float("inf"), "x"])
def test_bad_pixel_error_is_a_usage_error_in_api_words(terrain, tau):
    with pytest.raises(UsageError, match="pixel_error"):
        lod.select(terrain, view(terrain), tau)


def test_unknown_strategy_names_the_choices(terrain):
    with pytest.raises(UsageError, match="use one of rtin, chunked, bruteforce"):
        terrain.select(view(terrain), 1.0, "no_such_strategy")


def test_selection_writes_nothing_into_the_terrain(terrain):
    before = dict(vars(terrain))
    for name in lod.STRATEGIES:
        lod.select(terrain, view(terrain), 4.0, name, reuse=False)
    lod.static(terrain, 3.0)
    after = vars(terrain)
    assert set(after) == set(before)
    # the running counts of what was read (TerrainLike) may grow; nothing else may change
    counts = {"decoded_tiles", "decoded_normals", "decoded_bounds", "bytes_read"}
    assert all(after[k] is before[k] for k in before if k not in counts)


def test_stand_in_height_is_recorded_at_preprocess(terrain):
    Z = terrain.scene_xyz()[2]
    assert terrain.meta["stand_in_z"] == 0.5 * (np.nanmin(Z) + np.nanmax(Z))


def test_cli_choices_and_help_come_from_the_registry():
    from geoterrain.cli.main import cli

    for cmd in ("mesh", "render", "view", "bench"):
        out = CliRunner().invoke(cli, [cmd, "--help"]).output
        for name in lod.STRATEGIES:
            assert name in out, (cmd, name)


def test_help_pays_for_neither_numba_nor_vtk():
    code = ("import sys; from geoterrain.cli.main import cli\n"
            "try:\n    cli(['mesh', '--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numba', 'vtk', 'vtkmodules', 'pyvista') if m in sys.modules]\n"
            "print('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "HEAVY []" in out
