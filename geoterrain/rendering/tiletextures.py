"""View-dependent terrain textures: a texture quadtree beside the geometry quadtree.

Seed 000 §2.5 (chunked LOD keeps a texture quadtree beside the geometry one):
each triangle a selection draws lies in one stored tile footprint (the smallest
quadtree tile (L, x, y) that holds it; RTIN, chunked, GeoMipMapping, quadtree and
bruteforce triangles all do, skirts included). The footprint's shading
(elevation colours × hillshade from the stored normal maps, :mod:`textures`)
comes from the coarsest pyramid level ``Lt`` whose texel projects to at most
``TEXEL_PX`` = 1.5 pixels (so 0.75–1.5 px: about one) at the footprint's nearest
point to the eye, as the side of a square of the texel's projected area::

    texel_px(Lt) = 2^Lt · s0 · f · √c / d ≤ TEXEL_PX,   f = (H / 2) / tan(fov_y / 2)

(``s0`` the finest sample spacing, ``d`` the distance from the eye to the box of
the footprint's drawn vertices, ``c`` the largest |cos| between one of its drawn
faces' normals and the line to the eye, that angle lessened by the relief's roughness at
the faces' size within 60° of square on (:func:`surface_facing`: a coarse face stands
for rougher relief, which faces the eye more), at least ``MIN_FACING``), clamped to
``L - MAX_PAGE_LEVELS ≤ Lt ≤ L``. A texel seen at a grazing angle covers c times the
pixels across the slope that it covers along it: the area's side √c lies between the
distance alone (c = 1, texels finer than a pixel across the slope) and a mipmap's rule
(c, its larger texel derivative), which blurred rtin's pictures: its faces are smoother,
so more foreshortened, than the fine relief their texture shows (Laplacian deviation of
an fBm overview 13.3 against 18.2 for the mipmapped whole-DEM texture; √c: 18.9). On
the 4097² fBm flight of ``benchmarks/bench_render.py`` √c shades 1125 tiles instead of
1647.

Only the level-``Lt`` tiles under a footprint that its triangles touch are
shaded, each once per (level, x, y, shading, palette) and kept in the terrain's
byte-bounded tile cache; a tile no drawn triangle touches is never decoded or
shaded. Chosen by measurement on srtm1_japan at 640×360, rtin τ = 1 against the
bruteforce render with the mipmapped whole-DEM level-0 texture: texels ≤ 0.5 / 1 /
1.5 / 2 px gave 34.7 / 36.9 / 37.8 / 37.7 dB (view 1) and 33.6 / 35.0 / 35.3 / 35.2 dB
(view 2); finer texels alias, as there are no mipmaps across atlas pages. With √c:
37.85 and 35.56 dB at 1.5 px (docs/lab/rendering-frame.md has every shared DEM).

Where a level-0 sample spans more than ``TEXEL_PX`` pixels (a coarse DEM, or a close
view), a footprint's texels come from a *magnified* level ``Lt < 0``, down to
``-MAX_MAGNIFY``: a level-0 tile's area cut into 2^-Lt × 2^-Lt virtual tiles of the same
(2^t + 1)² texels, each 2^Lt samples apart. Their key is (Lt, x, y) on that finer tile
grid, so the atlas places them as any other; the style shades them from the heights and
shading interpolated at their texels (:class:`~geoterrain.rendering.tileshader.TileShader`),
so colour steps and coasts follow the surface, not its samples.

How a tile is shaded is the picture's style's business
(:class:`~geoterrain.rendering.tileshader.TileShader`): the atlas asks it for the tiles
it places. The pages are packed into one atlas texture (one actor, per-vertex texture
coordinates; vertices are duplicated per footprint). An atlas rather than one
actor per tile: a frame has hundreds of pages, and VTK draws one actor per call.

Examples
--------
>>> from geoterrain import lod
>>> from geoterrain.rendering.tileshader import TileShader
>>> v = View((0, -900, 500), (0, 0, 0), size=(320, 240))
>>> tex = build_view_texture(t, lod.select(t, v), v, TileShader(t))
>>> tex.image.dtype.name, tex.tcoords.shape[1], tex.stats["textures_built"] > 0
('uint8', 2, True)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.memory import ZeroPool
from geoterrain.rendering.atlaskernels import (
    clamp_fill,
    face_footprints,
    footprint_groups,
    group_boxes,
    group_face_area,
    group_facing,
    magnify_into,
    number_pages,
    page_tcoords,
    table_size,
    tile_table,
)
from geoterrain.rendering.textures import sample_spacing

if TYPE_CHECKING:
    from geoterrain.rendering.tileshader import TileShader
    from geoterrain.terrainlike import TerrainLike

TEXEL_PX = 1.5  # texels of 0.75-1.5 px: finer ones alias without mipmaps (measured below)
MIN_FACING = 2.0 ** -8  # a footprint seen edge on: 4 levels coarser, at most the top
MAX_PAGE_LEVELS = 3  # a footprint's page is at most 2^3 × 2^3 tiles (513² texels at t = 6)
MAX_MAGNIFY = 3  # texels down to 1/8 of a sample apart (level -3): smooth classification
LT_BIAS = 8  # texel levels are packed in page keys as Lt + LT_BIAS (5 bits, Lt ≥ -8)
MAX_ATLAS = 8192  # texels per side; beyond it every page is coarsened one level
GUTTER = 1  # replicated border texels around each page (no bleeding between pages)
# footprints are grouped through the whole (level, y, x) tile table up to this many
# tiles, or this many per face; beyond, through a sort of the ones used
DENSE_TABLE, DENSE_PER_FACE = 1 << 16, 2
MISSING_GREY = 128  # a tile that is not stored (all nodata): never visible


@dataclass
class ViewTexture:
    """An atlas and the mesh arrays that map onto it.

    ``points`` (V', 3), ``faces`` (F, 3) into them, ``tcoords`` (V', 2) float32,
    ``source`` (V',) the selection vertex each point copies, ``image`` (H, W, 3) uint8
    (read-only; row r of the image at v = (r + 0.5) / H, so VTK, whose row 0 is v = 0,
    shows it as it is, without a flipped copy), ``stats`` (textures_built,
    texture_tiles, pages, texel_levels (pages per texel level), atlas, texture_ms).
    """

    points: np.ndarray
    faces: np.ndarray
    tcoords: np.ndarray
    source: np.ndarray
    image: np.ndarray
    stats: dict = field(default_factory=dict)
    layout: bytes | None = None  # what the image's texels depend on (None: not reusable)


# the atlases' memory, reused once the atlas shown before is released (no page faults)
_ATLASES = ZeroPool()


def _stand_in(shader: TileShader, top: int, key: tuple, step: int, atlas: np.ndarray, r: int,
              c: int) -> bool:
    """Write tile ``key``'s texels (step + 1)² at (r, c) of ``atlas``, cut from the nearest
    ancestor whose shading is already cached, each ancestor texel repeated 2^d × 2^d;
    False (nothing written) if none is cached."""
    L, x, y = key
    for d in range(1, top - L + 1):
        if step >> d < 1:
            break
        anc = shader.peek(L + d, x >> d, y >> d)
        if anc is None:
            continue
        n = step >> d  # the tile's width in ancestor texels
        oy, ox = (y - (y >> d << d)) * n, (x - (x >> d << d)) * n
        magnify_into(atlas, r, c, anc, oy, ox, d, step + 1)
        return True
    return False


def footprints(ij: np.ndarray, faces: np.ndarray, grid) -> tuple[np.ndarray, ...]:
    """(L, x, y) of the smallest stored-tile footprint holding each face, all arrays (F,).

    Examples
    --------
    >>> L, x, y = footprints(np.array([[0, 0], [0, 32], [32, 0]]), np.array([[0, 1, 2]]),
    ...                      t.grid)
    >>> int(L[0]), int(x[0]), int(y[0])
    (0, 0, 0)
    """
    base = tile_table(grid)
    return _table_keys(face_footprints(ij, faces, grid.t, base), base)


def _table_keys(e: np.ndarray, base: np.ndarray) -> tuple[np.ndarray, ...]:
    """(L, x, y) of dense tile-table indices ``e`` (``base``: the
    :func:`~geoterrain.rendering.atlaskernels.tile_table`)."""
    top = (len(base) - 4) // 3
    offsets, across = base[:top + 2], base[top + 2:2 * top + 3]
    L = np.searchsorted(offsets, e, side="right") - 1
    rem = e - offsets[L]
    return L, rem % across[L], rem // across[L]


def _pack(sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Shelf packing of square pages (largest first): (x0, y0, width, height)."""
    order = np.argsort(-sizes, kind="stable")
    W = max(int(sizes.max()), int(math.ceil(math.sqrt(float((sizes.astype(np.float64) ** 2)
                                                              .sum())) * 1.1)))
    x0 = np.zeros(len(sizes), np.int64)
    y0 = np.zeros(len(sizes), np.int64)
    cx = cy = shelf = 0
    for k in order:  # one step per page (tens to hundreds), never per texel
        s = int(sizes[k])
        if cx + s > W:
            cy, cx, shelf = cy + shelf, 0, 0
        x0[k], y0[k] = cx, cy
        cx += s
        shelf = max(shelf, s)
    return x0, y0, W, cy + shelf


def build_view_texture(terrain: TerrainLike, selection, view, shader: TileShader,
                       texel_px: float = TEXEL_PX, max_builds: int | None = None,
                       previous: ViewTexture | None = None) -> ViewTexture:
    """The atlas of what ``selection`` draws in ``view`` at about ``texel_px`` px per texel,
    its tiles shaded by ``shader`` (:class:`~geoterrain.rendering.tileshader.TileShader`:
    the picture's style).

    ``max_builds`` caps the tiles shaded anew by this call (an interactive frame's
    budget): past it, a tile whose shading is not cached is cut from its nearest cached
    ancestor's, magnified (``stats["textures_deferred"]`` counts them; a later call
    with the same selection shades the next ones). None: every tile at its own level.

    ``previous``: the atlas shown last. Where this view's atlas would hold the same
    tiles at the same places (the same pages, levels, tiles and packing, the terrain not
    edited since, none of them deferred), its image is kept (``stats["atlas_reused"]``):
    no tile is copied, and the renderer, given the same image, uploads nothing; only the
    mesh's texture coordinates are made anew.

    Examples
    --------
    >>> from geoterrain import lod
    >>> from geoterrain.rendering.tileshader import TileShader
    >>> v = View((0, -900, 500), (0, 0, 0), size=(320, 240))
    >>> tex = build_view_texture(t, lod.select(t, v), v, TileShader(t, "elevation"))
    >>> bool((tex.tcoords >= 0).all() and (tex.tcoords <= 1).all())
    True
    """
    t0 = time.perf_counter()
    g = terrain.grid
    top = g.top_level
    # a footprint is its index e in the dense (level, y, x) tile table (atlaskernels)
    base = tile_table(g)
    built0 = shader.built
    if selection.parts.n_cells == 0 or selection.parts.n_points == 0:
        return ViewTexture(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2),
                           np.float32), np.zeros(0, np.int64), np.zeros((1, 1, 3), np.uint8),
                           {"textures_built": 0, "texture_tiles": 0, "textures_deferred": 0,
                            "pages": 0, "texel_levels": {}, "atlas": [0, 0],
                            "texture_ms": 0.0})
    pts, ij, tris = _mesh_arrays(selection)
    fp = _footprints(pts, ij, tris, g.t, base, view)
    fp.facing = surface_facing(fp, ij, tris, roughness(terrain))
    fLt = _texel_levels(fp, view, sample_spacing(terrain), texel_px, top,
                        min(MAX_MAGNIFY, g.t))
    pg = _pages(fp, fLt, g.t, top)
    step = 1 << g.t
    tiles = _tile_ranges(pg, step)
    layout = _layout(pg, tiles, terrain.generation, shader)
    if previous is not None and previous.layout == layout:
        return _finish(previous.image, pg, fp, tris, ij, pts, step, layout, t0, {
            "textures_built": 0, "texture_tiles": previous.stats.get("texture_tiles", 0),
            "textures_deferred": 0, "atlas_reused": True})
    # zeroed, on 4 KiB pages (a fresh atlas on huge pages stalled on its first touch,
    # the kernel compacting memory for them: 11 ms of an 8 MB atlas's fill), reused once
    # the atlas shown before is released (a fresh mapping faulted page by page: 1.4 ms
    # of a 4 MB atlas). The pages are filled below (their tiles, then clamped to those
    # over the rest of the page and its gutter), so the atlas is not filled with a colour
    # first: only a multisampled pixel shaded more than a texel past a face, at a grazing
    # seam, reads the shelves' slack, zero (3 pixels of 256 k, by up to 15 levels, in a
    # review's view; they read grey before, as wrong)
    atlas = _ATLASES.zeros((pg.AH, pg.AW, 3), np.uint8)
    placed, rect = _place(pg, tiles, _Stored(terrain.tile_info), step, atlas)
    # the tiles' shading, those not cached shaded now (at most max_builds, in drawing
    # order); past the budget a tile is cut from a cached ancestor where there is one
    rgbs = shader([key for key, _, _ in placed], max_builds)
    deferred = 0
    for (key, r, c), rgb in zip(placed, rgbs, strict=True):
        if rgb is None:
            if _stand_in(shader, top, key, step, atlas, r, c):
                deferred += 1
                continue
            rgb = shader.tile(*key)
        atlas[r:r + step + 1, c:c + step + 1] = rgb
    # each page's written tiles clamped to their edge over the rest of the page and its
    # gutter (a multisampled pixel centre may fall past a face at a page's seam)
    page = (step << pg.k) + 1 + 2 * GUTTER  # a page's allocation: its texels and gutter
    clamp_fill(atlas, rect, np.stack([pg.ay, pg.ax, page, page], 1))
    atlas.setflags(write=False)  # shown by VTK without a copy (rendering._image_data)
    return _finish(atlas, pg, fp, tris, ij, pts, step, None if deferred else layout, t0, {
        "textures_built": shader.built - built0, "texture_tiles": len(placed),
        "textures_deferred": deferred, "atlas_reused": False})


