"""Streamed static meshes: the same mesh as the in-memory path, whatever the chunk size."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.export.meshdata import with_elevation
from geoterrain.export.meshfiles import write_mesh
from geoterrain.export.meshstream import STREAM_FORMATS, check_in_memory, write_static_mesh
from geoterrain.ingest.synth import generate
from geoterrain.lod.stream import static_chunks
from tests.conftest import write_tif


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """A square store, and a non-square one with a hole (invalid samples to drop)."""
    d = tmp_path_factory.mktemp("ms")
    a = write_tif(d / "a.tif", generate("fbm", 65, seed=3))
    z = generate("ridged", (77, 100), seed=5).astype(np.float32)
    z[30:41, 20:37] = np.nan
    b = write_tif(d / "b.tif", z, nodata=np.nan)
    # the square (the edge-padded static mesh; a root grid's: test_root_grid_export.py)
    ts = [geoterrain.open(geoterrain.preprocess(a, d / "a.geoterrain", tile_size=16)),
          geoterrain.open(geoterrain.preprocess(b, d / "b.geoterrain", tile_size=32,
                                                root_grid=False))]
    yield ts
    for t in ts:
        t.close()


def _keys(ij: np.ndarray, N: int) -> np.ndarray:
    """One integer per place: grid indices in 2^-20 steps (cut points are fractional)."""
    q = np.round(np.asarray(ij, np.float64) * 2.0 ** 20).astype(np.int64)
    return q[:, 0] * (N << 20) + q[:, 1]


def _triangles(ij: np.ndarray, faces: np.ndarray, N: int) -> np.ndarray:
    """Each triangle as its sorted corner places, rows sorted: the mesh up to vertex order
    (a corner is a sample, or a cut point of the clip to the data: grid indices in
    2^-20 steps)."""
    tri = np.sort(_keys(ij, N)[faces], axis=1)
    return tri[np.lexsort(tri.T[::-1])]


def _chunked(t, e, chunk):
    cs = list(static_chunks(t, e, chunk=chunk))
    ij = np.concatenate([c.ij for c in cs])
    faces = np.concatenate([c.faces for c in cs])
    firsts = [c.first for c in cs]
    assert firsts == list(np.cumsum([0] + [len(c.ij) for c in cs[:-1]]))
    return ij, faces, np.concatenate([c.xyz for c in cs])


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.integers(0, 1), e=st.floats(0, 60, allow_nan=False),
       chunk=st.integers(1, 3000))
def test_chunks_are_the_in_memory_static_mesh(stores, which, e, chunk):
    t = stores[which]
    N = t.grid.size
    sel = t.static_selection(e)
    ij, faces, xyz = _chunked(t, e, chunk)
    # every vertex used, numbered once, in order of first use
    assert len(np.unique(_keys(ij, N))) == len(ij)
    first_use = np.unique(faces.ravel(), return_index=True)[1]
    assert np.array_equal(np.unique(faces.ravel()), np.arange(len(ij)))
    assert np.all(np.diff(first_use) > 0)
    assert np.array_equal(_triangles(ij, faces, N),
                          _triangles(sel.ij, sel.surface_faces(), N))
    # positions and winding: those of the in-memory mesh at the same places
    rk = _keys(sel.ij, N)
    o = np.argsort(rk)
    got = np.asarray(sel.mesh.points)[o[np.searchsorted(rk[o], _keys(ij, N))]]
    assert np.array_equal(got, xyz)
    assert np.all(np.isfinite(xyz))
    p = xyz[faces]
    area2 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) \
        - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    assert np.all(area2 > 0)  # counter-clockwise seen from above, as the in-memory mesh


def _canon(m: pv.PolyData):
    """Points sorted, faces as sorted rank triples, and the point order used."""
    p = np.asarray(m.points, np.float64)
    o = np.lexsort(p.T[::-1])
    rank = np.empty(len(p), np.int64)
    rank[o] = np.arange(len(p))
    f = np.sort(rank[m.faces.reshape(-1, 4)[:, 1:]], axis=1)
    return p[o], f[np.lexsort(f.T[::-1])], o


@pytest.mark.fast
@pytest.mark.parametrize("ext", STREAM_FORMATS)
@pytest.mark.parametrize("which", [0, 1])
def test_streamed_file_is_the_written_mesh(stores, tmp_path, ext, which):
    t = stores[which]
    e = 3.0
    ref_path = write_mesh(with_elevation(t, t.static_selection(e).mesh), tmp_path / f"r{ext}")
    st_ = write_static_mesh(t, e, tmp_path / f"s{ext}", chunk=500)
    a, b = pv.read(ref_path), pv.read(tmp_path / f"s{ext}")
    assert st_["triangles"] == a.n_cells == b.n_cells > 0
    pa, fa, oa = _canon(a)
    pb, fb, ob = _canon(b)
    assert np.array_equal(pa, pb) and np.array_equal(fa, fb)
    if ext == ".ply":  # VTK's point normals: the normalised sum of unit face normals
        na, nb = a.point_data["Normals"][oa], b.point_data["Normals"][ob]
        assert np.abs(na - nb).max() < 1e-5
    if ext == ".stl":  # unit facet normals, facing up (counter-clockwise seen from above)
        raw = (tmp_path / f"s{ext}").read_bytes()
        rec = np.frombuffer(raw[84:], np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)),
                                                 ("a", "<u2")]))
        assert len(rec) == int(np.frombuffer(raw[80:84], "<u4")[0]) == b.n_cells
        v = rec["v"].astype(np.float64)
        n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        assert np.abs(n - rec["n"]).max() < 1e-4 and np.all(rec["n"][:, 2] > 0)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([f"r{ext}", f"s{ext}"])


@pytest.mark.parametrize("ext", STREAM_FORMATS)
def test_chunk_size_does_not_change_the_file(stores, tmp_path, ext):
    t = stores[1]
    write_static_mesh(t, 1.0, tmp_path / f"a{ext}", chunk=7)
    write_static_mesh(t, 1.0, tmp_path / f"b{ext}", chunk=1 << 20)
    assert (tmp_path / f"a{ext}").read_bytes() == (tmp_path / f"b{ext}").read_bytes()


@pytest.mark.fast
def test_a_failed_stream_leaves_nothing(stores, tmp_path, monkeypatch):
    import geoterrain.lod.stream as S

    t = stores[0]
    out = tmp_path / "m.ply"
    out.write_bytes(b"old")
    real = S.static_chunks

    def broken(*a, **k):
        for i, c in enumerate(real(*a, **k)):
            if i == 2:
                raise geoterrain.exceptions.StoreCorruptError("boom")
            yield c

    monkeypatch.setattr(S, "static_chunks", broken)
    with pytest.raises(geoterrain.exceptions.StoreCorruptError):
        write_static_mesh(t, 0.5, out, overwrite=True, chunk=100)
    assert out.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["m.ply"]


@pytest.mark.fast
def test_in_memory_formats_refuse_a_mesh_too_large(stores):
    t = stores[0]
    check_in_memory(t, 1.0, "m.vtp")  # fits
    with pytest.raises(geoterrain.exceptions.UsageError, match=r"\.ply, \.obj, \.stl"):
        check_in_memory(t, 1.0, "m.vtp", available=10_000)
    check_in_memory(t, 1e9, "m.vtp", available=10_000)  # two triangles fit


@pytest.mark.fast
def test_cli_mesh_streams_and_refuses(stores, tmp_path, monkeypatch):
    from tests.test_cli import assert_one_line_error, run

    t = stores[1]
    res = run("mesh", t.path, "-o", tmp_path / "m.ply", "--max-error", "2", "--json")
    assert res.exit_code == 0, res.output
    assert '"streamed": true' in res.output
    assert pv.read(tmp_path / "m.ply").n_cells == t.static_selection(2.0).stats["triangles"]
    import geoterrain.export.meshstream as M

    monkeypatch.setattr(M, "available_memory", lambda: 10_000)
    res = run("mesh", t.path, "-o", tmp_path / "m.vtp", "--max-error", "2")
    assert_one_line_error(res, 2)
    assert "--max-error" in res.stderr and ".ply" in res.stderr
    assert not (tmp_path / "m.vtp").exists()
