"""Cesium quantized-mesh-1.0 tile sets (geographic tiling scheme), our own writer.

Layout (what CesiumJS's ``CesiumTerrainProvider`` reads):

- ``layer.json``: format ``quantized-mesh-1.0``, scheme ``tms``, projection
  EPSG:4326, zoom range, per-level ``available`` tile ranges, extensions
  ``octvertexnormals`` and ``watermask``.
- ``{z}/{x}/{y}.terrain``: gzip-compressed tiles. Level z has 2^(z+1) × 2^z tiles
  of 180/2^z degrees; y counts from the south.
- ``geoterrain.json``: each tile's declared error (metres) and the run's figures.

A tile's mesh: the DEM is sampled bilinearly on a (2^k+1)² lattice aligned with
the tile's edges (pyproj maps lon/lat to the source CRS); the per-vertex errors δ
of that lattice (:func:`geoterrain.bounds.vertex_errors`, seed 002) pick the
vertices (δ > the level's error: Cesium's ``levelMaximumGeometricError`` for
z < max zoom, ``max_error`` at max zoom); every lattice sample on the tile's
border is kept, so neighbouring tiles share their edge vertices exactly (same
lon/lat, same height, one height quantisation range for the whole set). Lattice
samples with an invalid DEM neighbour are invalid and no triangle touches them:
nodata becomes a hole, never a spike. The declared error of a tile is the largest
|mesh − DEM| measured on the decoded (quantised) mesh at every valid DEM sample
inside the tile. Normals (oct-encoded, ECEF) come from central differences of the
lattice with a one-sample margin, so they agree across tile edges too.

Why our own writer: quantized-mesh-encoder casts positions to float32 (about
1 m of longitude) and quantises heights per tile, so neighbouring tiles' edge
vertices would not coincide.

Examples
--------
>>> cesium_level_error(0) > cesium_level_error(1) > 0
True
>>> tile_rect(1, 3, 1)
(90.0, 0.0, 180.0, 90.0)
"""

from __future__ import annotations

import gzip
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pyproj import CRS, Transformer

from geoterrain.bounds import vertex_errors
from geoterrain.exceptions import UsageError, WriteError, exists_error
from geoterrain.lod.kernels import close_upward, extract
from geoterrain.lod.mesh import orient_ccw

WGS84_A = 6378137.0
WGS84_B = 6356752.3142451793
QMAX = 32767
MEASURE_SAMPLES = 1 << 20  # DEM samples measured per block


def cesium_level_error(z: int, tile_width: int = 65) -> float:
    """Cesium's ``levelMaximumGeometricError`` (metres) of a geographic-scheme level."""
    return WGS84_A * 2 * math.pi * 0.25 / (tile_width * 2 * (1 << z))


def tile_rect(z: int, x: int, y: int) -> tuple[float, float, float, float]:
    """(west, south, east, north) in degrees of TMS tile (z, x, y), geographic scheme."""
    s = 180.0 / (1 << z)
    return -180.0 + x * s, -90.0 + y * s, -180.0 + (x + 1) * s, -90.0 + (y + 1) * s


