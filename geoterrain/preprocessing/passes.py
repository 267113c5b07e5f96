"""The streaming preprocess's passes (:mod:`geoterrain.preprocessing.streaming`) as scheduler tasks,
and the records that let a killed run be resumed.

After the scan and the quantizer, four passes over the raster are independent: δ with
δ_edge and the radius codes, the tile table, the normals, and the height blobs. With
residual bins (a lossy store, :attr:`geoterrain.codec.quantize.Quantizer.bins`) the decoded
heights depend on the pyramid: the height pass then runs first and writes them to the
scratch arrays of ``decoded/``, which the other three read instead of the raster. Each is
a module-level function of a picklable :class:`Job` (the raster's path and every
setting), opens the raster itself, and writes into its own folder of the job's scratch
folder (:meth:`geoterrain.preprocessing.scratch.ScratchArrays.shared`), so any scheduler
(:mod:`geoterrain.preprocessing.schedulers`) can run it. When a pass ends its result is recorded
there
as plain data (JSON and ``.npz``, no pickle), which ``--resume`` reads back.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import struct
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np

from geoterrain._version import __version__
from geoterrain.bounds.normalbytes import NORMAL_BITS
from geoterrain.bounds.tilebounds import TileTable
from geoterrain.codec.quantize import Quantizer, codes_to_heights, roundtrip
from geoterrain.core.atomicfiles import pid_alive
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.core.memory import release_free_heap
from geoterrain.exceptions import InputError
from geoterrain.ingest.windows import RasterSpec, WindowReader
from geoterrain.preprocessing.bands.codec import band_encode_pyramid
from geoterrain.preprocessing.bands.curvature import band_metric_terms
from geoterrain.preprocessing.bands.delta import (
    _saturate,
    band_vertex_errors,
    copy_levels,
    edge_rows,
    raise_delta,
)
from geoterrain.preprocessing.bands.leaf import band_leaf_slack, follow_slack
from geoterrain.preprocessing.bands.normals import band_normal_codes
from geoterrain.preprocessing.bands.radii import band_metric_radius_codes, band_radius_codes
from geoterrain.preprocessing.bands.tiles import band_tile_bounds
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["PASSES", "RECORDED", "Job", "Source", "adopt", "heights_records", "job_record",
           "pass_result", "run_pass"]


def whole(grid: Grid) -> int | tuple[int, int]:
    """The grid every pass computes on: the square's side N, or a root grid's extent
    (rows, cols) (:attr:`geoterrain.core.grid.Grid.extent`), as the whole-grid
    preprocess pads it (:func:`geoterrain.preprocessing.surface.pad`).

    Examples
    --------
    >>> whole(Grid.for_shape(65, 65)), whole(Grid.for_shape(65, 129, 16, roots=True))
    (65, (65, 129))
    """
    return grid.size if grid.square else grid.extent


def root_span(grid: Grid) -> int | None:
    """A root grid's root side (:attr:`geoterrain.core.grid.Grid.span`); None: the square."""
    return grid.span


