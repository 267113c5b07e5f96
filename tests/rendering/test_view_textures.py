"""View-dependent textures and truthful frame statistics.

- a view looking away from the terrain reads nothing: 0 tiles of any kind, 0 textures,
  0 bytes, and its stats say so;
- textures are built only for tiles under drawn faces, at a texel of about ≤ 1 px;
- every face lies in its footprint tile, which is the smallest one holding it;
- a picture is rendered once (no second render for a statistic);
- the picture stays within 35 dB of the bruteforce render with the whole-DEM
  level-0 texture (the previous renderer) on a real DEM.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain import lod
from geoterrain.core.grid import Grid
from geoterrain.core.view import View
from geoterrain.rendering import tiletextures
from geoterrain.rendering.atlaskernels import group_boxes, group_facing, number_pages
from geoterrain.rendering.scene import TerrainScene, default_view, render, render_array
from geoterrain.rendering.tileshader import TileShader
from geoterrain.rendering.tiletextures import build_view_texture, footprints
from geoterrain.rendering.window import pyvista_plotter
from tests.rendering.test_render import _fidelity_terrain, psnr, synth_store

ZERO = ("tiles_decoded", "normals_decoded", "bounds_decoded", "textures_built", "bytes_read",
        "texture_tiles")


def _fresh(tmp_path_factory, size=257, **kw):
    t = synth_store(tmp_path_factory, f"vtex{size}", size=size, **kw)
    return geoterrain.open(t.path)  # a new handle: an empty cache


@pytest.mark.fast
def test_away_render_reads_nothing(tmp_path_factory, tmp_path):
    t = _fresh(tmp_path_factory)
    lo, hi = t.scene_box()
    eye = (float(hi[0]) + 50.0, 0.0, float(hi[2]) + 100.0)
    away = View(eye, (eye[0] + 1000.0, 0.0, eye[2] + 200.0), size=(320, 200))
    st_ = render(t, away, tmp_path / "away.png", colorbar=False, scale_bar=False,
                 north_arrow=False)
    # nothing read but the opening (the picture's first frame reports it: issue 51)
    nothing = set(ZERO) - {"bytes_read"}
    assert {k: st_[k] for k in nothing} == dict.fromkeys(nothing, 0), st_
    assert st_["bytes_read"] == t.bytes_read == t.open_bytes
    assert st_["triangles"] == 0 and st_["terrain_fraction"] == 0.0
    assert (t.decoded_tiles, t.decoded_normals, t.decoded_bounds) == (0, 0, 0)
    # and a view of the terrain does read, and says so
    st2 = render(t, default_view(t, (320, 200)), tmp_path / "home.png")
    assert st2["tiles_decoded"] > 0 and st2["normals_decoded"] > 0
    assert st2["textures_built"] > 0 and st2["bytes_read"] > 0 and st2["peak_rss_mb"] > 0


def test_textures_only_under_drawn_faces(tmp_path_factory):
    t = _fresh(tmp_path_factory, size=1025)
    g = t.grid
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    # a low view of one corner: most of the terrain is not drawn
    v = View((float(lo[0]) - 200.0, float(lo[1]) - 200.0, float(hi[2]) + 150.0),
             (float(lo[0]) + 300.0, float(lo[1]) + 300.0, float(c[2])), size=(320, 200))
    sel = lod.select(t, v, 1.0)
    tex = build_view_texture(t, sel, v, TileShader(t))
    built = [k[-3:] for k in t.cache_keys() if k[0] == "rgb"]  # (..., level, x, y)
    assert len(built) == tex.stats["textures_built"] > 0
    ij = sel.ij.astype(np.int64)
    f = sel.faces
    i0, i1 = ij[f, 0].min(1), ij[f, 0].max(1)
    j0, j1 = ij[f, 1].min(1), ij[f, 1].max(1)
    step = 1 << g.t
    level0 = t.tile_keys(0)
    for (L, x, y) in built:
        if L < 0:  # magnified: a part of a level-0 tile, within its drawn faces' box
            w, k = step >> -L, -L
            inside = ((i0 >= (y >> k) * step) & (i1 <= ((y >> k) + 1) * step)
                      & (j0 >= (x >> k) * step) & (j1 <= ((x >> k) + 1) * step))
            assert inside.any(), (L, x, y)
            assert (j1[inside].max() >= x * w and j0[inside].min() <= (x + 1) * w
                    and i1[inside].max() >= y * w and i0[inside].min() <= (y + 1) * w)
            continue
        w = step << L
        touches = ((j1 >= x * w) & (j0 <= (x + 1) * w) & (i1 >= y * w) & (i0 <= (y + 1) * w))
        assert touches.any(), (L, x, y)
    assert len([k for k in built if k[0] == 0]) < len(level0) / 4
    # texels of about a pixel: the atlas is a few times the picture, not the DEM
    assert tex.image.shape[0] * tex.image.shape[1] < 16 * v.size[0] * v.size[1]


@pytest.mark.fast
def test_a_frame_budget_shows_magnified_ancestors_then_the_same_atlas(tmp_path_factory):
    """With ``max_builds`` a frame shades at most that many new tiles (where a cached
    ancestor can stand in); each stand-in is its ancestor's texels repeated; repeating
    the call shades the rest and ends with the atlas of an unbudgeted build."""
    from geoterrain.rendering.tiletextures import _stand_in

    t = _fresh(tmp_path_factory, size=1025)
    lo, hi = t.scene_box()
    c = 0.5 * (lo + hi)
    far = default_view(t, (320, 200))
    near = View((float(lo[0]) - 100.0, float(lo[1]) - 100.0, float(hi[2]) + 80.0),
                (float(c[0]), float(c[1]), float(c[2])), size=(320, 200))
    # the coarse tiles, cached
    build_view_texture(t, lod.select(t, far, 1.0), far, TileShader(t))
    sel = lod.select(t, near, 1.0)
    passes = []
    while True:
        tex = build_view_texture(t, sel, near, TileShader(t), max_builds=3)
        passes.append(tex)
        if tex.stats["textures_deferred"] == 0:
            break
        assert tex.stats["textures_built"] == 3
        assert len(passes) < 200
    assert len(passes) > 2 and passes[0].stats["textures_deferred"] > 0
    assert not np.array_equal(passes[0].image, passes[-1].image)
    fresh = _fresh(tmp_path_factory, size=1025)
    ref = build_view_texture(fresh, sel, near, TileShader(fresh))
    np.testing.assert_array_equal(passes[-1].image, ref.image)
    np.testing.assert_array_equal(passes[-1].tcoords, ref.tcoords)
    # a stand-in is its ancestor's texels, each repeated 2^d × 2^d
    shader = TileShader(t)
    key = shader.key

    step = 1 << t.grid.t
    L, x, y = 0, 5, 6
    anc = t.peek(key(2, 1, 1))
    assert anc is not None
    blk = np.zeros((step + 3, step + 3, 3), np.uint8)  # level 1 or 2 is cached: d = 1 or 2
    assert _stand_in(shader, t.grid.top_level, (L, x, y), step, blk, 1, 2)
    assert not blk[0].any() and not blk[:, :2].any()  # written at (1, 2) only
    blk = blk[1:, 2:]
    d = 1 if t.peek(key(1, 2, 3)) is not None else 2
    src = t.peek(key(L + d, x >> d, y >> d))
    n = step >> d
    oy, ox = (y % (1 << d)) * n, (x % (1 << d)) * n
    for r in (0, 7, step):
        for q in (0, 9, step):
            assert (blk[r, q] == src[oy + (r >> d), ox + (q >> d)]).all()


@pytest.mark.fast
def test_footprints_grouped_by_sort_equal_the_dense_table(tmp_path_factory, monkeypatch):
    """A pyramid with far more tiles than drawn faces groups its footprints through a
    sort instead of the dense tile table: the same atlas and mesh arrays."""
    import geoterrain.rendering.tiletextures as tt

    t = _fresh(tmp_path_factory, size=1025)
    for v in (default_view(t, (320, 200)), default_view(t, (320, 200), 80.0, 15.0)):
        sel = lod.select(t, v, 1.0)
        dense = build_view_texture(t, sel, v, TileShader(t))
        monkeypatch.setattr(tt, "DENSE_TABLE", 0)
        monkeypatch.setattr(tt, "DENSE_PER_FACE", 0)
        sparse = build_view_texture(t, sel, v, TileShader(t))
        monkeypatch.undo()
        for f in ("points", "faces", "tcoords", "source", "image"):
            np.testing.assert_array_equal(getattr(dense, f), getattr(sparse, f))


@pytest.mark.fast
def test_exaggerated_textures_are_not_the_base_terrains(tmp_path_factory):
    """A vertically exaggerated view shares the tile cache: its steeper shading must
    not be served the base terrain's (or the reverse)."""
    from geoterrain.exaggerate import exaggerated
    from geoterrain.rendering.tileshader import tile_rgb

    t = _fresh(tmp_path_factory)
    L = t.grid.top_level
    a = tile_rgb(t, L, 0, 0, "normals")
    b = tile_rgb(exaggerated(t, 4.0), L, 0, 0, "normals")
    fresh = tile_rgb(exaggerated(_fresh(tmp_path_factory), 4.0), L, 0, 0, "normals")
    assert not np.array_equal(a, b)
    np.testing.assert_array_equal(b, fresh)


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.integers(3, 9), st.data())
def test_footprint_is_the_smallest_tile_holding_a_face(n, data):
    g = Grid(2 ** n + 1, 2 ** n + 1, n, min(3, n))
    k = data.draw(st.integers(0, n))  # corners on a 2^k lattice, like a mesh's vertices:
    S = ((g.size - 1) >> k) + 1  # faces often end exactly on a tile's edge
    pts = data.draw(st.lists(st.tuples(st.integers(0, S - 1), st.integers(0, S - 1)),
                             min_size=3, max_size=3))
    ij = np.array(pts, np.int64) << k
    L, X, Y = footprints(ij, np.array([[0, 1, 2]]), g)
    w = (1 << g.t) << int(L[0])
    assert ij[:, 1].min() >= X[0] * w and ij[:, 1].max() <= (X[0] + 1) * w
    assert ij[:, 0].min() >= Y[0] * w and ij[:, 0].max() <= (Y[0] + 1) * w
    if L[0] > 0:  # no tile one level finer holds it
        w2 = w // 2
        xs, ys = ij[:, 1].min() // w2, ij[:, 0].min() // w2
        assert not (ij[:, 1].max() <= (xs + 1) * w2 and ij[:, 0].max() <= (ys + 1) * w2)


