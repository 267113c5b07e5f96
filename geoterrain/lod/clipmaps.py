"""Geometry clipmaps (seed 000 §2.9, Losasso & Hoppe 2004; §2.10, Asirvatham & Hoppe):
what ``clipmap``, ``clipmap_bounded`` and ``clipmap_gpu`` share.

- **Levels.** Level l is the pyramid's level l (every 2^l-th sample, the store's heights);
  its clip region is an n × n grid of level-l vertices (n = 2^k − 1, default 255, odd so
  that its perimeter falls on the coarser level's vertices), centred on the viewer and
  snapped to even level-l vertices (rule 3: the active perimeter lies on even vertices).
  The finest active level f is the finest whose extent n·g_l is at least 2.5 times the
  viewer's height above the terrain (§2.9: levels with h > 0.4·n·g_l are skipped); the
  coarsest is the first whose grid covers the whole DEM (as the paper's coarsest level
  covers its terrain: levels leave and join at the fine end only). Choice: h is the
  height above the highest terrain the clipmap covers, not above the ground under the
  eye, so a level flight keeps its levels and draws a constant count before culling
  (above the ground under the eye, the one-minute loop switched the finest level with
  the ridges it crossed: 226 316 to 323 090 triangles); it never gives a coarser level
  than the ground under the eye would. The count changes only when the viewer climbs or descends
  through a level's 0.4·n·g_l.
- **Active regions and cropping.** A clip region is moved inside the data rectangle
  (cropping: a region that reaches past the DEM is shifted back rather than cut, so it
  keeps its n × n vertices; one wider than the DEM is cut to it). Nesting holds after the
  shift (rule 4: a finer region inside its coarser one). Level l draws its render region
  active(l) − active(l − 1) as the level's union-jack triangles (a conforming cut of the
  project's bintree, docs/conventions.md).
- **No cracks.** Where a level-l region meets the coarser level l + 1, the two level-l
  triangles along each level-(l+1) edge are replaced by their bintree parent (the fine
  side drops its odd perimeter vertex, the degenerate-triangle ring of the paper made
  conforming): every edge is shared by at most two triangles, no T-junction.
- **Transition regions** (eq. 4-30 … 4-32): a vertex whose home level is l (the coarsest
  level holding it, where it is odd) is blended towards the level-(l+1) surface by
  α = max(α_x, α_y), α_x = clamp((|x − v_x| − ((x_max − x_min)/2 − w − 1)) / w, 0, 1) in
  level-l units around the viewer v, w = n/10 (≥ 2): α = 1 at the region's perimeter.
- **No data.** A clipmap assumes complete data. A level-l cell whose footprint mixes
  data and no-data is drawn by level l − 1 (its four cells) instead, recursively down to
  level 0, where only triangles with three valid corners are drawn; a cell next to a
  region drawn two levels finer is refined too (precomputed once per terrain), so levels
  meeting at an edge differ by at most one and stitch as above. Valid data is never
  left uncovered.
- **Toroidal updates.** Each level keeps its n × n heights in a toroidal buffer (sample
  (r, c) at [r mod n, c mod n]) and a normal map of the same shape, computed from its
  heights (§2.9: normal maps from the geometry). When the region moves, only the newly
  exposed rows and columns (an L-shaped ring) are read from the store's tiles, and only
  their normals (and the normals beside them, whose differences change) are recomputed
  (stats ``samples_updated``, ``normals_updated``).
- **Culling** (``cull``): each render region is cut into rectangles (4 for ``clipmap``,
  as the paper; the footprints of ``clipmap_gpu``), each culled by its stored tiles' boxes
  against the frustum and, with ``occlusion``, the horizon. ``clipmap`` does not cull by
  default (its whole rings, so the count it draws does not follow the heading: §2.9's
  steady rendering rate); ``clipmap_gpu`` and ``clipmap_bounded`` do. A view whose
  frustum misses the whole terrain draws nothing, culling or not.

State (the buffers and regions of the last frame) lives in the terrain's derived slot,
one per strategy, n and culling (:func:`state_key`); any view or τ is handled, a far jump
just reads more. The
per-terrain tables and the toroidal buffers are :mod:`geoterrain.lod.clipmapdata`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain.core.view import OUTSIDE, View
from geoterrain.lod.clipmapdata import Level, Tables, buffer_heights, tables, update_level
from geoterrain.lod.mesh import empty_parts, mesh_parts, orient_ccw
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import TileIndex, tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

N_DEFAULT = 255  # n = 2^k − 1 vertices per side (§2.9)
HEIGHT_FACTOR = 0.4  # §2.9: a level is skipped while the viewer's height > 0.4·n·g_l


# ------------------------------------------------------------------ regions
def viewer_grid(terrain: TerrainLike, view: View) -> tuple[float, float]:
    """The eye's position in full-resolution grid indices (row, column)."""
    f = terrain.frame
    X, Y = f.scene_to_crs(np.array([view.eye[0]]), np.array([view.eye[1]]))
    a, b, c, d, e, ff = f.transform[:6]
    det = a * e - b * d
    x, y = float(X[0]) - c, float(Y[0]) - ff
    j = (e * x - b * y) / det - 0.5
    i = (-d * x + a * y) / det - 0.5
    return i, j


