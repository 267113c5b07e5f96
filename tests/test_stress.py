"""Numerical-stability stress suite: hostile DEMs and cameras through the whole pipeline.

preprocess → select (every strategy) → measure (→ render, for a few cheap cases), asserting:

- no NaN/inf in any output (mesh points, stats, scene positions of valid samples);
- measured error ≤ τ (screen space, for the strategies registered as bounded) or ≤ E
  (static), with 1e-9 relative slack plus the float64 round-off of the heights and
  positions;
- the conforming strategies' meshes are conforming (every edge used at most twice, no
  T-junction);
- the height codec stays within ε with ``max_error``;
- no exception other than a documented input error (``geoterrain.exceptions``).

The quick part runs by default (marker ``stress``); heavy cases are also marked ``slow``
and run with ``pytest -m stress`` (which overrides the default ``-m 'not slow'``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import geoterrain
from conftest import real_dem, write_tif
from geoterrain.bench.harness import flight
from geoterrain.core.view import View
from geoterrain.exceptions import InputError
from geoterrain.lod import STRATEGIES, strategy_info
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    mesh_heights_on_grid,
    screen_space_error,
    vertical_error,
)

pytestmark = pytest.mark.stress

TAUS = (1.0, 4.0)
STATIC_E = (0.0, 0.5, 5.0)
EPS64 = np.finfo(np.float64).eps
REL = 1e-9


# ---------------------------------------------------------------- helpers
def fbm(n: int, m: int | None = None, seed: int = 0, amp: float = 500.0) -> np.ndarray:
    from geoterrain.ingest.synth import generate

    z = generate("fbm", (n, m or n), seed=seed)
    z = z - z.min()
    return amp * z / max(float(z.max()), 1e-12)


def build(tmp_path, z, name="dem", pre=None, **tif):
    """Write a GeoTIFF, preprocess it and open the store."""
    tif.setdefault("dtype", "float64" if np.asarray(z).dtype == np.float64 else None)
    src = write_tif(tmp_path / f"{name}.tif", z, **tif)
    store = geoterrain.preprocess(src, tmp_path / f"{name}.geoterrain", **(pre or {}))
    return geoterrain.open(store)


def z_roundoff(Z: np.ndarray) -> float:
    """A bound on float64 round-off of heights interpolated on a triangle."""
    m = float(np.nanmax(np.abs(Z))) if np.isfinite(Z).any() else 0.0
    return 16 * EPS64 * max(m, 1.0)


def check_finite_stats(stats: dict) -> None:
    for k, v in stats.items():
        if isinstance(v, (int, float, np.number)) and not isinstance(v, bool):
            assert math.isfinite(float(v)), f"stat {k} = {v}"


def mesh_parts(sel):
    pts = np.asarray(sel.mesh.points, np.float64)
    faces = sel.surface_faces()
    ij = sel.ij
    assert np.isfinite(pts).all(), "non-finite mesh points"
    vz = pts[:, 2] if len(pts) else np.zeros(0)
    return ij, faces, vz


def check_conforming(t, ij, faces, vz) -> None:
    """Every edge used by at most two triangles; no crack or T-junction (height spread)."""
    if len(faces) == 0:
        return
    N = max(t.grid.extent)  # a stride above every row and column (a root grid's too)
    key = (np.asarray(ij[:, 0], np.int64) * N + np.asarray(ij[:, 1], np.int64))[faces]
    e = np.concatenate([key[:, [0, 1]], key[:, [1, 2]], key[:, [2, 0]]])
    e.sort(axis=1)
    _, counts = np.unique(e[:, 0] * (N * N) + e[:, 1], return_counts=True)
    assert counts.max() <= 2, f"an edge is used by {counts.max()} triangles"
    H, W = t.grid.rows, t.grid.cols
    zlo, zhi = mesh_height_range_on_grid(ij, faces, vz, (H, W))
    spread = np.nan_to_num(zhi - zlo)
    assert spread.max() <= z_roundoff(vz), f"crack/T-junction: height spread {spread.max()}"


def check_static(t, Es=STATIC_E, mesher="rtin", conforming=True) -> None:
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    for E in Es:
        sel = t.static_selection(E, mesher=mesher)
        check_finite_stats(sel.stats)
        ij, faces, vz = mesh_parts(sel)
        err = vertical_error(ij, faces, vz, Zt, valid)
        assert math.isfinite(err.max)
        assert err.max <= E * (1 + REL) + z_roundoff(Z), f"static {mesher} E={E}: {err.max}"
        if mesher == "tin" and valid.all():  # it covers the raster's rectangle
            assert err.n_uncovered_valid == 0, f"static tin E={E}: holes"
        if conforming:
            check_conforming(t, ij, faces, vz)


def check_view(t, view: View, strategies=None, taus=TAUS, conforming=True) -> None:
    strategies = STRATEGIES if strategies is None else strategies
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    assert np.isfinite(X).all() and np.isfinite(Y).all()
    Zt = np.where(valid, Z, 0.0)
    # round-off allowance in pixels: height round-off seen from the nearest sample in view
    inside = valid & ((np.stack([X, Y, Zt], -1) @ view.planes[:, :3].T + view.planes[:, 3])
                      >= 0).all(-1)
    d = np.sqrt((X - view.eye[0]) ** 2 + (Y - view.eye[1]) ** 2 + (Zt - view.eye[2]) ** 2)
    dmin = float(d[inside].min()) if inside.any() else 1.0
    slack_px = view.lam * z_roundoff(Z) / max(dmin, 1e-300)
    runs = [(s, tau, m) for s in strategies for tau in taus
            for m in ((False, True) if strategy_info(s).morphs else (None,))]
    for strategy, tau, morph in runs:
        # ρ ≤ τ at every sample in the frustum: no horizon culling here (with it, at
        # the visible samples: tests/lod/test_occlusion.py); morphing off and on
        sel = t.select(view, pixel_error=tau, strategy=strategy, occlusion=False,
                       morph=morph)
        check_finite_stats(sel.stats)
        ij, faces, vz = mesh_parts(sel)
        e = screen_space_error(ij, faces, vz, X, Y, Zt, valid, view.eye, view.planes,
                               view.lam)
        assert math.isfinite(e.max), f"{strategy} τ={tau} morph={morph}: error {e.max}"
        info = strategy_info(strategy)
        assert not info.bounded or e.max <= tau * (1 + REL) + slack_px, (
            f"{strategy} τ={tau} morph={morph}: measured {e.max} px > τ (view {view})")
        if e.n_uncovered:
            check_holes(view, tau, ij, faces, vz, X, Y, Zt, valid, strategy)
        if info.conforming and conforming:
            check_conforming(t, ij, faces, vz)


def check_holes(view, tau, ij, faces, vz, X, Y, Z, valid, strategy) -> None:
    """Valid samples in the frustum that no triangle covers must be explained: next to
    nodata (triangles need three valid corners) or within τ pixels of the frustum's border
    (a triangle entirely outside one plane is culled, and the surface is ≤ τ px away)."""
    _, covered = mesh_heights_on_grid(ij, faces, vz, Z.shape)
    P = np.stack([X, Y, Z], -1)
    dpl = P @ view.planes[:, :3].T + view.planes[:, 3]
    hole = (dpl >= 0).all(-1) & valid & ~covered
    pad = np.pad(~valid, 1, constant_values=True)
    H, W = Z.shape
    near_nodata = np.zeros_like(valid)
    for di in range(3):
        for dj in range(3):
            near_nodata |= pad[di:di + H, dj:dj + W]
    hole &= ~near_nodata
    if not hole.any():
        return
    r, u, f = view.basis()
    q = P[hole] - view.eye
    depth = q @ f
    dist = np.linalg.norm(q, axis=1)
    w, h = view.size
    x = w / 2 + view.lam * (q @ r) / depth
    y = h / 2 - view.lam * (q @ u) / depth
    border = np.minimum(np.minimum(x, w - x), np.minimum(y, h - y))
    allow = tau * (dist / depth) ** 2 * (1 + 1e-6) + 1e-6  # LP's ρ is exact on the axis
    zband = tau * dist / view.lam * (1 + 1e-6)  # the near / far plane
    ok = (border <= allow) | (dpl[hole][:, 4] <= zband) | (dpl[hole][:, 5] <= zband)
    assert ok.all(), (f"{strategy} τ={tau}: {int((~ok).sum())} valid samples in view are "
                      f"not drawn, {float(border[~ok].min()):.3g} px inside the image")


def views_for(t, n: int = 4) -> list[View]:
    X, Y, Z = t.scene_xyz()
    ok = np.isfinite(Z)
    lo = np.array([X[ok].min(), Y[ok].min(), Z[ok].min()])
    hi = np.array([X[ok].max(), Y[ok].max(), Z[ok].max()])
    return [v for _, v in flight(lo, hi, n_views=n, size=(640, 360))]


def full_check(t, n_views: int = 4, Es=STATIC_E) -> None:
    check_static(t, Es)
    for v in views_for(t, n_views):
        check_view(t, v)


# ---------------------------------------------------------------- offsets and spacing
OFFSETS = {
    "utm": dict(origin=(500000.0, 5000000.0)),
    "ecef_scale": dict(crs="EPSG:3857", origin=(6.4e6, 6.4e6)),
    "negative_ecef": dict(crs="EPSG:3857", origin=(-6.4e6, -6.4e6)),
}


@pytest.mark.parametrize("name", sorted(OFFSETS))
def test_large_offsets(tmp_path, name):
    t = build(tmp_path, fbm(65), **OFFSETS[name])
    X, Y, _ = t.scene_xyz()
    assert abs(X).max() < 1e4 and abs(Y).max() < 1e4  # the scene origin is the raster centre
    full_check(t)


def test_ecef_scale_heights(tmp_path):
    """Heights of 6.4e6 m (geocentric radius): an absurd-height input error unless the user
    confirms them with z_scale, and then the pipeline must hold at that magnitude."""
    z = 6.4e6 + fbm(65)
    with pytest.raises(InputError, match="z_scale"):
        build(tmp_path, z, name="refused")
    full_check(build(tmp_path, z, pre={"z_scale": 1.0}), Es=(0.0, 0.5, 5.0))


def test_everest_heights_with_centimetre_noise(tmp_path):
    rng = np.random.default_rng(0)
    z = 8848.0 + 0.01 * rng.standard_normal((65, 65))
    full_check(build(tmp_path, z), Es=(0.0, 0.005, 0.02))


@pytest.mark.parametrize("spacing", [0.01, 1000.0, (1.0, 100.0), (100.0, 1.0)],
                         ids=["1cm", "1km", "aniso_1_100", "aniso_100_1"])
def test_spacing(tmp_path, spacing):
    from geoterrain.ingest.synth import write_geotiff

    z = fbm(65, amp=50.0 if spacing == 0.01 else 500.0)
    src = write_geotiff(tmp_path / "s.tif", z, spacing=spacing)
    t = geoterrain.open(geoterrain.preprocess(src, tmp_path / "s.geoterrain"))
    full_check(t)


# ---------------------------------------------------------------- hostile shapes of terrain
def _hostile(name: str, n: int = 65) -> np.ndarray:
    i, j = np.mgrid[0:n, 0:n].astype(np.float64)
    rng = np.random.default_rng(7)
    if name == "spike":
        z = np.zeros((n, n))
        z[n // 2, n // 2 + 1] = 5000.0
    elif name == "cliff":
        z = np.where(j > n / 2 + 0.3, 1000.0, 0.0)
    elif name == "white_noise":
        z = 100.0 * rng.standard_normal((n, n))
    elif name == "constant":
        z = np.full((n, n), 42.0)
    elif name == "tilt_89deg":
        z = np.tan(np.radians(89.0)) * j * 1.0  # 1 m spacing: ~3.7 km over 65 samples
    else:
        raise KeyError(name)
    return z


@pytest.mark.parametrize("name", ["spike", "cliff", "white_noise", "constant", "tilt_89deg"])
def test_hostile_relief(tmp_path, name):
    spacing = 1.0 if name == "tilt_89deg" else 10.0
    full_check(build(tmp_path, _hostile(name), spacing=spacing))


# ---------------------------------------------------------------- nodata
def _nodata_case(name: str, n: int = 65) -> tuple[np.ndarray, float | None]:
    z = fbm(n).astype(np.float32)
    i, j = np.mgrid[0:n, 0:n]
    if name == "checkerboard":
        hole = ((i // 4) + (j // 4)) % 2 == 1
    elif name == "checkerboard_1px":
        hole = (i + j) % 2 == 1
    elif name == "one_sample_strip":
        hole = j != n // 3
    elif name == "two_sample_strip":
        hole = (j != n // 3) & (j != n // 3 + 1)
    elif name == "border":
        hole = (i < 3) | (i >= n - 3) | (j < 3) | (j >= n - 3)
    elif name == "nan_inside":
        z[20:30, 10:40] = np.nan
        return z, None
    else:
        raise KeyError(name)
    z[hole] = -9999.0
    return z, -9999.0


@pytest.mark.parametrize("name", ["checkerboard", "checkerboard_1px", "one_sample_strip",
                                  "two_sample_strip", "border", "nan_inside"])
def test_nodata_patterns(tmp_path, name):
    z, nodata = _nodata_case(name)
    t = build(tmp_path, z, nodata=nodata, dtype="float32")
    full_check(t)
    # invalid samples are never drawn: every mesh vertex is a valid sample
    X, Y, Z = t.scene_xyz()
    for strategy in STRATEGIES:
        sel = t.select(views_for(t, 1)[0], 1.0, strategy)
        ij = sel.ij.astype(np.int64)
        if len(ij):
            assert np.isfinite(Z[ij[:, 0], ij[:, 1]]).all()


@pytest.mark.fast
def test_spike_among_nodata_seen_from_its_top(tmp_path):
    """Regression: a visible valid spike whose surrounding diamonds are mixed (nodata
    nearby) and whose neighbours' spheres are all outside the view was left undrawn by
    rtin (every triangle around it was skipped as an unrefined mixed diamond)."""
    z = np.zeros((17, 33), np.float32)
    z[8, 16] = 3000.0
    for ij in [(8, 14), (6, 17), (7, 18), (10, 13)]:
        z[ij] = -9999.0
    t = build(tmp_path, z, nodata=-9999.0, dtype="float32")
    X, Y, Z = t.scene_xyz()
    top = np.array([X[8, 16], Y[8, 16], 3000.0])
    view = View(tuple(top + [0.5, 1.5, 0.003]), tuple(top + [-1.0, -2.8, 0.0]),
                size=(320, 180))
    check_view(t, view, taus=(1.0,))
    sel = t.select(view, 1.0, "rtin")
    assert [8, 16] in sel.ij.astype(int).tolist()


@pytest.mark.fast
def test_all_nodata_is_a_clear_input_error(tmp_path):
    z = np.full((9, 9), -9999.0, np.float32)
    with pytest.raises(InputError, match="nodata"):
        build(tmp_path, z, nodata=-9999.0, dtype="float32")


# ---------------------------------------------------------------- shapes and dtypes
@pytest.mark.parametrize("shape", [(2, 2), (3, 3), (2, 1000), (1000, 2), (2, 3), (5, 2)],
                         ids=lambda s: f"{s[0]}x{s[1]}")
def test_degenerate_shapes(tmp_path, shape):
    rng = np.random.default_rng(1)
    z = 100.0 * rng.random(shape)
    full_check(build(tmp_path, z), n_views=4)


@pytest.mark.fast
@pytest.mark.parametrize("shape", [(1, 5), (5, 1), (1, 1)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_too_small_is_a_clear_input_error(tmp_path, shape):
    with pytest.raises(InputError, match="at least 2×2"):
        build(tmp_path, np.ones(shape))


@pytest.mark.parametrize("shape", [(4097, 3), (3, 4097)], ids=["4097x3", "3x4097"])
@pytest.mark.slow
def test_long_thin_grids(tmp_path, shape):
    rng = np.random.default_rng(2)
    z = np.cumsum(rng.standard_normal(shape), axis=0 if shape[0] > shape[1] else 1)
    t = build(tmp_path, z)
    check_static(t, Es=(0.0, 1.0))
    for v in views_for(t, 4):
        check_view(t, v, taus=(1.0,))


DTYPES = {"int16": (-500, 3000), "uint16": (0, 60000), "int32": (-90000, 90000),
          "float32": (-400.25, 8848.5), "float64": (-400.125, 8848.0625)}


@pytest.mark.parametrize("dtype", sorted(DTYPES))
def test_dtypes(tmp_path, dtype):
    lo, hi = DTYPES[dtype]
    z = lo + (hi - lo) * fbm(65, amp=1.0)
    if dtype.startswith(("int", "uint")):
        z = np.rint(z)
    pre = {"z_scale": 1.0} if max(abs(lo), abs(hi)) > 1e5 else None
    t = build(tmp_path, z.astype(dtype), dtype=dtype, pre=pre)
    # lossless: the stored heights are exactly the source's
    h, v = t.level_heights(0)
    np.testing.assert_array_equal(h[:65, :65], z.astype(dtype).astype(np.float64))
    full_check(t)


@pytest.mark.parametrize("eps", [0.01, 0.5, 3.0])
def test_codec_within_max_error(tmp_path, eps):
    z = fbm(129, amp=2000.0) + 8000.0
    t = build(tmp_path, z, pre={"codec_error": eps})
    h, v = t.level_heights(0)
    d = np.abs(h[:129, :129] - z)
    assert d.max() <= eps * (1 + REL) + z_roundoff(z), d.max()
    full_check(t, n_views=2)


def test_float32_vs_float64(tmp_path):
    """The same heights (exact in float32) stored as float32 and float64 give the same LOD:
    the heights, hence every float64 stage, are bit-identical; δ is stored in float32 in
    both stores, so meshes may only differ where δ is within float32 ε of a threshold."""
    z32 = (fbm(129) + 1234.5).astype(np.float32)
    t32 = build(tmp_path, z32, name="f32", dtype="float32")
    t64 = build(tmp_path, z32.astype(np.float64), name="f64", dtype="float64")
    X32, Y32, Z32 = t32.scene_xyz()
    X64, Y64, Z64 = t64.scene_xyz()
    np.testing.assert_array_equal(Z32, Z64)
    np.testing.assert_array_equal(X32, X64)
    tol = np.finfo(np.float32).eps * float(np.abs(Z64).max())
    for E in (0.0, 0.25, 2.0, 10.0):
        a = {tuple(p) for p in t32.static_selection(E).ij.astype(int).tolist()}
        b = {tuple(p) for p in t64.static_selection(E).ij.astype(int).tolist()}
        diff = np.array(sorted(a ^ b), np.int64).reshape(-1, 2)
        if len(diff):
            d = t64.gather(diff[:, 0], diff[:, 1], ("delta",))["delta"]
            assert np.all(np.abs(d - E) <= tol), f"E={E}: meshes differ away from threshold"
    for v in views_for(t64, 2):
        for strategy in STRATEGIES:
            m32 = t32.select(v, 1.0, strategy).mesh
            m64 = t64.select(v, 1.0, strategy).mesh
            assert m32.n_points == m64.n_points and m32.n_cells == m64.n_cells
            np.testing.assert_array_equal(np.asarray(m32.points), np.asarray(m64.points))


# ---------------------------------------------------------------- geographic grids
GEOGRAPHIC = {
    "pole_89N": dict(origin=(10.0, 89.5), spacing=0.005),
    "pole_89S": dict(origin=(10.0, -89.0), spacing=0.005),
    "antimeridian": dict(origin=(179.85, 10.0), spacing=0.005),
    "equator": dict(origin=(-0.15, 0.15), spacing=0.005),
}


@pytest.mark.parametrize("name", sorted(GEOGRAPHIC))
def test_geographic(tmp_path, name):
    t = build(tmp_path, fbm(65), crs="EPSG:4326", **GEOGRAPHIC[name])
    X, Y, Z = t.scene_xyz()
    assert np.isfinite(X).all() and np.isfinite(Y).all()
    # the metric extent is sane (no wrap-around jump at ±180°, no blow-up at the pole)
    dx = np.diff(X, axis=1)
    dy = np.diff(Y, axis=0)
    assert np.abs(dx).max() < 1e4 and np.abs(dy).max() < 1e4
    full_check(t)


# ---------------------------------------------------------------- camera extremes
@pytest.fixture(scope="module")
def fbm_terrain(tmp_path_factory):
    d = tmp_path_factory.mktemp("cam")
    return build(d, fbm(129, seed=5), origin=(500000.0, 5000000.0))


def _camera_extremes(t) -> dict[str, View]:
    X, Y, Z = t.scene_xyz()
    zmin, zmax = float(np.nanmin(Z)), float(np.nanmax(Z))
    zc = float(Z[64, 64])
    half = float(X.max() - X.min()) / 2
    zmid = 0.5 * (zmin + zmax)
    return {
        "eye_inside_terrain": View((0, 0, zc - 50.0), (half, 0, zc - 50.0), size=(320, 180)),
        "eye_below_looking_up": View((0, 0, zmin - 100), (0, 10, zmax), size=(320, 180)),
        "eye_1e7m_down": View((0, 1.0, 1e7), (0, 0, 0), size=(320, 180)),
        "eye_1e7m_side": View((1e7, 0, zmax), (0, 0, zmid), size=(320, 180)),
        "near_1e-3": View((-half, -half, zmax + 10), (0, 0, zmid), size=(320, 180),
                          near=1e-3, far=1e7),
        "fov_1": View((-half, -half, zmax + 10), (0, 0, zmid), fov_y_deg=1.0, size=(320, 180)),
        "fov_170": View((0, -half / 4, zmax + 10), (0, 0, zmid), fov_y_deg=170.0,
                        size=(320, 180)),
        "straight_down": View((0, 0, zmax + 500), (0, 0, zmin), size=(320, 180)),
        "straight_down_up_x": View((0, 0, zmax + 500), (0, 0, zmin), up=(1, 0, 0),
                                   size=(320, 180)),
        "along_horizon": View((-2 * half, 0, zmid), (2 * half, 0, zmid), size=(320, 180)),
        "horizon_at_eye_height": View((0, -half, zmax + 0.001), (0, half, zmax + 0.001),
                                      size=(320, 180)),
    }


CAMERAS = ["eye_inside_terrain", "eye_below_looking_up", "eye_1e7m_down", "eye_1e7m_side",
           "near_1e-3", "fov_1", "fov_170", "straight_down", "straight_down_up_x",
           "along_horizon", "horizon_at_eye_height"]


@pytest.mark.parametrize("cam", CAMERAS)
def test_camera_extremes(fbm_terrain, cam):
    check_view(fbm_terrain, _camera_extremes(fbm_terrain)[cam], taus=(0.5, 1.0, 8.0))


@pytest.mark.fast
def test_degenerate_camera_is_a_clear_error():
    with pytest.raises(ValueError):
        View((0, 0, 0), (0, 0, 0)).basis()
    with pytest.raises(ValueError):
        View((0, 0, 0), (1, 0, 0), fov_y_deg=180.0)


# ---------------------------------------------------------------- render (cheap cases)
def _render(t, view):
    render = pytest.importorskip("geoterrain.rendering.scene")
    img, stats = render.render_array(t, view, pixel_error=1.0)
    assert img.shape == (view.size[1], view.size[0], 3)
    check_finite_stats(stats)
    return img


@pytest.mark.fast
@pytest.mark.parametrize("name", ["spike", "cliff", "constant"])
def test_render_hostile(tmp_path, name):
    t = build(tmp_path, _hostile(name, 33))
    X, Y, Z = t.scene_xyz()
    zmax = float(np.nanmax(Z))
    _render(t, View((0, -2000, zmax + 2000), (0, 0, 0), size=(160, 120)))


@pytest.mark.fast
def test_render_empty_selection(tmp_path):
    """Regression: an empty LOD mesh (terrain behind the camera) used to make the first
    frame raise PyVista's 'Empty meshes cannot be plotted'; it renders the background."""
    t = build(tmp_path, fbm(33))
    X, Y, Z = t.scene_xyz()
    zmax = float(np.nanmax(Z))
    away = View((0, -500, zmax + 10), (0, -1000, zmax + 10), size=(160, 120))
    assert t.select(away, 1.0, "rtin").mesh.n_points == 0
    _render(t, away)


