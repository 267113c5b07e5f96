"""Turn grid-indexed triangles into a :class:`TriMesh` in the scene frame.

Every mesh a strategy hands back through :mod:`geoterrain.lod` carries the point
arrays ``grid_ij`` (the sample of each vertex) and ``elevation`` (metres, added
once at the seam by :func:`add_elevation`, so every strategy gets it).

A :class:`TriMesh` is VTK's own ``vtkPolyData`` with the few of ``pyvista.PolyData``'s
accessors the strategies and the offscreen render use (``points``, ``point_data``,
``cell_data``, ``n_points``, ``n_cells``, ``regular_faces``): making and drawing a mesh
imports no PyVista (about 0.25 s of a cold ``geoterrain render``). Where a caller gets a
mesh through the API (``Selection.mesh``, ``Terrain.mesh()``) it is a ``pyvista.PolyData``
(:meth:`TriMesh.pyvista`: the same arrays, not copied).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

if TYPE_CHECKING:
    import pyvista as pv


class Arrays:
    """A mesh's point or cell arrays by name, as ``pyvista.PolyData.point_data`` reads and
    sets them (numpy views of VTK's arrays; a new array becomes the active scalars when
    there are none, as PyVista makes it)."""

    __slots__ = ("_data",)

    def __init__(self, data):
        self._data = data  # a vtkPointData or vtkCellData

    def __contains__(self, name: str) -> bool:
        return bool(self._data.HasArray(name))

    def __getitem__(self, name: str) -> np.ndarray:
        arr = self._data.GetAbstractArray(name)
        if arr is None:
            raise KeyError(name)
        return vtk_to_numpy(arr)

    def __setitem__(self, name: str, values) -> None:
        had = name in self
        if had:
            self._data.RemoveArray(name)
        _add(self._data, name, np.ascontiguousarray(values))
        if not had and self._data.GetScalars() is None:
            self._data.SetActiveScalars(name)

    def keys(self) -> list[str]:
        d = self._data
        return [d.GetArrayName(k) for k in range(d.GetNumberOfArrays())]


class TriMesh(vtkPolyData):
    """A triangle mesh: ``vtkPolyData`` with ``pyvista.PolyData``'s accessors that the
    selection and the offscreen render use; any other of PyVista's attributes is read
    from :meth:`pyvista` (which imports PyVista).

    Examples
    --------
    >>> m = polydata(np.array([[0, 0, 4.0], [1, 0, 6], [0, 1, 8]]), np.array([[0, 1, 2]]))
    >>> m.n_points, m.n_cells, m.regular_faces.tolist()
    (3, 1, [[0, 1, 2]])
    >>> m.pyvista().n_cells  # doctest: +SKIP
    1
    """

    #: the ``pyvista.PolyData`` that ``Selection.mesh`` made of this mesh, once
    shown = None

    @property
    def n_points(self) -> int:
        return self.GetNumberOfPoints()

    @property
    def n_cells(self) -> int:
        return self.GetNumberOfCells()

    @property
    def points(self) -> np.ndarray:
        """(V, 3) vertex positions (a view of VTK's array)."""
        p = self.GetPoints()
        return vtk_to_numpy(p.GetData()) if p is not None else np.zeros((0, 3))

    @points.setter
    def points(self, xyz) -> None:
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(np.ascontiguousarray(xyz, np.float64), deep=False))
        self.SetPoints(pts)

    @property
    def point_data(self) -> Arrays:
        return Arrays(self.GetPointData())

    @property
    def cell_data(self) -> Arrays:
        return Arrays(self.GetCellData())

    @property
    def active_scalars_name(self) -> str | None:
        s = self.GetPointData().GetScalars()
        return s.GetName() if s is not None else None

    @property
    def regular_faces(self) -> np.ndarray:
        """(F, 3) vertex indices of the triangles."""
        polys = self.GetPolys()
        if polys is None or not self.n_cells:
            return np.zeros((0, 3), np.int64)
        return vtk_to_numpy(polys.GetConnectivityArray()).reshape(-1, 3)

    @property
    def active_texture_coordinates(self) -> np.ndarray | None:
        tc = self.GetPointData().GetTCoords()
        return vtk_to_numpy(tc) if tc is not None else None

    @active_texture_coordinates.setter
    def active_texture_coordinates(self, tc: np.ndarray) -> None:
        arr = numpy_to_vtk(np.ascontiguousarray(tc), deep=False)
        arr.SetName("Texture Coordinates")  # PyVista's name
        self.GetPointData().SetTCoords(arr)
        self.Modified()

    def pyvista(self) -> pv.PolyData:
        """This mesh as a ``pyvista.PolyData``: a new VTK object sharing its points, cells
        and arrays (no copy)."""
        import pyvista as pv

        return pv.PolyData(self, deep=False)

    def __getattr__(self, name: str):
        # PyVista's other attributes (bounds, plot, save, ...), on the shared copy
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.pyvista(), name)


