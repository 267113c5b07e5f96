"""Cesium quantized-mesh-1.0 tile sets (geographic tiling scheme), our own writer.

Layout (what CesiumJS's ``CesiumTerrainProvider`` reads):

- ``layer.json``: format ``quantized-mesh-1.0``, scheme ``tms``, projection
  EPSG:4326, zoom range, per-level ``available`` tile ranges, extensions
  ``octvertexnormals`` and ``watermask``.
- ``{z}/{x}/{y}.terrain``: gzip-compressed tiles. Level z has 2^(z+1) × 2^z tiles
  of 180/2^z degrees; y counts from the south.
- ``geoterrain.json``: each tile's declared error (metres) and the run's figures.

A tile's mesh: the DEM is sampled bilinearly on a (2^k+1)² lattice aligned with
the tile's edges (pyproj maps lon/lat to the source CRS), and the vertices are picked
on that lattice by one of two meshers (``mesher``):

- ``"tin"`` (the default): a greedy TIN of the lattice (:mod:`qmeshtin`). Each edge
  is first simplified alone, as a 1-D polyline through its lattice samples within the
  level's edge threshold, so that both tiles sharing it keep the same points; the
  interior is then refined with those points inserted first and no other edge point
  added. The declared error is measured: the largest |decoded tile − DEM| over the
  DEM samples the tile covers.
- ``"rtin"``: the per-vertex errors δ of the lattice
  (:func:`geoterrain.bounds.delta.vertex_errors`, seed 002) pick the vertices of the
  bintree cut, and every lattice sample on the tile's border is kept. Its declared
  error is an a-priori bound (below).

Either way neighbouring tiles share their edge vertices exactly (same lon/lat, same
height, one height quantisation range for the whole set). Lattice samples with an
invalid DEM neighbour are invalid and no triangle touches them: nodata becomes a hole,
never a spike. Normals (oct-encoded, ECEF) come from central differences of the
lattice with a one-sample margin, so they agree across tile edges too.

An rtin tile's declared error is an a-priori bound on |mesh − DEM| at every DEM sample
it covers (:func:`build_tile`): the resampling error of the full lattice (measured
at the DEM samples before any vertex is chosen) + the largest δ left out + the
quantisation of heights and of u, v. Below max zoom the vertex threshold is the
level's Cesium ``levelMaximumGeometricError`` minus the other terms, so the bound
fits the error Cesium refines by (a TIN tile starts from the same threshold and
lowers it while its measured error exceeds the level's); a level whose error leaves
no room is rebuilt on a lattice twice as fine (257², when its tiles stay within
16-bit indices). At max zoom the threshold is ``max_error`` and the declared error is
what it is (Cesium refines no further there); ``geoterrain.json`` lists it per tile and
per level.

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

from geoterrain.bounds.delta import vertex_errors
from geoterrain.core.atomicfiles import write_atomic
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.export.qmeshdem import GeoDem, lattice_normals, lonlat_bounds, pixel_degrees
from geoterrain.export.qmeshformat import (
    QMAX,
    cesium_level_error,
    ecef,
    encode_tile,
    lattice,
    tile_rect,
)
from geoterrain.export.qmeshtin import (
    EDGE_SHARE,
    MIN_THRESHOLD,
    hilbert_order,
    measured_error,
    tin_tile,
)
from geoterrain.lod.kernels import close_upward, extract
from geoterrain.lod.mesh import orient_ccw

log = logging.getLogger("geoterrain")

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

MEASURE_SAMPLES = 1 << 20  # DEM samples measured per block
TILE_MESHERS = ("rtin", "tin")
#: Each tile's mesher by default: the greedy TIN (0.44× rtin's bytes on srtm1_japan at the
#: same per-level errors, the same time once its kernels are compiled; docs/lab/qmesh-tin.md)
DEFAULT_TILE_MESHER = "tin"


# ------------------------------------------------------------------------- one tile
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


def build_tile(dem: GeoDem, z: int, x: int, y: int, M: int, target: float,
               hrange: tuple[float, float], flat: bool = False, *,
               fixed_threshold: float | None = None,
               mesher: str = "rtin") -> tuple[bytes, float, int, dict] | None:
    """One tile's bytes, declared error bound (metres), triangle count and the terms of
    the bound; None if no data. ``mesher="tin"``: the greedy TIN of the lattice
    (:func:`_build_tin`, its declared error measured); the rest of this docstring is
    the lattice's bintree cut (``"rtin"``).

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
    lon, lat = lattice(rect, M)
    h = np.full(lon.shape, hrange[0]) if flat else dem.bilinear(lon, lat)
    valid = np.isfinite(h)
    if valid.sum() < 3:
        return None
    h0, h1 = hrange
    e_h = 0.5 * (h1 - h0) / QMAX * (1 + 1e-9)
    dlon, dlat = 0.5 * (e - w) / QMAX, 0.5 * (n - s_) / QMAX
    if mesher == "tin" and not flat:
        return _build_tin(dem, rect, M, lon, lat, h, valid, target, hrange, fixed_threshold)
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
        res = select_tile(dem, rect, M, lon, lat, h, valid, delta, thr, hrange, flat)
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


