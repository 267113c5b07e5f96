"""The preprocess pipeline: DEM → padded pyramid → errors, normals, codec → store.

Stages (timed; ``preprocess(timings=...)`` receives the times, never the store, so the
same input and options give the same bytes):
read → pad → quantise → errors → radii → tile bounds → normals → compress → write.
This module runs them (:func:`preprocess`, and the threads beside them); the stages
themselves are :mod:`geoterrain.preprocessing.surface` (read, pad, quantise, errors,
radii), :mod:`geoterrain.bounds.tilebounds` (tile bounds), :mod:`geoterrain.bounds.normals`,
:mod:`geoterrain.preprocessing.levelblobs` (compress) and
:mod:`geoterrain.preprocessing.storewrite` (write).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from geoterrain.bounds.delta import delta_max_finite
from geoterrain.bounds.edgepad import (
    has_padding,
)
from geoterrain.bounds.normalbytes import NORMAL_BITS
from geoterrain.bounds.normals import level_normal_codes, ring_normal_codes
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.core.grid import footprint_counts
from geoterrain.core.memory import available_memory, collector_paused, small_pages
from geoterrain.core.paths import STORE_SUFFIX, input_problem
from geoterrain.core.progress import Progress, StageClock
from geoterrain.core.threads import PARALLEL_MIN_SAMPLES, cores_for
from geoterrain.exceptions import InputError
from geoterrain.ingest.remote import is_url
from geoterrain.preprocessing import levelblobs
from geoterrain.preprocessing.levelblobs import HeightsJob, tile_blobs
from geoterrain.preprocessing.request import Request, request
from geoterrain.preprocessing.storewrite import write_rows
from geoterrain.preprocessing.streaming import stream, streaming_band
from geoterrain.preprocessing.surface import Dem, Surface, pad, quantise, read_dem, vertex_bounds
from geoterrain.store.schema import page_size_for
from geoterrain.store.writer import StoreThread

log = logging.getLogger("geoterrain")
STAGES = ("read", "pad", "quantise", "errors", "radii", "tile bounds", "normals", "compress",
          "write")


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
        schema version 18, :data:`geoterrain.store.schema.ROOTS_SCHEMA_VERSION`), not to
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
    # whole-grid arrays on 4 KiB pages; no cyclic collection over the imports meanwhile
    with small_pages(), collector_paused():  # (core/memory.py)
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
                   and surface.valid.size >= levelblobs.HEIGHTS_THREAD_SAMPLES else None)
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
    jobs = surface.valid.size >= levelblobs.HEIGHTS_THREAD_SAMPLES
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
                    stand_in_z=blobs.stand_in,  # stand_in_z(surface.Z, surface.valid)
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
