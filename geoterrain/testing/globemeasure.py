"""Measured screen-space error ρ of a globe's mesh against a store's own samples.

The truth is a store as it holds its heights (the decoded full resolution): each sample
placed by pyproj at its geodetic lon, lat and height (EPSG:4979 → EPSG:4978). The drawn
mesh and the samples are carried by a central (gnomonic) projection from the planet's
centre onto the tangent plane at the store: a ray from the centre becomes one point
(x, y), a flat triangle a flat triangle, and along the rays through a flat triangle 1/ρ
(ρ the distance along the plane's normal axis) is affine in (x, y).
:func:`geoterrain.testing.metricmeasure.metric_errors` then finds each sample's triangle
and the mesh's 1/ρ there, with no code of the globe in between; the radial gap is
|Δ(1/ρ)|·ρ_mesh·ρ_true·|(x, y, 1)|, and ρ_px = λ·gap / ‖sample − eye‖ (the flat
measure's definition). The store's outer ``border`` samples, where it blends into the
layer under it, are left out.

Examples
--------
>>> P = np.array([[6.4e6, 0.0, 0.0]])
>>> x, y, w = gnomonic(P, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]))
>>> float(x[0]), float(w[0])
(0.0, 6400000.0)
"""

from __future__ import annotations

import numpy as np
from pyproj import Transformer

from geoterrain.testing.metricmeasure import metric_errors

__all__ = ["store_truth", "gnomonic", "measured_rho"]


def store_truth(terrain, border: int) -> np.ndarray:
    """(N, 3) ECEF float64 of a geographic store's samples as it holds them (codec's full
    resolution), ``border`` samples in from its edges, placed by pyproj."""
    T = terrain.frame.transform
    z = terrain.scene_xyz()[2] / (terrain.frame.z_to_m * terrain.frame.z_scale)
    lat = T[5] + (np.arange(z.shape[0]) + 0.5) * T[4]
    lon = T[2] + (np.arange(z.shape[1]) + 0.5) * T[0]
    LON, LAT = np.meshgrid(lon, lat)
    x, y, zz = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(
        LON.ravel(), LAT.ravel(), z.ravel())
    truth = np.stack([x, y, zz], -1)
    core = np.zeros(z.shape, bool)
    core[border:-border, border:-border] = True
    return truth[core.ravel() & np.isfinite(z).ravel()]


def gnomonic(P: np.ndarray, c: np.ndarray, e1: np.ndarray, e2: np.ndarray):
    """(x, y, ρ) of points P by central projection onto the plane c·p = 1 (unit c)."""
    w = P @ c
    return (P @ e1) / w, (P @ e2) / w, w


def measured_rho(sel, truth: np.ndarray, view, centre_dir: np.ndarray
                 ) -> tuple[float, int, int]:
    """(worst ρ in px, samples measured, samples in the frustum under no triangle) of the
    globe selection ``sel`` (its float64 ``world`` vertices and ``faces``) against
    ``truth`` (:func:`store_truth`) seen from ``view``; ``centre_dir``: the store's
    direction from the planet's centre."""
    c = centre_dir / np.linalg.norm(centre_dir)
    e1 = np.cross([0.0, 0.0, 1.0], c)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    W = sel.world
    near = (W @ c) / np.linalg.norm(W, axis=1) > 0.995  # the mesh around the store
    F = sel.faces[near[sel.faces].all(1)]
    vx, vy, vw = gnomonic(W, c, e1, e2)
    sx, sy, sw = gnomonic(truth, c, e1, e2)
    eye = np.asarray(view.eye, np.float64)
    inside = np.ones(len(truth), bool)
    for a, b, cc, d in view.planes:  # the frustum's inward planes, in ECEF
        inside &= truth @ np.array([a, b, cc]) + d >= 0
    err, outside = metric_errors(F, vx, vy, 1.0 / vw, sx, sy, 1.0 / sw, inside)
    ok = np.isfinite(err)
    if not ok.any():
        return 0.0, 0, int(outside.sum())
    # 1/ρ_mesh = 1/ρ_true ± err: the radial gap along the sample's ray
    rho_mesh = 1.0 / (1.0 / sw[ok] + err[ok])
    gap = err[ok] * rho_mesh * sw[ok] * np.sqrt(1 + sx[ok] ** 2 + sy[ok] ** 2)
    dist = np.linalg.norm(truth[ok] - eye, axis=1)
    return float((view.lam * gap / dist).max()), int(ok.sum()), int(outside.sum())
