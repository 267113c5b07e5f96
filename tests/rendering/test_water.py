"""Water that reads as water, and coasts that follow the surface.

- On a coarse topo-bathymetric DEM (91 × 120 samples, 1 km apart, −2500 … 1500 m) drawn
  at ``-z 3``, the coastline in the picture lies within one texel of the 0 m contour of
  the bilinearly interpolated DEM: between every pair of neighbouring pixels drawn one as
  water (blue) and the other as land, the DEM read back by rasterio (independently of the
  renderer), interpolated bilinearly, crosses 0 m within one texel of the ground segment
  between the two pixels' points (each unprojected through the depth buffer).
- The water surface is flat at the water level × the exaggeration, lit, semi-transparent
  (opaquer over deeper water), ends at the shore, and is drawn with shadows and drapes.
"""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

import geoterrain
from geoterrain.core.view import View
from geoterrain.exaggerate import exaggerated
from geoterrain.ingest.synth import generate
from geoterrain.rendering.antialias import depth_buffer
from geoterrain.rendering.colours import Palette
from geoterrain.rendering.scene import TerrainScene, overview, render
from geoterrain.rendering.shading import Light
from geoterrain.rendering.water import ALPHA_MAX, ALPHA_MIN, water_mesh
from geoterrain.rendering.window import pyvista_plotter
from tests.conftest import write_tif

# heavy cases below are not in the fast tier; the light ones are marked one by one

_STORE: dict = {}


def topobathy(tmp_path_factory):
    """A coarse topo-bathymetric DEM (float32, 120 × 91 samples, 1 km apart)."""
    if "t" not in _STORE:
        d = tmp_path_factory.mktemp("topobathy")
        z = generate("fbm", (91, 120), seed=4, base=-2500.0, relief=4000.0)
        dem = write_tif(d / "topobathy.tif", z.astype(np.float32), spacing=1000.0)
        _STORE["t"] = (geoterrain.preprocess(dem, d / "topobathy.geoterrain"), dem)
    path, dem = _STORE["t"]
    return geoterrain.open(path), dem


