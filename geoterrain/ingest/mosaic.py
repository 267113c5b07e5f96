"""Ingest: several DEM tiles read as one raster (a GDAL VRT mosaic).

``preprocess`` accepts a ``.vrt`` (GDAL reads it natively), a list of files, a
glob (``tiles/*.hgt``) or a folder (its rasters by suffix, :data:`FOLDER_SUFFIXES`:
SRTM's ``.hgt`` and ``.hgt.zip`` as downloaded, GeoTIFFs, …). A list, glob or folder
becomes a VRT written here from each source's rasterio metadata (size, geotransform,
CRS, dtype, nodata): no pixel is read or copied, GDAL pastes the sources lazily, so
the mosaic costs what one raster of its size costs. (``rasterio.merge`` would instead
copy every tile into one more in-memory array, and rasterio has no BuildVRT.)

The sources must share one CRS, one pixel size (north-up, no rotation), one band
count and one pixel grid; each source's nodata is honoured (its nodata pixels
leave what lies below, and gaps between tiles are nodata).
"""

from __future__ import annotations

import glob as _glob
import warnings
from pathlib import Path

import numpy as np
import rasterio

from geoterrain.core.paths import input_problem
from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.gdalerrors import gdal_reason
from geoterrain.ingest.remote import Url, is_url, list_file, read_list


def escape(text: str) -> str:
    """``xml.sax.saxutils.escape``, imported when a VRT is written (it imports urllib's
    request and http.client with ssl: 10-25 ms that reading a raster need not pay)."""
    from xml.sax.saxutils import escape as _escape

    return _escape(text)


GLOB_CHARS = "*?["
#: What a folder given as a DEM contributes: files whose names end so (case-insensitive),
#: not its subfolders. VRTs are left out (one usually pastes the folder's own tiles).
FOLDER_SUFFIXES = (".tif", ".tiff", ".hgt", ".hgt.zip", ".asc", ".img", ".bil", ".dem",
                   ".dt0", ".dt1", ".dt2", ".jp2", ".flt")
_GDAL_TYPES = {"uint8": "Byte", "int8": "Int8", "uint16": "UInt16", "int16": "Int16",
               "uint32": "UInt32", "int32": "Int32", "float32": "Float32",
               "float64": "Float64", "int64": "Int64", "uint64": "UInt64"}


def is_glob(src: str | Path) -> bool:
    """Whether ``src`` is a glob pattern (and not an existing file's name).

    Examples
    --------
    >>> is_glob("tiles/*.hgt"), is_glob("dem.tif")
    (True, False)
    """
    return (isinstance(src, str) and not is_url(src) and any(c in src for c in GLOB_CHARS)
            and not Path(src).exists())


def is_folder(src) -> bool:
    """Whether a DEM argument is a local folder (its rasters are read as one mosaic).

    Examples
    --------
    >>> is_folder("."), is_folder("dem.tif"), is_folder(["a.tif"]), is_folder("a" * 300)
    (True, False, False, False)
    """
    if not isinstance(src, (str, Path)) or is_url(src):
        return False
    try:
        return Path(src).is_dir()
    except OSError:  # a name the system cannot look up (too long, ...): not a folder
        return False


def folder_files(folder: str | Path) -> list[Path]:
    """The rasters of a folder (:data:`FOLDER_SUFFIXES`), sorted by name; a one-line
    :class:`InputError` naming the suffixes when it holds none.

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> for n in ("N35E139.hgt", "N35E138.SRTMGL1.hgt.zip", "N35E139.hgt.aux.xml"):
    ...     _ = (d / n).write_bytes(b"")
    >>> [p.name for p in folder_files(d)]
    ['N35E138.SRTMGL1.hgt.zip', 'N35E139.hgt']
    """
    folder = Path(folder)
    files = sorted(p for p in folder.iterdir()
                   if p.name.lower().endswith(FOLDER_SUFFIXES) and p.is_file())
    if not files:
        # not recursive (a download's subfolders often hold masks beside the DEM), but
        # say where the rasters are and how to name them
        deeper = sorted(p for p in folder.rglob("*")
                        if p.name.lower().endswith(FOLDER_SUFFIXES) and p.is_file())
        hint = (f"; its subfolders hold {len(deeper)}: give a glob such as "
                f"'{folder / '**' / ('*' + _suffix(deeper[0]))}'" if deeper else
                "; give the files, a glob or a .vrt")
        raise InputError(f"{folder}: a folder with no raster file (none ends in "
                         f"{', '.join(FOLDER_SUFFIXES)}){hint}")
    return files


def _suffix(p: Path) -> str:
    name = p.name.lower()
    return next(s for s in sorted(FOLDER_SUFFIXES, key=len, reverse=True) if name.endswith(s))


