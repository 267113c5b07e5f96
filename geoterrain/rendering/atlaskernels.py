"""Compiled passes over a mesh's faces for the per-view texture atlas.

:func:`~geoterrain.rendering.tiletextures.build_view_texture` groups a selection's faces by
their stored-tile footprint (seed 000 §2.5: a texture quadtree beside the geometry
one), measures each footprint's drawn box, and duplicates each vertex once per page it
is drawn from. Done with numpy sorts (``argsort``, ``unique``) this cost 25–30 ms of a
45 k-triangle frame and, on a 33 M-triangle bruteforce frame, tens of GB of int64
temporaries. Here a footprint is its index in the dense (level, y, x) tile table
(``base[L] + y·across_L + x``, as :class:`~geoterrain.lod.pool.TilePool` numbers
tiles; :func:`tile_table`), so grouping is a scatter into that table and the per-page
vertex numbering a counting sort: each pass is linear in the faces.

Examples
--------
>>> import numpy as np
>>> ij = np.array([[0, 0], [0, 64], [64, 0], [64, 64]])
>>> faces = np.array([[0, 1, 2], [1, 3, 2]])  # two triangles
>>> from geoterrain.core.grid import Grid
>>> base = tile_table(Grid.for_shape(129, 129))  # 2² level-0 tiles of 65², 1 at level 1
>>> base.tolist()  # the level offsets, then each level's tiles across, then down
[0, 4, 5, 2, 1, 2, 1]
>>> fp = face_footprints(ij, faces, 6, base)
>>> fp.tolist()  # both faces lie in level-0 tile (0, 0)
[0, 0]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class AtlasPages(NamedTuple):
    """An atlas's pages as :func:`page_tcoords`'s kernel reads them, per page: its texel
    level, its footprint's level, x and y, and the atlas column and row it starts at
    (int64 arrays)."""

    texel_level: np.ndarray
    level: np.ndarray
    x: np.ndarray
    y: np.ndarray
    col: np.ndarray
    row: np.ndarray


def tile_table(grid) -> np.ndarray:
    """The dense tile table the kernels take: ``grid.offsets()`` (tile (L, x, y) is entry
    ``offsets[L] + y·across_L + x``), then each level's tiles across, then down (a square
    grid's 2^(top−L) both ways; a root grid's :meth:`~geoterrain.core.grid.Grid.tiles`)."""
    levels = grid.levels
    return np.concatenate([grid.offsets(), [grid.tiles(L)[0] for L in levels],
                           [grid.tiles(L)[1] for L in levels]]).astype(np.int64)


@njit(cache=True, nogil=True, inline="always")
def _table_top(base):
    """The top level of a :func:`tile_table`: (top + 2) offsets, 2 (top + 1) counts."""
    return (len(base) - 4) // 3


def table_size(base: np.ndarray) -> int:
    """Entries of the dense table of :func:`tile_table` ``base``."""
    return int(base[(len(base) - 4) // 3 + 1])


def _as_faces(faces: np.ndarray) -> np.ndarray:
    """Triangles (F, 3) int64, C-ordered: the kernels' input (a VTK connectivity array,
    (3F,), reshaped)."""
    return np.ascontiguousarray(np.asarray(faces).reshape(-1, 3), np.int64)


@njit(cache=True, nogil=True, inline="always")
def _footprint(ij, faces, t, base, f):
    """Face f's footprint: the dense table index of the finest tile that holds it."""
    top = _table_top(base)
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    i0 = min(ij[a, 0], ij[b, 0], ij[c, 0])
    i1 = max(ij[a, 0], ij[b, 0], ij[c, 0])
    j0 = min(ij[a, 1], ij[b, 1], ij[c, 1])
    j1 = max(ij[a, 1], ij[b, 1], ij[c, 1])
    key = base[top]  # not held by any tile: the top tile (footprints' default)
    for lv in range(top + 1):  # finest first: the first tile that holds the face
        w = np.int64(1 << t) << lv
        across, down = base[top + 2 + lv], base[2 * top + 3 + lv]
        xs, ys = min(j0 // w, across - 1), min(i0 // w, down - 1)
        if j1 <= (xs + 1) * w and i1 <= (ys + 1) * w:
            key = base[lv] + ys * across + xs
            break
    return key


@njit(cache=True, nogil=True)
def _footprints(ij, faces, t, base, out):
    for f in range(len(out)):
        out[f] = _footprint(ij, faces, t, base, f)


@njit(cache=True, nogil=True)
def _footprint_groups(ij, faces, t, base, pts, eye, key, lo, hi, ilo, ihi, facing):
    for f in range(len(key)):
        k = _footprint(ij, faces, t, base, f)
        key[f] = k
        _box(faces, f, k, pts, ij, lo, hi, ilo, ihi)
        _face_facing(faces, f, k, pts, eye, facing)


def footprint_groups(ij: np.ndarray, faces: np.ndarray, t: int, base: np.ndarray,
                     pts: np.ndarray, eye) -> tuple[np.ndarray, ...]:
    """:func:`face_footprints`, then :func:`group_boxes` and :func:`group_facing` over the
    whole dense tile table, in one pass over the faces: (key (F,), lo, hi, ilo, ihi,
    facing (n,)), n the table's size (:func:`table_size`).

    Examples
    --------
    >>> faces = np.array([[0, 1, 2]])
    >>> ij = np.array([[0, 0], [0, 8], [8, 0]])
    >>> pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> one = np.array([0, 1, 1, 1])  # one tile: offsets (0, 1), 1 across, 1 down
    >>> key, lo, hi, ilo, ihi, facing = footprint_groups(ij, faces, 3, one, pts,
    ...                                                  (1 / 3, 1 / 3, 5.0))
    >>> key.tolist(), hi[0].tolist(), round(float(facing[0]), 3)
    ([0], [1.0, 1.0, 0.0], 1.0)
    """
    faces = _as_faces(faces)
    n = table_size(base)
    key = np.empty(len(faces), np.int64)
    lo, hi, ilo, ihi = _empty_boxes(n)
    facing = np.zeros(n)
    _footprint_groups(np.ascontiguousarray(ij, np.int64), faces, t,
                      np.ascontiguousarray(base, np.int64), np.ascontiguousarray(pts, np.float64),
                      np.asarray(eye, np.float64), key, lo, hi, ilo, ihi, facing)
    return key, lo, hi, ilo, ihi, facing


def face_footprints(ij: np.ndarray, faces: np.ndarray, t: int, base: np.ndarray
                    ) -> np.ndarray:
    """Dense tile-table index of each face's footprint: the smallest stored-tile square
    (level L, x, y) that holds the face (the rule of
    :func:`~geoterrain.rendering.tiletextures.footprints`).

    ``ij`` (V, 2) grid indices, ``faces`` (F, 3) the triangles' vertex ids,
    ``t`` log2 of the tile width in samples, ``base`` the :func:`tile_table`.
    Returns (F,) int64; see the module example.
    """
    faces = _as_faces(faces)
    out = np.empty(len(faces), np.int64)
    _footprints(np.ascontiguousarray(ij, np.int64), faces, t,
                np.ascontiguousarray(base, np.int64), out)
    return out


def _empty_boxes(n: int) -> tuple[np.ndarray, ...]:
    """n empty boxes: scene lo, hi (n, 3) at ±inf, grid ilo, ihi (n, 2) at the int64
    extremes (what :func:`group_boxes` leaves for a group without faces)."""
    big = np.iinfo(np.int64)
    return (np.full((n, 3), np.inf), np.full((n, 3), -np.inf),
            np.full((n, 2), big.max, np.int64), np.full((n, 2), big.min, np.int64))


@njit(cache=True, nogil=True, inline="always")
def _box(faces, f, k, pts, ij, lo, hi, ilo, ihi):
    for c in range(3):
        v = faces[f, c]
        for d in range(3):
            lo[k, d] = min(lo[k, d], pts[v, d])
            hi[k, d] = max(hi[k, d], pts[v, d])
        for d in range(2):
            ilo[k, d] = min(ilo[k, d], ij[v, d])
            ihi[k, d] = max(ihi[k, d], ij[v, d])


@njit(cache=True, nogil=True)
def _boxes(faces, key, pts, ij, lo, hi, ilo, ihi):
    for f in range(len(key)):
        _box(faces, f, key[f], pts, ij, lo, hi, ilo, ihi)


def group_boxes(faces: np.ndarray, key: np.ndarray, pts: np.ndarray, ij: np.ndarray,
                n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per group 0 … n−1 (``key`` per face): the box of its faces' corners in scene units
    (lo, hi (n, 3)) and in grid indices (ilo, ihi (n, 2)); empty groups keep ±inf and
    the int64 extremes.

    Examples
    --------
    >>> import numpy as np
    >>> faces = np.array([[0, 1, 2]])
    >>> pts = np.array([[0., 0, 5], [1, 0, 6], [0, 1, 7]])
    >>> lo, hi, ilo, ihi = group_boxes(faces, np.array([1]), pts, np.zeros((3, 2), int), 2)
    >>> hi[1].tolist(), bool(np.isinf(lo[0]).all())
    ([1.0, 1.0, 7.0], True)
    """
    lo, hi, ilo, ihi = _empty_boxes(n)
    _boxes(_as_faces(faces), np.ascontiguousarray(key, np.int64),
           np.ascontiguousarray(pts, np.float64), np.ascontiguousarray(ij, np.int64),
           lo, hi, ilo, ihi)
    return lo, hi, ilo, ihi


@njit(cache=True, nogil=True, inline="always")
def _face_facing(faces, f, k, pts, eye, out):
    """out[k] = max(out[k], |cos|) of face f's normal and the line to ``eye``."""
    a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
    ux, uy, uz = pts[b, 0] - pts[a, 0], pts[b, 1] - pts[a, 1], pts[b, 2] - pts[a, 2]
    vx, vy, vz = pts[c, 0] - pts[a, 0], pts[c, 1] - pts[a, 1], pts[c, 2] - pts[a, 2]
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    rx = eye[0] - (pts[a, 0] + pts[b, 0] + pts[c, 0]) / 3.0
    ry = eye[1] - (pts[a, 1] + pts[b, 1] + pts[c, 1]) / 3.0
    rz = eye[2] - (pts[a, 2] + pts[b, 2] + pts[c, 2]) / 3.0
    den = np.sqrt((nx * nx + ny * ny + nz * nz) * (rx * rx + ry * ry + rz * rz))
    if den > 0.0:  # a degenerate face (no area) or one at the eye faces nothing
        cos = min(abs(nx * rx + ny * ry + nz * rz) / den, 1.0)
        if 0 <= k < len(out):  # checked: numba does not bounds-check
            out[k] = max(out[k], cos)


@njit(cache=True, nogil=True)
def _facing(faces, key, pts, eye, out):
    for f in range(len(key)):
        _face_facing(faces, f, key[f], pts, eye, out)




def group_facing(faces: np.ndarray, key: np.ndarray, pts: np.ndarray, eye, n: int
                 ) -> np.ndarray:
    """Per group 0 … n−1 (``key`` per face): the largest |cos| between a face's normal and
    the line from its centroid to ``eye``, 1 for a face seen square on, 0 edge on (and
    for an empty group). A texel on a face of facing c covers c times the pixels it
    covers square on (c times fewer across its foreshortened direction):
    :func:`~geoterrain.rendering.tiletextures.build_view_texture` sizes its texels by the side of
    that area, √c.

    Examples
    --------
    >>> import numpy as np
    >>> faces = np.array([[0, 1, 2]])
    >>> pts = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> round(float(group_facing(faces, np.array([0]), pts, (1 / 3, 1 / 3, 5.0), 1)[0]), 6)
    1.0
    >>> float(group_facing(faces, np.array([0]), pts, (5.0, 1 / 3, 0.0), 1)[0])
    0.0
    """
    out = np.zeros(n)
    _facing(_as_faces(faces), np.ascontiguousarray(key, np.int64),
            np.ascontiguousarray(pts, np.float64), np.asarray(eye, np.float64), out)
    return out


@njit(cache=True, nogil=True)
def _area_sums(ij, faces, key, area, count):
    for f in range(len(key)):
        k = key[f]
        if 0 <= k < len(area):  # checked: numba does not bounds-check
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            u0, u1 = ij[b, 0] - ij[a, 0], ij[b, 1] - ij[a, 1]
            v0, v1 = ij[c, 0] - ij[a, 0], ij[c, 1] - ij[a, 1]
            area[k] += 0.5 * abs(u0 * v1 - u1 * v0)
            count[k] += 1


def group_face_area(ij: np.ndarray, faces: np.ndarray, key: np.ndarray, n: int
                    ) -> np.ndarray:
    """Per group 0 … n−1 (``key`` per face): its faces' mean area in grid cells (from
    their corners' (row, column) ``ij``; 0 for an empty group).

    Examples
    --------
    >>> ij = np.array([[0, 0], [0, 1], [1, 0], [0, 4], [4, 0]])
    >>> group_face_area(ij, np.array([[0, 1, 2], [0, 3, 4]]), np.array([0, 0]), 2).tolist()
    [4.25, 0.0]
    """
    area, count = np.zeros(n), np.zeros(n, np.int64)
    _area_sums(np.ascontiguousarray(ij, np.int64), _as_faces(faces),
               np.ascontiguousarray(key, np.int64), area, count)
    return area / np.maximum(count, 1)


@njit(cache=True, nogil=True)
def _number(faces, group, G, V, src, pg, out_faces):
    F = len(group)
    start = np.zeros(G + 1, np.int64)  # counting sort of the faces by group
    for f in range(F):
        start[group[f] + 1] += 1
    for g in range(G):
        start[g + 1] += start[g]
    order = np.empty(F, np.int64)
    fill = start[:-1].copy()
    for f in range(F):
        g = group[f]
        order[fill[g]] = f
        fill[g] += 1
    # the (page, vertex) pairs drawn, each once, page by page in first-seen order
    stamp = np.full(V, -1, np.int64)
    pv = np.empty(3 * F, np.int64)
    pgs = np.empty(3 * F, np.int64)
    n = 0
    for g in range(G):
        for q in range(start[g], start[g + 1]):
            f = order[q]
            for c in range(3):
                v = faces[f, c]
                if stamp[v] != g:
                    stamp[v] = g
                    pv[n] = v
                    pgs[n] = g
                    n += 1
    # ordered by page, then vertex (np.unique's order), by two stable counting sorts:
    # by vertex, then by page (linear: a comparison sort per page cost 2/3 of the pass)
    cnt = np.zeros(V + 1, np.int64)
    for p in range(n):
        cnt[pv[p] + 1] += 1
    for v in range(V):
        cnt[v + 1] += cnt[v]
    byv = np.empty(n, np.int64)
    for p in range(n):
        byv[cnt[pv[p]]] = p
        cnt[pv[p]] += 1
    pstart = np.zeros(G + 1, np.int64)
    for p in range(n):
        pstart[pgs[p] + 1] += 1
    for g in range(G):
        pstart[g + 1] += pstart[g]
    fill = pstart[:-1].copy()
    for q in range(n):
        p = byv[q]
        g = pgs[p]
        src[fill[g]] = pv[p]
        pg[fill[g]] = g
        fill[g] += 1
    newid = np.empty(V, np.int64)
    for g in range(G):  # the faces renumbered into their page's points
        for p in range(pstart[g], pstart[g + 1]):
            newid[src[p]] = p
        for q in range(start[g], start[g + 1]):
            f = order[q]
            for c in range(3):
                out_faces[f, c] = newid[faces[f, c]]
    return n


def number_pages(faces: np.ndarray, group: np.ndarray, n_groups: int, n_vertices: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One point per (page, vertex) drawn: a vertex shared by two pages is duplicated.

    Returns ``source`` (P,) the vertex each point copies, ``page`` (P,) its page, and
    the faces (F, 3) renumbered into the points, in the faces' own order. Points are
    ordered by page, then vertex (the order of ``np.unique(page·V + vertex)``).

    Examples
    --------
    >>> import numpy as np
    >>> faces = np.array([[0, 1, 2], [1, 3, 2]])
    >>> src, page, faces = number_pages(faces, np.array([1, 0]), 2, 4)
    >>> src.tolist(), page.tolist(), faces.tolist()
    ([1, 2, 3, 0, 1, 2], [0, 0, 0, 1, 1, 1], [[3, 4, 5], [0, 2, 1]])
    """
    F = len(group)
    src = np.empty(3 * F, np.int64)
    pg = np.empty(3 * F, np.int64)
    out = np.empty((F, 3), np.int64)
    n = _number(_as_faces(faces), np.ascontiguousarray(group, np.int64),
                n_groups, n_vertices, src, pg, out)
    return src[:n].copy(), pg[:n].copy(), out


@njit(cache=True, nogil=True)
def _tcoords(src, pg, ij, pts, pages, step, gutter, AW, AH, tc, out_pts):
    Lt, gL, gX, gY, ax, ay = pages
    for p in range(len(src)):
        g, v = pg[p], src[p]
        scale = 2.0 ** Lt[g]  # a texel's width in level-0 samples (a fraction: magnified)
        span = np.float64(step << gL[g])
        col = (ax[g] + gutter) + (ij[v, 1] - gX[g] * span) / scale
        row = (ay[g] + gutter) + (ij[v, 0] - gY[g] * span) / scale
        tc[p, 0] = (col + 0.5) / AW
        tc[p, 1] = (row + 0.5) / AH
        for d in range(3):
            out_pts[p, d] = pts[v, d]


def page_tcoords(src: np.ndarray, pg: np.ndarray, ij: np.ndarray, pts: np.ndarray,
                 pages: tuple, step: int, gutter: int, size: tuple[int, int]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Each point's texture coordinates (P, 2) float32 in the atlas and its position
    (P, 3): point p copies vertex ``src[p]`` (grid indices ``ij``, scene ``pts``) on page
    ``pg[p]``. ``pages`` = (texel level, footprint level, x, y, atlas column, atlas row)
    arrays per page; ``size`` the atlas's (width, height). A texel's centre is at
    (column + 0.5) / width, VTK's v at (row + 0.5) / height.

    Examples
    --------
    >>> one = np.array([0]), np.array([0]), np.array([0]), np.array([0])
    >>> tc, xyz = page_tcoords(np.array([0]), np.array([0]), np.array([[2, 3]]),
    ...                        np.array([[1.0, 2.0, 3.0]]), (*one, np.array([5]),
    ...                        np.array([7])), 4, 1, (20, 10))
    >>> tc.tolist(), xyz.tolist()  # column 5 + 1 + 3, row 7 + 1 + 2
    ([[0.4749999940395355, 1.0499999523162842]], [[1.0, 2.0, 3.0]])
    """
    pages = AtlasPages(*(np.ascontiguousarray(a, np.int64) for a in pages))
    tc = np.empty((len(src), 2), np.float32)
    out_pts = np.empty((len(src), 3), np.float64)
    _tcoords(np.ascontiguousarray(src, np.int64), np.ascontiguousarray(pg, np.int64),
             np.ascontiguousarray(ij, np.int64), np.ascontiguousarray(pts, np.float64),
             pages, int(step), int(gutter), float(size[0]), float(size[1]), tc, out_pts)
    return tc, out_pts


@njit(cache=True, nogil=True)
def _magnify(atlas, r, c, anc, oy, ox, d, n):
    for i in range(n):
        si = oy + (i >> d)
        for j in range(n):
            sj = ox + (j >> d)
            for k in range(3):
                atlas[r + i, c + j, k] = anc[si, sj, k]


def magnify_into(atlas: np.ndarray, r: int, c: int, anc: np.ndarray, oy: int, ox: int,
                 d: int, n: int) -> None:
    """Write ``anc``'s texels from (oy, ox), each repeated 2^d × 2^d, into the n × n block
    of ``atlas`` at (r, c): a stand-in tile magnified from a cached ancestor, with no
    index arrays (a numpy fancy-index copy took 31 µs a 65² tile).

    Examples
    --------
    >>> a = np.zeros((4, 4, 3), np.uint8)
    >>> magnify_into(a, 0, 0, np.arange(12, dtype=np.uint8).reshape(2, 2, 3), 0, 0, 1, 4)
    >>> a[:, :, 0].tolist()
    [[0, 0, 3, 3], [0, 0, 3, 3], [6, 6, 9, 9], [6, 6, 9, 9]]
    """
    last = (n - 1) >> d  # the last ancestor texel read, from (oy, ox)
    if not (0 <= r and 0 <= c and r + n <= atlas.shape[0] and c + n <= atlas.shape[1]
            and 0 <= oy and 0 <= ox and oy + last < anc.shape[0] and ox + last < anc.shape[1]
            and atlas.shape[2:] == anc.shape[2:] == (3,)):
        raise ValueError("a stand-in block reads or writes outside its arrays")
    _magnify(atlas, int(r), int(c), anc, int(oy), int(ox), int(d), int(n))


@njit(cache=True, nogil=True)
def _clamp_fill(atlas, rect, box):
    for g in range(rect.shape[0]):
        a, b, h, w = rect[g, 0], rect[g, 1], rect[g, 2], rect[g, 3]
        j0, j1 = box[g, 1], box[g, 1] + box[g, 3]
        for i in range(box[g, 0], box[g, 0] + box[g, 2]):
            si = min(max(i, a), a + h - 1)
            if a <= i < a + h:  # a written row: only its texels left and right of it
                for j in range(j0, b):
                    for k in range(3):
                        atlas[i, j, k] = atlas[si, b, k]
                for j in range(b + w, j1):
                    for k in range(3):
                        atlas[i, j, k] = atlas[si, b + w - 1, k]
                continue
            for j in range(j0, j1):
                sj = min(max(j, b), b + w - 1)
                for k in range(3):
                    atlas[i, j, k] = atlas[si, sj, k]


def clamp_fill(atlas: np.ndarray, rect: np.ndarray, box: np.ndarray) -> None:
    """Every texel of ``box[g]`` outside ``rect[g]`` (rows (row, column, height, width))
    set to the nearest texel of ``rect[g]``: a page's written tiles clamped to its edge,
    as GL's clamp-to-edge would, out to the page's gutter. A multisampled pixel is shaded
    at its centre, which at a seam may lie past the face, by more than a texel on an
    oblique page; it then reads the page's own edge, not unwritten memory.

    Examples
    --------
    >>> a = np.zeros((4, 5, 3), np.uint8); a[1:3, 1:4, 0] = [[1, 2, 3], [4, 5, 6]]
    >>> clamp_fill(a, np.array([[1, 1, 2, 3]]), np.array([[0, 0, 4, 5]]))
    >>> a[:, :, 0].tolist()
    [[1, 1, 2, 3, 3], [1, 1, 2, 3, 3], [4, 4, 5, 6, 6], [4, 4, 5, 6, 6]]
    """
    rect, box = np.asarray(rect, np.int64).reshape(-1, 4), np.asarray(box, np.int64).reshape(-1, 4)
    H, W = atlas.shape[:2]
    if len(rect) and ((rect[:, 2:] < 1).any() or (box[:, :2] < 0).any()
                      or (box[:, 0] + box[:, 2] > H).any() or (box[:, 1] + box[:, 3] > W).any()
                      or (rect[:, :2] < box[:, :2]).any()
                      or (rect[:, :2] + rect[:, 2:] > box[:, :2] + box[:, 2:]).any()):
        raise ValueError("a page's rectangle or box lies outside the atlas")
    _clamp_fill(atlas, rect, box)