def region(centre: float, half: int, lo: int, hi: int) -> tuple[int, int]:
    """A level's vertex range [r0, r0 + 2·half] centred on ``centre`` (level units),
    its ends even, moved inside [lo, hi] (cropping by a shift), cut to it when wider.

    Examples
    --------
    >>> region(100.3, 4, 0, 1000), region(1.0, 4, 0, 1000), region(5.0, 40, 0, 20)
    ((96, 104), (0, 8), (0, 20))
    """
    r0 = 2 * int(math.floor((centre - half) / 2.0 + 0.5))
    r0 = max(min(r0, hi - 2 * half), lo)
    r0 -= r0 % 2
    r1 = min(r0 + 2 * half, hi)
    return r0, r1


@njit(cache=True, nogil=True)
def number_vertices(keys, vmap, verts):
    """Local ids of flat sample ``keys`` (first use order) into ``verts``; ``vmap`` (N²,
    int32, all −1) is left all −1. Returns (ids, V)."""
    ids = np.empty(keys.shape[0], np.int64)
    V = 0
    for k in range(keys.shape[0]):
        w = keys[k]
        if vmap[w] < 0:
            vmap[w] = V
            verts[V] = w
            V += 1
        ids[k] = vmap[w]
    for k in range(V):
        vmap[verts[k]] = -1
    return ids, V