def _build_tin(dem: GeoDem, rect, M: int, lon, lat, h, valid, target: float, hrange,
               fixed_threshold: float | None):
    """A TIN tile (:mod:`geoterrain.export.qmeshtin`): edges simplified within the
    level's edge threshold (``fixed_threshold`` at max zoom, else ``EDGE_SHARE`` ×
    ``target``: the same for every tile of the level, so neighbours keep the same edge
    points), the interior within the tile's threshold: ``fixed_threshold``, or below max
    zoom ``target`` less the lattice's resampling error and the quantisation terms (as
    the lattice tiles' first threshold), lowered while the measured error exceeds
    ``target``. The declared error is the measured one (:func:`measured_error`), plus
    1 µm for rounding."""
    w, s_, e, n = rect
    slon, slat, sh = dem.samples(rect)
    e_h = 0.5 * (hrange[1] - hrange[0]) / QMAX
    if fixed_threshold is not None:
        thr = tau = fixed_threshold
        e_r = None
    else:
        tau = EDGE_SHARE * target
        e_r = _resampling_error(dem, rect, h, valid)
        fine, fidx = _fine_faces(M)
        fine = fine[valid.ravel()[fidx][fine].all(1)]
        e_uv = _slope_bound(lon.ravel()[fidx], lat.ravel()[fidx],
                            np.nan_to_num(h.ravel()[fidx], nan=0.0), fine,
                            0.5 * (e - w) / QMAX, 0.5 * (n - s_) / QMAX)
        thr = max(target - e_r - e_h - e_uv, MIN_THRESHOLD)
    for _ in range(6):
        ij, faces = tin_tile(h, valid, thr, tau)
        if len(faces) == 0:
            return None
        faces = faces[hilbert_order(ij, faces)]  # neighbours close: smaller deltas, better gzip
        # every valid edge point, drawn or not: next to nodata one side may leave a hole
        # where the other draws, and both must still list the same edge vertices
        r, c = ij[:, 0], ij[:, 1]
        edge = np.flatnonzero(((r == 0) | (r == M - 1) | (c == 0) | (c == M - 1)) & valid[r, c])
        data, faces, vlon, vlat, _, hq = _encode(dem, rect, M, lon, lat, h, ij, faces, hrange,
                                                 False, edge)
        bound = measured_error(rect, vlon, vlat, hq, faces, hrange, slon, slat, sh) + 1e-6
        if fixed_threshold is not None or bound <= target or thr <= MIN_THRESHOLD:
            break
        thr = max(thr - (bound - target), 0.5 * thr, MIN_THRESHOLD)
    info = {"M": M, "e_r": e_r, "e_h": e_h, "threshold": thr, "edge_threshold": tau,
            "fits": bound <= target}
    return data, bound, len(faces), info


def select_tile(dem: GeoDem, rect, M: int, lon, lat, h, valid, delta, thr: float, hrange,
            flat: bool):
    """The tile's bytes, faces, largest left-out δ and slope term at threshold ``thr``."""
    w, s_, e, n = rect
    dlon, dlat = 0.5 * (e - w) / QMAX, 0.5 * (n - s_) / QMAX
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
    edge = None
    if not flat:  # every valid edge sample, drawn or not (as _build_tin's): next to nodata
        # one side may leave a hole where the other draws, and both must list the same
        r, c = ij[:, 0], ij[:, 1]
        edge = np.flatnonzero(((r == 0) | (r == M - 1) | (c == 0) | (c == M - 1)) & valid[r, c])
    data, faces, vlon, vlat, vh, _ = _encode(dem, rect, M, lon, lat, h, ij, faces, hrange, flat,
                                             edge)
    if flat:  # two triangles (L is the mesh itself): the measured error is exact
        d_max, e_uv = 0.0, 0.0
    else:
        left_out = valid & ~active & np.isfinite(delta)
        d_max = float(delta[left_out].max(initial=0.0))
        e_uv = _slope_bound(vlon, vlat, vh, faces, dlon, dlat)
    return data, faces, d_max, e_uv


