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
of that lattice (:func:`geoterrain.bounds.delta.vertex_errors`, seed 002) pick the
vertices. Every lattice sample on the tile's border is kept, so neighbouring tiles
share their edge vertices exactly (same lon/lat, same height, one height
quantisation range for the whole set). Lattice samples with an invalid DEM
neighbour are invalid and no triangle touches them: nodata becomes a hole, never a
spike. Normals (oct-encoded, ECEF) come from central differences of the lattice
with a one-sample margin, so they agree across tile edges too.

Each tile's declared error is an a-priori bound on |mesh − DEM| at every DEM sample
it covers (:func:`build_tile`): the resampling error of the full lattice (measured
at the DEM samples before any vertex is chosen) + the largest δ left out + the
quantisation of heights and of u, v. Below max zoom the vertex threshold is the
level's Cesium ``levelMaximumGeometricError`` minus the other terms, so the bound
fits the error Cesium refines by; a level whose resampling error leaves no room is
rebuilt on a lattice twice as fine (257², when its tiles stay within 16-bit
indices). At max zoom the threshold is ``max_error`` and the bound is what it is
(Cesium refines no further there); ``geoterrain.json`` lists it per tile and per level.

Heights are the DEM's own unless ``geoid="egm96"`` converts EGM96 orthometric heights
(SRTM's) to the WGS 84 ellipsoidal heights CesiumJS assumes (pyproj, PROJ's EGM96
grid); without it the terrain sits off by the geoid undulation (−107 to +85 m).

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

import functools
import gzip
import json
import logging
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pyproj import CRS, Transformer

from geoterrain.bounds.delta import vertex_errors
from geoterrain.core.atomicfiles import write_atomic
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.lod.kernels import close_upward, extract
from geoterrain.lod.mesh import orient_ccw

log = logging.getLogger("geoterrain")

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

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
GEOIDS = ("egm96",)


def geoid_transformer(geoid: str = "egm96") -> Transformer:
    """pyproj's vertical transform from EGM96 heights to WGS 84 ellipsoidal heights.

    Needs PROJ's EGM96 grid (``us_nga_egm96_15.tif``, or ``egm96_15.gtx`` from
    Debian's ``proj-data`` package in /usr/share/proj); never a ballpark no-op.

    Examples
    --------
    >>> try:
    ...     n = geoid_transformer().transform(0.0, 0.0, 0.0)[2]  # N at (0°, 0°)
    ... except UsageError:
    ...     n = 17.16  # the grid is not installed here
    >>> round(n, 2)
    17.16
    """
    import pyproj

    if geoid not in GEOIDS:
        raise UsageError(f"unknown geoid {geoid!r}; use one of {', '.join(GEOIDS)}")

    def make() -> Transformer:
        return Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True,
                                    allow_ballpark=False, only_best=True)
    try:
        return make()
    except pyproj.exceptions.ProjError:
        if not Path("/usr/share/proj/egm96_15.gtx").exists():
            raise UsageError("the EGM96 geoid grid is not installed: apt-get install proj-data "
                             "(Debian/Ubuntu), or put us_nga_egm96_15.tif in PROJ's data folder "
                             f"({pyproj.datadir.get_user_data_dir()})") from None
    pyproj.datadir.append_data_dir("/usr/share/proj")  # Debian's proj-data
    return make()


def pixel_degrees(terrain: TerrainLike) -> float:
    """The DEM's sample spacing at its centre, in degrees of latitude (longitude steps
    shrunk by cos φ), from its frame alone (no tile is decoded).

    Examples
    --------
    >>> 0 < pixel_degrees(t) < 1
    True
    """
    f, H, W = terrain.frame, terrain.grid.rows, terrain.grid.cols
    if f.kind == "pixel" or f.crs_wkt is None:
        raise UsageError("quantized-mesh tiles need a georeferenced DEM; this one has no CRS")
    to_geo = Transformer.from_crs(CRS.from_wkt(f.crs_wkt), "EPSG:4326", always_xy=True)
    a, b, c, d, e, g = f.transform[:6]
    jj, ii = np.array([W / 2, W / 2 + 1.0]) + 0.5, np.array([H / 2, H / 2 + 1.0]) + 0.5
    lon, lat = to_geo.transform(a * jj + b * ii + c, d * jj + e * ii + g)
    return float(max(abs(lon[1] - lon[0]) * math.cos(math.radians(lat[0])),
                     abs(lat[1] - lat[0])))


