"""Error bounds: per-vertex δ and nested radii r (Lindstrom & Pascucci), their metric
form on geographic grids, edge padding, tile and leaf bounds, normal maps, and the blobs
that store them.
"""

__all__ = ["curvature", "delta", "edgepad", "gapcoder", "leafbounds", "log8codes", "normalbytes",
           "normals", "ownguess", "radii", "tileblobs", "tilebounds", "vertexdata"]