# ---------------------------------------------------------------- real DEMs
@pytest.mark.parametrize("name", ["srtm3_pysheds.tif", "roi_epsg3089.tif", "terrarium.png"])
def test_real_dems(tmp_path, name):
    store = geoterrain.preprocess(real_dem(name), tmp_path / "r.geoterrain")
    full_check(geoterrain.open(store), n_views=2, Es=(0.0, 1.0))


@pytest.mark.parametrize("name", ["srtm1_japan.tif", "fuji_terrain_rgb.png"])
@pytest.mark.slow
def test_real_dems_large(tmp_path, name):
    store = geoterrain.preprocess(real_dem(name), tmp_path / "r.geoterrain")
    full_check(geoterrain.open(store), n_views=4, Es=(0.0, 1.0, 10.0))


# ---------------------------------------------------------------- heavy cases
@pytest.mark.parametrize("name", ["spike", "cliff", "white_noise", "tilt_89deg"])
@pytest.mark.slow
def test_hostile_relief_large(tmp_path, name):
    spacing = 1.0 if name == "tilt_89deg" else 10.0
    z = _hostile(name, 513)
    if name == "tilt_89deg":
        z = z / 8.0  # stay below the absurd-height guard (1e5 m) at 513 samples
    t = build(tmp_path, z, spacing=spacing)
    check_static(t, Es=(0.0, 1.0))
    for v in views_for(t, 4):
        check_view(t, v, taus=(1.0,))


