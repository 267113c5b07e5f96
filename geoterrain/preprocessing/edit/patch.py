"""What an edit writes: a patch of heights placed on the store's grid, combined with the
heights there by a mode, and fitted to the store's quantizer.

A patch is a window of the DEM's samples (``row``, ``col``: its top-left sample; rows
southwards, columns eastwards, as the DEM's pixels) and its heights in the DEM's own
units, NaN where the patch has nothing to say: those samples are left as they are. A
georeferenced raster becomes one by :func:`read_patch`: placed as it is when it lies on
the store's grid (same CRS, pixel size and pixel corners), else resampled onto it by
rasterio (its CRS transform by pyproj).

Modes, at each sample the patch covers:

- ``replace``: the patch's height; over nodata too (a void filled);
- ``add``: the height plus the patch's (a cut is negative, a fill positive);
- ``min`` / ``max``: the lower / higher of the two (a cut down to a design surface, an
  embankment up to one);

``add``, ``min`` and ``max`` leave a nodata sample nodata (there is no height there to
add to or compare with).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.codec.quantize import Quantizer, codes_to_heights, heights_to_codes
from geoterrain.exceptions import InputError, UsageError

if TYPE_CHECKING:
    from geoterrain.core.frame import Frame
    from geoterrain.core.grid import Grid

__all__ = ["MODES", "RESAMPLING", "Patch", "combine", "fit_to_quantizer", "read_patch"]

MODES = ("replace", "add", "min", "max")
RESAMPLING = ("nearest", "bilinear", "cubic")


@dataclass
class Patch:
    """Heights (source units, NaN: no change) whose top-left sample is (``row``, ``col``)
    of the DEM, and where they came from (``source``, for messages and the store's
    edit log)."""

    row: int
    col: int
    heights: np.ndarray
    source: str = "array"

    def clipped(self, grid: Grid) -> Patch:
        """The part inside the DEM's rows × cols; InputError when nothing is.

        Examples
        --------
        >>> from geoterrain.core.grid import Grid
        >>> p = Patch(-1, 3, np.ones((4, 4))).clipped(Grid.for_shape(5, 5, tile_size=2))
        >>> p.row, p.col, p.heights.shape
        (0, 3, (3, 2))
        """
        h = np.asarray(self.heights, np.float64)
        if h.ndim != 2 or not h.size:
            raise UsageError(f"{self.source}: heights must be a non-empty 2-D array, got "
                             f"shape {h.shape}")
        r0, c0 = max(self.row, 0), max(self.col, 0)
        r1, c1 = min(self.row + h.shape[0], grid.rows), min(self.col + h.shape[1], grid.cols)
        if r1 <= r0 or c1 <= c0:
            raise InputError(f"{self.source}: the patch (rows {self.row} … "
                             f"{self.row + h.shape[0] - 1}, columns {self.col} … "
                             f"{self.col + h.shape[1] - 1}) lies outside the DEM's "
                             f"{grid.rows} × {grid.cols} samples; check where it is placed")
        return Patch(r0, c0, h[r0 - self.row:r1 - self.row, c0 - self.col:c1 - self.col],
                     self.source)


def combine(old: np.ndarray, old_valid: np.ndarray, patch: np.ndarray, mode: str
            ) -> tuple[np.ndarray, np.ndarray]:
    """The heights and validity after ``mode`` (module docstring) of ``patch`` (NaN: no
    change) over ``old`` (NaN where not ``old_valid``).

    Examples
    --------
    >>> old = np.array([[1.0, np.nan, 5.0]]); ok = np.isfinite(old)
    >>> p = np.array([[2.0, 2.0, np.nan]])
    >>> [combine(old, ok, p, m)[0].tolist() for m in ("replace", "add", "max")]
    [[[2.0, 2.0, 5.0]], [[3.0, nan, 5.0]], [[2.0, nan, 5.0]]]
    """
    if mode not in MODES:
        raise UsageError(f"unknown mode {mode!r}; use one of {', '.join(MODES)}",
                         cli=f"--mode must be one of {', '.join(MODES)}, got {mode!r}")
    has = np.isfinite(patch)
    if mode == "replace":
        h = np.where(has, patch, old)
        v = old_valid | has
    else:
        both = has & old_valid
        op = {"add": np.add, "min": np.minimum, "max": np.maximum}[mode]
        with np.errstate(invalid="ignore"):
            h = np.where(both, op(old, np.where(has, patch, 0.0)), old)
        v = old_valid.copy()
    h = np.where(v, h, np.nan)
    return h, v & np.isfinite(h)


def fit_to_quantizer(heights: np.ndarray, valid: np.ndarray, q: Quantizer, *,
                     round_heights: bool, source: str) -> tuple[np.ndarray, float]:
    """The new heights as the store can hold them, and the largest change that took.

    A lossless store of integer or decimal codes (an integer DEM, Terrain-RGB's 0.1 m, a
    float DEM written with d decimals) holds exactly the heights on its grid: others are
    refused in one line, or rounded to the grid with ``round_heights``. A lossless float
    store holds the floats of its source's width: heights are rounded to it (float32:
    what writing the edited DEM as float32 would do), and the largest rounding is
    returned. A store coded within ε holds any height within ε (its contract): they are
    kept as given and the codec rounds them. Heights past the quantizer's range are
    refused.

    Examples
    --------
    >>> q = Quantizer("int")
    >>> fit_to_quantizer(np.array([[2.25]]), np.array([[True]]), q, round_heights=True,
    ...                  source="p")
    (array([[2.]]), 0.25)
    """
    h = np.where(valid, heights, 0.0)
    try:
        back = codes_to_heights(heights_to_codes(h, q), q)
    except ValueError:
        raise InputError(f"{source}: heights out of the store's range (its quantizer: "
                         f"{q.mode}, step {q.step:g}); check the patch's units") from None
    if not np.isfinite(back[valid]).all():
        raise InputError(f"{source}: heights out of the store's range (float{q.float_bits}); "
                         "check the patch's units")
    if q.mode == "quantized":  # within ε by the codec: the store's contract
        return np.where(valid, heights, np.nan), 0.0
    off = valid & (back != h)
    diff = float(np.abs(back - h)[off].max()) if off.any() else 0.0
    if off.any() and not round_heights and q.mode != "float":
        k = np.flatnonzero(off.ravel())[0]
        example = float(h.ravel()[k])
        grid = (f"float{q.float_bits}" if q.mode == "float" else
                f"multiples of {q.step:g}" + (f" from {q.offset:g}" if q.offset else ""))
        raise InputError(
            f"{source}: {int(off.sum())} heights, e.g. {example!r}, are not on the store's "
            f"lossless grid ({grid}); pass round_heights=True to round them to it (by at "
            f"most {diff:.3g}), or preprocess the edited DEM again",
            cli=f"{source}: {int(off.sum())} heights, e.g. {example!r}, are not on the "
            f"store's lossless grid ({grid}); pass --round to round them to it (by at most "
            f"{diff:.3g}), or preprocess the edited DEM again")
    return np.where(valid, back, np.nan), diff


def read_patch(path: str | Path, frame: Frame, grid: Grid, *, at: tuple[int, int] | None = None,
               resampling: str = "bilinear", band: int | None = None) -> Patch:
    """A raster file as a :class:`Patch` on the store's grid.

    Placed by ``at`` = (row, col) of its top-left sample when given (a store or a patch
    without georeference needs it); else by its georeference: as it is when it lies on
    the store's grid (same CRS and pixel size, corners on the store's pixel corners),
    otherwise reprojected and resampled onto the store's grid by rasterio
    (``resampling``: nearest, bilinear or cubic). Its nodata samples change nothing.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> from geoterrain.ingest.raster import read_raster
    >>> from geoterrain.core.frame import Frame
    >>> from geoterrain.core.grid import Grid
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "d.tif"), generate("fbm", 9))
    >>> r = read_raster(dem)
    >>> f = Frame.from_raster(r.transform, r.crs_wkt, 9, 9)
    >>> p = read_patch(dem, f, Grid.for_shape(9, 9))
    >>> p.row, p.col, p.heights.shape
    (0, 0, (9, 9))
    """
    from geoterrain.ingest.raster import read_raster

    if resampling not in RESAMPLING:
        raise UsageError(f"unknown resampling {resampling!r}; use one of "
                         f"{', '.join(RESAMPLING)}")
    r = read_raster(path, band=band, encoding="raw")
    h = np.where(r.valid, r.heights, np.nan)
    name = Path(path).name
    if at is not None:
        return Patch(int(at[0]), int(at[1]), h, name).clipped(grid)
    if r.crs_wkt is None or frame.crs_wkt is None:
        raise UsageError(f"{name}: {'the patch' if r.crs_wkt is None else 'the store'} has no "
                         "georeference; give the patch's place with at=(row, col)",
                         cli=f"{name}: {'the patch' if r.crs_wkt is None else 'the store'} "
                         "has no georeference; give its place with --at ROW,COL")
    from rasterio.crs import CRS

    src_crs, dst_crs = CRS.from_wkt(r.crs_wkt), CRS.from_wkt(frame.crs_wkt)
    a, _, c, _, e, f = frame.transform
    pa, _, pc, _, pe, pf = r.transform
    col = (pc - c) / a
    row = (pf - f) / e
    on_grid = (src_crs == dst_crs and abs(pa - a) <= 1e-9 * abs(a) and abs(pe - e) <= 1e-9 * abs(e)
               and abs(col - round(col)) < 1e-6 and abs(row - round(row)) < 1e-6)
    if on_grid:
        return Patch(int(round(row)), int(round(col)), h, name).clipped(grid)
    return _resampled(r, h, name, frame, grid, resampling)


def _resampled(r, h: np.ndarray, name: str, frame: Frame, grid: Grid, resampling: str) -> Patch:
    """The patch reprojected onto the store's pixels that its footprint covers."""
    from rasterio.crs import CRS
    from rasterio.transform import Affine, array_bounds
    from rasterio.warp import Resampling, reproject, transform_bounds

    src_t = Affine(*r.transform)
    src_crs, dst_crs = CRS.from_wkt(r.crs_wkt), CRS.from_wkt(frame.crs_wkt)
    bounds = array_bounds(h.shape[0], h.shape[1], src_t)  # (west, south, east, north)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        w, s, e_, n = transform_bounds(src_crs, dst_crs, *bounds, densify_pts=21)
    a, _, c, _, e, f = frame.transform
    # the store's pixels whose centres may fall in the footprint, one more on each side
    c0 = int(np.floor((w - c) / a)) - 1
    c1 = int(np.ceil((e_ - c) / a)) + 1
    r0 = int(np.floor((n - f) / e)) - 1
    r1 = int(np.ceil((s - f) / e)) + 1
    c0, r0 = max(c0, 0), max(r0, 0)
    c1, r1 = min(c1, grid.cols), min(r1, grid.rows)
    if c1 <= c0 or r1 <= r0:
        raise InputError(f"{name}: the patch does not overlap the store's DEM; check its CRS "
                         "and extent")
    out = np.full((r1 - r0, c1 - c0), np.nan)
    dst_t = Affine(a, 0.0, c + c0 * a, 0.0, e, f + r0 * e)
    reproject(h, out, src_transform=src_t, src_crs=src_crs, dst_transform=dst_t,
              dst_crs=dst_crs, src_nodata=np.nan, dst_nodata=np.nan,
              resampling=getattr(Resampling, resampling))
    return Patch(r0, c0, out, name).clipped(grid)
