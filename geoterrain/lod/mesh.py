"""Turn grid-indexed triangles into a ``pyvista.PolyData`` in the scene frame.

Every mesh a strategy hands back through :mod:`geoterrain.lod` carries the point
arrays ``grid_ij`` (the sample of each vertex) and ``elevation`` (metres, added
once at the seam by :func:`add_elevation`, so every strategy gets it).
"""

from __future__ import annotations

import numpy as np
import pyvista as pv
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray


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
    """A triangle PolyData with float64 points, ``grid_ij`` point data and cell arrays.

    The arrays are wrapped, not copied, where they already have VTK's layout (C order,
    float64 points and ``grid_ij``, int32 or int64 faces): a frame's mesh costs no copy.
    """
    xyz = np.ascontiguousarray(xyz, np.float64)
    faces = np.asarray(faces)
    if faces.dtype not in (np.int32, np.int64):
        faces = faces.astype(np.int64)
    if len(faces):
        mesh = pv.PolyData()
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(xyz, deep=False))
        mesh.SetPoints(pts)
        cells = vtkCellArray()
        if faces.dtype == np.int32:  # fixed-size cells: no offsets array at all
            cells.SetData(3, numpy_to_vtk(np.ascontiguousarray(faces).ravel(), deep=False))
        else:
            cells = pv.CellArray.from_regular_cells(np.ascontiguousarray(faces))
        mesh.SetPolys(cells)
    else:
        mesh = pv.PolyData()
        if len(xyz):
            mesh.points = xyz
    if ij is not None and len(ij):
        _add(mesh.GetPointData(), "grid_ij", np.ascontiguousarray(ij, np.float64))
    for k, v in (cell_arrays or {}).items():
        if len(faces):
            _add(mesh.GetCellData(), k, np.ascontiguousarray(v))
    return mesh


def _add(data, name: str, values: np.ndarray) -> None:
    # numpy_to_vtk(deep=False) keeps a reference to ``values`` on the VTK array
    if values.dtype == np.bool_:
        values = values.astype(np.uint8)
    arr = numpy_to_vtk(values, deep=False)
    arr.SetName(name)
    data.AddArray(arr)


def add_elevation(mesh: pv.PolyData, z_scale: float,
                  elevation: np.ndarray | None = None) -> pv.PolyData:
    """Add the point array ``elevation`` (metres) to ``mesh`` in place and make it active.

    Scene Z is the height in metres × the vertical exaggeration (``Frame.z``:
    height × z_to_m × z_scale), so elevation = Z / z_scale: the unexaggerated height
    in metres, whatever the DEM's vertical unit. Skirt vertices get the height of
    where they hang (their own Z), like every other point. ``elevation``: the array,
    already computed by this formula (float32 of Z · (1 / z_scale)) where the mesh was
    made; it is then added as it is.

    Examples
    --------
    >>> m = add_elevation(polydata(np.array([[0, 0, 4.0], [1, 0, 6], [0, 1, 8]]),
    ...                            np.array([[0, 1, 2]])), z_scale=2.0)
    >>> m.active_scalars_name, m.point_data["elevation"].tolist()
    ('elevation', [2.0, 3.0, 4.0])
    """
    if mesh.n_points:
        e = elevation
        if e is None:
            z = vtk_to_numpy(mesh.GetPoints().GetData())[:, 2]
            e = np.empty(len(z), np.float32)  # one pass, no float64 temporary
            np.multiply(z, 1.0 / float(z_scale), out=e, casting="unsafe")
        pd = mesh.GetPointData()  # VTK calls: a frame pays no wrapper overhead here
        pd.RemoveArray("elevation")
        _add(pd, "elevation", e)
        pd.SetActiveScalars("elevation")
    return mesh


def empty_polydata() -> pv.PolyData:
    """The mesh of a view that draws nothing.

    Examples
    --------
    >>> empty_polydata().n_cells
    0
    """
    return polydata(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
