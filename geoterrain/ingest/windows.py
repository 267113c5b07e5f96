"""Ingest a window at a time: any raster :func:`geoterrain.ingest.raster.read_raster` reads,
read by rows (issue 45: every input streams).

:class:`RasterSpec` says how to open a source and turn its pixels into heights (a file, a
URL GDAL reads, or a mosaic's VRT text; a band, or a Terrain-RGB / Terrarium PNG
decoding; the nodata; whether rows are flipped north-up). It is plain data, so a
scheduler can ship it to a worker process, which opens the source itself.
:class:`WindowReader` hands out windows of heights (float64, NaN where invalid) and
validity, the values :func:`~geoterrain.ingest.raster.read_raster` reads there.
:func:`describe` makes the spec from the same arguments as ``read_raster``, with the same
checks and choices, reading only metadata and, for an auto-detected PNG encoding, the
statistics that choose it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import rasterio
from rasterio.windows import Window

from geoterrain.core.orderstat import median
from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.composite import (
    CompositeReader,
    Layer,
    Target,
    describe_target,
    needs_composite,
    plan,
)
from geoterrain.ingest.gdalerrors import gdal_reason
from geoterrain.ingest.mosaic import build_vrt, failing_tile, mosaic_name, source_files
from geoterrain.ingest.raster import (
    ENCODINGS,
    GDAL_READ_OPTIONS,
    ROUGH_PNG_STEP,
    TERRAIN_RGB_OFFSET,
    TERRAIN_RGB_SCALE,
    TERRARIUM_OFFSET,
    TERRARIUM_SCALE,
)
from geoterrain.ingest.remote import is_url

__all__ = ["RasterSpec", "WindowReader", "describe", "localize", "read_errors"]

log = logging.getLogger("geoterrain")


@dataclasses.dataclass(frozen=True)
class RasterSpec:
    """A raster source and how its pixels become heights (picklable).

    ``path``: what rasterio opens (a file or a URL); ``vrt``: a VRT's XML text instead (a
    mosaic); ``band``: the 1-based band of a raw raster; ``encoding``: ``raw``,
    ``terrain-rgb`` or ``terrarium``; ``nodata``: the void value (raw; NaN: none but NaN);
    ``flip``: south-up rows read north-up; ``label``: the name in messages and the
    store's ``source``; ``files``: the local files it reads (a resumed run checks them);
    ``layers`` and ``target``: sources of several resolutions or CRSs merged onto one
    grid (:mod:`geoterrain.ingest.composite`).
    """

    path: str
    vrt: str | None
    band: int
    encoding: str
    nodata: float | None
    flip: bool
    label: str
    files: tuple[str, ...] = ()
    layers: tuple[Layer, ...] = ()
    target: Target | None = None

    @contextlib.contextmanager
    def open(self, cache: int | None = None) -> Iterator:
        """The source opened with rasterio (GDAL's read options set, its block cache
        ``cache`` bytes if given); a composite's layers as a
        :class:`~geoterrain.ingest.composite.CompositeReader`."""
        opts = GDAL_READ_OPTIONS if cache is None else {**GDAL_READ_OPTIONS,
                                                        "GDAL_CACHEMAX": int(cache)}
        with warnings.catch_warnings(), rasterio.Env(**opts):
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            if self.layers:
                reader = CompositeReader(self.layers, self.target)
                try:
                    yield reader
                finally:
                    reader.close()
            elif self.vrt is not None:
                with rasterio.MemoryFile(self.vrt.encode(), ext="vrt") as mem, \
                        mem.open() as ds:
                    yield ds
            else:
                with rasterio.open(self.path) as ds:
                    yield ds

    @property
    def scale_offset(self) -> tuple[float | None, float | None]:
        """(scale, offset) of a PNG encoding's integer codes; (None, None) for raw."""
        if self.encoding == "terrain-rgb":
            return TERRAIN_RGB_SCALE, TERRAIN_RGB_OFFSET
        if self.encoding == "terrarium":
            return TERRARIUM_SCALE, TERRARIUM_OFFSET
        return None, None


