"""What the globe's heights come from: stores placed on the planet, and a base layer.

A :class:`StoreLayer` reads one ``.geoterrain`` store through
:class:`~geoterrain.terrainlike.TerrainLike` at geodetic (lon, lat): pyproj takes WGS 84
lon, lat to the store's CRS, its geotransform to a (row, column) of pyramid level s, and
the height is the bilinear interpolant of that level's four samples around it (NaN where
one of them is no data or padding: the next layer shows there); a root-grid store's
level is read from its tiles across and down, as a square store's. A store spanning 360° of
longitude interpolates across the antimeridian (its last column to its first); one that
reaches a pole blends its polar row into the row's mean at the pole, so the surface is
continuous there (no tear, no spike).

**Which level a node reads** (seed 001 L537, the depth from the resolution): a node of
depth D, whose vertices are about Δ_D apart, reads the coarsest store level whose samples
are no farther apart than Δ_D (the finest level it could show), so a view from space
decodes a few coarse tiles, never the whole store. The store's own error is then carried
into the node's error by measuring against the store's full resolution
(:mod:`geoterrain.globe.errors`). A store is "resolved" at depth D_s =
⌈log₂(E_face / (n·s))⌉ (the seed's formula, L493; s its sample spacing, E_face the RT
face's mean edge, n a node's cells): at D_s its vertices are at most s apart
(:func:`resolved_depth`).

The :class:`BaseLayer` is under every store: seed 001's procedural planet
(:class:`~geoterrain.globe.noise.Planet`), the bare ellipsoid (h = 0), or a user's global
store.

Examples
--------
>>> b = BaseLayer.ellipsoid()
>>> b.heights(np.array([10.0]), np.array([20.0]), np.array([[1.0, 0, 0]])).tolist()
[0.0]
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from pyproj import CRS, Geod, Transformer

from geoterrain.exceptions import InputError
from geoterrain.globe.noise import Planet

__all__ = ["StoreLayer", "BaseLayer", "FACE_EDGE_M", "resolved_depth"]

FACE_EDGE_M = 4_156_000.0  # the RT face's mean spherical edge at R = 6 371 km (seed 001 §2.2)
MAX_DEPTH = 24
FEATHER = 32.0  # samples over which a store's edge blends into the layers under it
TILE_CACHE = 2048  # decoded tiles a store layer keeps, in metres (65² float64: 33 kB each)


def resolved_depth(spacing_m: float, node_cells: int) -> int:
    """The first depth whose vertices are no farther apart than the data's samples:
    D = ⌈log₂(E_face / (n·s))⌉ (seed 001's formula, L493).

    The deepest nodes' flat triangles do not pass through the samples (the face lattice
    is not the store's grid), and their gap to them, which the nodes' errors count
    (:mod:`geoterrain.globe.errors`), falls with the vertex spacing: on srtm1_japan
    (s = 25 m, n = 16) up to 13.0 m at the nearest depth (31.7 m vertices), 7.7 m at this
    one (15.9 m). Since leaves are drawn from the eye on, ρ ≤ τ holds from λ·e/τ on: at
    τ = 1 and 320 × 240 pixels, 3.5 km rather than 5.8 km. The price is a level: four times
    the leaves' triangles where they are drawn.

    Examples
    --------
    >>> resolved_depth(30.0, 128), resolved_depth(90.0, 128), resolved_depth(1.0, 128)
    (11, 9, 15)
    """
    return int(min(MAX_DEPTH, max(0, math.ceil(math.log2(FACE_EDGE_M / (node_cells * spacing_m))
                                               - 1e-9))))


@dataclass
class _Geo:
    """A store's placement: WGS 84 → its CRS, its affine transform and what wraps."""

    to_crs: Transformer | None
    inv: tuple[float, ...]  # inverse affine: (x, y) → (col, row) of level-0 pixel centres
    west: float
    wrap: bool  # 360° of longitude
    north_pole: bool
    south_pole: bool


class StoreLayer:
    """One store on the globe. ``terrain``: a :class:`~geoterrain.terrainlike.TerrainLike`.

    Attributes: ``spacing`` (metres between level-0 samples, the finer of its two axes at
    the store's centre), ``name``, ``feather`` (samples of its edge that blend into what lies
    under it, :meth:`weight`) and :meth:`footprint` (a closed lon/lat outline).
    """

    def __init__(self, terrain, name: str | None = None, feather: float = FEATHER):
        self.terrain = terrain
        self.name = name or str(getattr(terrain, "path", "store"))
        self.feather = float(feather)
        fr, g = terrain.frame, terrain.grid
        if fr.kind == "pixel" or fr.crs_wkt is None:
            raise InputError(f"{self.name}: the store has no CRS, so it has no place on the "
                             "globe; preprocess a georeferenced DEM (or give its CRS)")
        crs = CRS.from_wkt(fr.crs_wkt)
        a, _, c, _, e, f = fr.transform
        self.geographic = fr.kind == "geographic"
        to_crs = None if (self.geographic and crs.geodetic_crs is not None and
                          crs.geodetic_crs.equals(CRS.from_epsg(4326).geodetic_crs)) \
            else Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        span = abs(a) * g.cols
        self._geo = _Geo(to_crs, (a, c, e, f), min(c, c + a * g.cols),
                         self.geographic and span >= 360.0 - 1e-6 * abs(a),
                         self.geographic and abs(max(f, f + e * g.rows) - 90.0) < 1e-9,
                         self.geographic and abs(min(f, f + e * g.rows) + 90.0) < 1e-9)
        self._lock = threading.Lock()
        self._tiles: OrderedDict[tuple[int, int, int], np.ndarray] = OrderedDict()
        self.spacing = self._spacing()
        self._lonlat_box = self._box()

    # ---------------------------------------------------------------- geometry
    def _spacing(self) -> float:
        fr, g = self.terrain.frame, self.terrain.grid
        a, _, c, _, e, f = fr.transform
        if self.geographic:
            lat = f + e * g.rows / 2
            geod = Geod(ellps="WGS84")
            lon = c + a * g.cols / 2
            _, _, ns = geod.inv(lon, lat, lon, lat + abs(e))
            _, _, ew = geod.inv(lon, lat, lon + abs(a), lat)
            return float(max(min(ns, ew if ew > 0 else ns), 1e-3))
        return float(abs(a) * fr.unit_to_m)

    def _box(self) -> tuple[float, float, float, float]:
        lon, lat = self.footprint()
        return float(lon.min()), float(lon.max()), float(lat.min()), float(lat.max())

    def footprint(self, per_side: int = 64, inset: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The outline of the data's rectangle (pixel centres) as WGS 84 lon, lat (a closed
        ring, ``per_side`` points a side), ``inset`` samples inside it."""
        fr, g = self.terrain.frame, self.terrain.grid
        k = np.linspace(0.0, 1.0, per_side, endpoint=False)
        a, H, W = inset, g.rows - 1 - 2 * inset, g.cols - 1 - 2 * inset
        i = a + np.concatenate([0 * k, k * H, H + 0 * k, H - k * H])
        j = a + np.concatenate([k * W, W + 0 * k, W - k * W, 0 * k])
        x, y = fr.crs_xy(i, j)
        if self._geo.to_crs is None:
            return np.asarray(x, np.float64), np.asarray(y, np.float64)
        lon, lat = self._geo.to_crs.transform(x, y, direction="INVERSE")
        return np.asarray(lon), np.asarray(lat)

    def covers_globe(self) -> bool:
        """Whether the store's data cover every longitude and both poles without a gap."""
        m = self.terrain.meta
        return bool(self._geo.wrap and self._geo.north_pole and self._geo.south_pole
                    and float(m.get("nodata_fraction", 1.0)) == 0.0)

    def covers(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Whether WGS 84 lon, lat lie in the rectangle of the store's pixel centres (its
        footprint; with a 360° store, every longitude; with a polar row, up to the pole)."""
        if self.covers_globe():
            return np.ones(np.shape(lon), bool)
        g = self.terrain.grid
        ri, cj = self.grid_coords(lon, lat)
        geo = self._geo
        with np.errstate(invalid="ignore"):
            rok = (ri >= (-0.5 if geo.north_pole else 0.0)) & \
                (ri <= (g.rows - 0.5 if geo.south_pole else g.rows - 1))
            cok = np.isfinite(cj) if geo.wrap else (cj >= 0.0) & (cj <= g.cols - 1)
        return rok & cok

    def in_band(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Whether lon, lat lie in the footprint's outer ``feather`` samples (0 < weight < 1)."""
        w = self.weight(lon, lat)
        return self.covers(lon, lat) & (w < 1.0)

    def weight(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """How much of this store a composite takes at lon, lat: 1 inside, falling to 0
        over the outer ``feather`` samples of its rectangle (a smoothstep), so a store
        meets what lies under it by a slope, not a wall. A 360° store has no east or west
        edge, a polar one no edge at its pole."""
        if self.covers_globe() or self.feather <= 0:
            return np.ones(np.shape(lon))
        g = self.terrain.grid
        ri, cj = self.grid_coords(lon, lat)
        geo = self._geo
        big = np.full(np.shape(ri), np.inf)
        e_n = big if geo.north_pole else ri
        e_s = big if geo.south_pole else (g.rows - 1) - ri
        e_w = big if geo.wrap else cj
        e_e = big if geo.wrap else (g.cols - 1) - cj
        with np.errstate(invalid="ignore"):
            t = np.clip(np.minimum(np.minimum(e_n, e_s), np.minimum(e_w, e_e)) / self.feather,
                        0.0, 1.0)
        t = np.where(np.isfinite(t), t, 0.0)
        return t * t * (3.0 - 2.0 * t)

    def edge_samples(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Level-0 samples (grid units) from lon, lat to the nearest side of the rectangle of
        the store's pixel centres, every side counted (a 360° store's seam and a polar row
        too); negative outside, NaN where lon, lat have no place in the store's CRS."""
        g = self.terrain.grid
        ri, cj = self.grid_coords(lon, lat)
        with np.errstate(invalid="ignore"):
            return np.minimum(np.minimum(ri, (g.rows - 1) - ri),
                              np.minimum(cj, (g.cols - 1) - cj))

    def ground_steps(self) -> tuple[float, float]:
        """The least ground distance (metres) of one level-0 step along a column and along a
        row anywhere in the store (geographic: the row step at the latitude farthest from the
        equator, the column step at the one nearest it; projected: the CRS step less 2 % for
        the projection's scale)."""
        fr, g = self.terrain.frame, self.terrain.grid
        a, _, c, _, e, f = fr.transform
        if not self.geographic:
            return abs(a) * fr.unit_to_m * 0.98, abs(e) * fr.unit_to_m * 0.98
        lats = np.clip(np.array([f, f + e * g.rows]), -89.999, 89.999)
        far = float(lats[np.argmax(np.abs(lats))])
        near = 0.0 if lats.min() <= 0.0 <= lats.max() else float(lats[np.argmin(np.abs(lats))])
        geod = Geod(ellps="WGS84")
        _, _, ew = geod.inv(0.0, far, abs(a), far)
        _, _, ns = geod.inv(0.0, near, 0.0, near + abs(e))
        return float(ew) * 0.999, float(ns) * 0.999

    def full_heights(self, rows_per_block: int = 256) -> np.ndarray:
        """Every level-0 sample's height (metres, the store's z scale; NaN: no data)."""
        g = self.terrain.grid
        out = np.empty((g.rows, g.cols))
        cols = np.arange(g.cols, dtype=np.int64)
        for r0 in range(0, g.rows, rows_per_block):
            rr = np.arange(r0, min(g.rows, r0 + rows_per_block), dtype=np.int64)
            R, C = np.meshgrid(rr, cols, indexing="ij")
            out[rr] = self._samples(0, R.ravel(), C.ravel()).reshape(R.shape)
        return out

    def level_for(self, spacing: float) -> int:
        """The coarsest store level whose samples are at most ``spacing`` metres apart."""
        top = self.terrain.grid.top_level
        if spacing <= self.spacing:
            return 0
        return int(min(top, math.floor(math.log2(spacing / self.spacing))))

    def grid_coords(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional level-0 (row, column) of WGS 84 lon, lat (pixel centres at integers)."""
        geo = self._geo
        lon = np.asarray(lon, np.float64)
        lat = np.asarray(lat, np.float64)
        if geo.to_crs is None:
            x = geo.west + np.mod(lon - geo.west, 360.0)
            y = lat
        else:
            with np.errstate(all="ignore"):
                x, y = geo.to_crs.transform(lon, lat)
            x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        a, c, e, f = geo.inv
        return (y - f) / e - 0.5, (x - c) / a - 0.5

    def samples(self, rows_per_block: int = 256):
        """The store's own samples, full resolution, where the globe shows them unblended
        (weight 1: outside the feathered edge), block of rows by block: yields WGS 84 lon,
        lat and heights (metres, the store's z scale), 1-D, no-data left out. These are the
        truth a node's error is measured against (:mod:`geoterrain.globe.errors`)."""
        fr, g = self.terrain.frame, self.terrain.grid
        cols = np.arange(g.cols, dtype=np.int64)
        for r0 in range(0, g.rows, rows_per_block):
            rr = np.arange(r0, min(g.rows, r0 + rows_per_block), dtype=np.int64)
            R, C = np.meshgrid(rr, cols, indexing="ij")
            h = self._samples(0, R.ravel(), C.ravel())
            x, y = fr.crs_xy(R.ravel().astype(np.float64), C.ravel().astype(np.float64))
            if self._geo.to_crs is None:
                lon, lat = np.asarray(x, np.float64), np.asarray(y, np.float64)
            else:
                lon, lat = self._geo.to_crs.transform(x, y, direction="INVERSE")
                lon, lat = np.asarray(lon, np.float64), np.asarray(lat, np.float64)
            ok = np.isfinite(h) & np.isfinite(lon) & np.isfinite(lat)
            ok[ok] = self.weight(lon[ok], lat[ok]) >= 1.0
            if ok.any():
                yield lon[ok], lat[ok], h[ok]

    # ----------------------------------------------------------------- heights
    def _tile(self, level: int, y: int, x: int) -> np.ndarray:
        """Tile (level, x, y)'s heights in metres (T, T), NaN where there is no data; the
        last ``TILE_CACHE`` tiles asked for are kept (the store's own cache keeps codes)."""
        key = (level, y, x)
        h = self._tiles.get(key)
        if h is not None:
            self._tiles.move_to_end(key)
            return h
        t = self.terrain
        T = t.grid.tile_samples
        h = t.frame.z(t.tile(level, x, y).heights) if (level, x, y) in t.tile_info \
            else np.full((T, T), np.nan)
        self._tiles[key] = h
        if len(self._tiles) > TILE_CACHE:
            self._tiles.popitem(last=False)
        return h

    def _samples(self, level: int, r: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Level-``level`` sample heights at integer (row, column) (NaN outside or no data)."""
        t = self.terrain
        g = t.grid
        n_r, n_c = g.level_shape(level)  # (n, n) on a square grid; a root grid's lattice
        out = np.full(r.shape, np.nan)
        ok = (r >= 0) & (c >= 0) & (r < n_r) & (c < n_c)
        if not ok.any():
            return out
        rr, cc = r[ok], c[ok]
        across, down = g.tiles(level)
        ty = np.minimum(rr >> g.t, down - 1)
        tx = np.minimum(cc >> g.t, across - 1)
        key = ty * across + tx
        present = np.zeros(across * down, bool)
        present[key] = True
        need = np.flatnonzero(present)
        T = g.tile_samples
        stack = np.empty((len(need), T, T))
        with self._lock:
            for n_, k in enumerate(need.tolist()):
                y, x = divmod(k, across)
                stack[n_] = self._tile(level, y, x)
        slot = np.zeros(across * down, np.int64)
        slot[need] = np.arange(len(need))
        out[ok] = stack[slot[key], rr - (ty << g.t), cc - (tx << g.t)]
        return out

    def heights(self, lon: np.ndarray, lat: np.ndarray, level: int) -> np.ndarray:
        """Bilinear heights (metres, the store's z scale) of pyramid level ``level`` at WGS 84
        lon, lat; NaN where any of the four samples is missing."""
        lon = np.asarray(lon, np.float64)
        lat = np.asarray(lat, np.float64)
        shape = lon.shape
        lon, lat = lon.ravel(), lat.ravel()
        out = np.full(lon.shape, np.nan)
        cand = np.ones(lon.shape, bool)
        if self.geographic and self._geo.to_crs is None and not self._geo.wrap:
            L0, L1, A0, A1 = self._lonlat_box
            pad = 2.0 * (1 << level) * abs(self.terrain.frame.transform[0])
            cand = (np.mod(lon - L0 + pad, 360.0) <= (L1 - L0) + 2 * pad) & \
                (lat >= A0 - pad) & (lat <= A1 + pad)
        if not cand.any():
            return out.reshape(shape)
        out[cand] = self._heights(*self.grid_coords(lon[cand], lat[cand]), level)
        return out.reshape(shape)

    def _heights(self, ri0: np.ndarray, cj0: np.ndarray, level: int) -> np.ndarray:
        """Bilinear level-s heights at fractional level-0 (row, column)."""
        g = self.terrain.grid
        S = 1 << level
        rows = -(-g.rows // S)  # level-s samples with data: ceil(rows / 2^s)
        cols = -(-g.cols // S)
        fin = np.isfinite(ri0) & np.isfinite(cj0)
        ri0 = np.where(fin, ri0, -1e9)
        cj0 = np.where(fin, cj0, -1e9)
        r0 = np.floor(ri0 / S).astype(np.int64)
        c0 = np.floor(cj0 / S).astype(np.int64)
        fr = ri0 / S - r0
        fc = cj0 / S - c0
        c1 = c0 + 1
        if self._geo.wrap:
            # the cell from the last level-s column to the first one, 360° on
            last0 = (cols - 1) * S
            cw = np.where(cj0 < 0, cj0 + g.cols, cj0)
            wrap = cw > last0
            c0 = np.where(wrap, cols - 1, c0)
            c1 = np.where(wrap, 0, c1)
            fc = np.where(wrap, (cw - last0) / (g.cols - last0), fc)
        r1 = r0 + 1
        h4 = self._samples(level, np.concatenate([r0, r0, r1, r1]),
                           np.concatenate([c0, c1, c0, c1])).reshape(4, -1)
        h = (1 - fr) * ((1 - fc) * h4[0] + fc * h4[1]) + fr * ((1 - fc) * h4[2] + fc * h4[3])
        geo = self._geo
        if geo.north_pole or geo.south_pole:
            last_r0 = (rows - 1) * S
            north = geo.north_pole & (ri0 < 0) & (ri0 >= -0.5)
            south = geo.south_pole & (ri0 > last_r0) & (ri0 <= g.rows - 0.5)
            for m, row, pole in ((north, 0, -0.5), (south, rows - 1, g.rows - 0.5)):
                if m.any():
                    h[m] = self._polar(level, row, (ri0[m] - row * S) / (pole - row * S),
                                       cj0[m] / S, cols)
        return h

    def _polar(self, level: int, row: int, w: np.ndarray, cj: np.ndarray,
               cols: int) -> np.ndarray:
        """Between a polar data row and its pole: the row's height (interpolated along the
        row, wrapping) blended by ``w`` (0 on the row, 1 at the pole) into the row's mean,
        which the pole takes at every longitude."""
        c0 = np.floor(cj).astype(np.int64)
        fc = cj - c0
        rr = np.full(c0.shape, row, np.int64)
        edge = (1 - fc) * self._samples(level, rr, np.mod(c0, cols)) \
            + fc * self._samples(level, rr, np.mod(c0 + 1, cols))
        allc = self._samples(level, np.full(cols, row, np.int64),
                             np.arange(cols, dtype=np.int64))
        mean = float(np.mean(allc)) if np.isfinite(allc).all() else np.nan
        w = np.clip(w, 0.0, 1.0)
        return (1 - w) * edge + w * mean


class BaseLayer:
    """The layer under every store: ``kind`` "procedural" (seed 001's planet, a
    :class:`~geoterrain.globe.noise.Planet`), "ellipsoid" (h = 0) or "store" (a global
    :class:`StoreLayer`, with h = 0 where it has no data)."""

    def __init__(self, kind: str, planet: Planet | None = None,
                 store: StoreLayer | None = None):
        self.kind, self.planet, self.store = kind, planet, store

    @staticmethod
    def ellipsoid() -> BaseLayer:
        return BaseLayer("ellipsoid")

    @staticmethod
    def procedural(seed: int = 1) -> BaseLayer:
        return BaseLayer("procedural", Planet(seed=seed))

    def heights(self, lon: np.ndarray, lat: np.ndarray, d: np.ndarray,
                level: int = 0) -> np.ndarray:
        """Heights (metres) at lon, lat, whose unit directions are ``d`` (..., 3)."""
        if self.kind == "procedural":
            return self.planet.heights(d)
        if self.kind == "store":
            h = self.store.heights(lon, lat, level)
            return np.where(np.isfinite(h), h, 0.0)
        return np.zeros(np.shape(lon))
