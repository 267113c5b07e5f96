"""Ingest: read a DEM with rasterio into heights, a validity mask and its georeference.

Any single-band raster GDAL reads (GeoTIFF/COG, SRTM ``.hgt``, Esri ASCII,
USGS DEM, ...) and the Mapbox Terrain-RGB and Terrarium PNG encodings.
"""

from __future__ import annotations

import logging
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rasterio
from rasterio.errors import RasterioIOError

from geoterrain.core.memory import available_memory
from geoterrain.core.paths import input_problem
from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.composite import CompositeReader, needs_composite, plan
from geoterrain.ingest.gdalerrors import gdal_reason
from geoterrain.ingest.mosaic import failing_tile, mosaic_name, open_mosaic, source_files
from geoterrain.ingest.remote import is_url

log = logging.getLogger("geoterrain")

ENCODINGS = ("auto", "raw", "terrain-rgb", "terrarium")

# Terrain-RGB: h = -10000 + (R*65536 + G*256 + B) * 0.1  (../shared/dems/README.md)
TERRAIN_RGB_SCALE, TERRAIN_RGB_OFFSET = 0.1, -10000.0
# Terrarium: h = R*256 + G + B/256 - 32768, i.e. an integer code times 1/256
TERRARIUM_SCALE, TERRARIUM_OFFSET = 1.0 / 256.0, -32768.0


@dataclass
class Raster:
    """A DEM in memory: heights as float64 with a validity mask.

    ``scale`` and ``offset`` are set when the heights are known to be
    ``offset + k * scale`` for integers ``k`` (PNG encodings), which lets the
    codec store them losslessly as integers.
    """

    heights: np.ndarray  # (H, W) float64; arbitrary where not valid
    valid: np.ndarray  # (H, W) bool
    transform: tuple[float, ...] | None  # GDAL affine (a, b, c, d, e, f), or None
    crs_wkt: str | None
    src_dtype: str
    nodata: float | None
    encoding: str
    path: str
    scale: float | None = None
    offset: float | None = None
    is_integer: bool = False

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape  # type: ignore[return-value]


def _decode_png(rgb: np.ndarray, encoding: str) -> tuple[np.ndarray, float, float]:
    """Integer codes of a Terrain-RGB or Terrarium tile; heights = offset + code * scale."""
    r, g, b = (rgb[k].astype(np.int64) for k in range(3))
    if encoding == "terrain-rgb":
        return r * 65536 + g * 256 + b, TERRAIN_RGB_SCALE, TERRAIN_RGB_OFFSET
    return r * 65536 + g * 256 + b, TERRARIUM_SCALE, TERRARIUM_OFFSET


ABSURD_HEIGHT = 1e5  # |h| beyond this is almost surely a unit or nodata problem
# Values some tools write for voids without declaring them nodata (SRTM, ArcGRID, float32 min)
VOID_SENTINELS = (-32768.0, -32767.0, -9999.0, float(np.finfo(np.float32).min))
ROUGH_PNG_STEP = 1000.0  # metres: a median neighbour step beyond this is not terrain
# GDAL decodes the blocks of a compressed raster on every core (4097² DEFLATE GeoTIFF:
# 0.27 → 0.13 s on 2 cores, docs/lab/preprocess.md); the bytes read are the same
# GDAL's block cache is set, not left at its default of 5 % of RAM: a whole-raster read
# keeps no block after copying it out, and a windowed one rereads little
# Rasters over HTTP (GDAL's /vsicurl/): a failed request is retried 3 times, half a second
# apart; the other options only concern HTTP requests
GDAL_READ_OPTIONS = {"GDAL_NUM_THREADS": "ALL_CPUS", "GDAL_CACHEMAX": 64 * 2**20,
                     "GDAL_HTTP_MAX_RETRY": 3, "GDAL_HTTP_RETRY_DELAY": 0.5,
                     "GDAL_HTTP_TIMEOUT": 60}
