"""Sources of different resolutions and CRSs merged onto one target grid (issue 45).

A mosaic whose tiles share one CRS, pixel size and pixel grid is pasted by a plain VRT
(:mod:`geoterrain.ingest.mosaic`). Otherwise, or when a target grid is declared
(``crs``, ``resolution``), the sources are *layers* of a composite:

- **the target grid**: the CRS given, else the finest source's; the resolution given
  (target CRS units), else the finest source's there; the union of the sources' extents,
  on the pixel grid of the finest source when it is in the target CRS at that
  resolution (so its samples land on target samples).
- **each layer** is read a window at a time: a source already on the target grid
  directly (its samples kept exactly), any other through GDAL's warper in a warped VRT
  (rasterio's :class:`~rasterio.vrt.WarpedVRT`) with the resampling asked for
  (``bilinear``, ``cubic``, ``nearest``), its own nodata excluded from the kernel (GDAL
  renormalises the weights of the valid samples), never averaged in. The warp uses the
  exact transformer (no approximation), so a sample's value does not depend on the
  window it is read in.
- **priority**: where layers overlap, the first valid layer wins, finest first by
  default (``priority="finest"``), or in the order given (``"order"``); a void of one
  layer is filled from the next.

Nothing is merged in memory: :class:`CompositeReader` composes each window as it is read.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import warnings

import numpy as np
import rasterio
from rasterio.enums import Resampling
from rasterio.vrt import WarpedVRT
from rasterio.windows import Window

from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.gdalerrors import gdal_reason

__all__ = ["RESAMPLINGS", "PRIORITIES", "Layer", "Target", "CompositeReader", "plan",
           "needs_composite"]

RESAMPLINGS = ("bilinear", "cubic", "nearest")
PRIORITIES = ("finest", "order")
_EARTH = 6378137.0


@dataclasses.dataclass(frozen=True)
class Layer:
    """One source of a composite: its path (or URL), band, nodata (None: none but NaN)
    and, when it already lies on the target grid, the (row, column) of its first sample
    there (``offset``; None: warped)."""

    path: str
    band: int
    nodata: float | None
    offset: tuple[int, int] | None


@dataclasses.dataclass(frozen=True)
class Target:
    """The grid the layers are merged onto: CRS (WKT), GDAL affine (north up), size, the
    resampling of warped layers, and the heights' dtype."""

    crs_wkt: str
    transform: tuple[float, ...]
    width: int
    height: int
    resampling: str
    dtype: str


def _info(p: str, band: int | None, nodata: float | None) -> dict:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(p) as s:
                if s.crs is None:
                    raise InputError(f"{p}: has no CRS; sources of a merge are placed by "
                                     "their CRS and geotransform (georeference it first)")
                t = s.transform
                if t.b != 0 or t.d != 0:
                    raise InputError(f"{p}: is rotated; warp it north-up first")
                b = band or 1
                if band is None and s.count > 1:
                    raise UsageError(f"{p}: has {s.count} bands; choose one with band=N",
                                     cli=f"{p}: has {s.count} bands; choose one with --band N")
                if not 1 <= b <= s.count:
                    raise UsageError(f"{p}: band {b} out of range; it has {s.count} band(s)",
                                     cli=f"{p}: --band {b} out of range; it has {s.count} "
                                     "band(s)")
                nd = s.nodatavals[b - 1] if nodata is None else float(nodata)
                return {"path": p, "crs": s.crs, "t": t, "w": s.width, "h": s.height,
                        "band": b, "nodata": None if nd is None else float(nd),
                        "dtype": s.dtypes[b - 1], "bounds": s.bounds}
    except rasterio.errors.RasterioIOError as exc:
        raise InputError(f"{p}: not a raster GDAL can read ({gdal_reason(exc)})") from None


def _metres(s: dict) -> float:
    # the pixel's side in metres (geometric mean of its two sides), to rank resolutions
    a, e = abs(s["t"].a), abs(s["t"].e)
    if s["crs"].is_geographic:
        lat = math.radians(0.5 * (s["bounds"].bottom + s["bounds"].top))
        k = math.pi * _EARTH / 180.0
        return math.sqrt(a * k * max(math.cos(lat), 1e-6) * e * k)
    unit = s["crs"].linear_units_factor[1] if s["crs"].is_projected else 1.0
    return math.sqrt(a * e) * unit


