"""A render's memory follows the view, not the raster (issue 11)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core.memory import sparse_zeros


def _rss_kib() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4  # resident pages of 4 KiB


@pytest.mark.fast
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sparse_flags_commit_only_the_pages_written():
    """Writing 5 000 scattered flags of a 16385² grid commits about 5 000 pages, not
    the 2 MiB huge pages numpy's own zeros would (that was 180 MB at 16385²)."""
    before = _rss_kib()
    a = sparse_zeros((16385, 16385), np.uint8)
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, 16385, (2, 5000))
    a[i, j] = 1
    grown = _rss_kib() - before
    assert a.sum() == len(set(zip(i.tolist(), j.tolist(), strict=True)))
    assert grown < 5000 * 4 * 2, f"{grown} KiB committed for 5 000 flags"
    del a


# the render process's own peak: VmHWM, not ru_maxrss (which survives exec, so it would
# report this test runner's peak after the preprocess)
_RENDER = (
    "import json, sys\n"
    "from geoterrain.cli.main import cli\n"
    "from geoterrain.core.memory import peak_rss\n"
    "cli(sys.argv[1:], prog_name='geoterrain', standalone_mode=False)\n"
    "print(json.dumps({'peak_bytes': peak_rss()}))\n"
)


@pytest.mark.slow
def test_a_16385_render_peaks_under_one_gigabyte(tmp_path):
    """Synthesise and preprocess a 16385² DEM (about 2 min and 14 GB here), then render
    it at 1280×720 and τ = 1 from an overview and from two low views: each whole process
    peaks under 1 GB (10⁹ bytes)."""
    gt = [sys.executable, "-m", "geoterrain.cli.main"]
    tif, store = tmp_path / "big.tif", tmp_path / "big.geoterrain"
    subprocess.run([*gt, "synth", "fbm", "--size", "16385", "--seed", "3", "-o", str(tif)],
                   check=True, capture_output=True)
    subprocess.run([*gt, "-q", "preprocess", str(tif), "-o", str(store)], check=True,
                   capture_output=True)
    tif.unlink()
    for k, view in enumerate([[], ["--elevation", "12", "--distance", "20000"],
                              ["--elevation", "5", "--distance", "4000"]]):
        png, stats = tmp_path / f"v{k}.png", tmp_path / f"v{k}.json"
        r = subprocess.run([sys.executable, "-c", _RENDER, "render", str(store), "-o", str(png),
                            "--size", "1280x720", "--pixel-error", "1", "--stats", str(stats),
                            *view], check=True, capture_output=True, text=True)
        peak = json.loads(r.stdout.strip().splitlines()[-1])["peak_bytes"]
        s = json.loads(stats.read_text())
        print(f"view {k} {view}: peak {peak / 1e6:.0f} MB, {s['triangles']} triangles")
        assert s["triangles"] > 0 and s["terrain_fraction"] > 0.3, s
        assert peak < 1e9, f"view {view}: the render peaked at {peak / 1e6:.0f} MB"


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 40_000), st.booleans()), min_size=1, max_size=30))
def test_zero_pool_never_hands_out_memory_in_use(ops):
    """The atlas pool: every array it hands out is zeroed, and never shares memory with
    an array (or a view of one, or a VTK array sharing one) that is still alive."""
    from vtkmodules.util.numpy_support import numpy_to_vtk

    from geoterrain.core.memory import ZeroPool

    pool = ZeroPool(keep=2, largest=30_000)
    alive: list = []
    for size, keep in ops:
        a = pool.zeros((size, 3), np.uint8)
        assert a.shape == (size, 3) and not a.any()
        assert not any(np.shares_memory(a, b) for b, _ in alive)
        a[:] = 7  # written, as an atlas is
        if keep:  # still shown: through a VTK array sharing a view of it
            alive.append((a.reshape(-1), numpy_to_vtk(a.reshape(-1, 3), deep=False)))
            del a
        if len(alive) > 3:
            alive.pop(0)
    assert len(pool) <= 5  # the arrays alive at an allocation (3 kept, the last), a new one
