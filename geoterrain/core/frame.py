"""The scene frame: metric 3-D positions of every sample, computed with pyproj.

- Projected CRS: CRS coordinates of the pixel centres, converted to metres with
  the CRS's own axis unit (US survey feet, feet, ...).
- Geographic CRS: exact sample positions (lon, lat) projected by pyproj into an
  azimuthal equidistant frame centred on the raster: true ground proportions,
  no resampling of heights. A root grid's frame (``lattice``) takes pyproj only on
  level 0's lattice and proxy positions past it (:meth:`Frame.xy`): its padding.
- No CRS (PNG tiles): unit pixels, or a given pixel size.

The scene origin is the raster's centre, so coordinates stay small (float32
safe in the renderer) whatever the CRS coordinates are.
"""

from __future__ import annotations

import os
import re
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import asdict, dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.lattice import lattice_edges, lattice_xy

# what a frame may hold, and a store's reader checks (core/limits.py)
from geoterrain.core.limits import (  # noqa: F401 - part of this module's API
    PIXEL_SIZE_RANGE,
    SCENE_LIMIT,
    UNIT_TO_M_RANGE,
    Z_SCALE_RANGE,
)
from geoterrain.exceptions import InputError, UsageError

if TYPE_CHECKING:
    from pyproj import CRS, Transformer

# pyproj (a tenth of a second of CPU to import) is loaded where a frame is built or a
# transform runs: a command that only reads a store's numbers (``info``) never loads it

# Vertical units a user may state (metres per unit); pyproj supplies horizontal ones.
Z_UNITS = {"m": 1.0, "ft": 0.3048, "us-ft": 1200.0 / 3937.0}
#: The widest geographic extent (metres) the flat scene draws (:meth:`Frame.flat_problem`).
FLAT_LIMIT_M = 1_000_000.0


