"""A preprocess's request, resolved once: the source's files, the store to write, and
where the raster sits in the scene.

Both preprocesses (:mod:`geoterrain.preprocessing.pipeline`, whole;
:mod:`geoterrain.preprocessing.streaming`, a window at a time) take the
:class:`Request` that :func:`request` checks, and place the raster they read with
:func:`place`, so the two resolve a source the same way and only once.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoterrain.core.atomicfiles import remove_stale_partials
from geoterrain.core.frame import PIXEL_SIZE_RANGE, Frame
from geoterrain.core.grid import Grid
from geoterrain.core.paths import STORE_SUFFIX, check_output, default_store_path
from geoterrain.exceptions import UsageError
from geoterrain.ingest.mosaic import is_folder, mosaic_name, sources
from geoterrain.ingest.remote import Url
from geoterrain.ingest.units import parse_tile, resolve_z_units, tile_from_path, tile_georeference
from geoterrain.preprocessing.schedulers import parse_scheduler

__all__ = ["MAX_TILE_SIZE", "Placement", "Request", "place", "request", "root_layout"]

log = logging.getLogger("geoterrain")
MAX_TILE_SIZE = 4096


@dataclass(frozen=True)
class Request:
    """A preprocess's checked request: the source as given (``src``), its ``files``
    (several for a mosaic; a URL as :class:`~geoterrain.ingest.remote.Url`), the store
    to write, the tile size, the source's short ``name`` (messages and the store's
    ``source`` metadata), and ``root_grid``: the layout asked for (True, the default: a
    rectangular root grid; False: one padded square; :func:`root_layout` decides)."""

    files: list[Path | Url]
    mosaic: bool
    dst: Path
    overwrite: bool
    src: str | Path | list
    tile_size: int
    name: str
    root_grid: bool = True  # a rectangular root grid (core/grid.py); False: the square


def root_layout(root_grid: bool) -> bool:
    """Whether a new store's grid is a root grid (``Grid.for_shape(..., roots=True)``:
    level 0 padded to the next tile multiple under 1 × 1, 2 × 1 or 1 × 2 roots, which is
    the square itself whenever the two tile alike), or one padded (2^n + 1)² square: the
    one place both preprocesses decide it, on every frame. ``root_grid``: what was asked
    (the default, True; False: ``--square-grid``).

    Examples
    --------
    >>> root_layout(True), root_layout(False)
    (True, False)
    """
    return bool(root_grid)


def request(src: str | Path | list, dst: str | Path | None, *, tile_size: int,
            codec_error: float | None, pixel_size: float | None, overwrite: bool,
            scheduler: str, resume: bool, root_grid: bool = True) -> Request:
    """A preprocess's arguments checked before any work (a one-line
    :class:`UsageError` each), and a killed run's leftovers beside ``dst`` removed
    unless it is resumed.

    Examples
    --------
    >>> r = request(__file__, "x.geoterrain", tile_size=64, codec_error=None,
    ...             pixel_size=None, overwrite=True, scheduler="sync", resume=True)
    >>> r.dst.name, r.mosaic, r.name
    ('x.geoterrain', False, 'request.py')
    """
    if codec_error is not None and not (np.isfinite(codec_error) and codec_error >= 0):
        raise UsageError(f"codec_error must be a finite number ≥ 0, got {codec_error}",
                         cli=f"--codec-error must be a finite number ≥ 0, got {codec_error}")
    plo, phi = PIXEL_SIZE_RANGE
    if pixel_size is not None and not (np.isfinite(pixel_size) and plo <= pixel_size <= phi):
        raise UsageError(f"pixel_size must be a number in [{plo:g}, {phi:g}] metres, got "
                         f"{pixel_size}", cli=f"--pixel-size must be a number in [{plo:g}, "
                         f"{phi:g}] metres, got {pixel_size}")
    if not (isinstance(tile_size, int) and 2 <= tile_size <= MAX_TILE_SIZE
            and tile_size & (tile_size - 1) == 0):
        raise UsageError(f"tile_size must be a power of two in [2, {MAX_TILE_SIZE}], "
                         f"got {tile_size}", cli=f"--tile-size must be a power of two in "
                         f"[2, {MAX_TILE_SIZE}], got {tile_size}")
    parse_scheduler(scheduler)  # a bad spec is a usage error before any work
    files, mosaic = sources(src)
    name = mosaic_name(files)
    folder = is_folder(src) and Path(src).resolve() != Path.cwd().resolve()
    if dst is None and mosaic and not folder:
        raise UsageError("a mosaic (list of files, glob or this folder) has no default "
                         "store name; pass dst", cli="a mosaic (several files, a glob or "
                         "this folder) has no default store name; pass -o STORE")
    if dst is None and folder:  # srtm/ -> srtm.geoterrain, beside the folder
        d = Path(src).resolve()
        dst = d.with_name(d.name + STORE_SUFFIX)
    elif dst is None:  # a URL's store goes to this folder, named after the URL's file
        dst = default_store_path(files[0].name if isinstance(files[0], Url) else src)
    dst = Path(dst)
    if not resume:  # a killed streaming run's scratch stays for resume to take up
        remove_stale_partials(dst.parent if str(dst.parent) else Path("."))
    # a regular file or nothing, replaced only with overwrite, never one of the inputs
    check_output(dst, overwrite, inputs=files)
    return Request(files, mosaic, dst, overwrite, src, tile_size, name, bool(root_grid))


class Placement(NamedTuple):
    """Where a raster sits: its georeference (a web-map tile's placed), scene frame and
    padded grid."""

    transform: tuple | None
    crs_wkt: str | None
    frame: Frame
    grid: Grid


def place(req: Request, shape: tuple[int, int], transform: tuple | None,
          crs_wkt: str | None, *, tile: str | None, pixel_size: float | None, z_units: str,
          z_scale: float | None, label: str) -> Placement:
    """Where the raster read for ``req`` (``shape`` rows, cols; its ``transform`` and
    ``crs_wkt``, None when it has none) sits: a web-map tile placed in Web Mercator by
    its z/x/y (``tile``, else one its path ends in), the scene frame (pyproj) with its
    height unit, and the padded grid of ``req.tile_size`` tiles (its layout:
    :func:`root_layout`).

    Examples
    --------
    >>> r = request("dem/9/450/201.png", "x.geoterrain", tile_size=64, codec_error=None,
    ...             pixel_size=None, overwrite=True, scheduler="sync", resume=True)
    >>> p = place(r, (256, 256), None, None, tile=None, pixel_size=None, z_units="auto",
    ...           z_scale=None, label="201.png")
    >>> p.frame.kind, "3857" in p.crs_wkt, p.grid.size, p.grid.square
    ('projected', True, 257, True)
    """
    H, W = shape
    zxy = parse_tile(tile) if tile is not None else None
    if zxy is not None and (pixel_size is not None or crs_wkt is not None):
        raise UsageError("a web-map tile is placed by its z/x/y; give tile or pixel_size, not "
                         "both", cli="give --tile or --pixel-size, not both")
    if zxy is None and crs_wkt is None and pixel_size is None and not req.mosaic:
        zxy = tile_from_path(req.src)
    if zxy is not None:
        transform, crs_wkt = tile_georeference(*zxy, W, H)
        log.info("%s: web-map tile %d/%d/%d in EPSG:3857", req.src, *zxy)
    z_units = resolve_z_units(z_units, crs_wkt, label)
    frame = Frame.from_raster(transform, crs_wkt, H, W, pixel_size=pixel_size, z_units=z_units,
                              z_scale=1.0 if z_scale is None else z_scale)
    if crs_wkt is None and pixel_size is None:
        log.warning("%s has no CRS: using 1 m per pixel; set pixel_size (--pixel-size)",
                    req.src)
    grid = Grid.for_shape(H, W, tile_size=req.tile_size, roots=root_layout(req.root_grid))
    if grid.extent != grid.shape:  # a geographic frame's padding past the lattice: proxies
        frame = frame.with_lattice(grid.shape)
    return Placement(transform, crs_wkt, frame, grid)
