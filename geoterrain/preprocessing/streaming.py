"""The preprocess job for a DEM larger than memory: the store of
:func:`geoterrain.preprocessing.pipeline.preprocess`, from a raster read a window at a time
(issue 12).

Each stage is its whole-grid twin's streaming form, the same bits
(``tests/preprocessing/test_streaming_stages.py``):

- the quantizer from band statistics (:mod:`geoterrain.preprocessing.bands.quantize`);
- δ, δ_edge and the per-level heights in row bands (:mod:`geoterrain.preprocessing.bands.delta`),
the
  radius codes nested on them (:mod:`geoterrain.preprocessing.bands.radii`);
- the tile table (:mod:`geoterrain.preprocessing.bands.tiles`) and every level's normals
  (:mod:`geoterrain.preprocessing.bands.normals`) in row bands;
- the height blobs a super-tile at a time (:mod:`geoterrain.preprocessing.bands.codec`);
- the δ, r and normals blobs a tile row at a time, from each level's lattice rebuilt
  from the per-level arrays (:func:`geoterrain.bounds.tileblobs.level_blobs` on that window).

Per-level arrays live in scratch files (:mod:`geoterrain.preprocessing.scratch`); blobs go to the
store writer as they are made. Memory is set by ``band``: the rows of a band's window
and of one tile row of each level, not the raster. The four passes after the quantizer
run on any scheduler (:mod:`geoterrain.preprocessing.passes`,
:mod:`geoterrain.preprocessing.schedulers`),
and a killed run can be resumed. Projected and pixel frames; a single-band raster GDAL
reads (a ``.vrt`` too; not a web-map PNG encoding, a list or a glob of tiles).
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
import rasterio

from geoterrain.bounds.edgepad import has_padding
from geoterrain.bounds.tileblobs import BoundsCoding, level_blobs, ring_blobs
from geoterrain.bounds.vertexdata import (
    log8_exponent,
    pack_block_errors,
    store_metadata,
)
from geoterrain.codec.quantize import roundtrip
from geoterrain.core.atomicfiles import remove_stale_partials
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.core.paths import check_output, input_problem
from geoterrain.core.progress import Progress, StageClock
from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.raster import ABSURD_HEIGHT, GDAL_READ_OPTIONS, VOID_SENTINELS
from geoterrain.ingest.units import resolve_z_units
from geoterrain.preprocessing.bands.quantize import band_quantizer
from geoterrain.preprocessing.passes import (
    PASSES,
    Job,
    Source,
    adopt,
    heights_records,
    job_record,
    run_pass,
)
from geoterrain.preprocessing.schedulers import run_tasks
from geoterrain.preprocessing.scratch import ScratchArrays
from geoterrain.store.database import StoreWriter

__all__ = ["preprocess_streaming", "streaming_band"]

log = logging.getLogger("geoterrain")

# Bytes per sample of a band's rows, over every stage's windows and their copies, and
# what the process holds besides (imports, compiled kernels, tile tables): measured on
# the 16385² fBm (docs/lab/streaming.md), with a margin
BAND_BYTES_PER_SAMPLE = 200
FIXED_BYTES = 400 << 20
BAND_SAMPLES = 1 << 20  # at most this many samples a band (streaming_band)
STAGES = ("scan", "quantise", "errors, tiles, normals, heights", "blobs", "write")


def streaming_band(path: str | Path, memory_limit: int) -> int | None:
    """The band (rows, a power of two) to preprocess ``path`` a window at a time within
    ``memory_limit`` bytes; None when the whole raster fits (or when the streaming
    preprocess does not take the file: several bands, a PNG tile, geographic
    coordinates, which then go whole).

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> dem = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 65))
    >>> streaming_band(dem, 1 << 40), streaming_band(dem, 1 << 18)
    (None, 2)
    """
    from geoterrain.ingest.raster import PREPROCESS_BYTES_PER_SAMPLE

    if input_problem(path, utf8=True) is not None:  # read_raster says why, in one line
        return None
    try:
        with rasterio.open(path) as ds:
            if ds.count != 1 or ds.driver == "PNG" or (ds.crs is not None
                                                     and ds.crs.is_geographic):
                return None
            H, W = ds.height, ds.width
    except rasterio.errors.RasterioIOError:
        return None
    if H * W * PREPROCESS_BYTES_PER_SAMPLE["projected"] <= memory_limit:
        return None
    N = Grid.for_shape(H, W).size
    # at most BAND_SAMPLES a band, whatever the limit: the band's memory is then the same
    # for every raster width (4097²: 256 rows, 397 MB; 16385²: 64 rows, 430 MB), and
    # wider bands gain no time (16385²: 104 s with 64 rows, 107 s with 128, 115 s with 256)
    rows = min(max(memory_limit - FIXED_BYTES, 0) // (N * BAND_BYTES_PER_SAMPLE),
               BAND_SAMPLES // (N - 1))
    return int(max(1 << max(int(rows).bit_length() - 1, 0), 2))


def _scan(src: Source, band: int) -> tuple[float | None, int]:
    # raster.py's rules over the file's rows: an undeclared void sentinel (the minimum,
    # one of VOID_SENTINELS, more than 1000 below every other height) and ±inf samples
    m1 = m2 = np.inf  # the smallest finite height, and the smallest above it
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
        m1 = min(cands)
        m2 = min((c for c in cands if c > m1), default=np.inf)
    void = None
    if np.isfinite(m1) and m1 in VOID_SENTINELS and np.isfinite(m2) and m2 - m1 > 1000.0:
        void = m1
    return void, n_inf


def _lattice(sa: ScratchArrays, pre: str, L: int, n: int, p0: int, p1: int, m: int,
             top: bool, dtype) -> np.ndarray:
    """Rows p0 … p1 − 1 of level L's lattice (m a side, sample (p, q) = grid sample
    (p 2^L, q 2^L)) of the per-level arrays ``{pre}C{k}``…: level L's new vertices, and
    at the top level every coarser one too (0 elsewhere)."""
    out = np.zeros((p1 - p0, m), dtype)
    for k in range(L, n if top else L + 1):
        u = 1 << (k - L)
        for x, ro, co in (("C", u, u), ("R", u, 0), ("K", 0, u)):
            a_lo = max(-(-(p0 - ro) // (2 * u)), 0)
            a_hi = (p1 - 1 - ro) // (2 * u)
            if a_hi < a_lo:
                continue
            rows = sa.read(f"{pre}{x}{k}", a_lo, a_hi + 1)
            a_hi = a_lo + len(rows) - 1
            out[ro + 2 * u * a_lo - p0:ro + 2 * u * a_hi - p0 + 1:2 * u, co::2 * u] = rows
    return out


def preprocess_streaming(
    src: str | Path,
    dst: str | Path | None = None,
    *,
    tile_size: int = 64,
    z_scale: float | None = None,
    z_units: str = "auto",
    codec_error: float | None = None,
    overwrite: bool = False,
    nodata: float | None = None,
    band: int = 256,
    scratch: str | Path | None = None,
    derive_normals: bool = True,
    derive_bounds: bool = True,
    scheduler: str = "sync",
    resume: bool = False,
    progress: Progress | None = None,
    timings: dict | None = None,
) -> Path:
    """Preprocess a DEM a window at a time into the store
    :func:`~geoterrain.preprocessing.pipeline.preprocess` writes (the same tiles, blobs and
    metadata but the timings); memory is set by ``band`` rows, not the raster.

    Parameters are :func:`~geoterrain.preprocessing.pipeline.preprocess`'s, and
    ``band`` (rows per band, a power of two), ``scratch`` (the folder of the scratch
    files; default the store's folder) and ``scheduler``
    (:mod:`geoterrain.preprocessing.schedulers`: where the four passes run, δ with δ_edge and the
    radius codes, the tile table, the normals and the height blobs, the last one first
    with ``codec_error``, as the others read its decoded heights; the store is the same
    on every one, and this process stays its only writer) and ``resume`` (reuse
    the passes a killed run of the same job into ``dst`` finished: its scratch folder
    records each pass's result; the store is the one an uninterrupted run writes).

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
    stage = StageClock(STAGES, progress, timings)

    if band < 2 or band & (band - 1):
        raise UsageError(f"band must be a power of two ≥ 2, got {band}")
    src = Path(src)
    dst = Path(dst) if dst is not None else src.with_suffix(".geoterrain")
    check_output(dst, overwrite, inputs=[src])  # core/paths.py: what may be replaced
    if (why := input_problem(src, utf8=True)) is not None:
        raise InputError(f"{src}: {why}; check the path")
    with rasterio.Env(**GDAL_READ_OPTIONS), rasterio.open(src) as ds:
        if ds.count != 1:
            raise UsageError(f"{src}: has {ds.count} bands; the streaming preprocess reads "
                             "single-band rasters")
        if ds.height < 2 or ds.width < 2:
            raise InputError(f"{src}: grid is {ds.height}×{ds.width}; a DEM needs at least "
                             "2×2 samples")
        dtype = ds.dtypes[0]
        crs_wkt = ds.crs.to_wkt() if ds.crs else None
        transform = tuple(ds.transform)[:6] if (ds.crs or not ds.transform.is_identity) \
            else None
        flip = transform is not None and transform[4] > 0
        if flip:  # south-up: rows flipped to north-up (raster.py)
            a, b, c, d_, e, f = transform
            transform = (a, b, c, d_, -e, f + e * ds.height)
        grid = Grid.for_shape(ds.height, ds.width, tile_size=tile_size)
        zu = resolve_z_units(z_units, crs_wkt, str(src))
        frame = Frame.from_raster(transform, crs_wkt, ds.height, ds.width, z_units=zu,
                                  z_scale=1.0 if z_scale is None else z_scale)
        if frame.kind == "geographic":
            raise UsageError(f"{src}: geographic coordinates; the streaming preprocess "
                             "takes projected or pixel grids (use preprocess)")
        declared = ds.nodatavals[0] if nodata is None else float(nodata)
        probe = Source(ds, grid, None, flip)
        void, n_inf = _scan(probe, band)
        if n_inf:
            raise InputError(f"{src}: {n_inf} sample(s) are ±inf; declare them nodata (e.g. "
                             "gdal_translate -a_nodata)")
        nd = declared if declared is not None else void
        source = Source(ds, grid, nd, flip)
        N = grid.size
        stage("scan")

        q = band_quantizer(lambda: source.bands(band), dtype, codec_error)
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
            raise InputError(f"{src}: every sample is nodata; check the nodata value or the band")
        if max(abs(raw[0]), abs(raw[1])) > ABSURD_HEIGHT and z_scale is None:
            raise InputError(f"{src}: heights reach {max(map(abs, raw)):.3g}, beyond "
                             f"±{ABSURD_HEIGHT:.0e}; if they are real pass --z-scale (e.g. 1), "
                             "else set the right nodata or unit")
        frame.check_scene(N, *raw)  # scene coordinates within SCENE_LIMIT (frame.py)
        stage("quantise")

    parent = Path(scratch) if scratch is not None else (dst.parent if str(dst.parent) else
                                                        Path("."))
    pad = has_padding(grid)
    # the scratch folder is named like a partial store (.NAME.scratch.partial-PID): a
    # killed run's is removed by the next run in this folder (atomicfiles.remove_stale_partials)
    # unless that run resumes it
    job = Job(str(src), grid.to_json(), frame.to_json(), q, nd, flip, band, "", pad)
    record = job_record(src, job)
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
        if q.bins == 1:
            (vrange, stand_in, er, dmax, emax), (bounds, blocks), _, _ = run_tasks(
                scheduler, [(run_pass, (job, name)) for name in PASSES])
        else:  # the decoded heights first: the other passes read them (streampasses)
            (hp,) = run_tasks(scheduler, [(run_pass, (job, "heights"))])
            hv = list(hp["range"])
            (vrange, stand_in, er, dmax, emax), (bounds, blocks), _ = run_tasks(
                scheduler, [(run_pass, (job, name)) for name in PASSES if name != "heights"])
        stage("errors, tiles, normals, heights")
        sa = ScratchArrays.shared(os.path.join(folder, "bounds"))
        se = ScratchArrays.shared(os.path.join(folder, "edge")) if pad else None
        sn = ScratchArrays.shared(os.path.join(folder, "normals"))
        try:
            with StoreWriter(dst, overwrite=overwrite) as w:
                for part in heights_records(os.path.join(folder, "heights.bin")):
                    w.put_blobs("heights", part)
                stored = set(bounds)  # the tiles whose footprint holds a valid sample
                meta = _level_blobs(w, sa, se, sn, grid, bounds, stored, er, dmax, emax,
                                    derive_normals, derive_bounds)
                stage("blobs")
                w.put_blobs("block_delta", {(grid.top_level, 0, 0): pack_block_errors(blocks)})
                w.put_metadata(store_metadata(
                    source=src.name, source_dtype=dtype,
                    source_nodata=None if nd is None else float(nd), encoding="raw",
                    grid=grid.to_json(), frame=frame.to_json(), quantizer=q.to_json(),
                    normals_derived=(list(range(grid.top_level + 1))
                                     if meta["derive_normals"] else []), valid_samples=nvalid,
                    samples=grid.rows * grid.cols, height_range=hv,
                    delta_max_finite=meta["delta_max"],
                    edge_max=meta["edge_max"] if pad else None, stand_in_z=stand_in,
                    block_delta_levels=int(blocks.shape[2])))
                stage("write")
                w.commit()
        finally:
            for arrs in (sa, se, sn):
                if arrs is not None:
                    arrs.close()
    return dst


def _level_blobs(w: StoreWriter, sa: ScratchArrays, se: ScratchArrays | None,
                 sn: ScratchArrays, grid: Grid, bounds: dict, stored: set, er: int,
                 dmax: float, emax: float, derive_normals: bool,
                 derive_bounds: bool) -> dict:
    """The δ, r, normals and δ_edge blobs and the tile rows, a tile row of each level at a
    time (preprocessing.preprocess's compress stage on each level's lattice window).
    ``dmax``, ``emax``: the largest finite δ and δ_edge, which set δ's code exponent."""
    n, t, top = grid.n, grid.t, grid.top_level
    T, T1 = grid.tile_samples, grid.tile_samples - 1
    derive_normals = derive_normals and T >= 3
    derive_bounds = derive_bounds and T >= 3 and top > 0
    ed = log8_exponent(np.array([dmax]))
    if se is not None:
        ed = max(ed, log8_exponent(np.array([emax])))
    row_keys: dict[tuple[int, int], list[int]] = {}  # (L, y) → the stored tiles' x
    for L, x, y in stored:
        row_keys.setdefault((L, y), []).append(x)
    tile_rows: dict = {}
    edge_max: list = []
    e_stored: list = []
    e_only: list = []
    for L in grid.levels:
        m = grid.tiles_per_side(L) * T1 + 1
        is_top = L == top
        for y in range(grid.tiles_per_side(L)):
            keys = sorted(row_keys.get((L, y), ()))
            p0, p1 = y * T1, y * T1 + T
            d = _lattice(sa, "", L, n, p0, p1, m, is_top, np.float32)
            rc = _lattice(sa, "r", L, n, p0, p1, m, is_top, np.uint8)
            nrm = sn.read(f"n{L}", p0, p1).reshape(T, m, 2)
            coding = BoundsCoding(d, None, ed, r_codes=(rc, er))
            edge = None
            if se is not None:
                # every vertex of the lattice: an unstored tile's δ_edge blob is whole
                edge = BoundsCoding(_lattice(se, "", L, n, p0, p1, m, True, np.float32),
                                    None, ed, r_codes=(rc, er))
            top_w = 0 if is_top else 1  # the window's level 0 is level L
            if keys:
                ring = derive_normals  # every level's normals: the border ring
                blobs, dm, rm = level_blobs(
                    coding, nrm, t, 0, top_w, [(x, 0) for x in keys],
                    ("delta", "radius") if ring else ("delta", "radius", "normals"),
                    ring=L == 0 and derive_bounds)
                if ring:
                    blobs["normals"] = ring_blobs(nrm, t, [(x, 0) for x in keys])
                for kind, b in blobs.items():
                    w.put_blobs(kind, {(L, x, y): v for (_, x, _), v in b.items()})
                for x, a, b in zip(keys, dm.tolist(), rm.tolist(), strict=True):
                    tile_rows[(L, x, y)] = (*bounds[(L, x, y)], a, b)
            if edge is None:
                continue
            # edgepad.edge_tiles / edge_only_tiles on this tile row's window
            held_diff = _held(coding.dc != edge.dc, T1, is_top)
            held_pos = _held(edge.dc > 0, T1, is_top)
            # stored tiles: new vertices as differences from δ; unstored ones: whole
            for keys_e, base, into in (([x for x in keys if held_diff[x]], coding, e_stored),
                                       ([x for x in range(len(held_pos)) if held_pos[x]
                                         and (L, x, y) not in stored], None, e_only)):
                if not keys_e:
                    continue
                eb, emx, _ = level_blobs(edge, nrm, t, 0, top_w if base is not None else 0,
                                         [(x, 0) for x in keys_e], ("delta",), base=base)
                w.put_blobs("delta_edge", {(L, x, y): v for (_, x, _), v in eb["delta"].items()})
                into += [[L, x, y, v if np.isfinite(v) else None]
                         for x, v in zip(keys_e, emx.tolist(), strict=True)]
        # the metadata's order (preprocessing.preprocess): a level's stored tiles by
        # (x, y), then its unstored ones by (y, x)
        edge_max += sorted(e_stored, key=lambda e: (e[1], e[2])) + e_only
        e_stored, e_only = [], []
    w.put_tiles(tile_rows)
    return {"delta_max": dmax, "edge_max": edge_max, "derive_normals": derive_normals}


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