def _one(p: str | Path | Url) -> Path | Url:
    return p if isinstance(p, Url) else Url(str(p)) if is_url(p) else Path(p)


def source_files(src: str | Path | list | tuple) -> list[Path | Url]:
    """The files of a DEM argument: one path or URL, a list of them, a glob (sorted;
    ``**`` spans subfolders), a folder (:func:`folder_files`) or a ``.txt`` file listing
    them (:mod:`geoterrain.ingest.remote`).

    Examples
    --------
    >>> source_files("dem.tif"), source_files("https://example.com/dem.tif")
    ([PosixPath('dem.tif')], [Url('https://example.com/dem.tif')])
    """
    return sources(src)[0]


def sources(src: str | Path | list | tuple) -> tuple[list[Path | Url], bool]:
    """:func:`source_files` of a DEM argument and whether it names several
    (:func:`is_several`), resolved once.

    Examples
    --------
    >>> sources("dem.tif"), sources(["https://example.com/a.tif"])
    (([PosixPath('dem.tif')], False), ([Url('https://example.com/a.tif')], True))
    """
    if isinstance(src, (list, tuple)):
        if not src:
            raise UsageError("no DEM given: pass a file, a list of files or a glob")
        files = [_one(p) for p in src]
    elif is_folder(src):
        files = folder_files(src)
    elif is_glob(src):
        # `**` spans any depth of subfolders, as a shell's globstar does
        files = [Path(p) for p in sorted(_glob.glob(str(src), recursive=True))
                 if not Path(p).is_dir()]
        if not files:
            raise InputError(f"{src}: no file matches this pattern; check the folder and suffix")
    elif list_file(src):
        files = [_one(p) for p in read_list(src)]
        if not files:
            raise InputError(f"{src}: lists no source; write one URL or path a line")
        if len(files) == 1:
            return files, True
    else:
        return [_one(src)], False
    for p in files:  # a local device or FIFO is never opened (a URL is GDAL's to fetch)
        if not is_url(p) and (why := input_problem(p, utf8=True)) is not None:
            raise InputError(f"{p}: {why}; give raster files")
    return files, True


def is_several(src: str | Path | list | tuple) -> bool:
    """Whether a DEM argument names several sources (a list, a glob, a folder, a list
    file).

    Examples
    --------
    >>> is_several(["a.tif", "b.tif"]), is_several("dem.tif")
    (True, False)
    """
    return (isinstance(src, (list, tuple)) or is_glob(src) or is_folder(src)
            or list_file(src))


def mosaic_name(files: list[Path]) -> str:
    """A short name of a mosaic for messages and the store's ``source`` metadata."""
    if len(files) == 1:
        return files[0].name
    return f"mosaic of {len(files)} files ({files[0].name} … {files[-1].name})"


def _describe(p: Path) -> dict:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(str(p)) as s:
                return {"path": p, "w": s.width, "h": s.height, "count": s.count,
                        "dtypes": s.dtypes, "crs": s.crs, "t": s.transform,
                        "nodata": s.nodatavals, "georef": s.crs is not None
                        or not s.transform.is_identity}
    except rasterio.errors.RasterioIOError as exc:
        raise InputError(f"{p}: not a raster GDAL can read ({gdal_reason(exc)})") from None