def _bilinear(z: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The DEM interpolated bilinearly at fractional (row, column) positions."""
    i = np.clip(i, 0, z.shape[0] - 1)
    j = np.clip(j, 0, z.shape[1] - 1)
    i0 = np.minimum(np.floor(i).astype(int), z.shape[0] - 2)
    j0 = np.minimum(np.floor(j).astype(int), z.shape[1] - 2)
    fi, fj = i - i0, j - j0
    return ((1 - fi) * (1 - fj) * z[i0, j0] + (1 - fi) * fj * z[i0, j0 + 1]
            + fi * (1 - fj) * z[i0 + 1, j0] + fi * fj * z[i0 + 1, j0 + 1])


def _unproject(plotter, xs: np.ndarray, ys: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """World points (N, 3) of picture pixels (x right, y down) at their depth-buffer
    values, through the camera VTK drew with."""
    w, h = plotter.render_window.GetSize()
    cam = plotter.camera
    m = cam.GetCompositeProjectionTransformMatrix(w / h, -1, 1)
    M = np.array([[m.GetElement(r, c) for c in range(4)] for r in range(4)])
    ndc = np.stack([2 * (xs + 0.5) / w - 1, 1 - 2 * (ys + 0.5) / h, 2 * depth - 1,
                    np.ones(len(xs))])
    p = np.linalg.solve(M, ndc)
    return (p[:3] / p[3]).T


def _watery(img: np.ndarray) -> np.ndarray:
    """Pixels coloured as water: blue over red by a tenth of their brightness, whatever
    the shade (every water colour has it by 0.19 or more, every land colour by 0.02 or
    less), so a pixel half land and half water falls near the middle."""
    rgb = img.astype(np.float64)
    return (rgb[..., 2] - rgb[..., 0]) > 0.1 * rgb.sum(-1)


def _depth_jumps(plotter, z: np.ndarray) -> np.ndarray:
    """Pixels next to a depth jump (an occluding edge or the terrain's outline): where the
    ground under a pixel and under a 4-neighbour are more than 4 pixels' footprints apart,
    grown by a pixel."""
    H, W = z.shape
    ys, xs = np.mgrid[0:H, 0:W]
    p = _unproject(plotter, xs.ravel().astype(float), ys.ravel().astype(float),
                   z.ravel()).reshape(H, W, 3)
    p[z >= 1.0] = np.nan
    jump = np.zeros((H, W), bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = p[:H - dy, :W - dx], p[dy:, dx:]
        gap = np.linalg.norm(a - b, axis=-1)
        foot = np.nanmedian(gap)
        big = ~(gap <= 4 * foot)  # NaN (background) counts as a jump
        jump[:H - dy, :W - dx] |= big
        jump[dy:, dx:] |= big
    grown = jump.copy()
    grown[1:] |= jump[:-1]
    grown[:-1] |= jump[1:]
    grown[:, 1:] |= jump[:, :-1]
    grown[:, :-1] |= jump[:, 1:]
    return grown


def _coast_pairs(tmp_path_factory, size=(960, 540), azimuth=190.0, elevation=40.0,
                 water=True):
    """Per pair of 4-neighbour pixels drawn one water and one land (both on the terrain):
    whether the bilinear DEM crosses 0 m on the ground segment between them, extended by
    one texel at each end; with the texel levels drawn."""
    t, dem = topobathy(tmp_path_factory)
    e = exaggerated(t, 3.0)
    v = overview(e, size, azimuth, elevation, colorbar=False, scale_bar=False,
                 north_arrow=False)
    scene = TerrainScene(pyvista_plotter(size, "msaa"), e, water=water)
    try:
        img, _ = scene.frame(v)
        z = depth_buffer(scene.plotter)
        levels = scene.texture_stats["texel_levels"]
        water_px = _watery(img)
        terrain = z < 1.0
        pairs = []
        for dy, dx in ((0, 1), (1, 0)):
            a = water_px[:-dy or None, :-dx or None]
            b = water_px[dy:, dx:]
            ok = (a != b) & terrain[:-dy or None, :-dx or None] & terrain[dy:, dx:]
            ys, xs = np.nonzero(ok)
            pairs.append((ys, xs, ys + dy, xs + dx))
        ya, xa, yb, xb = (np.concatenate(k) for k in zip(*pairs, strict=True))
        keep = (ya > 2) & (xa > 2) & (yb < size[1] - 3) & (xb < size[0] - 3)
        # not where nearer terrain hides farther (a pixel there blends two surfaces, its
        # depth one of them): no depth jump within a pixel of either
        jump = _depth_jumps(scene.plotter, z)
        keep &= ~jump[ya, xa] & ~jump[yb, xb]
        ya, xa, yb, xb = ya[keep], xa[keep], yb[keep], xb[keep]
        pa = _unproject(scene.plotter, xa.astype(float), ya.astype(float), z[ya, xa])
        pb = _unproject(scene.plotter, xb.astype(float), yb.astype(float), z[yb, xb])
        # a pixel's footprint on the ground there: the larger step to its right and lower
        # neighbours' points (at its own depth, on the same surface)
        za = z[ya, xa]
        foot = np.maximum(
            np.linalg.norm((_unproject(scene.plotter, xa + 1.0, ya.astype(float), za)
                            - pa)[:, :2], axis=1),
            np.linalg.norm((_unproject(scene.plotter, xa.astype(float), ya + 1.0, za)
                            - pa)[:, :2], axis=1))
    finally:
        scene.plotter.close()
    with rasterio.open(dem) as src:
        raw = src.read(1).astype(np.float64)
        a_, _, c_, _, e_, f_ = src.transform[:6]
    ox, oy = t.frame.origin_crs
    u = t.frame.unit_to_m

    def rc(p):  # scene metres → source (row, column) of sample centres
        return (p[:, 1] / u + oy - f_) / e_ - 0.5, (p[:, 0] / u + ox - c_) / a_ - 0.5

    (ra, ca), (rb, cb) = rc(pa), rc(pb)
    texel = 2.0 ** max(levels)  # the coarsest texel drawn, in samples
    inside = np.minimum(ra, rb) > 1
    inside &= np.maximum(ra, rb) < raw.shape[0] - 2
    inside &= (np.minimum(ca, cb) > 1) & (np.maximum(ca, cb) < raw.shape[1] - 2)
    ra, ca, rb, cb = ra[inside], ca[inside], rb[inside], cb[inside]
    foot = foot[inside] / abs(a_) / u
    reach = float(texel + foot.max()) * 1.5
    coarse = _contour_distance(raw, ra, ca, rb, cb, reach)
    tol = np.where(texel >= foot, texel, texel + foot)
    return _coast_check(coarse, raw, (ra, ca, rb, cb), tol), foot, texel, levels


def _contour_distance(raw, ra, ca, rb, cb, reach: float, n: int = 8) -> np.ndarray:
    """The distance (samples) from each segment (ra, ca)–(rb, cb) to the 0 m contour of the
    bilinear DEM: the smallest radius r ≤ ``reach`` whose capsule around the segment holds
    heights on both sides of 0 m, searched on a lattice of ``reach`` / ``n`` (so an
    overestimate by at most that; inf beyond ``reach``)."""
    t = np.linspace(0.0, 1.0, n + 1)
    off = np.linspace(-reach, reach, 2 * n + 1)
    P = np.stack(np.meshgrid(t, off, off, indexing="ij"), -1).reshape(-1, 3)
    rad = np.hypot(P[:, 1], P[:, 2])
    keep = rad <= reach + 1e-12
    P, rad = P[keep], rad[keep]
    sr = ra[:, None] + P[None, :, 0] * (rb - ra)[:, None] + P[None, :, 1]
    sc = ca[:, None] + P[None, :, 0] * (cb - ca)[:, None] + P[None, :, 2]
    h = _bilinear(raw, sr, sc) > 0
    # both sides within r: r reaches the nearest point of each side
    near_land = np.where(h, rad[None, :], np.inf).min(1)
    near_sea = np.where(~h, rad[None, :], np.inf).min(1)
    return np.maximum(near_land, near_sea)


def _coast_check(dist_coarse, raw, seg, tol):
    """The pairs beyond ``tol`` on the coarse lattice measured again on a fine one."""
    dist = dist_coarse.copy()
    again = np.flatnonzero(dist > tol)
    if len(again):
        ra, ca, rb, cb = (x[again] for x in seg)
        dist[again] = _contour_distance(raw, ra, ca, rb, cb, float(tol[again].max()) * 1.5,
                                        n=48)
    return dist


@pytest.mark.parametrize("elevation", [40.0, 70.0])
def test_coast_is_within_a_texel_of_the_bilinear_contour(tmp_path_factory, elevation):
    """At -z 3, from the default 40° and from 70°: every coast pixel pair is within one
    texel of the contour where texels are coarser than the pixels (70°: 0.9 texel at
    most, measured), and within one texel and one pixel's footprint where the texels are
    finer than the pixels (40°, seen obliquely: 2 texels = 0.25 samples at most); the
    nearest-sample colours of before were off by up to half a sample (4 texels)."""
    dist, foot, texel, levels = _coast_pairs(tmp_path_factory, elevation=elevation)
    assert len(dist) > 300 and min(levels) < 0  # a coarse DEM: magnified texels drawn
    coarse = texel >= foot  # texels no finer than the pixels
    tol = np.where(coarse, texel, texel + foot)
    far = dist > tol
    assert not far.any(), (f"{int(far.sum())} of {len(dist)} coast pixel pairs too far "
                           f"(texel {texel} samples): {np.sort(dist[far])[-5:]}")
    if elevation == 70.0:
        assert coarse.mean() > 0.9


@pytest.mark.fast
def test_water_surface_is_flat_lit_and_translucent(tmp_path_factory):
    t, _ = topobathy(tmp_path_factory)
    for n in (1.0, 3.0):
        m = water_mesh(exaggerated(t, n), Palette("auto"))
        top = m.points[:, 2]
        assert np.allclose(top[np.abs(top) < 1e-9], 0.0)  # the sea at 0 m, even at -z 3
        alpha = m.point_data["rgba"][:, 3] / 255.0
        assert alpha.max() == pytest.approx(ALPHA_MAX, abs=0.01)
        # the shore's vertices are clear, the others between the shallow and deep opacity
        assert (alpha == 0).any() and alpha[alpha > 0].min() >= ALPHA_MIN - 0.01
    # --water-level H: the surface at H (× the exaggeration)
    m = water_mesh(exaggerated(t, 2.0), Palette("auto", water_level=300.0))
    surface = m.points[m.point_data["rgba"][:, 3] < 255 * ALPHA_MAX - 1, 2]
    assert np.allclose(surface, 600.0)
    # no water in a palette without it; none under the data either
    assert water_mesh(t, Palette("viridis")) is None
    assert water_mesh(t, Palette("auto", water_level=-5000.0)) is None


def test_water_is_drawn_with_shadows_and_drape(tmp_path_factory, tmp_path):
    """The picture with water: the sea's pixels are water-blue and flat-lit (far less
    varied than the sea floor's relief shading under it without the surface), with
    shadows and with a drape too."""
    t, dem = topobathy(tmp_path_factory)
    v = overview(t, (480, 270))
    out = {}
    for name, kw in (("water", {}), ("bare", {"water": False}),
                     ("shadows", {"light": Light(250, 20, shadows=True)}),
                     ("drape", {"drape": _drape(t, tmp_path)})):
        stats = render(t, v, tmp_path / f"{name}.png", **kw)
        import imageio.v3 as iio

        out[name] = iio.imread(tmp_path / f"{name}.png").astype(int)
        assert stats["anti_aliasing"] == ("msaa" if kw.get("water", True) else "edges")
    with rasterio.open(dem) as src:
        z = src.read(1)
    assert (z < 0).mean() > 0.3
    blue = lambda img: (img[..., 2] - img[..., 0]) > 25  # noqa: E731
    sea = blue(out["water"]) & blue(out["bare"])
    assert sea.mean() > 0.1
    # the flat surface evens out the sea floor's relief shading
    assert out["water"][sea].std(0).mean() < 0.8 * out["bare"][sea].std(0).mean()
    for name in ("shadows", "drape"):
        assert blue(out[name]).mean() > 0.5 * sea.mean(), name


def _drape(t, tmp_path):
    """A grey georeferenced image over the DEM (a stand-in orthophoto)."""
    from rasterio.transform import from_bounds

    from geoterrain.rendering.drape import Drape

    f = t.frame
    a, _, c, _, e, top = f.transform
    box = (c, top + e * t.grid.rows, c + a * t.grid.cols, top)
    p = tmp_path / "ortho.tif"
    with rasterio.open(p, "w", driver="GTiff", width=64, height=48, count=3, dtype="uint8",
                       crs=f.crs_wkt, transform=from_bounds(*box, 64, 48)) as dst:
        dst.write(np.full((3, 48, 64), 150, np.uint8))
    return Drape(str(p), 0.8)


@pytest.mark.fast
def test_top_down_view_has_no_seam_between_water_and_land(tmp_path_factory):
    """Straight down, the water surface ends at the shore: no sky or background shows
    between the sea and the land (its cells reach the first dry sample)."""
    t, _ = topobathy(tmp_path_factory)
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    v = View(tuple(c + [0, 0, 200000.0]), tuple(c), (0, 1, 0), 30.0, (480, 270))
    scene = TerrainScene(pyvista_plotter(v.size), t)
    try:
        scene.frame(v)
        terrain = depth_buffer(scene.plotter) < 1.0
    finally:
        scene.plotter.close()
    ys, xs = np.nonzero(terrain)
    inner = terrain[ys.min() + 2:ys.max() - 1, xs.min() + 2:xs.max() - 1]
    assert inner.all()


def test_top_down_perspective_water_covers_a_sea_of_zeros(tmp_path_factory):
    """A sea of exact zeros (as SRTM's) seen from high straight above in perspective: the
    terrain's mesh is coarse there (its vertical errors barely show) and rises above 0 m
    near the coast; the water surface is drawn over it everywhere the bare sea shows
    (lifted by what moves it half a pixel at most), not only where the mesh stays at 0 m."""
    d = tmp_path_factory.mktemp("zerosea")
    z = (generate("fbm", (129, 129), seed=7, base=0.0, relief=400.0)
         + np.linspace(-500.0, 400.0, 129)[None, :])
    z = np.maximum(z, 0.0).astype(np.float32)  # the sea on the west: exact zeros
    assert 0.3 < (z == 0).mean() < 0.5
    dem = write_tif(d / "zerosea.tif", z, spacing=30.0)
    t = geoterrain.open(geoterrain.preprocess(dem, d / "zerosea.geoterrain"))
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    v = View(tuple(c + [0, 0, 9000.0]), tuple(c), (0, 1, 0), 30.0, (320, 240))
    pics = {}
    for water in (False, True):
        scene = TerrainScene(pyvista_plotter(v.size, "msaa"), t, water=water,
                             cmap=Palette("auto", water_level=0.0))
        try:
            pics[water] = scene.frame(v, 1.0)[0].astype(int)
        finally:
            scene.plotter.close()
    bare, wet = pics[False], pics[True]
    # the bare sea: its one flat colour (the most frequent watery colour)
    cols, counts = np.unique(bare[_watery(bare)].reshape(-1, 3), axis=0, return_counts=True)
    sea = np.all(bare == cols[counts.argmax()], axis=-1)
    assert sea.sum() > 0.1 * sea.size
    covered = np.abs(wet - bare).sum(-1) > 6
    assert covered[sea].mean() > 0.999, covered[sea].mean()