@pytest.mark.parametrize("name", sorted(GEOGRAPHIC))
@pytest.mark.slow
def test_geographic_large(tmp_path, name):
    g = dict(GEOGRAPHIC[name])
    g["spacing"] = 0.001
    t = build(tmp_path, fbm(513, seed=3), crs="EPSG:4326", **g)
    check_static(t, Es=(0.0, 2.0))
    for v in views_for(t, 4):
        check_view(t, v, taus=(1.0,))


@pytest.mark.parametrize("name", ["checkerboard", "checkerboard_1px", "border", "nan_inside"])
@pytest.mark.slow
def test_nodata_large(tmp_path, name):
    z, nodata = _nodata_case(name, 513)
    t = build(tmp_path, z, nodata=nodata, dtype="float32")
    check_static(t, Es=(0.0, 1.0))
    for v in views_for(t, 4):
        check_view(t, v, taus=(1.0,))


@pytest.fixture(scope="module")
def fbm_terrain_large(tmp_path_factory):
    d = tmp_path_factory.mktemp("camL")
    return build(d, fbm(1025, seed=9, amp=2000.0), origin=(500000.0, 5000000.0))


@pytest.mark.parametrize("cam", CAMERAS)
@pytest.mark.slow
def test_camera_extremes_large(fbm_terrain_large, cam):
    t = fbm_terrain_large
    Z = t.scene_xyz()[2]
    v = _camera_extremes(t)[cam]
    if cam == "eye_inside_terrain":
        zc = float(Z[512, 512]) - 50.0
        v = View((0, 0, zc), (1000.0, 0, zc), size=(320, 180))
    check_view(t, v, taus=(1.0,))


