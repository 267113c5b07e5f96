"""Simplified chunk meshes for chunked LOD, cached per tile and joined without a loop.

Seed 000 §2.5 (Ulrich's chunked LOD) draws, for each quadtree node, a chunk: a
mesh of the node's footprint simplified to the node's geometric error, built
once and reused every frame. Here a stored tile (L, x, y) is a node, and its
chunk is the longest-edge-bisection mesh (seed 002) of the tile's level-L
samples that keeps every vertex with δ > θ, θ being the chunk's error:

- ``ε_chunk = max(E, δ_sub)``, with E the tile's stored error (of its uniform
  level-L surface against every full-resolution sample of its footprint) and
  δ_sub the largest δ of the finer vertices in the footprint (from the finer
  tiles' stored max δ). Saturated δ bounds a triangle's error by the δ of its
  split vertex (LP eq. 1), so dropping level-L vertices with δ ≤ δ_sub keeps
  the chunk within δ_sub of the samples. On this project's pyramids δ_sub
  equals E up to float rounding, so the chunk's error is the tile's error and
  the quadtree selects the same tiles; the chunk has ~3.5× fewer triangles.
- Where δ_sub is not finite (a footprint with nodata, whose mixed diamonds
  carry δ = inf), θ = 0: the chunk keeps every level-L vertex with δ > 0 and
  its error stays E (a dropped vertex has δ = 0: it lies on the surface).

A chunk is built from its tile's δ and heights only (the local bintree is the
global one restricted to the tile: squares whose row + column index is odd
have the anti-diagonal, so their columns are mirrored first). Its border
chain, in order along each inner edge, gives the skirts.

:func:`assemble_chunks` joins many chunks and their skirts in one compiled pass
over the cached chunks packed end to end: no per-tile Python work per frame.

A chunk also keeps every vertex its parent chunk keeps (:func:`_active`), so its mesh
refines its parent's: each of its triangles lies in one of the parent's. On the stores
measured this adds 0–0.15 % triangles. It lets :func:`morph_heights` morph a chunk to
its parent: placed by :func:`parent_weights`, its vertices draw the parent's surface
exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from geoterrain.lod.kernels import close_upward, extract, tree_roots, tree_row
from geoterrain.lod.mesh import add_elevation, empty_parts, mesh_parts, orient_ccw
from geoterrain.lod.occlusion import hidden_rows
from geoterrain.lod.tiles import TileIndex, TileTree, tile_table

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


@dataclass
class Chunk:
    """One tile's simplified mesh: global sample indices ``ij`` (V, 2), scene
    ``xyz`` (V, 3), ``faces`` (F, 3, counter-clockwise from above), the vertices on
    its inner edges as skirt segments ``skirt_ab`` (S, 2) of local vertex ids,
    and ``level``."""

    ij: np.ndarray
    xyz: np.ndarray
    faces: np.ndarray
    skirt_ab: np.ndarray
    level: int


def chunk_errors(index: TileIndex) -> tuple[np.ndarray, np.ndarray]:
    """ε_chunk and the simplification threshold θ per index row.

    ε_chunk = θ = max(stored tile error, δ of the finer vertices); where the finer δ
    is not finite (nodata) ε_chunk is the stored error and θ = 0.

    Examples
    --------
    >>> from geoterrain.lod.tiles import tile_index
    >>> e, theta = chunk_errors(tile_index(t)); bool((e >= tile_index(t).error).all())
    True
    """
    keys = index.keys
    sub = np.zeros(len(keys))
    top = int(keys[:, 0].max()) if len(keys) else 0
    for L in range(1, top + 1):  # finer level first: δ_sub(L) = max over the children
        kids = np.flatnonzero(keys[:, 0] == L - 1)
        par = index.rows_of(np.stack([np.full(len(kids), L), keys[kids, 1] // 2,
                                      keys[kids, 2] // 2], 1))
        ok = par >= 0
        np.maximum.at(sub, par[ok], np.maximum(index.delta_max[kids[ok]], sub[kids[ok]]))
    fin = np.isfinite(sub)
    err = np.where(fin, np.maximum(index.error, sub), index.error)
    return err, np.where(fin, err, 0.0)


def _cache(terrain: TerrainLike, index: TileIndex) -> dict:
    held = terrain.derived(__name__, dict)
    c = held.get("chunks")
    if c is None or c["index"] is not index:
        T = terrain.grid.tile_samples
        err, theta = chunk_errors(index)
        c = held["chunks"] = {"index": index, "error": err, "theta": theta,
                                "vid": np.full(T * T, -1, np.int32)}
    return c


def chunk_error(terrain: TerrainLike, index: TileIndex) -> np.ndarray:
    """The cached :func:`chunk_errors` of ``terrain``."""
    return _cache(terrain, index)["error"]


def chunk(terrain: TerrainLike, index: TileIndex, row: int) -> Chunk:
    """The cached chunk of index row ``row`` (built on first use)."""
    cache = _cache(terrain, index)
    ch = cache.get(row)
    if ch is None:
        ch = cache[row] = _build(terrain, index, row, cache)
    return ch


def chunk_leaves(terrain: TerrainLike, index: TileIndex, view, tau: float, *,
                 occlusion: bool = True) -> tuple[np.ndarray, dict]:
    """The chunks to draw: the tile quadtree walked top-down, a node refined while
    λ·ε_chunk > τ·D_min (D_min: eye to the node's box; seed 000 §2.5), nodes outside
    the frustum or hidden behind nearer terrain culled, a node inside the frustum
    passing that to its children (``occlusion=False``: no horizon culling).

    A compiled stack walk over a dense (level, y, x) → row table: the work follows
    the nodes visited, not the number of stored tiles.

    Examples
    --------
    >>> from geoterrain.lod.tiles import tile_index
    >>> leaves, st = chunk_leaves(t, tile_index(t), View((0, -800, 400), (0, 0, 0)), 1.0)
    >>> st["tiles_visited"] >= len(leaves) > 0
    True
    """
    cache = _cache(terrain, index)
    tree = cache.get("table")
    if tree is None:
        top = terrain.grid.top_level
        tree = cache["table"] = TileTree(*tile_table(index, top, terrain.grid), top,
                                         index.lo, index.hi)
    rows = np.empty(len(index.keys), np.int64)
    seen = np.empty(len(index.keys), np.int64)
    args = (tree, cache["error"], view.terms(tau))
    hidden = np.zeros(len(index.keys), bool)
    if occlusion:
        # the walk without culling first: the horizon is asked only about the nodes it
        # reaches (a few hundred), not every stored tile; culling only prunes that walk
        n, _, _, _, n_seen = _walk_chunks(*args, hidden, rows, seen)
        hidden = hidden_rows(terrain, view, rows=seen[:n_seen])
    n, visited, culled, n_hidden, _ = _walk_chunks(*args, hidden, rows, seen)
    return rows[:n], {"tiles_visited": int(visited), "tiles_culled": int(culled),
                      "tiles_hidden": int(n_hidden)}


@njit(cache=True, nogil=True)
def _walk_chunks(tree, err, view, hidden, out, seen):
    """:func:`chunk_leaves`'s walk of the quadtree ``tree``
    (:class:`~geoterrain.lod.tiles.TileTree`) for ``view``
    (:class:`~geoterrain.core.view.ViewTerms`): the chunks to draw into ``out``, the
    nodes in the frustum into ``seen``; returns (drawn, visited, culled, hidden, seen)."""
    table, base, top, lo, hi = tree
    eye, planes, lam, tau = view.eye, view.planes, view.lam, view.tau
    rx, ry = tree_roots(base, top)  # every root, the first popped first
    stack = np.empty((4 * (top + 1) + 4 + rx * ry, 4), np.int64)  # (L, x, y, inside)
    sp = 0
    for k in range(rx * ry - 1, -1, -1):
        stack[sp, 0], stack[sp, 1], stack[sp, 2], stack[sp, 3] = top, k % rx, k // rx, 0
        sp += 1
    n, visited, culled, n_hidden, n_seen = 0, 0, 0, 0, 0
    while sp > 0:
        sp -= 1
        L, x, y, inside = stack[sp]
        row = tree_row(table, base, top, L, x, y)
        if row < 0:
            continue
        visited += 1
        if inside == 0:
            inside = 1
            for q in range(planes.shape[0]):
                a, b, c, w = planes[q, 0], planes[q, 1], planes[q, 2], planes[q, 3]
                fx = hi[row, 0] if a >= 0 else lo[row, 0]
                fy = hi[row, 1] if b >= 0 else lo[row, 1]
                fz = hi[row, 2] if c >= 0 else lo[row, 2]
                if a * fx + b * fy + c * fz + w < 0:
                    inside = -1
                    break
                nx = lo[row, 0] if a >= 0 else hi[row, 0]
                ny = lo[row, 1] if b >= 0 else hi[row, 1]
                nz = lo[row, 2] if c >= 0 else hi[row, 2]
                if a * nx + b * ny + c * nz + w < 0:
                    inside = 0
            if inside < 0:
                culled += 1
                continue
        seen[n_seen] = row  # in the frustum: a node the horizon may be asked about
        n_seen += 1
        if hidden[row]:  # behind nearer terrain: neither drawn nor refined
            n_hidden += 1
            continue
        dx = max(lo[row, 0] - eye[0], 0.0, eye[0] - hi[row, 0])
        dy = max(lo[row, 1] - eye[1], 0.0, eye[1] - hi[row, 1])
        dz = max(lo[row, 2] - eye[2], 0.0, eye[2] - hi[row, 2])
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        e = err[row]
        if L > 0 and (lam * e > tau * d or (d == 0.0 and e > 0.0)):
            for k in range(4):
                stack[sp, 0], stack[sp, 1] = L - 1, 2 * x + (k & 1)
                stack[sp, 2], stack[sp, 3] = 2 * y + (k >> 1), inside
                sp += 1
        else:
            out[n] = row
            n += 1
    return n, visited, culled, n_hidden, n_seen


def _active(terrain: TerrainLike, index: TileIndex, row: int, cache: dict) -> np.ndarray:
    """The vertices chunk ``row`` keeps (T × T flags in the tile's own layout, rows and
    columns as stored): δ > θ, the mixed diamonds, every vertex its parent chunk keeps
    (so the chunk refines its parent's mesh: each of its triangles lies in one of the
    parent's, which morphing to the parent needs), closed upward."""
    key = ("active", row)
    got = cache.get(key)
    if got is not None:
        return got
    T = terrain.grid.tile_samples
    L, x, y = (int(v) for v in index.keys[row])
    D = terrain.tile_delta(L, x, y).astype(np.float64)
    active = (D > float(cache["theta"][row])) | ~np.isfinite(D)
    if L < terrain.grid.top_level:
        prow = int(index.rows_of(np.array([[L + 1, x // 2, y // 2]]))[0])
        if prow >= 0:  # the parent's kept vertices, every other sample of this tile
            h = (T - 1) // 2
            pa = _active(terrain, index, prow, cache)
            active[::2, ::2] |= pa[(y % 2) * h:(y % 2) * h + h + 1,
                                   (x % 2) * h:(x % 2) * h + h + 1]
    flip = (x + y) % 2 == 1  # anti-diagonal square: mirror the columns
    a = active[:, ::-1].copy() if flip else active
    close_upward(a)
    active = a[:, ::-1] if flip else a
    cache[key] = active
    return active


def _build(terrain: TerrainLike, index: TileIndex, row: int, cache: dict) -> Chunk:
    g = terrain.grid
    T = g.tile_samples
    L, x, y = (int(v) for v in index.keys[row])
    D = terrain.tile_delta(L, x, y).astype(np.float64)
    heights = terrain.tile(L, x, y).heights
    flip = (x + y) % 2 == 1  # anti-diagonal square: mirror the columns
    Dl = D[:, ::-1] if flip else D
    mixed = ~np.isfinite(Dl)
    active = _active(terrain, index, row, cache)
    active = active[:, ::-1].copy() if flip else active.copy()
    faces, flat = extract(active, mixed, cache["vid"])
    a, b = flat // T, flat % T
    if flip:
        b = T - 1 - b
    z = heights[a, b]
    valid = np.isfinite(z)
    faces = faces[valid[faces].all(1)]
    used = np.zeros(len(flat), bool)
    used[faces] = True
    remap = np.cumsum(used) - 1
    faces, a, b, z = remap[faces], a[used], b[used], z[used]
    step = 1 << L
    ij = np.stack([(y * (T - 1) + a) * step, (x * (T - 1) + b) * step], 1).astype(np.int64)
    X, Y = terrain.frame.xy(ij[:, 0], ij[:, 1])
    xyz = np.stack([X, Y, terrain.frame.z(z)], 1)
    faces = orient_ccw(ij, faces.astype(np.int64))
    # skirt segments: consecutive chunk vertices along each inner edge
    across, down = g.tiles(L)
    segs = []
    for on_edge, along, inner in ((a == 0, b, y > 0), (a == T - 1, b, y < down - 1),
                                  (b == 0, a, x > 0), (b == T - 1, a, x < across - 1)):
        if not inner:
            continue
        v = np.flatnonzero(on_edge)
        v = v[np.argsort(along[v])]
        if len(v) > 1:
            segs.append(np.stack([v[:-1], v[1:]], 1))
    skirt_ab = np.concatenate(segs) if segs else np.zeros((0, 2), np.int64)
    return Chunk(ij, xyz, faces, skirt_ab, L)


class PackedChunks(NamedTuple):
    """The packed chunks as :func:`_gather_chunks` reads them (:meth:`_Packed.arrays`):
    per index row its first vertex ``vo``, face ``fo`` and skirt segment ``so``, their
    counts ``nv``, ``nf``, ``ns`` and its level ``lvl``; every chunk's vertices ``xyz``
    (float64), ``ij`` (float64, as the mesh holds them), faces (int32, the chunk's own
    vertex ids) and skirt segments ``seg`` end to end."""

    vo: np.ndarray
    fo: np.ndarray
    so: np.ndarray
    nv: np.ndarray
    nf: np.ndarray
    ns: np.ndarray
    lvl: np.ndarray
    xyz: np.ndarray
    ij: np.ndarray
    faces: np.ndarray
    seg: np.ndarray


class ChunkMesh(NamedTuple):
    """A frame's chunked mesh as :func:`_gather_chunks` writes it: per vertex ``xyz`` and
    grid ``ij`` (float64), ``elevation`` (float32 metres: scene z × ``inv_scale``, as
    :func:`~geoterrain.lod.mesh.add_elevation` computes it), per face its vertices
    ``faces`` (int32), ``level`` and ``skirt`` flag."""

    xyz: np.ndarray
    ij: np.ndarray
    elevation: np.ndarray
    faces: np.ndarray
    level: np.ndarray
    skirt: np.ndarray


class _Packed:
    """Every built chunk's arrays packed end to end (grown on demand), with per-row
    offsets, so a frame's mesh is gathered by one compiled pass."""

    def __init__(self, n_rows: int):
        self.vo = np.full(n_rows + 1, -1, np.int64)  # per row: first vertex, face, segment
        self.fo = np.full(n_rows + 1, -1, np.int64)
        self.so = np.full(n_rows + 1, -1, np.int64)
        self.nv = np.zeros(n_rows, np.int64)
        self.nf = np.zeros(n_rows, np.int64)
        self.ns = np.zeros(n_rows, np.int64)
        self.lvl = np.zeros(n_rows, np.int16)
        # the dtypes the frame's mesh has: a frame copies them block by block, unconverted
        self.xyz, self.ij = np.zeros((0, 3)), np.zeros((0, 2))
        self.faces, self.seg = np.zeros((0, 3), np.int32), np.zeros((0, 2), np.int64)
        # per vertex: where it lies on the parent chunk (morphing only), laid out as the
        # vertices and filled for the rows ``weighed``
        self.pid, self.pw = np.zeros((0, 3), np.int64), np.zeros((0, 3))
        self.weighed = np.zeros(n_rows, bool)
        self.V = self.F = self.S = 0

    @staticmethod
    def _put(a: np.ndarray, at: int, b: np.ndarray) -> np.ndarray:
        if at + len(b) > len(a):
            a = np.concatenate([a[:at], np.zeros((max(2 * len(a), at + len(b)),) + a.shape[1:],
                                                 a.dtype)])
        a[at:at + len(b)] = b
        return a

    def add(self, row: int, ch: Chunk) -> None:
        self.vo[row], self.fo[row], self.so[row] = self.V, self.F, self.S
        self.nv[row], self.nf[row], self.ns[row] = len(ch.xyz), len(ch.faces), len(ch.skirt_ab)
        self.lvl[row] = ch.level
        self.xyz = self._put(self.xyz, self.V, ch.xyz)
        self.ij = self._put(self.ij, self.V, ch.ij)
        self.faces = self._put(self.faces, self.F, ch.faces)  # local ids: int32 holds them
        self.seg = self._put(self.seg, self.S, ch.skirt_ab)
        self.V += len(ch.xyz)
        self.F += len(ch.faces)
        self.S += len(ch.skirt_ab)

    def arrays(self) -> PackedChunks:
        """The arrays as they are now (:meth:`add` may replace them)."""
        return PackedChunks(self.vo, self.fo, self.so, self.nv, self.nf, self.ns, self.lvl,
                            self.xyz, self.ij, self.faces, self.seg)


def _packed(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray) -> _Packed:
    cache = _cache(terrain, index)
    pk = cache.get("packed")
    if pk is None:
        pk = cache["packed"] = _Packed(len(index.keys))
    for r in leaves[pk.vo[leaves] < 0].tolist():  # chunks not built yet
        pk.add(r, chunk(terrain, index, r))
    return pk


@njit(cache=True, nogil=True)
def _gather_chunks(leaves, depth, packed, mesh, zmorph, inv_scale):
    """Copy the chunks of ``leaves`` (from ``packed``: :class:`PackedChunks`) into the
    output arrays ``mesh`` (:class:`ChunkMesh`): surfaces first (heights from ``zmorph``
    when it is not empty), then two hanging vertices per skirt segment (a, b), ``depth``
    below, and triangles (a, b', b), (a, a', b'); each vertex's elevation is its scene z
    × ``inv_scale``."""
    vo, fo, so, nv, nf, ns, lvl, XYZ, IJ, FACES, SEG = packed
    xyz, ij, elevation, faces, level, skirt = mesh
    V = 0
    F = 0
    morph = zmorph.shape[0] > 0
    for k in range(leaves.shape[0]):
        r = leaves[k]
        o = vo[r]
        for v in range(nv[r]):
            xyz[V + v, 0] = XYZ[o + v, 0]
            xyz[V + v, 1] = XYZ[o + v, 1]
            z = zmorph[V + v] if morph else XYZ[o + v, 2]
            xyz[V + v, 2] = z
            elevation[V + v] = z * inv_scale
            ij[V + v, 0] = IJ[o + v, 0]
            ij[V + v, 1] = IJ[o + v, 1]
        o = fo[r]
        for f in range(nf[r]):
            faces[F + f, 0] = FACES[o + f, 0] + V
            faces[F + f, 1] = FACES[o + f, 1] + V
            faces[F + f, 2] = FACES[o + f, 2] + V
            level[F + f] = lvl[r]
            skirt[F + f] = 0
        V += nv[r]
        F += nf[r]
    base = 0
    for k in range(leaves.shape[0]):  # skirts after every surface vertex
        r = leaves[k]
        m = ns[r] if depth[k] > 0 else 0
        for q in range(m):
            a = base + SEG[so[r] + q, 0]
            b = base + SEG[so[r] + q, 1]
            sa, sb = V, V + 1
            for c in range(2):
                xyz[sa, c] = xyz[a, c]
                xyz[sb, c] = xyz[b, c]
                ij[sa, c] = ij[a, c]
                ij[sb, c] = ij[b, c]
            xyz[sa, 2] = xyz[a, 2] - depth[k]
            xyz[sb, 2] = xyz[b, 2] - depth[k]
            elevation[sa] = xyz[sa, 2] * inv_scale
            elevation[sb] = xyz[sb, 2] * inv_scale
            faces[F, 0], faces[F, 1], faces[F, 2] = a, sb, b
            faces[F + 1, 0], faces[F + 1, 1], faces[F + 1, 2] = a, sa, sb
            level[F] = lvl[r]
            level[F + 1] = lvl[r]
            skirt[F] = 1
            skirt[F + 1] = 1
            V += 2
            F += 2
        base += nv[r]


def assemble_chunks(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray,
                    skirt_depth: np.ndarray | None = None, zmorph: np.ndarray | None = None):
    """One mesh of the chunks of ``leaves`` with skirts ``skirt_depth[k]`` deep (seed 000
    §skirts; none where 0 or None), their vertices at heights ``zmorph`` (the chunks'
    vertices in order, :func:`morph_heights`) if given. Cell data ``skirt`` and ``level``;
    point data ``grid_ij`` and ``elevation`` (active, as
    :func:`~geoterrain.lod.mesh.add_elevation` makes it).

    Examples
    --------
    >>> from geoterrain.lod.tiles import tile_index
    >>> ix = tile_index(t)
    >>> assemble_chunks(t, ix, ix.rows_of(np.array([[t.grid.top_level, 0, 0]]))).n_cells > 0
    True
    """
    return assemble_counted(terrain, index, leaves, skirt_depth, zmorph)[0]


def assemble_counted(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray,
                     skirt_depth: np.ndarray | None = None,
                     zmorph: np.ndarray | None = None) -> tuple[object, int, int]:
    """:func:`assemble_chunks`, and its numbers of surface and skirt triangles (known
    before the mesh is filled: no pass over it to count them)."""
    leaves = np.asarray(leaves, np.int64)
    if not len(leaves):
        return empty_parts(), 0, 0
    depth = np.zeros(len(leaves)) if skirt_depth is None else np.asarray(skirt_depth, float)
    pk = _packed(terrain, index, leaves)
    n_skirt = 2 * int(pk.ns[leaves][depth > 0].sum())
    n_surf = int(pk.nf[leaves].sum())
    V = int(pk.nv[leaves].sum()) + n_skirt
    F = n_surf + n_skirt
    # the layouts the PolyData wraps without a copy: float64 grid_ij, int32 faces
    xyz, ij, elev = np.empty((V, 3)), np.empty((V, 2)), np.empty(V, np.float32)
    faces, level, skirt = np.empty((F, 3), np.int32), np.empty(F, np.int16), np.empty(F, np.uint8)
    zm = np.zeros(0) if zmorph is None else np.asarray(zmorph, np.float64)
    z_scale = float(terrain.frame.z_scale)
    _gather_chunks(leaves, depth, pk.arrays(), ChunkMesh(xyz, ij, elev, faces, level, skirt), zm,
                   1.0 / z_scale)
    mesh = mesh_parts(xyz, faces, ij, {"skirt": skirt, "level": level})
    add_elevation(mesh, z_scale, elev)  # (filled by the gather, with add_elevation's formula)
    return mesh, n_surf, n_skirt


# ---------------------------------------------------------------- morphing to the parent
def parents(terrain: TerrainLike, index: TileIndex) -> np.ndarray:
    """Per index row, the row of its parent tile (−1 for the top one or a missing one)."""
    cache = _cache(terrain, index)
    got = cache.get("parents")
    if got is None:
        k = index.keys
        got = cache["parents"] = index.rows_of(np.stack([k[:, 0] + 1, k[:, 1] // 2,
                                                         k[:, 2] // 2], 1))
    return got


@njit(cache=True, nogil=True)
def _locate(pij, pfaces, cij, T, ids, w):
    """For each vertex ``cij`` (the child's local sample, rows/columns in [0, T)), the
    parent triangle holding it (``pfaces`` into ``pij``, the parent's vertices in the
    same local units) and its barycentric weights; ``ids`` −1 where none does."""
    grid = np.full((T, T), -1, np.int64)
    for v in range(cij.shape[0]):
        grid[cij[v, 0], cij[v, 1]] = v
    for f in range(pfaces.shape[0]):
        a, b, c = pfaces[f, 0], pfaces[f, 1], pfaces[f, 2]
        ai, aj, bi, bj = pij[a, 0], pij[a, 1], pij[b, 0], pij[b, 1]
        ci, cj = pij[c, 0], pij[c, 1]
        det = (bi - ai) * (cj - aj) - (bj - aj) * (ci - ai)
        if det == 0:
            continue
        i0, i1 = max(min(ai, bi, ci), 0), min(max(ai, bi, ci), T - 1)
        j0, j1 = max(min(aj, bj, cj), 0), min(max(aj, bj, cj), T - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                v = grid[i, j]
                if v < 0 or ids[v, 0] >= 0:
                    continue
                wb = ((i - ai) * (cj - aj) - (j - aj) * (ci - ai)) / det
                wc = ((bi - ai) * (j - aj) - (bj - aj) * (i - ai)) / det
                wa = 1.0 - wb - wc
                if wa >= -1e-12 and wb >= -1e-12 and wc >= -1e-12:
                    ids[v, 0], ids[v, 1], ids[v, 2] = a, b, c
                    w[v, 0], w[v, 1], w[v, 2] = wa, wb, wc


def parent_weights(terrain: TerrainLike, index: TileIndex, row: int) -> tuple[np.ndarray,
                   np.ndarray]:
    """Where chunk ``row``'s vertices lie on its parent chunk's mesh: per vertex the
    parent's three vertex numbers (−1 where no parent triangle holds it: nodata, or no
    parent) and barycentric weights. The chunk refines its parent (:func:`_active`), so
    at weights × parent heights the chunk draws its parent's surface exactly."""
    cache = _cache(terrain, index)
    key = ("weights", row)
    got = cache.get(key)
    if got is None:
        ch = chunk(terrain, index, row)
        ids = np.full((len(ch.ij), 3), -1, np.int64)
        w = np.zeros((len(ch.ij), 3))
        prow = int(parents(terrain, index)[row])
        if prow >= 0:
            par = chunk(terrain, index, prow)
            T = terrain.grid.tile_samples
            L, x, y = (int(v) for v in index.keys[row])
            step = 1 << L
            origin = np.array([y * (T - 1), x * (T - 1)], np.int64)
            _locate(par.ij // step - origin, par.faces, ch.ij // step - origin, T, ids, w)
        got = cache[key] = (ids, w)
    return got


@njit(cache=True, nogil=True)
def _morph_rows(order, t, par, vo, nv, XYZ, PID, PW, err, MZ, bound, done):
    """Heights of the chunks ``order`` (coarse first, each one's t) into ``MZ`` (laid out
    as the packed vertices): z = t·z_own + (1 − t)·(the parent's morphed surface at the
    vertex, by its barycentric weights); a chunk whose parent is not morphing (or that
    has none) draws its own heights. ``bound``: the largest chunk error along each row's
    morphing ancestors."""
    for k in range(order.shape[0]):
        r = order[k]
        p = par[r]
        o = vo[r]
        tk = t[k]
        if tk >= 1.0 or p < 0 or not done[p]:
            for v in range(nv[r]):
                MZ[o + v] = XYZ[o + v, 2]
            bound[r] = err[r]
        else:
            po = vo[p]
            for v in range(nv[r]):
                z = XYZ[o + v, 2]
                a = PID[o + v, 0]
                if a >= 0:
                    zp = (PW[o + v, 0] * MZ[po + a] + PW[o + v, 1] * MZ[po + PID[o + v, 1]]
                          + PW[o + v, 2] * MZ[po + PID[o + v, 2]])
                    MZ[o + v] = tk * z + (1.0 - tk) * zp
                else:
                    MZ[o + v] = z
            bound[r] = max(err[r], bound[p])
        done[r] = True


@njit(cache=True, nogil=True)
def _leaf_heights(leaves, vo, nv, MZ, out):
    V = 0
    for k in range(leaves.shape[0]):
        r = leaves[k]
        for v in range(nv[r]):
            out[V + v] = MZ[vo[r] + v]
        V += nv[r]


def morph_heights(terrain: TerrainLike, index: TileIndex, leaves: np.ndarray, eye, lam: float,
                  tau: float, tau_min: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chunked LOD's morph to the parent, cascaded (seed 000 §2.5; the band of seed 002
    eq. 3): a chunk whose parent projects to ρ_P = λ·ε_P / D_min(P) draws
    z = t·z_own + (1 − t)·(its parent's morphed surface), t = (ρ_P − τ_min)/(τ − τ_min)
    clipped to [0, 1]. The walk refines at τ_min, so a chunk appears at t = 0 on its
    parent's surface (no pop) and is whole (t = 1) by the time its parent would break τ.

    Returns the heights of the leaves' vertices in order, each leaf's t, and each
    leaf's error bound while it morphs (the largest chunk error along its morphing
    ancestors), for the skirts. Array work per level of the tree and one compiled pass
    over the vertices: no Python loop per chunk once the chunks are built."""
    cache = _cache(terrain, index)
    err, par = cache["error"], parents(terrain, index)
    lo, hi = index.lo, index.hi
    leaves = np.asarray(leaves, np.int64)

    def t_of(rows):
        p = par[rows]
        q = np.maximum(p, 0)
        d = np.linalg.norm(np.maximum(np.maximum(lo[q] - eye, 0.0), eye - hi[q]), axis=1)
        e = err[q]
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where(e > 0, lam * e / d, 0.0)
        t = np.clip((rho - tau_min) / (tau - tau_min), 0.0, 1.0)
        return np.where(p < 0, 1.0, np.nan_to_num(t, nan=1.0))

    t_leaf = t_of(leaves)
    known = np.zeros(len(index.keys), bool)
    known[leaves] = True
    rows, ts = [leaves], [t_leaf]
    todo = leaves[t_leaf < 1.0]
    while len(todo):  # the ancestors whose surfaces a morphing chunk leans on, a level a pass
        up = np.unique(par[todo])
        up = up[(up >= 0) & ~known[np.maximum(up, 0)]]
        if not len(up):
            break
        known[up] = True
        tu = t_of(up)
        rows.append(up)
        ts.append(tu)
        todo = up[tu < 1.0]
    rows, ts = np.concatenate(rows), np.concatenate(ts)
    order = np.argsort(-index.keys[rows, 0], kind="stable")  # coarse first
    rows, ts = rows[order], ts[order]
    pk = _packed(terrain, index, rows)
    if len(pk.pid) < pk.V:  # room for every packed vertex's weights (read only if weighed)
        grow = max(pk.V, 2 * len(pk.pid)) - len(pk.pid)
        pk.pid = np.concatenate([pk.pid, np.empty((grow, 3), np.int64)])
        pk.pw = np.concatenate([pk.pw, np.empty((grow, 3))])
    for r in rows[(ts < 1.0) & ~pk.weighed[rows]].tolist():  # new morphing chunks only
        ids, w = parent_weights(terrain, index, r)
        o = pk.vo[r]
        pk.pid[o:o + len(ids)], pk.pw[o:o + len(ids)] = ids, w
        pk.weighed[r] = True
    MZ = np.empty(pk.V)
    bound = np.zeros(len(index.keys))
    _morph_rows(rows, ts, par, pk.vo, pk.nv, pk.xyz, pk.pid, pk.pw, err, MZ, bound,
                np.zeros(len(index.keys), np.bool_))
    z = np.empty(int(pk.nv[leaves].sum()))
    _leaf_heights(leaves, pk.vo, pk.nv, MZ, z)
    return z, t_leaf, bound[leaves]