def _random_faces(F: int, V: int, G: int, data):
    """F random triangles over V vertices, each in one of G groups, and VTK's flat cells."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2 ** 32 - 1)))
    faces = rng.integers(0, V, (F, 3))
    cells = np.concatenate([np.full((F, 1), 3), faces], 1).ravel()
    return rng, faces, rng.integers(0, G, F), cells


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.integers(1, 30), st.integers(1, 12), st.data())
def test_pages_number_each_vertex_once_per_page(F, V, G, data):
    """The counting-sort numbering equals np.unique over (page, vertex), faces in order."""
    _, faces, group, cells = _random_faces(F, V, G, data)
    src, page, out = number_pages(faces, group, G, V)
    upk, inv = np.unique(np.repeat(group, 3) * V + faces.ravel(), return_inverse=True)
    np.testing.assert_array_equal(src, upk % V)
    np.testing.assert_array_equal(page, upk // V)
    np.testing.assert_array_equal(out, inv.reshape(-1, 3))


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(1, 20), st.integers(1, 9), st.data())
def test_page_boxes_hold_their_faces_corners(F, V, G, data):
    rng, faces, key, cells = _random_faces(F, V, G, data)
    pts, ij = rng.normal(size=(V, 3)), rng.integers(-50, 50, (V, 2))
    lo, hi, ilo, ihi = group_boxes(faces, key, pts, ij, G)
    for g in range(G):
        c = faces[key == g].ravel()
        if len(c) == 0:
            assert np.isinf(lo[g]).all() and np.isinf(hi[g]).all()
            continue
        np.testing.assert_array_equal(lo[g], pts[c].min(0))
        np.testing.assert_array_equal(hi[g], pts[c].max(0))
        np.testing.assert_array_equal(ilo[g], ij[c].min(0))
        np.testing.assert_array_equal(ihi[g], ij[c].max(0))


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(3, 20), st.integers(1, 9), st.data())
def test_page_facing_is_its_most_squarely_seen_face(F, V, G, data):
    """The compiled facing equals the angle from numpy's cross products, per group."""
    rng, faces, key, cells = _random_faces(F, V, G, data)
    pts = rng.normal(size=(V, 3)) * rng.uniform(0.1, 100.0)
    eye = rng.normal(size=3) * 300.0
    got = group_facing(faces, key, pts, eye, G)
    a, b, c = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
    n = np.cross(b - a, c - a)
    ray = eye - (a + b + c) / 3.0
    den = np.linalg.norm(n, axis=1) * np.linalg.norm(ray, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.where(den > 0, np.abs((n * ray).sum(1)) / den, 0.0)
    for g in range(G):
        want = cos[key == g].max(initial=0.0)
        assert abs(got[g] - min(want, 1.0)) <= 1e-9, (g, got[g], want)
    assert ((got >= 0) & (got <= 1)).all()


def _texel_levels(t, view, monkeypatch, foreshorten: bool) -> dict:
    from geoterrain.rendering.atlaskernels import table_size

    if not foreshorten:  # every footprint taken as seen square on
        fused = tiletextures.footprint_groups
        monkeypatch.setattr(tiletextures, "footprint_groups", lambda *a: (
            *fused(*a)[:5], np.ones(table_size(a[3]))))
        monkeypatch.setattr(tiletextures, "group_facing",
                            lambda faces, key, pts, eye, n: np.ones(n))
    sel = lod.select(t, view, pixel_error=1.0, strategy="rtin")
    levels = build_view_texture(t, sel, view, TileShader(t)).stats["texel_levels"]
    monkeypatch.undo()
    return levels


def test_grazing_footprints_get_coarser_texels(tmp_path_factory, monkeypatch):
    """At a grazing angle texels are coarser than square on (never finer), by the
    texel's projected area; a view straight down on the plane is unchanged."""
    from tests.rendering.test_pictures import array_store

    t = array_store(tmp_path_factory, "flat1025", np.full((1025, 1025), 100.0))
    lo, hi = t.scene_box()
    c = (0.5 * (lo + hi)).tolist()
    size = (320, 240)
    mean = lambda lv: sum(k * n for k, n in lv.items()) / sum(lv.values())  # noqa: E731
    top = View((c[0], c[1], c[2] + 8000.0), tuple(c), size=size, up=(0.0, 1.0, 0.0))
    assert _texel_levels(t, top, monkeypatch, True) == _texel_levels(t, top, monkeypatch,
                                                                       False)
    # 6° above the plane: a texel's projected area is sin 6° ≈ 1/10 of square on's, its
    # side ≈ 1/3: one level coarser or more
    graze = View((c[0], c[1] - 13000.0, c[2] + 13000.0 * np.tan(np.radians(6.0))), tuple(c),
                 size=size)
    on, off = (_texel_levels(t, graze, monkeypatch, f) for f in (True, False))
    assert min(on) >= min(off) and max(on) >= max(off)
    # rtin draws the plane as one page: 1.4 levels finer than one texel a pixel by
    # distance alone (level 1), 1.5 levels coarser by √c (c ≈ 0.12: level 2); a mipmap's
    # c would make it 3 levels coarser (level 4), blurring the relief rtin's flat faces
    # stand for
    assert len(on) == len(off) == 1
    assert 1.0 <= mean(on) - mean(off) <= 2.0, (on, off)


@pytest.mark.fast
def test_a_picture_is_rendered_once(tmp_path_factory):
    t = _fresh(tmp_path_factory)
    size = (320, 200)
    scene = TerrainScene(pyvista_plotter(size), t)
    count = []
    scene.plotter.render_window.AddObserver("StartEvent", lambda *_: count.append(1))
    try:
        render_array(t, default_view(t, size), scene=scene)
        n = len(count)
        img, st_ = render_array(t, default_view(t, size, azimuth=40.0), scene=scene)
    finally:
        scene.plotter.close()
    assert len(count) - n == 1, len(count) - n
    assert 0.2 < st_["terrain_fraction"] <= 1.0


def test_view_textures_match_the_full_resolution_texture(tmp_path_factory):
    """rtin + per-view textures vs bruteforce + the whole-DEM level-0 texture ≥ 35 dB."""
    t = _fidelity_terrain(tmp_path_factory)
    size = (640, 360)
    ref = TerrainScene(pyvista_plotter(size), t, textures="global")
    new = TerrainScene(pyvista_plotter(size), t)
    out = []
    try:
        for az, el in ((200, 35), (90, 20)):
            v = default_view(t, size, az, el)
            a, _ = ref.frame(v, 1.0, "bruteforce")
            b, sb = new.frame(v, 1.0, "rtin")
            out.append(psnr(a, b))
            assert sb["textures_built"] + sb["texture_tiles"] > 0
    finally:
        ref.plotter.close()
        new.plotter.close()
    print("PSNR", [f"{p:.2f}" for p in out])
    assert min(out) >= 35.0, out


@pytest.mark.fast
def test_unknown_texture_mode(tmp_path_factory):
    t = _fresh(tmp_path_factory)
    with pytest.raises(geoterrain.exceptions.UsageError):
        TerrainScene(pyvista_plotter((64, 64)), t, textures="atlas")


@pytest.mark.fast
@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_clamp_fill_is_clamp_to_edge(seed):
    """Every texel of a page's box outside its written rectangle is the rectangle's
    nearest texel (GL's clamp-to-edge), and the rectangle itself is left as written."""
    from geoterrain.rendering.atlaskernels import clamp_fill

    rng = np.random.default_rng(seed)
    H, W = int(rng.integers(4, 30)), int(rng.integers(4, 30))
    atlas = rng.integers(0, 256, (H, W, 3)).astype(np.uint8)
    r0, c0 = int(rng.integers(0, H - 1)), int(rng.integers(0, W - 1))
    bh, bw = int(rng.integers(1, H - r0 + 1)), int(rng.integers(1, W - c0 + 1))
    a, b = r0 + int(rng.integers(0, bh)), c0 + int(rng.integers(0, bw))
    h, w = int(rng.integers(1, r0 + bh - a + 1)), int(rng.integers(1, c0 + bw - b + 1))
    want = atlas.copy()
    ii = np.clip(np.arange(r0, r0 + bh), a, a + h - 1)
    jj = np.clip(np.arange(c0, c0 + bw), b, b + w - 1)
    want[r0:r0 + bh, c0:c0 + bw] = atlas[ii[:, None], jj[None, :]]
    clamp_fill(atlas, np.array([[a, b, h, w]]), np.array([[r0, c0, bh, bw]]))
    assert np.array_equal(atlas, want)


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_page_tcoords_are_the_numpy_formula(seed):
    """The compiled texture coordinates are, to the bit, the array formula's: a point's
    column in its page (grid column minus the page origin, in texels of its level), plus
    the page's atlas column and gutter, at the texel's centre, over the atlas width."""
    from geoterrain.rendering.atlaskernels import page_tcoords

    rng = np.random.default_rng(seed)
    G, V, P, step, gutter = int(rng.integers(1, 9)), 50, int(rng.integers(1, 80)), 64, 1
    Lt = rng.integers(0, 6, G)
    gL = Lt + rng.integers(0, 3, G)
    gX, gY = rng.integers(0, 9, G), rng.integers(0, 9, G)
    ax, ay = rng.integers(0, 3000, G), rng.integers(0, 3000, G)
    src, pg = rng.integers(0, V, P), rng.integers(0, G, P)
    ij = rng.integers(0, 1 << 14, (V, 2))
    pts = rng.normal(size=(V, 3))
    AW, AH = int(rng.integers(100, 8192)), int(rng.integers(100, 8192))
    tc, xyz = page_tcoords(src, pg, ij, pts, (Lt, gL, gX, gY, ax, ay), step, gutter, (AW, AH))
    scale = np.left_shift(1, Lt[pg]).astype(np.float64)
    span = (step << gL[pg]).astype(np.float64)
    col = ax[pg] + gutter + (ij[src, 1] - gX[pg] * span) / scale
    row = ay[pg] + gutter + (ij[src, 0] - gY[pg] * span) / scale
    want = np.stack([(col + 0.5) / AW, (row + 0.5) / AH], 1).astype(np.float32)
    assert np.array_equal(tc.view(np.int32), want.view(np.int32))
    assert np.array_equal(xyz, pts[src])


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(3, 40), st.data())
def test_one_pass_footprint_groups_are_the_three_passes(F, V, data):
    """The fused pass gives each face's footprint, the footprints' boxes and their facing
    exactly as face_footprints, group_boxes and group_facing do over the dense table."""
    from geoterrain.rendering.atlaskernels import (
        face_footprints,
        footprint_groups,
        table_size,
        tile_table,
    )

    rng = np.random.default_rng(data.draw(st.integers(0, 2 ** 32 - 1)))
    faces = rng.integers(0, V, (F, 3))
    t, top = 2, 3
    base = tile_table(Grid(33, 33, t + top, t))  # 4^(top − L) tiles at level L
    ij = rng.integers(0, (1 << t) * (1 << top) + 1, (V, 2))
    pts, eye = rng.normal(size=(V, 3)), rng.normal(size=3) * 5
    key, lo, hi, ilo, ihi, facing = footprint_groups(ij, faces, t, base, pts, eye)
    want = face_footprints(ij, faces, t, base)
    n = table_size(base)
    assert n == sum(4 ** (top - L) for L in range(top + 1))
    np.testing.assert_array_equal(key, want)
    for a, b in zip((lo, hi, ilo, ihi), group_boxes(faces, want, pts, ij, n), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(facing, group_facing(faces, want, pts, eye, n))


@pytest.mark.fast
def test_an_unchanged_atlas_is_kept_and_no_picture_changes(tmp_path_factory):
    """A frame whose atlas would hold the same tiles at the same places keeps the one
    shown (no texel copied or uploaded); no picture differs from a fresh scene's."""
    t = _fresh(tmp_path_factory)
    size = (320, 200)
    a = default_view(t, size)
    b = default_view(t, size, azimuth=100.0, elevation=25.0)
    scene = TerrainScene(pyvista_plotter(size), t)
    try:
        img_a, st_a = scene.frame(a)
        img_a2, st_a2 = scene.frame(a)  # the same view: the same atlas, kept
        img_b, st_b = scene.frame(b)
        img_a3, st_a3 = scene.frame(a)  # another atlas was shown in between
    finally:
        scene.plotter.close()
    assert not st_a["atlas_reused"] and st_a2["atlas_reused"] and st_a2["textures_built"] == 0
    assert not st_b["atlas_reused"] and not st_a3["atlas_reused"]
    assert np.array_equal(img_a2, img_a) and np.array_equal(img_a3, img_a)
    fresh = TerrainScene(pyvista_plotter(size), _fresh(tmp_path_factory))
    try:
        assert np.array_equal(fresh.frame(b)[0], img_b)
    finally:
        fresh.plotter.close()


@pytest.mark.fast
def test_an_atlas_is_not_kept_across_an_edit_or_a_budget(tmp_path_factory):
    t = _fresh(tmp_path_factory)
    v = View((0, -900, 500), (0, 0, 0), size=(320, 240))
    sel = lod.select(t, v)
    shader = TileShader(t)
    first = build_view_texture(t, sel, v, shader)
    again = build_view_texture(t, sel, v, shader, previous=first)
    assert again.stats["atlas_reused"] and again.image is first.image
    assert np.array_equal(again.tcoords, first.tcoords) and np.array_equal(again.faces,
                                                                           first.faces)
    other = build_view_texture(t, sel, v, TileShader(t, "elevation"), previous=first)
    assert not other.stats["atlas_reused"]  # another style
    t.generation += 1  # as an edit taken in by refresh() counts it
    assert not build_view_texture(t, sel, v, shader, previous=first).stats["atlas_reused"]
    # an atlas with tiles cut from their ancestors (a frame's budget) is never kept
    t2 = _fresh(tmp_path_factory, size=1025)
    lo, hi = t2.scene_box()
    c = 0.5 * (lo + hi)
    far = default_view(t2, (320, 200))
    near = View((float(lo[0]) - 100.0, float(lo[1]) - 100.0, float(hi[2]) + 80.0),
                (float(c[0]), float(c[1]), float(c[2])), size=(320, 200))
    shader2 = TileShader(t2)
    build_view_texture(t2, lod.select(t2, far, 1.0), far, shader2)  # the coarse tiles
    sel2 = lod.select(t2, near, 1.0)
    part = build_view_texture(t2, sel2, near, shader2, max_builds=3)
    assert part.stats["textures_deferred"] > 0 and part.layout is None
    assert not build_view_texture(t2, sel2, near, shader2, max_builds=3,
                                  previous=part).stats["atlas_reused"]


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.integers(1, 200), st.integers(1, 9), st.integers(1, 7), st.data())
def test_surface_facing_lessens_only_coarse_faces_angles(F, G, t, data):
    """The surface's facing is never below the drawn faces' (nor above 1); footprints
    drawn with the grid's own faces (half a cell each, as bruteforce draws) keep their
    facing to the bit, and so do those seen more obliquely than ROUGH_GRAZING; with no
    roughness every footprint keeps it; a coarser face's angle to the eye is lessened by
    β at its size (2^m samples across), at most."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2 ** 32 - 1)))
    fe = rng.integers(0, G, F)
    fe[:G] = np.arange(min(G, F))  # most footprints hold a face
    legs = rng.integers(1, 1 << t, F)  # each face a right triangle of legs ℓ samples
    fine = data.draw(st.booleans())
    if fine:
        legs[:] = 1
    o = rng.integers(0, 1000, (F, 2))
    ij = np.concatenate([o, o + np.stack([np.zeros(F, int), legs], 1),
                         o + np.stack([legs, np.zeros(F, int)], 1)])
    tris = np.stack([np.arange(F), F + np.arange(F), 2 * F + np.arange(F)], 1)
    facing = rng.uniform(0.0, 1.0, G)
    fp = tiletextures._Footprints(*[np.zeros(G, np.int64)] * 3, *[np.zeros((G, 3))] * 2,
                                  *[np.zeros((G, 2), np.int64)] * 2, facing, fe)
    beta = np.concatenate([[0.0], np.cumsum(rng.uniform(0.0, 0.4, t))])
    got = tiletextures.surface_facing(fp, ij, tris, beta)
    assert (got >= facing).all() and (got <= 1.0).all()
    np.testing.assert_array_equal(tiletextures.surface_facing(fp, ij, tris, 0 * beta), facing)
    held = np.bincount(fe, minlength=G) > 0
    grazing = np.arccos(facing) > tiletextures.ROUGH_GRAZING
    np.testing.assert_array_equal(got[grazing], facing[grazing])
    if fine:
        np.testing.assert_array_equal(got, facing)
    for g in np.flatnonzero(held):  # the faces' mean area, as a right triangle's legs
        leg = np.sqrt(np.mean(legs[fe == g].astype(float) ** 2))
        most = np.interp(np.log2(leg), np.arange(t + 1), beta)
        assert np.arccos(facing[g]) - np.arccos(got[g]) <= most + 1e-9, (g, leg)


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.integers(1, 300), st.integers(3, 20), st.integers(1, 9), st.data())
def test_group_face_area_is_numpys_mean(F, V, G, data):
    """The compiled mean face area per group equals numpy's cross products and bincount."""
    from geoterrain.rendering.atlaskernels import group_face_area

    rng, faces, key, _ = _random_faces(F, V, G, data)
    ij = rng.integers(-50, 50, (V, 2))
    a, b = ij[faces[:, 1]] - ij[faces[:, 0]], ij[faces[:, 2]] - ij[faces[:, 0]]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    n = np.bincount(key, minlength=G)
    want = np.bincount(key, weights=area, minlength=G) / np.maximum(n, 1)
    np.testing.assert_allclose(group_face_area(ij, faces, key, G), want, rtol=1e-12)


