"""What a preprocess writes into its store, and in what order.

:func:`store_metadata`: the metadata a preprocess writes (the whole-grid one and the
streaming one); :func:`write_store` / :func:`write_rows`: a whole grid's blobs, tile
table and metadata into a store, the blob rows in the streamed preprocess' order
(:func:`~geoterrain.preprocessing.levelblobs.tile_row_order`, which sets each row's id, so
both preprocesses write the same bytes).
"""

from __future__ import annotations

import numpy as np

from geoterrain.bounds.normalbytes import NORMAL_BITS, NORMALS_PLANAR_DXDY
from geoterrain.bounds.tilebounds import pack_block_errors
from geoterrain.core.grid import Grid
from geoterrain.core.progress import StageClock
from geoterrain.preprocessing.levelblobs import TileBlobs, tile_row_order
from geoterrain.preprocessing.request import Request
from geoterrain.store.schema import page_size_for
from geoterrain.store.writer import StoreThread, StoreWriter


def store_metadata(*, source: str, source_dtype: str, source_nodata: float | None,
                   encoding: str, grid: dict, frame: dict, quantizer: dict,
                   normals_derived: list[int], valid_samples: int, samples: int,
                   height_range: list, delta_max_finite: float, edge_max: list | None,
                   stand_in_z: float, block_delta_levels: int,
                   ring_residual: bool = False) -> dict:
    """The metadata a preprocess writes (the whole-grid one and the streaming one).

    ``normals_derived``: the levels whose normals blobs are border rings (every level of
    the grid, or none); ``ring_residual``: those rings hold their codes' differences from
    the tile's derived map (``normals_ring_residual``, schema 17).

    Examples
    --------
    >>> m = store_metadata(source="d.tif", source_dtype="int16", source_nodata=None,
    ...     encoding="raw", grid={}, frame={}, quantizer={}, normals_derived=[0, 1],
    ...     valid_samples=3, samples=4, height_range=[0, 1], delta_max_finite=0.0,
    ...     edge_max=None, stand_in_z=0.5, block_delta_levels=1)
    >>> m["nodata_fraction"], m["normals_derived"], "delta_edge" in m
    (0.25, [0, 1], False)
    """
    from geoterrain._version import __version__

    return {
        "format": "geoterrain",
        "generator": f"geoterrain {__version__}",
        "source": source,
        "source_dtype": source_dtype,
        "source_nodata": source_nodata,
        "encoding": encoding,
        "grid": grid,
        "frame": frame,
        "quantizer": quantizer,
        "normal_bits": NORMAL_BITS,
        "normals_layout": NORMALS_PLANAR_DXDY,
        # levels whose normals blobs hold only the tile's border ring (the interior is
        # the central differences of the level's decoded heights, computed on read)
        **({"normals_derived": [int(v) for v in normals_derived]} if normals_derived else {}),
        # each ring code as its difference mod 256 from the code the reader derives there
        # from the tile alone (one-sided at the border: bounds.normals.ring_guess)
        **({"normals_ring_residual": True} if normals_derived and ring_residual else {}),
        "valid_samples": valid_samples,
        "nodata_fraction": float(1.0 - valid_samples / samples),
        "height_range": height_range,
        "delta_max_finite": delta_max_finite,
        # per tile with a second δ (padding replicated, edgepad.py): [L, x, y, max of its
        # new vertices' stored δ_edge (None: +inf)]; absent without padding
        **({"delta_edge": edge_max} if edge_max is not None else {}),
        "stand_in_z": stand_in_z,
        # the root tile's block_delta blob: each block's δ_n, n = 0 … this − 1
        "block_delta_levels": block_delta_levels,
        # no timings and no clock: the same input and options give the same bytes
        # (preprocess(timings=...) and `preprocess -v` report the stages' times)
    }


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
    ``heights`` is False: given already), the δ, r, normals and δ_edge blobs in the streamed
    preprocess's order (:func:`tile_row_order`; unless ``rows`` is False: given already,
    :func:`~geoterrain.preprocessing.levelblobs.tile_blobs`' ``on_rows``), the GeoMipMapping blocks'
    δ_n, the tile table and the metadata."""
    if heights:
        w.put_blobs("heights", blobs.heights)
    for kind, b in tile_row_order(blobs.extra, set(blobs.heights)) if rows else ():
        w.put_blobs(kind, b)
    w.put_blobs("block_delta", {(grid.top_level, 0, 0): pack_block_errors(blocks)})
    w.put_tiles(blobs.tile_rows)
    w.put_metadata(store_metadata(**meta))
    w.commit()