def needs_composite(files: list, crs: str | None = None,
                    resolution: float | None = None) -> bool:
    """Whether ``files`` must be merged as a composite: a target grid is declared, or their
    CRSs, pixel sizes or pixel grids differ.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> a = write_geotiff(os.path.join(d, "a.tif"), generate("fbm", 9))
    >>> b = write_geotiff(os.path.join(d, "b.tif"), generate("fbm", 9), spacing=30.0)
    >>> needs_composite([a]), needs_composite([a, b]), needs_composite([a], resolution=5.0)
    (False, True, True)
    """
    if crs is not None or resolution is not None:
        return True
    if len(files) < 2:
        return False
    info = []
    for p in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
                with rasterio.open(str(p)) as s:
                    info.append((s.crs, s.transform))
        except rasterio.errors.RasterioIOError:
            return False  # the plain mosaic says which file cannot be read
    crs0, t0 = info[0]
    for c, t in info[1:]:
        if c != crs0 or not (np.isclose(t.a, t0.a, rtol=1e-9, atol=0)
                             and np.isclose(t.e, t0.e, rtol=1e-9, atol=0)):
            return True
        cx, cy = (t.c - t0.c) / t0.a, (t.f - t0.f) / t0.e
        if abs(cx - round(cx)) > 1e-6 or abs(cy - round(cy)) > 1e-6:
            return True
    return False


def plan(files: list, crs: str | None = None, resolution: float | None = None,
         resampling: str = "bilinear", priority: str = "finest", band: int | None = None,
         nodata: float | None = None) -> tuple[tuple[Layer, ...], Target]:
    """The layers (in priority order) and the target grid of a composite of ``files``.

    Examples
    --------
    >>> import tempfile, os
    >>> from pathlib import Path
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> a = write_geotiff(os.path.join(d, "a.tif"), generate("fbm", 9), spacing=30.0)
    >>> b = write_geotiff(os.path.join(d, "b.tif"), generate("fbm", 9), spacing=1.0,
    ...                   origin=(500100.0, 4999900.0))
    >>> layers, target = plan([a, b])
    >>> [Path(x.path).name for x in layers], target.transform[0], (target.width, target.height)
    (['b.tif', 'a.tif'], 1.0, (270, 270))
    """
    from rasterio.crs import CRS
    from rasterio.warp import calculate_default_transform, transform_bounds

    if resampling not in RESAMPLINGS:
        raise UsageError(f"unknown resampling {resampling!r}; use one of "
                         f"{', '.join(RESAMPLINGS)}")
    if priority not in PRIORITIES:
        raise UsageError(f"unknown priority {priority!r}; use one of {', '.join(PRIORITIES)}")
    if resolution is not None and not (np.isfinite(resolution) and resolution > 0):
        raise UsageError(f"resolution must be a finite number > 0, got {resolution}",
                         cli=f"--resolution must be a finite number > 0, got {resolution}")
    info = [_info(str(p), band, nodata) for p in files]
    order = sorted(range(len(info)), key=lambda k: _metres(info[k])) if priority == "finest" \
        else list(range(len(info)))
    finest = info[min(range(len(info)), key=lambda k: _metres(info[k]))]
    try:
        dst = CRS.from_user_input(crs) if crs is not None else finest["crs"]
    except rasterio.errors.CRSError as exc:
        raise UsageError(f"unknown CRS {crs!r} ({exc})", cli=f"--crs {crs!r} is not a CRS "
                         f"({exc})") from None
    if not (dst.is_projected or dst.is_geographic):
        raise UsageError(f"CRS {crs!r} is neither projected nor geographic")
    if resolution is not None:
        xres = yres = float(resolution)
    elif finest["crs"] == dst:
        xres, yres = abs(finest["t"].a), abs(finest["t"].e)
    else:
        t, _, _ = calculate_default_transform(finest["crs"], dst, finest["w"], finest["h"],
                                              *finest["bounds"])
        xres = yres = min(abs(t.a), abs(t.e))
    # the union of the extents in the target CRS
    boxes = [transform_bounds(s["crs"], dst, *s["bounds"], densify_pts=21) for s in info]
    west, south = min(b[0] for b in boxes), min(b[1] for b in boxes)
    east, north = max(b[2] for b in boxes), max(b[3] for b in boxes)
    # on the finest source's pixel grid when it is the target's (its samples kept as they are)
    on_grid = finest["crs"] == dst and np.isclose(abs(finest["t"].a), xres, rtol=1e-9) and \
        np.isclose(abs(finest["t"].e), yres, rtol=1e-9) and finest["t"].e < 0
    ax, ay = (finest["t"].c, finest["t"].f) if on_grid else (west, north)
    x0 = ax + math.floor((west - ax) / xres + 1e-9) * xres
    y0 = ay + math.ceil((north - ay) / yres - 1e-9) * yres
    width = max(2, math.ceil((east - x0) / xres - 1e-9))
    height = max(2, math.ceil((y0 - south) / yres - 1e-9))
    transform = (xres, 0.0, x0, 0.0, -yres, y0)
    dtype = np.result_type(np.float32, *[np.dtype(s["dtype"]) for s in info]).name
    layers = []
    for k in order:
        s = info[k]
        offset = None
        if s["crs"] == dst and np.isclose(s["t"].a, xres, rtol=1e-9) and \
                np.isclose(s["t"].e, -yres, rtol=1e-9):
            cx, cy = (s["t"].c - x0) / xres, (y0 - s["t"].f) / yres
            if abs(cx - round(cx)) <= 1e-6 and abs(cy - round(cy)) <= 1e-6:
                offset = (int(round(cy)), int(round(cx)))
        layers.append(Layer(s["path"], s["band"], s["nodata"], offset))
    target = Target(dst.to_wkt(), transform, int(width), int(height), resampling, dtype)
    return tuple(layers), target


