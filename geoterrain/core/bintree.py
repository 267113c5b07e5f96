"""Implicit, array-oriented geometry of the longest-edge bisection bintree.

Conventions (docs/conventions.md, seed 002 §2.2): the grid has N = 2**n + 1 samples per
side, indexed ``[i, j]``. A triangle ``(a, b, c)`` has hypotenuse a–b and right-angle
apex c; its split vertex is ``m = (a + b) / 2`` and its children are ``(c, a, m)`` and
``(b, c, m)``. The two base triangles (depth 0) split the square along the diagonal
(0, 0)–(N−1, N−1).

Every non-corner sample is the split vertex of exactly one bintree depth:

* depth ``2k`` (``h = 2**(n-k-1)``): *centres* of the 2h × 2h blocks, ``[h::2h, h::2h]``;
  their diamond is the whole block, split along the union-jack diagonal;
* depth ``2k+1`` (same ``h``): *edge midpoints* of those blocks, ``[h::2h, ::2h]``
  (hypotenuse along the rows) and ``[::2h, h::2h]`` (hypotenuse along the columns);
  their diamond is the rotated square ``|di| + |dj| <= h`` clipped to the domain.

On a rectangular root grid (:class:`geoterrain.core.grid.Grid` with ``roots=True``) the
top is ``rx`` × ``ry`` root squares of side 2**n, each its own pair of base triangles,
split along the union-jack diagonal of its place (root (x, y): the main diagonal when
x + y is even). That is the bintree of a larger square cut to the roots' extent: the
parity and the parent/child rules are local, so the functions below take ``roots`` and
differ only in where the domain ends (the extent, ``ry·2**n`` × ``rx·2**n``) and in the
roots' corners, which, like the square's four, are always present.

Everything here is vectorised over arrays of (i, j) integer pairs; there are no node
objects (the same implicit indexing as Martini). The ``*_nb`` helpers are the same rules
for one vertex, compiled and inlined into the numba kernels (δ, saturation, radii, LOD),
so each rule has one owner.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "base_triangles",
    "root_triangles",
    "child_nb",
    "half_span",
    "main_diagonal_nb",
    "parents_nb",
    "split_vertex",
    "triangle_children",
    "uniform_triangles",
    "vertex_children",
    "vertex_depth",
    "vertex_level",
    "vertex_parents",
]


def half_span(n: int, depth: int) -> int:
    """Half-size ``h`` of the split vertices at bintree ``depth`` of a 2**n + 1 grid.

    Examples
    --------
    >>> half_span(2, 0), half_span(2, 1), half_span(2, 2), half_span(2, 3)
    (2, 2, 1, 1)
    """
    if not 0 <= depth < 2 * n:
        raise ValueError(f"depth must be in [0, {2 * n}), got {depth}")
    return 1 << (n - depth // 2 - 1)


def base_triangles(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The two depth-0 triangles ``(a, b, c)``, each an (2, 2) int64 array of (i, j).

    Both are counter-clockwise seen from above with X east and Y north (rows grow
    southwards), and so are all their descendants (bisection keeps the orientation).

    Examples
    --------
    >>> a, b, c = base_triangles(1)
    >>> a.tolist(), b.tolist(), c.tolist()
    ([[0, 0], [2, 2]], [[2, 2], [0, 0]], [[0, 2], [2, 0]])
    """
    s = 1 << n
    a = np.array([[0, 0], [s, s]], dtype=np.int64)
    b = np.array([[s, s], [0, 0]], dtype=np.int64)
    c = np.array([[0, s], [s, 0]], dtype=np.int64)
    return a, b, c


