"""The analysis stage's answers against their references: the figures of issue 47's bar.

    python benchmarks/bench_analysis.py --dems ../shared/dems [--polygons 40] [--points 10000]
                                        [--codec-error 0.5]
    python benchmarks/bench_analysis.py --dems ../shared/dems --contour-size 4097

1. ``height_at`` at ``--points`` random points on every DEM of ``--dems`` (GeoTIFFs and
   PNG tiles) and on a synthetic one with voids, from a lossless store and one made with
   ``--codec-error``, against a bilinear read of the source raster (rasterio; the numpy
   oracle of ``geoterrain.testing.analysisref``): the largest difference, the codec's ε,
   and whether NaN falls exactly where the source has nodata.
2. ``surface_area`` and ``volume`` on ``--polygons`` random star polygons over
   srtm1_japan against GEOS on the full-resolution triangulation: the largest relative
   difference of each quantity; then with ``max_error`` (0.5, 2, 8, 30 m) against the
   exact answer: the largest |difference| / reported bound.
3. ``contours`` at 50 m on srtm1_japan (and at 100 m on a ``--contour-size`` fBm, 10 m
   cells) against ``gdal_contour``: levels whose closed and open line counts differ,
   and the largest Hausdorff distance in cells.

Each section prints one line per DEM or case, and the time it took.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.analysis import Plane, contours, height_at, surface_area, volume
from geoterrain.testing.analysisref import (
    bilinear_reference,
    contour_comparison,
    triangulated_reference,
)


def _source(path: Path):
    """(heights, valid, transform or None) as rasterio reads the source; PNG tiles by
    their encoding's formula."""
    import rasterio

    with rasterio.open(path) as src:
        if path.suffix == ".png":
            rgb = src.read().astype(np.float64)
            R, G, B = rgb[0], rgb[1], rgb[2]
            if "terrarium" in path.name:
                z = R * 256 + G + B / 256 - 32768
            else:
                z = -10000 + (R * 65536 + G * 256 + B) * 0.1
            return z, np.isfinite(z), None
        m = src.read(1, masked=True).astype(np.float64)
        z = np.asarray(m.filled(np.nan))
        return z, ~np.ma.getmaskarray(m) & np.isfinite(z), tuple(src.transform)[:6]


def _points(t, n: int, rng) -> np.ndarray:
    a, _, c, _, e, f = t.frame.transform[:6]
    fj = rng.uniform(-0.5, t.grid.cols - 0.5, n)
    fi = rng.uniform(-0.5, t.grid.rows - 0.5, n)
    return np.column_stack([a * (fj + 0.5) + c, e * (fi + 0.5) + f])


def _voids(work: Path) -> Path:
    """A 450 × 500 fBm GeoTIFF (UTM, 10 m) with 1 % scattered voids and a lake of them."""
    import rasterio
    from rasterio.transform import from_origin

    from geoterrain.ingest.synth import generate

    z = generate("fbm", 513, seed=3)[:450, :500].astype(np.float32)
    rng = np.random.default_rng(3)
    z[rng.random(z.shape) < 0.01] = -9999.0
    z[100:160, 200:290] = -9999.0
    p = work / "voids_fbm.tif"
    with rasterio.open(p, "w", driver="GTiff", width=500, height=450, count=1,
                       dtype="float32", crs="EPSG:32633", nodata=-9999.0,
                       transform=from_origin(500000.0, 5000000.0, 10.0, 10.0)) as dst:
        dst.write(z, 1)
    return p


def heights(dems: list[Path], work: Path, n: int, eps: float | None) -> None:
    print(f"height_at at {n} random points against rasterio + bilinear (numpy), "
          f"{'lossless' if eps is None else f'codec error {eps:g}'}:")
    for p in dems:
        t0 = time.perf_counter()
        t = geoterrain.open(geoterrain.preprocess(p, work / f"{p.stem}_{eps}.geoterrain",
                                                  codec_error=eps))
        z, valid, tr = _source(p)
        pts = _points(t, n, np.random.default_rng(47))
        got = height_at(t, pts)
        want = bilinear_reference(z, valid, tr or t.frame.transform, pts)
        same_nan = bool(np.array_equal(np.isnan(got.height), np.isnan(want)))
        ok = ~np.isnan(want)
        d = float(np.abs(got.height[ok] - want[ok]).max(initial=0.0))
        print(f"  {p.name:28s} max |diff| {d:.3g} (codec ε {t.quantizer.codec_error:g}), "
              f"NaN exactly at nodata: {same_nan} ({int((~ok).sum())} NaN), "
              f"{time.perf_counter() - t0:.1f} s")


def _metres(t):
    f = t.frame
    if f.kind != "geographic":
        return lambda x, y: (x * f.unit_to_m, y * f.unit_to_m)
    from pyproj import CRS, Transformer

    a, _, c, _, e, top = f.transform[:6]
    lon0, lat0 = c + a * t.grid.cols / 2, top + e * t.grid.rows / 2
    aeqd = CRS.from_proj4(f"+proj=aeqd +lat_0={lat0} +lon_0={lon0} +ellps=WGS84")
    tr = Transformer.from_crs(CRS.from_wkt(f.crs_wkt), aeqd, always_xy=True)
    return lambda x, y: tr.transform(x, y)


