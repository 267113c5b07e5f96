"""Tests for the independent mesh-vs-DEM error measurement."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from geoterrain.testing.measure import (
    EPS,
    ScreenError,
    VerticalError,
    mesh_height_range_on_grid,
    mesh_heights_on_grid,
    picture_coordinates,
    picture_displacement,
    screen_space_error,
    vertical_error,
    vertical_error_polydata,
)


def uniform_mesh(N: int, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Uniform union-jack triangulation of an N x N grid with cells of side s."""
    n = (N - 1) // s
    a, b = (x.ravel() for x in np.mgrid[0:n, 0:n])

    def vid(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        return r * (n + 1) + c

    c00, c01, c10, c11 = vid(a, b), vid(a, b + 1), vid(a + 1, b), vid(a + 1, b + 1)
    main = (a % 2) == (b % 2)  # diagonal through the corner with odd row/s and col/s
    f1 = np.where(main[:, None], np.c_[c00, c11, c10], np.c_[c01, c10, c00])
    f2 = np.where(main[:, None], np.c_[c00, c11, c01], np.c_[c01, c10, c11])
    r, c = np.mgrid[0 : n + 1, 0 : n + 1]
    return np.c_[r.ravel(), c.ravel()] * s, np.r_[f1, f2]


def naive_worst(vij, faces, vz, shape):
    """Per-triangle, per-sample loop: worst-case low/high mesh height at every sample."""
    H, W = shape
    lo = np.full(shape, np.inf)
    hi = np.full(shape, -np.inf)
    for f in faces:
        (i0, j0), (i1, j1), (i2, j2) = (np.asarray(vij[k], float) for k in f)
        z0, z1, z2 = (float(vz[k]) for k in f)
        det = (i1 - i0) * (j2 - j0) - (i2 - i0) * (j1 - j0)
        if det == 0:
            continue
        for i in range(max(0, int(np.floor(min(i0, i1, i2)))),
                       min(H - 1, int(np.ceil(max(i0, i1, i2)))) + 1):
            for j in range(max(0, int(np.floor(min(j0, j1, j2)))),
                           min(W - 1, int(np.ceil(max(j0, j1, j2)))) + 1):
                # Barycentrics by sub-triangle areas (a different formula from the module).
                w0 = ((i1 - i) * (j2 - j) - (i2 - i) * (j1 - j)) / det
                w1 = ((i2 - i) * (j0 - j) - (i0 - i) * (j2 - j)) / det
                w2 = 1.0 - w0 - w1
                if min(w0, w1, w2) >= -EPS:
                    z = w0 * z0 + w1 * z1 + w2 * z2
                    lo[i, j] = min(lo[i, j], z)
                    hi[i, j] = max(hi[i, j], z)
    return lo, hi


def naive_vertical(vij, faces, vz, Z, valid):
    lo, hi = naive_worst(vij, faces, vz, Z.shape)
    covered = np.isfinite(hi)
    err = np.maximum(hi - Z, Z - lo)
    sel = covered & valid
    return err[sel], int(np.count_nonzero(valid & ~covered))


@pytest.mark.fast
def test_plane_mesh_has_zero_error() -> None:
    N = 33
    vij, faces = uniform_mesh(N, 8)
    plane = lambda i, j: 3.5 * i - 1.25 * j + 100.0  # noqa: E731
    vz = plane(vij[:, 0], vij[:, 1]).astype(float)
    i, j = np.mgrid[0:N, 0:N]
    Z = plane(i, j).astype(float)
    e = vertical_error(vij, faces, vz, Z, np.ones((N, N), bool))
    assert isinstance(e, VerticalError)
    assert e.max < 1e-9 and e.mean < 1e-9 and e.p99 < 1e-9
    assert e.n_samples == N * N and e.n_uncovered_valid == 0
    zmesh, covered = mesh_heights_on_grid(vij, faces, vz, (N, N))
    assert covered.all()
    np.testing.assert_allclose(zmesh, Z, atol=1e-9)


@pytest.mark.fast
def test_two_triangles_over_bumpy_grid_matches_brute_force() -> None:
    N = 17
    rng = np.random.default_rng(0)
    Z = rng.normal(0.0, 10.0, (N, N)) + np.add.outer(np.arange(N), np.arange(N)) * 2.0
    vij = np.array([[0, 0], [0, N - 1], [N - 1, 0], [N - 1, N - 1]])
    faces = np.array([[0, 3, 2], [0, 3, 1]])  # split along the (0, 0)-(N-1, N-1) diagonal
    vz = np.array([Z[0, 0], Z[0, N - 1], Z[N - 1, 0], Z[N - 1, N - 1]])
    worst = 0.0
    total, count = 0.0, 0
    for i in range(N):
        for j in range(N):
            if i >= j:  # lower-left triangle (0,0), (N-1,N-1), (N-1,0)
                z = vz[0] + (vz[2] - vz[0]) * (i - j) / (N - 1) + (vz[3] - vz[0]) * j / (N - 1)
            else:
                z = vz[0] + (vz[1] - vz[0]) * (j - i) / (N - 1) + (vz[3] - vz[0]) * i / (N - 1)
            worst = max(worst, abs(z - Z[i, j]))
            total += abs(z - Z[i, j])
            count += 1
    e = vertical_error(vij, faces, vz, Z, np.ones((N, N), bool))
    assert e.max == pytest.approx(worst, rel=1e-12, abs=1e-12)
    assert e.mean == pytest.approx(total / count, rel=1e-12)
    assert e.n_samples == N * N


@st.composite
def subset_meshes(draw):
    k = draw(st.integers(1, 4))
    N = 2**k + 1
    s = 2 ** draw(st.integers(0, k - 1))
    vij, faces = uniform_mesh(N, s)
    keep = draw(st.lists(st.booleans(), min_size=len(faces), max_size=len(faces)))
    faces = faces[np.array(keep, bool)]
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    vz = rng.normal(0.0, 50.0, len(vij))
    Z = rng.normal(0.0, 50.0, (N, N))
    valid = rng.random((N, N)) < 0.8
    return vij, faces, vz, Z, valid


@pytest.mark.fast
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(subset_meshes())
def test_random_subsets_agree_with_naive_loop(case) -> None:
    vij, faces, vz, Z, valid = case
    errs, n_unc = naive_vertical(vij, faces, vz, Z, valid)
    e = vertical_error(vij, faces, vz, Z, valid)
    assert e.n_samples == errs.size
    assert e.n_uncovered_valid == n_unc
    if errs.size:
        assert e.max == pytest.approx(errs.max(), abs=1e-9)
        assert e.mean == pytest.approx(errs.mean(), abs=1e-9)
        assert e.p99 == pytest.approx(np.percentile(errs, 99), abs=1e-9)
    lo, hi = naive_worst(vij, faces, vz, Z.shape)
    zmin, zmax = mesh_height_range_on_grid(vij, faces, vz, Z.shape)
    cov = np.isfinite(hi)
    np.testing.assert_array_equal(np.isfinite(zmax), cov)
    np.testing.assert_allclose(zmin[cov], lo[cov], atol=1e-9)
    np.testing.assert_allclose(zmax[cov], hi[cov], atol=1e-9)
    zmesh, covered = mesh_heights_on_grid(vij, faces, vz, Z.shape)
    np.testing.assert_array_equal(covered, cov)
    assert np.all((zmesh[cov] >= lo[cov] - 1e-9) & (zmesh[cov] <= hi[cov] + 1e-9))


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.integers(1, 12),
    st.booleans(),
)
def test_arbitrary_overlapping_triangles_agree_with_naive_loop(seed, n_tri, integer) -> None:
    """Overlapping, degenerate, off-grid and partly outside triangles."""
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(1, 14)), int(rng.integers(1, 14)))
    vij = rng.uniform(-3.0, 16.0, (3 * n_tri, 2))
    if integer:
        vij = np.round(vij)
    faces = rng.integers(0, len(vij), (n_tri, 3))
    vz = rng.normal(0.0, 10.0, len(vij))
    Z = rng.normal(0.0, 10.0, shape)
    valid = np.ones(shape, bool)
    errs, n_unc = naive_vertical(vij, faces, vz, Z, valid)
    e = vertical_error(vij, faces, vz, Z, valid)
    assert e.n_uncovered_valid == n_unc
    assert e.n_samples == errs.size
    if errs.size:
        assert e.max == pytest.approx(errs.max(), abs=1e-7)


