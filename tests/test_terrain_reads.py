"""What a terrain reads, as functions over TerrainLike (geoterrain/gathers.py, extent.py,
heightreads.py, normalreads.py; bounds/tilereads.block_errors) and the height codec's
package (codec/pyramid/): each vertex gathered from its coarsest tile against the raster
it came from, a level's grid, the scene box and the stand-in height against the samples,
a damaged blob refused in one line, the normal codes counted; the public import paths
kept; and each of these modules importing only the stages before its own."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import write_tif
from geoterrain import extent, gathers, normalreads
from geoterrain.exceptions import StoreCorruptError
from geoterrain.heightreads import decode_heights
from geoterrain.ingest.synth import generate
from geoterrain.terrainlike import TerrainLike

pytestmark = pytest.mark.fast

NODATA = -9999
ROOT = Path(geoterrain.__file__).parent


@pytest.fixture(scope="module", params=["square", "roots"])
def terrain(request, tmp_path_factory):
    """An int16 raster with a void, lossless: 129² on a square grid (normals derived on
    read), or 50 × 121 on 2 × 1 roots (normal maps stored whole), tiles of 8 samples (so
    vertices lie on 4 or 5 levels)."""
    rows, cols = (129, 129) if request.param == "square" else (50, 121)
    z = generate("fbm", cols, seed=5)[:rows, :cols]
    z = np.rint(800.0 * (z - z.min()) / max(float(np.ptp(z)), 1e-12)).astype(np.int16)
    z[20:27, 30:45] = NODATA
    d = tmp_path_factory.mktemp("reads")
    src = write_tif(d / "z.tif", z, dtype="int16", nodata=NODATA)
    roots = request.param == "roots"
    store = geoterrain.preprocess(src, d / "z.geoterrain", tile_size=8, root_grid=roots,
                                  derive_normals=not roots)
    with geoterrain.open(store) as t:
        assert t.grid.layout == request.param
        yield t, z


@settings(max_examples=30, deadline=None)
@given(data=st.data())
def test_gather_reads_every_vertex_as_the_raster_holds_it(terrain, data):
    t, z = terrain
    n = data.draw(st.integers(1, 60))
    i = np.array(data.draw(st.lists(st.integers(0, z.shape[0] - 1), min_size=n, max_size=n)))
    j = np.array(data.draw(st.lists(st.integers(0, z.shape[1] - 1), min_size=n, max_size=n)))
    got = gathers.gather(t, i, j, ("height", "x", "y", "delta"))
    valid = z[i, j] != NODATA
    # heights from each vertex's coarsest tile: the raster's samples (a lossless store),
    # NaN over the void; x, y those of the frame at (i, j)
    assert np.array_equal(got["height"][valid], z[i, j][valid].astype(np.float64))
    assert np.isnan(got["height"][~valid]).all()
    X, Y = t.frame.xy(i, j)
    assert np.array_equal(got["x"], X) and np.array_equal(got["y"], Y)
    assert (got["delta"] >= 0).all()
    # the level a vertex is read from holds it: i and j are multiples of 2^level
    L = gathers.vertex_level(t, i, j)
    assert ((i % (1 << L) == 0) & (j % (1 << L) == 0)).all()
    assert t.gather(i, j, ("height",))["height"].tobytes() == got["height"].tobytes()


def test_level_grids_and_the_scene_are_the_rasters(terrain):
    t, z = terrain
    valid = z != NODATA
    for L in t.grid.levels:
        s = 1 << L
        h, v = gathers.level_heights(t, L)
        zl, vl = z[::s, ::s], valid[::s, ::s]
        assert np.array_equal(v[:zl.shape[0], :zl.shape[1]], vl)
        assert np.array_equal(h[:zl.shape[0], :zl.shape[1]][vl], zl[vl].astype(np.float64))
    X, Y, Z = gathers.scene_xyz(t)
    assert Z.shape == z.shape and np.isnan(Z[~valid]).all()
    assert np.array_equal(Z[valid], t.frame.z(z[valid]))
    # the scene box holds every valid sample and no more than the top tiles' boxes
    lo, hi = extent.scene_box(t)
    assert lo[2] == np.nanmin(Z) and hi[2] == np.nanmax(Z)
    assert (lo[:2] <= [np.min(X), np.min(Y)]).all() and (hi[:2] >= [np.max(X), np.max(Y)]).all()
    assert lo[2] <= extent.stand_in_z(t) <= hi[2]


def test_stacks_are_the_tiles_and_empty_tiles_hold_nothing(terrain):
    t, _ = terrain
    stored = t.tile_keys(0)[:3]
    absent = (0, 10**6, 0)  # no tile there: δ 0, heights NaN
    s = gathers.tile_stacks(t, [*stored, absent], ("delta", "height"))
    for n, k in enumerate(stored):
        assert np.array_equal(s["delta"][n], t.tile_delta(*k))
        assert np.array_equal(s["height"][n], t.tile(*k).heights, equal_nan=True)
    assert (s["delta"][-1] == 0).all() and np.isnan(s["height"][-1]).all()


def test_a_damaged_height_blob_is_refused_in_one_line(terrain):
    t, _ = terrain
    key = t.tile_keys(0)[0]
    tile = decode_heights(t, key, t.reader.get_blob)
    assert np.array_equal(tile.heights, t.tile(*key).heights, equal_nan=True)
    with pytest.raises(StoreCorruptError, match=r"cannot be decoded; re-run") as e:
        decode_heights(t, key, t.reader.get_blob, b"\x03\x00")
    assert "\n" not in str(e.value)


def test_normal_codes_are_the_terrains_and_counted(terrain):
    t, _ = terrain
    # every level derived on read (the square store) or every map stored whole (roots)
    assert len(t.meta.get("normals_derived", ())) == (len(t.grid.levels) if
                                                      t.grid.layout == "square" else 0)
    keys = [k for L in t.grid.levels for k in t.tile_keys(L)[:2]]
    before = t.decoded_normals
    codes = normalreads.normal_codes(t, keys, t.reader.get_blob)
    assert t.decoded_normals == before + len(keys)
    assert np.array_equal(codes, t.normal_codes(keys))
    from geoterrain.bounds.tilereads import block_errors

    assert block_errors(t, t.reader.get_blob) is t.block_errors()  # one cached table


def test_the_public_names_keep_their_import_paths(terrain):
    from geoterrain.codec import pyramid
    from geoterrain.codec.pyramid import decode, decoded, encode, layout

    for name in ("BLOB_VERSION", "blob_predictor", "encode_child", "encode_pyramid",
                 "encode_root", "decode_tile", "decode_tile_valid", "tile_valid",
                 "decoded_codes", "decoded_heights", "encode_decoded", "pyramid_shape",
                 "roots_shape", "top_bins"):
        owner = next(m for m in (layout, decoded, encode, decode) if hasattr(m, name))
        assert getattr(pyramid, name) is getattr(owner, name), name
    from geoterrain.terrain import Terrain, Tile, TileKey, edit, open  # noqa: F401

    assert isinstance(terrain[0], TerrainLike)


# the stages each module may import from (module-level and inside functions alike)
LAYERS = {
    "codec/pyramid/__init__.py": ("geoterrain.codec.pyramid.",),
    "codec/pyramid/layout.py": ("geoterrain.codec.", "geoterrain.core."),
    "codec/pyramid/decoded.py": ("geoterrain.codec.", "geoterrain.core."),
    "codec/pyramid/encode.py": ("geoterrain.codec.", "geoterrain.core."),
    "codec/pyramid/decode.py": ("geoterrain.codec.", "geoterrain.core."),
    **{f"{m}.py": ("geoterrain.core.", "geoterrain.bounds.", "geoterrain.codec.",
                   "geoterrain.exceptions", "geoterrain.terrainlike")
       for m in ("gathers", "extent", "heightreads", "normalreads")},
}


def imported(path: Path) -> set[str]:
    names = set()
    for n in ast.walk(ast.parse(path.read_text())):
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("geoterrain"):
            names.update(f"{n.module}.{a.name}" for a in n.names)  # a module or a name in it
        elif isinstance(n, ast.Import):
            names.update(a.name for a in n.names if a.name.startswith("geoterrain"))
    return names


@pytest.mark.parametrize("module", sorted(LAYERS))
def test_each_read_module_imports_only_earlier_stages(module):
    allowed = LAYERS[module]
    later = sorted(m for m in imported(ROOT / module) if not m.startswith(allowed))
    assert not later, f"{module} imports {later}"
    if module.startswith("codec/pyramid/") and not module.endswith("__init__.py"):
        # the package's modules never import the package itself (no cycle through it)
        tree = ast.parse((ROOT / module).read_text())
        assert "geoterrain.codec.pyramid" not in {
            n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