# ... except in a fork() child: GDAL's pool of decoding threads was made in the parent
# and its threads are not copied, so a read waits for them forever (Pool(2).map of
# preprocess after a preprocess in the parent hung on a multi-block GeoTIFF)
os.register_at_fork(after_in_child=lambda: GDAL_READ_OPTIONS.update(GDAL_NUM_THREADS="1"))
# peak RSS of the preprocess per source sample, measured (benchmarks/bench_preprocess.py,
# docs/lab/preprocess.md): 62 at
# 4097² and 52 at 8193² in a projected CRS, 116 at 4097² in a geographic one (full X, Y
# and the curvilinear terms); with a margin
PREPROCESS_BYTES_PER_SAMPLE = {"projected": 72, "geographic": 128}


def _undeclared_voids(data: np.ndarray, valid: np.ndarray) -> float | None:
    """A sentinel value that stands for voids (far below every other height), or None."""
    # the lowest valid value without copying the valid ones (exact in float64: the
    # heights are the data's values); the copy only when it is a sentinel
    if not valid.any():
        return None
    top = np.inf if data.dtype.kind == "f" else np.iinfo(data.dtype).max
    lo = float(np.min(data, where=valid, initial=top))
    for s in VOID_SENTINELS:
        if lo == s:
            v = data[valid]
            rest = v[v != lo]
            if rest.size and float(rest.min()) - lo > 1000.0:
                return s
    return None


def _too_rough(h: np.ndarray, valid: np.ndarray) -> float:
    """The median |difference| between valid neighbouring heights (metres)."""
    d = [np.abs(np.diff(h, axis=a))[(valid[1:] & valid[:-1]) if a == 0 else
                                     (valid[:, 1:] & valid[:, :-1])] for a in (0, 1)]
    d = np.concatenate(d)
    return float(np.median(d)) if d.size else 0.0


def _guess_png_encoding(red: np.ndarray) -> str:
    # Real heights (-500..9000 m) put Terrain-RGB's red byte near 1-2 and
    # Terrarium's near 126-163, so the median red byte tells them apart.
    return "terrarium" if float(np.median(red)) >= 64 else "terrain-rgb"


def read_raster(
    path: str | Path | list,
    band: int | None = None,
    encoding: str = "auto",
    nodata: float | None = None,
    crs: str | None = None,
    resolution: float | None = None,
    resampling: str = "bilinear",
    priority: str = "finest",
) -> Raster:
    """Read a DEM into a :class:`Raster`.

    Parameters
    ----------
    path
        Any raster GDAL reads (a ``.vrt`` too), or a Terrain-RGB / Terrarium PNG tile;
        or a list of files or a glob (``tiles/*.hgt``): a mosaic read as one raster
        (see :mod:`geoterrain.ingest.mosaic`).
    band
        1-based band for multi-band rasters that are not a known PNG encoding.
    encoding
        ``auto`` (PNG tiles with 3-4 uint8 bands are decoded as Terrain-RGB or
        Terrarium, other rasters read raw), ``raw``, ``terrain-rgb`` or
        ``terrarium``. An auto-detected PNG whose heights are implausibly rough
        is refused: name its encoding.
    nodata
        The value of voids, overriding the file's; NaN: only NaN is a void. When
        neither is given, an undeclared -32768, -32767, -9999 or float32-min run
        far below the other heights is taken as voids, with a warning.

    crs, resolution, resampling, priority
        Sources of several resolutions or CRSs, or any source with a declared target grid
        (``crs``, ``resolution`` in its units), are merged onto one grid
        (:mod:`geoterrain.ingest.composite`): each source warped there (``resampling``
        ``bilinear``, ``cubic`` or ``nearest``) with its own nodata, the first valid
        source winning where they overlap (finest first, or ``priority="order"``: as
        given).

    A south-up raster (positive row step) is flipped to north-up.

    Examples
    --------
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> import tempfile, os
    >>> p = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 9))
    >>> read_raster(p).shape
    (9, 9)
    """
    if encoding not in ENCODINGS:
        raise UsageError(f"unknown encoding {encoding!r}; use one of {', '.join(ENCODINGS)}")
    files = source_files(path)
    if needs_composite(files, crs, resolution):
        return _read_composite(files, band, encoding, nodata, crs, resolution, resampling,
                               priority)
    if len(files) > 1:
        return _read_mosaic(files, band, encoding, nodata)
    p = files[0]
    if not is_url(p) and (why := input_problem(p, utf8=True)) is not None:  # a device, a FIFO
        raise InputError(f"{p}: {why}; give a raster file")
    try:
        with warnings.catch_warnings(), rasterio.Env(**GDAL_READ_OPTIONS):
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(str(p)) as src:
                _check_memory(src, p)
                return _read_open(src, p, band, encoding, nodata)
    except RasterioIOError as exc:
        raise InputError(f"{p}: not a raster GDAL can read ({gdal_reason(exc)})") from None