# ---------------------------------------------------------------- root grids (issue 45)
ROOT_GRIDS = {"2x1": (65, 129, 16), "1x2": (129, 65, 16), "2x1_lattice_short": (50, 121, 8),
              "2x1_one_level": (65, 129, 64), "1x1_lattice_short": (50, 60, 8)}


@pytest.mark.parametrize("name", sorted(ROOT_GRIDS))
def test_root_grid(tmp_path, name):
    """The stress checks on a store of 2 × 1 (or 1 × 2) root tiles, or one root over
    fewer tiles than the square's (jacksboro's case), every strategy."""
    rows, cols, ts = ROOT_GRIDS[name]
    t = build(tmp_path, fbm(rows, cols, seed=11), pre={"root_grid": True, "tile_size": ts})
    assert t.grid.layout == "roots" and t.grid.roots == tuple(map(int, name[:3].split("x")))
    full_check(t)
    check_static(t, mesher="tin")  # the greedy TIN of the raster's rectangle


@pytest.mark.fast
def test_root_grid_quick(tmp_path):
    t = build(tmp_path, fbm(33, 65, seed=12), pre={"root_grid": True, "tile_size": 8})
    assert t.grid.roots == (2, 1)
    full_check(t, n_views=2, Es=(0.0, 5.0))
    check_static(t, Es=(0.0, 5.0), mesher="tin")