class MeshParts:
    """A selected triangle mesh as numpy arrays: what every LOD strategy makes.

    Making and reading it touches no VTK object, so a selection may run on any thread
    (the viewer's worker): VTK's objects are made by the thread that draws, from
    :meth:`trimesh` (once; the arrays are wrapped, not copied). A VTK object made on a
    worker thread while the main thread frees one can deadlock the two (VTK's garbage
    collector's lock and Python's GIL taken in opposite orders). It reads as a
    :class:`TriMesh` does: ``points``, ``point_data``, ``cell_data`` (dicts of arrays),
    ``n_points``, ``n_cells``, ``regular_faces``, ``active_scalars_name``.

    Examples
    --------
    >>> m = mesh_parts(np.array([[0, 0, 4.0], [1, 0, 6], [0, 1, 8]]), np.array([[0, 1, 2]]),
    ...                cell_arrays={"skirt": np.zeros(1, np.uint8)})
    >>> m.n_points, m.n_cells, m.regular_faces.tolist(), "skirt" in m.cell_data
    (3, 1, [[0, 1, 2]], True)
    >>> t = m.trimesh()  # on the thread that draws
    >>> t.n_cells, t is m.trimesh()
    (1, True)
    """

    __slots__ = ("points", "triangles", "point_data", "cell_data", "active_scalars_name",
                 "_vtk")

    def __init__(self, points: np.ndarray, triangles: np.ndarray,
                 point_data: dict[str, np.ndarray], cell_data: dict[str, np.ndarray]):
        self.points = points
        self.triangles = triangles  # (F, 3)
        self.point_data = point_data
        self.cell_data = cell_data
        self.active_scalars_name: str | None = None
        self._vtk: TriMesh | None = None

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_cells(self) -> int:
        return len(self.triangles)

    @property
    def regular_faces(self) -> np.ndarray:
        """(F, 3) vertex indices of the triangles."""
        return self.triangles

    @property
    def faces(self) -> np.ndarray:
        """The triangles as ``pyvista.PolyData.faces`` lists them: (3, a, b, c) each."""
        f = self.triangles
        return np.hstack([np.full((len(f), 1), 3, f.dtype), f]).ravel()

    def trimesh(self) -> TriMesh:
        """The mesh as VTK's object (made on the first call, by the calling thread; the
        arrays as they are then)."""
        if self._vtk is None:
            m = polydata(self.points, self.triangles, self.point_data.get("grid_ij"),
                         self.cell_data)
            if len(self.points):
                pd = m.GetPointData()
                for k, v in self.point_data.items():
                    if k != "grid_ij":
                        _add(pd, k, np.ascontiguousarray(v))
                if self.active_scalars_name is not None:
                    pd.SetActiveScalars(self.active_scalars_name)
            self._vtk = m
        return self._vtk

    def __getattr__(self, name: str):
        # PyVista's other attributes (bounds, save, ...), on VTK's mesh (made here)
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.trimesh(), name)


def mesh_parts(xyz: np.ndarray, faces: np.ndarray, ij: np.ndarray | None = None,
               cell_arrays: dict[str, np.ndarray] | None = None) -> MeshParts:
    """A strategy's mesh: float64 points, ``grid_ij`` point data and cell arrays, as
    :func:`polydata` makes them, without VTK (:class:`MeshParts`)."""
    xyz = np.ascontiguousarray(xyz, np.float64)
    faces = np.asarray(faces)
    if faces.dtype not in (np.int32, np.int64):
        faces = faces.astype(np.int64)
    faces = faces.reshape(-1, 3)
    pdata = {}
    if ij is not None and len(ij):
        pdata["grid_ij"] = np.ascontiguousarray(ij, np.float64)
    cdata = {k: np.ascontiguousarray(v) for k, v in (cell_arrays or {}).items()} \
        if len(faces) else {}
    return MeshParts(xyz, faces, pdata, cdata)


def empty_parts() -> MeshParts:
    """The mesh of a view that draws nothing.

    Examples
    --------
    >>> empty_parts().n_cells
    0
    """
    return mesh_parts(np.zeros((0, 3)), np.zeros((0, 3), np.int64))


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
             cell_arrays: dict[str, np.ndarray] | None = None) -> TriMesh:
    """A triangle mesh with float64 points, ``grid_ij`` point data and cell arrays.

    The arrays are wrapped, not copied, where they already have VTK's layout (C order,
    float64 points and ``grid_ij``, int32 or int64 faces): a frame's mesh costs no copy.
    """
    xyz = np.ascontiguousarray(xyz, np.float64)
    faces = np.asarray(faces)
    if faces.dtype not in (np.int32, np.int64):
        faces = faces.astype(np.int64)
    mesh = TriMesh()
    if len(faces):
        pts = vtkPoints()
        pts.SetData(numpy_to_vtk(xyz, deep=False))
        mesh.SetPoints(pts)
        cells = vtkCellArray()  # fixed-size cells (int32 or int64): no offsets array at all
        conn = np.ascontiguousarray(faces).ravel()
        cells.SetData(3, numpy_to_vtk(conn, deep=False) if faces.dtype == np.int32
                      else numpy_to_vtkIdTypeArray(conn, deep=False))  # as PyVista's
        mesh.SetPolys(cells)
    elif len(xyz):
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


def add_elevation(mesh: TriMesh | MeshParts, z_scale: float,
                  elevation: np.ndarray | None = None) -> TriMesh | MeshParts:
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
    if isinstance(mesh, MeshParts):
        if mesh.n_points:
            e = elevation
            if e is None:
                e = np.empty(mesh.n_points, np.float32)
                np.multiply(mesh.points[:, 2], 1.0 / float(z_scale), out=e, casting="unsafe")
            mesh.point_data["elevation"] = e
            mesh.active_scalars_name = "elevation"
        return mesh
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


def empty_polydata() -> TriMesh:
    """The mesh of a view that draws nothing.

    Examples
    --------
    >>> empty_polydata().n_cells
    0
    """
    return polydata(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
