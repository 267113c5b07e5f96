"""A level-0 tile's δ, r and normals, derived on read from the tile's decoded heights.

(:func:`tile_leaf_bounds` is what ``Terrain`` calls for a ring blob of δ or r; for one of
normals it derives the rest with :func:`geoterrain.bounds.normals.derived_codes` from the
x, y of :func:`normal_xy`.)

Below the top level a tile stores only the vertices new at its level (the others are
its parent's, :mod:`geoterrain.bounds.vertexdata`). At level 0 those are the samples with an
odd row or column: the bintree's finest vertices, of half-span h = 1 (seed 002 §2.3):

- a block centre (odd row and column): its diamond is its own closed 2 × 2 cell, so its
  exact δ (:func:`geoterrain.bounds.delta.vertex_errors`) is the h = 1 closed form over those
  9 samples, saturated with its 4 edge midpoints (§2.4, L46: they are its children and
  have none), and its sphere radius is the largest distance to them (L50–52: they are
  leaves, r = 0);
- an edge midpoint: a leaf (r = 0); its diamond is the two cells beside it, both inside
  the tile unless it lies on the tile's border.

So every new vertex's δ and r is a function of the tile's own samples, except the δ of
the edge midpoints on the border ring, whose second cell lies in the next tile (its
validity decides between the closed form, a partial sweep and +inf). A store keeps only
those ring values (:data:`geoterrain.bounds.vertexdata.RING`); a reader rebuilds the rest here,
with the same arithmetic as the whole-grid kernels (the same compiled helpers, no fast
math), and codes them as the preprocess codes them, so it decodes the same values.
"""

from __future__ import annotations

# one module per job: closedforms.py (δ and r of a tile's own samples), guesses.py (the
# codes guessed from the heights), geographic.py (a geographic tile's δ slack), normalxy.py
# (the normals' x, y and the rings' guesses); every name of the module they were split
# from is re-exported here, so every import path stays
from geoterrain.bounds.leafbounds.closedforms import (  # noqa: F401
    _NO_RING,
    Ring,
    _centre_radius_nb,
    _leaf_delta_nb,
    _leaf_radius_nb,
    _status,
    _table,
    centre_radius,
    leaf_delta,
    leaf_radius,
    tile_centre_radius,
    tile_leaf_bounds,
)
from geoterrain.bounds.leafbounds.geographic import (  # noqa: F401
    _inner,
    geographic_leaf_delta,
    tile_slack,
)
from geoterrain.bounds.leafbounds.guesses import (  # noqa: F401
    CentreHeights,
    _alpha_score,
    _centre_guess_nb,
    _mid_base,
    _mids_alpha_nb,
    _mids_pred_nb,
    _spacings,
    _tile_heights,
    _zp,
    _zq,
    centre_guess,
    mids_codes,
    mids_residuals,
    tile_centre_guess,
    tile_edge_own_codes,
    tile_mids_codes,
    tile_own_codes,
)
from geoterrain.bounds.leafbounds.normalxy import (  # noqa: F401
    NORMAL_XY_NODES,
    NORMAL_XY_TOLERANCE,
    _bilinear,
    _Layout,
    normal_axes,
    normal_xy,
    ring_guesses,
)

__all__ = ["CentreHeights", "centre_guess", "centre_radius", "geographic_leaf_delta",
           "leaf_delta", "leaf_radius", "mids_codes", "mids_residuals", "normal_axes",
           "normal_xy", "ring_guesses", "tile_centre_guess", "tile_centre_radius",
           "tile_edge_own_codes", "tile_leaf_bounds", "tile_mids_codes", "tile_own_codes",
           "tile_slack"]
