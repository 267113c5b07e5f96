"""quantized-mesh-1.0 bytes: the geographic tiling scheme, one tile's encoding, and
the extension blocks a server adds or strips.

What CesiumJS's ``CesiumTerrainProvider`` reads: a header (centre, height range,
bounding sphere, horizon occlusion point), zig-zag delta-coded u, v, h quantised to
0..32767 over the tile's rectangle, high-water-mark-coded indices, the four edge
vertex lists, then extensions (oct-encoded normals, a water mask, metadata).

Examples
--------
>>> cesium_level_error(0) > cesium_level_error(1) > 0
True
>>> tile_rect(1, 3, 1)
(90.0, 0.0, 180.0, 90.0)
>>> len(_tiny_tile()) > 88
True
"""

from __future__ import annotations

import json
import math

import numpy as np
from pyproj import Transformer

from geoterrain.exceptions import UsageError

WGS84_A = 6378137.0
WGS84_B = 6356752.3142451793
QMAX = 32767


def cesium_level_error(z: int, tile_width: int = 65) -> float:
    """Cesium's ``levelMaximumGeometricError`` (metres) of a geographic-scheme level."""
    return WGS84_A * 2 * math.pi * 0.25 / (tile_width * 2 * (1 << z))


def tile_rect(z: int, x: int, y: int) -> tuple[float, float, float, float]:
    """(west, south, east, north) in degrees of TMS tile (z, x, y), geographic scheme."""
    s = 180.0 / (1 << z)
    return -180.0 + x * s, -90.0 + y * s, -180.0 + (x + 1) * s, -90.0 + (y + 1) * s



def ecef(lon, lat, h):
    """ECEF (x, y, z) metres of lon/lat/ellipsoidal height (pyproj EPSG:4979 → 4978)."""
    tr = ecef.tr  # type: ignore[attr-defined]
    x, y, z = tr.transform(lon, lat, h)
    return np.stack([np.asarray(x), np.asarray(y), np.asarray(z)], axis=-1)


ecef.tr = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)  # type: ignore


def lattice(rect, M: int, margin: int = 0):
    """Lon/lat of a tile's M × M lattice (row 0 north), with ``margin`` extra rings."""
    w, s, e, n = rect
    k = np.arange(-margin, M + margin)
    lon = w + (e - w) * k / (M - 1)
    lat = n - (n - s) * k / (M - 1)  # row 0 = north, like the DEM
    return np.meshgrid(lon, lat)


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
    p = ecef(w + (e - w) * u / QMAX, s + (n - s) * v / QMAX, hh)
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


def _tiny_tile() -> bytes:
    """A two-triangle tile (the doctests' example)."""
    rect = tile_rect(0, 0, 0)
    lon, lat = lattice(rect, 3)
    n = np.tile([0.0, 0.0, 1.0], (4, 1))
    faces = np.array([[0, 1, 2], [2, 1, 3]])
    return encode_tile(lon[::2, ::2].ravel(), lat[::2, ::2].ravel(), np.array([0, 1, 2, 3]),
                       faces, (0.0, 1.0), rect, n)