@pytest.mark.fast
def test_uncovered_and_invalid_samples() -> None:
    N = 9
    vij = np.array([[0, 0], [0, 8], [8, 0]])
    faces = np.array([[0, 1, 2]])  # covers i + j <= 8
    Z = np.zeros((N, N))
    valid = np.ones((N, N), bool)
    valid[0, 0] = False
    Z[8, 8] = 1e6  # uncovered: must not count
    e = vertical_error(vij, faces, np.ones(3), Z, valid)
    i, j = np.mgrid[0:N, 0:N]
    inside = i + j <= 8
    assert e.n_samples == int(inside.sum()) - 1
    assert e.n_uncovered_valid == int((~inside).sum())
    assert e.max == pytest.approx(1.0)
    zmesh, covered = mesh_heights_on_grid(vij, faces, np.ones(3), (N, N))
    np.testing.assert_array_equal(covered, inside)
    assert np.isnan(zmesh[~inside]).all()


@pytest.mark.fast
def test_empty_mesh() -> None:
    e = vertical_error(np.zeros((0, 2)), np.zeros((0, 3), int), np.zeros(0), np.zeros((3, 4)))
    assert e.n_samples == 0 and e.n_uncovered_valid == 12 and e.max == 0.0


def _scene(N: int, spacing: float = 10.0):
    i, j = np.mgrid[0:N, 0:N].astype(float)
    X = j * spacing
    Y = -i * spacing
    Z = 5.0 * np.sin(i / 3.0) + 0.5 * j
    return X, Y, Z