def _star(rng, cx, cy, r, n):
    from shapely.geometry import Polygon

    while True:
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
        rad = r * rng.uniform(0.3, 1.0, n)
        p = Polygon(np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)]))
        if p.is_valid and p.area > 0:
            return p


def areas(japan: Path, work: Path, n: int) -> None:
    t = geoterrain.open(geoterrain.preprocess(japan, work / "japan_a.geoterrain"))
    z, valid, tr = _source(japan)
    rng = np.random.default_rng(2026)
    worst = dict.fromkeys(("area_2d", "area_3d", "cut", "fill"), 0.0)
    ratio, t0 = 0.0, time.perf_counter()
    for _ in range(n):
        cx, cy = rng.uniform(139.14, 139.32), rng.uniform(35.28, 35.45)
        poly = _star(rng, cx, cy, rng.uniform(0.002, 0.03), int(rng.integers(3, 14)))
        base = Plane(0.0, 0.0, float(rng.uniform(0, 600)))
        ref = triangulated_reference(z, valid, tr, _metres(t), poly, base, t.frame.z_to_m)
        a, v = surface_area(t, poly), volume(t, poly, base)
        for k, got in (("area_2d", a.area_2d), ("area_3d", a.area_3d), ("cut", v.cut),
                       ("fill", v.fill)):
            scale = max(abs(ref[k]), 1.0)
            worst[k] = max(worst[k], abs(got - ref[k]) / scale)
        for e in (0.5, 2.0, 8.0, 30.0):
            ac, vc = surface_area(t, poly, max_error=e), volume(t, poly, base, max_error=e)
            if ac.bound_3d > 0:
                ratio = max(ratio, abs(ac.area_3d - a.area_3d) / ac.bound_3d)
            if vc.bound > 0:
                for k in ("cut", "fill", "net"):
                    ratio = max(ratio, abs(getattr(vc, k) - getattr(v, k)) / vc.bound)
    print(f"surface_area and volume on {n} random polygons over srtm1_japan against GEOS "
          f"(full-resolution triangulation): largest relative difference "
          + ", ".join(f"{k} {w:.2g}" for k, w in worst.items())
          + f"; with max_error 0.5/2/8/30: largest |answer − exact| / bound {ratio:.3f}"
          f" ({time.perf_counter() - t0:.1f} s)")


def _gdal_lines(src: Path, out: Path, interval: float):
    import shapely
    from pyogrio.raw import read

    subprocess.run(["gdal_contour", "-q", "-i", repr(interval), "-a", "elev", str(src),
                    str(out)], check=True)
    meta, _, geom, fields = read(out)
    elev = fields[meta["fields"].tolist().index("elev")]
    return [shapely.get_coordinates(g) for g in shapely.from_wkb(geom)], elev


def contour_case(name: str, src: Path, work: Path, interval: float) -> None:
    t = geoterrain.open(geoterrain.preprocess(src, work / f"{src.stem}_c.geoterrain"))
    t0 = time.perf_counter()
    c = contours(t, interval)
    mine = time.perf_counter() - t0
    lines, elev = _gdal_lines(src, work / f"{src.stem}_c.gpkg", interval)
    res = contour_comparison(c.lines, c.heights, lines, elev)
    differ = [h for h, (a, b, _) in res.items() if a != b]
    cell = abs(t.frame.transform[0])
    hd = max(d for *_, d in res.values()) / cell
    closed = sum(a[0] for a, _, _ in res.values())
    opened = sum(a[1] for a, _, _ in res.values())
    print(f"  {name}, every {interval:g}: {len(res)} levels, {closed} closed and {opened} "
          f"open lines; levels whose counts differ from gdal_contour's: {len(differ)}; "
          f"largest Hausdorff distance {hd:.3g} cells; {c.stats['tiles_decoded']} tiles "
          f"decoded in {mine:.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dems", required=True, help="the folder of the shared DEMs")
    ap.add_argument("--points", type=int, default=10_000)
    ap.add_argument("--codec-error", type=float, default=0.5,
                    help="heights also from a store made with this codec error")
    ap.add_argument("--polygons", type=int, default=40)
    ap.add_argument("--contour-size", type=int, default=0,
                    help="also compare contours on an fBm of this size (e.g. 4097)")
    ap.add_argument("--skip", default="", help="sections to skip: heights,areas,contours")
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # rasterio: PNG tiles have no georeference
    folder = Path(a.dems)
    dems = sorted(p for p in folder.iterdir() if p.suffix in (".tif", ".png"))
    skip = set(a.skip.split(","))
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        dems.append(_voids(work))
        if "heights" not in skip:
            for eps in (None, a.codec_error):
                heights(dems, work, a.points, eps)
        if "areas" not in skip:
            areas(folder / "srtm1_japan.tif", work, a.polygons)
        if "contours" not in skip:
            if shutil.which("gdal_contour") is None:
                print("contours: gdal_contour not found (make gdal)")
                return
            print("contours against gdal_contour:")
            contour_case("srtm1_japan", folder / "srtm1_japan.tif", work, 50.0)
            if a.contour_size:
                from geoterrain.ingest.synth import generate, write_geotiff

                n = a.contour_size
                src = write_geotiff(work / f"fbm{n}.tif", generate("fbm", n, seed=7),
                                    spacing=10.0)
                contour_case(f"{n}² fBm", src, work, 100.0)


if __name__ == "__main__":
    main()