@dataclass(frozen=True)
class Frame:
    """How grid indices (i, j) map to scene coordinates (metres).

    Examples
    --------
    >>> f = Frame.pixel(rows=3, cols=3, pixel_size=2.0)
    >>> X, Y = f.xy(np.array([0, 2]), np.array([0, 2]))
    >>> X.tolist(), Y.tolist()
    ([-2.0, 2.0], [2.0, -2.0])
    """

    kind: str  # "projected" | "geographic" | "pixel"
    rows: int
    cols: int
    transform: tuple[float, ...]  # GDAL affine of the source grid (pixel corners)
    crs_wkt: str | None = None
    unit_to_m: float = 1.0  # horizontal CRS unit → metres
    z_to_m: float = 1.0  # vertical unit → metres
    z_scale: float = 1.0  # vertical exaggeration
    origin_crs: tuple[float, float] = (0.0, 0.0)  # CRS coords of the scene origin
    # (rows, cols) of level 0's lattice of a geographic root grid whose extent passes it:
    # positions past it are proxies (:meth:`xy`); None: pyproj everywhere (stores before
    # schema 16, and every frame whose grid has no sample past its lattice)
    lattice: tuple[int, int] | None = None

    # ----------------------------------------------------------------- builders
    @staticmethod
    def pixel(rows: int, cols: int, pixel_size: float = 1.0, **kw) -> Frame:
        """A frame without georeference: ``pixel_size`` metres per sample."""
        t = (pixel_size, 0.0, 0.0, 0.0, -pixel_size, 0.0)
        fr = Frame("pixel", rows, cols, t, **kw)
        return fr._with_origin()

    @staticmethod
    def from_raster(
        transform: tuple[float, ...] | None,
        crs_wkt: str | None,
        rows: int,
        cols: int,
        pixel_size: float | None = None,
        z_units: str = "m",
        z_scale: float = 1.0,
    ) -> Frame:
        """Build the frame of a raster from its affine transform and CRS."""
        if z_units not in Z_UNITS:
            raise UsageError(f"unknown vertical unit {z_units!r}; use one of {', '.join(Z_UNITS)}")
        lo, hi = Z_SCALE_RANGE
        if not (np.isfinite(z_scale) and lo <= z_scale <= hi):
            raise UsageError(f"z_scale must be a number in [{lo:g}, {hi:g}], got {z_scale}",
                             cli=f"--z-scale must be a number in [{lo:g}, {hi:g}], got "
                                 f"{z_scale}")
        kw = dict(z_to_m=Z_UNITS[z_units], z_scale=float(z_scale))
        if crs_wkt is None or pixel_size is not None:
            return Frame.pixel(rows, cols, pixel_size or 1.0, **kw)
        if transform is None:
            raise InputError("the raster has a CRS but no geotransform; cannot place it")
        if transform[1] != 0 or transform[3] != 0:
            raise InputError("rotated geotransforms are not supported; warp the DEM north-up first")
        from pyproj import CRS

        crs = CRS.from_wkt(crs_wkt)
        if crs.is_geographic:
            a, _, c, _, e, f = transform
            lat = (f + 0.5 * e, f + (rows - 0.5) * e)  # pixel-centre latitudes
            if not all(np.isfinite(transform)) or max(abs(v) for v in lat) > 90:
                raise InputError(f"latitudes reach {max(abs(v) for v in lat):.6g}°, beyond ±90°: "
                                 "the geotransform or the CRS is wrong; fix it (gdal_edit.py "
                                 "-a_ullr / -a_srs) first")
            return Frame("geographic", rows, cols, tuple(transform), crs_wkt, **kw)._with_origin()
        if not crs.is_projected:
            raise InputError(f"unsupported CRS kind for {crs.name!r}; reproject to a projected CRS")
        unit = crs.axis_info[0].unit_conversion_factor if crs.axis_info else 1.0
        unit /= _scale_factor(crs, transform, rows, cols)
        if not (np.isfinite(unit) and UNIT_TO_M_RANGE[0] <= unit <= UNIT_TO_M_RANGE[1]):
            raise InputError(f"the CRS's unit is {unit:.3g} m, outside {UNIT_TO_M_RANGE[0]:g} "
                             f"… {UNIT_TO_M_RANGE[1]:g} m; fix the CRS (gdal_edit.py -a_srs)")
        return Frame("projected", rows, cols, tuple(transform), crs_wkt, unit_to_m=unit,
                     **kw)._with_origin()

    def _with_origin(self) -> Frame:
        ox, oy = self._crs_xy(np.array([(self.rows - 1) / 2]), np.array([(self.cols - 1) / 2]))
        return Frame(**{**asdict(self), "origin_crs": (float(ox[0]), float(oy[0]))})

    @cached_property
    def aeqd_wkt(self) -> str | None:
        """The local metric frame of a geographic grid (None for the other kinds): the
        azimuthal equidistant projection of the CRS's geodetic datum about
        :attr:`origin_crs`. Built from ``crs_wkt`` and ``origin_crs`` when first asked for
        (pyproj is loaded then); stores of schema 23 on no longer hold it (it was a third
        of a small store's metadata, docs/lab/store-size.md).

        Examples
        --------
        >>> from pyproj import CRS
        >>> f = Frame.from_raster((0.001, 0, 10, 0, -0.001, 50), CRS.from_epsg(4326).to_wkt(),
        ...                       6, 6)
        >>> "Azimuthal Equidistant" in f.aeqd_wkt, Frame.pixel(3, 3).aeqd_wkt
        (True, None)
        """
        if self.kind != "geographic":
            return None
        from pyproj import CRS
        from pyproj.crs import ProjectedCRS
        from pyproj.crs.coordinate_operation import AzimuthalEquidistantConversion

        geod = CRS.from_wkt(self.crs_wkt).geodetic_crs
        conv = AzimuthalEquidistantConversion(latitude_natural_origin=self.origin_crs[1],
                                              longitude_natural_origin=self.origin_crs[0])
        return ProjectedCRS(conversion=conv, geodetic_crs=geod).to_wkt()

    # --------------------------------------------------------------- mapping
    def _crs_xy(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """CRS coordinates of pixel centres (i, j) by the affine transform."""
        a, b, c, d, e, f = self.transform
        jj, ii = np.asarray(j, np.float64) + 0.5, np.asarray(i, np.float64) + 0.5
        return a * jj + b * ii + c, d * jj + e * ii + f

    def crs_xy(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source-CRS coordinates (float64) of the centres of samples (i, j).

        Examples
        --------
        >>> Frame.pixel(3, 3, 2.0).crs_xy(np.array([0]), np.array([2]))
        (array([5.]), array([-1.]))
        """
        return self._crs_xy(i, j)

    @cached_property
    def _to_scene(self) -> Transformer | None:
        if self.kind != "geographic":
            return None
        from pyproj import CRS, Transformer

        return Transformer.from_crs(CRS.from_wkt(self.crs_wkt), CRS.from_wkt(self.aeqd_wkt),
                                    always_xy=True)

    def xy(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scene X (east), Y (north) in metres of samples (i, j); any broadcastable shape.

        A geographic frame with a :attr:`lattice` of (R, C) samples gives pyproj's
        positions for i ≤ a = R − 1 and j ≤ b = C − 1 and, past them, the proxy

            P(i, j) = P(i', j') + d_i·(P(a, j') − P(a − 1, j')) + d_j·(P(i', b) − P(i', b − 1))

        with i' = min(i, a), j' = min(j, b), d_i = max(i − a, 0), d_j = max(j − b, 0):
        each column continued past the lattice's last row by its last step, each row past
        its last column likewise, the corner by both (affine in i and in j there, finite
        where pyproj is, equal to pyproj's on the lattice's edge, and no pyproj call per
        padding sample). A root grid's padding holds no valid sample, so these positions
        only place padding vertices; every bound the preprocess computes on them holds for
        what is drawn at them, since every reader takes its positions from here.

        Examples
        --------
        >>> from pyproj import CRS
        >>> f = Frame.from_raster((0.001, 0, 10, 0, -0.001, 50), CRS.from_epsg(4326).to_wkt(),
        ...                       6, 6).with_lattice((7, 7))
        >>> X, Y = f.xy(np.array([5, 6, 7, 8, 9]), np.full(5, 3))  # rows 7 … 9: proxies
        >>> bool(np.allclose(np.diff(Y[1:], 2), 0, atol=1e-6)), bool((np.diff(Y) < 0).all())
        (True, True)
        >>> X0, Y0 = Frame(**{**f.to_json(), "lattice": None}).xy(np.arange(7), np.full(7, 3))
        >>> bool((X0[5:7] == X[:2]).all() and (Y0[5:7] == Y[:2]).all())  # pyproj's, bit for bit
        True
        """
        x, y = self._crs_xy(i, j)
        if self.kind == "geographic":
            # Padding rows may run past a pole: clamp so pyproj stays finite.
            y = np.clip(y, -90.0, 90.0)
            if self.lattice is not None:
                return self._lattice_xy(i, j, x, y)
            return _transform_threads(self._to_scene, x, y, owned=True)
        return (x - self.origin_crs[0]) * self.unit_to_m, (y - self.origin_crs[1]) * self.unit_to_m

    def with_lattice(self, lattice: tuple[int, int] | None) -> Frame:
        """This frame with proxy positions past level 0's ``lattice`` (rows, cols) when it
        is geographic (:meth:`xy`); any other frame as it is (its positions are affine).

        Examples
        --------
        >>> Frame.pixel(3, 3).with_lattice((5, 5)).lattice is None
        True
        """
        if self.kind != "geographic" or lattice is None:
            return self
        R, C = (int(v) for v in lattice)
        if R < max(2, self.rows) or C < max(2, self.cols):
            raise ValueError(f"a lattice of {R} × {C} samples does not hold the raster's "
                             f"{self.rows} × {self.cols}")
        return Frame(**{**asdict(self), "lattice": (R, C)})

    def _lattice_xy(self, i, j, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # pyproj on the lattice, the proxy of xy()'s docstring past it (core/lattice.py)
        return lattice_xy(self.lattice, self._project, self._crs_xy, lambda: self._lattice_edges,
                          i, j, x, y)

    def _project(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # pyproj into the scene, x and y this call's own (fresh arrays)
        return _transform_threads(self._to_scene, x, y, owned=True)

    @cached_property
    def _lattice_edges(self) -> tuple[np.ndarray, np.ndarray]:
        return lattice_edges(self.lattice, self._project, self._crs_xy)

    def z(self, heights: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Scene Z (metres, exaggerated) of heights in source units (into ``out``, which
        may be ``heights`` itself)."""
        return np.multiply(np.asarray(heights, np.float64), self.z_to_m * self.z_scale,
                           out=out)

    def check_scene(self, size: int | tuple[int, int], lo: float, hi: float) -> None:
        """Refuse (one line) a padded ``size`` × ``size`` grid (or ``(rows, cols)``, a
        root grid's extent) of heights ``lo`` … ``hi`` (source units) whose scene
        coordinates would pass :data:`SCENE_LIMIT` metres: a pixel size, a unit or a
        vertical exaggeration far too large.

        Examples
        --------
        >>> Frame.pixel(3, 3, 2.0).check_scene(3, 0.0, 10.0)
        """
        R, C = (size, size) if np.ndim(size) == 0 else size
        x, y = self.xy(np.array([0, R - 1])[:, None], np.array([0, C - 1])[None, :])
        z = self.z(np.array([lo, hi], np.float64))
        span = max(float(np.abs(v).max()) for v in (x, y, z))
        if not np.isfinite(span) or span > SCENE_LIMIT:
            raise InputError(f"the scene would reach {span:.3g} m from its centre, beyond "
                             f"{SCENE_LIMIT:.0e} m: pixel_size, z_scale or the unit is too "
                             "large", cli=f"the scene would reach {span:.3g} m from its "
                             f"centre, beyond {SCENE_LIMIT:.0e} m: --pixel-size, --z-scale "
                             "or --z-units is too large")

    def heights_from_z(self, Z: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`z`."""
        return np.asarray(Z, np.float64) / (self.z_to_m * self.z_scale)

    def grid_xy(self, n: int | tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Scene X, Y of the whole padded n × n grid, or of ``(rows, cols)`` samples (a
        root grid's extent) (float64). In a projected frame X depends on the column only
        and Y on the row only: they are read-only broadcast views of one row and one
        column (no n² copies)."""
        R, C = (n, n) if np.ndim(n) == 0 else n
        if self.kind == "geographic":  # a column of rows against a row of columns
            return self.xy(np.arange(R)[:, None], np.arange(C)[None, :])
        return self.axis_xy(np.arange(R), np.arange(C))

    def axis_xy(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scene X, Y of the samples ``rows`` × ``cols`` of a projected or pixel frame,
        where X depends on the column only and Y on the row only: read-only broadcast
        views of one row of X and one column of Y (:meth:`grid_xy`'s values).

        Examples
        --------
        >>> X, Y = Frame.pixel(3, 3, 2.0).axis_xy(np.array([0, 2]), np.array([1, 2]))
        >>> X.tolist(), Y.tolist()
        ([[0.0, 2.0], [0.0, 2.0]], [[2.0, 2.0], [-2.0, -2.0]])
        """
        if self.kind == "geographic":
            raise ValueError("a geographic frame's x, y depend on both row and column")
        xs, _ = self.xy(np.zeros(len(cols)), cols)
        _, ys = self.xy(rows, np.zeros(len(rows)))
        shape = (len(rows), len(cols))
        return np.broadcast_to(xs[None, :], shape), np.broadcast_to(ys[:, None], shape)

    def crs_to_scene(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scene X, Y of points given in the source CRS."""
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        if self.kind == "geographic":
            X, Y = self._to_scene.transform(x, y)
            return np.asarray(X), np.asarray(Y)
        return (x - self.origin_crs[0]) * self.unit_to_m, (y - self.origin_crs[1]) * self.unit_to_m

    def crs_point_to_scene(self, p) -> tuple[float, float, float]:
        """A camera point given as source-CRS x, y and a height z in metres → scene frame.

        Examples
        --------
        >>> Frame.pixel(3, 3, 2.0, z_scale=2.0).crs_point_to_scene((3.0, -3.0, 10.0))
        (0.0, 0.0, 20.0)
        """
        X, Y = self.crs_to_scene(np.array([p[0]]), np.array([p[1]]))
        return float(X[0]), float(Y[0]), float(p[2]) * self.z_scale

    def scene_to_crs(self, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Source-CRS coordinates of scene points."""
        X, Y = np.asarray(X, np.float64), np.asarray(Y, np.float64)
        if self.kind == "geographic":
            x, y = self._to_scene.transform(X, Y, direction="INVERSE")
            return np.asarray(x), np.asarray(y)
        return X / self.unit_to_m + self.origin_crs[0], Y / self.unit_to_m + self.origin_crs[1]

    def flat_problem(self) -> str | None:
        """Why a flat scene cannot show this frame honestly, or None when it can.

        A geographic grid is flattened onto a local azimuthal-equidistant plane. Beyond about
        :data:`FLAT_LIMIT_M` (1 000 km) that plane drifts far from the Earth (its surface
        falls ≈ 20 km below the plane 500 km from the centre, ≈ 700 km at 3 000 km), and a
        grid that reaches a pole folds there. Both are for the globe. The extents are
        geodesic lengths on the frame's ellipsoid (pyproj's ``Geod``): the longest parallel
        it spans and its meridian.

        Examples
        --------
        >>> from pyproj import CRS
        >>> wkt = CRS.from_epsg(4326).to_wkt()
        >>> world = Frame.from_raster((0.25, 0, -180, 0, -0.25, 90), wkt, 720, 1440)
        >>> world.flat_problem()
        'it reaches the north and south poles'
        >>> Frame.from_raster((0.001, 0, 139, 0, -0.001, 36), wkt, 300, 300).flat_problem()
        """
        if self.kind != "geographic":
            return None
        a, _, c, _, e, f = self.transform
        lat0, lat1 = sorted((f, f + e * self.rows))
        poles = [name for name, hit in (("north", lat1 >= 90.0 - 0.5 * abs(e)),
                                        ("south", lat0 <= -90.0 + 0.5 * abs(e))) if hit]
        if poles:
            return f"it reaches the {' and '.join(poles)} pole{'s' if len(poles) > 1 else ''}"
        from pyproj import CRS

        geod = CRS.from_wkt(self.crs_wkt).get_geod()
        lon_span = min(abs(a) * self.cols, 360.0)
        lat_eq = min(max(0.0, lat0), lat1)  # the spanned latitude nearest the equator
        lons = c + np.linspace(0.0, 1.0, 65) * lon_span * np.sign(a)
        ew = geod.line_length(lons, np.full(65, lat_eq))
        lon_mid = c + a * self.cols / 2
        ns = geod.line_length([lon_mid, lon_mid], [lat0, lat1])
        if max(ew, ns) > FLAT_LIMIT_M:
            return (f"it spans {ew / 1e3:,.0f} × {ns / 1e3:,.0f} km, over the "
                    f"{FLAT_LIMIT_M / 1e3:,.0f} km a flat scene can show honestly")
        return None

    @property
    def columns_per_turn(self) -> int | None:
        """The columns of one whole turn of longitude when this geographic grid's columns
        span exactly 360° (a whole-globe raster: the column after the last is the first
        again, and a lookup between them wraps); None for any other grid.

        Examples
        --------
        >>> from pyproj import CRS
        >>> wkt = CRS.from_epsg(4326).to_wkt()
        >>> Frame.from_raster((0.25, 0, -180, 0, -0.25, 90), wkt, 720, 1440).columns_per_turn
        1440
        >>> Frame.from_raster((0.25, 0, -180, 0, -0.25, 90), wkt, 720, 1441).columns_per_turn
        """
        if self.kind != "geographic":
            return None
        a = abs(self.transform[0])
        return self.cols if abs(a * self.cols - 360.0) <= 1e-9 * 360.0 else None

    @property
    def crs_name(self) -> str:
        """The CRS's name: its WKT's root name where the root is a plain CRS (what
        pyproj's ``CRS.name`` gives, without loading pyproj), else pyproj's.

        Examples
        --------
        >>> Frame.pixel(3, 3).crs_name
        'none (pixel units)'
        >>> Frame("projected", 3, 3, (1, 0, 0, 0, -1, 0), 'PROJCS["NAD83 / UTM zone 17N",'
        ...       'GEOGCS["NAD83"]]').crs_name
        'NAD83 / UTM zone 17N'
        """
        if not self.crs_wkt:
            return "none (pixel units)"
        m = _WKT_ROOT.match(self.crs_wkt)
        if m:
            return m.group(2).replace('""', '"')
        from pyproj import CRS

        return CRS.from_wkt(self.crs_wkt).name

    def to_json(self) -> dict:
        """The store's frame; ``lattice`` only where it is set; no ``aeqd_wkt`` (schema
        23: a reader builds it from ``crs_wkt`` and ``origin_crs``, :attr:`aeqd_wkt`)."""
        d = asdict(self)
        if d["lattice"] is None:
            del d["lattice"]
        else:
            d["lattice"] = list(d["lattice"])
        return d

    @staticmethod
    def from_json(d: dict) -> Frame:
        d = dict(d)
        d.pop("aeqd_wkt", None)  # derived (:attr:`aeqd_wkt`); a store's check refuses it
        d["transform"] = tuple(d["transform"])
        d["origin_crs"] = tuple(d["origin_crs"])
        if d.get("lattice") is not None:
            d["lattice"] = tuple(int(v) for v in d["lattice"])
        return Frame(**d)


# a WKT 1 or 2 root that is a plain CRS, and its name (a quote inside it doubled)
_WKT_ROOT = re.compile(r'\s*(PROJCS|GEOGCS|GEOCCS|PROJCRS|GEOGCRS|GEODCRS)\s*\[\s*'
                       r'"((?:[^"]|"")*)"\s*,')


def check_flat(frame: Frame, name: str) -> None:
    """Raise a one-line :class:`~geoterrain.exceptions.InputError` pointing to the globe
    when the flat scene cannot show ``frame`` honestly (:meth:`Frame.flat_problem`).

    Examples
    --------
    >>> check_flat(Frame.pixel(10, 10), "dem.geoterrain")
    """
    why = frame.flat_problem()
    if why is not None:
        msg = (f"{name}: {why}; a flat scene would fold or distort it: draw it on the globe "
               "(geoterrain.globe.Globe)")
        raise InputError(msg, cli=f"{name}: {why}; a flat scene would fold or distort it: "
                         f"draw it on the globe: geoterrain render --globe {name} -o "
                         "earth.png (or view --globe; geoterrain.globe.Globe in Python)")


def level_transform(transform, level: int):
    """The affine transform (rasterio ``Affine``) of pyramid level L of a source grid.

    Pixel centre k of level L is source pixel centre k·2^L.

    Examples
    --------
    >>> level_transform((10.0, 0.0, 500.0, 0.0, -10.0, 900.0), 1)
    Affine(20.0, 0.0, 495.0,
           0.0, -20.0, 905.0)
    """
    from rasterio.transform import Affine

    s = float(1 << level)
    return Affine(*transform[:6]) @ Affine.translation(0.5 - s / 2, 0.5 - s / 2) @ Affine.scale(s)


def _scale_factor(crs: CRS, transform, rows: int, cols: int) -> float:
    """The projection's point scale factor at the grid centre, where it departs from 1 by
    more than 1 % (Web Mercator: 1/cos φ); else 1, so conformal grids such as UTM keep
    their CRS metres. Scene distances near the centre are then true ground metres."""
    from pyproj import Proj, Transformer

    a, _, c, _, e, f = transform
    x, y = c + a * cols / 2, f + e * rows / 2
    try:
        lon, lat = Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True).transform(x, y)
        k = float(Proj(crs).get_factors(lon, lat).parallel_scale)
    except Exception:  # noqa: BLE001 - projections without factors keep their units
        return 1.0
    return k if np.isfinite(k) and k > 0 and abs(k - 1) > 0.01 else 1.0


_CHUNK = 1 << 18  # points per pyproj call when a transform is split over threads


def _transform_threads(tr, x: np.ndarray, y: np.ndarray, owned: bool = False
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``tr.transform(x, y)`` as float64 arrays of the broadcast shape; large inputs in
    chunks on every core (pyproj releases the GIL; a 1025² geographic grid: 0.70 → 0.35 s
    on 2 cores, the same values). ``owned``: x and y are this call's to overwrite (fresh
    arrays): when they are C-ordered float64 of one shape the transform writes its result
    into them (pyproj's ``inplace``, the same values without its copy of the input and
    ours of its output)."""
    x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
    shape, n = x.shape, x.size
    inplace = (owned and x.flags.c_contiguous and y.flags.c_contiguous and x.flags.writeable
               and y.flags.writeable and not np.shares_memory(x, y))
    if inplace:
        X, Y = x.reshape(-1), y.reshape(-1)
    workers = min(os.cpu_count() or 1, max(1, n // _CHUNK))
    if workers < 2:
        if inplace:
            tr.transform(X, Y, inplace=True)
            return x, y
        X, Y = tr.transform(x, y)
        return np.asarray(X, np.float64).reshape(shape), np.asarray(Y, np.float64).reshape(shape)
    if not inplace:
        xf, yf = x.ravel(), y.ravel()
        X, Y = np.empty(n), np.empty(n)
    cuts = np.linspace(0, n, workers + 1).astype(np.int64)

    def part(k: int) -> None:
        a, b = cuts[k], cuts[k + 1]
        if inplace:
            tr.transform(X[a:b], Y[a:b], inplace=True)
        else:
            X[a:b], Y[a:b] = tr.transform(xf[a:b], yf[a:b])

    # the first chunk on this thread, the others on the kept pool's threads (a
    # Transformer builds its PROJ object once per thread that uses it: 6-7 ms of CPU,
    # which a pool made per call paid again at every call, a band of the xy pass)
    rest = [_pool().submit(part, k) for k in range(1, workers)]
    try:
        part(0)
    finally:
        wait(rest)  # none still writes X, Y when this returns or raises
    for f in rest:
        f.result()
    return X.reshape(shape), Y.reshape(shape)


_POOL: list = [None]  # _transform_threads' threads, made at its first split call
_POOL_LOCK = [threading.Lock()]


def _pool() -> ThreadPoolExecutor:
    with _POOL_LOCK[0]:
        if _POOL[0] is None:
            _POOL[0] = ThreadPoolExecutor(max(1, (os.cpu_count() or 1) - 1),
                                          thread_name_prefix="geoterrain-pyproj")
        return _POOL[0]


def _forget_pool() -> None:
    # a fork child has none of the parent's threads (nor a lock one of them held)
    _POOL[0] = None
    _POOL_LOCK[0] = threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)
