"""Triangle strips of a refinement's mesh (seed 002 §3.4, L358–364: ``AnexaStrip``).

Seed 002 builds one generalised triangle strip while it refines: each leaf triangle
adds one vertex, and where the winding would flip a vertex is repeated (a degenerate
triangle) so that the strip goes on. :func:`anexa_strip` is that procedure, literally,
on an active set (the seed's golden strip of L490 is its test); :func:`triangle_strips`
gives the same kind of strip from a mesh's triangles in the order the bisection walk
(:func:`geoterrain.lod.kernels.walk_leaves`) emits them, where consecutive leaves
share an edge: a triangle that shares the strip's last edge adds its third vertex, one
that shares the edge before it adds a repeated vertex first (the seed's parity swap),
and one that shares neither starts a new strip (culled triangles, nodata, a new tile).

VTK draws them through ``vtkPolyData.SetStrips`` (:func:`strip_mesh`): whether
that is faster than the triangle lists the project draws is measured by
``benchmarks/bench_strips.py`` (docs/benchmarks.md: no faster on VTK's CPU renderer).

Examples
--------
>>> faces = np.array([[0, 1, 2], [2, 1, 3], [2, 3, 4]])  # consistently wound
>>> cells, stats = triangle_strips(faces)
>>> cells.tolist(), stats["strips"]
([5, 0, 1, 2, 3, 4], 1)
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["anexa_strip", "root_seed_order", "seed_order", "strip_mesh", "strip_triangles",
           "triangle_strips"]


@njit(cache=True, nogil=True)
def _strips_nb(faces, out, starts):
    """Generalised strips of ``faces`` in their order into ``out`` (vertex ids) and
    ``starts`` (each strip's first position); returns (positions used, strips,
    degenerate triangles). A face that shares the strip's last edge goes on it (after a
    repeated vertex where its winding would flip, the seed's swap); another starts a
    new strip."""
    n = 0
    ns = 0
    degenerate = 0
    F = faces.shape[0]
    f = 0
    while f < F:
        starts[ns] = n
        ns += 1
        out[n], out[n + 1], out[n + 2] = faces[f, 0], faces[f, 1], faces[f, 2]
        n += 3
        k = 1  # the strip's next triangle: (v[k], v[k+1], new) reversed when k is odd
        f += 1
        while f < F:
            p, q = out[n - 2], out[n - 1]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            w = _third(a, b, c, p, q)
            if w < 0 or not _drawn_as(a, b, c, p, q, w, k):
                break
            # which edge stays open: (q, w), or (p, w) after the seed's swap (a repeated
            # vertex, a degenerate triangle: the face is drawn with the same winding)
            if f + 1 < F and _third(faces[f + 1, 0], faces[f + 1, 1], faces[f + 1, 2], q,
                                    w) < 0 and _third(faces[f + 1, 0], faces[f + 1, 1],
                                                      faces[f + 1, 2], p, w) >= 0:
                out[n] = p
                n += 1
                k += 1
                degenerate += 1
            out[n] = w
            n += 1
            k += 1
            f += 1
    starts[ns] = n
    return n, ns, degenerate


@njit(cache=True, nogil=True, inline="always")
def _third(a, b, c, p, q):
    # the face's vertex off the edge (p, q), or -1 when it does not hold that edge
    ap, aq = a == p, a == q
    bp, bq = b == p, b == q
    cp, cq = c == p, c == q
    if (ap and bq) or (aq and bp):
        return c
    if (ap and cq) or (aq and cp):
        return b
    if (bp and cq) or (bq and cp):
        return a
    return -1


@njit(cache=True, nogil=True, inline="always")
def _drawn_as(a, b, c, p, q, w, k):
    # whether the strip's triangle k from (p, q) + w, drawn (p, q, w) for even k and
    # (q, p, w) for odd k, winds as the face (a, b, c) (a rotation of it)
    u, v = (p, q) if k % 2 == 0 else (q, p)
    return (u == a and v == b and w == c) or (u == b and v == c and w == a) or \
        (u == c and v == a and w == b)


def triangle_strips(faces: np.ndarray) -> tuple[np.ndarray, dict]:
    """Generalised triangle strips of ``faces`` (F, 3) in their order, with the winding
    of each face kept; returns VTK's cell array (for each strip its length, then its
    vertex ids) and counts (strips, strip vertices, degenerate triangles, triangles).

    Examples
    --------
    >>> cells, st = triangle_strips(np.array([[0, 1, 2], [2, 1, 3], [5, 6, 7]]))
    >>> cells.tolist(), st["strips"], st["triangles"]
    ([4, 0, 1, 2, 3, 3, 5, 6, 7], 2, 3)
    """
    faces = np.ascontiguousarray(faces, np.int64).reshape(-1, 3)
    F = len(faces)
    out = np.empty(3 * F + 4 * F + 3, np.int64)
    starts = np.empty(F + 1, np.int64)
    n, ns, deg = _strips_nb(faces, out, starts)
    lens = np.diff(starts[:ns + 1])
    cells = np.empty(n + ns, np.int64)
    pos = starts[:ns] + np.arange(ns)
    cells[pos] = lens
    mask = np.ones(n + ns, bool)
    mask[pos] = False
    cells[mask] = out[:n]
    return cells, {"strips": int(ns), "strip_vertices": int(n), "degenerate": int(deg),
                   "triangles": int(F)}


def strip_triangles(cells: np.ndarray) -> np.ndarray:
    """The non-degenerate triangles (T, 3) a strip cell array draws, each in the winding
    VTK draws it (the strip's k-th triangle reversed when k is odd).

    Examples
    --------
    >>> strip_triangles(np.array([5, 0, 1, 2, 3, 4])).tolist()
    [[0, 1, 2], [2, 1, 3], [2, 3, 4]]
    """
    out = []
    k = 0
    cells = np.asarray(cells, np.int64)
    while k < len(cells):
        m = int(cells[k])
        s = cells[k + 1:k + 1 + m]
        for q in range(m - 2):
            tri = (s[q], s[q + 1], s[q + 2]) if q % 2 == 0 else (s[q + 1], s[q], s[q + 2])
            if len(set(tri)) == 3:
                out.append(tri)
        k += m + 1
    return np.array(out, np.int64).reshape(-1, 3)


def seed_order(faces: np.ndarray, ij: np.ndarray, n: int) -> np.ndarray:
    """The order in which seed 002's ``RefinaMalha`` meets the leaf triangles ``faces``
    of a bisection of a (2^n + 1)² grid (``ij``: each vertex's grid row and column): the
    four base triangles around the centre S, E, N, W, and in each triangle (apex i,
    hypotenuse midpoint j) the child on its first end a before the other, a = j + rot(j −
    i) with rot clockwise on even levels (:func:`anexa_strip`). Consecutive leaves in
    this order share the edge the strip goes on, so :func:`triangle_strips` of the
    reordered faces makes the seed's long strips.

    Examples
    --------
    >>> ij = np.array([[0, 0], [0, 2], [2, 2], [2, 0], [1, 1]])  # rows southwards
    >>> faces = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    >>> seed_order(faces, ij, 1).tolist()  # S (the bottom row), E, N, W
    [2, 1, 0, 3]
    """
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    F = len(faces)
    side = 1 << n
    # x east, y north, as the seed draws them
    x = np.asarray(ij, np.int64)[:, 1]
    y = side - np.asarray(ij, np.int64)[:, 0]
    cx3 = x[faces].sum(axis=1)  # 3 × the centroid
    cy3 = y[faces].sum(axis=1)
    half = side // 2
    # the base triangle: quadrant S, E, N, W around the centre (apex the centre)
    dx, dy = cx3 - 3 * half, cy3 - 3 * half
    quad = np.where(np.abs(dy) >= np.abs(dx), np.where(dy < 0, 0, 2), np.where(dx > 0, 1, 3))
    mids = np.array([[half, 0], [side, half], [half, side], [0, half]])
    ix = np.full(F, half)
    iy = np.full(F, half)
    jx, jy = mids[quad, 0].copy(), mids[quad, 1].copy()
    key = quad.astype(np.int64) << 61
    area2 = np.abs((x[faces[:, 1]] - x[faces[:, 0]]) * (y[faces[:, 2]] - y[faces[:, 0]])
                   - (x[faces[:, 2]] - x[faces[:, 0]]) * (y[faces[:, 1]] - y[faces[:, 0]]))
    for depth in range(2 * n):
        lev = 2 * n - depth
        vx, vy = jx - ix, jy - iy
        # the current triangle's doubled area: |v|² (a right isosceles one)
        live = 2 * (vx * vx + vy * vy) > area2
        if not live.any():
            break
        rx, ry = (vy, -vx) if lev % 2 == 0 else (-vy, vx)
        ax, ay = jx + rx, jy + ry
        bx, by = jx - rx, jy - ry
        # the a-side child (apex j, hypotenuse a–i) holds the centroid: it lies on a's
        # side of the line from i through j
        s_c = vx * (cy3 - 3 * iy) - vy * (cx3 - 3 * ix)
        s_a = vx * (ay - iy) - vy * (ax - ix)
        e = (s_c * s_a) > 0
        fx = np.where(e, (ax + ix) // 2, (ix + bx) // 2)
        fy = np.where(e, (ay + iy) // 2, (iy + by) // 2)
        key = np.where(live & ~e, key | (np.int64(1) << np.int64(60 - depth)), key)
        ix, iy = np.where(live, jx, ix), np.where(live, jy, iy)
        jx, jy = np.where(live, fx, jx), np.where(live, fy, jy)
    return np.argsort(key, kind="stable")


def root_seed_order(faces: np.ndarray, ij: np.ndarray, grid) -> np.ndarray:
    """The seed's refinement order of ``faces`` (:func:`geoterrain.lod.strips.seed_order`):
    on a root grid, root after root (row by row), each root the seed's square (its own
    bintree, rtin's triangles never crossing a root's edge)."""
    if grid.square:
        return seed_order(faces, ij, grid.n)
    span = 1 << grid.n
    ij = np.asarray(ij, np.int64)
    c3 = ij[faces].sum(axis=1)  # 3 × each face's centroid: inside one root
    across = grid.roots[0]
    root = (c3[:, 0] // (3 * span)) * across + c3[:, 1] // (3 * span)
    parts = []
    for r in np.unique(root):  # a root or two
        sel = np.flatnonzero(root == r)
        origin = np.array([r // across, r % across]) * span
        parts.append(sel[seed_order(faces[sel], ij - origin, grid.n)])
    return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def strip_mesh(mesh, src, grid):
    """``mesh`` (triangles in the order of the selection ``src``'s) drawn as seed 002's
    triangle strips (:mod:`geoterrain.lod.strips`): the faces in the order the seed's
    refinement meets them, then stripped; points, point data and the texture kept (a
    triangle's cell data is not: a strip is one cell)."""
    import pyvista as pv

    faces = np.asarray(mesh.regular_faces)
    order = root_seed_order(np.asarray(src.regular_faces), np.asarray(src.point_data["grid_ij"]),
                         grid)
    cells, st = triangle_strips(faces[order])
    out = pv.PolyData()
    out.SetPoints(mesh.GetPoints())
    out.strips = cells
    tc = mesh.active_texture_coordinates
    if tc is not None:
        out.active_texture_coordinates = tc
    for k, v in st.items():
        out.field_data[f"strip_{k}"] = np.array([v])
    return out


# --------------------------------------------------------------- the seed, literally
def anexa_strip(active, n: int) -> list[tuple[int, int]]:
    """Seed 002's ``RefinaMalha`` with ``AnexaStrip`` (L320–364), as written: one
    generalised strip of the refinement of a (2^k + 1)² grid whose active vertices are
    ``active`` ((x, y) → bool, x east, y north), ``n`` = 2k levels. Returns the strip's
    vertices (the seed's two leading copies of the SW corner included).

    The call (i, j) is the triangle of right-angle apex i and hypotenuse midpoint j; its
    hypotenuse's ends a = j + rot(j − i), b = j − rot(j − i), rot turning clockwise on
    even levels and counter-clockwise on odd ones (the seed's notes, §2.7).

    Examples
    --------
    >>> len(anexa_strip(lambda v: v == (1, 1), 2))  # 3×3, the root only: 4 triangles
    11
    """
    side = 1 << (n // 2)
    sw, se, ne, nw = (0, 0), (side, 0), (side, side), (0, side)
    c = (side // 2, side // 2)
    V = [sw, sw]
    state = {"parity": 0}

    def append(v, p):
        if v != V[-2] and v != V[-1]:
            if p != state["parity"]:
                state["parity"] = p
            else:
                V.append(V[-2])
            V.append(v)

    def refine(i, j, lev):
        if lev > 0 and active(i):
            vx, vy = j[0] - i[0], j[1] - i[1]
            rx, ry = (vy, -vx) if lev % 2 == 0 else (-vy, vx)
            a = (j[0] + rx, j[1] + ry)
            b = (j[0] - rx, j[1] - ry)
            fe = ((a[0] + i[0]) // 2, (a[1] + i[1]) // 2)
            fd = ((i[0] + b[0]) // 2, (i[1] + b[1]) // 2)
            refine(j, fe, lev - 1)
            append(i, lev % 2)
            refine(j, fd, lev - 1)

    mids = [((c[0], 0), se), ((side, c[1]), ne), ((c[0], side), nw), ((0, c[1]), sw)]
    for mid, corner in mids:
        refine(c, mid, n)
        append(corner, 1)
    return V