@pytest.mark.fast
def test_roughness_is_zero_on_a_plane_and_grows_with_face_size(tmp_path_factory):
    from tests.rendering.test_pictures import array_store

    flat = array_store(tmp_path_factory, "flat1025", np.full((1025, 1025), 100.0))
    np.testing.assert_array_equal(tiletextures.roughness(flat), 0.0)
    b = tiletextures.roughness(_fresh(tmp_path_factory))
    assert b[0] == 0.0 and (np.diff(b) > 0).all(), b


def _tile_texels(t, view, strategy, monkeypatch, rough: bool = True) -> dict:
    """The texel level each level-0 tile under a drawn face gets, by (row, column);
    ``rough`` False: footprints facing the eye as their drawn faces do (no roughness)."""
    got = {}
    levels = tiletextures._texel_levels

    def spy(fp, *a, **kw):
        lt = levels(fp, *a, **kw)
        for L, x, y, v in zip(fp.L.tolist(), fp.X.tolist(), fp.Y.tolist(), lt.tolist(),
                              strict=True):
            for r in range(y << L, (y + 1) << L):
                for c in range(x << L, (x + 1) << L):
                    got[r, c] = v
        return lt

    monkeypatch.setattr(tiletextures, "_texel_levels", spy)
    if not rough:
        monkeypatch.setattr(tiletextures, "roughness", lambda terrain: np.zeros(8))
    build_view_texture(t, lod.select(t, view, pixel_error=1.0, strategy=strategy), view,
                       TileShader(t))
    monkeypatch.undo()
    return got