def _finish(atlas: np.ndarray, pg: _Pages, fp: _Footprints, tris: np.ndarray,
            ij: np.ndarray, pts: np.ndarray, step: int, layout: bytes | None, t0: float,
            st: dict) -> ViewTexture:
    """The mesh mapped onto ``atlas`` (its pages ``pg``) and the stats."""
    # one point per (page, vertex): a vertex shared by two pages is duplicated
    src, pgi, faces = number_pages(tris, pg.e_group[fp.fe], pg.G, len(pts))
    # VTK's v: the image's row 0 at v = 0 (see ViewTexture)
    tc, xyz = page_tcoords(src, pgi, ij, pts, (pg.Lt, pg.gL, pg.gX, pg.gY, pg.ax, pg.ay),
                           step, GUTTER, (pg.AW, pg.AH))
    lv, nlv = np.unique(pg.Lt, return_counts=True)
    st.update(pages=pg.G, texel_levels={int(a): int(b) for a, b in zip(lv, nlv, strict=True)},
              atlas=[int(pg.AW), int(pg.AH)],
              texture_ms=round((time.perf_counter() - t0) * 1e3, 3))
    return ViewTexture(xyz, faces, tc, src, atlas, st, layout)


def _layout(pg: _Pages, tiles: tuple[np.ndarray, ...], generation: int, shader) -> bytes:
    """What an atlas's texels depend on: its size, each page's texel level, tile, place
    and the range of its tiles written, the terrain's edits and the style."""
    head = np.array([pg.AW, pg.AH, generation, id(shader)], np.int64)
    return b"".join(np.ascontiguousarray(a, np.int64).tobytes() for a in (
        head, pg.Lt, pg.gL, pg.gX, pg.gY, pg.ax, pg.ay, *tiles))