def _encode(dem: GeoDem, rect, M: int, lon, lat, h, ij, faces, hrange, flat: bool,
            extra: np.ndarray | None = None):
    """A tile's bytes from lattice vertices ``ij`` (rows, columns) and ``faces``; also the
    faces renumbered in first-use order and the used vertices' lon, lat, height and
    quantised height. ``extra``: vertices (indices into ``ij``) written even if no face
    uses them, after the used ones."""
    h0, h1 = hrange
    faces = orient_ccw(ij, faces.astype(np.int64))
    # vertices in order of first use (the high-water-mark index coding needs it)
    big = faces.size + len(ij)
    first = np.full(len(ij), big, np.int64)
    np.minimum.at(first, faces.ravel(), np.arange(faces.size))
    if extra is not None:
        first[extra] = np.minimum(first[extra], faces.size + np.arange(len(extra)))
    used = np.flatnonzero(first < big)
    order = used[np.argsort(first[used], kind="stable")]
    remap = np.full(len(ij), -1, np.int64)
    remap[order] = np.arange(len(order))
    faces, ij = remap[faces], ij[order]
    vlon, vlat = lon[ij[:, 0], ij[:, 1]], lat[ij[:, 0], ij[:, 1]]
    vh = h[ij[:, 0], ij[:, 1]]
    hq = np.clip(np.round((vh - h0) / (h1 - h0) * QMAX), 0, QMAX).astype(np.int64)
    if flat:
        nrm = ecef(vlon, vlat, np.ones(len(vlon))) - ecef(vlon, vlat, np.zeros(len(vlon)))
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    else:
        nrm = lattice_normals(dem, rect, M)[ij[:, 0], ij[:, 1]]
    if len(order) > 65536:
        raise _TooManyVertices(f"a tile has {len(order)} vertices, more than 16-bit indices hold")
    data = encode_tile(vlon, vlat, hq, faces, hrange, rect, nrm)
    return data, faces, vlon, vlat, vh, hq


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


def lattice_has_triangle(valid: np.ndarray) -> np.ndarray:
    """Whether each (…, M, M) lattice validity holds a triangle of the full-resolution RTIN
    triangulation (:func:`_diagonals`) with three valid corners: exactly the lattices on
    which :func:`select_tile`'s cut has a face at any threshold (a cut triangle over a mix
    of valid and invalid samples is always split, δ being +inf on a mixed diamond), so
    exactly the rtin tiles :func:`build_tile` gives.

    Examples
    --------
    >>> v = np.zeros((3, 3), bool); v[0, :2] = v[1, 1] = True  # the cell's triangle
    >>> w = np.zeros((3, 3), bool); w[0, :2] = w[1, 0] = True  # across its diagonal
    >>> bool(lattice_has_triangle(v)), bool(lattice_has_triangle(w))
    (True, False)
    """
    M = valid.shape[-1]
    main = _diagonals(M)
    k00, k01 = valid[..., :-1, :-1], valid[..., :-1, 1:]
    k10, k11 = valid[..., 1:, :-1], valid[..., 1:, 1:]
    tri = np.where(main, k00 & k11 & (k01 | k10), k01 & k10 & (k00 | k11))
    return tri.any(axis=(-2, -1))


