"""The bintree on a rectangular root grid (issue 45): the roots' base triangles, the
uniform cuts, and the vertex DAG's parents and children, checked against the triangles
themselves (bisection done here by hand, not by the functions under test), and the 1 × 1
root grid against the square's functions."""

from collections import Counter

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoterrain.core.bintree import (
    base_triangles,
    root_triangles,
    uniform_triangles,
    vertex_children,
    vertex_depth,
    vertex_parents,
)

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

ROOTS = st.sampled_from([(1, 1), (2, 1), (1, 2), (3, 2)])


def _bisect(a, b, c):  # the convention's split, written out: (c, a, m), (b, c, m)
    m = (a + b) // 2
    return np.concatenate([c, b]), np.concatenate([a, c]), np.concatenate([m, m])


def _cuts(n, roots):
    """Every depth's uniform cut, from the root triangles, bisected here."""
    a, b, c = root_triangles(n, roots)
    out = [(a, b, c)]
    for _ in range(2 * n - 1):
        a, b, c = _bisect(a, b, c)
        out.append((a, b, c))
    return out


@given(st.integers(1, 4), ROOTS)
def test_root_triangles_tile_the_extent_counter_clockwise_and_conforming(n, roots):
    rx, ry = roots
    S = 1 << n
    for depth, (a, b, c) in enumerate(_cuts(n, roots)):
        x = lambda p: p[:, 1].astype(float)  # noqa: E731 - east
        y = lambda p: -p[:, 0].astype(float)  # noqa: E731 - north (rows grow south)
        area2 = (x(b) - x(a)) * (y(c) - y(a)) - (y(b) - y(a)) * (x(c) - x(a))
        assert (area2 > 0).all()  # counter-clockwise seen from above, every triangle
        assert area2.sum() == 2 * rx * ry * S * S  # they cover the extent (no overlap:
        #                                            conforming below and all inside)
        for p in (a, b, c):
            assert ((p >= 0) & (p <= [ry * S, rx * S])).all()
        # conforming: an edge is in two triangles, or in one on the extent's border
        # (a T-junction would leave a half-edge in one triangle inside the extent)
        edges = Counter()
        for p, q in ((a, b), (b, c), (c, a)):
            for e in zip(map(tuple, p), map(tuple, q), strict=True):
                edges[tuple(sorted(e))] += 1
        for (p, q), k in edges.items():
            on_border = (p[0] == q[0] and p[0] in (0, ry * S)) or \
                (p[1] == q[1] and p[1] in (0, rx * S))
            assert k == 2 or (k == 1 and on_border), (depth, p, q, k)
        if depth % 2 == 0:  # a level's union-jack surface (docs/conventions.md)
            s = 2 * S >> (depth // 2 + 1)
            cell = np.minimum(a, b) // s
            diag_ok = ((a + b) // 2 // s == cell).all()
            assert diag_ok
            odd = ((cell[:, 0] + cell[:, 1]) % 2 == 1)  # the odd-odd corner's cell parity
            main = (b - a)[:, 0] * (b - a)[:, 1] > 0  # hypotenuse along (0, 0)–(1, 1)
            assert (main == ~odd).all()


@given(st.integers(1, 4), ROOTS)
def test_the_vertex_dag_matches_the_triangles(n, roots):
    cuts = _cuts(n, roots)
    parents, depth_of = {}, {}
    for depth, (a, b, c) in enumerate(cuts):
        m = (a + b) // 2
        for mm, cc in zip(map(tuple, m), map(tuple, c), strict=True):
            parents.setdefault(mm, set()).add(cc)
            depth_of[mm] = depth
    rx, ry = roots
    S = 1 << n
    II, JJ = (v.ravel() for v in np.indices((ry * S + 1, rx * S + 1)))
    d = vertex_depth(II, JJ, n, roots)
    for i, j, k in zip(II, JJ, d, strict=True):  # every sample: a split vertex or a corner
        assert depth_of.get((i, j), -1) == k
    keep = d >= 0
    par = vertex_parents(II[keep], JJ[keep], n, roots)
    ch = vertex_children(II[keep], JJ[keep], n, roots)
    children = {}
    for v, ps in zip(zip(II[keep], JJ[keep], strict=True), par, strict=True):
        got = {tuple(p) for p in ps if p[0] >= 0}
        assert got == parents[v], v  # the apexes of its diamond's one or two triangles
        for p in got:
            children.setdefault(p, set()).add(v)
    for v, cs in zip(zip(II[keep], JJ[keep], strict=True), ch, strict=True):
        assert {tuple(c) for c in cs if c[0] >= 0} == children.get(v, set()), v


@given(st.integers(1, 5))
def test_one_root_is_the_square(n):
    for x, y in zip(root_triangles(n), base_triangles(n), strict=True):
        assert (x == y).all()
    a, b, c = uniform_triangles(n, 2 * n - 1)
    ra, rb, rc = uniform_triangles(n, 2 * n - 1, (1, 1))
    assert (a == ra).all() and (b == rb).all() and (c == rc).all()
    II, JJ = np.indices((2**n + 1, 2**n + 1))
    assert (vertex_depth(II, JJ, n) == vertex_depth(II, JJ, n, (1, 1))).all()
