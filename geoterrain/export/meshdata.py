"""A selection's triangles as plain arrays for writers: the vertices its faces use,
their elevation and normals, and the georeference that maps a written position back
to the source CRS.

Examples
--------
>>> m = mesh_arrays(t, t.static_selection(5.0))
>>> bool(m.faces.max() < len(m.xyz))
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geoterrain._version import __version__

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


@dataclass
class MeshArrays:
    """The referenced part of a selection, ready to write.

    ``xyz`` scene frame (float64), ``faces`` (F, 3), ``ij`` grid row/column of each
    vertex's sample, ``elevation`` metres (scene Z without vertical exaggeration),
    ``normals`` area-weighted unit vertex normals (scene frame), ``surface`` (F,) bool
    (False on skirt triangles).
    """

    xyz: np.ndarray
    faces: np.ndarray
    ij: np.ndarray
    elevation: np.ndarray
    normals: np.ndarray
    surface: np.ndarray


def mesh_arrays(terrain: TerrainLike, selection, *, skirts: bool = True) -> MeshArrays:
    """The vertices the selection's triangles use, with elevation and normals.

    Examples
    --------
    >>> m = mesh_arrays(t, t.static_selection(5.0))
    >>> m.xyz.shape[0] == m.elevation.shape[0] == m.normals.shape[0]
    True
    """
    faces = selection.faces
    surface = np.ones(len(faces), bool)
    if len(faces) and "skirt" in selection.parts.cell_data:
        surface = np.asarray(selection.parts.cell_data["skirt"]) == 0
    if not skirts:
        faces, surface = faces[surface], surface[surface]
    pts = np.asarray(selection.parts.points, np.float64)
    used = np.zeros(len(pts), bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    xyz = pts[used]
    ij = selection.ij[used] if len(selection.ij) else np.zeros((len(xyz), 2))
    faces = remap[faces].astype(np.int64)
    elevation = (xyz[:, 2] / (terrain.frame.z_scale or 1.0)).astype(np.float32)
    return MeshArrays(xyz, faces, ij, elevation, vertex_normals(xyz, faces), surface)


def vertex_normals(xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (float32); +Z where a vertex has no area.

    Examples
    --------
    >>> n = vertex_normals(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]), np.array([[0, 1, 2]]))
    >>> n.tolist()
    [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    """
    p = xyz[faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # length = 2 × area
    n = np.zeros((len(xyz), 3))
    for k in range(3):
        for c in range(3):
            n[:, c] += np.bincount(faces[:, k], fn[:, c], minlength=len(xyz))
    length = np.linalg.norm(n, axis=1)
    bad = length == 0
    n[bad] = (0.0, 0.0, 1.0)
    length[bad] = 1.0
    return (n / length[:, None]).astype(np.float32)


def georeference(terrain: TerrainLike, scale: float = 1.0, offset: tuple[float, float,
                 float] = (0, 0, 0)
                 ) -> dict:
    """How a written position maps back to the source CRS (the sidecar's content).

    A file position p (its axes named by the format) is ``scene = p / scale + offset``
    in the scene frame: east, north, up metres from ``origin_crs``. For a projected
    frame, source-CRS x, y = ``origin_crs + (east, north) / unit_to_m``; for a
    geographic one (east, north) are coordinates of ``positions_crs_wkt`` (an
    azimuthal equidistant CRS centred on the origin). Heights: up / z_scale metres.

    Examples
    --------
    >>> g = georeference(t)
    >>> g["frame"], len(g["origin_crs"])
    ('projected', 2)
    """
    f = terrain.frame
    return {
        "generator": f"geoterrain {__version__}",
        "crs_name": f.crs_name,
        "crs_wkt": f.crs_wkt,
        "frame": f.kind,
        "positions_crs_wkt": f.aeqd_wkt if f.kind == "geographic" else f.crs_wkt,
        "origin_crs": [float(v) for v in f.origin_crs],
        "unit_to_m": f.unit_to_m,
        "z_scale": f.z_scale,
        "units": "metres" if scale == 1.0 else f"{scale:g} per metre",
        "scale": float(scale),
        "offset_scene": [float(v) for v in offset],
        "transform": list(f.transform),
        "grid": [terrain.grid.rows, terrain.grid.cols],
    }


def with_elevation(terrain: TerrainLike, mesh):
    """A shallow copy of ``mesh`` with an ``elevation`` point array (metres, made active).

    Examples
    --------
    >>> m = with_elevation(t, t.mesh(5.0))
    >>> m.active_scalars_name
    'elevation'
    """
    out = mesh.copy(deep=False)
    if out.n_points:
        z = np.asarray(out.points, np.float64)[:, 2]
        out.point_data["elevation"] = (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)
        out.set_active_scalars("elevation")
    return out