def test_rough_relief_gets_the_texels_of_its_own_faces(tmp_path_factory, monkeypatch):
    """On a rough fBm, rtin's coarse faces get the texel levels bruteforce's faces (the
    relief's own) get in the same tiles, more closely than from their own facing
    (which took their smoothness for the relief's and chose coarser texels)."""
    t = _fresh(tmp_path_factory, size=513)
    gaps = []
    for az, el, k in ((90, 20, 0.3), (90, 25, 0.5)):  # oblique views, part magnified
        home = default_view(t, (640, 360), az, el)
        c, e = np.asarray(home.look_at), np.asarray(home.look_from)
        v = View(tuple(c + k * (e - c)), tuple(c), size=(640, 360))
        brute = _tile_texels(t, v, "bruteforce", monkeypatch)
        now = _tile_texels(t, v, "rtin", monkeypatch)
        faces_only = _tile_texels(t, v, "rtin", monkeypatch, rough=False)
        both = sorted(set(brute) & set(now))
        assert len(both) > 20
        gap = np.mean([abs(now[k] - brute[k]) for k in both])
        gap0 = np.mean([abs(faces_only[k] - brute[k]) for k in both])
        print("mean |ΔLt| against bruteforce:", round(gap, 3), "faces alone", round(gap0, 3))
        assert gap <= gap0, (gap, gap0)
        gaps.append((gap, gap0))
    assert sum(g for g, _ in gaps) < sum(g0 for _, g0 in gaps), gaps