ALL_INSIDE = np.tile([0.0, 0.0, 0.0, 1.0], (6, 1))


@pytest.mark.fast
def test_screen_space_error_of_constant_offset() -> None:
    N, offset, lam = 17, 2.5, 800.0
    X, Y, Z = _scene(N)
    vij, faces = uniform_mesh(N, 1)  # every sample is a vertex: error is exactly the offset
    vz = Z[vij[:, 0], vij[:, 1]] + offset
    eye = np.array([30.0, -40.0, 200.0])
    e = screen_space_error(vij, faces, vz, X, Y, Z, np.ones((N, N), bool), eye, ALL_INSIDE, lam)
    assert isinstance(e, ScreenError)
    dist = np.sqrt((X - eye[0]) ** 2 + (Y - eye[1]) ** 2 + (Z - eye[2]) ** 2)
    rho = lam * offset / dist
    assert e.n_samples == N * N and e.n_uncovered == 0
    assert e.max == pytest.approx(rho.max(), rel=1e-12)
    assert e.mean == pytest.approx(rho.mean(), rel=1e-12)
    # A single sample: rho = lam * offset / distance.
    valid = np.zeros((N, N), bool)
    valid[4, 7] = True
    e1 = screen_space_error(vij, faces, vz, X, Y, Z, valid, eye, ALL_INSIDE, lam)
    assert e1.n_samples == 1
    assert e1.max == pytest.approx(lam * offset / dist[4, 7], rel=1e-12)


@pytest.mark.fast
def test_samples_outside_frustum_are_excluded() -> None:
    N, lam = 17, 1000.0
    X, Y, Z = _scene(N)
    vij, faces = uniform_mesh(N, 1)
    vz = Z[vij[:, 0], vij[:, 1]].copy()
    # Huge error only in columns j >= 10 (X >= 100).
    far = vij[:, 1] >= 10
    vz[far] += 1000.0
    planes = ALL_INSIDE.copy()
    planes[0] = [-1.0, 0.0, 0.0, 95.0]  # inside when X <= 95, i.e. j <= 9
    eye = np.array([0.0, 0.0, 300.0])
    valid = np.ones((N, N), bool)
    e = screen_space_error(vij, faces, vz, X, Y, Z, valid, eye, planes, lam)
    assert e.n_samples == N * 10
    # Column 9 samples touch triangles reaching column 10: the worst over them counts.
    dist = np.sqrt((X - eye[0]) ** 2 + (Y - eye[1]) ** 2 + (Z - eye[2]) ** 2)
    assert e.max == pytest.approx(0.0, abs=1e-9)
    assert np.isfinite(dist).all()
    # Everything outside: nothing measured.
    planes[1] = [1.0, 0.0, 0.0, -1e9]
    e0 = screen_space_error(vij, faces, vz, X, Y, Z, valid, eye, planes, lam)
    assert e0.n_samples == 0 and e0.max == 0.0


@pytest.mark.fast
def test_screen_space_uncovered_inside_frustum() -> None:
    N = 9
    X, Y, Z = _scene(N)
    vij = np.array([[0, 0], [0, 8], [8, 0]])
    faces = np.array([[0, 1, 2]])
    e = screen_space_error(vij, faces, np.zeros(3), X, Y, Z, None,
                           np.array([0.0, 0.0, 100.0]), ALL_INSIDE, 1.0)
    i, j = np.mgrid[0:N, 0:N]
    assert e.n_samples == int((i + j <= 8).sum())
    assert e.n_uncovered == int((i + j > 8).sum())