class _Dem:
    """The store's full-resolution heights (metres) and where lon/lat fall on them.

    ``geoid``: the heights are EGM96 orthometric heights; convert them to WGS 84
    ellipsoidal heights (what CesiumJS assumes) at every sample, through pyproj.
    ``window``: ((i0, i1), (j0, j1)), the level-0 rows and columns (inclusive) to read;
    only the stored tiles under them are decoded, and sample (i, j) of the arrays is
    sample (i0 + i, j0 + j) of the grid (positions are computed on the whole grid and
    the integer offset subtracted, exactly, so two windows agree on a shared sample).
    ``heights=False``: the georeference alone (no tile is decoded).
    """

    def __init__(self, terrain: TerrainLike, geoid: str | None = None,
                 window: tuple[tuple[int, int], tuple[int, int]] | None = None,
                 heights: bool = True):
        f = terrain.frame
        if f.kind == "pixel" or f.crs_wkt is None:
            raise UsageError("quantized-mesh tiles need a georeferenced DEM; this one has no CRS")
        self.H, self.W = terrain.grid.rows, terrain.grid.cols
        self.i0 = self.j0 = 0
        self.transform = f.transform
        crs = CRS.from_wkt(f.crs_wkt)
        self.to_src = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        self.to_geo = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
        self.pixel_deg = pixel_degrees(terrain)
        self.full = (self.H, self.W)
        if not heights:
            self.h, self.valid = np.full((0, 0), np.nan), np.zeros((0, 0), bool)
            return
        if window is None:
            h, v = terrain.level_heights(0)
            H, W = self.H, self.W
            self.h = (h[:H, :W] * f.z_to_m).astype(np.float64)
            self.valid = v[:H, :W].copy()
        else:
            from geoterrain.export.webtiles import level_window

            (i0, i1), (j0, j1) = window
            i0, j0 = max(int(i0), 0), max(int(j0), 0)
            i1, j1 = min(int(i1), self.H - 1), min(int(j1), self.W - 1)
            self.h = level_window(terrain, 0, (i0, i1), (j0, j1),
                                  lambda ks: [terrain.tile(*k).heights for k in ks])[..., 0]
            self.h *= f.z_to_m
            self.valid = np.isfinite(self.h)
            self.i0, self.j0 = i0, j0
            self.H, self.W = self.h.shape
        self.h[~self.valid] = np.nan
        if geoid is not None:
            tr = geoid_transformer(geoid)
            ii, jj = np.nonzero(self.valid)
            lon, lat = self.lonlat(ii, jj)
            _, _, hz = tr.transform(lon, lat, self.h[ii, jj])
            self.h[ii, jj] = np.asarray(hz, np.float64)

    def lonlat(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lon/lat of (fractional) sample positions (pixel centres at integers)."""
        a, b, c, d, e, f = self.transform[:6]
        jj = np.asarray(j, np.float64) + (0.5 + self.j0)
        ii = np.asarray(i, np.float64) + (0.5 + self.i0)
        lon, lat = self.to_geo.transform(a * jj + b * ii + c, d * jj + e * ii + f)
        return np.asarray(lon), np.asarray(lat)

    def pixel(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional sample row, column of lon/lat (north-up grids, frame.py's rule)."""
        x, y = self.to_src.transform(lon, lat)
        a, _, c, _, e, f = self.transform[:6]
        return ((np.asarray(y) - f) / e - 0.5) - self.i0, ((np.asarray(x) - c) / a - 0.5) - self.j0

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


class _TooManyVertices(UsageError):
    """A tile's mesh needs more vertices than quantized-mesh's 16-bit indices hold."""


@functools.lru_cache(maxsize=8)
def _fine_faces(M: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces and (row, col) of the full-resolution RTIN triangulation of an M × M lattice."""
    act = np.ones((M, M), bool)
    faces, fidx = extract(act, np.zeros_like(act), np.full(M * M, -1, np.int32))
    faces = faces.astype(np.int64)
    faces.flags.writeable = fidx.flags.writeable = False  # cached: shared by every tile
    return faces, fidx


def _slope_bound(lon, lat, hgt, faces, dlon: float, dlat: float) -> float:
    """max over triangles of |∂h/∂lon|·dlon + |∂h/∂lat|·dlat: how far a vertex shift of
    at most (dlon, dlat) moves the surface (the map T → T_q is affine per triangle)."""
    if len(faces) == 0:
        return 0.0
    p = np.stack([lon, lat, hgt], 1)[faces]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    n = np.cross(a, b)
    ok = np.abs(n[:, 2]) > 0
    g = -n[ok, :2] / n[ok, 2:3]  # (∂h/∂lon, ∂h/∂lat)
    return float((np.abs(g[:, 0]) * dlon + np.abs(g[:, 1]) * dlat).max(initial=0.0))


def build_tile(dem: _Dem, z: int, x: int, y: int, M: int, target: float,
               hrange: tuple[float, float], flat: bool = False, *,
               fixed_threshold: float | None = None) -> tuple[bytes, float, int, dict] | None:
    """One tile's bytes, declared error bound (metres), triangle count and the terms of
    the bound; None if no data.

    The bound, for every DEM sample p the tile covers (seed 002's δ for the middle term):
    |mesh_q(p) − DEM(p)| ≤ e_r + δ_max + e_h + e_uv, where

    - e_r  = max |L(p) − DEM(p)| over the DEM samples, L the full-resolution lattice
      surface (the resampling error, measured before any vertex is chosen);
    - δ_max = the largest δ of a left-out vertex: |mesh − L| ≤ δ_max everywhere;
    - e_h  = half a height quantisation step;
    - e_uv = the slope bound of :func:`_slope_bound` for u, v rounded to 1/32767.

    The vertex threshold is ``target − e_r − e_h − e_uv`` (``fixed_threshold`` when
    given), so the bound is ≤ ``target`` whenever ``e_r + e_h + e_uv`` leaves room
    (``info["fits"]``).
    ``flat``: a tile too coarse to hold a DEM sample on its lattice gets the two
    triangles of its rectangle at the lowest height (its error is measured).
    """
    rect = tile_rect(z, x, y)
    w, s_, e, n = rect
    if flat:
        M = 3
    lon, lat = _lattice(rect, M)
    h = np.full(lon.shape, hrange[0]) if flat else dem.bilinear(lon, lat)
    valid = np.isfinite(h)
    if valid.sum() < 3:
        return None
    h0, h1 = hrange
    e_h = 0.5 * (h1 - h0) / QMAX * (1 + 1e-9)
    dlon, dlat = 0.5 * (e - w) / QMAX, 0.5 * (n - s_) / QMAX
    e_r = _resampling_error(dem, rect, h, valid)
    if flat:
        e_uv = 0.0
    else:
        fine, fidx = _fine_faces(M)
        fine = fine[valid.ravel()[fidx][fine].all(1)]
        e_uv = _slope_bound(lon.ravel()[fidx], lat.ravel()[fidx],
                            np.nan_to_num(h.ravel()[fidx], nan=0.0), fine, dlon, dlat)
    rest = e_r + e_h + e_uv
    thr = fixed_threshold if fixed_threshold is not None else max(target - rest, 0.0)
    delta = vertex_errors(np.nan_to_num(h, nan=0.0), valid)
    for _ in range(4):  # the mesh's own slope term may exceed the lattice's: lower thr
        res = _select(dem, rect, M, lon, lat, h, valid, delta, thr, hrange, flat)
        if res is None:
            return None
        data, faces, d_max, e_uv = res
        bound = e_r + d_max + e_h + e_uv
        if fixed_threshold is not None or bound <= target or thr == 0.0:
            break
        thr = max(thr - (bound - target), 0.0)
    info = {"M": M, "e_r": e_r, "delta": d_max, "e_h": e_h, "e_uv": e_uv, "threshold": thr,
            "fits": bound <= target}
    return data, bound, len(faces), info


def _select(dem: _Dem, rect, M: int, lon, lat, h, valid, delta, thr: float, hrange,
            flat: bool):
    """The tile's bytes, faces, largest left-out δ and slope term at threshold ``thr``."""
    w, s_, e, n = rect
    dlon, dlat = 0.5 * (e - w) / QMAX, 0.5 * (n - s_) / QMAX
    h0, h1 = hrange
    active = delta > thr
    if flat:
        active[:] = False
    else:
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
    vh = h[ij[:, 0], ij[:, 1]]
    hq = np.clip(np.round((vh - h0) / (h1 - h0) * QMAX), 0, QMAX).astype(np.int64)
    if flat:
        nrm = _ecef(vlon, vlat, np.ones(len(vlon))) - _ecef(vlon, vlat, np.zeros(len(vlon)))
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    else:
        nrm = _normals(dem, rect, M)[ij[:, 0], ij[:, 1]]
    if len(order) > 65536:
        raise _TooManyVertices(f"a tile has {len(order)} vertices, more than 16-bit indices hold")
    data = encode_tile(vlon, vlat, hq, faces, hrange, rect, nrm)
    if flat:  # two triangles (L is the mesh itself): the measured error is exact
        d_max, e_uv = 0.0, 0.0
    else:
        left_out = valid & ~active & np.isfinite(delta)
        d_max = float(delta[left_out].max(initial=0.0))
        e_uv = _slope_bound(vlon, vlat, vh, faces, dlon, dlat)
    return data, faces, d_max, e_uv


@functools.lru_cache(maxsize=8)
def _diagonals(M: int) -> np.ndarray:
    """(M−1, M−1) bool: True where the full-resolution RTIN triangulation splits cell
    (r, c) along (r, c)–(r+1, c+1), False along (r, c+1)–(r+1, c)."""
    faces, fidx = _fine_faces(M)
    r, c = fidx[faces] // M, fidx[faces] % M
    r0, c0 = r.min(1), c.min(1)
    main = np.zeros((M - 1, M - 1), bool)
    has = ((r == r0[:, None]) & (c == c0[:, None])).any(1)  # the cell's (r, c) corner
    has &= ((r == r0[:, None] + 1) & (c == c0[:, None] + 1)).any(1)
    main[r0[has], c0[has]] = True
    main.flags.writeable = False
    return main


def _resampling_error(dem: _Dem, rect, h: np.ndarray, valid: np.ndarray) -> float:
    """Largest |L − DEM| at the valid DEM samples inside ``rect``, L being the lattice
    heights ``h`` on the full-resolution RTIN triangulation (triangles with an invalid
    corner are holes: their samples are skipped). Vectorised: cell, side of the
    diagonal, then the triangle's linear interpolation."""
    M = h.shape[0]
    w, s, e, n = rect
    bl, bt = np.linspace(w, e, 17), np.linspace(s, n, 17)
    bi, bj = dem.pixel(np.concatenate([bl, bl, bl * 0 + w, bl * 0 + e]),
                       np.concatenate([bt * 0 + s, bt * 0 + n, bt, bt]))
    i0, i1 = max(0, int(np.floor(bi.min())) - 1), min(dem.H - 1, int(np.ceil(bi.max())) + 1)
    j0, j1 = max(0, int(np.floor(bj.min())) - 1), min(dem.W - 1, int(np.ceil(bj.max())) + 1)
    if i1 < i0 or j1 < j0:
        return 0.0
    main = _diagonals(M)
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
        ii, jj = ii[inside], jj[inside]
        x = (slon[inside] - w) / (e - w) * (M - 1)  # lattice column
        y = (n - slat[inside]) / (n - s) * (M - 1)  # lattice row
        c = np.clip(np.floor(x).astype(np.int64), 0, M - 2)
        r = np.clip(np.floor(y).astype(np.int64), 0, M - 2)
        u, v = x - c, y - r
        h00, h01, h10, h11 = h[r, c], h[r, c + 1], h[r + 1, c], h[r + 1, c + 1]
        k00, k01, k10, k11 = valid[r, c], valid[r, c + 1], valid[r + 1, c], valid[r + 1, c + 1]
        m = main[r, c]
        up = u >= v  # main diagonal: (00, 01, 11) above it, (00, 10, 11) below
        lo = u + v <= 1  # other diagonal: (00, 01, 10) before it, (01, 10, 11) after
        surf = np.where(m, np.where(up, h00 + u * (h01 - h00) + v * (h11 - h01),
                                    h00 + v * (h10 - h00) + u * (h11 - h10)),
                        np.where(lo, h00 + u * (h01 - h00) + v * (h10 - h00),
                                 h11 + (1 - u) * (h10 - h11) + (1 - v) * (h01 - h11)))
        ok = np.where(m, k00 & k11 & np.where(up, k01, k10),
                      k01 & k10 & np.where(lo, k00, k11))
        diff = np.abs(surf - dem.h[ii, jj])[ok]
        worst = max(worst, float(diff.max(initial=0.0)))
    return worst


# ------------------------------------------------------------------------ tile set
def max_zoom_for(pixel_deg: float, lattice: int) -> int:
    """The first level whose lattice spacing is at most the DEM's sample spacing
    ``pixel_deg`` (degrees, :func:`pixel_degrees`).

    Examples
    --------
    >>> max_zoom_for(1 / 3600, 129)  # 1″ SRTM
    13
    """
    for z in range(0, 24):
        if 180.0 / (1 << z) / (lattice - 1) <= pixel_deg * (1 + 1e-9):
            return z
    return 23


def _tile_folder(out: Path, z: int, x: int) -> Path:
    """``out/z/x``, made if absent; a link or a file in its place is refused (tiles are
    never written through a link out of the tile set)."""
    p = out
    for part in (str(z), str(x)):
        p = p / part
        try:
            p.mkdir(exist_ok=True)
        except FileExistsError:
            pass
        check_output(p, True, folder=True)
    return p


def write_tileset(terrain: TerrainLike, out_dir: str | Path, *, max_zoom: int | None = None,
                  min_zoom: int = 0, lattice: int = 129, max_error: float = 1.0,
                  overwrite: bool = False, geoid: str | None = None,
                  progress: Callable[[str, int, int], None] | None = None) -> dict:
    """Write a quantized-mesh tile set of ``terrain`` into ``out_dir``; returns its figures.

    ``lattice`` (2^k + 1 samples a side) ≤ 129 keeps tiles within 16-bit indices.
    ``geoid="egm96"``: the DEM holds EGM96 heights (SRTM does); the tiles get WGS 84
    ellipsoidal heights (:func:`geoid_transformer`), and the declared errors are against
    those.
    """
    # a folder (new, with its parents, or one to write into; never a link or a file),
    # whose files are replaced only with overwrite
    out = Path(out_dir)
    if os.path.lexists(out):
        check_output(out, True, folder=True, inputs=[terrain.path], option="-o")
        for name in ("layer.json", "geoterrain.json"):
            check_output(out / name, overwrite, inputs=[terrain.path])
    if lattice < 3 or (lattice - 1) & (lattice - 2) or lattice > 129:
        raise UsageError(f"lattice must be 2^k + 1 in 3..129, got {lattice}")
    t0 = time.perf_counter()
    # the data fills levels up to its own resolution; one level past it is the most a
    # tile set can use (finer tiles would only resample the same samples again)
    fill = max_zoom_for(pixel_degrees(terrain), lattice)
    zmax = fill if max_zoom is None else int(max_zoom)
    if zmax > min(fill + 1, 22):
        log.warning("max_zoom %d is past what the DEM can fill (its resolution is reached at "
                    "zoom %d): capped at %d", zmax, fill, min(fill + 1, 22))
        zmax = min(fill + 1, 22)
    if not 0 <= min_zoom <= zmax <= 22:
        raise UsageError(f"zoom range {min_zoom}..{zmax} is not within 0..22",
                         cli=f"zoom range {min_zoom}..{zmax} is not within 0..22 (--min-zoom "
                             f"must be at most --max-zoom, and at most {zmax} for this DEM)")
    dem = _Dem(terrain, geoid)
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
    errors, available, levels = {}, {}, {}
    nbytes = triangles = 0
    data_from = zmax  # levels coarser than the first with lattice data get flat tiles
    by_level: dict[int, list[tuple[int, int]]] = {}
    for z, x, y in jobs:
        by_level.setdefault(z, []).append((x, y))
    done = 0
    try:
        out.mkdir(parents=True, exist_ok=True)
        for z, xys in by_level.items():
            # below max zoom: the bound must fit Cesium's level error; a level where the
            # resampling error leaves no room is rebuilt on a lattice twice as fine
            target = max_error if z == zmax else cesium_level_error(z)
            fixed = max_error if z == zmax else None
            sizes = [lattice] + ([2 * lattice - 1] if z < zmax and lattice < 257 else [])
            for M in sizes:
                try:
                    built = _build_level(dem, z, xys, M, target, hrange, fixed, data_from)
                except _TooManyVertices:
                    break  # keep the coarser lattice's tiles
                tiles, data_from = built
                if all(r[3]["fits"] for r in tiles.values()):
                    break
            nb = nt = 0
            for (x, y), (data, bound, ntri, _) in tiles.items():
                p = _tile_folder(out, z, x) / f"{y}.terrain"
                blob = gzip.compress(data, compresslevel=6, mtime=0)
                write_atomic(p, blob)  # a partial, then a rename: never a half tile
                nb, nt = nb + len(blob), nt + ntri
                errors[f"{z}/{x}/{y}"] = math.ceil(bound * 1e4) / 1e4  # rounded up
                available.setdefault(z, []).append((x, y))
            nbytes, triangles = nbytes + nb, triangles + nt
            if tiles:
                bounds = [r[1] for r in tiles.values()]
                levels[z] = {"lattice": max(r[3]["M"] for r in tiles.values()),
                             "tiles": len(tiles), "bytes": nb, "triangles": nt,
                             "level_error": target, "max_declared": max(bounds),
                             "max_resampling": max(r[3]["e_r"] for r in tiles.values()),
                             "over_level_error": sum(b > target for b in bounds)}
            done += len(xys)
            if progress:
                progress(f"z{z}", done, len(jobs))
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
             "heights": f"WGS 84 ellipsoidal (from {geoid.upper()})" if geoid else "as stored",
             "over_level_error": sum(v["over_level_error"] for v in levels.values()),
             "levels": levels, "declared_error": errors}
    write_atomic(out / "layer.json", json.dumps(layer, indent=1), overwrite)
    write_atomic(out / "geoterrain.json", json.dumps(stats, indent=1), overwrite)
    return {k: v for k, v in stats.items() if k not in ("declared_error", "levels")}


def _build_level(dem: _Dem, z: int, xys, M: int, target: float, hrange, fixed, data_from: int):
    """Every tile of level ``z`` on an M-lattice: {(x, y): build_tile's result}."""
    tiles = {}
    for x, y in xys:
        res = build_tile(dem, z, x, y, M, target, hrange, fixed_threshold=fixed)
        if res is not None:
            data_from = min(data_from, z)
        elif z < data_from:
            res = build_tile(dem, z, x, y, M, target, hrange, flat=True, fixed_threshold=fixed)
        if res is not None:
            tiles[(x, y)] = res
    return tiles, data_from


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


# ------------------------------------------------------------ tiles cut on request
EXTENSION_IDS = {"octvertexnormals": 1, "watermask": 2, "metadata": 4}
METADATA_LEVELS = 10  # a tile's metadata lists the tiles of the next 10 levels under it


def split_extensions(data: bytes) -> tuple[bytes, dict[str, bytes]]:
    """A quantized-mesh tile's bytes (not gzipped) → (the mesh without extensions, {name:
    the extension's whole block: id, length, payload}).

    Examples
    --------
    >>> data = _tiny_tile()
    >>> core, ext = split_extensions(data)
    >>> sorted(ext), core + ext["octvertexnormals"] + ext["watermask"] == data
    (['octvertexnormals', 'watermask'], True)
    """
    v = int.from_bytes(data[88:92], "little")
    pos = 92 + 6 * v
    if v > 65536:
        pos += (-pos) % 4
    n = int.from_bytes(data[pos:pos + 4], "little")
    pos += 4 + n * 3 * (4 if v > 65536 else 2)
    for _ in range(4):  # the west, south, east and north edge lists
        k = int.from_bytes(data[pos:pos + 4], "little")
        pos += 4 + k * (4 if v > 65536 else 2)
    core, ext = data[:pos], {}
    names = {i: n for n, i in EXTENSION_IDS.items()}
    while pos + 5 <= len(data):
        eid, length = data[pos], int.from_bytes(data[pos + 1:pos + 5], "little")
        ext[names.get(eid, str(eid))] = data[pos:pos + 5 + length]
        pos += 5 + length
    return core, ext


def metadata_block(meta: dict) -> bytes:
    """The metadata extension (id 4) of a tile: JSON, as CesiumJS reads it."""
    js = json.dumps(meta, separators=(",", ":")).encode()
    # the extension's length, then the JSON's own length and the JSON
    return bytes([4]) + (4 + len(js)).to_bytes(4, "little") + len(js).to_bytes(4, "little") + js


class QuantizedMeshTiles:
    """quantized-mesh-1.0 tiles of ``terrain`` cut one at a time (a server's source).

    The same tiles as :func:`write_tileset` builds, with what a whole-set writer learns
    from all the tiles fixed beforehand instead: one height quantisation range for every
    tile (the store's recorded height range, widened by 120 m with ``geoid``), the
    ``lattice`` at every level, and the tiles a level has (those whose lattice holds at
    least 3 samples inside the DEM's grid, found from the georeference alone; coarser
    levels than the first such level get flat tiles at the lowest height, as the writer
    gives them). Building tile (z, x, y) decodes only the level-0 tiles under its
    rectangle (:class:`_Dem`'s window), and its declared bound is :func:`build_tile`'s.

    Examples
    --------
    >>> q = QuantizedMeshTiles(t)
    >>> q.layer("dem")["format"], q.exists(0, 0, 0), q.exists(0, 5, 0)
    ('quantized-mesh-1.0', True, False)
    >>> data, bound, triangles = q.tile(q.max_zoom, *min(q.level_tiles(q.max_zoom)))
    >>> bound > 0 and triangles > 0
    True
    """

    def __init__(self, terrain: TerrainLike, *, lattice: int = 129, max_error: float = 1.0,
                 geoid: str | None = None, max_zoom: int | None = None):
        if lattice < 3 or (lattice - 1) & (lattice - 2) or lattice > 129:
            raise UsageError(f"lattice must be 2^k + 1 in 3..129, got {lattice}")
        if not max_error > 0:
            raise UsageError(f"max_error must be > 0, got {max_error}")
        self.terrain, self.lattice, self.max_error, self.geoid = terrain, lattice, max_error, geoid
        self.geo = _Dem(terrain, geoid, heights=False)
        if geoid is not None:
            geoid_transformer(geoid)  # fail now if the grid is missing
        self.max_zoom = (max_zoom_for(self.geo.pixel_deg, lattice) if max_zoom is None
                         else int(max_zoom))
        if not 0 <= self.max_zoom <= 22:
            raise UsageError(f"max_zoom must be in 0..22, got {self.max_zoom}")
        self.extent = self.geo.extent()
        lo, hi = terrain.scene_box()
        zs = terrain.frame.z_scale or 1.0
        pad = 120.0 if geoid else 0.0  # EGM96's undulation is within −107..+86 m
        h0, h1 = math.floor(lo[2] / zs - pad), math.ceil(hi[2] / zs + pad)
        self.hrange = (float(h0), float(max(h1, h0 + 1)))
        self._levels: dict[int, frozenset[tuple[int, int]]] = {}

    # ---------------------------------------------------------------- which tiles
    def _touching(self, z: int) -> tuple[range, range]:
        w, s, e, n = self.extent
        size = 180.0 / (1 << z)
        xs = range(max(int((w + 180) // size), 0), min(int(math.ceil((e + 180) / size)), 2 << z))
        ys = range(max(int((s + 90) // size), 0), min(int(math.ceil((n + 90) / size)), 1 << z))
        return xs, ys

    def _lattice_tiles(self, z: int) -> frozenset[tuple[int, int]]:
        """Tiles of level z whose lattice has ≥ 3 samples inside the DEM's grid (the
        level's lattices as one lon/lat grid through pyproj, counted per tile)."""
        xs, ys = self._touching(z)
        M = self.lattice
        if len(xs) * len(ys) == 0:
            return frozenset()
        size = 180.0 / (1 << z)
        k = np.arange(len(xs) * (M - 1) + 1)
        lon = -180.0 + xs.start * size + k * size / (M - 1)
        k = np.arange(len(ys) * (M - 1) + 1)
        lat = -90.0 + ys.start * size + k * size / (M - 1)
        inside = np.zeros((len(lat), len(lon)), bool)
        for r in range(0, len(lat), 256):  # rows of the grid at a time
            LO, LA = np.meshgrid(lon, lat[r:r + 256])
            i, j = self.geo.pixel(LO, LA)
            H, W = self.geo.full
            inside[r:r + 256] = (i >= 0) & (i <= H - 1) & (j >= 0) & (j <= W - 1)
        out = set()
        for a, y in enumerate(ys):
            for b, x in enumerate(xs):
                blk = inside[a * (M - 1):(a + 1) * (M - 1) + 1, b * (M - 1):(b + 1) * (M - 1) + 1]
                if np.count_nonzero(blk) >= 3:
                    out.add((x, y))
        return frozenset(out)

    def level_tiles(self, z: int) -> frozenset[tuple[int, int]]:
        """The (x, y) TMS tiles level z has (see the class docs)."""
        if z not in self._levels:
            if not 0 <= z <= self.max_zoom:
                return frozenset()
            if z <= self.data_from - 1:
                xs, ys = self._touching(z)
                got = {(x, y) for x in xs for y in ys}
                if z == 0:
                    got |= {(0, 0), (1, 0)}  # Cesium starts from both level-0 tiles
                self._levels[z] = frozenset(got)
            else:
                self._levels[z] = self._lattice_tiles(z)
        return self._levels[z]

    @functools.cached_property
    def data_from(self) -> int:
        """The first level whose lattice reaches into the DEM (coarser ones are flat)."""
        for z in range(self.max_zoom + 1):
            if self._lattice_tiles(z):
                return z
        return self.max_zoom + 1

    def exists(self, z: int, x: int, y: int) -> bool:
        """Whether TMS tile (z, x, y) is one of the set's tiles."""
        return 0 <= z <= self.max_zoom and (x, y) in self.level_tiles(z)

    def layer(self, name: str, tiles: str = "{z}/{x}/{y}.terrain?v={version}") -> dict:
        """The set's ``layer.json`` (availability per level, the extensions served)."""
        return {
            "tilejson": "2.1.0", "name": name, "version": "1.0.0",
            "format": "quantized-mesh-1.0", "scheme": "tms", "projection": "EPSG:4326",
            "tiles": [tiles], "bounds": list(self.extent),
            "minzoom": 0, "maxzoom": self.max_zoom,
            "available": [_ranges(sorted(self.level_tiles(z)))
                          for z in range(self.max_zoom + 1)],
            "extensions": ["octvertexnormals", "watermask", "metadata"],
            "metadataAvailability": METADATA_LEVELS,
            "attribution": "geoterrain",
        }

    # ---------------------------------------------------------------- one tile
    def target(self, z: int) -> tuple[float, float | None]:
        """(the bound's target, the fixed vertex threshold or None) of level z."""
        if z == self.max_zoom:
            return self.max_error, self.max_error
        return cesium_level_error(z), None

    def tile(self, z: int, x: int, y: int) -> tuple[bytes, float, int]:
        """(tile bytes with the octvertexnormals and watermask extensions, not gzipped;
        declared error bound in metres; triangles) of TMS tile (z, x, y), which must
        :meth:`exists`."""
        M = self.lattice
        target, fixed = self.target(z)
        res = None
        if z >= self.data_from:
            res = build_tile(self._window(z, x, y), z, x, y, M, target, self.hrange,
                             fixed_threshold=fixed)
        if res is None:  # coarser than the data, or all nodata: the flat tile
            return self._flat(z, x, y)
        data, bound, ntri, _ = res
        return data, bound, ntri

    def metadata(self, z: int, x: int, y: int) -> dict:
        """The metadata extension's content: the tiles of the next
        :data:`METADATA_LEVELS` levels under this one (CesiumJS learns the set's
        availability from it when ``layer.json`` says ``metadataAvailability``)."""
        out = []
        for d in range(1, METADATA_LEVELS + 1):
            if z + d > self.max_zoom:
                break
            kids = [(cx, cy) for cx, cy in self.level_tiles(z + d)
                    if cx >> d == x and cy >> d == y]
            out.append(_ranges(sorted(kids)) if kids else [])
        while out and not out[-1]:
            out.pop()
        return {"available": out}

    def _window(self, z: int, x: int, y: int) -> _Dem:
        """The DEM under tile (z, x, y) and a margin (the normals' lattice ring and the
        bilinear neighbours): only those level-0 tiles are decoded."""
        w, s, e, n = tile_rect(z, x, y)
        mx, my = (e - w) / (self.lattice - 1), (n - s) / (self.lattice - 1)
        t = np.linspace(0.0, 1.0, 33)
        lon = np.concatenate([w - mx + t * (e - w + 2 * mx), w - mx + t * (e - w + 2 * mx),
                              t * 0 + w - mx, t * 0 + e + mx])
        lat = np.concatenate([t * 0 + s - my, t * 0 + n + my,
                              s - my + t * (n - s + 2 * my), s - my + t * (n - s + 2 * my)])
        i, j = self.geo.pixel(lon, lat)
        win = ((int(np.floor(np.nanmin(i))) - 2, int(np.ceil(np.nanmax(i))) + 2),
               (int(np.floor(np.nanmin(j))) - 2, int(np.ceil(np.nanmax(j))) + 2))
        H, W = self.geo.full
        win = ((max(win[0][0], 0), min(win[0][1], H - 1)),
               (max(win[1][0], 0), min(win[1][1], W - 1)))
        if win[0][0] > win[0][1] or win[1][0] > win[1][1]:
            return _Dem(self.terrain, self.geoid, heights=False)
        return _Dem(self.terrain, self.geoid, window=win)

    def _flat(self, z: int, x: int, y: int) -> tuple[bytes, float, int]:
        """Two triangles at the lowest height over the tile's rectangle; its bound needs no
        heights: every height lies in the quantisation range."""
        rect = tile_rect(z, x, y)
        lon, lat = _lattice(rect, 3)
        h = np.full(lon.shape, self.hrange[0])
        valid = np.ones(lon.shape, bool)
        data, faces, _, _ = _select(self.geo, rect, 3, lon, lat, h, valid, np.zeros((3, 3)),
                                    0.0, self.hrange, True)
        e_h = 0.5 * (self.hrange[1] - self.hrange[0]) / QMAX
        return data, self.hrange[1] - self.hrange[0] + e_h, len(faces)


def _tiny_tile() -> bytes:
    """A two-triangle tile (the doctests' example)."""
    rect = tile_rect(0, 0, 0)
    lon, lat = _lattice(rect, 3)
    n = np.tile([0.0, 0.0, 1.0], (4, 1))
    faces = np.array([[0, 1, 2], [2, 1, 3]])
    return encode_tile(lon[::2, ::2].ravel(), lat[::2, ::2].ravel(), np.array([0, 1, 2, 3]),
                       faces, (0.0, 1.0), rect, n)