def build_vrt(files: list[Path]) -> str:
    """A GDAL VRT (XML text) pasting ``files`` onto one grid, after checking they fit.

    One-line :class:`InputError` for mixed CRSs, pixel sizes, band counts, rotated
    or ungeoreferenced sources, and sources off the common pixel grid.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> a = write_geotiff(os.path.join(d, "a.tif"), generate("fbm", 9))
    >>> build_vrt([Path(a)]).startswith("<VRTDataset")
    True
    """
    info = [_describe(p) for p in files]
    first = info[0]
    for s in info:
        if not s["georef"]:
            raise InputError(f"{s['path']}: has no georeference; a mosaic places its tiles by "
                             "their geotransforms (give one file, or georeference the tiles)")
        t = s["t"]
        if t.b != 0 or t.d != 0:
            raise InputError(f"{s['path']}: is rotated; a mosaic needs north-up tiles "
                             "(gdalwarp them first)")
        if s["crs"] != first["crs"]:
            raise InputError(f"mixed CRSs: {first['path'].name} is {first['crs']}, "
                             f"{s['path'].name} is {s['crs']}; reproject the tiles to one CRS")
        f = first["t"]
        if not (np.isclose(t.a, f.a, rtol=1e-9, atol=0) and np.isclose(t.e, f.e, rtol=1e-9,
                                                                        atol=0)):
            raise InputError(f"mixed resolutions: {first['path'].name} has pixels "
                             f"{f.a:g}×{abs(f.e):g}, {s['path'].name} {t.a:g}×{abs(t.e):g}; "
                             "resample the tiles to one pixel size")
        if s["count"] != first["count"]:
            raise InputError(f"mixed band counts: {first['path'].name} has {first['count']}, "
                             f"{s['path'].name} {s['count']}; give tiles with the same bands")
    a, e = first["t"].a, first["t"].e
    if e > 0:
        raise InputError(f"{first['path']}: is south-up; a mosaic needs north-up tiles")
    x0 = min(s["t"].c for s in info)
    y0 = max(s["t"].f for s in info)
    offs = []
    for s in info:
        cx, cy = (s["t"].c - x0) / a, (s["t"].f - y0) / e
        ox, oy = round(cx), round(cy)
        if abs(cx - ox) > 1e-6 or abs(cy - oy) > 1e-6:
            raise InputError(f"{s['path'].name}: is off the pixel grid of {first['path'].name} "
                             f"(offset {cx:.3f}, {cy:.3f} pixels); resample onto one grid")
        offs.append((ox, oy))
    width = max(ox + s["w"] for (ox, _), s in zip(offs, info, strict=True))
    height = max(oy + s["h"] for (_, oy), s in zip(offs, info, strict=True))
    dtype = np.result_type(*(d for s in info for d in s["dtypes"])).name
    if dtype not in _GDAL_TYPES:
        raise InputError(f"{first['path']}: pixel type {dtype} cannot be mosaicked")
    srs = f"<SRS>{escape(first['crs'].to_wkt())}</SRS>" if first["crs"] else ""
    gt = ", ".join(repr(float(v)) for v in (x0, a, 0.0, y0, 0.0, e))
    bands = []
    for b in range(1, first["count"] + 1):
        nds = [s["nodata"][b - 1] for s in info]
        declared = [v for v in nds if v is not None]
        # the mosaic's nodata: the sources' own; gaps and source voids are filled with it
        band_nd = declared[0] if declared else (float("nan") if dtype.startswith("float")
                                                else None)
        srcs = []
        for (ox, oy), s, nd in zip(offs, info, nds, strict=True):
            nd_xml = f"<NODATA>{_num(nd)}</NODATA>" if nd is not None else ""
            srcs.append(
                "<ComplexSource>"
                f"<SourceFilename relativeToVRT=\"0\">{escape(_gdal_name(s['path']))}"
                f"</SourceFilename><SourceBand>{b}</SourceBand>"
                f"<SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{s['w']}\" ySize=\"{s['h']}\"/>"
                f"<DstRect xOff=\"{ox}\" yOff=\"{oy}\" xSize=\"{s['w']}\" ySize=\"{s['h']}\"/>"
                f"{nd_xml}</ComplexSource>")
        nd_band = f"<NoDataValue>{_num(band_nd)}</NoDataValue>" if band_nd is not None else ""
        bands.append(f"<VRTRasterBand dataType=\"{_GDAL_TYPES[dtype]}\" band=\"{b}\">"
                     f"{nd_band}{''.join(srcs)}</VRTRasterBand>")
    return (f"<VRTDataset rasterXSize=\"{width}\" rasterYSize=\"{height}\">{srs}"
            f"<GeoTransform>{gt}</GeoTransform>{''.join(bands)}</VRTDataset>")


def failing_tile(files: list) -> str | None:
    """"NAME: GDAL's reason" of the first of ``files`` whose pixels cannot be read (read a
    few rows at a time), or None: what names the culprit when a mosaic's read fails (GDAL's
    own message may name no file).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> a = write_geotiff(os.path.join(tempfile.mkdtemp(), "a.tif"), generate("fbm", 9))
    >>> failing_tile([a]) is None
    True
    """
    from rasterio.windows import Window

    for f in files:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
                with rasterio.open(str(f)) as s:
                    for i in range(0, s.height, 512):
                        s.read(window=Window(0, i, s.width, min(512, s.height - i)))
        except rasterio.errors.RasterioError as exc:
            return f"{Path(str(f)).name}: {gdal_reason(exc)}"
    return None


def _gdal_name(p: Path | Url) -> str:
    # what a VRT names: a URL through GDAL's HTTP reader, a file by its absolute path
    return p.gdal if isinstance(p, Url) else str(p.resolve())


def _num(v: float) -> str:
    return "nan" if np.isnan(v) else repr(float(v))


def open_mosaic(files: list[Path]):
    """``files`` opened as one rasterio dataset (a VRT in memory), to use as a context.

    The caller must also close the returned MemoryFile (:func:`contextlib.ExitStack`).
    """
    mem = rasterio.MemoryFile(build_vrt(files).encode(), ext="vrt")
    return mem, mem.open()
