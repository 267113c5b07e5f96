"""Per-vertex error bounds: exact δ and its saturation (the nested radii:
:mod:`geoterrain.bounds.radii`).

Seed 002 (Lindstrom & Pascucci): δ is the object-space error of a vertex (§2.3), saturated
so that δ(parent) ≥ δ(child) (§2.4, L46); with the nested bounding-sphere radii
(:mod:`geoterrain.bounds.radii`) the screen-space error of LP eq. 2, ρ = λ δ / (|p − o| − r), is
monotone along the vertex DAG.

Unlike the midpoint-only error of the seed (and of Martini), δ here is the exact maximum
of |z − S| over every valid full-resolution sample of the vertex's closed diamond, S being
the two triangles drawn while the vertex is absent, so δ bounds the vertical error of any
mesh extracted with it. Grid and bintree conventions: docs/conventions.md and
:mod:`geoterrain.core.bintree` (whose compiled helpers give the parents, children and
union-jack parity used here). Per-tile bounds: :mod:`geoterrain.bounds.tilebounds`; the slow
numpy oracles the tests compare against: :mod:`geoterrain.testing.reference`.

Invalid samples
---------------
``valid`` is authoritative (a valid sample with a non-finite height is treated as
invalid). Heights of invalid samples are never read for δ or tile errors. A diamond that
mixes valid and invalid samples gets δ = +inf; an all-invalid one gets 0.

Root grids
----------
On a rectangular root grid (issue 45, :mod:`geoterrain.core.bintree`) the arrays are
the roots' extent, (ry·S + 1, rx·S + 1) for roots of side S = ``span``, with the samples
beyond the raster invalid: the same kernels, over a rectangle of blocks, stop at the
roots' centres and edges (half-span S/2), and every root's corners get 0 as the square's
four do. ``span`` None is the square (S = N − 1).

"""

from __future__ import annotations

# one module per job: grid.py (the grids' checks), sweeps.py (one diamond's or block's
# sweep, the kernels' bundles), exact.py (the whole grid's δ and its saturation), fields.py
# (δ with the tile-bound fields), checks.py (checks of stored δ); every name of the
# module they were split from is re-exported here, so every import path stays
from geoterrain.bounds.delta.checks import (  # noqa: F401
    _below_own_error_nb,
    _finite_max_nb,
    below_own_error,
    delta_max_finite,
)
from geoterrain.bounds.delta.exact import (  # noqa: F401
    _block_status_nb,
    _raw_delta,
    _raw_delta_nb,
    _saturate_pull_nb,
    saturate,
    vertex_errors,
)
from geoterrain.bounds.delta.fields import (  # noqa: F401
    _block_sweep_field,
    _field_err,
    _field_lines,
    _raw_delta_fields_nb,
    vertex_errors_fields,
)
from geoterrain.bounds.delta.grid import check_grid, grid_order  # noqa: F401
from geoterrain.bounds.delta.sweeps import (  # noqa: F401
    _FM,
    Beside,
    Cell,
    Diamond,
    _block_sweep,
    _block_sweep_part,
    _centre1,
    _edge_err,
    _edge_err_part,
    _mid1,
    cell_rows_nb,
    edge_delta_nb,
    edge_err_window,
    edge_status_nb,
)

__all__ = ["below_own_error", "delta_max_finite", "saturate", "vertex_errors",
           "vertex_errors_fields"]
