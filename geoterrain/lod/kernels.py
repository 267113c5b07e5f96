"""Compiled bintree kernels (numba), by job:

- :mod:`geoterrain.lod.activekernels`: the active set's flags (:class:`ActiveFlags`), the
  resumable stack-based walk and extraction (vertices numbered in order), the closure
  upward, the static fill and the sample positions (:func:`sample_xy`);
- :mod:`geoterrain.lod.lpkernels`: LP activity (seed 002 eq. 2) filled a block at a time
  behind the blocks' bounds, and the tiles that can hold an active vertex;
- :mod:`geoterrain.lod.tilekernels`: the tile tree (coarsest tile of a sample, roots, rows,
  tiles marked and walked from the top) and the pooled samples gathered.

This module names them all, as before the split.

Benchmarked against the level-by-level numpy bisection it replaced; today's figures come
from ``benchmarks/bench_lod.py`` (docs/benchmarks.md; history in docs/lab/lod-flight.md).
"""

from __future__ import annotations

from geoterrain.lod.activekernels import (  # noqa: F401 - this module's names before the split
    ActiveFlags,
    _grow_box,
    _set_parents,
    _walk,
    close_upward,
    close_upward_boxes,
    extract,
    fill_static,
    sample_xy,
    walk_leaves,
    walk_shape,
    walk_start,
)
from geoterrain.lod.lpkernels import (  # noqa: F401
    BLOCK,
    _block_floor,
    _box_reach,
    _fill_block,
    _point_reach,
    _sphere_out,
    block_bounds,
    fill_lp,
    lp_tiles,
)
from geoterrain.lod.tilekernels import (  # noqa: F401
    _coarsest_tile,
    gather_pooled,
    level_boxes,
    lp_tiles_walk,
    mark_tiles,
    tree_roots,
    tree_row,
)