def root_triangles(n: int, roots: tuple[int, int] = (1, 1)
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The depth-0 triangles of a root grid of ``roots`` = (across, down) squares of side
    2**n: two per root, in raster order of the roots, each pair split along the root's
    union-jack diagonal (the main one where x + y is even); counter-clockwise as
    :func:`base_triangles`, which are the 1 × 1 case.

    Examples
    --------
    >>> a, b, c = root_triangles(1, (2, 1))
    >>> a.tolist(), b.tolist()
    ([[0, 0], [2, 2], [2, 2], [0, 4]], [[2, 2], [0, 0], [0, 4], [2, 2]])
    >>> c.tolist()  # the second root splits along its anti-diagonal
    [[0, 2], [2, 0], [0, 2], [2, 4]]
    """
    s = 1 << n
    rx, ry = roots
    y, x = (v.ravel() for v in np.indices((ry, rx)))
    o = np.stack([y * s, x * s], -1).repeat(2, axis=0)  # each root's (0, 0), twice
    main = ((x + y) % 2 == 0).repeat(2)
    first = np.tile([True, False], rx * ry)
    # main: hypotenuse (0, 0)–(s, s), apexes (0, s) and (s, 0); else (s, 0)–(0, s), apexes
    # (0, 0) and (s, s)
    a = np.where(main[:, None], np.where(first[:, None], [0, 0], [s, s]),
                 np.where(first[:, None], [s, 0], [0, s]))
    c = np.where(main[:, None], np.where(first[:, None], [0, s], [s, 0]),
                 np.where(first[:, None], [0, 0], [s, s]))
    b = np.where(main[:, None], np.where(first[:, None], [s, s], [0, 0]),
                 np.where(first[:, None], [0, s], [s, 0]))
    return (a + o).astype(np.int64), (b + o).astype(np.int64), (c + o).astype(np.int64)


def split_vertex(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Split vertex (hypotenuse midpoint) of triangles with hypotenuse ``a``–``b``.

    Examples
    --------
    >>> split_vertex(np.array([[0, 0]]), np.array([[4, 4]])).tolist()
    [[2, 2]]
    """
    return (np.asarray(a) + np.asarray(b)) // 2


def triangle_children(
    a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Children of K triangles, stacked as 2K triangles: first all ``(c, a, m)``, then
    all ``(b, c, m)``.

    Examples
    --------
    >>> a, b, c = base_triangles(1)
    >>> ca, cb, cc = triangle_children(a[:1], b[:1], c[:1])
    >>> ca.tolist(), cb.tolist(), cc.tolist()
    ([[0, 2], [2, 2]], [[0, 0], [0, 2]], [[1, 1], [1, 1]])
    """
    m = split_vertex(a, b)
    return (np.concatenate([c, b]), np.concatenate([a, c]), np.concatenate([m, m]))


def uniform_triangles(n: int, depth: int, roots: tuple[int, int] = (1, 1)
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All triangles at bintree ``depth`` (the uniform cut), as (K, 2) int64 arrays, of
    the square (or of a root grid's ``roots``).

    Depth ``2(n - L)`` is the union-jack uniform surface of pyramid level L.

    Examples
    --------
    >>> a, b, c = uniform_triangles(1, 2)
    >>> len(a), len(uniform_triangles(1, 2, (2, 1))[0])
    (8, 16)
    """
    a, b, c = root_triangles(n, roots)
    for _ in range(depth):
        a, b, c = triangle_children(a, b, c)
    return a, b, c


def _lowbit(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    v = np.bitwise_or(i, j)
    return v & -v


def vertex_level(i: np.ndarray, j: np.ndarray, top_level: int) -> np.ndarray:
    """The coarsest pyramid level holding sample (i, j): trailing zero bits of ``i | j``,
    capped at ``top_level``; (0, 0) is on every level, so it gets ``top_level``.

    Level L keeps the samples ``[::2**L, ::2**L]`` (docs/conventions.md).

    Examples
    --------
    >>> vertex_level(np.array([0, 4, 2, 1, 8]), np.array([0, 0, 4, 2, 8]), 2).tolist()
    [2, 2, 1, 0, 2]
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    low = np.bitwise_or(i, j)
    low = np.where(low == 0, np.int64(1) << top_level, low & -low)
    return np.minimum(np.log2(low).astype(np.int64), top_level)


@njit(cache=True, inline="always")
def main_diagonal_nb(bi, bj):
    """Union-jack parity: True when block (bi, bj) of a uniform cut (blocks of any side,
    counted from the grid origin) is split along its main diagonal (0, 0)–(1, 1), False
    for the anti-diagonal (0, 1)–(1, 0). Seed 002 §2.3 parity rule; compiled, inlined.

    Examples
    --------
    >>> main_diagonal_nb(0, 0), main_diagonal_nb(0, 1), main_diagonal_nb(3, 1)
    (True, False, True)
    """
    return (bi + bj) % 2 == 0


@njit(cache=True, inline="always")
def parents_nb(i, j, h):
    """The two parents ``(i0, j0, i1, j1)`` of vertex (i, j) of half-span ``h``
    (``h`` = the lowest set bit of ``i | j``); compiled, inlined.

    A block centre (i/h and j/h odd) has the two corners of its 2h block that are off
    the split diagonal (:func:`main_diagonal_nb`); an edge midpoint has the two ends of
    the perpendicular through it: (i, j ± h) if its hypotenuse runs along the rows
    (i/h odd), else (i ± h, j). Same rule as :func:`vertex_parents`, but a parent outside
    the grid (boundary edge midpoints) is returned as is: callers check ``0 <= . < N``.

    Examples
    --------
    >>> parents_nb(2, 2, 2), parents_nb(2, 0, 2), parents_nb(0, 1, 1)
    ((0, 4, 4, 0), (2, -2, 2, 2), (-1, 1, 1, 1))
    """
    if (i // h) % 2 == 1:
        if (j // h) % 2 == 1:  # centre: the corners off the split diagonal
            sg = 1 if main_diagonal_nb((i - h) // (2 * h), (j - h) // (2 * h)) else -1
            return i - h, j + sg * h, i + h, j - sg * h
        return i, j - h, i, j + h  # edge midpoint, hypotenuse along the rows
    return i - h, j, i + h, j  # edge midpoint, hypotenuse along the columns


@njit(cache=True, inline="always")
def child_nb(i, j, h, k):
    """Child ``k`` (0..3) ``(ci, cj)`` of vertex (i, j) of half-span ``h``; compiled, inlined.

    A block centre's children are its 4 edge midpoints (i ∓ h, j), (i, j ∓ h) in the
    order up, down, left, right; an edge midpoint's are the centres of the (up to) four
    h/2 blocks around it, (i ∓ h/2, j ∓ h/2) in raster order. Same order as
    :func:`vertex_children`. Edge midpoints with h = 1 are leaves (no children) and
    children outside the grid are returned as is: callers skip both.

    Examples
    --------
    >>> [child_nb(2, 2, 2, k) for k in range(4)]
    [(0, 2), (4, 2), (2, 0), (2, 4)]
    >>> [child_nb(2, 0, 2, k) for k in range(4)]
    [(1, -1), (1, 1), (3, -1), (3, 1)]
    """
    if (i // h) % 2 == 1 and (j // h) % 2 == 1:  # centre → its 4 edge midpoints
        if k < 2:
            return i + (2 * k - 1) * h, j
        return i, j + (2 * k - 5) * h
    q = h // 2  # edge midpoint → centres of the h/2 blocks around it
    return i + (2 * (k // 2) - 1) * q, j + (2 * (k % 2) - 1) * q


def _extent(n: int, roots: tuple[int, int]) -> tuple[int, int]:
    """(last row, last column) of the domain: the square's 2**n, or the roots' extent."""
    return roots[1] << n, roots[0] << n


def vertex_depth(i: np.ndarray, j: np.ndarray, n: int, roots: tuple[int, int] = (1, 1)
                 ) -> np.ndarray:
    """Bintree depth at which sample (i, j) is a split vertex; −1 for the 4 corners (every
    root's corners on a root grid).

    Examples
    --------
    >>> vertex_depth(np.array([2, 0, 2, 1, 1]), np.array([2, 2, 0, 1, 0]), 2).tolist()
    [0, 1, 1, 2, 3]
    >>> vertex_depth(np.array([0, 2, 2]), np.array([4, 6, 4]), 2, (2, 1)).tolist()
    [-1, 0, 1]
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    s = 1 << n
    g = _lowbit(i, j)
    corner = (g == 0) | (g >= s)  # (0, 0), or a multiple of the root span both ways
    g = np.where(corner, s, g)
    k = n - 1 - np.log2(g).astype(np.int64)  # h = g = 2**(n-k-1)
    centre = ((i // g) % 2 == 1) & ((j // g) % 2 == 1)
    d = np.where(centre, 2 * k, 2 * k + 1)
    return np.where(corner, -1, d)


def vertex_parents(i: np.ndarray, j: np.ndarray, n: int, roots: tuple[int, int] = (1, 1)
                   ) -> np.ndarray:
    """Parents (apexes of the diamond triangles) of non-corner samples.

    Returns an (..., 2, 2) int64 array of two (i, j) pairs; a missing parent (boundary
    edge midpoint) is (−1, −1). On a root grid an edge midpoint of two roots' common
    edge has one parent in each.

    Examples
    --------
    >>> vertex_parents(np.array([2]), np.array([2]), 2).tolist()
    [[[0, 4], [4, 0]]]
    >>> vertex_parents(np.array([2]), np.array([4]), 2, (2, 1)).tolist()
    [[[2, 2], [2, 6]]]
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    si, sj = _extent(n, roots)
    h = _lowbit(i, j)
    centre = ((i // h) % 2 == 1) & ((j // h) % 2 == 1)
    # Centre: union-jack block parity (a + b) % 2 == 0 → split along the main diagonal,
    # parents on the anti-diagonal (seed 002 §2.3 parity rule).
    par = (((i - h) // (2 * h)) + ((j - h) // (2 * h))) % 2
    sgn = np.where(par == 0, 1, -1)
    c_p = np.stack([np.stack([i - h, j + sgn * h], -1), np.stack([i + h, j - sgn * h], -1)], -2)
    # Edge midpoint: hypotenuse along rows if i is the odd multiple of h.
    along_rows = (i // h) % 2 == 1
    di = np.where(along_rows, 0, h)
    dj = np.where(along_rows, h, 0)
    e_p = np.stack([np.stack([i - di, j - dj], -1), np.stack([i + di, j + dj], -1)], -2)
    out = np.where(centre[..., None, None], c_p, e_p)
    bad = (out < 0) | (out > np.array([si, sj]))
    bad = bad.any(-1, keepdims=True)
    return np.where(bad, -1, out)


def vertex_children(i: np.ndarray, j: np.ndarray, n: int, roots: tuple[int, int] = (1, 1)
                    ) -> np.ndarray:
    """Children of non-corner samples: (..., 4, 2) int64, missing ones (−1, −1).

    Examples
    --------
    >>> vertex_children(np.array([2]), np.array([2]), 2).tolist()
    [[[0, 2], [4, 2], [2, 0], [2, 4]]]
    >>> vertex_children(np.array([2]), np.array([4]), 2, (2, 1)).tolist()
    [[[1, 3], [1, 5], [3, 3], [3, 5]]]
    """
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    si, sj = _extent(n, roots)
    h = _lowbit(i, j)
    centre = ((i // h) % 2 == 1) & ((j // h) % 2 == 1)
    q = h // 2
    c_off = np.stack([-h, 0 * h, h, 0 * h, 0 * h, -h, 0 * h, h], -1).reshape(*h.shape, 4, 2)
    e_off = np.stack([-q, -q, -q, q, q, -q, q, q], -1).reshape(*h.shape, 4, 2)
    off = np.where(centre[..., None, None], c_off, e_off)
    out = np.stack([i, j], -1)[..., None, :] + off
    bad = ((out < 0) | (out > np.array([si, sj]))).any(-1, keepdims=True)
    bad = bad | ((~centre) & (h == 1))[..., None, None]  # finest edge midpoints: leaves
    return np.where(bad, -1, out)