class WindowReader:
    """Windows of an opened source as heights and validity, north up.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> p = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 9))
    >>> spec, _ = describe(p)
    >>> with spec.open() as ds:
    ...     h, v = WindowReader(ds, spec).heights(2, 4, 0, 9)
    >>> h.shape, bool(v.all())
    ((2, 9), True)
    """

    def __init__(self, ds, spec: RasterSpec) -> None:
        self.ds, self.spec = ds, spec
        self.H, self.W = ds.height, ds.width

    def _window(self, i0: int, i1: int, j0: int, j1: int) -> Window:
        if self.spec.flip:
            return Window(j0, self.H - i1, j1 - j0, i1 - i0)
        return Window(j0, i0, j1 - j0, i1 - i0)

    def raw(self, i0: int, i1: int, j0: int = 0, j1: int | None = None) -> np.ndarray:
        """The raw band's rows i0 … i1 − 1, columns j0 … j1 − 1 (north up), the file's
        dtype (a raw raster)."""
        j1 = self.W if j1 is None else j1
        with read_errors(self.spec.label, self.spec.files):
            a = self.ds.read(self.spec.band, window=self._window(i0, i1, j0, j1))
        return a[::-1] if self.spec.flip else a

    def heights(self, i0: int, i1: int, j0: int = 0, j1: int | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """(heights float64, NaN where invalid; valid) of rows i0 … i1 − 1 and columns
        j0 … j1 − 1: read_raster's values there."""
        with read_errors(self.spec.label, self.spec.files):
            return self._heights(i0, i1, j0, j1)

    def _heights(self, i0: int, i1: int, j0: int = 0, j1: int | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        j1 = self.W if j1 is None else j1
        spec = self.spec
        if spec.layers:
            return self.ds.heights(i0, i1, j0, j1)
        if spec.encoding in ("terrain-rgb", "terrarium"):
            rgba = self.ds.read(window=self._window(i0, i1, j0, j1))
            if spec.flip:
                rgba = rgba[:, ::-1]
            r, g, b = (rgba[k].astype(np.int64) for k in range(3))
            scale, offset = spec.scale_offset
            h = offset + (r * 65536 + g * 256 + b).astype(np.float64) * scale
            ok = rgba[3] > 0 if rgba.shape[0] == 4 else np.ones(h.shape, bool)
            return np.where(ok, h, np.nan), ok
        data = self.raw(i0, i1, j0, j1)
        h = data.astype(np.float64)
        ok = np.isfinite(h)
        nd = spec.nodata
        if nd is not None and not np.isnan(nd):
            if np.issubdtype(data.dtype, np.floating):
                ok &= data != np.asarray(nd, dtype=data.dtype)  # float32 nodata: compare there
            else:
                ok &= data != nd
        return np.where(ok, h, np.nan), ok


@contextlib.contextmanager
def read_errors(label: str, files: tuple = ()) -> Iterator[None]:
    """A read GDAL fails (a corrupt tile, an HTTP error, a truncated response after its
    retries) as one :class:`InputError` line naming the source and GDAL's reason (for a
    mosaic of ``files``, the tile that fails)."""
    try:
        yield
    except rasterio.errors.RasterioError as exc:
        why = (failing_tile(files) if len(files) > 1 else None) or gdal_reason(exc)
        raise InputError(f"{label}: a read failed ({why})") from None


def localize(spec: RasterSpec, folder: str | Path) -> RasterSpec:
    """``spec`` with its sources read over HTTP copied once into GeoTIFFs in ``folder``
    (a band of block rows at a time: each remote block is fetched once), so that the
    passes that read the raster again read local files; local sources are left as they
    are.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> p = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 9))
    >>> spec, _ = describe(p)
    >>> localize(spec, tempfile.mkdtemp()) == spec  # nothing remote
    True
    """
    folder = Path(folder)
    if spec.layers and any(is_url(lay.path) for lay in spec.layers):
        folder.mkdir(parents=True, exist_ok=True)
        layers = []
        for k, lay in enumerate(spec.layers):
            if is_url(lay.path):
                local = folder / f"layer_{k}.tif"
                _copy(lay.path, None, [lay.band], local, lay.path)
                lay = dataclasses.replace(lay, path=str(local), band=1)
            layers.append(lay)
        return dataclasses.replace(spec, layers=tuple(layers))
    if spec.layers or not (is_url(spec.path) or (spec.vrt is not None
                                                 and "/vsicurl/" in spec.vrt)):
        return spec
    folder.mkdir(parents=True, exist_ok=True)
    local = folder / "source.tif"
    bands = [spec.band] if spec.encoding == "raw" else None
    _copy(spec.path, spec.vrt, bands, local, spec.label)
    return dataclasses.replace(spec, path=str(local), vrt=None,
                               band=1 if spec.encoding == "raw" else spec.band)


def _copy(path: str, vrt: str | None, bands: list[int] | None, dst: Path, label: str) -> None:
    # the source's bands, as they are stored (rows not flipped), into a tiled GeoTIFF
    probe = RasterSpec(path, vrt, 1, "raw", None, False, label)
    with probe.open() as ds, read_errors(label):
        bands = bands or list(range(1, ds.count + 1))
        prof = {"driver": "GTiff", "width": ds.width, "height": ds.height,
                "count": len(bands), "dtype": ds.dtypes[bands[0] - 1], "crs": ds.crs,
                "transform": ds.transform, "nodata": ds.nodatavals[bands[0] - 1],
                "tiled": True, "blockxsize": 256, "blockysize": 256, "BIGTIFF": "IF_SAFER"}
        rows = max(ds.block_shapes[bands[0] - 1][0], 256)
        with rasterio.open(dst, "w", **prof) as out:
            for i in range(0, ds.height, rows):
                w = Window(0, i, ds.width, min(rows, ds.height - i))
                out.write(ds.read(bands, window=w), window=w)


def _kth_uint8(counts: np.ndarray, k: int) -> int:
    return int(np.searchsorted(np.cumsum(counts), k, side="right"))


def _median_red(ds, spec: RasterSpec, rows: int) -> float:
    # np.median of the red band (uint8) from a histogram: exact
    counts = np.zeros(256, np.int64)
    for i in range(0, ds.height, rows):
        w = Window(0, i, ds.width, min(rows, ds.height - i))
        counts += np.bincount(ds.read(1, window=w).ravel(), minlength=256)
    n = int(counts.sum())
    if n % 2:
        return float(_kth_uint8(counts, n // 2))
    a, b = _kth_uint8(counts, n // 2 - 1), _kth_uint8(counts, n // 2)
    return float((np.float64(a) + np.float64(b)) / 2.0)


def _median_step(reader: WindowReader, rows: int) -> float:
    # raster._too_rough: the median |difference| between valid neighbours, exactly
    H = reader.H

    def bands():
        for i in range(0, H, rows):
            h, v = reader.heights(i, min(i + rows + 1, H))
            h = np.where(v, h, 0.0)
            dv = np.abs(np.diff(h, axis=0))[v[1:] & v[:-1]]
            dh = np.abs(np.diff(h[:rows], axis=1))[v[:rows, 1:] & v[:rows, :-1]]
            yield np.concatenate([dv, dh])

    m = median(bands)
    return 0.0 if m is None else m


def describe(src: str | Path | list, band: int | None = None, encoding: str = "auto",
             nodata: float | None = None, rows: int = 256, crs: str | None = None,
             resolution: float | None = None, resampling: str = "bilinear",
             priority: str = "finest") -> tuple[RasterSpec, dict]:
    """The :class:`RasterSpec` of a DEM argument (a file, URL, list or glob) read with
    :func:`~geoterrain.ingest.raster.read_raster`'s arguments, and its metadata:
    ``shape``, ``transform`` (GDAL affine, north up; None without georeference),
    ``crs_wkt``, ``dtype``, ``encoding`` (the one decided), ``nodata`` (declared or given;
    an undeclared void sentinel is the streaming scan's), ``scale`` and ``offset``.

    Same checks and one-line errors as ``read_raster``; an auto-detected PNG encoding is
    chosen from its red band's median and refused when its heights are implausibly
    rough, both computed exactly, ``rows`` at a time. Sources of several resolutions or
    CRSs, or a declared target grid (``crs``, ``resolution``), make a composite
    (:func:`geoterrain.ingest.composite.plan`).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> p = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 9))
    >>> spec, meta = describe(p)
    >>> spec.encoding, meta["shape"]
    ('raw', (9, 9))
    """
    if encoding not in ENCODINGS:
        raise UsageError(f"unknown encoding {encoding!r}; use one of {', '.join(ENCODINGS)}")
    files = source_files(src)
    vrt = None
    if needs_composite(files, crs, resolution):
        if encoding not in ("auto", "raw"):
            raise UsageError("sources merged onto a target grid are read raw; drop encoding",
                             cli="sources merged onto a target grid are read raw; drop "
                             "--encoding")
        layers, target = plan(files, crs, resolution, resampling, priority, band, nodata)
        local = tuple(str(f.resolve()) for f in files if isinstance(f, Path))
        spec = RasterSpec("", None, 1, "raw", None, False, mosaic_name(files), local, layers,
                          target)
        return spec, describe_target(target)
    if len(files) > 1:
        vrt = build_vrt(files)
        label, path = mosaic_name(files), ""
    else:
        p = files[0]
        if not p.exists():
            raise InputError(f"{p}: no such file; check the path")
        if p.is_dir():
            raise InputError(f"{p}: is a directory, not a raster file")
        label, path = p.name, str(p)
    probe = RasterSpec(path, vrt, 1, "raw", None, False, label)
    try:
        with probe.open() as ds:
            return _describe_open(ds, probe, files, band, encoding, nodata, rows)
    except rasterio.errors.RasterioIOError as exc:
        if vrt is not None:
            raise InputError(f"{label}: a tile cannot be read ({gdal_reason(exc)})") from None
        raise InputError(f"{files[0]}: not a raster GDAL can read ({gdal_reason(exc)})") \
            from None


def _describe_open(ds, probe: RasterSpec, files: list[Path], band: int | None,
                   encoding: str, nodata_arg: float | None, rows: int
                   ) -> tuple[RasterSpec, dict]:
    p = files[0] if probe.vrt is None else Path(probe.label)
    count, dtype = ds.count, ds.dtypes[0]
    is_png_tile = ds.driver == "PNG" and count in (3, 4) and dtype == "uint8"
    guessed = False
    if encoding == "auto":
        encoding = "raw"
        if is_png_tile and band is None:
            encoding = "terrarium" if _median_red(ds, probe, rows) >= 64 else "terrain-rgb"
            guessed = True
    crs_wkt = ds.crs.to_wkt() if ds.crs else None
    transform = tuple(ds.transform)[:6] if (ds.crs or not ds.transform.is_identity) else None
    if ds.height < 2 or ds.width < 2:
        raise InputError(f"{p}: grid is {ds.height}×{ds.width}; a DEM needs at least 2×2 "
                         "samples")
    flip = transform is not None and transform[4] > 0
    if flip:  # south-up: rows flipped to north-up (raster.py)
        a, b, c, d, e, f = transform
        transform = (a, b, c, d, -e, f + e * ds.height)
    local = tuple(str(f.resolve()) for f in files if isinstance(f, Path))
    meta = {"shape": (ds.height, ds.width), "transform": transform, "crs_wkt": crs_wkt,
            "dtype": dtype, "encoding": encoding, "scale": None, "offset": None,
            "nodata": None}
    if encoding in ("terrain-rgb", "terrarium"):
        if count < 3 or dtype != "uint8":
            raise InputError(f"{p}: {encoding} needs 3 or 4 uint8 bands (RGB[A]), found "
                             f"{count} {dtype}")
        spec = RasterSpec(probe.path, probe.vrt, 1, encoding, None, flip, probe.label, local)
        meta["scale"], meta["offset"] = spec.scale_offset
        if guessed:
            step = _median_step(WindowReader(ds, spec), rows)
            if step > ROUGH_PNG_STEP:
                raise InputError(
                    f"{p}: decoded as {encoding}, neighbouring heights differ by {step:.0f} m "
                    "(median): not an elevation tile of that encoding; pass "
                    "encoding='terrain-rgb', 'terrarium' or 'raw'", cli=f"{p}: decoded as "
                    f"{encoding}, neighbouring heights differ by {step:.0f} m (median): not an "
                    "elevation tile of that encoding; pass --encoding terrain-rgb, terrarium "
                    "or raw")
        return spec, meta
    if band is None:
        if count > 1:
            raise UsageError(f"{p}: has {count} bands; choose one with band=N (1..{count})",
                             cli=f"{p}: has {count} bands; choose one with --band N (1..{count})")
        band = 1
    if not 1 <= band <= count:
        raise UsageError(f"{p}: band {band} out of range; the raster has {count} band(s)",
                         cli=f"{p}: --band {band} out of range; the raster has {count} band(s)")
    nd = ds.nodatavals[band - 1] if nodata_arg is None else float(nodata_arg)
    meta["dtype"] = ds.dtypes[band - 1]
    meta["nodata"] = None if nd is None else float(nd)
    spec = RasterSpec(probe.path, probe.vrt, band, "raw", meta["nodata"], flip, probe.label,
                      local)
    return spec, meta
