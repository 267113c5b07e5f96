"""Where a question's points fall on the grid, and what answering it read.

Shared by every module of :mod:`geoterrain.analysis`:

- :func:`as_xy` checks an (N, 2) array (or one point) and :func:`to_source` brings it
  into the DEM's own CRS (``crs=None``), from lon/lat (``crs="lonlat"``) or any CRS
  pyproj knows;
- :func:`grid_coords` gives the fractional row and column of a point on the grid of
  sample centres (row i, column j at the centre of source pixel (i, j)), and
  :func:`inside` whether it lies within the raster's extent (pixel edges included);
  :func:`turn_coords` takes a whole-globe grid's columns modulo its turn;
- :class:`Reads` counts the tiles decoded, the blob bytes read and the time a question
  took (every answer reports them).

Examples
--------
>>> xy = as_xy([[t.frame.transform[2] + 5.0, t.frame.transform[5] - 5.0]])
>>> fi, fj = grid_coords(t.frame, xy)
>>> float(fi[0]), float(fj[0]), bool(inside(t.grid, fi, fj)[0])
(0.0, 0.0, True)
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from geoterrain.exceptions import InputError, UsageError

if TYPE_CHECKING:
    from geoterrain.core.frame import Frame
    from geoterrain.core.grid import Grid
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Reads", "as_xy", "frame_geod", "from_source", "grid_coords", "inside",
           "outside_error", "source_xy", "to_source", "turn_coords", "vertical_unit"]


def as_xy(points: Any) -> np.ndarray:
    """``points`` as an (N, 2) float64 array; one point (x, y) gives N = 1.

    Examples
    --------
    >>> as_xy((1, 2)).tolist(), as_xy([[1, 2], [3, 4]]).shape
    ([[1.0, 2.0]], (2, 2))
    """
    try:
        a = np.asarray(points, np.float64)
    except (TypeError, ValueError):
        raise UsageError("points must be numbers: an (N, 2) array of x, y") from None
    if a.ndim == 1 and a.shape[0] == 2:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != 2:
        raise UsageError(f"points must be an (N, 2) array of x, y, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise UsageError("points must be finite numbers (a NaN or inf was given)")
    return a


def _crs(frame: Frame, crs: Any):
    """The pyproj CRS of the points (None: the DEM's own)."""
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    if crs is None:
        return None
    if frame.kind == "pixel" or not frame.crs_wkt:
        raise UsageError("the DEM has no CRS (pixel units): give the points in its own "
                         "coordinates, without a CRS",
                         cli="the DEM has no CRS (pixel units): give the points in its own "
                             "coordinates, without --crs or --lonlat")
    try:
        return CRS.from_user_input("EPSG:4326" if crs == "lonlat" else crs)
    except CRSError:
        raise UsageError(f"unknown CRS {crs!r}: give an EPSG code (EPSG:4326), a PROJ "
                         "string or WKT", cli=f"--crs: unknown CRS {crs!r}; give an EPSG "
                         "code such as EPSG:4326, a PROJ string or WKT") from None


def to_source(frame: Frame, xy: np.ndarray, crs: Any = None) -> np.ndarray:
    """Points (N, 2) in ``crs`` (None: already in the DEM's CRS; ``"lonlat"``: longitude,
    latitude in degrees, WGS 84) → the DEM's CRS, by pyproj.

    Examples
    --------
    >>> lon, lat = from_source(t.frame, np.array([[500000.0, 5000000.0]]), "lonlat")[0]
    >>> np.allclose(to_source(t.frame, np.array([[lon, lat]]), "lonlat"), [[5e5, 5e6]])
    True
    """
    from pyproj import CRS, Transformer

    src = _crs(frame, crs)
    if src is None:
        return xy
    tr = Transformer.from_crs(src, CRS.from_wkt(frame.crs_wkt), always_xy=True)
    x, y = tr.transform(xy[:, 0], xy[:, 1])
    out = np.column_stack([np.asarray(x, np.float64), np.asarray(y, np.float64)])
    if not np.isfinite(out).all():
        bad = int(np.flatnonzero(~np.isfinite(out).all(axis=1))[0])
        raise InputError(f"point {bad} ({xy[bad, 0]:.10g}, {xy[bad, 1]:.10g}) cannot be "
                         f"placed in the DEM's CRS from {src.name}: check the CRS and the "
                         "axis order (x/longitude first)")
    return out


def from_source(frame: Frame, xy: np.ndarray, crs: Any = None) -> np.ndarray:
    """The inverse of :func:`to_source`: points in the DEM's CRS → ``crs``."""
    from pyproj import CRS, Transformer

    dst = _crs(frame, crs)
    if dst is None:
        return xy
    tr = Transformer.from_crs(CRS.from_wkt(frame.crs_wkt), dst, always_xy=True)
    x, y = tr.transform(xy[:, 0], xy[:, 1])
    return np.column_stack([np.asarray(x, np.float64), np.asarray(y, np.float64)])


def grid_coords(frame: Frame, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fractional (row, column) of source-CRS points on the grid of sample centres: sample
    (i, j) is the centre of source pixel (i, j), so its row is i exactly."""
    a, _, c, _, e, f = frame.transform[:6]
    fj = (xy[:, 0] - c) / a - 0.5
    fi = (xy[:, 1] - f) / e - 0.5
    return fi, fj


def turn_coords(frame: Frame, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`grid_coords`, with a whole-globe grid's columns taken modulo its turn
    (:attr:`Frame.columns_per_turn`) into [−0.5, turn − 0.5): every longitude lies on such
    a grid, 190° on −170°'s column, and the half cells either side of 180° lie between its
    last column and its first. Any other grid's columns are :func:`grid_coords`'.

    Examples
    --------
    >>> turn_coords(t.frame, np.array([[500015.0, 4999985.0]]))[1].tolist()
    [1.0]
    """
    fi, fj = grid_coords(frame, xy)
    turn = frame.columns_per_turn
    if turn:
        fj = np.mod(fj + 0.5, turn) - 0.5
    return fi, fj


def vertical_unit(terrain: TerrainLike) -> str:
    """The name of the DEM's vertical unit ("m", "ft", "US survey ft", …), as answers
    label their heights.

    Examples
    --------
    >>> vertical_unit(t)
    'm'
    """
    from geoterrain.ingest.units import unit_of_factor

    return unit_of_factor(terrain.frame.z_to_m) or f"{terrain.frame.z_to_m:g} m"


def frame_geod(frame: Frame):
    """pyproj's ``Geod`` on the frame's ellipsoid (WGS 84 where its CRS names none): ground
    distances and azimuths on a geographic grid.

    Examples
    --------
    >>> from geoterrain.core.frame import Frame
    >>> round(frame_geod(Frame.pixel(3, 3)).a)
    6378137
    """
    from pyproj import CRS, Geod

    g = CRS.from_wkt(frame.crs_wkt).get_geod() if frame.crs_wkt else None
    return g or Geod(ellps="WGS84")


def source_xy(frame: Frame, fi: np.ndarray, fj: np.ndarray) -> np.ndarray:
    """Source-CRS points (N, 2) of fractional grid coordinates (:func:`grid_coords`'s
    inverse)."""
    a, _, c, _, e, f = frame.transform[:6]
    return np.column_stack([a * (np.asarray(fj) + 0.5) + c, e * (np.asarray(fi) + 0.5) + f])


def inside(grid: Grid, fi: np.ndarray, fj: np.ndarray) -> np.ndarray:
    """Whether fractional grid points lie within the raster's extent (its pixels' outer
    edges, closed): up to half a cell beyond the outermost sample centres."""
    return (fi >= -0.5) & (fi <= grid.rows - 0.5) & (fj >= -0.5) & (fj <= grid.cols - 0.5)


def outside_error(frame: Frame, grid: Grid, xy: np.ndarray, crs: Any, bad: np.ndarray,
                  what: str = "point") -> InputError:
    """The one-line error for points outside the data: the first one, how many, and the
    DEM's extent in the points' CRS."""
    k = int(np.flatnonzero(bad)[0])
    a, _, c, _, e, f = frame.transform[:6]
    x0, x1 = sorted((c, c + a * grid.cols))
    y0, y1 = sorted((f, f + e * grid.rows))
    where = "" if crs is None else f" (given in {crs}; the extent is in the DEM's CRS)"
    n = int(bad.sum())
    more = f" and {n - 1} more" if n > 1 else ""
    verb = "lie" if n > 1 else "lies"  # "point 0 and 1 more lie", "point 0 lies"
    return InputError(f"{what} {k} ({xy[k, 0]:.10g}, {xy[k, 1]:.10g}){more} {verb} outside "
                      f"the data: the DEM covers x {x0:.10g} … {x1:.10g}, y {y0:.10g} … "
                      f"{y1:.10g}{where}")


class Reads:
    """What a question read from the store and how long it took: a context manager over a
    terrain's decode counters.

    Examples
    --------
    >>> with Reads(t) as r:
    ...     _ = t.tile(0, 1, 1)
    >>> sorted(r.stats())
    ['bounds_decoded', 'bytes_read', 'seconds', 'tiles_decoded']
    """

    def __init__(self, terrain: TerrainLike):
        self.terrain = terrain
        self.t0 = (terrain.decoded_tiles, terrain.decoded_bounds, terrain.bytes_read)
        self.start = time.perf_counter()
        self.end: float | None = None

    def __enter__(self) -> Reads:
        return self

    def __exit__(self, *exc) -> None:
        self.end = time.perf_counter()

    def stats(self, **extra: Any) -> dict[str, Any]:
        """tiles_decoded, bounds_decoded (δ or r arrays), bytes_read and seconds so far."""
        t = self.terrain
        end = self.end if self.end is not None else time.perf_counter()
        return {"tiles_decoded": t.decoded_tiles - self.t0[0],
                "bounds_decoded": t.decoded_bounds - self.t0[1],
                "bytes_read": t.bytes_read - self.t0[2],
                "seconds": end - self.start, **extra}