class Source:
    """Rows of the padded (N, N) grid (a root grid: its (R, C) extent) from a raster
    source (:mod:`geoterrain.ingest.windows`): source heights (float64, NaN where
    invalid) and validity, north up, the padding invalid."""

    def __init__(self, ds, grid: Grid, spec: RasterSpec) -> None:
        self.reader = WindowReader(ds, spec)
        self.grid, self.spec = grid, spec
        self.H, self.W = grid.rows, grid.cols
        self.R, self.C = grid.extent

    def file_rows(self, i0: int, i1: int, j0: int = 0, j1: int | None = None) -> np.ndarray:
        """The raw band's rows i0 … i1 − 1 and columns j0 … j1 − 1 (north up), the
        file's dtype (a raw raster)."""
        return self.reader.raw(i0, i1, j0, j1)

    def rows(self, i0: int, i1: int, j0: int = 0, j1: int | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        j1 = self.C if j1 is None else j1
        z = np.full((i1 - i0, j1 - j0), np.nan)
        v = np.zeros(z.shape, bool)
        r1 = min(i1, self.H)
        c1 = min(j1, self.W)
        if r1 > i0 and c1 > j0:
            h, ok = self.reader.heights(i0, r1, j0, c1)
            z[:r1 - i0, :c1 - j0] = h
            v[:r1 - i0, :c1 - j0] = ok
        return z, v

    def bands(self, band: int):
        return (self.rows(i, min(i + band, self.R))[0] for i in range(0, self.R, band))


@dataclasses.dataclass(frozen=True)
class Job:
    """What a pass needs (picklable: a scheduler ships it to its worker): the source and
    how its pixels become heights (``spec``, with the nodata the scan settled), the grid,
    the scene frame, the quantizer, rows per band, the scratch folder, whether the grid
    has padding, and whether level 0's bounds are derived on read (a geographic store's
    δ slack)."""

    spec: RasterSpec
    grid: dict
    frame: dict
    q: Quantizer
    band: int
    folder: str
    pad: bool
    derive_bounds: bool = True

    @property
    def geographic(self) -> bool:
        return self.frame["kind"] == "geographic"

    @contextlib.contextmanager
    def opened(self) -> Iterator[Opened]:
        """The source opened in this process, with the grid's scene rows and x, y
        (:class:`Opened`)."""
        grid = Grid(**self.grid)
        frame = Frame.from_json(self.frame)
        with self.spec.open(cache=STREAM_GDAL_CACHE) as ds:
            source = Source(ds, grid, self.spec)
            decoded: list[ScratchArrays] = []  # the height pass's, opened at the first read
            xyz: list[ScratchArrays] = []  # the xy pass's, opened at the first read

            def scene(i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
                z, v = source.rows(i0, i1)
                if self.q.bins == 1:
                    return frame.z(roundtrip(z, v, self.q)), v  # decoded, scene metres
                del z  # only the mask: the heights are the height pass's (in place below)
                if not decoded:
                    decoded.append(ScratchArrays.shared(os.path.join(self.folder, DECODED)))
                h = decoded[0].read("h", i0, i1)
                h[~v] = np.nan
                return frame.z(h, out=h), v

            def xy(i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
                if not xyz:
                    xyz.append(ScratchArrays.shared(os.path.join(self.folder, XY)))
                return xyz[0].read("X", i0, i1), xyz[0].read("Y", i0, i1)

            if self.geographic:  # x, y depend on row and column: xy()
                xs, ys = np.zeros(source.C), np.zeros(source.R)
            else:
                X, Y = frame.grid_xy(whole(grid))
                xs, ys = np.ascontiguousarray(X[0]), np.ascontiguousarray(Y[:, 0])
            try:
                yield Opened(source, scene, grid, xs, ys, xy if self.geographic else None,
                             frame)
            finally:
                for a in decoded + xyz:
                    a.close()


class Opened(NamedTuple):
    """A pass's view of its source: the padded grid's rows (``source``), their decoded
    scene heights and validity (``scene(i0, i1)``), the grid, scene x of each column and y
    of each row (a projected or pixel frame) or ``xy(i0, i1)`` → the rows' scene X, Y (a
    geographic one, from the xy pass's scratch arrays; None otherwise), and the frame."""

    source: Source
    scene: Callable
    grid: Grid
    xs: np.ndarray
    ys: np.ndarray
    xy: Callable | None
    frame: Frame


def _xy_pass(job: Job) -> None:
    # a geographic grid's scene X, Y (pyproj), every row of the grid (the square, or a
    # root grid's extent), into scratch arrays the other passes read (Frame.grid_xy's
    # values, a band at a time)
    grid = Grid(**job.grid)
    frame = Frame.from_json(job.frame)
    R, C = grid.extent
    sx = ScratchArrays.shared(os.path.join(job.folder, XY))
    try:
        sx.create("X", (R, C), np.float64)
        sx.create("Y", (R, C), np.float64)
        cols = np.arange(C)[None, :]
        for i0 in range(0, R, job.band):
            # a column of rows against a row of columns: frame.xy broadcasts them (the
            # values of every (i, j) pair, without two band-sized index arrays)
            X, Y = frame.xy(np.arange(i0, min(i0 + job.band, R))[:, None], cols)
            if not (np.isfinite(X).all() and np.isfinite(Y).all()):
                raise InputError(f"{job.spec.label}: pyproj gives no scene position for some "
                                 "samples of the padded grid; crop the raster (gdal_translate "
                                 "-projwin) or reproject it")
            sx.write("X", i0, X)
            sx.write("Y", i0, Y)
            X = Y = None  # before the next band's are made
    finally:
        sx.close()


def _bounds_pass(job: Job) -> tuple:
    # δ with each level's vertex heights, δ_edge, and the radius codes nested on them:
    # (valid range, stand-in height, r's exponent, largest finite δ and δ_edge, and a
    # geographic grid's level-0 slack)
    with job.opened() as o:
        grid, scene, N = o.grid, o.scene, whole(o.grid)
        span = root_span(grid)
        sa = ScratchArrays.shared(os.path.join(job.folder, "bounds"))
        lvl = band_vertex_errors(scene, N, band=job.band, scratch=sa, heights=True, span=span)
        dmax, emax, slack = lvl.max_finite, 0.0, None
        n = grid.n
        data = (grid.rows, grid.cols)
        if job.geographic:  # curvilinear: δ and r that hold in scene x, y (bounds.curvature)
            terms = band_metric_terms(scene, o.xy, N, job.band, sa, span=span,
                                      empty_from=grid.rows)  # the rows below: padding
            dmax = raise_delta(sa, n)
            er = band_metric_radius_codes(sa, N, o.xy, span=span)
            if job.derive_bounds and grid.tile_samples >= 3 and grid.top_level > 0:
                if job.pad:  # what δ_edge follows below
                    copy_levels(sa, n, "", "db")
                slack = band_leaf_slack(sa, N, grid.t, scene, empty_from=grid.rows)
                if slack is not None:
                    dmax = _saturate(sa, n, SATURATE_BUDGET)
        else:
            er = band_radius_codes(sa, N, o.xs, o.ys, *lvl.valid_range[:2], span=span)
        if job.pad:
            se = ScratchArrays.shared(os.path.join(job.folder, "edge"))
            rows = edge_rows(scene, data)
            emax = band_vertex_errors(rows, N, band=job.band, scratch=se, data=data,
                                      span=span).max_finite
            if job.geographic:  # only where a padding sample is read (bounds.curvature)
                band_metric_terms(rows, o.xy, N, job.band, se, pre="e", window=data,
                                  base=terms, span=span)
                emax = raise_delta(se, n, terms="e")
                if slack is not None:  # where δ_edge was δ it follows δ's raise, nested again
                    follow_slack(se, sa, n)
                    emax = _saturate(se, n, SATURATE_BUDGET)
            se.close()
        sa.close()
        return (lvl.valid_range, lvl.stand_in, er, dmax, emax,
                None if slack is None else [[x, y, s] for (_, x, y), s in sorted(slack.items())])


SATURATE_BUDGET = 16 << 20  # bytes of rows a saturation reads at a time


def _tiles_pass(job: Job) -> tuple:
    with job.opened() as o:
        # the tiles as arrays (TileTable): a dict of named tuples held until the store's
        # writing cost 438 bytes a tile (16385²: 87 381 tiles, 36.5 MB traced)
        return band_tile_bounds(o.scene, whole(o.grid), o.grid.t, o.xs, o.ys, band=job.band,
                                xy=o.xy, span=root_span(o.grid), table=True)


def _normals_pass(job: Job) -> None:
    with job.opened() as o:
        sn = ScratchArrays.shared(os.path.join(job.folder, "normals"))
        band_normal_codes(o.scene, whole(o.grid), o.xs, o.ys, o.grid.top_level + 1, sn,
                          band=job.band, bits=NORMAL_BITS, xy=o.xy,
                          t=o.grid.t if o.grid.tile_samples >= 3 else None)
        sn.close()


_RECORD = struct.Struct("<iiiI")  # a height blob's record: L, x, y, length


def _heights_pass(job: Job) -> dict:
    # the height blobs into a scratch file of records, as they are made; with residual
    # bins, the decoded heights too (DECODED, row-major float64) and their range
    with job.opened() as o, open(os.path.join(job.folder, "heights.bin"), "wb") as fh:
        source, grid = o.source, o.grid
        roots = None if grid.square else grid.roots
        count = [0]
        span = [np.inf, -np.inf]

        def sink(part: dict) -> None:
            for key, b in part.items():
                fh.write(_RECORD.pack(*key, len(b)) + b)
            count[0] += len(part)

        if job.q.bins == 1:
            band_encode_pyramid(source.rows, whole(grid), grid.t, job.q, sink=sink,
                                coarse_max=COARSE_MAX, roots=roots)
            return {"blobs": count[0], "range": None}
        sa = ScratchArrays.shared(os.path.join(job.folder, DECODED))
        try:
            sa.create("h", grid.extent, np.float64)

            def decoded(i0: int, j0: int, codes: np.ndarray, valid: np.ndarray) -> None:
                h = codes_to_heights(codes, job.q)
                span[:] = (min(span[0], float(np.min(h, where=valid, initial=np.inf))),
                           max(span[1], float(np.max(h, where=valid, initial=-np.inf))))
                sa.write("h", i0, h, c0=j0)

            band_encode_pyramid(source.rows, whole(grid), grid.t, job.q, sink=sink,
                                decoded=decoded, coarse_max=COARSE_MAX, roots=roots)
        finally:
            sa.close()
        return {"blobs": count[0], "range": span}


def heights_records(path: str, batch: int = 4096) -> Iterator[dict]:
    """The height blobs of :func:`_heights_pass`'s file, ``batch`` at a time."""
    with open(path, "rb") as fh:
        part: dict = {}
        while head := fh.read(_RECORD.size):
            L, x, y, n = _RECORD.unpack(head)
            part[(L, x, y)] = fh.read(n)
            if len(part) >= batch:
                yield part
                part = {}
        if part:
            yield part


def _save_done(path: str, out) -> None:
    # a finished pass's result, as plain data (a resumed run reads no pickle)
    if isinstance(out, tuple) and len(out) == 2 and isinstance(out[0], TileTable):  # tiles
        payload = {"kind": "tiles"}
        np.savez(path + ".npz", keys=out[0].keys, rows=out[0].rows, blocks=out[1])
    else:
        payload = {"kind": "value", "value": out}
    tmp = f"{path}.{os.getpid()}"
    with open(tmp, "w") as fh:
        json.dump(payload, fh)
    os.replace(tmp, path)


def _load_done(path: str):
    with open(path) as fh:
        payload = json.load(fh)
    if payload["kind"] == "tiles":
        with np.load(path + ".npz", allow_pickle=False) as z:
            return TileTable(z["keys"], z["rows"]), z["blocks"]
    v = payload["value"]
    return (tuple(v[0]), *v[1:]) if isinstance(v, list) else v


# GDAL's block cache while the streaming preprocess reads the raster in bands:
# GDAL_READ_OPTIONS' 64 MB held a whole 4097 × 2049 float32 mosaic's blocks (50 MB, its
# VRT's too), memory that grew with the raster; a band's rows reuse few blocks (that
# mosaic, a sweep of 256-row bands with a 128-row halo: 0.59 s with 64 MB, 0.69 s with
# 16, 0.92 s with 8; the 1025 × 513 one, read in one window, keeps none there;
# docs/lab/streaming.md)
STREAM_GDAL_CACHE = 8 << 20
PASSES = {"bounds": _bounds_pass, "tiles": _tiles_pass, "normals": _normals_pass,
          "heights": _heights_pass, "xy": _xy_pass}
DECODED = "decoded"  # the decoded heights with residual bins (scratch arrays, by the height pass)
XY = "xy"  # a geographic grid's scene x, y (scratch arrays, by the xy pass)
COARSE_MAX = 1025  # the height pass's coarse grid side (bandcodec.super_level)


# passes whose result run_pass leaves in its record (None returned): the tile table, which
# grows with the raster (16385²: 8.4 MB), is read back by pass_result once every pass has
# run, not held through the normals and height passes (docs/lab/streaming.md)
RECORDED = frozenset({"tiles"})


def run_pass(job: Job, name: str):
    """Run pass ``name``, or read its result if a resumed run's folder has it; the
    result is recorded when the pass ends (``done-NAME``). A pass of :data:`RECORDED`
    returns None: its result is :func:`pass_result`'s."""
    done = os.path.join(job.folder, f"done-{name}")
    if os.path.exists(done):
        return None if name in RECORDED else _load_done(done)
    out = PASSES[name](job)
    _save_done(done, out)
    if name in RECORDED:
        out = None
    release_free_heap()  # what the pass freed, before the next one (docs/lab/streaming.md)
    return out


def pass_result(job: Job, name: str):
    """The recorded result of pass ``name`` (run by :func:`run_pass`)."""
    return _load_done(os.path.join(job.folder, f"done-{name}"))


# what the passes write to the scratch folder; a killed run's folder from code that wrote
# another format is not resumed (2: each level's normal map from the level's own samples;
# 3: the height pass's result a dict, and with residual bins the decoded heights first;
# 4: any source (a raster spec), geographic grids with their xy pass)
SCRATCH_FORMAT = 4


def job_record(job: Job) -> dict:
    # what a resumed run must share with the killed one: the input files, every setting and
    # the scratch format
    files = []
    for f in job.spec.files:
        st = os.stat(f)
        files.append([f, st.st_size, st.st_mtime_ns])
    d = dataclasses.asdict(job)
    d.pop("folder")
    d["q"] = dataclasses.asdict(job.q)
    return json.loads(json.dumps({"files": files, "job": d, "generator": __version__,
                                  "scratch_format": SCRATCH_FORMAT}))


def adopt(parent: Path, dst: Path, record: dict) -> str | None:
    """A killed run's scratch folder for ``dst`` with the same job record, renamed to this
    process (its passes' results are reused), or None."""
    pat = re.compile(rf"^\.{re.escape(dst.name)}\.scratch\.partial-(\d+)$")
    for e in os.scandir(parent):
        m = pat.match(e.name)
        if not m or pid_alive(int(m.group(1))) or e.stat().st_uid != os.getuid():
            continue
        try:
            with open(os.path.join(e.path, "job.json")) as fh:
                same = json.load(fh) == record
        except (OSError, ValueError):
            same = False
        if same:
            mine = str(parent / f".{dst.name}.scratch.partial-{os.getpid()}")
            os.rename(e.path, mine)
            return mine
    return None