# ------------------------------------------------------------------------ sampling
class _Dem:
    """The store's full-resolution heights (metres) and where lon/lat fall on them."""

    def __init__(self, terrain):
        f = terrain.frame
        if f.kind == "pixel" or f.crs_wkt is None:
            raise UsageError("quantized-mesh tiles need a georeferenced DEM; this one has no CRS")
        h, v = terrain.level_heights(0)
        H, W = terrain.grid.rows, terrain.grid.cols
        self.h = (h[:H, :W] * f.z_to_m).astype(np.float64)
        self.valid = v[:H, :W].copy()
        self.h[~self.valid] = np.nan
        self.H, self.W = H, W
        self.transform = f.transform
        crs = CRS.from_wkt(f.crs_wkt)
        self.to_src = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        self.to_geo = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        self.pixel_deg = self._pixel_degrees(f)

    def _pixel_degrees(self, f) -> float:
        i, j = np.array([self.H / 2, self.H / 2 + 1.0]), np.array([self.W / 2, self.W / 2 + 1.0])
        lon, lat = self.lonlat(i, j)
        return float(max(abs(lon[1] - lon[0]) * math.cos(math.radians(lat[0])),
                         abs(lat[1] - lat[0])))

    def lonlat(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lon/lat of (fractional) sample positions (pixel centres at integers)."""
        a, b, c, d, e, f = self.transform[:6]
        jj, ii = np.asarray(j, np.float64) + 0.5, np.asarray(i, np.float64) + 0.5
        lon, lat = self.to_geo.transform(a * jj + b * ii + c, d * jj + e * ii + f)
        return np.asarray(lon), np.asarray(lat)

    def pixel(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional sample row, column of lon/lat (north-up grids, frame.py's rule)."""
        x, y = self.to_src.transform(lon, lat)
        a, _, c, _, e, f = self.transform[:6]
        return (np.asarray(y) - f) / e - 0.5, (np.asarray(x) - c) / a - 0.5

    def bilinear(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Heights (metres) at lon/lat; NaN where a neighbouring sample is invalid/outside."""
        i, j = self.pixel(lon, lat)
        out = np.full(i.shape, np.nan)
        ok = (i >= 0) & (i <= self.H - 1) & (j >= 0) & (j <= self.W - 1)
        i0 = np.clip(np.floor(i[ok]).astype(np.int64), 0, max(self.H - 2, 0))
        j0 = np.clip(np.floor(j[ok]).astype(np.int64), 0, max(self.W - 2, 0))
        fi, fj = i[ok] - i0, j[ok] - j0
        i1, j1 = np.minimum(i0 + 1, self.H - 1), np.minimum(j0 + 1, self.W - 1)
        h = self.h
        out[ok] = ((h[i0, j0] * (1 - fj) + h[i0, j1] * fj) * (1 - fi)
                   + (h[i1, j0] * (1 - fj) + h[i1, j1] * fj) * fi)
        return out

    def extent(self) -> tuple[float, float, float, float]:
        """Lon/lat box of the grid (its border densified through pyproj)."""
        t = np.linspace(0, 1, 65)
        i = np.concatenate([t * 0, t, t * 0 + 1, t]) * (self.H - 1)
        j = np.concatenate([t, t * 0, t, t * 0 + 1]) * (self.W - 1)
        lon, lat = self.lonlat(i, j)
        return float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())


# ------------------------------------------------------------------------- one tile
def _ecef(lon, lat, h):
    tr = _ecef.tr  # type: ignore[attr-defined]
    x, y, z = tr.transform(lon, lat, h)
    return np.stack([np.asarray(x), np.asarray(y), np.asarray(z)], axis=-1)


_ecef.tr = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)  # type: ignore


def _lattice(rect, M: int, margin: int = 0):
    w, s, e, n = rect
    k = np.arange(-margin, M + margin)
    lon = w + (e - w) * k / (M - 1)
    lat = n - (n - s) * k / (M - 1)  # row 0 = north, like the DEM
    return np.meshgrid(lon, lat)


def _normals(dem: _Dem, rect, M: int) -> np.ndarray:
    """(M, M, 3) unit ECEF normals by central differences on a lattice with a margin."""
    lon, lat = _lattice(rect, M, 1)
    h = dem.bilinear(lon, lat)
    up = _ecef(lon, lat, np.ones_like(h)) - _ecef(lon, lat, np.zeros_like(h))
    p = _ecef(lon, lat, np.nan_to_num(h, nan=0.0))
    de = p[1:-1, 2:] - p[1:-1, :-2]  # east
    dn = p[:-2, 1:-1] - p[2:, 1:-1]  # north
    nrm = np.cross(de, dn)
    ln = np.linalg.norm(nrm, axis=-1, keepdims=True)
    bad = ~np.isfinite(h[:-2, 1:-1] + h[2:, 1:-1] + h[1:-1, :-2] + h[1:-1, 2:])
    nrm = np.where(bad[..., None] | (ln == 0), up[1:-1, 1:-1], nrm / np.maximum(ln, 1e-300))
    return nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)


def oct_encode(n: np.ndarray) -> np.ndarray:
    """Cesium's ``AttributeCompression.octEncode`` (8 bits per component), (V, 2) uint8."""
    p = n / np.abs(n).sum(axis=1, keepdims=True)
    x, y = p[:, 0].copy(), p[:, 1].copy()
    neg = p[:, 2] < 0
    sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
    x[neg], y[neg] = (1 - np.abs(p[neg, 1])) * sx[neg], (1 - np.abs(p[neg, 0])) * sy[neg]
    q = np.round((np.clip(np.stack([x, y], 1), -1, 1) * 0.5 + 0.5) * 255)
    return q.astype(np.uint8)


def _zigzag_deltas(a: np.ndarray) -> np.ndarray:
    d = np.diff(a.astype(np.int32), prepend=0)
    return ((d << 1) ^ (d >> 31)).astype(np.uint16)


def horizon_occlusion_point(p: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Cesium's ``EllipsoidalOccluder.computeHorizonCullingPoint`` (ellipsoid-scaled)."""
    radii = np.array([WGS84_A, WGS84_A, WGS84_B])
    d = centre / radii
    d = d / np.linalg.norm(d)
    sp = p / radii
    mag2 = (sp * sp).sum(1)
    mag = np.sqrt(mag2)
    u = sp / mag[:, None]
    mag2, mag = np.maximum(mag2, 1.0), np.maximum(mag, 1.0)
    cos_a = u @ d
    sin_a = np.linalg.norm(np.cross(u, d), axis=1)
    cos_b = 1.0 / mag
    sin_b = np.sqrt(mag2 - 1.0) * cos_b
    with np.errstate(divide="ignore", invalid="ignore"):
        m = 1.0 / (cos_a * cos_b - sin_a * sin_b)
    if not np.all(np.isfinite(m) & (m > 0)):  # no horizon point (a huge tile): never culled
        return d * 10.0
    return d * float(m.max())


def encode_tile(lon, lat, hq, faces, hrange, rect, normals) -> bytes:
    """quantized-mesh-1.0 bytes (not gzipped) of one tile; vertices in first-use order."""
    w, s, e, n = rect
    u = np.round((lon - w) / (e - w) * QMAX).astype(np.int64)
    v = np.round((lat - s) / (n - s) * QMAX).astype(np.int64)
    h0, h1 = hrange
    hh = h0 + (h1 - h0) * hq / QMAX
    p = _ecef(w + (e - w) * u / QMAX, s + (n - s) * v / QMAX, hh)
    lo, hi = p.min(0), p.max(0)
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(p - centre, axis=1).max())
    occ = horizon_occlusion_point(p, centre)
    header = np.array([*centre], "<f8").tobytes() + np.array([h0, h1], "<f4").tobytes() \
        + np.array([*centre, radius, *occ], "<f8").tobytes()
    V = len(u)
    if V > 65536:
        raise UsageError("a tile has more than 65536 vertices; use a smaller lattice")
    body = [header, np.uint32(V).tobytes(), _zigzag_deltas(u).tobytes(),
            _zigzag_deltas(v).tobytes(), _zigzag_deltas(hq).tobytes()]
    idx = faces.ravel().astype(np.int64)
    highest = np.concatenate([[0], np.maximum.accumulate(idx)[:-1] + 1])
    body += [np.uint32(len(faces)).tobytes(), (highest - idx).astype("<u2").tobytes()]
    for sel, key in ((u == 0, v), (v == 0, u), (u == QMAX, v), (v == QMAX, u)):
        ids = np.flatnonzero(sel)
        ids = ids[np.argsort(key[ids], kind="stable")]
        body += [np.uint32(len(ids)).tobytes(), ids.astype("<u2").tobytes()]
    oct_ = oct_encode(normals).tobytes()
    body += [np.uint8(1).tobytes(), np.uint32(len(oct_)).tobytes(), oct_]
    body += [np.uint8(2).tobytes(), np.uint32(1).tobytes(), np.uint8(0).tobytes()]  # all land
    return b"".join(body)


def build_tile(dem: _Dem, z: int, x: int, y: int, M: int, threshold: float,
               hrange: tuple[float, float], flat: bool = False
               ) -> tuple[bytes, float, int] | None:
    """One tile's bytes, declared error (metres) and triangle count; None if no data.

    ``flat``: a tile too coarse to hold a DEM sample on its lattice gets the two
    triangles of its rectangle at the lowest height (its error, measured against
    the DEM, is declared like any other).
    """
    rect = tile_rect(z, x, y)
    if flat:
        M = 3
    lon, lat = _lattice(rect, M)
    h = np.full(lon.shape, hrange[0]) if flat else dem.bilinear(lon, lat)
    valid = np.isfinite(h)
    if valid.sum() < 3:
        return None
    delta = vertex_errors(np.nan_to_num(h, nan=0.0), valid)
    active = delta > threshold
    if flat:
        active[:] = False
    if not flat:
        active[0, :] = active[-1, :] = active[:, 0] = active[:, -1] = True  # shared borders
    close_upward(active)
    faces, fidx = extract(active, np.zeros_like(active), np.full(M * M, -1, np.int32))
    ij = np.stack([fidx // M, fidx % M], 1)
    faces = faces[valid.ravel()[fidx][faces].all(1)]
    if len(faces) == 0:
        return None
    faces = orient_ccw(ij, faces.astype(np.int64))
    # vertices in order of first use (the high-water-mark index coding needs it)
    first = np.full(len(fidx), len(faces) * 3, np.int64)
    np.minimum.at(first, faces.ravel(), np.arange(faces.size))
    used = np.flatnonzero(first < faces.size)
    order = used[np.argsort(first[used], kind="stable")]
    remap = np.full(len(fidx), -1, np.int64)
    remap[order] = np.arange(len(order))
    faces, ij = remap[faces], ij[order]
    vlon, vlat = lon[ij[:, 0], ij[:, 1]], lat[ij[:, 0], ij[:, 1]]
    h0, h1 = hrange
    hq = np.clip(np.round((h[ij[:, 0], ij[:, 1]] - h0) / (h1 - h0) * QMAX), 0, QMAX)
    hq = hq.astype(np.int64)
    if flat:
        nrm = _ecef(vlon, vlat, np.ones(len(vlon))) - _ecef(vlon, vlat, np.zeros(len(vlon)))
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    else:
        nrm = _normals(dem, rect, M)[ij[:, 0], ij[:, 1]]
    data = encode_tile(vlon, vlat, hq, faces, hrange, rect, nrm)
    # measured on the mesh as decoders see it: quantised u, v and heights
    w, s_, e, n = rect
    qlon = w + (e - w) * np.round((vlon - w) / (e - w) * QMAX) / QMAX
    qlat = s_ + (n - s_) * np.round((vlat - s_) / (n - s_) * QMAX) / QMAX
    err = _measure(dem, rect, qlon, qlat, h0 + (h1 - h0) * hq / QMAX, faces)
    return data, err, len(faces)


def _measure(dem: _Dem, rect, lon, lat, hgt, faces) -> float:
    """Largest |mesh − DEM| at every valid DEM sample inside ``rect``."""
    import matplotlib.tri as mtri

    w, s, e, n = rect
    bl, bt = np.linspace(w, e, 17), np.linspace(s, n, 17)
    bi, bj = dem.pixel(np.concatenate([bl, bl, bl * 0 + w, bl * 0 + e]),
                       np.concatenate([bt * 0 + s, bt * 0 + n, bt, bt]))
    i0, i1 = max(0, int(np.floor(bi.min())) - 1), min(dem.H - 1, int(np.ceil(bi.max())) + 1)
    j0, j1 = max(0, int(np.floor(bj.min())) - 1), min(dem.W - 1, int(np.ceil(bj.max())) + 1)
    if i1 < i0 or j1 < j0:
        return 0.0
    interp = None
    worst = 0.0
    rows = max(1, MEASURE_SAMPLES // (j1 - j0 + 1))
    for r0 in range(i0, i1 + 1, rows):  # every sample, a block of rows at a time
        ii, jj = np.meshgrid(np.arange(r0, min(i1 + 1, r0 + rows)), np.arange(j0, j1 + 1),
                             indexing="ij")
        ok = dem.valid[ii, jj]
        ii, jj = ii[ok], jj[ok]
        slon, slat = dem.lonlat(ii, jj)
        inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n)
        if not inside.any():
            continue
        if interp is None:
            interp = mtri.LinearTriInterpolator(mtri.Triangulation(lon, lat, faces), hgt)
        surf = np.ma.filled(interp(slon[inside], slat[inside]), np.nan)
        diff = np.abs(surf - dem.h[ii[inside], jj[inside]])
        diff = diff[np.isfinite(diff)]  # samples in a hole (next to nodata) have no surface
        worst = max(worst, float(diff.max(initial=0.0)))
    return worst


# ------------------------------------------------------------------------ tile set
def max_zoom_for(dem: _Dem, lattice: int) -> int:
    """The first level whose lattice spacing is at most the DEM's sample spacing."""
    for z in range(0, 24):
        if 180.0 / (1 << z) / (lattice - 1) <= dem.pixel_deg * (1 + 1e-9):
            return z
    return 23


def write_tileset(terrain, out_dir: str | Path, *, max_zoom: int | None = None,
                  min_zoom: int = 0, lattice: int = 129, max_error: float = 1.0,
                  overwrite: bool = False,
                  progress: Callable[[str, int, int], None] | None = None) -> dict:
    """Write a quantized-mesh tile set of ``terrain`` into ``out_dir``; returns its figures.

    ``lattice`` (2^k + 1 samples a side) ≤ 129 keeps tiles within 16-bit indices.
    """
    out = Path(out_dir)
    if (out / "layer.json").exists() and not overwrite:
        raise exists_error(out / "layer.json")
    if lattice < 3 or (lattice - 1) & (lattice - 2) or lattice > 129:
        raise UsageError(f"lattice must be 2^k + 1 in 3..129, got {lattice}")
    t0 = time.perf_counter()
    dem = _Dem(terrain)
    zmax = max_zoom_for(dem, lattice) if max_zoom is None else int(max_zoom)
    if not 0 <= min_zoom <= zmax <= 22:
        raise UsageError(f"zoom range {min_zoom}..{zmax} is not within 0..22")
    w, s, e, n = dem.extent()
    hv = dem.h[dem.valid]
    hrange = (float(np.floor(hv.min())), float(np.ceil(hv.max())))
    if hrange[1] <= hrange[0]:
        hrange = (hrange[0], hrange[0] + 1.0)
    jobs = []
    for z in range(min_zoom, zmax + 1):
        size = 180.0 / (1 << z)
        xs = range(int((w + 180) // size), min(int(math.ceil((e + 180) / size)), 2 << z))
        ys = range(int((s + 90) // size), min(int(math.ceil((n + 90) / size)), 1 << z))
        jobs += [(z, x, y) for y in ys for x in xs]
    if min_zoom == 0:  # Cesium starts from both level-0 tiles
        jobs = [(0, x, 0) for x in (0, 1)] + [j for j in jobs if j[0] > 0]
    errors, available = {}, {}
    nbytes = triangles = 0
    data_from = zmax  # levels coarser than the first with lattice data get flat tiles
    try:
        out.mkdir(parents=True, exist_ok=True)
        for k, (z, x, y) in enumerate(jobs):
            thr = max_error if z == zmax else cesium_level_error(z)
            res = build_tile(dem, z, x, y, lattice, thr, hrange)
            if res is not None:
                data_from = min(data_from, z)
            elif z < data_from:
                res = build_tile(dem, z, x, y, lattice, thr, hrange, flat=True)
            if progress:
                progress(f"z{z}", k + 1, len(jobs))
            if res is None:
                continue
            data, err, nt = res
            p = out / str(z) / str(x) / f"{y}.terrain"
            p.parent.mkdir(parents=True, exist_ok=True)
            blob = gzip.compress(data, compresslevel=6, mtime=0)
            p.write_bytes(blob)
            nbytes += len(blob)
            triangles += nt
            errors[f"{z}/{x}/{y}"] = math.ceil(err * 1e4) / 1e4  # rounded up
            available.setdefault(z, []).append((x, y))
    except OSError as exc:
        raise WriteError(f"{out}: cannot write the tile set ({exc.strerror or exc})") from None
    seconds = time.perf_counter() - t0
    layer = {
        "tilejson": "2.1.0", "name": Path(str(terrain.path)).stem, "version": "1.0.0",
        "format": "quantized-mesh-1.0", "scheme": "tms", "projection": "EPSG:4326",
        "tiles": ["{z}/{x}/{y}.terrain?v={version}"], "bounds": [w, s, e, n],
        "minzoom": min_zoom, "maxzoom": zmax,
        "available": [_ranges(available.get(z, [])) for z in range(zmax + 1)],
        "extensions": ["octvertexnormals", "watermask"],
        "attribution": "geoterrain",
    }
    stats = {"tiles": len(errors), "bytes": nbytes, "seconds": round(seconds, 2),
             "triangles": triangles, "min_zoom": min_zoom, "max_zoom": zmax,
             "lattice": lattice, "max_error": max_error, "height_range": list(hrange),
             "level_error": {z: (max_error if z == zmax else cesium_level_error(z))
                             for z in range(min_zoom, zmax + 1)},
             "declared_error": errors}
    (out / "layer.json").write_text(json.dumps(layer, indent=1))
    (out / "geoterrain.json").write_text(json.dumps(stats, indent=1))
    return {k: v for k, v in stats.items() if k != "declared_error"}


def _ranges(tiles: list[tuple[int, int]]) -> list[dict]:
    """Runs of consecutive x in each row y, as layer.json availability rectangles."""
    out = []
    for y in sorted({ty for _, ty in tiles}):
        xs = sorted(tx for tx, ty in tiles if ty == y)
        start = prev = xs[0]
        for x in xs[1:] + [None]:
            if x is None or x != prev + 1:
                out.append({"startX": start, "endX": prev, "startY": y, "endY": y})
                start = x
            prev = x if x is not None else prev
    return out
