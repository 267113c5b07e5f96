"""Where a quantized-mesh tile samples the store: the DEM's full-resolution heights
in metres (optionally EGM96 → WGS 84 ellipsoidal, through pyproj), bilinear at any
lon/lat, and ECEF normals on a tile's lattice.

Examples
--------
>>> dem = GeoDem(t, heights=False)
>>> (dem.H, dem.W) == (t.grid.rows, t.grid.cols)
True
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pyproj import CRS, Transformer

from geoterrain.exceptions import UsageError
from geoterrain.export.qmeshformat import ecef, lattice
from geoterrain.export.webtiles import fold_lon

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


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


class GeoDem:
    """The store's full-resolution heights (metres) and where lon/lat fall on them.

    ``geoid``: the heights are EGM96 orthometric heights; convert them to WGS 84
    ellipsoidal heights (what CesiumJS assumes) at every sample, through pyproj.
    ``window``: ((i0, i1), (j0, j1)), the level-0 rows and columns (inclusive) to read;
    only the stored tiles under them are decoded, and sample (i, j) of the arrays is
    sample (i0 + i, j0 + j) of the grid (positions are computed on the whole grid and
    the integer offset subtracted, exactly, so two windows agree on a shared sample).
    ``heights=False``: the georeference alone (no tile is decoded); with ``mask``, an
    (H, W) bool array, the validity too (:meth:`valid_at`; no heights: ``h`` is empty).
    """

    def __init__(self, terrain: TerrainLike, geoid: str | None = None,
                 window: tuple[tuple[int, int], tuple[int, int]] | None = None,
                 heights: bool = True, mask: np.ndarray | None = None):
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
        # a whole-globe grid's columns wrap: local column k is the grid's column
        # (j0 + k) mod turn, and the arrays of the whole grid carry column 0 again after
        # the last, so a lookup between the two interpolates across the antimeridian
        self.turn = f.columns_per_turn
        # a geographic grid's longitudes may run past ±180° (170°…190°, or 0°…360°): a
        # longitude is taken to within 180° of the grid's centre before it is looked up,
        # so the tiles west of the antimeridian find the grid's east end (and a tile's
        # border maps without a jump unless the tile holds the centre's antipode)
        self.centre = (float(self.lonlat(np.array([(self.H - 1) / 2]),
                                         np.array([(self.W - 1) / 2]))[0][0])
                       if crs.is_geographic else None)
        if not heights:
            self.h, self.valid = np.full((0, 0), np.nan), np.zeros((0, 0), bool)
            if mask is not None:
                if mask.shape != (self.H, self.W):
                    raise ValueError(f"mask {mask.shape} is not the grid's {(self.H, self.W)}")
                self.valid = self._wrapped(np.asarray(mask, bool))
            self.W += 1 if self.turn else 0
            return
        if window is None:
            h, v = terrain.level_heights(0)
            H, W = self.H, self.W
            self.h = self._wrapped((h[:H, :W] * f.z_to_m).astype(np.float64))
            self.valid = self._wrapped(v[:H, :W].copy())
            self.W = self.h.shape[1]
        else:
            from geoterrain.export.webtiles import wrapped_window

            (i0, i1), (j0, j1) = window
            i0, i1 = max(int(i0), 0), min(int(i1), self.H - 1)
            if self.turn:  # any columns, taken modulo the turn (at most one turn here)
                j0, j1 = int(j0) % self.turn, int(j1) - int(j0) + int(j0) % self.turn
                if j1 - j0 + 1 >= self.turn:
                    j0, j1 = 0, self.turn  # the whole turn and column 0 again
            else:
                j0, j1 = max(int(j0), 0), min(int(j1), self.W - 1)
            self.h = wrapped_window(terrain, 0, (i0, i1), (j0, j1),
                                    lambda ks: [terrain.tile(*k).heights for k in ks],
                                    period=self.turn)[..., 0]
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

    def _wrapped(self, a: np.ndarray) -> np.ndarray:
        """``a`` (the whole grid's columns) with column 0 again after the last on a
        whole-globe grid; ``a`` itself on any other."""
        return np.concatenate([a, a[:, :1]], axis=1) if self.turn else a

    def columns(self, j0: int, j1: int) -> np.ndarray:
        """Local columns j0..j1 that the arrays hold: clipped to them; on a whole-globe
        grid taken modulo the turn first (each column once), so a range may run past
        either end.

        >>> GeoDem(t, heights=False).columns(-2, 3).tolist()[:4]
        [0, 1, 2, 3]
        """
        if not self.turn:
            return np.arange(max(j0, 0), min(j1, self.W - 1) + 1)
        k = np.unique(np.mod(np.arange(j0, j1 + 1), self.turn))
        return k[k < self.W]

    def contiguous(self, j: np.ndarray) -> np.ndarray:
        """Local columns ``j`` (of :meth:`pixel`) made continuous on a whole-globe grid:
        each within half a turn of the first finite one, so a rectangle across the
        antimeridian spans a few columns, not the whole turn; ``j`` on any other grid."""
        j = np.asarray(j, np.float64)
        if not self.turn or not np.isfinite(j).any():
            return j
        ref = j[np.isfinite(j)][0]
        return ref + np.mod(j - ref + self.turn / 2, self.turn) - self.turn / 2

    def unwrap(self, lon: np.ndarray) -> np.ndarray:
        """``lon`` (degrees) taken to the grid's turn: whole turns added, to within 180°
        of its centre; as given on a projected grid (its projection takes any
        longitude)."""
        lon = np.asarray(lon, np.float64)
        if self.centre is None:
            return lon
        return lon + 360.0 * np.round((self.centre - lon) / 360.0)

    def lonlat(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lon/lat of (fractional) sample positions (pixel centres at integers)."""
        a, b, c, d, e, f = self.transform[:6]
        jj = np.asarray(j, np.float64) + (0.5 + self.j0)
        ii = np.asarray(i, np.float64) + (0.5 + self.i0)
        lon, lat = self.to_geo.transform(a * jj + b * ii + c, d * jj + e * ii + f)
        return np.asarray(lon), np.asarray(lat)

    def pixel(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional sample row, column of lon/lat (north-up grids, frame.py's rule; any
        longitude, :meth:`unwrap`)."""
        x, y = self.to_src.transform(self.unwrap(lon), lat)
        a, _, c, _, e, f = self.transform[:6]
        j = ((np.asarray(x) - c) / a - 0.5) - self.j0
        if self.turn:  # the local column within the turn that starts at the window
            j = np.mod(j, self.turn)
        return ((np.asarray(y) - f) / e - 0.5) - self.i0, j

    def _corners(self, lon: np.ndarray, lat: np.ndarray):
        """The bilinear neighbours of lon/lat: ``ok`` (inside the grid), and for the points
        inside, rows i0, i1, columns j0, j1 and the fractions fi, fj."""
        i, j = self.pixel(lon, lat)
        ok = (i >= 0) & (i <= self.H - 1) & (j >= 0) & (j <= self.W - 1)
        i0 = np.clip(np.floor(i[ok]).astype(np.int64), 0, max(self.H - 2, 0))
        j0 = np.clip(np.floor(j[ok]).astype(np.int64), 0, max(self.W - 2, 0))
        fi, fj = i[ok] - i0, j[ok] - j0
        i1, j1 = np.minimum(i0 + 1, self.H - 1), np.minimum(j0 + 1, self.W - 1)
        return ok, i0, i1, j0, j1, fi, fj

    def box(self, rect) -> tuple[int, int, int, int]:
        """Rows i0..i1 and columns j0..j1 of the samples that may lie inside ``rect`` (w,
        s, e, n degrees; its border mapped through pyproj, a sample's margin); the whole
        grid where a point of the border has no image in the DEM's CRS (a coarse tile
        reaching past the projection's domain). On a whole-globe grid the columns are
        not clipped: they may run past either end (read them through :meth:`columns`)."""
        w, s, e, n = rect
        bl, bt = np.linspace(w, e, 17), np.linspace(s, n, 17)
        bi, bj = self.pixel(np.concatenate([bl, bl, bl * 0 + w, bl * 0 + e]),
                            np.concatenate([bt * 0 + s, bt * 0 + n, bt, bt]))
        if not (np.isfinite(bi).all() and np.isfinite(bj).all()):
            return 0, self.H - 1, 0, self.W - 1
        i0 = max(0, int(np.floor(bi.min())) - 1)
        i1 = min(self.H - 1, int(np.ceil(bi.max())) + 1)
        if self.turn:  # columns past either end wrap (:meth:`columns`)
            bj = self.contiguous(bj)
            return i0, i1, int(np.floor(bj.min())) - 1, int(np.ceil(bj.max())) + 1
        j0 = max(0, int(np.floor(bj.min())) - 1)
        j1 = min(self.W - 1, int(np.ceil(bj.max())) + 1)
        return i0, i1, j0, j1

    def samples(self, rect) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lon (in the tile's turn), lat and height of every valid sample inside ``rect``
        (closed)."""
        w, s, e, n = rect
        i0, i1, j0, j1 = self.box(rect)
        cols = self.columns(j0, j1)
        if i1 < i0 or not len(cols):
            return np.zeros(0), np.zeros(0), np.zeros(0)
        ii, kk = np.nonzero(self.valid[i0:i1 + 1, cols])
        ii, jj = ii + i0, cols[kk]
        slon, slat = self.lonlat(ii, jj)
        slon = w + np.mod(slon - w, 360.0)  # the tile's turn (a grid past the antimeridian)
        inside = (slon >= w) & (slon <= e) & (slat >= s) & (slat <= n)
        return slon[inside], slat[inside], self.h[ii[inside], jj[inside]]

    def bilinear(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """Heights (metres) at lon/lat; NaN where a neighbouring sample is invalid/outside."""
        ok, i0, i1, j0, j1, fi, fj = self._corners(lon, lat)
        out = np.full(ok.shape, np.nan)
        h = self.h
        out[ok] = ((h[i0, j0] * (1 - fj) + h[i0, j1] * fj) * (1 - fi)
                   + (h[i1, j0] * (1 - fj) + h[i1, j1] * fj) * fi)
        return out

    def valid_at(self, lon: np.ndarray, lat: np.ndarray, inside: bool = False):
        """Where :meth:`bilinear` gives a height (all four neighbours valid, inside the
        grid), from the validity alone: ``np.isfinite(bilinear(lon, lat))`` without heights;
        with ``inside``, also where the four neighbours lie in the grid (valid or not).

        Examples
        --------
        >>> d = GeoDem(t)
        >>> lon, lat = d.lonlat(np.array([0.5, 3.25]), np.array([0.5, -1.0]))
        >>> d.valid_at(lon, lat).tolist() == np.isfinite(d.bilinear(lon, lat)).tolist()
        True
        """
        ok, i0, i1, j0, j1, _, _ = self._corners(lon, lat)
        out = np.zeros(ok.shape, bool)
        v = self.valid
        out[ok] = v[i0, j0] & v[i0, j1] & v[i1, j0] & v[i1, j1]
        return (out, ok) if inside else out

    def extent(self) -> tuple[float, float, float, float]:
        """Lon/lat box of the grid (its border densified through pyproj)."""
        t = np.linspace(0, 1, 65)
        i = np.concatenate([t * 0, t, t * 0 + 1, t]) * (self.H - 1)
        j = np.concatenate([t, t * 0, t, t * 0 + 1]) * (self.W - 1)
        lon, lat = self.lonlat(i, j)
        return float(lon.min()), float(lat.min()), float(lon.max()), float(lat.max())



def lonlat_bounds(w: float, s: float, e: float, n: float) -> list[float]:
    """A layer's ``bounds`` [west, south, east, north] with longitudes in [-180°, 180°]: a
    grid past the antimeridian (170°…190°) has west > east (170, …, -170), as Cesium's
    ``Rectangle`` takes one that crosses it.

    >>> lonlat_bounds(170.0, 0.0, 190.0, 10.0), lonlat_bounds(-10.0, 0.0, 10.0, 5.0)
    ([170.0, 0.0, -170.0, 10.0], [-10.0, 0.0, 10.0, 5.0])
    """
    if e - w >= 360.0:
        return [-180.0, s, 180.0, n]
    return [fold_lon(w), s, fold_lon(e), n]



def lattice_normals(dem: GeoDem, rect, M: int) -> np.ndarray:
    """(M, M, 3) unit ECEF normals by central differences on a lattice with a margin."""
    lon, lat = lattice(rect, M, 1)
    lat = np.clip(lat, -90.0, 90.0)  # the margin ring of a polar tile: no latitude past a pole
    h = dem.bilinear(lon, lat)
    up = ecef(lon, lat, np.ones_like(h)) - ecef(lon, lat, np.zeros_like(h))
    p = ecef(lon, lat, np.nan_to_num(h, nan=0.0))
    de = p[1:-1, 2:] - p[1:-1, :-2]  # east
    dn = p[:-2, 1:-1] - p[2:, 1:-1]  # north
    nrm = np.cross(de, dn)
    ln = np.linalg.norm(nrm, axis=-1, keepdims=True)
    bad = ~np.isfinite(h[:-2, 1:-1] + h[2:, 1:-1] + h[1:-1, :-2] + h[1:-1, 2:])
    nrm = np.where(bad[..., None] | (ln == 0), up[1:-1, 1:-1], nrm / np.maximum(ln, 1e-300))
    return nrm / np.linalg.norm(nrm, axis=-1, keepdims=True)
