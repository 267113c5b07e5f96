"""A node's payload (seed 001 §2.3, L352–358): its mesh, node-relative in float32, and what
the morph and the bounds need.

The seed stores each node's final world-space mesh instead of a heightmap, relative to
the node's centre in float32, plus a normal map. Ours, per vertex of the (n + 1)² grid:

- ``rel`` (float32): the position minus the node's centre ``centre`` (float64). A node of
  depth D spans about 4 156 km / 2^D, so float32 keeps it to 2^−24 of that: 0.25 m for a
  root, 0.1 mm at depth 12 (seed summary §2.8);
- ``d`` (float64), ``r`` and ``rT`` (float64): the vertex's ray, its distance from the centre
  and the coarser surface's along the same ray: the morph slides it there
  (:mod:`geoterrain.globe.cdlod`), and collision meshes and measurements use them in
  float64 (the drawn mesh is ``rel``);
- ``normals`` and ``normals_t`` (float32): unit normals of the node's surface and of the
  coarser one (central differences over the one-sample border, so neighbours agree), the
  seed's normal map and its parent's, blended by the same k;
- ``elevation`` and ``elevation_t``: metres above the ellipsoid (unexaggerated), for colours.

A collision payload (``normals=False``) skips the normals (seed 001 L463).

Examples
--------
>>> from geoterrain.globe.surface import Surface
>>> from geoterrain.globe.model import Model
>>> from geoterrain.globe.layers import BaseLayer
>>> s = Surface(Model.get("sphere"), [], BaseLayer.ellipsoid(), node_cells=8)
>>> p = make_payload(s, (2, 1, 0, 1))
>>> p.rel.dtype, p.rel.shape, p.move > 0  # its odd vertices sit above the coarser chords
(dtype('float32'), (81, 3), True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoterrain.globe.surface import NodeKey, NodeValues, Surface

__all__ = ["Payload", "make_payload", "payload_from_values", "grid_faces"]


@dataclass
class Payload:
    """A node's payload (module docstring). ``move`` is the largest |rT − r| (M, metres),
    ``r_lo``/``r_hi`` the vertices' least and greatest distance from the centre (own and
    morph targets), ``sag`` how far below them a flat triangle of the node can dip,
    ``slack`` the relative slack of the error chain (:mod:`geoterrain.globe.errors`) and
    ``slope`` the steepest radial change per metre along a cell edge."""

    key: NodeKey
    centre: np.ndarray
    rel: np.ndarray
    d: np.ndarray
    r: np.ndarray
    rT: np.ndarray
    normals: np.ndarray | None
    normals_t: np.ndarray | None
    elevation: np.ndarray
    elevation_t: np.ndarray
    move: float
    r_lo: float
    r_hi: float
    sag: float
    slack: float
    slope: float

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.rel, self.d, self.r, self.rT, self.elevation,
                                      self.elevation_t)
                   if a is not None) + sum(a.nbytes for a in (self.normals, self.normals_t)
                                           if a is not None)

    def positions(self, k: np.ndarray | float = 0.0) -> np.ndarray:
        """float64 positions (V, 3) morphed by ``k`` (per vertex or one value)."""
        return self.d * (self.r + k * (self.rT - self.r))[:, None]


def grid_faces(n: int) -> np.ndarray:
    """Triangles (2n², 3) of an (n + 1)² vertex grid, each cell split on its short diagonal
    (the RT rhombus's V1–V3 direction: (i, j + 1)–(i + 1, j)), outward (counter-clockwise
    seen from outside).

    Examples
    --------
    >>> grid_faces(1).tolist()
    [[0, 1, 2], [1, 3, 2]]
    """
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, d = a + 1, a + (n + 1)
    c = d + 1
    return np.stack([np.stack([a, b, d], 1), np.stack([b, c, d], 1)], 1).reshape(-1, 3)


def _normals(P: np.ndarray) -> np.ndarray:
    """Unit normals of the inner grid of positions P (m + 2, m + 2, 3) by central differences."""
    du = P[1:-1, 2:] - P[1:-1, :-2]
    dv = P[2:, 1:-1] - P[:-2, 1:-1]
    nrm = np.cross(du, dv)
    nrm /= np.linalg.norm(nrm, axis=-1)[..., None]
    return nrm.reshape(-1, 3).astype(np.float32)


def payload_from_values(s: Surface, v: NodeValues, normals: bool = True) -> Payload:
    """The :class:`Payload` of a node from its :class:`~geoterrain.globe.surface.NodeValues`."""
    inn = v.inner
    d = v.d[inn]
    r, rT = v.r[inn], v.rT[inn]
    m = d.shape[0]
    P = d * r[..., None]
    mid = m // 2
    centre = d[mid, mid] * 0.5 * (r.min() + r.max())
    rel = (P - centre).reshape(-1, 3).astype(np.float32)
    t0 = s.model.surface_distance(d)
    up = s.model.up(v.lon[inn], v.lat[inn])
    cosu = np.einsum("...j,...j", d, up)
    elev = ((r - t0) * cosu / s.scale).reshape(-1).astype(np.float32)
    elev_t = ((rT - t0) * cosu / s.scale).reshape(-1).astype(np.float32)
    nrm = nrm_t = None
    if normals:
        nrm = _normals(v.d * v.r[..., None])
        nrm_t = _normals(v.d * v.rT[..., None])
    lo = float(min(r.min(), rT.min()))
    hi = float(max(r.max(), rT.max()))
    # the angle of a cell's long diagonal: no flat triangle of the node reaches farther from
    # its corners' rays, so none dips below lo·cos(θ/2)
    diag = np.einsum("...j,...j", d[:-1, :-1], d[1:, 1:])
    theta = float(np.arccos(np.clip(diag.min(), -1.0, 1.0)))
    sag = lo * (1.0 - np.cos(theta / 2.0))
    fc = v.fn[inn]
    fr = max(float((np.maximum(np.maximum(fc[:-1, :-1], fc[1:, 1:]),
                               np.maximum(fc[1:, :-1], fc[:-1, 1:]))
                    / np.minimum(np.minimum(fc[:-1, :-1], fc[1:, 1:]),
                                 np.minimum(fc[1:, :-1], fc[:-1, 1:]))).max()), 1.0)
    slack = (hi / lo) ** 2 * fr - 1.0
    eu = np.linalg.norm(P[:, 1:] - P[:, :-1], axis=-1)
    ev = np.linalg.norm(P[1:] - P[:-1], axis=-1)
    slope = float(max((np.abs(np.diff(r, axis=1)) / eu).max(),
                      (np.abs(np.diff(r, axis=0)) / ev).max()))
    return Payload(v.key, centre, rel, np.ascontiguousarray(d.reshape(-1, 3)),
                   np.ascontiguousarray(r.reshape(-1)), np.ascontiguousarray(rT.reshape(-1)),
                   nrm, nrm_t, elev, elev_t,
                   float(np.abs(rT - r).max()), lo, hi, float(sag), float(slack), slope)


def make_payload(s: Surface, key: NodeKey, normals: bool = True) -> Payload:
    """Generate node ``key``'s payload (float64 throughout, float32 at the end)."""
    return payload_from_values(s, s.values(key), normals)