def _mesh_arrays(selection) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The selection's points (V, 3) float64, grid (row, column) per point and triangles
    (F, 3) int64."""
    mesh = selection.parts  # numpy arrays: no VTK object made or read (any thread)
    pts = np.asarray(mesh.points, np.float64)
    ij = np.asarray(mesh.point_data["grid_ij"])
    # the triangles copied as int64 (0.1 ms): nothing below keeps a view of the mesh's
    tris = np.array(mesh.regular_faces, np.int64).reshape(-1, 3)  # (F, 3)
    return pts, ij, tris


@dataclass
class _Footprints:
    """The tile footprints some face lies in: their (level, x, y), drawn vertices' scene
    box (lo, hi) and sample box (ilo, ihi), the faces' largest foreshortening, and each
    face's footprint ``fe``."""

    L: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    ilo: np.ndarray
    ihi: np.ndarray
    facing: np.ndarray
    fe: np.ndarray


def _footprints(pts: np.ndarray, ij: np.ndarray, tris: np.ndarray, t: int, base: np.ndarray,
                view) -> _Footprints:
    """Each face's smallest stored-tile footprint and the footprints' boxes: through the
    dense tile table (a scatter), or, with far more tiles than faces, a sort."""
    ntab = table_size(base)
    eye = np.asarray(view.eye, np.float64)
    if ntab <= max(DENSE_TABLE, DENSE_PER_FACE * len(tris)):  # a scatter into the table
        fkey, lo, hi, ilo_e, ihi_e, facing = footprint_groups(ij, tris, t, base, pts, eye)
        E = np.flatnonzero(np.isfinite(lo[:, 0]))  # the footprints some face lies in
        lo, hi, ilo_e, ihi_e, facing = lo[E], hi[E], ilo_e[E], ihi_e[E], facing[E]
        pos = np.empty(ntab, np.int64)
        pos[E] = np.arange(len(E))
        fe = pos[fkey]  # each face's footprint, numbered 0 … len(E) − 1
    else:  # far more tiles than faces (small tiles, a huge grid): number the used ones
        E, fe = np.unique(face_footprints(ij, tris, t, base), return_inverse=True)
        lo, hi, ilo_e, ihi_e = group_boxes(tris, fe, pts, ij, len(E))
        facing = group_facing(tris, fe, pts, eye, len(E))
    eL, eX, eY = _table_keys(E, base)
    return _Footprints(eL, eX, eY, lo, hi, ilo_e, ihi_e, facing, fe)