@pytest.mark.parametrize("name", ["checkerboard", "border", "nan_inside"])
def test_root_grid_nodata(tmp_path, name):
    z, nodata = _nodata_case(name)
    z = np.concatenate([z, z[:, 1:]], axis=1)  # 65 × 129: 2 × 1 roots of 16-sample tiles
    t = build(tmp_path, z, nodata=nodata, dtype="float32",
              pre={"root_grid": True, "tile_size": 16})
    assert t.grid.roots == (2, 1)
    full_check(t)
    # the TIN's bound and conformity around voids (the flips along voids once crossed
    # triangles the collapse pass had removed, folding two triangles over one edge)
    check_static(t, Es=(0.0, 5.0), mesher="tin")
    check_static(t, Es=(5.0,), mesher="tin-full")


@pytest.mark.parametrize("cam", CAMERAS)
def test_root_grid_camera_extremes(tmp_path, cam):
    t = build(tmp_path, fbm(129, 257, seed=5), origin=(500000.0, 5000000.0),
              pre={"root_grid": True, "tile_size": 16})
    check_view(t, _camera_extremes(t)[cam], taus=(0.5, 1.0, 8.0))


#: Geographic (EPSG:4326) root grids: 2 × 1 and 1 × 2 roots, at high latitude, across the
#: antimeridian, with voids, and a lattice short of the extent both ways.
GEOGRAPHIC_ROOT_GRIDS = {
    "2x1_60N_voids": dict(shape=(65, 129, 16), origin=(10.0, 61.0), spacing=0.005,
                          voids=True),
    "1x2_equator": dict(shape=(129, 65, 16), origin=(-0.15, 0.3), spacing=0.005),
    "2x1_lattice_short_80N": dict(shape=(50, 121, 8), origin=(100.0, 80.3), spacing=0.005),
    "2x1_antimeridian_45S": dict(shape=(65, 129, 16), origin=(179.7, -45.0), spacing=0.005,
                                 voids=True),
}