@pytest.mark.fast
def test_polydata_wrapper() -> None:
    pv = pytest.importorskip("pyvista")
    N = 9
    X, Y, Z = _scene(N)
    vij, faces = uniform_mesh(N, 4)
    vz = Z[vij[:, 0], vij[:, 1]] + 0.0
    pts = np.c_[X[vij[:, 0], vij[:, 1]], Y[vij[:, 0], vij[:, 1]], vz]
    mesh = pv.PolyData(pts, np.c_[np.full(len(faces), 3), faces].ravel())
    mesh.point_data["grid_ij"] = vij.astype(float)
    xyz = np.stack([X, Y, Z], axis=-1)
    got = vertical_error_polydata(mesh, xyz)
    want = vertical_error(vij, faces, vz, Z, np.ones((N, N), bool))
    assert got == want
    xyz[0, 0, 2] = np.nan  # NaN heights are invalid
    assert vertical_error_polydata(mesh, xyz).n_samples == N * N - 1


@pytest.mark.fast
def test_vectorised_rasteriser_on_a_large_uniform_mesh() -> None:
    N = 257
    vij, faces = uniform_mesh(N, 2)
    rng = np.random.default_rng(1)
    vz = rng.normal(0, 1, len(vij))
    zmesh, covered = mesh_heights_on_grid(vij, faces, vz, (N, N))
    assert covered.all()
    # Every vertex sample carries its own height.
    np.testing.assert_allclose(zmesh[vij[:, 0], vij[:, 1]], vz, atol=1e-12)
    # Cell centres on the diagonal: mean of the diagonal's end points.
    zmin, zmax = mesh_height_range_on_grid(vij, faces, vz, (N, N))
    np.testing.assert_allclose(zmin, zmax, atol=1e-9)


@pytest.mark.fast
def test_non_finite_and_degenerate_triangles_are_not_drawn() -> None:
    vij = np.array([[0.0, 0.0], [0.0, 4.0], [4.0, 0.0], [np.nan, 1.0], [2.0, 2.0]])
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 4, 4], [0, 1, 2]])
    vz = np.array([1.0, 1.0, np.nan, 0.0, 0.0])
    with np.errstate(all="raise"):
        zmesh, covered = mesh_heights_on_grid(vij, faces, vz, (5, 5))
    assert not covered.any() and np.isnan(zmesh).all()


@pytest.mark.slow
def test_two_million_triangles_on_4097_grid() -> None:
    N = 4097
    vij, faces = uniform_mesh(N, 4)
    assert len(faces) == 2 * 1024**2
    vz = np.random.default_rng(0).normal(0, 1, len(vij))
    zmesh, covered = mesh_heights_on_grid(vij, faces, vz, (N, N))
    assert covered.all()
    np.testing.assert_allclose(zmesh[vij[:, 0], vij[:, 1]], vz, atol=1e-9)


@pytest.mark.fast
def test_picture_displacement_counts_samples_drawn_in_from_outside() -> None:
    """A sample whose true point is outside the frustum but whose drawn point is inside
    is in the picture: it counts, with its displacement; one outside at both heights
    does not."""
    from types import SimpleNamespace

    N = 9
    i, j = np.mgrid[0:N, 0:N].astype(float)
    X, Y, Z = j * 10.0, -i * 10.0, np.full((N, N), -1.0)  # every true point at z = −1
    vij, faces = uniform_mesh(N, 1)
    vz = np.full(len(vij), -1.0)
    lifted = vij[:, 1] >= 5  # drawn at z = 0 from column 5 on
    vz[lifted] = 0.0
    planes = ALL_INSIDE.copy()
    planes[0] = [0.0, 0.0, 1.0, 0.5]  # inside when z >= −0.5: no true point is
    cam = SimpleNamespace(look_from=(40.0, -40.0, 200.0), look_at=(40.0, -40.0, 0.0),
                          up=(0.0, 1.0, 0.0), fov_y_deg=60.0, size=(400, 400), planes=planes)
    e, disp = picture_displacement(vij, faces, vz, X, Y, Z, None, cam, per_sample=True)
    shown = j >= 5  # column 4 is drawn at −1 (its triangles reach column 5 only at it)
    assert e.n_samples == int(shown.sum()) and e.n_uncovered == 0
    view = (cam.look_from, cam.look_at, cam.up, cam.fov_y_deg, cam.size)
    c0, r0, _ = picture_coordinates(X[shown], Y[shown], Z[shown], *view)
    c1, r1, _ = picture_coordinates(X[shown], Y[shown], np.zeros(int(shown.sum())), *view)
    np.testing.assert_allclose(np.sort(disp), np.sort(np.hypot(c1 - c0, r1 - r0)))
    assert e.max > 0.0
