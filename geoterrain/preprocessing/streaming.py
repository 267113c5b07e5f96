"""The preprocess job for a DEM larger than memory: the store of
:func:`geoterrain.preprocessing.pipeline.preprocess`, from a raster read a window at a time
(issues 12 and 45).

Each stage is its whole-grid twin's streaming form, the same bits
(``tests/preprocessing/test_streaming_stages.py``):

- the source a window at a time (:mod:`geoterrain.ingest.windows`: any raster, a mosaic's
  VRT, a PNG tile decoded per window);
- the quantizer from band statistics (:mod:`geoterrain.preprocessing.bands.quantize`);
- on a geographic grid, the scene x, y of every row once (pyproj, into scratch files);
- δ, δ_edge and the per-level heights in row bands
  (:mod:`geoterrain.preprocessing.bands.delta`), the radius codes nested on them
  (:mod:`geoterrain.preprocessing.bands.radii`); on a geographic grid δ, δ_edge and r made
  to hold in metric x, y (:mod:`geoterrain.preprocessing.bands.curvature`, the terms as
  maxima over bands) and level 0's δ slack (:mod:`geoterrain.preprocessing.bands.leaf`);
- the tile table (:mod:`geoterrain.preprocessing.bands.tiles`) and every level's normals
  (:mod:`geoterrain.preprocessing.bands.normals`) in row bands;
- the height blobs a super-tile at a time (:mod:`geoterrain.preprocessing.bands.codec`);
- the δ, r and normals blobs a tile row at a time, :data:`WINDOW_TILES` tiles of it at a
  time, from each level's lattice rebuilt from the per-level arrays
  (:func:`geoterrain.bounds.tileblobs.level_blobs` on that window).

Per-level arrays live in scratch files (:mod:`geoterrain.preprocessing.scratch`); blobs go to the
store writer as they are made. Memory is set by ``band``: the rows of a band's window
and a window of tiles, not the raster. The four passes after the quantizer
run on any scheduler (:mod:`geoterrain.preprocessing.passes`,
:mod:`geoterrain.preprocessing.schedulers`),
and a killed run can be resumed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import shutil
from pathlib import Path

import numpy as np

from geoterrain.bounds.edgepad import has_padding
from geoterrain.bounds.leafbounds import CentreHeights, ring_guesses
from geoterrain.bounds.log8codes import log8_exponent
from geoterrain.bounds.tileblobs import (
    BoundsCoding,
    EdgeGuess,
    OwnHeights,
    level_blobs,
    ring_blobs,
)
from geoterrain.bounds.tilebounds import TileTable, pack_block_errors
from geoterrain.bounds.vertexdata import shaped_zstd_level
from geoterrain.codec.quantize import roundtrip
from geoterrain.core.atomicfiles import remove_stale_partials
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.core.memory import release_free_heap
from geoterrain.core.paths import input_problem
from geoterrain.core.progress import Progress, StageClock
from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.raster import ABSURD_HEIGHT, VOID_SENTINELS
from geoterrain.ingest.remote import is_url
from geoterrain.ingest.windows import RasterSpec, describe, localize
from geoterrain.preprocessing.bands.delta import level_lattice
from geoterrain.preprocessing.bands.normals import ring_lines
from geoterrain.preprocessing.bands.quantize import band_quantizer
from geoterrain.preprocessing.passes import (
    STREAM_GDAL_CACHE,
    Job,
    Source,
    adopt,
    heights_records,
    job_record,
    pass_result,
    run_pass,
    whole,
)
from geoterrain.preprocessing.request import Request, place, request, root_layout
from geoterrain.preprocessing.schedulers import run_tasks
from geoterrain.preprocessing.scratch import ScratchArrays
from geoterrain.preprocessing.storewrite import store_metadata
from geoterrain.store.schema import page_size_for
from geoterrain.store.writer import StoreWriter

__all__ = ["band_rows", "preprocess_streaming", "stream", "streaming_band"]

log = logging.getLogger("geoterrain")

# Bytes per sample of a band's rows, over every stage's windows and their copies, and
# what the process holds besides (imports, compiled kernels, tile tables): measured on
# the 16385² fBm (docs/lab/streaming.md), with a margin
BAND_BYTES_PER_SAMPLE = 200
BAND_BYTES_PER_SAMPLE_GEOGRAPHIC = 400  # x, y and the metric terms' windows too
FIXED_BYTES = 400 << 20
BAND_SAMPLES = 1 << 20  # at most this many samples a band (streaming_band)
# a geographic grid's band holds twice the bytes a sample (scene x, y and the metric
# terms' window: a band and half a band of halo each side), so half the samples: the
# 4097 × 2049 mosaic on its root grid peaked 388 MB with 256-row bands and 338 MB with
# 128, the same CPU time (26.3 and 26.4 s), against 323 MB for a 1025 × 513 one in one
# band (docs/lab/root-grids.md, part 8)
BAND_SAMPLES_GEOGRAPHIC = 1 << 19
# tiles across a window of the blobs stage: a tile row is coded this many tiles at a
# time, so the stage's arrays are those of a 4097² raster's row (t = 6) at every width
WINDOW_TILES = 64
STAGES = ("scan", "quantise", "errors, tiles, normals, heights", "blobs", "write")


def streaming_band(shape: tuple[int, int], memory_limit: int, geographic: bool = False,
                   roots: bool = True) -> int | None:
    """The band (rows, a power of two) to preprocess a raster of ``shape`` (rows, cols) a
    window at a time within ``memory_limit`` bytes; None when its whole-grid preprocess
    fits (:data:`geoterrain.ingest.raster.PREPROCESS_BYTES_PER_SAMPLE`, more per sample in a
    geographic frame). ``roots``: the layout asked for (``preprocess``'s ``root_grid``),
    as :func:`geoterrain.preprocessing.request.root_layout` settles it: on a root grid
    the whole grid is the roots' extent, and a band as wide as the extent.

    Examples
    --------
    >>> streaming_band((65, 65), 1 << 40), streaming_band((65, 65), 1 << 18)
    (None, 2)
    >>> streaming_band((1762, 47163), 16 << 30, roots=False)  # pads to 65537²: streamed
    16
    >>> streaming_band((1762, 47163), 16 << 30)  # its extent: 32769 × 65537
    16
    """
    from geoterrain.ingest.raster import PREPROCESS_BYTES_PER_SAMPLE

    H, W = shape
    kind = "geographic" if geographic else "projected"
    # the whole grid: the roots' extent (the square's N², to which a long, thin raster
    # pads to more)
    R, C = Grid.for_shape(H, W, roots=root_layout(roots)).extent
    if R * C * PREPROCESS_BYTES_PER_SAMPLE[kind] <= memory_limit:
        return None
    return band_rows(C, memory_limit, geographic)


def band_rows(N: int, memory_limit: int, geographic: bool = False) -> int:
    """Rows per band (a power of two ≥ 2) of the streaming preprocess of a grid of side N
    (a root grid: N columns, its extent's) within ``memory_limit`` bytes.

    Examples
    --------
    >>> band_rows(4097, 1 << 30), band_rows(16385, 1 << 30), band_rows(65, 1 << 18)
    (256, 64, 2)
    >>> band_rows(4097, 1 << 30, geographic=True)
    128
    """
    per = BAND_BYTES_PER_SAMPLE_GEOGRAPHIC if geographic else BAND_BYTES_PER_SAMPLE
    # at most BAND_SAMPLES a band, whatever the limit: the band's memory is then the same
    # for every raster width (4097²: 256 rows, 397 MB; 16385²: 64 rows, 430 MB), and
    # wider bands gain no time (16385²: 104 s with 64 rows, 107 s with 128, 115 s with 256)
    cap = BAND_SAMPLES_GEOGRAPHIC if geographic else BAND_SAMPLES
    rows = min(max(memory_limit - FIXED_BYTES, 0) // (N * per), cap // (N - 1))
    return int(max(1 << max(int(rows).bit_length() - 1, 0), 2))


def _scan(src: Source, band: int) -> tuple[float | None, int, int]:
    # raster.py's rules over the file's rows: an undeclared void sentinel (the minimum,
    # one of VOID_SENTINELS, more than 1000 below every other height), how many samples
    # hold it, and the ±inf samples
    m1 = m2 = np.inf  # the smallest finite height, and the smallest above it
    n1 = 0  # how many samples are m1
    n_inf = 0
    for i in range(0, src.H, band):
        h = src.file_rows(i, min(i + band, src.H)).astype(np.float64)
        n_inf += int(np.isinf(h).sum())
        f = h[np.isfinite(h)]
        if not f.size:
            continue
        b1 = float(f.min())
        above = f[f > b1]
        cands = [m1, m2, b1, float(above.min()) if above.size else np.inf]
        if b1 < m1:
            n1 = 0
        m1 = min(cands)
        m2 = min((c for c in cands if c > m1), default=np.inf)
        n1 += int(np.count_nonzero(f == m1))
    void = None
    if np.isfinite(m1) and m1 in VOID_SENTINELS and np.isfinite(m2) and m2 - m1 > 1000.0:
        void = m1
    return void, n1, n_inf


def preprocess_streaming(
    src: str | Path | list,
    dst: str | Path | None = None,
    *,
    tile_size: int = 64,
    z_scale: float | None = None,
    z_units: str = "auto",
    codec_error: float | None = None,
    overwrite: bool = False,
    nodata: float | None = None,
    band: int = 256,
    raster_band: int | None = None,
    encoding: str = "auto",
    pixel_size: float | None = None,
    tile: str | None = None,
    scratch: str | Path | None = None,
    derive_normals: bool = True,
    derive_bounds: bool = True,
    scheduler: str = "sync",
    resume: bool = False,
    progress: Progress | None = None,
    crs: str | None = None,
    resolution: float | None = None,
    resampling: str = "bilinear",
    priority: str = "finest",
    timings: dict | None = None,
    root_grid: bool = True,
) -> Path:
    """Preprocess a DEM a window at a time into the store
    :func:`~geoterrain.preprocessing.pipeline.preprocess` writes (the same tiles, blobs and
    metadata but the timings); memory is set by ``band`` rows, not the raster.

    Every input ``preprocess`` takes: any raster GDAL reads (a ``.vrt`` too), a list or a
    glob of tiles (a mosaic, pasted by an in-memory VRT), a Terrain-RGB or Terrarium PNG
    tile (decoded a window at a time), in a projected, geographic or pixel frame.
    Parameters are :func:`~geoterrain.preprocessing.pipeline.preprocess`'s (its ``band``,
    the raster's band, is ``raster_band`` here), and ``band`` (rows per band, a power of
    two), ``scratch`` (the folder of the scratch files; default the store's folder) and
    ``scheduler`` (:mod:`geoterrain.preprocessing.schedulers`: where the passes run: on a
    geographic grid first its scene x, y; then δ with δ_edge and the radius codes, the
    tile table, the normals and the height blobs, the last one first with
    ``codec_error``, as the others read its decoded heights; the store is the same on
    every one, and this process stays its only writer) and ``resume`` (reuse the passes
    a killed run of the same job into ``dst`` finished: its scratch folder records each
    pass's result; the store is the one an uninterrupted run writes) and ``root_grid``
    (``preprocess``'s, a rectangular root grid by default, in a geographic, projected or
    pixel frame; the store the whole-grid preprocess writes with it).

    Examples
    --------
    >>> import tempfile, os, geoterrain
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 33, seed=1))
    >>> p = preprocess_streaming(dem, os.path.join(d, "s.geoterrain"), band=8)
    >>> geoterrain.open(p).grid.size
    33
    """
    req = request(src, dst, tile_size=tile_size, codec_error=codec_error,
                  pixel_size=pixel_size, overwrite=overwrite, scheduler=scheduler,
                  resume=resume, root_grid=root_grid)
    for f in req.files:  # a FIFO would block the read, a device never end
        if not is_url(f) and (why := input_problem(f, utf8=True)) is not None:
            raise InputError(f"{f}: {why}; check the path")
    return stream(req, z_scale=z_scale, z_units=z_units, codec_error=codec_error,
                  nodata=nodata, band=band, raster_band=raster_band, encoding=encoding,
                  pixel_size=pixel_size, tile=tile, scratch=scratch,
                  derive_normals=derive_normals, derive_bounds=derive_bounds,
                  scheduler=scheduler, resume=resume, progress=progress, crs=crs,
                  resolution=resolution, resampling=resampling, priority=priority,
                  timings=timings)


def stream(req: Request, *, z_scale: float | None = None, z_units: str = "auto",
           codec_error: float | None = None, nodata: float | None = None, band: int = 256,
           raster_band: int | None = None, encoding: str = "auto",
           pixel_size: float | None = None, tile: str | None = None,
           scratch: str | Path | None = None, derive_normals: bool = True,
           derive_bounds: bool = True, scheduler: str = "sync", resume: bool = False,
           progress: Progress | None = None, crs: str | None = None,
           resolution: float | None = None, resampling: str = "bilinear",
           priority: str = "finest", timings: dict | None = None) -> Path:
    """:func:`preprocess_streaming` of a request already resolved and checked
    (:func:`geoterrain.preprocessing.request.request`: the source's files and the store
    to write), as :func:`geoterrain.preprocessing.pipeline.preprocess` hands it on; the
    other parameters are ``preprocess_streaming``'s.

    Examples
    --------
    >>> import tempfile, os, geoterrain
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> from geoterrain.preprocessing.request import request
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 33, seed=1))
    >>> req = request(dem, None, tile_size=16, codec_error=None, pixel_size=None,
    ...               overwrite=False, scheduler="sync", resume=False)
    >>> geoterrain.open(stream(req, band=8)).grid.tile_samples
    17
    """
    stage = StageClock(STAGES, progress, timings)
    if band < 2 or band & (band - 1):
        raise UsageError(f"band must be a power of two ≥ 2, got {band}")
    spec, meta = describe(req.files, band=raster_band, encoding=encoding, nodata=nodata,
                          rows=band, crs=crs, resolution=resolution, resampling=resampling,
                          priority=priority)
    _, _, frame, grid = place(req, meta["shape"], meta["transform"], meta["crs_wkt"],
                              tile=tile, pixel_size=pixel_size, z_units=z_units,
                              z_scale=z_scale, label=spec.label if req.mosaic else str(req.src))
    dst = req.dst
    parent = Path(scratch) if scratch is not None else (dst.parent if str(dst.parent) else
                                                        Path("."))
    # a source read over HTTP is fetched once into a folder named like a partial store (a
    # killed run's is removed by the next run in this folder): every pass then reads it
    fetch = parent / f".{dst.name}.fetch.partial-{os.getpid()}"
    try:
        return _streamed(req, spec, meta, grid, frame, band, codec_error, z_scale, parent,
                         derive_normals, derive_bounds, scheduler, resume, stage, fetch)
    finally:
        shutil.rmtree(fetch, ignore_errors=True)


def _streamed(req: Request, spec: RasterSpec, meta: dict, grid: Grid, frame: Frame,
              band: int, codec_error: float | None, z_scale: float | None, parent: Path,
              derive_normals: bool, derive_bounds: bool, scheduler: str, resume: bool,
              stage: StageClock, fetch: Path) -> Path:
    # preprocess_streaming after its arguments: fetch, scan, quantise, the passes, write
    remote = spec  # what a resumed run must match: the source as given
    dst = req.dst
    spec = localize(spec, fetch)
    nd = meta["nodata"]
    with spec.open(cache=STREAM_GDAL_CACHE) as ds:
        if meta["encoding"] == "raw" and not spec.layers:  # (a merge: each source's nodata)
            void, n_void, n_inf = _scan(Source(ds, grid, spec), band)
            if n_inf:
                raise InputError(f"{spec.label}: {n_inf} sample(s) are ±inf; declare them "
                                 "nodata (e.g. gdal_translate -a_nodata)")
            if nd is None and void is not None:
                log.warning("%s: %d samples are %g, far below the other heights: taken as "
                            "nodata (undeclared voids); pass --nodata to say otherwise",
                            spec.label, n_void, void)
                nd = void
        spec = dataclasses.replace(spec, nodata=nd)
        source = Source(ds, grid, spec)
        N = source.R  # rows of the grid (the square's side, or a root grid's extent's)
        stage("scan")

        q = band_quantizer(lambda: source.bands(band), meta["dtype"], codec_error,
                           scale=meta["scale"], offset=meta["offset"])
        hv = [np.inf, -np.inf]  # decoded heights
        raw = [np.inf, -np.inf]  # source heights
        nvalid = 0
        for i in range(0, N, band):
            z, v = source.rows(i, min(i + band, N))
            nvalid += int(v.sum())
            if v.any():
                if q.bins == 1:  # decoded here; with bins by the height pass (below)
                    dz = roundtrip(z, v, q)[v]
                    hv = [min(hv[0], float(dz.min())), max(hv[1], float(dz.max()))]
                raw = [min(raw[0], float(z[v].min())), max(raw[1], float(z[v].max()))]
        if nvalid == 0:
            raise InputError(f"{spec.label}: every sample is nodata; check the nodata value or "
                             "the band")
        if max(abs(raw[0]), abs(raw[1])) > ABSURD_HEIGHT and z_scale is None:
            raise InputError(f"{spec.label}: heights reach {max(map(abs, raw)):.3g}, beyond "
                             f"±{ABSURD_HEIGHT:.0e}; if they are real pass --z-scale (e.g. 1), "
                             "else set the right nodata or unit")
        frame.check_scene(whole(grid), *raw)  # scene coordinates within SCENE_LIMIT
        stage("quantise")

    pad = has_padding(grid)
    derive_normals = bool(derive_normals) and grid.tile_samples >= 3
    derive_bounds = bool(derive_bounds) and grid.tile_samples >= 3 and grid.top_level > 0
    # the scratch folder is named like a partial store (.NAME.scratch.partial-PID): a
    # killed run's is removed by the next run in this folder (atomicfiles.remove_stale_partials)
    # unless that run resumes it
    job = Job(spec, grid.to_json(), frame.to_json(), q, band, "", pad, derive_bounds)
    record = job_record(dataclasses.replace(job, spec=dataclasses.replace(remote, nodata=nd)))
    folder = adopt(parent, dst, record) if resume else None
    if folder is not None:
        done = sorted(p.name[5:] for p in Path(folder).glob("done-*") if "." not in p.name)
        log.info("%s: resuming a killed run; passes done: %s", dst, ", ".join(done) or "none")
    remove_stale_partials(parent)
    if folder is None:
        folder = str(parent / f".{dst.name}.scratch.partial-{os.getpid()}")
        shutil.rmtree(folder, ignore_errors=True)
        os.makedirs(folder)
        with open(os.path.join(folder, "job.json"), "w") as fh:
            json.dump(record, fh)
    job = dataclasses.replace(job, folder=folder)
    with contextlib.ExitStack() as cleanup:
        cleanup.callback(shutil.rmtree, folder, True)
        first = (["xy"] if frame.kind == "geographic" else []) + \
            (["heights"] if q.bins > 1 else [])
        if first:  # what the other passes read: scene x, y; decoded heights (residual bins)
            got = dict(zip(first, run_tasks(scheduler, [(run_pass, (job, name))
                                                        for name in first]), strict=True))
            if "heights" in got:
                hv = list(got["heights"]["range"])
        rest = [name for name in ("bounds", "tiles", "normals", "heights") if name not in first]
        got = dict(zip(rest, run_tasks(scheduler, [(run_pass, (job, name)) for name in rest]),
                       strict=True))
        vrange, stand_in, er, dmax, emax, slack = got["bounds"]
        del got
        bounds, blocks = pass_result(job, "tiles")  # one copy, read back from its record
        stage("errors, tiles, normals, heights")
        sa = ScratchArrays.shared(os.path.join(folder, "bounds"))
        se = ScratchArrays.shared(os.path.join(folder, "edge")) if pad else None
        sn = ScratchArrays.shared(os.path.join(folder, "normals"))
        try:
            with StoreWriter(dst, overwrite=req.overwrite,
                             page_size=page_size_for(grid.rows, grid.cols)) as w:
                # 256 blobs a batch (about 1 MB; 4 096 held 21 MB at once, with the
                # writer's rows and the held copy on top: docs/lab/streaming.md)
                for part in heights_records(os.path.join(folder, "heights.bin"), 256):
                    # a root grid's tiles only (a footprint over the extent may reach
                    # one tile past the raster's last row or column)
                    w.put_blobs("heights", grid.held(part))
                # the tiles whose footprint holds a valid sample (the tile pass's table)
                stored = _own_tiles(grid, bounds)
                del bounds
                release_free_heap()  # the passes' and the height blobs' freed memory
                if frame.kind == "geographic" and derive_bounds:  # surface.vertex_bounds
                    ring: tuple[str, ...] = ("delta",) if slack is not None else ()
                else:
                    ring = ("delta", "radius") if derive_bounds else ()
                # schema 17: the normals' rings as differences from what a reader derives
                # (the normals pass's heights on the ring lines; not in a killed run's
                # scratch from before them)
                residual = derive_normals and "zr0" in sn
                guess = (frame.kind == "geographic" and derive_bounds
                         and "radius" not in ring)
                meta_blobs = _level_blobs(w, sa, se, sn, grid, stored, er, dmax, emax,
                                          derive_normals, ring,
                                          {(x, y): s for x, y, s in slack or ()},
                                          frame if residual else None,
                                          stand_in if guess else None, stand_in)
                del stored  # (in the staging table now: the commit reads it from there)
                stage("blobs")
                across, down = grid.tiles(0)  # a root grid's extent holds more than its tiles
                blocks = blocks[:down, :across]
                w.put_blobs("block_delta", {(grid.top_level, 0, 0): pack_block_errors(blocks)})
                w.put_metadata(store_metadata(
                    source=spec.label, source_dtype=meta["dtype"],
                    source_nodata=None if nd is None else float(nd),
                    encoding=meta["encoding"],
                    grid=grid.to_json(), frame=frame.to_json(), quantizer=q.to_json(),
                    normals_derived=(list(range(grid.top_level + 1))
                                     if derive_normals else []), ring_residual=residual,
                    valid_samples=nvalid,
                    samples=grid.rows * grid.cols, height_range=hv,
                    delta_max_finite=meta_blobs["delta_max"],
                    edge_max=meta_blobs["edge_max"] if pad else None, stand_in_z=stand_in,
                    block_delta_levels=int(blocks.shape[2])))
                stage("write")
                w.commit()
        finally:
            for arrs in (sa, se, sn):
                if arrs is not None:
                    arrs.close()
    return dst


def _level_blobs(w: StoreWriter, sa: ScratchArrays, se: ScratchArrays | None,
                 sn: ScratchArrays, grid: Grid, stored: TileTable, er: int,
                 dmax: float, emax: float, derive_normals: bool, ring: tuple[str, ...],
                 slack: dict, frame: Frame | None = None,
                 stand_in: float | None = None, own_stand_in: float = 0.0) -> dict:
    """The δ, r, normals and δ_edge blobs and the tile rows, a tile row of each level at a
    time, coded :data:`WINDOW_TILES` tiles at a time (preprocessing.preprocess's compress
    stage on each window of a level's lattice).
    ``stored``: the stored tiles' bounds; each tile row's go to the writer with the row's
    blobs (its staging table), so no per-tile Python rows pile up for the whole pyramid.
    ``dmax``, ``emax``: the largest finite δ and δ_edge, which set δ's code exponent;
    ``ring``: the kinds level 0 stores as border rings; ``slack``: a geographic store's
    level-0 slack per tile (x, y); ``frame`` (given): the normals' rings as differences
    from what a reader derives there (schema 17, :func:`_ring_guess_row`); ``stand_in``
    (given: a geographic store's): level 0's r centres as differences from their guess
    from the heights (the bounds pass's ``ZC0``…, the stand-in in place); ``own_stand_in``:
    the store's stand-in height, with which δ's blobs are guessed from the bounds pass's
    heights of every level (schema 20, :class:`geoterrain.bounds.tileblobs.OwnHeights`)."""
    n, t, top = grid.n, grid.t, grid.top_level
    T, T1 = grid.tile_samples, grid.tile_samples - 1
    zlevel = shaped_zstd_level(grid.rows, grid.cols)
    ed = log8_exponent(np.array([dmax]))
    if se is not None:
        ed = max(ed, log8_exponent(np.array([emax])))
    # each tile row's stored tiles, x ascending: the table's rows ordered by (L, y, x)
    k = stored.keys
    order = np.lexsort((k[:, 1], k[:, 2], k[:, 0]))
    lk = k[order]
    cut = np.flatnonzero((lk[1:, 0] != lk[:-1, 0]) | (lk[1:, 2] != lk[:-1, 2])) + 1
    starts, ends = np.r_[0, cut].tolist(), np.r_[cut, len(lk)].tolist()
    row_at = {(int(lk[i, 0]), int(lk[i, 2])): (i, j)  # (L, y) → its slice of ``order``
              for i, j in zip(starts, ends, strict=True) if i < j}
    edge_max: list = []
    e_stored: list = []
    e_only: list = []
    C = grid.extent[1]
    for L in grid.levels:
        m = ((C - 1) >> L) + 1  # the level's lattice over the extent (the square's side)
        across, down = grid.tiles(L)
        is_top = L == top
        top_w = 0 if is_top else 1  # a window's level 0 is level L
        for y in range(down):
            i, j = row_at.get((L, y), (0, 0))
            row_keys = lk[i:j, 1]
            p0, p1 = y * T1, y * T1 + T
            # the row's blobs, gathered over its windows and handed to the writer in the
            # order of one window as wide as the raster (the store's bytes follow it)
            got: dict = {}
            dms, rms = [], []
            e_rows: tuple[dict, dict] = ({}, {})
            for x0 in range(0, across, WINDOW_TILES):
                # a window of at most WINDOW_TILES tiles across: its arrays' bytes are
                # the same at every raster width (16385² level 0: 4.3 MB of δ alone
                # for the whole tile row)
                x1 = min(x0 + WINDOW_TILES, across)
                q0, q1 = x0 * T1, min(x1 * T1 + 1, m)
                keys = row_keys[(row_keys >= x0) & (row_keys < x1)].tolist()
                # every vertex of the lattice, the coarser levels' too: a PRED payload
                # holds its codes as differences from its parents'
                # (log8codes.pred_residuals)
                d = level_lattice(sa, "", L, n, p0, p1, m, True, np.float32, q0, q1)
                rc = level_lattice(sa, "r", L, n, p0, p1, m, True, np.uint8, q0, q1)
                nrm = sn.read(f"n{L}", p0, p1, 2 * q0, 2 * q1).reshape(T, q1 - q0, 2)
                coding = BoundsCoding(d, None, ed, r_codes=(rc, er))
                del d
                edge = None
                if se is not None:
                    # every vertex of the lattice: an unstored tile's δ_edge blob is whole
                    edge = BoundsCoding(level_lattice(se, "", L, n, p0, p1, m, True,
                                                      np.float32, q0, q1),
                                        None, ed, r_codes=(rc, er))
                local = [(x - x0, 0) for x in keys]
                if keys:  # every level's normals: the border ring (derive_normals)
                    centres = None
                    if stand_in is not None and not is_top:
                        # a geographic level-0 r's centres guessed from the heights, and
                        # above level 0 every r vertex (schema 20; the coarser levels'
                        # heights too, but the root tiles' corners, which no guess reads)
                        inw = (row_keys >= x0) & (row_keys < x1)
                        rows_k = stored.rows[order[i:j]][inw]
                        zl = level_lattice(sa, "Z", L, n, p0, p1, m, L > 0, np.float64,
                                           q0, q1)
                        centres = CentreHeights(zl, np.ones(zl.shape, np.uint8), stand_in,
                                                rows_k[:, 5:9].astype(np.float64))
                    # schema 20: the window's heights on the level's whole lattice (the
                    # stand-in in place), δ's blobs guessed from their own errors
                    own = OwnHeights(level_lattice(sa, "Z", L, n, p0, p1, m, True,
                                                   np.float64, q0, q1), None, own_stand_in)
                    blobs, dm, rm = level_blobs(
                        coding, nrm, t, 0, top_w, local,
                        ("delta", "radius") if derive_normals
                        else ("delta", "radius", "normals"),
                        ring=ring if L == 0 else False,
                        slack={(0, x - x0, 0): slack[(x, y)] for x in keys
                               if (x, y) in slack} if L == 0 and slack else None,
                        mids=L > 0 and "radius" in ring,
                        centres=centres if L == 0 else None,
                        heights=centres if L > 0 else None, own=own, zlevel=zlevel)
                    del centres, own
                    if derive_normals:
                        guess_n = (None if frame is None else
                                   _ring_guess_row(sn, grid, frame, L, y, keys, m))
                        blobs["normals"] = ring_blobs(nrm, t, local, 0, guess_n, zlevel)
                    for kind, bl in blobs.items():
                        got.setdefault(kind, {}).update(
                            {(L, x + x0, y): v for (_, x, _), v in bl.items()})
                    dms += dm.tolist()
                    rms += rm.tolist()
                if edge is None:
                    continue
                # edgepad.edge_tiles / edge_only_tiles on this window
                held_diff = _held(coding.dc != edge.dc, T1, is_top)[:x1 - x0]
                held_pos = _held(edge.dc > 0, T1, is_top)[:x1 - x0]
                kept = set(keys)  # this window's stored tiles
                # stored tiles: new vertices as differences from δ; unstored ones: whole
                for keys_e, base, into in (
                        ([x for x in keys if held_diff[x - x0]], coding, e_rows[0]),
                        ([x for x in range(x0, x0 + len(held_pos)) if held_pos[x - x0]
                          and x not in kept], None, e_rows[1])):
                    if not keys_e:
                        continue
                    # schema 23: the stored tiles below the top guessed from the
                    # heights, the padding replicated (ownguess.edge_own_codes): the
                    # data's samples of the window's lattice
                    guessed = base is not None
                    own_e = OwnHeights(level_lattice(sa, "Z", L, n, p0, p1, m, True,
                                                     np.float64, q0, q1), None,
                                       own_stand_in) if guessed else None
                    eg = EdgeGuess((grid.rows - 1 >> L) - p0 + 1,
                                   (grid.cols - 1 >> L) - q0 + 1, L > 0)
                    eb, emx, _ = level_blobs(edge, nrm, t, 0, top_w if base is not None
                                             else 0, [(x - x0, 0) for x in keys_e],
                                             ("delta",), base=base, zlevel=zlevel,
                                             own=own_e, edge=eg if guessed else None)
                    into.update({x: (v, mx) for x, (v, mx) in zip(
                        keys_e, zip(eb["delta"].values(), emx.tolist(), strict=True),
                        strict=True)})
            keys = row_keys.tolist()
            for kind, bl in got.items():
                w.put_blobs(kind, bl)
            if keys:
                w.put_tiles({(L, x, y): (int(r[0]), *r[1:], a, b) for x, r, a, b in zip(
                    keys, stored.rows[order[i:j]].tolist(), dms, rms, strict=True)})
            for into, out in zip(e_rows, (e_stored, e_only), strict=True):
                if into:
                    w.put_blobs("delta_edge", {(L, x, y): v for x, (v, _) in into.items()})
                    out += [[L, x, y, mx if np.isfinite(mx) else None]
                            for x, (_, mx) in into.items()]
        # the metadata's order (preprocessing.preprocess): a level's stored tiles by
        # (x, y), then its unstored ones by (y, x)
        edge_max += sorted(e_stored, key=lambda e: (e[1], e[2])) + e_only
        e_stored, e_only = [], []
    return {"delta_max": dmax, "edge_max": edge_max}


def _ring_guess_row(sn: ScratchArrays, grid: Grid, frame: Frame, L: int, y: int,
                    keys: list[int], m: int, group: int = 16) -> np.ndarray:
    """What a reader derives at the rings of level L's tiles (x, y), x in ``keys``
    (:func:`geoterrain.bounds.leafbounds.ring_guesses`), from the normals pass's heights on
    the ring lines (``zr{L}``, ``zc{L}``; the rest of each tile, which the ring's tangents
    never read, NaN), ``group`` tiles a window: a few hundred kB whatever the grid."""
    t = grid.t
    S = 1 << t
    T = S + 1
    p0, p1 = y * S, y * S + T
    lr, lc = ring_lines(sn.shape(f"n{L}")[0], t), ring_lines(m, t)
    a, b = np.searchsorted(lr, [p0, p1])
    zr = sn.read(f"zr{L}", int(a), int(b))
    zc = sn.read(f"zc{L}", p0, p1)
    out = np.empty((len(keys), 4 * T - 4, 2), np.uint8)
    for g0 in range(0, len(keys), group):
        ks = keys[g0:g0 + group]
        c0, c1 = ks[0] * S, ks[-1] * S + T
        win = np.full((T, c1 - c0), np.nan)
        win[lr[a:b] - p0] = zr[:, c0:c1]
        ca, cb = np.searchsorted(lc, [c0, c1])
        win[:, lc[ca:cb] - c0] = zc[:, ca:cb]
        out[g0:g0 + len(ks)] = ring_guesses(
            grid, frame, L, [(x, y) for x in ks], win, np.isfinite(win),
            np.array([(0, (x - ks[0]) * S) for x in ks], np.int64).reshape(-1, 2))
    return out


def _own_tiles(grid: Grid, table: TileTable) -> TileTable:
    # Grid.holds over the table's keys: a root grid's own tiles (a footprint over the
    # extent may reach one tile past the raster's last row or column)
    L, x, y = table.keys.T
    top = grid.top_level
    across, down = np.array([grid.tiles(lv) for lv in range(top + 1)], np.int64).T
    lc = np.clip(L, 0, top)
    ok = (L >= 0) & (L <= top) & (x >= 0) & (x < across[lc]) & (y >= 0) & (y < down[lc])
    if ok.all():  # (a square grid's: the table itself, not a second copy)
        return table
    return TileTable(table.keys[ok], table.rows[ok])


def _held(mark: np.ndarray, T1: int, top: bool) -> np.ndarray:
    # edgepad._holding on one tile row's lattice window (T rows): per tile, whether its
    # stored vertices (below the top, those new at the level) include a marked one
    lat = mark.copy()
    if not top:
        lat[::2, ::2] = False
    n = (lat.shape[1] - 1) // T1
    held = lat[:-1, :-1].reshape(T1, n, T1).any(axis=(0, 2))
    held |= lat[T1, :-1].reshape(n, T1).any(axis=1)
    held |= lat[:-1, T1::T1].any(axis=0)
    held |= lat[T1, T1::T1]
    return held
