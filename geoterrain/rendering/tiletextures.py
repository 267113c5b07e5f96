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
faces' normals and the line to the eye, at least ``MIN_FACING``), clamped to
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

from geoterrain.core.grid import level_offsets
from geoterrain.core.memory import ZeroPool
from geoterrain.rendering.atlaskernels import (
    clamp_fill,
    face_footprints,
    footprint_groups,
    group_boxes,
    group_facing,
    magnify_into,
    number_pages,
    page_tcoords,
)
from geoterrain.rendering.textures import sample_spacing

if TYPE_CHECKING:
    from geoterrain.rendering.tileshader import TileShader
    from geoterrain.terrainlike import TerrainLike

TEXEL_PX = 1.5  # texels of 0.75-1.5 px: finer ones alias without mipmaps (measured below)
MIN_FACING = 2.0 ** -8  # a footprint seen edge on: 4 levels coarser, at most the top
MAX_PAGE_LEVELS = 3  # a footprint's page is at most 2^3 × 2^3 tiles (513² texels at t = 6)
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
    top = grid.top_level
    base = level_offsets(top)
    return _table_keys(face_footprints(ij, faces, grid.t, base), base)


def _table_keys(e: np.ndarray, base: np.ndarray) -> tuple[np.ndarray, ...]:
    """(L, x, y) of dense tile-table indices ``e``."""
    top = len(base) - 2
    L = np.searchsorted(base, e, side="right") - 1
    rem = e - base[L]
    return L, rem & ((np.int64(1) << (top - L)) - 1), rem >> (top - L)


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
                       texel_px: float = TEXEL_PX, max_builds: int | None = None
                       ) -> ViewTexture:
    """The atlas of what ``selection`` draws in ``view`` at about ``texel_px`` px per texel,
    its tiles shaded by ``shader`` (:class:`~geoterrain.rendering.tileshader.TileShader`:
    the picture's style).

    ``max_builds`` caps the tiles shaded anew by this call (an interactive frame's
    budget): past it, a tile whose shading is not cached is cut from its nearest cached
    ancestor's, magnified (``stats["textures_deferred"]`` counts them; a later call
    with the same selection shades the next ones). None: every tile at its own level.

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
    base = level_offsets(top)
    mesh = selection.mesh
    built0 = shader.built
    counter = {"textures_built": 0}
    if mesh.n_cells == 0 or mesh.n_points == 0:
        return ViewTexture(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 2),
                           np.float32), np.zeros(0, np.int64), np.zeros((1, 1, 3), np.uint8),
                           {**counter, "texture_tiles": 0, "textures_deferred": 0,
                            "pages": 0, "texel_levels": {}, "atlas": [0, 0],
                            "texture_ms": 0.0})
    pts = np.asarray(mesh.points, np.float64)
    ij = np.asarray(mesh.point_data["grid_ij"])
    # the triangles from the cells' connectivity (the selections' fixed-size cell arrays
    # have no legacy array; exporting one walks every cell: 1 ms a frame at 50 k faces),
    # copied as int64 (0.1 ms): nothing below keeps a view of VTK's own array
    from vtkmodules.util.numpy_support import vtk_to_numpy

    tris = np.array(vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()),
                    np.int64).reshape(-1, 3)  # (F, 3)
    ntab = int(base[-1])
    eye = np.asarray(view.eye, np.float64)
    if ntab <= max(DENSE_TABLE, DENSE_PER_FACE * len(tris)):  # a scatter into the table
        fkey, lo, hi, ilo_e, ihi_e, facing = footprint_groups(ij, tris, g.t, base, pts, eye)
        E = np.flatnonzero(np.isfinite(lo[:, 0]))  # the footprints some face lies in
        lo, hi, ilo_e, ihi_e, facing = lo[E], hi[E], ilo_e[E], ihi_e[E], facing[E]
        pos = np.empty(ntab, np.int64)
        pos[E] = np.arange(len(E))
        fe = pos[fkey]  # each face's footprint, numbered 0 … len(E) − 1
    else:  # far more tiles than faces (small tiles, a huge grid): number the used ones
        E, fe = np.unique(face_footprints(ij, tris, g.t, base), return_inverse=True)
        lo, hi, ilo_e, ihi_e = group_boxes(tris, fe, pts, ij, len(E))
        facing = group_facing(tris, fe, pts, eye, len(E))
    eL, eX, eY = _table_keys(E, base)
    sh = 2 * (top + 1) + 1
    # 1. the texel level each footprint wants, from its drawn vertices' box and its
    #    faces' foreshortening (the texel's projected area, as a square of TEXEL_PX)
    d = np.linalg.norm(np.maximum(0.0, np.maximum(lo - eye, eye - hi)), axis=1)
    d = d / np.sqrt(np.maximum(facing, MIN_FACING))
    f = 0.5 * view.size[1] / math.tan(math.radians(view.fov_y_deg) / 2)
    s0 = sample_spacing(terrain)
    with np.errstate(divide="ignore", invalid="ignore"):
        want = np.floor(np.log2(np.maximum(d, 1e-30) * texel_px / (s0 * f)))
    want = np.clip(np.nan_to_num(want, nan=0.0, posinf=top, neginf=0.0), 0,
                   top).astype(np.int64)
    fLt = np.maximum(want, eL - MAX_PAGE_LEVELS)
    # 2. a footprint that wants a coarser texel than its own level is drawn from its
    #    ancestor tile at that level (one tile page), so far footprints share pages
    up = np.maximum(fLt - eL, 0)
    L2, X2, Y2 = np.maximum(eL, fLt), eX >> up, eY >> up
    step = 1 << g.t
    while True:
        keys, e_group = np.unique(((L2 << sh | Y2) << sh | X2) << 5 | fLt,
                                  return_inverse=True)
        G = len(keys)
        Lt = keys & 31
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
    np.minimum.at(ilo, e_group, ilo_e[:, 0])
    np.minimum.at(jlo, e_group, ilo_e[:, 1])
    np.maximum.at(ihi, e_group, ihi_e[:, 0])
    np.maximum.at(jhi, e_group, ihi_e[:, 1])
    # zeroed, on 4 KiB pages (a fresh atlas on huge pages stalled on its first touch,
    # the kernel compacting memory for them: 11 ms of an 8 MB atlas's fill), reused once
    # the atlas shown before is released (a fresh mapping faulted page by page: 1.4 ms
    # of a 4 MB atlas). The pages are filled below (their tiles, then clamped to those
    # over the rest of the page and its gutter), so the atlas is not filled with a colour
    # first: only a multisampled pixel shaded more than a texel past a face, at a grazing
    # seam, reads the shelves' slack, zero (3 pixels of 256 k, by up to 15 levels, in a
    # review's view; they read grey before, as wrong)
    atlas = _ATLASES.zeros((AH, AW, 3), np.uint8)
    n_tiles = deferred = 0
    rect = np.empty((G, 4), np.int64)  # per page: row, column, height, width written
    stored = terrain.tile_info
    # one step per page, on Python ints (numpy scalars cost more than the step itself);
    # the texels are whole-array copies
    placed = []  # (tile key, atlas row, atlas column) of every stored tile drawn
    for gi, (lt, kk, gl, gy, gx, py, px, i0, i1, j0, j1) in enumerate(zip(
            Lt.tolist(), k.tolist(), gL.tolist(), gY.tolist(), gX.tolist(), ay.tolist(),
            ax.tolist(), ilo.tolist(), ihi.tolist(), jlo.tolist(), jhi.tolist(),
            strict=True)):
        span = step << gl  # the footprint's width in full-resolution samples
        bi, bj = gy * span, gx * span
        y0, x0 = py + GUTTER, px + GUTTER
        wt = step << lt  # a level-lt tile's width in full-resolution samples
        last = (1 << kk) - 1
        ty0, ty1 = min(last, (i0 - bi) // wt), min(last, (i1 - bi - 1) // wt)
        tx0, tx1 = min(last, (j0 - bj) // wt), min(last, (j1 - bj - 1) // wt)
        # the texels written: these tiles' rectangle, whose border gets a gutter below
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
    # the tiles' shading, those not cached shaded now (at most max_builds, in drawing
    # order); past the budget a tile is cut from a cached ancestor where there is one
    rgbs = shader([key for key, _, _ in placed], max_builds)
    for (key, r, c), rgb in zip(placed, rgbs, strict=True):
        n_tiles += 1
        if rgb is None:
            if _stand_in(shader, top, key, step, atlas, r, c):
                deferred += 1
                continue
            rgb = shader.tile(*key)
        atlas[r:r + step + 1, c:c + step + 1] = rgb
    counter["textures_built"] = shader.built - built0
    # each page's written tiles clamped to their edge over the rest of the page and its
    # gutter (a multisampled pixel centre may fall past a face at a page's seam)
    page = (step << k) + 1 + 2 * GUTTER  # a page's allocation: its texels and gutter
    clamp_fill(atlas, rect, np.stack([ay, ax, page, page], 1))
    # one point per (page, vertex): a vertex shared by two pages is duplicated
    src, pg, faces = number_pages(tris, e_group[fe], G, len(pts))
    # VTK's v: the image's row 0 at v = 0 (see ViewTexture)
    tc, xyz = page_tcoords(src, pg, ij, pts, (Lt, gL, gX, gY, ax, ay), step, GUTTER,
                           (AW, AH))
    atlas.setflags(write=False)  # shown by VTK without a copy (rendering._image_data)
    lv, nlv = np.unique(Lt, return_counts=True)
    st = {**counter, "texture_tiles": n_tiles, "textures_deferred": deferred, "pages": G,
          "texel_levels": {int(a): int(b) for a, b in zip(lv, nlv, strict=True)},
          "atlas": [int(AW), int(AH)],
          "texture_ms": round((time.perf_counter() - t0) * 1e3, 3)}
    return ViewTexture(xyz, faces, tc, src, atlas, st)
