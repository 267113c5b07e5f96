"""The greedy TIN (lod/tin.py): its bound is exact on the samples, it covers the data, it
is a valid triangulation, and it is exposed through `lod.static` and the CLI.

Errors are measured by geoterrain.testing.measure (barycentric, over the valid samples),
which never imports the mesher.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoterrain.ingest.synth import generate
from geoterrain.lod.tin import greedy_mesh
from geoterrain.testing.measure import vertical_error

pytestmark = pytest.mark.fast


def _signed_areas(ij: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = ij[faces].astype(np.float64)
    x, y = p[..., 1], -p[..., 0]  # seen from above: x = column, y = −row
    return 0.5 * ((x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0])
                  - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0]))


def _dem(h: int, w: int, seed: int, relief: float) -> np.ndarray:
    return generate("fbm", (h, w), seed=seed, relief=relief).astype(np.float64)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(2, 40), w=st.integers(2, 40), seed=st.integers(0, 10_000),
       e=st.sampled_from([0.0, 0.1, 1.0, 7.5, 40.0, 1e9]),
       collapse=st.sampled_from([0.0, 0.05, 0.3, 1.0]))
def test_bound_exact_covering_and_a_valid_triangulation(h, w, seed, e, collapse):
    z = _dem(h, w, seed, 100.0)
    ij, f = greedy_mesh(z, None, e, collapse)
    valid = np.ones_like(z, bool)
    err = vertical_error(ij, f, z[ij[:, 0], ij[:, 1]], z, valid)
    assert err.n_uncovered_valid == 0
    assert err.max <= e * (1 + 1e-12) + 1e-9, (err.max, e)  # exact but for rounding
    a = _signed_areas(ij, f)
    assert (a > 0).all()  # wound counter-clockwise, none degenerate
    # positive triangles covering the rectangle with the rectangle's area: no overlap
    assert abs(a.sum() - (h - 1) * (w - 1)) < 1e-9 * h * w
    assert len(np.unique(ij, axis=0)) == len(ij)
    # Euler on a disc: F = 2V − B − 2 (B: vertices on the rectangle's border)
    border = ((ij[:, 0] == 0) | (ij[:, 0] == h - 1) | (ij[:, 1] == 0)
              | (ij[:, 1] == w - 1)).sum()
    assert len(f) == 2 * len(ij) - border - 2


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(3, 36), w=st.integers(3, 36), seed=st.integers(0, 10_000),
       e=st.sampled_from([0.0, 1.0, 5.0, 10.0, 1e9]), holes=st.integers(1, 4),
       collapse=st.sampled_from([0.0, 0.05, 1.0]))
def test_voids_are_never_spanned_and_the_bound_holds_around_them(h, w, seed, e, holes,
                                                                  collapse):
    z = _dem(h, w, seed, 100.0)
    rng = np.random.default_rng(seed)
    valid = np.ones_like(z, bool)
    for _ in range(holes):  # rectangular voids, some on the border or a corner
        i, j = rng.integers(0, h), rng.integers(0, w)
        valid[i:i + rng.integers(1, 6), j:j + rng.integers(1, 6)] = False
    zin = np.where(valid, z, np.nan)  # the mesher must never read an invalid height
    ij, f = greedy_mesh(np.nan_to_num(zin, nan=1e6), valid, e, collapse)
    assert valid[ij[f][..., 0], ij[f][..., 1]].all()  # only triangles of valid corners
    zv = np.where(valid, z, np.nan)
    err = vertical_error(ij, f, z[ij[:, 0], ij[:, 1]], zv, valid)
    assert err.max <= e * (1 + 1e-12) + 1e-9
    # no drawn triangle covers an invalid sample
    from geoterrain.testing.measure import mesh_heights_on_grid

    _, covered = mesh_heights_on_grid(ij, f, z[ij[:, 0], ij[:, 1]], z.shape)
    assert not (covered & ~valid).any()
    # what is left uncovered lies on a void's border (a sample with an invalid
    # 8-neighbour), never inside the data
    assert not (valid & ~covered & ~_void_border(valid)).any()
    assert (_signed_areas(ij, f) > 0).all()
    # conforming: no edge is used by more than two triangles (two positive triangles on
    # one side of an edge overlap); flips across collapsed triangles once broke this
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    assert np.unique(edges, axis=0, return_counts=True)[1].max(initial=0) <= 2


def _void_border(valid: np.ndarray) -> np.ndarray:
    """Samples with an invalid sample among their 8 neighbours (the rectangle's outside
    counts as valid)."""
    h, w = valid.shape
    v = np.pad(valid, 1, constant_values=True)
    out = np.zeros_like(valid)
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            out |= ~v[di:di + h, dj:dj + w]
    return out


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), e=st.sampled_from([0.5, 2.0, 8.0]),
       share=st.sampled_from([0.01, 0.05, 0.2]))
def test_the_bounded_collapse_stops_at_its_share(seed, e, share):
    """The collapse pass with a share removes at most ⌈share·n / 2⌉ points (two triangles
    each) of the n triangles the refinement left, exactly that many where the full pass
    removes twice as many (its order differs, so it may find fewer near the full pass's
    count), keeps only points the refinement inserted, and holds the bound."""
    z = _dem(80, 90, seed, 200.0)
    valid = np.ones_like(z, bool)
    n0, n1 = (len(greedy_mesh(z, None, e, c)[1]) for c in (0.0, 1.0))
    ij, f = greedy_mesh(z, None, e, share)
    removed = int(np.ceil(share * n0 / 2))
    assert len(f) >= n0 - 2 * removed
    if 2 * removed <= (n0 - n1) / 2:
        assert len(f) == n0 - 2 * removed, (len(f), n0, removed)
    p0 = {tuple(p) for p in greedy_mesh(z, None, e, 0.0)[0].tolist()}
    assert {tuple(p) for p in ij.tolist()} <= p0
    err = vertical_error(ij, f, z[ij[:, 0], ij[:, 1]], z, valid)
    assert err.max <= e * (1 + 1e-12) and err.n_uncovered_valid == 0
    assert (_signed_areas(ij, f) > 0).all()


def test_the_arrays_grow_and_the_refinement_resumes():
    """At e = 0 on fBm every sample is a point: 2·(H − 1)·(W − 1) triangles, eight times
    the kernel's first 1 024 rows, so the refinement returns to its driver three times
    to grow them and resumes where it stopped."""
    z = _dem(60, 70, 5, 300.0)
    ij, f = greedy_mesh(z, None, 0.0)
    assert len(f) == 2 * 59 * 69 and len(ij) == 60 * 70
    assert (_signed_areas(ij, f) > 0).all()
    err = vertical_error(ij, f, z[ij[:, 0], ij[:, 1]], z, np.ones(z.shape, bool))
    assert err.max == 0.0 and err.n_uncovered_valid == 0


def test_counts_no_more_than_rtin_and_through_the_seam(tmp_path):
    """`static(t, e, "tin")`: the bound on the store's own heights, fewer triangles than
    the bintree cut, the seam's stats; a bad mesher is one UsageError."""
    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.ingest.synth import write_geotiff

    dem = write_geotiff(str(tmp_path / "d.tif"), generate("fbm", (70, 90), seed=3))
    with geoterrain.open(geoterrain.preprocess(dem, str(tmp_path / "d.geoterrain"))) as t:
        _, _, Z = t.scene_xyz()
        valid = np.isfinite(Z)
        for e in (1.0, 5.0):
            n = {}
            for m in ("tin", "tin-full"):
                sel = t.static_selection(e, mesher=m)
                f = sel.surface_faces()
                err = vertical_error(np.asarray(sel.ij), f, np.asarray(sel.mesh.points)[:, 2],
                                     Z, valid)
                assert err.max <= e * (1 + 1e-12) and err.n_uncovered_valid == 0
                assert sel.stats["mesher"] == m and sel.stats["max_error"] == e
                n[m] = sel.stats["triangles"]
                assert n[m] == len(f) < t.static_selection(e).stats["triangles"]
                assert "elevation" in sel.mesh.point_data
            assert n["tin-full"] < n["tin"]
        with pytest.raises(UsageError, match="mesher"):
            t.static_selection(1.0, mesher="delaunay")


