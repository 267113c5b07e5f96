"""Horizon culling for rtin against the drawn surface, not only the true one.

rtin draws a tile that horizon culling hides with its ancestors' triangles (up to the
tile's δ above the true surface), and draws the terrain in front up to τ/λ × its
distance below the true surface (LP eq. 2: an inactive vertex has λδ ≤ τ(d − r)). So
the culling must hide every point of a hidden tile raised by the tile's δ behind nearer
terrain lowered by τ/λ × distance (:mod:`geoterrain.lod.occlusion`'s last argument).
Checked here by a plain ray march that shares no code with the culling, and end to end:
no sample the drawn picture shows (true point seen over the true surface, or drawn
point over the drawn surface) moves more than τ pixels
(:func:`geoterrain.testing.measure.picture_displacement` counts hidden samples too).
"""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from conftest import write_tif
from geoterrain.core.view import View
from geoterrain.lod import rtin
from geoterrain.lod.tiles import tile_index
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    picture_coordinates,
    picture_displacement,
)
from geoterrain.testing.reference import _uj_height, visible_samples

FINE = 0.05  # cells: the march's step where a coarse step may miss a thin crossing


def _store(tmp_path, n: int, seed: int, amp: float, ridge: float):
    """A rough fBm with a ridge across its middle rows: low views from the south side
    see over it, and the ground beyond is partly hidden."""
    from geoterrain.ingest.synth import generate

    z = generate("fbm", (n, n), seed=seed)
    z = amp * (z - z.min()) / max(float(np.ptp(z)), 1e-12)
    z[n // 2 - 4 : n // 2 + 4] += ridge
    src = write_tif(tmp_path / "f.tif", z, spacing=10.0)
    return geoterrain.open(geoterrain.preprocess(src, tmp_path / "f.geoterrain", tile_size=16))


@pytest.fixture(scope="module")
def fbm(tmp_path_factory):
    return _store(tmp_path_factory.mktemp("drawn"), 129, 7, 150.0, 120.0)


def _eye_ij(t, view) -> tuple[float, float]:
    """The eye's fractional (row, column) on an affine frame."""
    f = t.frame
    cx, cy = f.scene_to_crs(np.array([view.eye[0]]), np.array([view.eye[1]]))
    a, b, c, d, e, g = f.transform
    det = a * e - b * d
    return (
        float((a * (cy[0] - g) - d * (cx[0] - c)) / det - 0.5),
        float((e * (cx[0] - c) - b * (cy[0] - g)) / det - 0.5),
    )


def _view(t, seed: int, tau_k: int, size_k: int) -> tuple[View, float]:
    """A low view from south of the ridge, looking north across it (yaw ±40°, pitch
    −6° … 4°), and a τ of 1, 2 or 4 pixels; 160 × 90 or 320 × 180 pixels."""
    X, Y, Z = t.scene_xyz()
    rng = np.random.default_rng(seed)
    n = Z.shape[0]
    i, j = int(rng.integers(n * 5 // 8, n - 2)), int(rng.integers(2, n - 2))
    eye = np.array(
        [
            X[i, j] + rng.uniform(-4, 4),
            Y[i, j] + rng.uniform(-4, 4),
            Z[i, j] + rng.uniform(1.0, 20.0),
        ]
    )
    yaw, pitch = np.radians(rng.uniform(-40, 40)), np.radians(rng.uniform(-6, 4))
    look = eye + 500.0 * np.array(
        [np.sin(yaw) * np.cos(pitch), np.cos(yaw) * np.cos(pitch), np.sin(pitch)]
    )
    size = ((160, 90), (320, 180), (640, 360))[size_k]
    return View(tuple(eye), tuple(look), fov_y_deg=45.0, size=size), (1.0, 2.0, 4.0)[tau_k]


def _rtin_hidden(t, view: View, tau: float) -> np.ndarray:
    """The index rows rtin's selection culls (its own call of ``hidden_rows``)."""
    got = []
    real = rtin.hidden_rows

    def spy(*a, **k):
        got.append(real(*a, **k))
        return got[-1]

    with mock.patch.object(rtin, "hidden_rows", spy):
        rtin.view_active(t, tile_index(t), view, tau)
    return np.flatnonzero(got[0]) if got else np.zeros(0, np.int64)


def _blocked(z, eye_ij, ez, pi, pj, pz, before):
    """Whether the segment from each point (row pi, column pj, height pz) to the eye
    passes under the surface ``z`` (union-jack, as drawn) at a horizontal distance from
    the eye under ``before`` (cells): a plain march in steps of :data:`FINE` cells."""
    ok = np.ones(z.shape, bool)
    di, dj = eye_ij[0] - pi, eye_ij[1] - pj
    n = np.maximum(np.ceil(np.hypot(di, dj) / FINE), 1)
    out = np.zeros(len(pi), bool)
    for k in range(1, int(n.max())):
        s = np.minimum(k / n, 1.0)
        qi, qj = pi + s * di, pj + s * dj
        h = _uj_height(z, ok, qi, qj)
        near = (1 - s) * np.hypot(di, dj) < before
        out |= near & (s < 1) & (pz + s * (ez - pz) < h)
    return out


def _hidden_points(t, view, tau, rows, sink):
    """For the hidden rows: their full-resolution samples inside the frustum, raised by
    the tile's δ, and whether nearer terrain lowered by ``sink`` × distance hides each."""
    X, Y, Z = t.scene_xyz()
    ix = tile_index(t)
    S = 1 << t.grid.t
    e = np.asarray(view.eye, np.float64)
    dist = np.sqrt((X - e[0]) ** 2 + (Y - e[1]) ** 2 + (Z - e[2]) ** 2)
    low = Z - sink * dist  # the drawn surface is at least this high where LP draws it
    eij = _eye_ij(t, view)
    cell = float(np.hypot(X[0, 1] - X[0, 0], Y[0, 1] - Y[0, 0]))
    bad = total = 0
    for r in rows:
        L, x, y = (int(k) for k in ix.keys[r])
        w = S << L
        i, j = np.mgrid[
            y * w : min((y + 1) * w, Z.shape[0] - 1) + 1,
            x * w : min((x + 1) * w, Z.shape[1] - 1) + 1,
        ]
        i, j = i.ravel(), j.ravel()
        pz = Z[i, j] + float(ix.delta_max[r])
        P = np.stack([X[i, j], Y[i, j], pz], 1)
        inside = ((P @ view.planes[:, :3].T + view.planes[:, 3]) >= 0).all(1)
        if not inside.any():
            continue
        i, j, pz = i[inside], j[inside], pz[inside]
        g = float(ix.radius_max[r])  # the box rtin tests: grown by the spheres' radius
        dx = np.maximum.reduce([ix.lo[r, 0] - g - e[0], e[0] - ix.hi[r, 0] - g, 0.0])
        dy = np.maximum.reduce([ix.lo[r, 1] - g - e[1], e[1] - ix.hi[r, 1] - g, 0.0])
        before = float(np.hypot(dx, dy)) / cell
        hid = _blocked(low, eij, float(e[2]), i.astype(float), j.astype(float), pz, before)
        bad += int((~hid).sum())
        total += len(hid)
    return bad, total


@pytest.mark.fast
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.integers(0, 2), st.integers(0, 1))
def test_a_hidden_tile_raised_by_its_delta_stays_behind_lowered_terrain(fbm, seed, tau_k, size_k):
    """Every sample of a tile rtin culls, raised by the tile's largest δ (its ancestors'
    triangles may draw it that high), is hidden behind nearer terrain lowered by
    τ/λ × its distance (how low LP may draw it), by a ray march of its own."""
    view, tau = _view(fbm, seed, tau_k, size_k)
    rows = _rtin_hidden(fbm, view, tau)
    sink = tau / view.terms(tau, depth=rtin.DEPTH).lam
    bad, total = _hidden_points(fbm, view, tau, rows, sink)
    assert bad == 0, f"{bad} of {total} points of culled tiles seen ({view}, τ = {tau})"


def _seen_displacement(t, view: View, tau: float) -> tuple[float, float]:
    """rtin's largest picture displacement over the samples the picture shows (true
    point seen over the true surface, or drawn point over the drawn surface, by the
    oracle's ray march; where the mesh leaves a sample uncovered, outside the frustum,
    its true height stands in), and over every sample the measure counts."""
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    sel = t.select(view, tau, "rtin", occlusion=True, reuse=False)
    vz = np.asarray(sel.mesh.points)[:, 2]
    faces = sel.surface_faces()
    every = picture_displacement(sel.ij, faces, vz, X, Y, Z, valid, view).max
    if every <= tau:
        return every, every
    lo, _ = mesh_height_range_on_grid(sel.ij, faces, vz, Z.shape)  # conforming: lo = hi
    drawn = valid & np.isfinite(lo)
    cam = (view.look_from, view.look_at, view.up, view.fov_y_deg, view.size)
    c0, r0, _ = picture_coordinates(X[drawn], Y[drawn], Z[drawn], *cam)
    c1, r1, _ = picture_coordinates(X[drawn], Y[drawn], lo[drawn], *cam)
    over = np.zeros(Z.shape, bool)
    over[drawn] = np.hypot(c1 - c0, r1 - r0) > tau
    eij, ez = _eye_ij(t, view), float(view.eye[2])

    def seen(z):  # a coarse march, what it sees confirmed in fine steps
        c = visible_samples(z, valid, eij, ez, over)
        return visible_samples(z, valid, eij, ez, c, step=FINE) if c.any() else c

    shown = seen(Z) | seen(np.where(drawn, lo, Z))
    keep = valid & ~(over & ~shown)
    return picture_displacement(sel.ij, faces, vz, X, Y, Z, keep, view).max, every


@pytest.mark.fast
@pytest.mark.parametrize("seed", [3, 11])
def test_no_sample_the_picture_shows_moves_more_than_tau(fbm, seed):
    """With culling on, the samples of culled tiles are drawn coarse (counted over every
    sample, the measure exceeds τ), yet none the picture shows moves more than τ."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(4):
        view, tau = _view(fbm, int(rng.integers(2**31)), int(rng.integers(3)), 1)
        shown, every = _seen_displacement(fbm, view, tau)
        worst = max(worst, every / tau)
        assert shown <= tau * (1 + 1e-9), (shown, view, tau)
    assert worst > 1.0  # something was culled and drawn coarse: the check is exercised


@pytest.mark.fast
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.floats(0.0, 0.05), st.floats(0.0, 60.0))
def test_lift_and_sink_only_reveal(fbm, seed, sink, lift):
    """Raising the boxes' tops and lowering the occluders hides a subset of what plain
    culling hides, and lowering them further a subset again."""
    from geoterrain.lod.occlusion import hidden_rows

    view, _ = _view(fbm, seed, 0, 1)
    ix = tile_index(fbm)
    up = np.full(len(ix.keys), lift)
    plain = hidden_rows(fbm, view, ix.radius_max)
    drawn = hidden_rows(fbm, view, ix.radius_max, lift=up, sink=sink)
    assert not (drawn & ~plain).any()
    deeper = hidden_rows(fbm, view, ix.radius_max, lift=up, sink=2 * sink + 0.01)
    assert not (deeper & ~drawn).any()
