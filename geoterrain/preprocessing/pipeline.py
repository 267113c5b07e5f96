"""The preprocess pipeline: DEM → padded pyramid → errors, normals, codec → store.

Stages (timed; ``preprocess(timings=...)`` receives the times, never the store, so the
same input and options give the same bytes):
read → pad → quantise → errors → radii → tile bounds → normals → compress → write.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import delta_max_finite, saturate, vertex_errors_fields
from geoterrain.bounds.edgepad import (
    edge_deltas,
    edge_only_tiles,
    edge_support,
    edge_tiles,
    has_padding,
)
from geoterrain.bounds.leafbounds import CentreHeights, geographic_leaf_delta, ring_guesses
from geoterrain.bounds.normals import level_normal_codes, ring_normal_codes
from geoterrain.bounds.radii import numpy_range, stand_in_z, valid_range, vertex_radii
from geoterrain.bounds.tileblobs import (
    BoundsCoding,
    EdgeGuess,
    OwnHeights,
    level_blobs,
    radius_codes,
    ring_blobs,
)
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.bounds.vertexdata import (
    NORMAL_BITS,
    log8_exponent,
    pack_block_errors,
    shaped_zstd_level,
    store_metadata,
)
from geoterrain.codec.pyramid import decoded_heights, encode_decoded, encode_pyramid
from geoterrain.codec.quantchoice import choose_quantizer
from geoterrain.codec.quantize import Quantizer, codes_to_heights
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid, footprint_counts
from geoterrain.core.memory import available_memory, small_pages
from geoterrain.core.paths import STORE_SUFFIX, input_problem
from geoterrain.core.progress import Progress, StageClock
from geoterrain.core.threads import PARALLEL_MIN_SAMPLES, cores_for
from geoterrain.exceptions import InputError
from geoterrain.ingest.raster import ABSURD_HEIGHT, Raster, read_raster
from geoterrain.ingest.remote import is_url
from geoterrain.preprocessing.request import Request, place, request
from geoterrain.preprocessing.streaming import stream, streaming_band
from geoterrain.store.database import StoreThread, StoreWriter, page_size_for

log = logging.getLogger("geoterrain")
STAGES = ("read", "pad", "quantise", "errors", "radii", "tile bounds", "normals", "compress",
          "write")


def validate(r: Raster, z_scale: float | None) -> None:
    """Reject inputs that cannot give a correct store, with a one-line fix."""
    h, w = r.shape
    if h < 2 or w < 2:
        raise InputError(f"{r.path}: grid is {h}×{w}; a DEM needs at least 2×2 samples")
    nvalid = int(r.valid.sum())
    if nvalid == 0:
        raise InputError(f"{r.path}: every sample is nodata; check the nodata value or the band")
    lo, hi, _ = valid_range(r.heights, r.valid)  # valid samples are finite (raster.py)
    peak = max(abs(lo), abs(hi))
    if peak > ABSURD_HEIGHT and z_scale is None:
        why = f"{r.path}: heights reach {peak:.3g}, beyond ±{ABSURD_HEIGHT:.0e}; if they are real "
        raise InputError(why + "pass z_scale (e.g. 1), else set the right nodata or unit",
                         cli=why + "pass --z-scale (e.g. 1), else set the right nodata or unit")


def preprocess(
    src: str | Path | list,
    dst: str | Path | None = None,
    *,
    tile_size: int = 64,
    band: int | None = None,
    encoding: str = "auto",
    pixel_size: float | None = None,
    z_scale: float | None = None,
    z_units: str = "auto",
    tile: str | None = None,
    codec_error: float | None = None,
    overwrite: bool = False,
    nodata: float | None = None,
    progress: Progress | None = None,
    derive_normals: bool = True,
    derive_bounds: bool = True,
    memory_limit: int | None = None,
    scheduler: str = "sync",
    resume: bool = False,
    crs: str | None = None,
    resolution: float | None = None,
    resampling: str = "bilinear",
    priority: str = "finest",
    timings: dict | None = None,
    root_grid: bool = True,
) -> Path:
    """Preprocess a DEM into a store and return the store's path.

    Parameters
    ----------
    src
        A DEM GDAL reads (a ``.vrt`` too), or a Terrain-RGB/Terrarium PNG tile; or a
        mosaic: a list of files or a glob such as ``"srtm/*.hgt"`` (one CRS, one pixel
        size, one band count; see :mod:`geoterrain.ingest.mosaic`).
    dst
        The store to write; default: ``src`` with the suffix ``.geoterrain`` (a list
        or glob must name it).
    tile_size
        Tile edge in samples, a power of two (tiles hold ``tile_size + 1``²).
    band, encoding
        See :func:`geoterrain.ingest.raster.read_raster`.
    pixel_size
        Metres per sample for rasters without a CRS (default 1, with a warning).
    z_scale, z_units
        Vertical exaggeration, and the unit of the heights (``m``, ``ft``, ``us-ft``, or
        ``auto``: the CRS's vertical unit, else its horizontal one, else metres; a warning
        names the fix when the CRS and a given unit disagree).
    tile
        ``"z/x/y"`` of a web-map PNG tile: placed in Web Mercator at its true pixel size.
        A tile whose path ends in z/x/y.png is recognised by itself.
    codec_error
        The height codec's bound ε, in height units: every stored height is within ε
        of the source; default lossless. (Not the static mesh's ``max_error``.)
    overwrite
        Replace an existing store. Without it the store is published only if
        ``dst`` is still absent (of two racing runs, one gets "exists").
    nodata
        The value of voids, overriding the file's (NaN: none but NaN); see
        :func:`geoterrain.ingest.raster.read_raster` for undeclared voids.
    derive_normals
        Store only the border ring of each tile's normal map, at every level: a reader
        derives the rest from the tile's decoded heights, to the same codes (a level's
        map is the central differences of that level's samples, which read nothing
        outside the tile there; :func:`geoterrain.bounds.normals.level_normal_maps`). On
        geographic frames the reader takes the tile's scene x, y bilinear between pyproj
        nodes (:func:`geoterrain.bounds.leafbounds.normal_xy`; the tile's own where the frame
        bends too much for that), so those codes are the full map's or a neighbour code.
        False stores every normal, as stores before this option did.
    derive_bounds
        Store δ and r of each level-0 tile's new vertices only on its border ring: a
        reader derives the rest from the tile's decoded heights, to the same values
        (they are the bintree's finest vertices, whose diamonds lie in the tile;
        :mod:`geoterrain.bounds.leafbounds`). On geographic frames δ only, with a per-tile
        slack for its curvilinear term (:func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`:
        the derived δ is the stored grid's or a little above it); r there is stored
        whole. False stores them all.
    memory_limit
        Bytes the job may hold (default: half the memory available now). A DEM whose
        whole-grid preprocess would need more is read a window at a time
        (:func:`geoterrain.preprocessing.streaming.preprocess_streaming`, the same store), with
        bands sized to the limit: any input (a raster in any frame, a mosaic, a PNG tile).
    scheduler
        Where the streaming preprocess's four independent passes run
        (:mod:`geoterrain.preprocessing.schedulers`: ``sync``, ``threads:N``, ``processes:N``,
        ``dask:ADDRESS``, ``dask:local:N``); the store is the same on each. The
        whole-grid preprocess runs here. ``processes`` and ``dask:local`` start fresh
        Python processes, so a script that calls this with them needs Python's
        ``if __name__ == "__main__":`` guard.
    resume
        A streamed preprocess killed before it finished left its scratch folder beside
        ``dst``; with ``resume`` the same job reuses the passes it had finished and
        writes the store an uninterrupted run writes. Without it, that folder is removed.
    crs, resolution, resampling, priority
        Sources of different resolutions or CRSs (a 1 m LiDAR DEM inside a 30 m one), or
        any source with a declared target grid, are merged onto one grid
        (:mod:`geoterrain.ingest.composite`): ``crs`` (default: the finest source's),
        ``resolution`` in its units (default: the finest source's), each source warped
        there by GDAL with ``resampling`` (``bilinear``, ``cubic``, ``nearest``) and its
        own nodata; where they overlap the finest valid source wins, or the first given
        with ``priority="order"``, and voids are filled from the next.
    timings
        A dict that receives each stage's seconds (``read``, ..., ``write``). They are
        not stored: the same input and options write the same bytes.
    root_grid
        True (the default): a wide or tall raster is padded to the next multiple of the
        tile span a side, under a grid of root tiles (1 × 1, 2 × 1 or 1 × 2; a store of
        schema version 18, :data:`geoterrain.store.database.ROOTS_SCHEMA_VERSION`), not to
        one (2^n + 1)² square; a raster whose root grid tiles as the square does gets the
        square store (version 17), byte for byte. False: always
        the square, as stores made before root grids were (for a reader that takes only
        those). Whole or streamed (over ``memory_limit``: the same store), on every
        frame (:func:`geoterrain.preprocessing.request.root_layout`).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 33, seed=1))
    >>> preprocess(dem).name
    'dem.geoterrain'
    """
    req = request(src, dst, tile_size=tile_size, codec_error=codec_error,
                  pixel_size=pixel_size, overwrite=overwrite, scheduler=scheduler,
                  resume=resume, root_grid=root_grid)
    merge = dict(crs=crs, resolution=resolution, resampling=resampling, priority=priority)
    limit = available_memory() // 2 if memory_limit is None else int(memory_limit)
    probe = _probe(req, merge)
    if probe is not None:
        shape, crs_geographic = probe
        geographic = crs_geographic and tile is None and pixel_size is None
        rows = streaming_band(shape, limit, geographic, roots=req.root_grid)
        if rows is not None:  # too large for the whole grid: a window at a time
            return stream(req, z_scale=z_scale, z_units=z_units, codec_error=codec_error,
                          nodata=nodata, band=rows, raster_band=band, encoding=encoding,
                          pixel_size=pixel_size, tile=tile, derive_normals=derive_normals,
                          derive_bounds=derive_bounds, scheduler=scheduler, resume=resume,
                          progress=progress, timings=timings, **merge)
    if scheduler != "sync":  # not silently: the whole-grid preprocess runs here
        log.warning("%s fits the memory limit: preprocessed here, whole; the scheduler %s "
                    "runs a streamed preprocess only (lower --memory-limit to stream it)",
                    req.files[0] if not req.mosaic else "the mosaic", scheduler)
    with small_pages():  # whole-grid arrays on 4 KiB pages (core/memory.py)
        stage = StageClock(STAGES, progress, timings)
        # a large grid: numba's first call beside GDAL's decode (a small one runs only
        # the serial twins: nothing more to compile on a first run)
        warm = warm_kernels() if probe is not None \
            and probe[0][0] * probe[0][1] >= PARALLEL_MIN_SAMPLES else None
        dem = read_dem(req, band=band, encoding=encoding, nodata=nodata, tile=tile,
                       pixel_size=pixel_size, z_units=z_units, z_scale=z_scale, merge=merge)
        if warm is not None:
            warm.join()
        stage("read")
        surface = pad(dem)
        stage("pad")
        surface = quantise(dem, surface, codec_error)
        # valid samples per tile footprint: the tile table's and the height codec's
        counts = footprint_counts(surface.valid, dem.grid.t, dem.grid.top_level)
        # a large grid's height codec on a thread of its own from here, beside the bounds
        heights = (HeightsJob(dem, surface, counts) if surface.height_blobs is None
                   and surface.valid.size >= HEIGHTS_THREAD_SAMPLES else None)
        try:
            return _bounds_and_blobs(req, dem, surface, counts, heights, stage,
                                     derive_normals, derive_bounds)
        finally:
            if heights is not None:
                heights.join()  # an error: the thread stops using the arrays first



def _bounds_and_blobs(req: Request, dem: Dem, surface: Surface, counts: list[np.ndarray],
                      heights: HeightsJob | None, stage: StageClock, derive_normals: bool,
                      derive_bounds: bool) -> Path:
    # preprocess' stages from δ on (inside its small_pages), the heights coded by
    # ``heights`` if started
    stage("quantise")
    derive_normals = bool(derive_normals) and dem.grid.tile_samples >= 3
    derive_bounds = (bool(derive_bounds) and dem.grid.tile_samples >= 3
                     and dem.grid.top_level > 0)
    # a large grid's normals and tile bounds on threads of their own once δ is done
    # (their kernels release the GIL), beside the radii
    jobs = surface.valid.size >= HEIGHTS_THREAD_SAMPLES
    normals = Job(_normal_maps, dem, surface, derive_normals) if jobs else None
    tile_job = Job(_tile_bounds, dem, surface, counts) if jobs else None

    def clock(name: str) -> None:
        stage(name)
        if name == "errors" and normals is not None:
            normals.start()

    try:
        return _blobs_and_rows(req, dem, surface, counts, heights, stage, clock,
                               derive_normals, derive_bounds, normals, tile_job)
    finally:
        for job in (normals, tile_job):
            if job is not None:
                job.join()  # an error: the thread stops using the arrays first


def _tile_bounds(dem: Dem, surface: Surface, counts: list[np.ndarray], fields: dict | None
                 ) -> tuple[dict, np.ndarray]:
    # the tile table's bounds and the GeoMipMapping blocks' δ_n (tilebounds)
    tiles, blocks = tile_and_block_errors(surface.Z, surface.valid, surface.X, surface.Y,
                                          dem.grid.t, span=dem.grid.span, counts=counts,
                                          fields=fields)
    across, down = dem.grid.tiles(0)
    return tiles, blocks[:down, :across]  # a root grid's extent holds more than its tiles


def _normal_maps(dem: Dem, surface: Surface, derive_normals: bool) -> list:
    # one map per level, central differences of the level's own samples (seed 000
    # normal-map lighting): a reader rebuilds each tile's from its heights and ring
    with cores_for(surface.Z.size):  # a small grid: the serial twins (core/threads.py)
        if derive_normals:  # only the rings are stored: only they are mapped
            return ring_normal_codes(surface.X, surface.Y, surface.Z, surface.valid,
                                     dem.grid.top_level + 1, dem.grid.t, NORMAL_BITS)
        return level_normal_codes(surface.X, surface.Y, surface.Z, surface.valid,
                                  dem.grid.top_level + 1, NORMAL_BITS)


class Job:
    """``fn(*args)`` on a thread of its own from :meth:`start` on; :meth:`result` waits
    and raises its error (:meth:`start` not called: runs it there, on the caller's).

    Examples
    --------
    >>> job = Job(sum, [1, 2, 3])
    >>> job.start()
    >>> job.result()
    6
    """

    def __init__(self, fn: Callable, *args) -> None:
        self._fn, self._args = fn, args
        self._out = self._error = self._thread = None

    def _run(self) -> None:
        try:
            self._out = self._fn(*self._args)
        except BaseException as exc:  # noqa: BLE001 - raised by result(), on the caller's
            self._error = exc

    def start(self, *more) -> None:
        """Start the thread (once), ``more`` after the arguments given."""
        if self._thread is None:
            self._args += more
            self._thread = threading.Thread(target=self._run, name="geoterrain-job",
                                            daemon=True)
            self._thread.start()

    def join(self) -> None:
        """Wait for the thread, if started."""
        if self._thread is not None:
            self._thread.join()

    def result(self):
        """What ``fn`` returned (waits; raises its error)."""
        if self._thread is None:
            self._run()
        else:
            self._thread.join()
        if self._error is not None:
            raise self._error
        return self._out


def _blobs_and_rows(req: Request, dem: Dem, surface: Surface, counts: list[np.ndarray],
                    heights: HeightsJob | None, stage: StageClock, clock: Callable,
                    derive_normals: bool, derive_bounds: bool, normals: Job | None,
                    tile_job: Job | None) -> Path:
    # preprocess' stages from δ on, ``clock`` the stage clock that starts ``normals``,
    # ``tile_job`` (its last argument, δ's fields, given) started with δ's fields
    bounds = vertex_bounds(dem, surface, derive_bounds, clock,
                           on_fields=None if tile_job is None else tile_job.start)
    tiles, blocks = (tile_job.result() if tile_job is not None else
                     _tile_bounds(dem, surface, counts, bounds.fields))
    bounds.fields = None
    stage("tile bounds")
    normal_maps = (normals.result() if normals is not None else
                   _normal_maps(dem, surface, derive_normals))
    stage("normals")
    # the store's rows are inserted on a thread of their own, the height blobs' while
    # the δ, r and normals blobs are coded (the same calls, in the same order, as
    # on one thread: the same bytes); any error drops the partial file
    with StoreThread(req.dst, overwrite=req.overwrite,
                     page_size=page_size_for(dem.grid.rows, dem.grid.cols)) as store:
        blobs = tile_blobs(dem, surface, bounds, tiles, normal_maps, derive_normals, counts,
                           on_heights=lambda hb: store.put_blobs("heights", hb),
                           on_rows=store.put_blobs, heights=heights)
        del normal_maps
        stage("compress")
        meta = dict(source=req.name, source_dtype=dem.raster.src_dtype,
                    source_nodata=dem.raster.nodata, encoding=dem.raster.encoding,
                    grid=dem.grid.to_json(), frame=dem.frame.to_json(),
                    quantizer=surface.q.to_json(),
                    normals_derived=(list(range(dem.grid.top_level + 1)) if derive_normals
                                     else []), ring_residual=derive_normals,
                    valid_samples=dem.valid_samples, samples=dem.raster.valid.size,
                    height_range=surface.height_range,
                    delta_max_finite=delta_max_finite(bounds.delta),
                    edge_max=blobs.edge_max if has_padding(dem.grid) else None,
                    stand_in_z=stand_in_z(surface.Z, surface.valid),
                    block_delta_levels=int(blocks.shape[2]))
        write_rows(store, dem.grid, blobs, blocks, meta, heights=False, rows=False)
    stage("write")
    return req.dst


def warm_kernels() -> threading.Thread:
    """A thread making the process's first call of a parallel kernel (numba's typing
    registries and the kernel's load from its cache, about 0.2 s of CPU on one core in
    a fresh process), started before a large grid's read: GDAL decodes without the GIL
    meanwhile.
    Nothing in a fork() child (no parallel region there, core/threads.py). Results never
    depend on it.

    Examples
    --------
    >>> warm_kernels().join()
    """

    def first_call() -> None:
        from geoterrain.bounds.radii import _valid_range_nb
        from geoterrain.core.threads import forked

        if not forked():
            _valid_range_nb.parallel(np.zeros((2, 2)), np.ones((2, 2), bool))

    th = threading.Thread(target=first_call, name="geoterrain-warm", daemon=True)
    th.start()
    return th


def _probe(req: Request, merge: dict) -> tuple[tuple[int, int], bool] | None:
    """(rows, cols) of the source and whether its CRS is geographic, from its metadata
    (None when it cannot be read: the whole-grid reader then says why)."""
    import warnings

    import rasterio

    from geoterrain.ingest.composite import needs_composite, plan
    from geoterrain.ingest.mosaic import build_vrt

    if any(not is_url(f) and input_problem(f, utf8=True) is not None for f in req.files):
        return None  # the reader says why, in one line (a FIFO would block this open)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            if needs_composite(req.files, merge["crs"], merge["resolution"]):
                _, t = plan(req.files, **merge)
                geo = rasterio.crs.CRS.from_wkt(t.crs_wkt).is_geographic
                return (t.height, t.width), bool(geo)
            if req.mosaic:
                with rasterio.MemoryFile(build_vrt(req.files).encode(), ext="vrt") as mem, \
                        mem.open() as ds:
                    return (ds.height, ds.width), bool(ds.crs and ds.crs.is_geographic)
            with rasterio.open(str(req.files[0])) as ds:
                return (ds.height, ds.width), bool(ds.crs and ds.crs.is_geographic)
    except (rasterio.errors.RasterioIOError, InputError):
        return None


# ------------------------------------------------------------------ the stages
@dataclass
class Dem:
    """The DEM read: its raster (heights, mask, georeference), scene frame and padded
    grid."""

    raster: Raster
    frame: Frame
    grid: Grid
    valid_samples: int


def read_dem(req: Request, *, band: int | None, encoding: str, nodata: float | None,
             tile: str | None, pixel_size: float | None, z_units: str,
             z_scale: float | None, merge: dict | None = None) -> Dem:
    """Read and check the DEM (a web-map tile placed in Web Mercator by its z/x/y;
    sources merged onto one grid, ``merge``: :func:`geoterrain.ingest.raster.read_raster`'s
    crs, resolution, resampling and priority), and its frame (pyproj) and padded grid."""
    r = read_raster(req.files if req.mosaic else req.src, band=band, encoding=encoding,
                    nodata=nodata, **(merge or {}))
    validate(r, z_scale)
    r.transform, r.crs_wkt, frame, grid = place(req, r.shape, r.transform, r.crs_wkt,
                                                tile=tile, pixel_size=pixel_size,
                                                z_units=z_units, z_scale=z_scale, label=r.path)
    frame.check_scene(grid.whole_shape, *valid_range(r.heights, r.valid)[:2])
    return Dem(r, frame, grid, int(np.count_nonzero(r.valid)))


@dataclass
class Surface:
    """The padded grid's samples: source ``heights`` (NaN = nodata) and ``valid``, scene
    ``X``, ``Y`` and, once quantised, the decoded scene heights ``Z`` with the quantizer
    ``q``, their range (source units) and, with residual bins, the height blobs already
    coded."""

    heights: np.ndarray
    valid: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray | None = None
    q: Quantizer | None = None
    height_range: list[float] | None = None
    height_blobs: dict | None = None
    predictor: str = "auto"  # the codec's U(.) (an edit keeps the store's)


def pad(dem: Dem) -> Surface:
    """The DEM padded to the (2^n+1)² grid, or a root grid's extent (invalid padding),
    with scene x, y."""
    grid, r = dem.grid, dem.raster
    valid = grid.pad(r.valid, False, whole=True)
    h = r.heights
    if (h.shape == valid.shape and h.dtype == np.float64 and h.flags.c_contiguous
            and h.flags.writeable):  # no padding: the read's own array (no 134 MB copy)
        heights = h
    else:
        heights = grid.pad(h, np.nan, whole=True)
    if dem.valid_samples < valid.size:
        heights[~valid] = np.nan
    r.heights = None  # the padded array holds them now (memory: issue 12)
    X, Y = dem.frame.grid_xy(dem.grid.whole_shape)
    return Surface(heights, valid, X, Y)


def quantise(dem: Dem, s: Surface, codec_error: float | None) -> Surface:
    """The quantizer of the valid heights (NaN elsewhere, which it ignores) and the
    heights as a reader decodes them, in scene metres (``Z``)."""
    r = dem.raster
    q = choose_quantizer(s.heights, r.src_dtype, codec_error=codec_error, scale=r.scale,
                         offset=r.offset)
    height_blobs = None
    if q.bins > 1:  # residual bins: the heights depend on the pyramid, coded here once
        height_blobs, codes = encode_decoded(s.heights, s.valid, dem.grid.t, q,
                                             roots=dem.grid.codec_roots)
        height_blobs = dem.grid.held(height_blobs)
        Z = codes_to_heights(codes, q)
        del codes
        Z[~s.valid] = np.nan
    else:
        Z = decoded_heights(s.heights, s.valid, q)  # NaN where invalid
    lo, hi = numpy_range(Z, s.valid)  # as numpy's min and max give them, as stored
    height_range = [float(lo), float(hi)]
    Z = dem.frame.z(Z, out=Z)  # scene metres, in place
    return Surface(s.heights, s.valid, s.X, s.Y, Z, q, height_range, height_blobs)


@dataclass
class VertexBounds:
    """Per-vertex δ (saturated) and the radii's codes, how level 0's are stored (its
    ``ring_kinds`` as border rings, a geographic δ with its per-tile ``slack``), and the
    metric terms of a geographic frame."""

    delta: np.ndarray
    r_codes: np.ndarray
    ring_kinds: tuple[str, ...]
    slack: np.ndarray | None
    terms: tuple | None
    delta_before: np.ndarray | None
    derive: bool = False  # the store derives what it can on read (derive_bounds)
    fields: dict | None = None  # the tile bounds' level fields made in δ's sweep


def vertex_bounds(dem: Dem, s: Surface, derive_bounds: bool,
                  stage: StageClock | Callable[[str], None],
                  on_fields: Callable[[dict | None], None] | None = None) -> VertexBounds:
    """δ (LP's exact vertex errors, saturated) and the nested radii (seed 002 §2.4,
    L50–52) as the 8-bit log codes they are stored as; on a geographic frame, both made
    to hold in the scene's metric x, y (:mod:`geoterrain.bounds.curvature`).
    ``on_fields``: called with the tile bounds' level fields as soon as δ is done (then
    not kept in the result)."""
    frame, grid, valid = dem.frame, dem.grid, s.valid
    # δ, and in the same sweep the tile bounds' level fields of an all-valid grid
    delta, fields = vertex_errors_fields(s.Z, valid, span=grid.span, t=grid.t)
    stage("errors")
    if on_fields is not None:
        on_fields(fields)
        fields = None
    terms = radius = None
    if frame.kind == "geographic":  # curvilinear grid: δ and r that hold in scene x/y
        radius = vertex_radii(s.X, s.Y, s.Z, valid, span=grid.span)
        terms = metric_terms(s.X, s.Y, s.Z, valid, span=grid.span)
        delta, radius = metric_bounds(delta, radius, s.X, s.Y, s.Z, valid, terms=terms,
                                      span=grid.span)
    slack = delta_before = None
    ring_kinds: tuple[str, ...] = ("delta", "radius") if derive_bounds else ()
    if derive_bounds and frame.kind == "geographic":
        # level 0's δ as a reader derives it: the closed forms + a per-tile slack for the
        # metric term (δ only: r would need pyproj's x, y of every sample)
        delta_before = delta.copy() if has_padding(grid) else None
        slack = geographic_leaf_delta(delta, s.Z, valid, grid.t, terms[0], terms[2],
                                      grid.span)
        ring_kinds = ("delta",) if slack is not None else ()
    # nested on the coded values (a projected frame needs no radii before: r = nesting)
    r_codes = radius_codes(s.X, s.Y, s.Z, valid, radius, span=grid.span)
    del radius
    stage("radii")
    return VertexBounds(delta, r_codes, ring_kinds, slack, terms, delta_before,
                        derive_bounds, fields)


@dataclass
class TileBlobs:
    """Every stored tile's blobs by kind, its tile-table row, and the tiles with a
    second δ (``edge_max``)."""

    heights: dict
    extra: dict[str, dict]
    tile_rows: dict
    edge_max: list


def tile_blobs(dem: Dem, s: Surface, b: VertexBounds, tiles: dict,
               normal_maps: list, derive_normals: bool,
               counts: list[np.ndarray] | None = None,
               on_heights: Callable[[dict], None] | None = None,
               ring_residual: bool = True,
               on_rows: Callable[[str, dict], None] | None = None,
               heights: HeightsJob | None = None) -> TileBlobs:
    """The height pyramid's blobs (the residual codec), and every tile's δ, r, normals and
    δ_edge blobs with its tile-table row.

    δ: 8-bit log codes rounded up (saturation survives: one monotone map per store); r:
    8-bit log codes rounded up, nested on the codes. Below the top level only the
    vertices new at the level are stored; the others are the parent's
    (:mod:`geoterrain.bounds.vertexdata`). Padding is replicated from the data's edge for
    a second δ, the static mesh's (:mod:`geoterrain.bounds.edgepad`), coded with the same
    table as δ, so the two agree wherever their raw values do. ``counts``: the valid
    samples per tile footprint (:func:`geoterrain.core.grid.footprint_counts`), if known.
    ``on_heights``: called with the height blobs as soon as they are coded (the store's
    writer inserts them while the rest is coded). ``ring_residual`` (with
    ``derive_normals``): the normals' rings as differences from what a reader derives
    there (schema 17; False: as stored before, an edit of an older store). ``on_rows``:
    called with the δ, r, normals and δ_edge rows in the store's order
    (:func:`tile_row_order`), a level's as soon as it is coded and the heights have been
    handed to ``on_heights`` (so the writer inserts them while the next level is coded).
    ``heights``: the height blobs' :class:`HeightsJob`, if started already; with
    ``counts`` of a large grid (:data:`HEIGHTS_THREAD_SAMPLES`) one is started here: the
    height codec runs on a thread of its own beside the bounds' blobs (the same bytes).
    """
    grid, valid = dem.grid, s.valid
    height_blobs = s.height_blobs
    job = heights if height_blobs is None else None
    if job is None and height_blobs is None and counts is not None \
            and valid.size >= HEIGHTS_THREAD_SAMPLES:
        job = HeightsJob(dem, s, counts)
    if job is not None:  # the tiles it codes are known now: the bounds' loop needs no more
        stored = job.keys
    else:
        if height_blobs is None:
            height_blobs = grid.held(encode_pyramid(s.heights, valid, grid.t, s.q,
                                                    predictor=s.predictor,
                                                    roots=grid.codec_roots, counts=counts))
        if on_heights is not None:
            on_heights(height_blobs)
        stored = list(height_blobs)
    stored_set = set(stored)
    pending: list[tuple[str, dict]] = []  # rows coded, not yet handed to on_rows

    def hand_on(wait: bool) -> None:
        # the heights first (once their thread is done), then every pending row
        nonlocal height_blobs
        if height_blobs is None:
            if not (wait or job.done()):
                return
            height_blobs = job.result()
            if on_heights is not None:
                on_heights(height_blobs)
        if on_rows is not None:
            for kind, rows in pending:
                on_rows(kind, rows)
        pending.clear()

    try:
        return _tile_blobs(dem, s, b, tiles, normal_maps, derive_normals, ring_residual,
                           stored, stored_set, pending if on_rows is not None else None,
                           hand_on, lambda: height_blobs)
    finally:
        if job is not None:
            job.join()  # an error above: the thread stops using the arrays first


def _tile_blobs(dem: Dem, s: Surface, b: VertexBounds, tiles: dict, normal_maps: list,
                derive_normals: bool, ring_residual: bool, stored: list, stored_set: set,
                pending: list | None, hand_on: Callable[[bool], None],
                height_blobs: Callable[[], dict]) -> TileBlobs:
    # tile_blobs' bounds' blobs, level by level; each level's rows into ``pending``
    grid, frame, valid, Z = dem.grid, dem.frame, s.valid, s.Z
    delta = b.delta
    edge = d_edge = None
    if has_padding(grid):
        Zr, ok = edge_support(Z, valid, grid)
        d_edge = edge_deltas(Zr, ok, grid)
        if frame.kind == "geographic":  # only where a padding sample is read: the rest
            win = (grid.rows, grid.cols)  # is the original grid's terms
            et = metric_terms(s.X, s.Y, Zr, ok, window=win, base=b.terms, span=grid.span)
            d_edge, _ = metric_bounds(d_edge, None, s.X, s.Y, Zr, ok, window=win, terms=et,
                                      span=grid.span)
            del et
            if b.slack is not None:  # where δ_edge was δ it follows δ's raise, nested again
                same = d_edge == b.delta_before
                d_edge[same] = delta[same]
                saturate(d_edge, grid.span)
        del Zr, ok
    ed = None if d_edge is None else max(log8_exponent(delta), log8_exponent(d_edge))
    coding = BoundsCoding(delta, None, ed, r_codes=b.r_codes)
    if d_edge is not None:
        edge = BoundsCoding(d_edge, None, ed, r_codes=b.r_codes)
        del d_edge
        # one table, so comparing codes compares the stored values
        edge_keys = edge_tiles(coding.dc, edge.dc, grid, sorted(stored))
        # unstored tiles holding a vertex the static mesh may need: a whole δ_edge tile
        edge_only = edge_only_tiles(edge.dc, grid, stored_set)
    tile_rows: dict = {}
    extra: dict[str, dict] = {"delta": {}, "radius": {}, "normals": {}, "delta_edge": {}}
    no_map = np.zeros((0, 0, 2), np.uint8)  # level_blobs without normals reads none
    edge_max: list = []
    # a geographic level-0 r is stored whole: its centres as differences from their
    # guess from the heights (leafbounds.centre_guess, schema 17)
    guess = (b.derive and frame.kind == "geographic" and "radius" not in b.ring_kinds
             and grid.tile_samples >= 3 and grid.top_level > 0)
    stand_in = stand_in_z(Z, valid)
    # schema 20: δ's PRED and RING blobs guessed from the own errors on the heights
    own = OwnHeights(Z, valid, stand_in)
    ctx = _Level(grid, frame, Z, valid, tiles, b, coding, normal_maps, no_map, derive_normals,
                 ring_residual, guess, stand_in, own)
    # a large grid's levels of many tiles: their halves' blobs on two threads (each tile's
    # blobs are its own: the same bytes)
    pool = ThreadPoolExecutor(1, thread_name_prefix="geoterrain-blobs") \
        if valid.size >= HEIGHTS_THREAD_SAMPLES else None
    try:
        for L in grid.levels:
            keys = [k for k in stored if k[0] == L]
            if not keys:
                continue
            lattice = None
            if guess and 0 < L < grid.top_level:  # the level's heights, for every part
                sl = np.s_[::1 << L, ::1 << L]
                lattice = (np.ascontiguousarray(Z[sl]),
                           np.ascontiguousarray(valid[sl]).view(np.uint8))
            if pool is not None and len(keys) >= SPLIT_LEVEL_TILES:
                half = len(keys) // 2
                later = pool.submit(_level_part, ctx, L, keys[half:], lattice)
                one = _level_part(ctx, L, keys[:half], lattice)
                two = later.result()
                blobs = {kind: {**one[0][kind], **two[0][kind]} for kind in one[0]}
                dmax, rmax = (np.concatenate([one[i], two[i]]) for i in (1, 2))
            else:
                blobs, dmax, rmax = _level_part(ctx, L, keys, lattice)
            _level_rows(ctx, L, keys, blobs, dmax, rmax, extra, tile_rows, edge_max,
                        None if edge is None else (edge, edge_keys, edge_only), pending,
                        stored_set, hand_on)
    finally:
        if pool is not None:
            pool.shutdown()
    hand_on(True)
    return TileBlobs(height_blobs(), extra, tile_rows, edge_max)


SPLIT_LEVEL_TILES = 64  # a large grid's level of this many tiles: coded in two halves


@dataclass
class _Level:
    # what every level's blobs are made from (tile_blobs)
    grid: Grid
    frame: Frame
    Z: np.ndarray
    valid: np.ndarray
    tiles: dict
    b: VertexBounds
    coding: BoundsCoding
    normal_maps: list
    no_map: np.ndarray
    derive_normals: bool
    ring_residual: bool
    guess: bool
    stand_in: float
    own: OwnHeights


def _level_part(c: _Level, L: int, keys: list, lattice: tuple | None
                ) -> tuple[dict, np.ndarray, np.ndarray]:
    # the δ, r and normals blobs of the level's tiles ``keys`` and their maxima
    grid, Z, valid = c.grid, c.Z, c.valid
    # every level's rings: the rest is derived from the heights on read
    centres = heights = None
    if c.guess and L < grid.top_level:
        # level 0's r centres, and above it every r vertex (schema 20), as differences
        # from their guesses from the level's heights
        boxes = np.array([[c.tiles[k].xmin, c.tiles[k].xmax, c.tiles[k].ymin,
                           c.tiles[k].ymax] for k in keys], np.float64)
        if L == 0:
            centres = CentreHeights(Z, valid.view(np.uint8), c.stand_in, boxes)
        else:
            heights = CentreHeights(*lattice, c.stand_in, boxes)
    b = c.b
    blobs, dmax, rmax = level_blobs(c.coding, c.no_map if c.derive_normals else c.normal_maps[L],
                                    grid.t, L, grid.top_level,
                                    [(x, y) for _, x, y in keys],
                                    ("delta", "radius") if c.derive_normals else
                                    ("delta", "radius", "normals"),
                                    ring=b.ring_kinds if L == 0 else False,
                                    slack=b.slack if L == 0 else None,
                                    mids=L > 0 and "radius" in b.ring_kinds,
                                    centres=centres, heights=heights, own=c.own,
                                    zlevel=shaped_zstd_level(grid.rows, grid.cols))
    if c.derive_normals:
        guess_n = None
        if c.ring_residual:  # each ring as its difference from the reader's derived map
            sl = np.s_[::1 << L, ::1 << L]
            txy = [(x, y) for _, x, y in keys]
            guess_n = ring_guesses(grid, c.frame, L, txy, Z[sl], valid[sl],
                                   np.array([(y << grid.t, x << grid.t) for x, y in txy],
                                            np.int64).reshape(-1, 2))
        blobs["normals"] = ring_blobs(c.normal_maps[L], grid.t,
                                      [(x, y) for _, x, y in keys], L, guess_n,
                                      shaped_zstd_level(grid.rows, grid.cols))
    return blobs, dmax, rmax


def _level_rows(c: _Level, L: int, keys: list, blobs: dict, dmax: np.ndarray,
                rmax: np.ndarray, extra: dict, tile_rows: dict, edge_max: list,
                edges: tuple | None, pending: list | None, stored_set: set,
                hand_on: Callable[[bool], None]) -> None:
    # a level's blobs into ``extra``, its tile-table rows, its δ_edge blobs; its rows
    # into ``pending``
    grid, tiles, coding, no_map = c.grid, c.tiles, c.coding, c.no_map
    for kind, blob in blobs.items():
        extra[kind].update(blob)
    level_edge: dict = {}
    # per-tile max δ and r (of the values as stored, over the vertices new at this
    # level) let a view skip a tile without decoding it
    for key, dm, rm in zip(keys, dmax.tolist(), rmax.tolist(), strict=True):
        tile_rows[key] = (*tiles[key], dm, rm)
    # the second δ: new vertices over the parent's on stored tiles, whole tiles on
    # the unstored ones (nothing else there to read a parent from)
    # (the stored tiles' as differences from their δ codes: zero but near the padding)
    edge, edge_keys, edge_only = edges or (None, None, None)
    for keys_e, top, base in ([] if edge is None else
                              [(edge_keys, grid.top_level, coding), (edge_only, L, None)]):
        ekeys = [(x, y) for L2, x, y in keys_e if L2 == L]
        if not ekeys:
            continue
        # schema 23: the stored tiles below the top guessed from the heights, the
        # padding replicated (vertexdata.edge_own_codes)
        guessed = base is not None
        eb, emax, _ = level_blobs(edge, no_map, grid.t, L, top, ekeys, ("delta",),
                                  base=base, zlevel=shaped_zstd_level(grid.rows, grid.cols),
                                  own=c.own if guessed else None,
                                  edge=EdgeGuess(grid.rows, grid.cols, L > 0)
                                  if guessed else None)
        extra["delta_edge"].update(eb["delta"])
        level_edge.update(eb["delta"])
        edge_max.extend([L, x, y, m if np.isfinite(m) else None]
                        for (x, y), m in zip(ekeys, emax.tolist(), strict=True))
    if pending is not None:  # the level's rows: tile_row_order's, whose rows go by level
        pending.extend(tile_row_order(dict(blobs, delta_edge=level_edge), stored_set))
        hand_on(False)


HEIGHTS_THREAD_SAMPLES = 1 << 19  # from about 724²: the height codec on a thread of its own


def pyramid_keys(grid: Grid, counts: list[np.ndarray]) -> list[tuple[int, int, int]]:
    """The tiles the height codec stores (:func:`geoterrain.codec.pyramid.encode_pyramid`,
    kept by :meth:`Grid.held`), in its order, from the valid samples per footprint
    (:func:`geoterrain.core.grid.footprint_counts`): the top level's, then each level's
    down to 0, row by row.

    Examples
    --------
    >>> from geoterrain.core.grid import Grid
    >>> g = Grid.for_shape(9, 9, 4)
    >>> pyramid_keys(g, footprint_counts(np.ones((9, 9), bool), 2, g.top_level))
    [(1, 0, 0), (0, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, 1)]
    """
    keys = []
    for L in reversed(grid.levels):
        ys, xs = np.nonzero(counts[L])
        keys += [(L, x, y) for y, x in zip(ys.tolist(), xs.tolist(), strict=True)]
    return list(grid.held(dict.fromkeys(keys)))


class HeightsJob:
    """The height pyramid's blobs (:func:`geoterrain.codec.pyramid.encode_pyramid`, kept
    by :meth:`Grid.held`) coded on a thread of their own while the caller goes on: its
    kernels and zstd release the GIL, so the two cores share it with the bounds' blobs.
    The same bytes as coded in line. :attr:`keys` are the tiles it stores, in its order
    (:func:`pyramid_keys`), known at once; :meth:`result` waits and raises its error.

    Examples
    --------
    >>> from geoterrain.codec.quantize import Quantizer
    >>> from geoterrain.core.grid import Grid
    >>> g = Grid.for_shape(9, 9, 4)
    >>> v = np.ones((9, 9), bool)
    >>> s = Surface(np.arange(81.0).reshape(9, 9), v, v, v, q=Quantizer("int"))
    >>> job = HeightsJob(Dem(None, None, g, 81), s, footprint_counts(v, 2, g.top_level))
    >>> list(job.result()) == job.keys
    True
    """

    def __init__(self, dem: Dem, s: Surface, counts: list[np.ndarray]):
        self.keys = pyramid_keys(dem.grid, counts)
        self._out: dict | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(dem.grid, s, counts),
                                        name="geoterrain-heights", daemon=True)
        self._thread.start()

    def _run(self, grid: Grid, s: Surface, counts: list[np.ndarray]) -> None:
        try:
            self._out = grid.held(encode_pyramid(s.heights, s.valid, grid.t, s.q,
                                                 predictor=s.predictor,
                                                 roots=grid.codec_roots, counts=counts))
        except BaseException as exc:  # noqa: BLE001 - raised by result(), on the caller's
            self._error = exc

    def done(self) -> bool:
        """Whether the blobs are coded (or the codec failed)."""
        return not self._thread.is_alive()

    def join(self) -> None:
        """Wait for the thread."""
        self._thread.join()

    def result(self) -> dict:
        """The blobs, ``{(L, x, y): blob}`` in :attr:`keys`' order (waits; raises the
        codec's error)."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        if list(self._out) != self.keys:  # the bounds' rows followed these keys
            raise RuntimeError("the height codec stored other tiles than its footprint "
                               "counts say")
        return self._out


def tile_row_order(extra: dict[str, dict], stored: set) -> list[tuple[str, dict]]:
    """The δ, r, normals and δ_edge blobs in the order the streamed preprocess makes them
    (:func:`geoterrain.preprocessing.streaming.stream`: a tile row of each level at a
    time, coarse levels last; in a row its δ, r and normals by x, then its δ_edge, the
    ``stored`` tiles' before the others'), so the two write the same file: a store's
    bytes follow the sequence of its blob rows (:mod:`geoterrain.store.pagepack`).

    Examples
    --------
    >>> extra = {"delta": {(0, 1, 0): b"b", (0, 0, 0): b"a", (1, 0, 0): b"c"},
    ...          "delta_edge": {(0, 2, 0): b"e", (0, 0, 0): b"d"}}
    >>> for kind, b in tile_row_order(extra, {(0, 0, 0), (0, 1, 0)}):
    ...     print(kind, list(b))
    delta [(0, 0, 0), (0, 1, 0)]
    delta_edge [(0, 0, 0)]
    delta_edge [(0, 2, 0)]
    delta [(1, 0, 0)]
    """
    kinds = ("delta", "radius", "normals", "delta_edge")
    rows: dict[tuple[int, int], dict[str, list]] = {}  # (L, y) → kind → keys
    for kind in kinds:
        for k in extra.get(kind, ()):
            rows.setdefault((k[0], k[2]), {}).setdefault(kind, []).append(k)
    out = []
    for row in sorted(rows):
        for kind, keys in sorted(rows[row].items(), key=lambda kv: kinds.index(kv[0])):
            keys.sort(key=lambda k: k[1])
            parts = ([keys] if kind != "delta_edge" else
                     [[k for k in keys if k in stored], [k for k in keys if k not in stored]])
            out += [(kind, {k: extra[kind][k] for k in part}) for part in parts if part]
    return out


def write_store(req: Request, grid: Grid, blobs: TileBlobs, blocks: np.ndarray, meta: dict,
                stage: StageClock) -> None:
    """Write the store atomically: every blob, the tile table, the GeoMipMapping blocks'
    δ_n and the metadata, published as ``req.dst`` only when complete."""
    with StoreWriter(req.dst, overwrite=req.overwrite,
                     page_size=page_size_for(grid.rows, grid.cols)) as w:
        write_rows(w, grid, blobs, blocks, meta)
    stage("write")


def write_rows(w: StoreWriter | StoreThread, grid: Grid, blobs: TileBlobs,
               blocks: np.ndarray, meta: dict, heights: bool = True, rows: bool = True
               ) -> None:
    """Every row of the store into ``w`` and its commit: the height blobs (unless
    ``heights`` is False: given already), the δ, r, normals and δ_edge blobs in the
    streamed preprocess's order (:func:`tile_row_order`; unless ``rows`` is False: given
    already, :func:`tile_blobs`' ``on_rows``), the GeoMipMapping blocks' δ_n, the tile
    table and the metadata."""
    if heights:
        w.put_blobs("heights", blobs.heights)
    for kind, b in tile_row_order(blobs.extra, set(blobs.heights)) if rows else ():
        w.put_blobs(kind, b)
    w.put_blobs("block_delta", {(grid.top_level, 0, 0): pack_block_errors(blocks)})
    w.put_tiles(blobs.tile_rows)
    w.put_metadata(store_metadata(**meta))
    w.commit()


def cached_store_path(dem: str | Path) -> Path:
    """Where :func:`ensure_store` keeps a DEM's store: ``$XDG_CACHE_HOME/geoterrain``
    (default ``~/.cache/geoterrain``), keyed by the DEM's absolute path, size and
    mtime. Never beside the DEM: that folder may be shared or read-only.

    Examples
    --------
    >>> cached_store_path(__file__).parent.name
    'geoterrain'
    """
    import hashlib

    dem = Path(dem).resolve()
    st = dem.stat()
    key = f"{dem}\0{st.st_size}\0{st.st_mtime_ns}".encode()
    digest = hashlib.sha256(key).hexdigest()[:16]
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "geoterrain"
    return cache / f"{dem.stem}-{digest}{STORE_SUFFIX}"


def ensure_store(dem: str | Path, *, rebuild: bool = False,
                 progress: Progress | None = None) -> tuple[Path, bool]:
    """The cached store of ``dem`` (:func:`cached_store_path`), preprocessed now if it is
    missing (the key changes with the DEM's size and mtime) or ``rebuild``; returns
    (path, whether it was built).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 17))
    >>> [built for _, built in (ensure_store(dem), ensure_store(dem))]
    [True, False]
    """
    src = Path(dem)
    if not src.is_file():
        raise InputError(f"{src}: no such file; check the path")
    store = cached_store_path(src)
    if rebuild or not store.exists():
        store.parent.mkdir(parents=True, exist_ok=True)
        preprocess(src, store, overwrite=True, progress=progress)
        return store, True
    return store, False