class CompositeReader:
    """Windows of a composite: each sample from the first layer valid there (float64
    heights, NaN where no layer is; validity)."""

    def __init__(self, layers: tuple[Layer, ...], target: Target) -> None:
        self.layers, self.target = layers, target
        self.H, self.W = target.height, target.width
        self.height, self.width = target.height, target.width
        self._stack = contextlib.ExitStack()
        self._open = []
        from rasterio.transform import Affine

        dst_t = Affine(*target.transform)
        for lay in layers:
            ds = self._stack.enter_context(rasterio.open(lay.path))
            if lay.offset is not None:
                self._open.append(ds)
                continue
            vrt = self._stack.enter_context(WarpedVRT(
                ds, crs=target.crs_wkt, transform=dst_t, width=target.width,
                height=target.height, resampling=Resampling[target.resampling],
                src_nodata=lay.nodata, nodata=np.nan, dtype=target.dtype))
            self._open.append(_Blocks(vrt, lay.band))

    def close(self) -> None:
        self._stack.close()

    def heights(self, i0: int, i1: int, j0: int = 0, j1: int | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        j1 = self.W if j1 is None else j1
        z = np.full((i1 - i0, j1 - j0), np.nan)
        ok = np.zeros(z.shape, bool)
        for lay, ds in zip(self.layers, self._open, strict=True):
            if ok.all():
                break
            if lay.offset is None:
                h = ds.rows(i0, i1)[:, j0:j1].astype(np.float64)
                v = np.isfinite(h)
                r0, c0 = 0, 0
            else:  # on the target grid: the overlap read as it is
                oy, ox = lay.offset
                a0, b0 = max(i0, oy), max(j0, ox)
                a1, b1 = min(i1, oy + ds.height), min(j1, ox + ds.width)
                if a1 <= a0 or b1 <= b0:
                    continue
                a = ds.read(lay.band, window=Window(b0 - ox, a0 - oy, b1 - b0, a1 - a0))
                h = a.astype(np.float64)
                v = np.isfinite(h)
                if lay.nodata is not None and not np.isnan(lay.nodata):
                    nd = np.asarray(lay.nodata, a.dtype) if np.issubdtype(a.dtype, np.floating) \
                        else lay.nodata
                    v &= a != nd
                r0, c0 = a0 - i0, b0 - j0
            sub = np.s_[r0:r0 + h.shape[0], c0:c0 + h.shape[1]]
            take = v & ~ok[sub]
            z[sub][take] = h[take]
            ok[sub] |= take
        return z, ok


class _Blocks:
    """A warped VRT read by whole blocks, so that a sample's warped value is the same
    whatever window asks for it (the warper approximates the transform per chunk), with
    the last rows of blocks kept."""

    def __init__(self, vrt, band: int) -> None:
        self.vrt, self.band = vrt, band
        self.bh, self.bw = vrt.block_shapes[band - 1]
        self.cache: dict[int, np.ndarray] = {}

    def _block_row(self, k: int) -> np.ndarray:
        if k not in self.cache:
            H, W = self.vrt.height, self.vrt.width
            i0 = k * self.bh
            rows = min(self.bh, H - i0)
            out = np.empty((rows, W), self.vrt.dtypes[self.band - 1])
            for j in range(0, W, self.bw):
                out[:, j:j + self.bw] = self.vrt.read(
                    self.band, window=Window(j, i0, min(self.bw, W - j), rows))
            if len(self.cache) >= 2:
                self.cache.pop(next(iter(self.cache)))
            self.cache[k] = out
        return self.cache[k]

    def rows(self, i0: int, i1: int) -> np.ndarray:
        """Rows i0 … i1 − 1, every column."""
        parts = [self._block_row(k)[max(i0 - k * self.bh, 0):i1 - k * self.bh]
                 for k in range(i0 // self.bh, (i1 - 1) // self.bh + 1)]
        return np.concatenate(parts) if len(parts) > 1 else parts[0]


def describe_target(target: Target) -> dict:
    """The metadata of a composite (as :func:`geoterrain.ingest.windows.describe` gives)."""
    return {"shape": (target.height, target.width), "transform": tuple(target.transform),
            "crs_wkt": target.crs_wkt, "dtype": target.dtype, "encoding": "raw",
            "scale": None, "offset": None, "nodata": None}