def _check_memory(src, p) -> None:
    kind = "geographic" if src.crs is not None and src.crs.is_geographic else "projected"
    need = src.height * src.width * PREPROCESS_BYTES_PER_SAMPLE[kind]
    if need > available_memory():
        raise InputError(
            f"{p}: {src.height}×{src.width} samples need about {need / 2**30:.1f} "
            f"GiB to preprocess, {available_memory() / 2**30:.1f} GiB is available; "
            "crop or downsample it (gdal_translate -srcwin / -outsize) first")


def _read_composite(files: list[Path], band: int | None, encoding: str, nodata: float | None,
                    crs: str | None, resolution: float | None, resampling: str,
                    priority: str) -> Raster:
    """Sources merged onto one grid (:mod:`geoterrain.ingest.composite`), read whole."""
    if encoding not in ("auto", "raw"):
        raise UsageError("sources merged onto a target grid are read raw; drop encoding",
                         cli="sources merged onto a target grid are read raw; drop --encoding")
    layers, target = plan(files, crs, resolution, resampling, priority, band, nodata)
    label = mosaic_name(files)
    from rasterio.crs import CRS

    kind = "geographic" if CRS.from_wkt(target.crs_wkt).is_geographic else "projected"
    need = target.height * target.width * PREPROCESS_BYTES_PER_SAMPLE[kind]
    if need > available_memory():
        raise InputError(f"{label}: {target.height}×{target.width} samples need about "
                         f"{need / 2**30:.1f} GiB to preprocess whole, "
                         f"{available_memory() / 2**30:.1f} GiB is available; coarsen the "
                         "target grid (--resolution)")
    try:
        with rasterio.Env(**GDAL_READ_OPTIONS):
            reader = CompositeReader(layers, target)
            try:
                heights, valid = reader.heights(0, target.height)
            finally:
                reader.close()
    except RasterioIOError as exc:
        raise InputError(f"{label}: a source cannot be read ({gdal_reason(exc)})") from None
    return Raster(heights, valid, tuple(target.transform), target.crs_wkt, target.dtype, None,
                  "raw", label)


def _read_mosaic(files: list[Path], band: int | None, encoding: str,
                 nodata: float | None) -> Raster:
    """Several tiles as one raster through an in-memory VRT (:mod:`geoterrain.ingest.mosaic`)."""
    label = mosaic_name(files)
    mem, src = open_mosaic(files)
    try:
        with mem, src, rasterio.Env(**GDAL_READ_OPTIONS):
            _check_memory(src, label)
            r = _read_open(src, Path(label), band, encoding, nodata)
    except RasterioIOError as exc:
        why = failing_tile(files) or gdal_reason(exc)
        raise InputError(f"{label}: a tile cannot be read ({why})") from None
    return r