ROUGH_TILES = 8  # level-0 tiles whose normals measure a terrain's roughness
ROUGH_QUANTILE = 50  # a typical fine normal: the median of a block's deviations
# footprints whose faces are seen more obliquely than this keep their facing: there the
# relief's facing gained no picture (the low flight: ±0.05 dB) and cost 16 % of a frame
ROUGH_GRAZING = math.radians(60.0)


def roughness(terrain: TerrainLike) -> np.ndarray:
    """β[m], m = 0 … t: how far (radians) the full-resolution surface's normals turn from
    a face 2^m samples across that stands for them (the ``ROUGH_QUANTILE``-th percentile
    of the angles between the level-0 normals in a 2^m × 2^m block and the block's mean
    plane, median over the blocks of ``ROUGH_TILES`` level-0 tiles spread over the
    grid); β[0] = 0 (a face of the grid's own cells is the surface). Made once per
    terrain (:meth:`~geoterrain.terrain.Terrain.derived`).

    Examples
    --------
    >>> b = roughness(t)  # by face size: 1, 2, 4, … samples across
    >>> float(b[0]), bool((np.diff(b) >= 0).all() and b[-1] > 0)
    (0.0, True)
    """
    return terrain.derived(f"{__name__}.roughness", lambda: _roughness(terrain))


