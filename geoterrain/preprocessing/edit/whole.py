"""An edit recomputed over the whole grid: the preprocess's own stages on the store's
decoded heights with the patch applied, then only the rows that differ are written.

This is the edit every frame and store takes (a geographic grid's curvilinear δ and r, a
store coded in residual bins whose decoded heights depend on the pyramid, a change of the
store-wide numbers that every tile's codes depend on: δ's or r's code exponent, the
nodata stand-in height). It costs about a preprocess; :mod:`.local` gives the same rows
for an edit of a few tiles at a small fraction of that, and is tested against this one.

The stages run with the store's quantizer and the codec's predictor as the blobs record
them (a preprocess of the edited DEM may choose others: see :func:`store_predictor`), so
a lossless store's decoded heights are exactly the edited DEM's.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.bounds.delta import delta_max_finite
from geoterrain.bounds.edgepad import has_padding
from geoterrain.bounds.normalbytes import NORMAL_BITS
from geoterrain.bounds.normals import encode_octahedral, level_normal_maps
from geoterrain.bounds.radii import stand_in_z
from geoterrain.bounds.tilebounds import pack_block_errors, tile_and_block_errors
from geoterrain.bounds.vertexdata import RING
from geoterrain.codec.pyramid import blob_predictor, decoded_heights, encode_decoded
from geoterrain.codec.quantize import codes_to_heights
from geoterrain.core.progress import StageClock
from geoterrain.store.keys import unpack_blob_key
from geoterrain.store.reader import StoreReader

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Plan", "store_predictor", "whole_plan"]

_CUBIC = 8  # a height blob's flag bit: the cubic predictor (codec/pyramid/layout.py)


@dataclass
class Plan:
    """The rows an edit writes: blobs to put and to remove (``((level, x, y), kind)``),
    the tiles' rows (:data:`~geoterrain.store.catalog.TILE_COLUMNS` order: every tile's, or
    with ``all_tiles`` False those that change) and the new metadata; ``dirty``: level-0
    sample rectangles ``(r0, c0, r1, c1)`` (ends excluded) outside which no decoded
    height, δ, r or normal changed."""

    puts: dict = field(default_factory=dict)
    deletes: set = field(default_factory=set)
    tiles: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    dirty: list = field(default_factory=list)
    how: str = "whole grid"
    all_tiles: bool = True  # ``tiles`` holds every tile's row (else only those that change)


@contextmanager
def store_reader(terrain: TerrainLike) -> Iterator[StoreReader]:
    """The reader of the terrain's store: the terrain's own where it has one (its tile
    table, which each new reader unpacks first, 2-6 ms on a 4097² store, is read once),
    else a new one, closed after.

    Examples
    --------
    >>> with store_reader(t) as r:
    ...     r.get_blob((t.grid.top_level, 0, 0), "heights") is not None
    True
    """
    own = getattr(terrain, "reader", None)
    if isinstance(own, StoreReader):
        yield own
        return
    r = StoreReader(terrain.path)
    try:
        yield r
    finally:
        r.close()


def store_predictor(terrain: TerrainLike) -> str:
    """The codec's predictor the store's height blobs record: ``"cubic"`` or ``"linear"``
    (a preprocess chooses it from the DEM's entropy; an edit keeps it)."""
    g = terrain.grid
    tops = [(g.top_level, x, y) for y in range(g.roots[1]) for x in range(g.roots[0])]
    with store_reader(terrain) as r:  # the first stored root's (every root records the same)
        blob = next((b for b in (r.get_blob(k, "heights") for k in tops) if b is not None),
                    None)
    if blob is None:
        return "linear"
    return blob_predictor(blob)


def store_layout(terrain: TerrainLike) -> tuple[bool, bool]:
    """(normals derived, level-0 bounds derived): how the store keeps its normals and
    level 0's δ and r (border rings, the rest derived on read), as a preprocess was
    asked (``derive_normals``, ``derive_bounds``)."""
    g = terrain.grid
    derive_normals = bool(terrain.meta.get("normals_derived"))
    derive_bounds = False
    keys = terrain.tile_keys(0)
    if keys and g.top_level > 0:
        with store_reader(terrain) as r:
            blob = r.get_blob(keys[0], "delta")
        derive_bounds = bool(blob and len(blob) > 1 and blob[1] & RING)
    return derive_normals, derive_bounds


def whole_plan(terrain: TerrainLike, heights: np.ndarray, valid: np.ndarray,
               meta: dict) -> Plan:
    """The plan of the store holding the padded grid ``heights`` (source units, NaN where
    not ``valid``), computed by the preprocess's stages; ``meta``: the metadata to update
    (the old one). Blobs are compared with the store's: only those that differ are put.

    On a root grid ``heights`` is level 0's lattice (:attr:`Grid.shape`, as
    :meth:`~geoterrain.terrain.Terrain.level_heights` gives it) or the roots' extent; the
    stages run on the extent, as the whole-grid preprocess's do."""
    from geoterrain.preprocessing.levelblobs import tile_blobs
    from geoterrain.preprocessing.surface import Dem, Surface, vertex_bounds

    g, frame, q = terrain.grid, terrain.frame, terrain.quantizer
    pred = store_predictor(terrain)
    derive_normals, derive_bounds = store_layout(terrain)
    if not g.square and heights.shape != g.extent:  # the lattice: invalid to the extent
        h, v = heights, valid
        heights, valid = np.full(g.extent, np.nan), np.zeros(g.extent, bool)
        heights[:h.shape[0], :h.shape[1]] = h
        valid[:v.shape[0], :v.shape[1]] = v
    X, Y = frame.grid_xy(g.whole_shape)
    height_blobs = None
    if q.bins > 1:  # residual bins: decoded heights come out of the pyramid's coding
        height_blobs, codes = encode_decoded(heights, valid, g.t, q, predictor=pred,
                                             roots=g.codec_roots)
        height_blobs = g.held(height_blobs)
        Z = codes_to_heights(codes, q)
        del codes
        Z[~valid] = np.nan
    else:
        Z = decoded_heights(heights, valid, q)
    if valid.any():
        hv = Z[valid]
        height_range = [float(hv.min()), float(hv.max())]
        del hv
    else:
        height_range = list(meta["height_range"])
    Z = frame.z(Z, out=Z)
    s = Surface(heights, valid, X, Y, Z, q, height_range, height_blobs, pred)
    dem = Dem(None, frame, g, int(np.count_nonzero(valid)))
    clock = StageClock(("errors", "radii"), None)
    bounds = vertex_bounds(dem, s, derive_bounds and g.tile_samples >= 3 and g.top_level > 0,
                           clock)
    tiles, blocks = tile_and_block_errors(Z, valid, X, Y, g.t, span=g.span, fields=bounds.fields)
    bounds.fields = None
    across, down = g.tiles(0)
    blocks = blocks[:down, :across]  # a root grid's extent holds more than its tiles
    normal_maps = [encode_octahedral(n, NORMAL_BITS) for n in level_normal_maps(
        X, Y, Z, valid, g.top_level + 1)]
    derive_normals = derive_normals and g.tile_samples >= 3
    blobs = tile_blobs(dem, s, bounds, tiles, normal_maps, derive_normals,
                       ring_residual=meta.get("normals_ring_residual") is True)
    new: dict = {}
    for key, b in blobs.heights.items():
        new[(key, "heights")] = b
    for kind, bb in blobs.extra.items():
        for key, b in bb.items():
            new[(key, kind)] = b
    new[((g.top_level, 0, 0), "block_delta")] = pack_block_errors(blocks)

    m = dict(meta)
    m.update(valid_samples=int(np.count_nonzero(valid)),
             nodata_fraction=float(1.0 - np.count_nonzero(valid) / (g.rows * g.cols)),
             height_range=height_range, delta_max_finite=delta_max_finite(bounds.delta),
             stand_in_z=stand_in_z(Z, valid),
             normals_derived=list(range(g.top_level + 1)) if derive_normals else [])
    if not derive_normals:
        m.pop("normals_derived")
    if has_padding(g):
        m["delta_edge"] = blobs.edge_max
    plan = diff_blobs(terrain, new)
    plan.tiles = blobs.tile_rows
    plan.meta = m
    return plan


def diff_blobs(terrain: TerrainLike, new: dict) -> Plan:
    """A plan putting the blobs of ``new`` that differ from the store's and removing the
    store's blobs that ``new`` lacks; ``dirty``: the footprints of the tiles touched."""
    r = StoreReader(terrain.path)
    try:
        table = r.table()
        old_keys = {unpack_blob_key(int(k)) for k in table.blobs}
        puts = {}
        for bk, data in new.items():
            if bk not in old_keys or r.get_blob(*bk) != data:
                puts[bk] = data
    finally:
        r.close()
    deletes = old_keys - set(new)
    g = terrain.grid
    touched = {k for k, _ in puts} | {k for k, _ in deletes}
    dirty = []
    for L, x, y in sorted(touched):
        span = g.tile_span(L)
        dirty.append((y * span, x * span, y * span + span + 1, x * span + span + 1))
    return Plan(puts, deletes, {}, {}, dirty)