# ------------------------------------------------------------------ a frame
def _rects(kind: str, W: tuple, inner: tuple | None) -> list[tuple[int, int, int, int]]:
    """The culling rectangles (cell ranges a0, a1, b0, b1) of a level's render region:
    ``clipmap``: the four strips around the finer region (one rectangle at the finest
    level), as §2.9; ``gpu``: the footprints of §2.10 on a 5 × 5 grid (m × m blocks,
    m × 3 fix-ups, the centre), whatever the finer region masks."""
    a0, a1, b0, b1 = W
    if kind == "gpu":
        def cuts(lo, hi):
            S = hi - lo
            m1 = max((S - 2) // 4, 1)  # m − 1 cells per block
            c = [lo, lo + m1, lo + 2 * m1, lo + 2 * m1 + 2, lo + 3 * m1 + 2, hi]
            c = [min(max(v, lo), hi) for v in c]
            return list(zip(c[:-1], c[1:], strict=True))
        return [(ra, rb, ca, cb) for ra, rb in cuts(a0, a1) for ca, cb in cuts(b0, b1)
                if ra < rb and ca < cb]
    if inner is None:
        return [W]
    q0, q1, p0, p1 = inner
    out = [(a0, q0, b0, b1), (q1, a1, b0, b1), (q0, q1, b0, p0), (q0, q1, p1, b1)]
    return [r for r in out if r[0] < r[1] and r[2] < r[3]]


def _rect_box(tb: Tables, index: TileIndex, lv: int, r: tuple) -> tuple | None:
    """The stored tiles' boxes over a level-``lv`` cell rectangle (None: no tile there)
    and their index rows."""
    Lt = min(lv, tb.top)
    span = tb.t + Lt
    across, down = tb.tiles[Lt]
    i0, i1 = (r[0] << lv) >> span, min(((r[1] << lv) - 1) >> span, down - 1)
    j0, j1 = (r[2] << lv) >> span, min(((r[3] << lv) - 1) >> span, across - 1)
    rows = tb.table[tb.base[Lt] + np.arange(i0, i1 + 1)[:, None] * across
                    + np.arange(j0, j1 + 1)[None, :]].ravel()
    rows = rows[rows >= 0]
    if not len(rows):
        return None
    return index.lo[rows].min(0), index.hi[rows].max(0), rows


def state_key(kind: str = "clipmap", n: int = N_DEFAULT, cull: bool | None = None) -> str:
    """The terrain's derived slot holding a clipmap's buffers and regions: one per kind,
    n and culling (``None``: the kind's default), so that two settings never share a
    frame's updates.

    Examples
    --------
    >>> state_key()
    'geoterrain.lod.clipmaps.state.clipmap.255'
    >>> state_key(cull=True).rsplit(".", 3)[1:], state_key("gpu", 31).rsplit(".", 2)[1:]
    (['clipmap', '255', 'cull'], ['gpu', '31'])
    """
    culls = _culls(kind, cull)
    tail = "" if culls == _culls(kind, None) else (".cull" if culls else ".whole")
    return f"{__name__}.state.{kind}.{n}{tail}"


def _culls(kind: str, cull: bool | None) -> bool:
    """Whether ``kind`` culls its render regions: ``clipmap`` draws its whole rings unless
    asked (``cull=True``), ``gpu`` and ``bounded`` cull unless asked not to."""
    return kind != "clipmap" if cull is None else bool(cull)


def select(terrain: TerrainLike, view: View, tau: float, *, kind: str = "clipmap",
           occlusion: bool = True, morph: bool = True, n: int = N_DEFAULT,
           cull: bool | None = None):
    """The geometry-clipmap mesh of ``view`` and its stats. ``kind``: ``clipmap`` (n × n
    regions, §2.9), ``bounded`` (the finest level and the regions' sizes from the stored
    tile errors, so ρ ≤ τ), ``gpu`` (§2.10's footprints); ``morph``: the transition
    regions (eq. 4-30 … 4-32); ``cull``: cull the render regions' rectangles against the
    frustum and, with ``occlusion``, the horizon (None: the kind's default, off for
    ``clipmap``, on for the others); without it the whole rings are drawn and
    ``occlusion`` is not used.

    Examples
    --------
    >>> mesh, stats = select(t, View((0, -800, 400), (0, 0, 0)), 4.0, n=31)
    >>> mesh.n_cells > 0 and stats["levels"][0] == stats["finest_level"]
    True
    """
    if n < 7 or (n + 1) & n:
        raise ValueError(f"n must be 2^k − 1 ≥ 7, got {n}")
    index = tile_index(terrain)
    if index.outside(view):
        return empty_parts(), {}
    bounded = kind == "bounded"
    tb = tables(terrain, bounded)
    g = terrain.grid
    N = tb.N
    cull = _culls(kind, cull)
    state = terrain.derived(state_key(kind, n, cull), dict)
    vi, vj = viewer_grid(terrain, view)
    half0 = (n - 1) // 2
    # the coarsest level: the first whose region covers the DEM (the grid's last level
    # with an even number of cells per side at most)
    span = max(tb.H, tb.W) - 1
    cap = max(g.n - 1, 0)
    if bounded:
        cap = min(cap, tb.top)
    Lmax = cap
    for lv in range(cap + 1):
        if (n - 1) << lv >= span:
            Lmax = lv
            break
    # §2.9's h, the viewer's height above the terrain, measured above the highest terrain
    # the clipmap covers (choice: not the ground under the eye, which changes with every
    # ridge a level flight crosses and would switch the finest level, and the drawn count
    # with it, frame to frame; never a coarser level than the ground under the eye gives)
    h = max(float(view.eye[2]) - float(np.nanmax(index.hi[:, 2])), 0.0)
    halves = {lv: half0 for lv in range(Lmax + 1)}
    if bounded:
        f, halves = _bounded_levels(terrain, index, tb, view, tau, Lmax, half0, vi, vj,
                                    state)
    else:
        f = Lmax
        for lv in range(Lmax + 1):  # §2.9: skip the levels with h > 0.4·n·g_l
            if HEIGHT_FACTOR * n * (1 << lv) * tb.dx >= h:
                f = lv
                break
    # regions, coarse to fine; each inside the coarser one (level-l vertex ranges)
    W: dict[int, tuple[int, int, int, int]] = {}
    open_: dict[int, tuple[bool, ...]] = {}
    sizes: dict[int, int] = {}
    for lv in range(Lmax, f - 1, -1):
        s = 1 << lv
        # the last level row / column the data reaches, rounded up to an even vertex
        hi_r = min(_even_up(-(-(tb.H - 1) // s)), (tb.NR - 1) // s)
        hi_c = min(_even_up(-(-(tb.W - 1) // s)), (N - 1) // s)
        r0, r1 = region(vi / s, halves[lv], 0, hi_r)
        c0, c1 = region(vj / s, halves[lv], 0, hi_c)
        if lv < Lmax:  # nesting: inside the coarser region
            P = W[lv + 1]
            r0, r1 = max(r0, 2 * P[0]), min(r1, 2 * P[1])
            c0, c1 = max(c0, 2 * P[2]), min(c1, 2 * P[3])
        W[lv] = (r0, r1, c0, c1)
        # which sides meet a coarser level (a side on the data's edge meets none)
        open_[lv] = (r0 > 0, r1 < hi_r, c0 > 0, c1 < hi_c)
        sizes[lv] = min(2 * halves[lv] + 1, max(hi_r, hi_c) + 1)  # the buffers' side
    # toroidal updates
    levels = state.setdefault("levels", {})
    n_h = n_n = 0
    for lv, (r0, r1, c0, c1) in W.items():
        size = max(r1 - r0 + 1, c1 - c0 + 1, sizes[lv])
        st = levels.get(lv)
        if st is None or st.size < size:
            st = levels[lv] = Level(size)
        a, b = update_level(terrain, index, st, lv, r0, r1, c0, c1, tb.dx * (1 << lv))
        n_h += a
        n_n += b
    for lv in [k for k in levels if k not in W]:
        del levels[lv]  # a level that left the clipmap (the viewer climbed): dropped
    hidden = hidden_rows(terrain, view, enabled=occlusion) if cull else None
    # render regions (culled with ``cull``), and the cells no-data sends to finer levels
    cells: dict[int, list] = {lv: [] for lv in range(Lmax + 1)}
    extra: dict[int, list] = {lv: [] for lv in range(Lmax + 1)}
    culled = 0
    geometry = 0
    for lv in range(Lmax, f - 1, -1):
        r0, r1, c0, c1 = W[lv]
        inner = None
        if lv > f:
            q = W[lv - 1]
            inner = (q[0] // 2, q[1] // 2, q[2] // 2, q[3] // 2)
        mask = np.ones((r1 - r0, c1 - c0), bool)
        if inner is not None:
            mask[inner[0] - r0:inner[1] - r0, inner[2] - c0:inner[3] - c0] = False
        geometry += 2 * int(mask.sum())
        rects = _rects(kind if kind == "gpu" else "clipmap", (r0, r1, c0, c1), inner) \
            if cull else []
        for rc in rects:
            got = _rect_box(tb, index, lv, rc)
            sub = mask[rc[0] - r0:rc[1] - r0, rc[2] - c0:rc[3] - c0]
            if got is None:
                continue
            lo, hi, rows = got
            if view.box_visibility(lo, hi) == OUTSIDE or hidden[rows].all():
                culled += int(sub.sum())
                sub[:] = False
        a, b = np.nonzero(mask)
        cells[lv].append((a + r0, b + c0))
    for lv in range(Lmax, -1, -1):  # no-data: a cell that must be drawn finer
        parts = cells[lv] + extra[lv]
        if not parts:
            continue
        a = np.concatenate([p[0] for p in parts])
        b = np.concatenate([p[1] for p in parts])
        ref = tb.refine[lv]
        down = ref[np.minimum(a, ref.shape[0] - 1), np.minimum(b, ref.shape[1] - 1)] \
            if lv > 0 else np.zeros(len(a), bool)
        cells[lv] = [(a[~down], b[~down])]
        if down.any():
            da, db = a[down], b[down]
            extra[lv - 1].append((np.repeat(2 * da, 4) + np.tile([0, 0, 1, 1], len(da)),
                                  np.repeat(2 * db, 4) + np.tile([0, 1, 0, 1], len(db))))
    mesh, nv, nd = _emit(terrain, tb, levels, W, cells, Lmax, f, (vi, vj), morph, open_,
                         state)
    stats = {"levels": (f, Lmax), "finest_level": f, "clipmap_n": n,
             "clipmap_triangles": geometry, "culled": cull, "cells_culled": culled,
             "samples_updated": n_h, "normals_updated": n_n, "refined_cells": nd}
    if bounded:
        stats["region_halves"] = tuple(halves[lv] for lv in range(f, Lmax + 1))
    return mesh, stats


def _even_up(x: int) -> int:
    return x + (x & 1)


def _coarser(tb: Tables, W: dict, Lmax: int, lv: int, na: np.ndarray, nb: np.ndarray
             ) -> np.ndarray:
    """Whether the level-``lv`` cells (na, nb) are drawn coarser than level lv: outside
    level lv's region and in a level-(lv+1) cell that no-data does not send finer (the
    levels meeting at an edge differ by at most one, so coarser is lv + 1)."""
    ok = (na >= 0) & (nb >= 0)
    if lv >= Lmax:
        return np.zeros(len(na), bool)
    if lv in W:
        r0, r1, c0, c1 = W[lv]
        ok &= ~((na >= r0) & (na < r1) & (nb >= c0) & (nb < c1))
    ref = tb.refine[lv + 1]
    pa, pb = na >> 1, nb >> 1
    ok &= (pa < ref.shape[0]) & (pb < ref.shape[1])
    return ok & ~ref[np.clip(pa, 0, ref.shape[0] - 1), np.clip(pb, 0, ref.shape[1] - 1)]


def _emit(terrain: TerrainLike, tb: Tables, levels: dict, W: dict, cells: dict, Lmax: int,
          f: int, viewer: tuple, morph: bool, open_: dict, state: dict):
    """The drawn cells as one conforming mesh: each level-l cell's two union-jack
    triangles, the pair along a level-(l+1) edge replaced by its bintree parent where the
    region across is drawn coarser; heights from the toroidal buffers (the cells no-data
    sent finer read the store), blended in the transition regions."""
    N = tb.N
    keys, lvl, deleg = [], [], []
    n_deleg = 0
    for lv in range(Lmax, -1, -1):
        if not cells[lv]:
            continue
        a, b = cells[lv][0]
        if not len(a):
            continue
        s = 1 << lv
        inside = np.zeros(len(a), bool)
        if lv in W:
            r0, r1, c0, c1 = W[lv]
            inside = (a >= r0) & (a < r1) & (b >= c0) & (b < c1)
        n_deleg += int((~inside).sum())
        pa, pb = a & 1, b & 1
        cr, cc = a | 1, b | 1  # the level-(l+1) cell's centre, the triangles' apex

        mrow = _coarser(tb, W, Lmax, lv, a - 1 + 2 * pa, b)
        mcol = _coarser(tb, W, Lmax, lv, a, b - 1 + 2 * pb)
        er = a + pa  # the row edge's row, the column edge's column
        ec = b + pb
        # row-edge triangles: (er, b), (er, b + 1), C — merged: (er, b), (er, b + 2), C
        keep_r = ~(mrow & (pb == 1))
        rb2 = np.where(mrow, b + 2, b + 1)
        tr = np.stack([np.stack([er, b], 1), np.stack([er, rb2], 1),
                       np.stack([cr, cc], 1)], 1)[keep_r]
        keep_c = ~(mcol & (pa == 1))
        ca2 = np.where(mcol, a + 2, a + 1)
        tc = np.stack([np.stack([a, ec], 1), np.stack([ca2, ec], 1),
                       np.stack([cr, cc], 1)], 1)[keep_c]
        t = np.concatenate([tr, tc]) * s  # full-resolution (i, j)
        keys.append(t[..., 0] * N + t[..., 1])
        lvl.append(np.full(len(t), lv, np.int16))
        deleg.append(np.concatenate([~inside[keep_r], ~inside[keep_c]]))
    if not keys:
        return empty_parts(), 0, n_deleg
    key = np.concatenate(keys)  # (F, 3)
    level = np.concatenate(lvl)
    dl = np.concatenate(deleg)
    vmap = state.get("vmap")
    if vmap is None or len(vmap) != tb.NR * N:
        vmap = state["vmap"] = np.full(tb.NR * N, -1, np.int32)
    verts = np.empty(key.size, np.int64)
    ids, V = number_vertices(key.ravel(), vmap, verts)
    verts = verts[:V]
    faces = ids.reshape(-1, 3)
    i, j = np.divmod(verts, N)
    # each vertex's height: from the buffer of the finest region holding it
    z = np.full(V, np.nan)
    home = np.full(V, -1)
    for lv in sorted(W):
        r0, r1, c0, c1 = W[lv]
        s = 1 << lv
        on = (home < 0) & (i % s == 0) & (j % s == 0)
        r, c = i // s, j // s
        on &= (r >= r0) & (r <= r1) & (c >= c0) & (c <= c1)
        z[on] = buffer_heights(levels[lv], r[on], c[on])
        home[on] = lv
    rest = home < 0
    if rest.any():  # cells no-data sent below the finest region
        got = terrain.gather(i[rest], j[rest], ("height",))["height"]
        z[rest] = terrain.frame.z(got)
    ok = np.isfinite(z)[faces].all(1)
    if morph:
        z = _transition(levels, W, open_, i, j, z, faces[dl], Lmax, f, viewer, tb.refine)
    faces, level = faces[ok], level[ok]
    if not len(faces):
        return empty_parts(), 0, n_deleg
    used = np.zeros(V, bool)
    used[faces] = True
    remap = np.cumsum(used) - 1
    faces = remap[faces]
    ij = np.stack([i[used], j[used]], 1)
    x, y = terrain.frame.xy(ij[:, 0], ij[:, 1])
    faces = orient_ccw(ij, faces)
    mesh = mesh_parts(np.stack([x, y, z[used]], 1), faces, ij,
                    {"skirt": np.zeros(len(faces), np.uint8), "level": level})
    return mesh, V, n_deleg


def _transition(levels: dict, W: dict, open_: dict, i, j, z, fixed_faces, Lmax, f, viewer,
                levels_refine: list) -> np.ndarray:
    """Eq. 4-30 … 4-32: each vertex blended towards the next coarser level's surface by α,
    at its home level (where it is odd), inside that level's region. Choice: α_x is 0 on a
    side of the viewer whose region side lies on the data's edge (no coarser level beyond
    it to blend to; a region shifted there is off-centre). Vertices of cells that no-data
    sent finer (``fixed_faces``) keep their heights (their level is not the ring's)."""
    from geoterrain.core.bintree import vertex_level

    vi, vj = viewer
    out = z.copy()
    fixed = np.zeros(len(z), bool)
    fixed[fixed_faces.ravel()] = True
    home = vertex_level(i, j, Lmax)
    for lv in range(f, Lmax):
        r0, r1, c0, c1 = W[lv]
        s = 1 << lv
        sel = np.flatnonzero((home == lv) & ~fixed)
        if not len(sel):
            continue
        r, c = i[sel] // s, j[sel] // s
        inside = (r > r0) & (r < r1) & (c > c0) & (c < c1)
        inside |= ((r == r0) | (r == r1)) & (c > c0) & (c < c1) & (c % 2 == 1)
        inside |= ((c == c0) | (c == c1)) & (r > r0) & (r < r1) & (r % 2 == 1)
        sel, r, c = sel[inside], r[inside], c[inside]
        # no blend towards a level-(l+1) cell that no-data (or, bounded, an unknown error)
        # sends finer: its surface is not drawn, nor bounded
        ref = levels_refine[lv + 1]
        near = np.zeros(len(sel), bool)
        for dr in (0, 1):
            for dc in (0, 1):
                a = np.where(r % 2 == 1, (r - 1) // 2, r // 2 - dr)
                b = np.where(c % 2 == 1, (c - 1) // 2, c // 2 - dc)
                ok = (a >= 0) & (b >= 0) & (a < ref.shape[0]) & (b < ref.shape[1])
                near |= ok & ref[np.clip(a, 0, ref.shape[0] - 1), np.clip(b, 0, ref.shape[1] - 1)]
        sel, r, c = sel[~near], r[~near], c[~near]
        w = max((r1 - r0 + 1) / 10.0, 2.0)  # w = n/10, at least 2 (§2.9)
        ar = (np.abs(r - vi / s) - ((r1 - r0) / 2.0 - w - 1.0)) / w
        ac = (np.abs(c - vj / s) - ((c1 - c0) / 2.0 - w - 1.0)) / w
        up, down, left, right = open_[lv]
        ar = np.where(np.where(r < vi / s, up, down), ar, 0.0)
        ac = np.where(np.where(c < vj / s, left, right), ac, 0.0)
        alpha = np.clip(np.maximum(ar, ac), 0.0, 1.0)  # eq. 4-30: max(α_x, α_z)
        go = alpha > 0
        if not go.any():
            continue
        sel, r, c, alpha = sel[go], r[go], c[go], alpha[go]
        st = levels[lv]
        ro, co = r % 2 == 1, c % 2 == 1
        # the two level-(l+1) samples that bracket each vertex
        A, B = (r - 1) // 2, (c - 1) // 2
        main = ((A + B) % 2) == 0
        ra = np.where(ro, r - 1, r)
        rb = np.where(ro, r + 1, r)
        ca = np.where(co, np.where(ro & ~main, c + 1, c - 1), c)
        cb = np.where(co, np.where(ro & ~main, c - 1, c + 1), c)
        tgt = 0.5 * (buffer_heights(st, ra, ca) + buffer_heights(st, rb, cb))
        good = np.isfinite(tgt)
        out[sel[good]] += alpha[good] * (tgt[good] - z[sel[good]])  # eq. 4-30
    return out


def _bounded_levels(terrain: TerrainLike, index: TileIndex, tb: Tables, view: View,
                    tau: float, Lmax: int, half0: int, vi: float, vj: float, state: dict):
    """``clipmap_bounded``'s finest level and region sizes from the stored tile errors.

    B_l = E_l + E_{l+1} bounds a level-l cell's error (E_l: the largest stored error of the
    level-l tiles in the frustum; the transition blend and the stitched edge move the
    surface by at most E_{l+1}). Level l + 1 is drawn only beyond λ·B_{l+1}/τ from the eye,
    so level l's region reaches that far (its half-size in cells: that distance over the
    level's narrowest spacing, plus one for the snapping), at least the nominal n × n; the
    finest level is the coarsest l whose region's box is at least λ·B_l/τ from the eye.
    Region sizes only grow within a state (the toroidal buffers keep their size)."""
    k = index.keys
    E = np.zeros(Lmax + 2)
    for lv in range(Lmax + 1):  # (every tile: a vertex out of view moves a triangle in it)
        sel = (k[:, 0] == min(lv, tb.top)) & np.isfinite(index.error)
        E[lv] = float(index.error[sel].max(initial=0.0))
    # a cell no-data sends from level l down to k is drawn within E_k: the largest over
    # the finer levels bounds it too
    E = np.maximum.accumulate(E)
    B = E[: Lmax + 1] + np.r_[E[1: Lmax + 1], E[Lmax]]
    lam = view.lam
    grown = state.setdefault("halves", {})
    if grown.get("tau") != tau or grown.get("lam") != lam:
        grown.clear()
        grown.update(tau=tau, lam=lam)
    halves = {}
    for lv in range(Lmax + 1):
        need = half0
        if lv < Lmax:
            R = lam * B[lv + 1] / tau
            need = max(half0, int(math.ceil(R / ((1 << lv) * tb.dx))) + 2)
        if lv > 0:
            # the finer region stays clear of this level's transition band (w = n/10), so
            # no vertex a finer cell uses is blended towards a level two coarser
            need = max(need, int(math.ceil((halves[lv - 1] / 2 + 2.1) / 0.8)))
        need += need % 2
        halves[lv] = max(need, grown.get(lv, 0))
        grown[lv] = halves[lv]
    f = 0
    eye = view.eye
    for lv in range(Lmax, -1, -1):
        s = 1 << lv
        span_r = halves[lv] * s
        lo = np.array([vi - span_r, vj - span_r])
        hi = np.array([vi + span_r, vj + span_r])
        box = _rect_box(tb, index, 0, (int(max(lo[0], 0)), int(min(hi[0], tb.NR - 1)) + 1,
                                       int(max(lo[1], 0)), int(min(hi[1], tb.N - 1)) + 1))
        if box is None:
            continue
        d = float(view.box_distance(box[0], box[1]))
        if lam * B[lv] <= tau * d:
            f = lv
            break
    del eye
    return f, halves
