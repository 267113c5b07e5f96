"""The preprocess pipeline: DEM → padded pyramid → errors, normals, codec → store.

Stages (timed; the times go into the store's metadata):
read → pad → quantise → errors → radii → tile bounds → normals → compress → write.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
from numba import njit

from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import saturate, vertex_errors
from geoterrain.bounds.edgepad import (
    edge_deltas,
    edge_only_tiles,
    edge_support,
    edge_tiles,
    has_padding,
)
from geoterrain.bounds.leafbounds import geographic_leaf_delta
from geoterrain.bounds.normals import encode_octahedral, level_normal_maps
from geoterrain.bounds.radii import stand_in_z, valid_range, vertex_radii
from geoterrain.bounds.tileblobs import BoundsCoding, level_blobs, radius_codes, ring_blobs
from geoterrain.bounds.tilebounds import tile_and_block_errors
from geoterrain.bounds.vertexdata import (
    NORMAL_BITS,
    log8_exponent,
    pack_block_errors,
    store_metadata,
)
from geoterrain.codec.pyramid import decoded_heights, encode_decoded, encode_pyramid
from geoterrain.codec.quantchoice import choose_quantizer
from geoterrain.codec.quantize import codes_to_heights
from geoterrain.core.atomicfiles import remove_stale_partials
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.core.memory import available_memory
from geoterrain.core.progress import Progress, StageClock
from geoterrain.exceptions import InputError, UsageError, exists_error
from geoterrain.ingest.mosaic import is_glob, mosaic_name, source_files
from geoterrain.ingest.raster import ABSURD_HEIGHT, Raster, read_raster
from geoterrain.ingest.units import parse_tile, resolve_z_units, tile_from_path, tile_georeference
from geoterrain.preprocessing.schedulers import parse_scheduler
from geoterrain.preprocessing.streaming import preprocess_streaming, streaming_band
from geoterrain.store.database import StoreWriter, default_store_path

log = logging.getLogger("geoterrain")
STAGES = ("read", "pad", "quantise", "errors", "radii", "tile bounds", "normals", "compress",
          "write")
MAX_TILE_SIZE = 4096


@njit(cache=True, nogil=True)
def _finite_max_nb(a):
    m = 0.0
    for v in a.ravel():
        if np.isfinite(v) and v > m:
            m = v
    return m


def _finite_max(a: np.ndarray) -> float:
    """max(0, the largest finite value of ``a``) without copying the finite values."""
    return float(_finite_max_nb(a))  # a float32 value is exact in float64


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
        Bytes the job may hold (default: half the memory available now). A raster whose
        whole-grid preprocess would need more is read a window at a time
        (:func:`geoterrain.preprocessing.streaming.preprocess_streaming`, the same store), with
        bands
        sized to the limit: a single-band raster in a projected or pixel frame. Others
        are refused in one line when they do not fit.
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

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 33, seed=1))
    >>> preprocess(dem).name
    'dem.geoterrain'
    """
    stage = StageClock(STAGES, progress)
    times = stage.times

    if codec_error is not None and not (np.isfinite(codec_error) and codec_error >= 0):
        raise UsageError(f"codec_error must be a finite number ≥ 0, got {codec_error}",
                         cli=f"--codec-error must be a finite number ≥ 0, got {codec_error}")
    if pixel_size is not None and not (np.isfinite(pixel_size) and pixel_size > 0):
        raise UsageError(f"pixel_size must be a finite number > 0, got {pixel_size}",
                         cli=f"--pixel-size must be a finite number > 0, got {pixel_size}")
    if not (isinstance(tile_size, int) and 2 <= tile_size <= MAX_TILE_SIZE
            and tile_size & (tile_size - 1) == 0):
        raise UsageError(f"tile_size must be a power of two in [2, {MAX_TILE_SIZE}], "
                         f"got {tile_size}", cli=f"--tile-size must be a power of two in "
                         f"[2, {MAX_TILE_SIZE}], got {tile_size}")
    parse_scheduler(scheduler)  # a bad spec is a usage error before any work
    files = source_files(src)
    mosaic = isinstance(src, (list, tuple)) or is_glob(src)
    if dst is None and mosaic:
        raise UsageError("a mosaic (list of files or glob) has no default store name; "
                         "pass dst", cli="a mosaic (several files or a glob) has no default "
                         "store name; pass -o STORE")
    dst = Path(dst) if dst is not None else default_store_path(src)
    if not resume:  # a killed streaming run's scratch stays for resume to take up
        remove_stale_partials(dst.parent if str(dst.parent) else Path("."))
    if dst.exists() and not overwrite:
        raise exists_error(dst)
    if any(f.resolve() == dst.resolve() for f in files):
        raise UsageError(f"{dst}: the store would overwrite its own input; choose another dst",
                         cli=f"{dst}: the store would overwrite its own input; choose another -o")

    if (not mosaic and tile is None and pixel_size is None and encoding in ("auto", "raw")
            and band in (None, 1)):
        limit = available_memory() // 2 if memory_limit is None else int(memory_limit)
        rows = streaming_band(files[0], limit)
        if rows is not None:  # too large for the whole grid: a window at a time
            return preprocess_streaming(
                files[0], dst, tile_size=tile_size, z_scale=z_scale, z_units=z_units,
                codec_error=codec_error, overwrite=overwrite,
                nodata=nodata, band=rows, derive_normals=derive_normals,
                derive_bounds=derive_bounds, scheduler=scheduler, resume=resume,
                progress=progress)
    r = read_raster(files if mosaic else src, band=band, encoding=encoding, nodata=nodata)
    validate(r, z_scale)
    zxy = parse_tile(tile) if tile is not None else None
    if zxy is not None and (pixel_size is not None or r.crs_wkt is not None):
        raise UsageError("a web-map tile is placed by its z/x/y; give tile or pixel_size, not "
                         "both", cli="give --tile or --pixel-size, not both")
    if zxy is None and r.crs_wkt is None and pixel_size is None and not mosaic:
        zxy = tile_from_path(src)
    if zxy is not None:
        r.transform, r.crs_wkt = tile_georeference(*zxy, r.shape[1], r.shape[0])
        log.info("%s: web-map tile %d/%d/%d in EPSG:3857", src, *zxy)
    z_units = resolve_z_units(z_units, r.crs_wkt, r.path)
    frame = Frame.from_raster(r.transform, r.crs_wkt, r.shape[0], r.shape[1],
                              pixel_size=pixel_size, z_units=z_units,
                              z_scale=1.0 if z_scale is None else z_scale)
    if r.crs_wkt is None and pixel_size is None:
        log.warning("%s has no CRS: using 1 m per pixel; set pixel_size (--pixel-size)", src)
    grid = Grid.for_shape(*r.shape, tile_size=tile_size)
    stage("read")

    valid = grid.pad(r.valid, False)
    heights = grid.pad(r.heights, np.nan)
    heights[~valid] = np.nan
    r.heights = None  # the padded copy holds them now (memory: issue 12)
    nvalid = int(np.count_nonzero(r.valid))
    X, Y = frame.grid_xy(grid.size)
    stage("pad")

    # the valid heights: NaN elsewhere, which the quantiser ignores
    q = choose_quantizer(heights, r.src_dtype, codec_error=codec_error, scale=r.scale,
                         offset=r.offset)
    height_blobs = None
    if q.bins > 1:  # residual bins: the heights depend on the pyramid, coded here once
        height_blobs, codes = encode_decoded(heights, valid, grid.t, q)
        Z = codes_to_heights(codes, q)
        del codes
        Z[~valid] = np.nan
    else:
        Z = decoded_heights(heights, valid, q)  # NaN where invalid
    # every level's normals and level 0's δ derived on read in every frame (a geographic
    # tile's with bilinear x, y and a slack: leafbounds.normal_xy, geographic_leaf_delta);
    # level 0's r only in an affine frame (a geographic one's needs pyproj's x, y of
    # every sample)
    derive_normals = bool(derive_normals) and grid.tile_samples >= 3
    derive_bounds = bool(derive_bounds) and grid.tile_samples >= 3 and grid.top_level > 0
    hv = Z[valid]
    height_range = [float(hv.min()), float(hv.max())]
    del hv
    Z = frame.z(Z, out=Z)  # scene metres, in place
    stage("quantise")

    delta = vertex_errors(Z, valid)
    stage("errors")
    terms = radius = None
    if frame.kind == "geographic":  # curvilinear grid: δ and r that hold in scene x/y
        radius = vertex_radii(X, Y, Z, valid)
        terms = metric_terms(X, Y, Z, valid)
        delta, radius = metric_bounds(delta, radius, X, Y, Z, valid, terms=terms)
    slack = delta_before = None
    ring_kinds: tuple[str, ...] = ("delta", "radius") if derive_bounds else ()
    if derive_bounds and frame.kind == "geographic":
        # level 0's δ as a reader derives it: the closed forms + a per-tile slack for the
        # metric term (δ only: r would need pyproj's x, y of every sample)
        delta_before = delta.copy() if has_padding(grid) else None
        slack = geographic_leaf_delta(delta, Z, valid, grid.t, terms[0], terms[2])
        ring_kinds = ("delta",) if slack is not None else ()
    # nested radii (seed 002 §2.4, L50–52) as the 8-bit log codes they are stored as,
    # nested on the coded values (a projected frame needs no radii before: r = nesting)
    r_codes = radius_codes(X, Y, Z, valid, radius)
    del radius
    stage("radii")
    # per-tile bounds, and every GeoMipMapping block's exact δ_n (seed 000 §2.4)
    bounds, blocks = tile_and_block_errors(Z, valid, X, Y, grid.t)
    stage("tile bounds")
    # one map per level, central differences of the level's own samples (seed 000
    # normal-map lighting): a reader rebuilds each tile's from its heights and ring
    nrm_levels = [encode_octahedral(n, NORMAL_BITS)
                  for n in level_normal_maps(X, Y, Z, valid, grid.top_level + 1)]
    stage("normals")

    if height_blobs is None:
        height_blobs = encode_pyramid(heights, valid, grid.t, q)
    # δ: 8-bit log codes rounded up (saturation survives: one monotone map per store);
    # r: 8-bit log codes rounded up, nested on the codes. Below the top level only the
    # vertices new at the level are stored; the others are the parent's (vertexdata.py).
    # padding by edge replication: a second δ for the static mesh (geoterrain/bounds/edgepad.py),
    # coded with the same table as δ, so the two agree wherever their raw values do
    edge = d_edge = None
    if has_padding(grid):
        Zr, ok = edge_support(Z, valid, grid)
        d_edge = edge_deltas(Zr, ok, grid)
        if frame.kind == "geographic":  # only where a padding sample is read: the rest
            win = (grid.rows, grid.cols)  # is the original grid's terms
            et = metric_terms(X, Y, Zr, ok, window=win, base=terms)
            d_edge, _ = metric_bounds(d_edge, None, X, Y, Zr, ok, window=win, terms=et)
            del et
            if slack is not None:  # where δ_edge was δ it follows δ's raise, nested again
                same = d_edge == delta_before
                d_edge[same] = delta[same]
                saturate(d_edge)
        del Zr, ok
    del terms, delta_before
    ed = None if d_edge is None else max(log8_exponent(delta), log8_exponent(d_edge))
    coding = BoundsCoding(delta, None, ed, r_codes=r_codes)
    if d_edge is not None:
        edge = BoundsCoding(d_edge, None, ed, r_codes=r_codes)
        del d_edge
        # one table, so comparing codes compares the stored values
        edge_keys = edge_tiles(coding.dc, edge.dc, grid, sorted(height_blobs))
        # unstored tiles holding a vertex the static mesh may need: a whole δ_edge tile
        edge_only = edge_only_tiles(edge.dc, grid, set(height_blobs))
    del r_codes
    tile_rows: dict = {}
    extra: dict[str, dict] = {"delta": {}, "radius": {}, "normals": {}, "delta_edge": {}}
    edge_max: list = []
    for L in grid.levels:
        keys = [k for k in height_blobs if k[0] == L]
        if not keys:
            continue
        # every level's rings: the rest is derived from the heights on read
        normals_ring = derive_normals
        blobs, dmax, rmax = level_blobs(coding, nrm_levels[L], grid.t, L, grid.top_level,
                                        [(x, y) for _, x, y in keys],
                                        ("delta", "radius") if normals_ring else
                                        ("delta", "radius", "normals"),
                                        ring=ring_kinds if L == 0 else False,
                                        slack=slack if L == 0 else None)
        if normals_ring:
            blobs["normals"] = ring_blobs(nrm_levels[L], grid.t, [(x, y) for _, x, y in keys],
                                          L)
        for kind, b in blobs.items():
            extra[kind].update(b)
        # per-tile max δ and r (of the values as stored, over the vertices new at this
        # level) let a view skip a tile without decoding it
        for key, dm, rm in zip(keys, dmax.tolist(), rmax.tolist(), strict=True):
            tile_rows[key] = (*bounds[key], dm, rm)
        # the second δ: new vertices over the parent's on stored tiles, whole tiles on
        # the unstored ones (nothing else there to read a parent from)
        # (the stored tiles' as differences from their δ codes: zero but near the padding)
        for keys_e, top, base in ([] if edge is None else
                                  [(edge_keys, grid.top_level, coding), (edge_only, L, None)]):
            ekeys = [(x, y) for L2, x, y in keys_e if L2 == L]
            if not ekeys:
                continue
            eb, emax, _ = level_blobs(edge, nrm_levels[L], grid.t, L, top, ekeys, ("delta",),
                                      base=base)
            extra["delta_edge"].update(eb["delta"])
            edge_max += [[L, x, y, m if np.isfinite(m) else None]
                         for (x, y), m in zip(ekeys, emax.tolist(), strict=True)]
    del coding, nrm_levels, edge
    stage("compress")

    with StoreWriter(dst, overwrite=overwrite) as w:
        w.put_blobs("heights", height_blobs)
        for kind, blobs in extra.items():
            w.put_blobs(kind, blobs)
        w.put_blobs("block_delta", {(grid.top_level, 0, 0): pack_block_errors(blocks)})
        w.put_tiles(tile_rows)
        w.put_metadata(store_metadata(
            source=mosaic_name(files), source_dtype=r.src_dtype, source_nodata=r.nodata,
            encoding=r.encoding, grid=grid.to_json(), frame=frame.to_json(),
            quantizer=q.to_json(),
            normals_derived=list(range(grid.top_level + 1)) if derive_normals else [],
            valid_samples=nvalid, samples=r.valid.size, height_range=height_range,
            delta_max_finite=_finite_max(delta),
            edge_max=edge_max if has_padding(grid) else None, stand_in_z=stand_in_z(Z, valid),
            block_delta_levels=int(blocks.shape[2]), times=times))
        stage("write")
        times["write"] = times.get("write", 0.0)
        w.commit()
    return dst


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
    return cache / f"{dem.stem}-{digest}.geoterrain"


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
