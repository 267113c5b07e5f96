"""A mesh closed into a printable solid: vertical walls down every boundary edge and a
flat base under the lowest point, checked to be a closed 2-manifold; and binary STL.

Examples
--------
>>> from geoterrain.export.meshdata import mesh_arrays
>>> s = solid(t, mesh_arrays(t, t.static_selection(5.0)))
>>> s.n_surface * 2 < len(s.faces)
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geoterrain._version import __version__
from geoterrain.exceptions import UsageError
from geoterrain.export.meshdata import MeshArrays, georeference

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


@dataclass
class Solid:
    """A surface closed into a solid (:func:`solid`): ``points`` (the surface's V points,
    then the same V on the bottom plane z = 0), ``faces`` wound outwards (the surface's
    ``n_surface`` faces, the bottom's as many, then the walls), and the map back to the
    scene frame: scene = point / ``scale`` + ``offset``; ``unit`` ("mm" with a print
    size, else "m"); ``base_height`` in that unit; ``geo`` the sidecar's georeference."""

    points: np.ndarray
    faces: np.ndarray
    n_surface: int
    scale: float
    offset: tuple[float, float, float]
    unit: str
    base_height: float
    geo: dict

    def rescaled(self, f: float) -> Solid:
        """The same solid with its units × ``f`` (millimetres → metres: 1e-3)."""
        geo = dict(self.geo, scale=self.geo["scale"] * f, base_height=self.base_height * f,
                   units=f"{self.geo['scale'] * f:g} per metre")
        return Solid(self.points * f, self.faces, self.n_surface, self.scale * f, self.offset,
                     {"mm": "m"}.get(self.unit, self.unit) if f == 1e-3 else self.unit,
                     self.base_height * f, geo)

    def surface(self, m: MeshArrays) -> MeshArrays:
        """The surface's :class:`MeshArrays` in the solid's units."""
        V = len(m.xyz)
        return MeshArrays(self.points[:V], m.faces, m.ij, m.elevation, m.normals, m.surface)

    def elevation(self, terrain: TerrainLike) -> np.ndarray:
        """Each point's elevation in metres (float32): its scene height / z_scale."""
        z = self.points[:, 2] / self.scale + self.offset[2]
        return (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)

    def sides(self, terrain: TerrainLike) -> MeshArrays:
        """The bottom and walls as their own mesh: the bottom's points (normal −z), then three
        points per wall triangle (its own normal, so walls are flat-shaded)."""
        F, V = self.n_surface, len(self.points) // 2
        bottom = self.faces[F:2 * F] - V
        walls = self.faces[2 * F:]
        p = self.points[walls].reshape(-1, 3)
        wn = np.cross(p[1::3] - p[0::3], p[2::3] - p[0::3])
        wn /= np.maximum(np.linalg.norm(wn, axis=1, keepdims=True), 1e-30)
        xyz = np.concatenate([self.points[V:], p])
        normals = np.concatenate([np.tile([0.0, 0.0, -1.0], (V, 1)), np.repeat(wn, 3, 0)])
        faces = np.concatenate([bottom, V + np.arange(len(p)).reshape(-1, 3)])
        z = xyz[:, 2] / self.scale + self.offset[2]
        elev = (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)
        return MeshArrays(xyz, faces.astype(np.int64), np.zeros((len(xyz), 2)), elev,
                          normals.astype(np.float32), np.ones(len(faces), bool))

    def summary(self) -> dict:
        """Its size along x, y, z, unit and base height (for the command's summary)."""
        ext = self.points.max(0) - self.points.min(0)
        return {"size": [float(v) for v in ext], "units": self.unit,
                "base_height": float(self.base_height)}


def solid(terrain: TerrainLike, m: MeshArrays, base_height: float | None = None,
          print_size: float | None = None) -> Solid:
    """The surface closed into a :class:`Solid`: walls down every boundary edge and a flat
    base.

    ``print_size`` (mm): the longer horizontal side becomes that long, every axis
    scaled alike (the vertical exaggeration is the terrain's, ``-z``); the model
    sits on z = 0 with x, y ≥ 0. ``base_height``: the base's thickness under the
    lowest point, in output units (mm with ``print_size``, else metres); default 3 mm,
    or 2 % of the longer side. The surface must be conforming (every interior edge
    shared by two triangles, as static and ``rtin`` meshes are).

    Examples
    --------
    >>> from geoterrain.export.meshdata import mesh_arrays
    >>> s = solid(t, mesh_arrays(t, t.static_selection(5.0)), print_size=100.0)
    >>> s.unit, float(s.points[:, 2].min()), round(float(np.ptp(s.points[:, :2], 0).max()), 6)
    ('mm', 0.0, 100.0)
    """
    if print_size is not None and not (np.isfinite(print_size) and print_size > 0):
        raise UsageError(f"print_size must be > 0 mm, got {print_size}",
                         cli=f"--print-size must be > 0 mm, got {print_size}")
    xyz, faces = m.xyz, m.faces
    lo, hi = xyz.min(0), xyz.max(0)
    side = float(max(hi[0] - lo[0], hi[1] - lo[1])) or 1.0
    scale = 1.0 if print_size is None else float(print_size) / side
    if base_height is None:
        base_height = 3.0 if print_size is not None else 0.02 * side
    if not (np.isfinite(base_height) and base_height > 0):
        raise UsageError(f"base_height must be > 0, got {base_height}",
                         cli=f"--base-height must be > 0, got {base_height}")
    offset = (float(lo[0]), float(lo[1]), float(lo[2]) - base_height / scale)
    top = (xyz - offset) * scale
    V = len(top)
    bottom = top.copy()
    bottom[:, 2] = 0.0
    # directed edges a→b of the (counter-clockwise) surface; boundary = no b→a partner
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    fwd, rev = a * V + b, b * V + a
    fs = np.sort(fwd)  # sorting, not np.unique/np.isin: several times faster here
    if (fs[1:] == fs[:-1]).any():
        raise UsageError("the mesh is not a manifold surface; cannot close it into a solid")
    boundary = ~_contains(fs, rev)
    ea, eb = a[boundary], b[boundary]
    if not _contains(np.sort(ea), eb).all() or not _contains(np.sort(eb), ea).all():
        raise UsageError("the mesh is not conforming (T-junctions); a printable solid needs a "
                         "static or rtin mesh")
    walls = np.concatenate([np.column_stack([ea, eb + V, eb]),
                            np.column_stack([ea, ea + V, eb + V])])
    out_faces = np.concatenate([faces, faces[:, ::-1] + V, walls])
    pts = np.concatenate([top, bottom])
    # edges that are each used once forwards and once backwards: a closed 2-manifold
    fa = out_faces.ravel()
    fb = out_faces[:, [1, 2, 0]].ravel()
    P = len(pts)
    f2, r2 = np.sort(fa * P + fb), np.sort(fb * P + fa)
    if not np.array_equal(f2, r2) or (f2[1:] == f2[:-1]).any():
        raise UsageError("the mesh is not conforming (T-junctions); a printable solid needs a "
                         "static or rtin mesh")
    geo = georeference(terrain, scale, offset)
    geo["base_height"] = float(base_height)
    return Solid(pts, out_faces, len(faces), scale, offset,
                 "mm" if print_size is not None else "m", float(base_height), geo)


def printable_solid(terrain: TerrainLike, m: MeshArrays, base_height: float | None = None,
                    print_size: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """:func:`solid` as (points (P, 3), faces (F, 3) wound outwards, georeference dict).

    Examples
    --------
    >>> from geoterrain.export.meshdata import mesh_arrays
    >>> pts, faces, geo = printable_solid(t, mesh_arrays(t, t.static_selection(5.0)))
    >>> len(faces) > 0 and geo["base_height"] > 0
    True
    """
    s = solid(terrain, m, base_height, print_size)
    return s.points, s.faces, s.geo


def _contains(sorted_keys: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Whether each of ``q`` is in ``sorted_keys`` (binary search)."""
    if len(sorted_keys) == 0:
        return np.zeros(len(q), bool)
    k = np.minimum(np.searchsorted(sorted_keys, q), len(sorted_keys) - 1)
    return sorted_keys[k] == q


def stl_bytes(xyz: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary STL of triangles ``faces`` over points ``xyz`` (float32, facet normals)."""
    p = xyz[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
    rec = np.zeros(len(faces), np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    rec["n"], rec["v"] = n, p
    header = f"geoterrain {__version__} printable solid".encode().ljust(80, b" ")
    return header + np.uint32(len(faces)).tobytes() + rec.tobytes()