def _read_open(src, p: Path, band: int | None, encoding: str, nodata_arg: float | None
               ) -> Raster:
    count, dtype = src.count, src.dtypes[0]
    is_png_tile = src.driver == "PNG" and count in (3, 4) and dtype == "uint8"
    named_raw = encoding == "raw"
    guessed = False
    if encoding == "auto":
        encoding = "raw"
        if is_png_tile and band is None:
            encoding = _guess_png_encoding(src.read(1))
            guessed = True
    crs_wkt = src.crs.to_wkt() if src.crs else None
    transform = tuple(src.transform)[:6] if (src.crs or not src.transform.is_identity) else None
    if src.height < 2 or src.width < 2:
        raise InputError(
            f"{p}: grid is {src.height}×{src.width}; a DEM needs at least 2×2 samples"
        )

    if encoding in ("terrain-rgb", "terrarium"):
        if count < 3 or dtype != "uint8":
            raise InputError(
                f"{p}: {encoding} needs 3 or 4 uint8 bands (RGB[A]), found {count} {dtype}"
            )
        rgba = src.read()
        codes, scale, offset = _decode_png(rgba, encoding)
        heights = offset + codes.astype(np.float64) * scale
        valid = np.ones(heights.shape, bool)
        if count == 4:
            valid &= rgba[3] > 0  # transparent pixels are nodata
        step = _too_rough(heights, valid)
        if guessed and step > ROUGH_PNG_STEP:
            raise InputError(
                f"{p}: decoded as {encoding}, neighbouring heights differ by {step:.0f} m (median)"
                ": not an elevation tile of that encoding; pass encoding='terrain-rgb', "
                "'terrarium' or 'raw'", cli=f"{p}: decoded as {encoding}, neighbouring heights "
                f"differ by {step:.0f} m (median): not an elevation tile of that encoding; pass "
                "--encoding terrain-rgb, terrarium or raw")
        return Raster(heights, valid, transform, crs_wkt, dtype, None, encoding, str(p),
                      scale=scale, offset=offset, is_integer=True)

    if (count >= 3 and dtype == "uint8" and transform is None and crs_wkt is None
            and not named_raw):
        # a picture (a photo, a map; a JPEG with EXIF), not heights: only when asked for
        raise InputError(f"{p}: {count} 8-bit bands without a CRS or georeference: a picture, "
                         "not a DEM; to read a band of it as heights pass encoding='raw' and "
                         "band", cli=f"{p}: {count} 8-bit bands without a CRS or "
                         "georeference: a picture, not a DEM; to read a band of it as heights "
                         "pass --encoding raw --band N")
    if band is None:
        if count > 1:
            raise UsageError(f"{p}: has {count} bands; choose one with band=N (1..{count})",
                             cli=f"{p}: has {count} bands; choose one with --band N (1..{count})")
        band = 1
    if not 1 <= band <= count:
        raise UsageError(f"{p}: band {band} out of range; the raster has {count} band(s)",
                         cli=f"{p}: --band {band} out of range; the raster has {count} band(s)")
    data = src.read(band)
    nodata = src.nodatavals[band - 1] if nodata_arg is None else float(nodata_arg)
    if transform is not None and transform[4] > 0:  # south-up: flip the rows to north-up
        a, b, c, d, e, f = transform
        data = data[::-1]
        transform = (a, b, c, d, -e, f + e * src.height)
    heights = data.astype(np.float64)
    # on the source's values (float32: half the bytes read; the same as on heights)
    valid = np.isfinite(data)
    finite = bool(valid.all())  # no NaN and no ±inf: no ±inf to count below
    if nodata is None:
        void = _undeclared_voids(data, valid)
        if void is not None:
            n = int((data == np.asarray(void, data.dtype)).sum())
            log.warning("%s: %d samples are %g, far below the other heights: taken as nodata "
                        "(undeclared voids); pass --nodata to say otherwise", p, n, void)
            nodata = void
    if nodata is not None and not np.isnan(nodata):
        if np.issubdtype(data.dtype, np.floating):
            # float nodata such as -3.4028235e38 is stored in float32: compare there
            valid &= data != np.asarray(nodata, dtype=data.dtype)
        else:
            valid &= data != nodata
    n_inf = 0 if finite else int(np.isinf(data).sum())
    if n_inf:
        raise InputError(
            f"{p}: {n_inf} sample(s) are ±inf; declare them nodata (e.g. gdal_translate -a_nodata)"
        )
    is_integer = bool(np.issubdtype(data.dtype, np.integer))
    return Raster(heights, valid, transform, crs_wkt, str(data.dtype),
                  None if nodata is None else float(nodata), "raw", str(p),
                  is_integer=is_integer)