def test_a_geographic_root_grid_meshes_as_its_square(tmp_path):
    """`mesh --mesher tin` on a wide EPSG:4326 raster with a void, on its 2 × 1 root grid
    (the default layout, issue 45): the bound is exact on the raster's own heights (read
    with rasterio), no triangle covers the void and every valid sample off its border is
    covered, the triangles are wound counter-clockwise and conforming (no edge used by
    three), both roots are meshed, each vertex sits on its sample's scene x, y, and the
    triangles are the square store's of the same raster (the TIN reads level 0 alone)."""
    import pyvista as pv
    import rasterio
    from click.testing import CliRunner

    import geoterrain
    from geoterrain.cli.main import cli
    from geoterrain.testing.measure import mesh_heights_on_grid
    from tests.conftest import write_tif

    z = _dem(70, 200, 8, 400.0).astype(np.float32)
    z[30:41, 120:151] = -9999.0
    dem = write_tif(tmp_path / "g.tif", z, crs="EPSG:4326", origin=(24.0, 61.0),
                    spacing=1 / 1200, nodata=-9999.0)
    with rasterio.open(dem) as src:
        h = src.read(1, masked=True)
    valid = ~np.ma.getmaskarray(h)
    rt = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "r.geoterrain", tile_size=32))
    sq = geoterrain.open(geoterrain.preprocess(dem, tmp_path / "s.geoterrain", tile_size=32,
                                               root_grid=False))
    assert (rt.frame.kind, rt.grid.layout, rt.grid.roots) == ("geographic", "roots", (2, 1))
    span = 1 << rt.grid.n  # a root's side in samples
    X, Y, _ = rt.scene_xyz()
    zs = rt.frame.z(h.filled(np.nan).astype(np.float64))  # the DEM's heights in the scene
    for e in (0.5, 4.0):
        sel = rt.static_selection(e, mesher="tin")
        ij, f = np.asarray(sel.ij, np.int64), sel.surface_faces()
        pts = np.asarray(sel.mesh.points)
        err = vertical_error(ij, f, pts[:, 2], np.where(valid, zs, np.nan), valid)
        assert err.max <= e * (1 + 1e-12) + 1e-9, (err.max, e)
        assert valid[ij[:, 0], ij[:, 1]].all()  # no vertex on a void
        # no triangle covers the void; what is left uncovered lies on the void's border
        _, covered = mesh_heights_on_grid(ij, f, pts[:, 2], valid.shape)
        assert not (covered & ~valid).any()
        assert not (valid & ~covered & ~_void_border(valid)).any()
        assert (_signed_areas(ij, f) > 0).all()
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        assert np.unique(edges, axis=0, return_counts=True)[1].max() <= 2
        assert (ij[:, 1] > span).any() and (ij[:, 1] < span).any()  # both roots
        assert np.allclose(pts[:, 0], X[ij[:, 0], ij[:, 1]], rtol=0, atol=1e-6)
        assert np.allclose(pts[:, 1], Y[ij[:, 0], ij[:, 1]], rtol=0, atol=1e-6)
        other = sq.static_selection(e, mesher="tin")
        assert np.array_equal(np.asarray(other.ij), np.asarray(sel.ij))
        assert np.array_equal(other.surface_faces(), f)
    out = tmp_path / "tin.ply"
    res = CliRunner().invoke(cli, ["mesh", str(rt.path), "-o", str(out), "--max-error", "4",
                                   "--mesher", "tin", "--json"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    assert pv.read(out).n_cells == sel.stats["triangles"] == len(f)