def _geographic_root_grid(tmp_path, name):
    g = GEOGRAPHIC_ROOT_GRIDS[name]
    rows, cols, ts = g["shape"]
    z = fbm(rows, cols, seed=13).astype(np.float32)
    nodata = None
    if g.get("voids"):
        z[20:27, 40:52] = -9999.0  # a void inside the west root
        z[:5, cols - 9:] = -9999.0  # and one on the data's north-east corner
        nodata = -9999.0
    t = build(tmp_path, z, crs="EPSG:4326", origin=g["origin"], spacing=g["spacing"],
              nodata=nodata, dtype="float32", pre={"root_grid": True, "tile_size": ts})
    assert t.grid.layout == "roots" and t.frame.kind == "geographic"
    assert t.grid.roots == tuple(map(int, name[:3].split("x")))
    return t


@pytest.mark.parametrize("name", sorted(GEOGRAPHIC_ROOT_GRIDS))
def test_geographic_root_grid(tmp_path, name):
    """The stress checks on geographic root grids (issue 45): every strategy, morphing
    off and on, ρ ≤ τ at every sample (measured in the scene's curvilinear x, y); rtin's
    static mesh within E and conforming."""
    t = _geographic_root_grid(tmp_path, name)
    full_check(t, n_views=3)


@pytest.mark.fast
def test_geographic_root_grid_quick(tmp_path):
    """The fast tier's geographic root grid: 33 × 65 at 70° N with a void on 2 × 1 roots,
    every strategy in one view at τ = 1 px (morphing off and on),
    rtin's static mesh at E = 5 (the four cases above: more views, τ and E)."""
    z = fbm(33, 65, seed=14).astype(np.float32)
    z[10:14, 40:47] = -9999.0
    t = build(tmp_path, z, crs="EPSG:4326", origin=(20.0, 70.2), spacing=0.004,
              nodata=-9999.0, dtype="float32", pre={"root_grid": True, "tile_size": 8})
    assert (t.frame.kind, t.grid.roots) == ("geographic", (2, 1))
    check_static(t, Es=(5.0,))
    check_view(t, views_for(t, 1)[0], taus=(1.0,))
