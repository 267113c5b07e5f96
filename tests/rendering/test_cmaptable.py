"""The colour maps held as tables give matplotlib's colours, value for value.

:mod:`geoterrain.rendering.cmaptable` keeps the maps the project names as their 256
colours so that shading with them imports no matplotlib. Checked here against matplotlib
itself (installed with the tests): the stored table is what matplotlib computes now, a
lookup of any fraction (edges of the 256 bins, 0 and 1, out of range, NaN, float32 or
float64) is matplotlib's colour, and :func:`~geoterrain.rendering.colours.colorize` gives
the same float32 colours through the table as through matplotlib. A render with such a map
and no overlays runs without importing matplotlib.
"""

from __future__ import annotations

import subprocess
import sys

import matplotlib
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from geoterrain.rendering import cmaptable
from geoterrain.rendering.cmaptable import NAMES, TABLE, colours, table
from geoterrain.rendering.colours import Palette, check_cmap, colorize


def _matplotlib(name, x):
    """matplotlib's colours, at the precision a texture keeps (float32)."""
    return np.asarray(matplotlib.colormaps[name](x))[..., :3].astype(np.float32)


@pytest.mark.fast
def test_the_stored_table_is_matplotlibs():
    assert set(TABLE) == set(NAMES)
    assert cmaptable._tables() == TABLE  # what the generator computes from matplotlib now
    for name in NAMES:
        assert np.array_equal(table(name), _matplotlib(name, np.arange(256))), name


@pytest.mark.fast
@pytest.mark.parametrize("name", NAMES)
def test_lookup_is_matplotlibs_at_every_edge(name):
    k = np.arange(257, dtype=np.float64) / 256
    x = np.concatenate([k, np.nextafter(k, -1), np.nextafter(k, 2), [0.0, 1.0, -0.0],
                        [-1e-9, -0.5, 1.5, np.inf, -np.inf, np.nan], np.linspace(0, 1, 1001)])
    for xx in (x, x.astype(np.float32), x.reshape(-1, 1)):
        got = colours(name, xx)
        assert got.shape == xx.shape + (3,)
        assert np.array_equal(got.astype(np.float32), _matplotlib(name, xx)), name


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(NAMES),
       x=arrays(np.float64, st.integers(1, 40),
                elements=st.one_of(st.floats(-0.5, 1.5),
                                   st.sampled_from([np.nan, np.inf, -np.inf]))))
def test_lookup_matches_matplotlib_anywhere(name, x):
    assert np.array_equal(colours(name, x).astype(np.float32), _matplotlib(name, x))


@pytest.mark.fast
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("water", [None, 120.0])
def test_colorize_through_the_table_is_colorize_through_matplotlib(monkeypatch, name, water):
    rng = np.random.default_rng(3)
    h = np.concatenate([rng.uniform(-200.0, 2200.0, 5000), [0.0, 2000.0, 120.0, np.nan]])
    pal = Palette(name, water_level=water)
    got = colorize(h, pal, (0.0, 2000.0), tolerance=0.5)
    monkeypatch.setattr(cmaptable, "TABLE", {})  # every map through matplotlib
    want = colorize(h, pal, (0.0, 2000.0), tolerance=0.5)
    assert got.dtype == want.dtype == np.float32
    assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.fast
def test_check_cmap_still_knows_every_matplotlib_map():
    check_cmap("magma")  # not in the table: matplotlib's
    for name in NAMES:
        check_cmap(name)
    from geoterrain.exceptions import UsageError

    with pytest.raises(UsageError, match="unknown colormap"):
        check_cmap("no-such-map")


@pytest.mark.slow  # a preprocess and a fresh process's render: 3–14 s on the shared machine
def test_a_render_with_a_table_map_and_no_overlays_imports_no_matplotlib(tmp_path):
    import geoterrain
    from geoterrain.ingest.synth import generate, write_geotiff

    src = write_geotiff(tmp_path / "d.tif", generate("fbm", 65, seed=2))
    store = geoterrain.preprocess(src, tmp_path / "d.geoterrain", tile_size=16)
    code = ("import sys; from geoterrain.cli.main import cli\n"
            f"try:\n    cli(['-q', 'render', {str(store)!r}, '-o', "
            f"{str(tmp_path / 'v.png')!r}, '--size', '96x64', '--cmap', 'gist_earth', "
            "'--no-overlays'])\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "print('MPL', 'matplotlib' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "MPL False" in out, out