def _resampling_error(dem: GeoDem, rect, h: np.ndarray, valid: np.ndarray) -> float:
    """Largest |L − DEM| at the valid DEM samples inside ``rect``, L being the lattice
    heights ``h`` on the full-resolution RTIN triangulation (triangles with an invalid
    corner are holes: their samples are skipped). Vectorised: cell, side of the
    diagonal, then the triangle's linear interpolation."""
    M = h.shape[0]
    w, s, e, n = rect
    i0, i1, j0, j1 = dem.box(rect)
    cols = dem.columns(j0, j1)
    if i1 < i0 or not len(cols):
        return 0.0
    main = _diagonals(M)
    worst = 0.0
    rows = max(1, MEASURE_SAMPLES // len(cols))
    for r0 in range(i0, i1 + 1, rows):  # every sample, a block of rows at a time
        ii, jj = np.meshgrid(np.arange(r0, min(i1 + 1, r0 + rows)), cols, indexing="ij")
        ok = dem.valid[ii, jj]
        ii, jj = ii[ok], jj[ok]
        slon, slat = dem.lonlat(ii, jj)
        slon = w + np.mod(slon - w, 360.0)  # the tile's turn
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
                  progress: Callable[[str, int, int], None] | None = None,
                  mesher: str = DEFAULT_TILE_MESHER) -> dict:
    """Write a quantized-mesh tile set of ``terrain`` into ``out_dir``; returns its figures.

    ``lattice`` (2^k + 1 samples a side) ≤ 129 keeps tiles within 16-bit indices.
    ``geoid="egm96"``: the DEM holds EGM96 heights (SRTM does); the tiles get WGS 84
    ellipsoidal heights (:func:`geoid_transformer`), and the declared errors are against
    those. ``mesher``: ``"rtin"``, the lattice's bintree cut with an a-priori bound, or
    ``"tin"``, a greedy TIN of the lattice with its error measured (:func:`_build_tin`).
    """
    check_tile_mesher(mesher)
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
    dem = GeoDem(terrain, geoid)
    w, s, e, n = dem.extent()
    hv = dem.h[dem.valid]
    hrange = (float(np.floor(hv.min())), float(np.ceil(hv.max())))
    if hrange[1] <= hrange[0]:
        hrange = (hrange[0], hrange[0] + 1.0)
    jobs = []
    for z in range(min_zoom, zmax + 1):
        size = 180.0 / (1 << z)
        # a grid past the antimeridian (170°…190°) wraps onto the western tiles
        span = range(int((w + 180) // size), int(math.ceil((e + 180) / size)))
        xs = list(dict.fromkeys(x % (2 << z) for x in span))[:2 << z]
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
                    built = _build_level(dem, z, xys, M, target, hrange, fixed, data_from,
                                         mesher)
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
                             "max_resampling": max((r[3]["e_r"] for r in tiles.values()
                                                    if r[3].get("e_r") is not None),
                                                   default=None),
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
        "tiles": ["{z}/{x}/{y}.terrain?v={version}"], "bounds": lonlat_bounds(w, s, e, n),
        "minzoom": min_zoom, "maxzoom": zmax,
        "available": [availability_ranges(available.get(z, [])) for z in range(zmax + 1)],
        "extensions": ["octvertexnormals", "watermask"],
        "attribution": "geoterrain",
    }
    stats = {"tiles": len(errors), "bytes": nbytes, "seconds": round(seconds, 2), "mesher": mesher,
             "triangles": triangles, "min_zoom": min_zoom, "max_zoom": zmax,
             "lattice": lattice, "max_error": max_error, "height_range": list(hrange),
             "heights": f"WGS 84 ellipsoidal (from {geoid.upper()})" if geoid else "as stored",
             "over_level_error": sum(v["over_level_error"] for v in levels.values()),
             "levels": levels, "declared_error": errors}
    write_atomic(out / "layer.json", json.dumps(layer, indent=1), overwrite)
    write_atomic(out / "geoterrain.json", json.dumps(stats, indent=1), overwrite)
    return {k: v for k, v in stats.items() if k not in ("declared_error", "levels")}


def _build_level(dem: GeoDem, z: int, xys, M: int, target: float, hrange, fixed, data_from: int,
                 mesher: str = "rtin"):
    """Every tile of level ``z`` on an M-lattice: {(x, y): build_tile's result}. A level
    with no lattice data coarser than the first with some gets flat tiles; a level with
    data gets none, whatever the order of its tiles (a flat tile beside a data tile
    would list other vertices, at other heights, along their shared edge)."""
    tiles = {}
    for x, y in xys:
        res = build_tile(dem, z, x, y, M, target, hrange, fixed_threshold=fixed, mesher=mesher)
        if res is not None:
            tiles[(x, y)] = res
    if tiles:
        data_from = min(data_from, z)
    elif z < data_from:
        for x, y in xys:
            res = build_tile(dem, z, x, y, M, target, hrange, flat=True, fixed_threshold=fixed)
            if res is not None:
                tiles[(x, y)] = res
    return tiles, data_from


def check_tile_mesher(mesher: str) -> None:
    """A quantized-mesh tile mesher name, or a UsageError."""
    if mesher not in TILE_MESHERS:
        raise UsageError(f"unknown tile mesher {mesher!r}: use one of {', '.join(TILE_MESHERS)}")


def availability_ranges(tiles: list[tuple[int, int]]) -> list[dict]:
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
