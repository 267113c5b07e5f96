"""The static mesh as a greedy-insertion TIN (Garland & Heckbert; Delatin's algorithm).

``mesher="tin"`` of :func:`geoterrain.lod.static`: a Delaunay triangulation of the data
rectangle refined by inserting, one at a time, the sample of largest vertical error of
the triangle of largest error, until no triangle's error exceeds ``max_error``
(:mod:`geoterrain.lod.tinkernels`, driven by :mod:`geoterrain.lod.tincollapse`, which
then collapses points no longer needed). A triangle's error is the largest
``|mesh − height|`` over every level-0 sample it covers, computed from the stored
(decoded) heights, so the bound is exact on the samples, as rtin's δ is.

Two TIN meshers differ only in that collapse pass (:data:`COLLAPSE`): ``"tin"`` stops it
once it has removed 5 % of the refinement's triangles (about 0.95× pydelatin's triangles,
0.7–1.0× its time on a quiet machine), ``"tin-full"`` tries every point (0.58–0.74×
pydelatin's triangles, about a quarter more time); docs/lab/static-mesh.md. Both hold
the same exact bound: a collapse is made only if every new triangle is within it.

Against the default (rtin's bintree cut): vertices anywhere, not only at bintree
midpoints, so fewer triangles at the same error (docs/lab/static-mesh.md); but the whole
level-0 grid is read at once (no streaming, no bounded memory), and the refinement is
sequential.

Nodata: a triangle is drawn only if its three corners are valid, and no drawn triangle
covers an invalid sample: a triangle that would (or one with an invalid corner that
covers a valid sample other than its corners) is refined, so voids are cut out down to
the grid's resolution along their border, as rtin's mixed diamonds (δ = ∞) are; then an
edge is flipped where the other diagonal draws more of the data (within the bound). A
valid sample on a void's border (an invalid sample among its 8 neighbours) may still be
left uncovered; none inside the data is.

Examples
--------
>>> import geoterrain, tempfile, os
>>> from geoterrain.ingest.synth import generate, write_geotiff
>>> dem = write_geotiff(os.path.join(tempfile.mkdtemp(), "d.tif"), generate("fbm", 65, seed=2))
>>> t = geoterrain.open(geoterrain.preprocess(dem))
>>> sel = t.static_selection(5.0, mesher="tin")
>>> sel.stats["mesher"], sel.stats["triangles"] < t.static_selection(5.0).stats["triangles"]
('tin', True)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["MESHERS", "greedy_mesh", "static"]

#: The static meshers: rtin's bintree cut (the default, streamed in bounded memory by
#: `mesh`/`export`) and the greedy TIN, its collapse pass bounded or full.
MESHERS = ("rtin", "tin", "tin-full")

#: The share of the refinement's triangles each TIN mesher's collapse pass may remove
#: (it stops there; 1: every point tried).
COLLAPSE = {"tin": 0.05, "tin-full": 1.0}


def greedy_mesh(z: np.ndarray, valid: np.ndarray | None, max_error: float,
                collapse: float = COLLAPSE["tin"]) -> tuple[np.ndarray, np.ndarray]:
    """The greedy TIN of heights ``z`` (H × W, scene units) within ``max_error``, its
    collapse pass stopped once it has removed the share ``collapse`` of the refinement's
    triangles (0: no collapse; 1: every point tried).

    Returns ``ij`` (V, 2) int64 rows and columns of the vertices and ``faces`` (F, 3)
    int64, counter-clockwise seen from above, only those with three valid corners.

    Examples
    --------
    >>> z = np.add.outer(np.arange(5.0), np.zeros(5))  # a plane: two triangles
    >>> ij, f = greedy_mesh(z, None, 0.0)
    >>> len(f), sorted(map(tuple, ij.tolist()))
    (2, [(0, 0), (0, 4), (4, 0), (4, 4)])
    """
    from geoterrain.lod.tincollapse import greedy_tin

    z = np.asarray(z, np.float64)
    H, W = z.shape
    if 16 * H * W >= 2**31:  # the kernels' int32 half-edges
        from geoterrain.exceptions import UsageError

        raise UsageError(f"the TIN mesher takes at most 134 million samples, this grid has "
                         f"{H * W:,}; use the rtin mesher")
    if valid is None:
        valid = np.ones_like(z, bool)
    valid = np.ascontiguousarray(valid, bool).ravel()
    voids = not bool(valid.all())
    zf = np.where(valid, z.ravel(), 0.0) if voids else np.ascontiguousarray(z).ravel()
    # error ≤ e, ties included (as Delatin stops): on integer heights many samples sit
    # exactly at e, and refining a hair under it costs a quarter more triangles
    faces, ij = greedy_tin(zf, valid, H, W, float(max_error), voids, float(collapse))
    return ij, faces


def static(terrain: TerrainLike, max_error: float, mesher: str = "tin"):
    """The greedy TIN of ``terrain``'s level-0 samples within ``max_error`` (scene
    units), its collapse pass as ``mesher`` says (:data:`COLLAPSE`), as a mesh in the
    scene frame (``grid_ij``, ``level`` 0, ``skirt`` 0) and stats."""
    from geoterrain.core.memory import small_pages
    from geoterrain.lod.mesh import mesh_parts

    g = terrain.grid
    H, W = g.rows, g.cols
    with small_pages():  # whole-grid arrays: a huge page's first touch can cost seconds
        h, valid = terrain.level_heights(0)
        z = terrain.frame.z(h[:H, :W])
        valid = valid[:H, :W]
        ij, faces = greedy_mesh(z, valid, max_error, COLLAPSE[mesher])
    if terrain.frame.kind == "geographic":  # the tiles' cached x, y (pyproj once a tile)
        got = terrain.gather(ij[:, 0], ij[:, 1], kinds=("x", "y"))
        x, y = got["x"], got["y"]
    else:
        x, y = terrain.frame.xy(ij[:, 0], ij[:, 1])
    xyz = np.stack([x, y, z[ij[:, 0], ij[:, 1]]], axis=1)
    n = len(faces)
    mesh = mesh_parts(xyz, faces, ij, {"skirt": np.zeros(n, np.uint8),
                                     "level": np.zeros(n, np.int8)})
    return mesh, {"mesher": mesher}
