"""Turn grid-indexed triangles into a ``pyvista.PolyData`` in the scene frame."""

from __future__ import annotations

import numpy as np
import pyvista as pv


def orient_ccw(ij: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces wound counter-clockwise seen from above (X = column, Y = −row)."""
    p = ij[faces].astype(np.float64)  # (F, 3, 2) as (i, j)
    x, y = p[..., 1], -p[..., 0]
    area2 = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    out = faces.copy()
    flip = area2 < 0
    out[flip, 1], out[flip, 2] = faces[flip, 2], faces[flip, 1]
    return out


def polydata(xyz: np.ndarray, faces: np.ndarray, ij: np.ndarray | None = None,
             cell_arrays: dict[str, np.ndarray] | None = None) -> pv.PolyData:
    """A triangle PolyData with float64 points, ``grid_ij`` point data and cell arrays."""
    if len(faces):
        mesh = pv.PolyData.from_regular_faces(np.ascontiguousarray(xyz, np.float64),
                                              np.asarray(faces, np.int64))
    else:
        mesh = pv.PolyData()
        if len(xyz):
            mesh.points = np.ascontiguousarray(xyz, np.float64)
    if ij is not None and len(ij):
        mesh.point_data["grid_ij"] = np.asarray(ij, np.float64)
    for k, v in (cell_arrays or {}).items():
        if len(faces):
            mesh.cell_data[k] = v
    return mesh


def empty_polydata() -> pv.PolyData:
    """The mesh of a view that draws nothing.

    Examples
    --------
    >>> empty_polydata().n_cells
    0
    """
    return polydata(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
