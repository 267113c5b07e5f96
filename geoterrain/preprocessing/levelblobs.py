"""Every stored tile's blobs of the whole-grid preprocess, level by level.

:func:`tile_blobs` codes the δ, r, normals and δ_edge blobs of every level
(:func:`geoterrain.bounds.tileblobs.level_blobs` on each level's tiles; a large grid's
levels on two threads, a level of :data:`SPLIT_LEVEL_TILES` tiles or more in two halves,
every part queued at once) and hands each level's rows on as they are made, in the
streamed preprocess's row order (:func:`tile_row_order`);
:class:`HeightsJob` codes a large grid's height blobs on a thread of its own
(:data:`HEIGHTS_THREAD_SAMPLES`) in the codec's tile order (:func:`pyramid_keys`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import saturate
from geoterrain.bounds.edgepad import (
    edge_deltas,
    edge_only_tiles,
    edge_support,
    edge_tiles,
    has_padding,
)
from geoterrain.bounds.leafbounds import CentreHeights, ring_guesses
from geoterrain.bounds.log8codes import log8_exponent
from geoterrain.bounds.radii import stand_in_z
from geoterrain.bounds.tileblobs import (
    BoundsCoding,
    EdgeGuess,
    OwnHeights,
    level_blobs,
    ring_blobs,
)
from geoterrain.bounds.vertexdata import shaped_zstd_level
from geoterrain.codec.pyramid import encode_pyramid
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.preprocessing.surface import Dem, Surface, VertexBounds


@dataclass
class TileBlobs:
    """Every stored tile's blobs by kind, its tile-table row, the tiles with a second δ
    (``edge_max``), and the height standing in for invalid samples
    (:func:`geoterrain.bounds.radii.stand_in_z`, the store's ``stand_in_z``)."""

    heights: dict
    extra: dict[str, dict]
    tile_rows: dict
    edge_max: list
    stand_in: float = 0.0


def tile_blobs(dem: Dem, s: Surface, b: VertexBounds, tiles: dict,
               normal_maps: list, derive_normals: bool,
               counts: list[np.ndarray] | None = None,
               on_heights: Callable[[dict], None] | None = None,
               ring_residual: bool = True,
               on_rows: Callable[[str, dict], None] | None = None,
               heights: HeightsJob | None = None) -> TileBlobs:
    """The height pyramid's blobs (the residual codec), and every tile's δ, r, normals and
    δ_edge blobs with its tile-table row.

    δ: 8-bit log codes rounded up (saturation survives: one monotone map per store); r: 8-bit log
    codes rounded up, nested on the codes. Below the top level only the vertices new at the level
    are stored; the others are the parent's (:mod:`geoterrain.bounds.vertexdata`). Padding is
    replicated from the data's edge for a second δ, the static mesh's
    (:mod:`geoterrain.bounds.edgepad`), coded with the same table as δ, so the two agree wherever
    their raw values do. ``counts``: the valid samples per tile footprint
    (:func:`geoterrain.core.grid.footprint_counts`), if known. ``on_heights``: called with the
    height blobs as soon as they are coded (the store's writer inserts them while the rest is
    coded). ``ring_residual`` (with ``derive_normals``): the normals' rings as differences from what
    a reader derives there (schema 17; False: as stored before, an edit of an older store).
    ``on_rows``: called with the δ, r, normals and δ_edge rows in the store's order
    (:func:`~geoterrain.preprocessing.levelblobs.tile_row_order`), a level's as soon as it is coded
    and the heights have been handed to ``on_heights`` (so the writer inserts them while the next
    level is coded). ``heights``: the height blobs' :class:`HeightsJob`, if started already; with
    ``counts`` of a large grid (:data:`HEIGHTS_THREAD_SAMPLES`) one is started here: the height
    codec runs on a thread of its own beside the bounds' blobs (the same bytes).
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
    edges = None if edge is None else (edge, edge_keys, edge_only)
    if valid.size < HEIGHTS_THREAD_SAMPLES:  # a small grid: level by level, in line
        for L in grid.levels:
            keys = [k for k in stored if k[0] == L]
            if keys:
                lattice = _lattice(ctx, L)
                _level_rows(ctx, L, keys, *_level_part(ctx, L, keys, lattice), extra,
                            tile_rows, edge_max, edges, pending, stored_set, hand_on)
    else:
        _pooled_levels(ctx, stored, extra, tile_rows, edge_max, edges, pending, stored_set,
                       hand_on)
    hand_on(True)
    return TileBlobs(height_blobs(), extra, tile_rows, edge_max, stand_in)


def _lattice(c: _Level, L: int) -> tuple | None:
    # the level's heights, for every part of a level with guessed r vertices
    if c.guess and 0 < L < c.grid.top_level:
        sl = np.s_[::1 << L, ::1 << L]
        return (np.ascontiguousarray(c.Z[sl]), np.ascontiguousarray(c.valid[sl]).view(np.uint8))
    return None


def _pooled_levels(c: _Level, stored: list, extra: dict, tile_rows: dict, edge_max: list,
                   edges: tuple | None, pending: list | None, stored_set: set,
                   hand_on: Callable[[bool], None]) -> None:
    # a large grid's levels on two threads: a level of many tiles in two halves (each
    # tile's blobs are its own: the same bytes), every part queued at once in level
    # order, so a thread done with its part takes the next (the next level's half)
    # rather than waiting for the other half; the rows taken level by level, in order
    pool = ThreadPoolExecutor(2, thread_name_prefix="geoterrain-blobs")
    try:
        plan = []
        for L in c.grid.levels:
            keys = [k for k in stored if k[0] == L]
            if not keys:
                continue
            lattice = _lattice(c, L)
            half = len(keys) // 2 if len(keys) >= SPLIT_LEVEL_TILES else len(keys)
            parts = [p for p in (keys[:half], keys[half:]) if p]
            plan.append((L, keys, [pool.submit(_level_part, c, L, p, lattice)
                                   for p in parts]))
        for L, keys, parts in plan:
            got = [f.result() for f in parts]
            blobs = {kind: {k: b for g in got for k, b in g[0][kind].items()}
                     for kind in got[0][0]}
            dmax, rmax = (np.concatenate([g[i] for g in got]) for i in (1, 2))
            _level_rows(c, L, keys, blobs, dmax, rmax, extra, tile_rows, edge_max, edges,
                        pending, stored_set, hand_on)
    finally:
        pool.shutdown(cancel_futures=True)


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
            # a level above 0 copied C-contiguous, as level 0 and the streaming
            # windows are: one compiled layout of the ring guess's kernel
            zl, vl = (Z, valid) if L == 0 else (np.ascontiguousarray(Z[sl]),
                                                 np.ascontiguousarray(valid[sl]))
            guess_n = ring_guesses(grid, c.frame, L, txy, zl, vl,
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
        # padding replicated (ownguess.edge_own_codes)
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
    >>> from geoterrain.core.grid import Grid, footprint_counts
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
    >>> from geoterrain.core.grid import Grid, footprint_counts
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