def _roughness(terrain: TerrainLike) -> np.ndarray:
    t = terrain.grid.t
    keys = sorted(terrain.tile_keys(0))
    if keys:
        n = min(ROUGH_TILES, len(keys))
        keys = [keys[(2 * i + 1) * len(keys) // (2 * n)] for i in range(n)]
    dev: list[list[np.ndarray]] = [[] for _ in range(t + 1)]
    for key in keys:
        nm = np.asarray(terrain.tile_normals(*key), np.float64)[:-1, :-1]  # (2^t)² cells
        with np.errstate(invalid="ignore", divide="ignore"):
            g = nm[..., :2] / nm[..., 2:3]  # the surface's gradient, −∂z/∂(x, y)
        for m in range(1, t + 1):
            b = 1 << m
            k = nm.shape[0] // b
            if k == 0:
                break
            blk = nm[:k * b, :k * b].reshape(k, b, k, b, 3).transpose(0, 2, 1, 3, 4)
            gb = g[:k * b, :k * b].reshape(k, b, k, b, 2).transpose(0, 2, 1, 3, 4)
            mean = np.concatenate([gb.mean(axis=(2, 3)), np.ones((k, k, 1))], axis=2)
            mean /= np.linalg.norm(mean, axis=2, keepdims=True)  # the block's plane
            cos = np.einsum("pqabc,pqc->pqab", blk, mean).reshape(k, k, -1)
            with np.errstate(invalid="ignore"):
                ang = np.arccos(np.clip(cos, -1.0, 1.0))
            ok = np.isfinite(ang).all(axis=2)  # blocks without nodata
            if ok.any():  # each block's ROUGH_QUANTILE-th percentile (nearest rank)
                q = (ROUGH_QUANTILE * (b * b - 1) + 50) // 100
                dev[m].append(np.partition(ang[ok], q, axis=1)[:, q])
    beta = np.zeros(t + 1)
    for m in range(1, t + 1):
        if dev[m]:
            beta[m] = max(float(np.median(np.concatenate(dev[m]))), beta[m - 1])
        else:
            beta[m] = beta[m - 1]
    return beta


def surface_facing(fp: _Footprints, ij: np.ndarray, tris: np.ndarray, beta: np.ndarray
                   ) -> np.ndarray:
    """The footprints' facing c as the full-resolution surface under their faces would
    show it: the drawn faces' largest |cos| (``fp.facing``) with the angle to the eye
    lessened by ``beta`` (:func:`roughness`) at the faces' mean size (2^m samples
    across: a face of area a grid cells, ``ij`` its corners' (row, column), stands for
    a right triangle of legs √(2a)). Coarse faces standing for rough relief get the
    texels the relief's own faces would; the grid's own faces (bruteforce's, m = 0)
    keep theirs, and so do footprints seen more obliquely than ``ROUGH_GRAZING``.

    Examples
    --------
    >>> ij = np.array([[0, 0], [0, 1], [1, 0], [0, 4], [4, 0]])
    >>> tris = np.array([[0, 1, 2], [0, 3, 4]])  # one cell's half, a 4-sample one
    >>> fp = _Footprints(*[np.zeros(2, np.int64)] * 3, *[np.zeros((2, 3))] * 2,
    ...                  *[np.zeros((2, 2), np.int64)] * 2, np.array([0.6, 0.6]),
    ...                  np.array([0, 1]))
    >>> beta = np.radians([0.0, 10.0, 20.0])
    >>> np.round(surface_facing(fp, ij, tris, beta), 3).tolist()  # 53° less 0° and 20°
    [0.6, 0.837]
    """
    if not len(fp.facing) or not (beta > 0).any():
        return fp.facing
    mean = group_face_area(ij, tris, fp.fe, len(fp.facing))
    with np.errstate(divide="ignore"):
        m = np.clip(0.5 * np.log2(2.0 * mean), 0.0, len(beta) - 1)
    lessen = np.interp(m, np.arange(len(beta)), beta)
    out = fp.facing.copy()
    k = (lessen > 0) & (out >= math.cos(ROUGH_GRAZING))
    out[k] = np.cos(np.maximum(0.0, np.arccos(np.clip(out[k], 0.0, 1.0)) - lessen[k]))
    return out


def _texel_levels(fp: _Footprints, view, s0: float, texel_px: float, top: int,
                  magnify: int = 0) -> np.ndarray:
    """The texel level each footprint wants, from its drawn vertices' box and its faces'
    foreshortening (the texel's projected area, as a square of ``texel_px``; module
    docstring), at most ``MAX_PAGE_LEVELS`` finer than the footprint and at least
    ``-magnify`` (a magnified level, texels 2^magnify per sample)."""
    eye = np.asarray(view.eye, np.float64)
    d = np.linalg.norm(np.maximum(0.0, np.maximum(fp.lo - eye, eye - fp.hi)), axis=1)
    d = d / np.sqrt(np.maximum(fp.facing, MIN_FACING))
    f = 0.5 * view.size[1] / math.tan(math.radians(view.fov_y_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        want = np.floor(np.log2(np.maximum(d, 1e-30) * texel_px / (s0 * f)))
    want = np.clip(np.nan_to_num(want, nan=0.0, posinf=top, neginf=-magnify), -magnify,
                   top).astype(np.int64)
    return np.maximum(want, fp.L - MAX_PAGE_LEVELS)


@dataclass
class _Pages:
    """The atlas's pages: per page its texel level ``Lt``, tile (gL, gX, gY), levels ``k``
    between them, place (ax, ay) and drawn samples' box (ilo, ihi, jlo, jhi); each
    footprint's page ``e_group``; the atlas's size (AW, AH)."""

    G: int
    Lt: np.ndarray
    gL: np.ndarray
    gX: np.ndarray
    gY: np.ndarray
    k: np.ndarray
    ax: np.ndarray
    ay: np.ndarray
    AW: int
    AH: int
    e_group: np.ndarray
    ilo: np.ndarray
    ihi: np.ndarray
    jlo: np.ndarray
    jhi: np.ndarray


def _pages(fp: _Footprints, fLt: np.ndarray, t: int, top: int) -> _Pages:
    """A footprint that wants a coarser texel than its own level is drawn from its
    ancestor tile at that level (one tile page), so far footprints share pages; the
    pages are packed, every page one level coarser while the atlas exceeds
    ``MAX_ATLAS``."""
    eL, eX, eY = fp.L, fp.X, fp.Y
    up = np.maximum(fLt - eL, 0)
    L2, X2, Y2 = np.maximum(eL, fLt), eX >> up, eY >> up
    sh = 2 * (top + 1) + 1
    step = 1 << t
    while True:
        keys, e_group = np.unique(((L2 << sh | Y2) << sh | X2) << 5 | (fLt + LT_BIAS),
                                  return_inverse=True)
        G = len(keys)
        Lt = (keys & 31) - LT_BIAS
        rest = keys >> 5
        gL = rest >> (2 * sh)
        gY, gX = (rest >> sh) & ((1 << sh) - 1), rest & ((1 << sh) - 1)
        k = gL - Lt
        sizes = (step << k) + 1 + 2 * GUTTER
        ax, ay, AW, AH = _pack(sizes)
        if max(AW, AH) <= MAX_ATLAS or (fLt >= L2).all():
            break
        fLt = np.minimum(fLt + 1, L2)  # too many texels: every page one level coarser
    big = np.iinfo(np.int64)
    ilo, jlo = np.full(G, big.max), np.full(G, big.max)
    ihi, jhi = np.full(G, big.min), np.full(G, big.min)
    np.minimum.at(ilo, e_group, fp.ilo[:, 0])
    np.minimum.at(jlo, e_group, fp.ilo[:, 1])
    np.maximum.at(ihi, e_group, fp.ihi[:, 0])
    np.maximum.at(jhi, e_group, fp.ihi[:, 1])
    return _Pages(G, Lt, gL, gX, gY, k, ax, ay, AW, AH, e_group, ilo, ihi, jlo, jhi)


class _Stored:
    """Whether a texture tile's data is stored: a stored tile's key, or a magnified tile
    (level < 0) whose level-0 tile is."""

    def __init__(self, tile_info):
        self.info = tile_info

    def __contains__(self, key) -> bool:
        L, x, y = key
        return (L, x, y) in self.info if L >= 0 else (0, x >> -L, y >> -L) in self.info


def _tile_ranges(pg: _Pages, step: int) -> tuple[np.ndarray, ...]:
    """Per page, the rows ty0 … ty1 and columns tx0 … tx1 of its level-Lt tiles that its
    faces' samples touch (whole arrays, (G,) each)."""
    span = np.left_shift(step, pg.gL)  # the footprint's width in full-resolution samples
    bi, bj = pg.gY * span, pg.gX * span
    # a tile's width in level-0 samples
    wt = np.where(pg.Lt >= 0, np.left_shift(step, np.maximum(pg.Lt, 0)),
                  np.right_shift(step, np.maximum(-pg.Lt, 0)))
    last = np.left_shift(1, pg.k) - 1
    return (np.minimum(last, (pg.ilo - bi) // wt), np.minimum(last, (pg.ihi - bi - 1) // wt),
            np.minimum(last, (pg.jlo - bj) // wt), np.minimum(last, (pg.jhi - bj - 1) // wt))


def _place(pg: _Pages, tiles: tuple[np.ndarray, ...], stored, step: int, atlas: np.ndarray
           ) -> tuple[list, np.ndarray]:
    """Where each page's tiles that its faces touch (``tiles``: :func:`_tile_ranges`) go
    in ``atlas``: (tile key, row, column) of the stored ones (a tile not stored is written
    grey now), and per page the rectangle (row, column, height, width) its tiles cover."""
    rect = np.empty((pg.G, 4), np.int64)
    # one step per page, on Python ints (numpy scalars cost more than the step itself);
    # the texels are whole-array copies
    placed = []
    for gi, (lt, kk, gy, gx, py, px, ty0, ty1, tx0, tx1) in enumerate(zip(
            pg.Lt.tolist(), pg.k.tolist(), pg.gY.tolist(), pg.gX.tolist(),
            pg.ay.tolist(), pg.ax.tolist(), *(a.tolist() for a in tiles), strict=True)):
        y0, x0 = py + GUTTER, px + GUTTER
        # the texels written: these tiles' rectangle, whose border gets a gutter
        rect[gi] = (y0 + ty0 * step, x0 + tx0 * step, (ty1 - ty0 + 1) * step + 1,
                    (tx1 - tx0 + 1) * step + 1)
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                key = (lt, (gx << kk) + tx, (gy << kk) + ty)
                r, c = y0 + ty * step, x0 + tx * step
                if key not in stored:
                    atlas[r:r + step + 1, c:c + step + 1] = MISSING_GREY
                else:
                    placed.append((key, r, c))
    return placed, rect
