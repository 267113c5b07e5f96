"""ROAM's per-terrain precomputation (seed 000 §2.2): eq. 4-1's wedgie thickness and eq.
4-2's variance of every bintree triangle, bottom up, compiled. The triangles and their
``2·m + side`` indexing are :mod:`geoterrain.lod.roamkernels`'s; :mod:`geoterrain.lod.roam`
builds the tables once per terrain.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoterrain.core.bintree import parents_nb


@njit(cache=True, inline="always")
def diamond_side(mi: int, mj: int, ci: int, cj: int) -> int:
    """Which half of the diamond centred at sample (mi, mj) has its apex at (ci, cj): 0 for
    the first parent of :func:`geoterrain.core.bintree.parents_nb`, 1 for the second.

    Examples
    --------
    >>> from geoterrain.core.bintree import parents_nb
    >>> i0, j0, i1, j1 = parents_nb(2, 2, 2)
    >>> diamond_side(2, 2, i0, j0), diamond_side(2, 2, i1, j1)
    (0, 1)
    """
    h = (mi | mj) & -(mi | mj)
    i0, j0, _, _ = parents_nb(mi, mj, h)
    return 0 if (ci == i0 and cj == j0) else 1


@njit(cache=True, inline="always")
def _bits(z):
    return 1 if np.isfinite(z) else 2


@njit(cache=True, nogil=True)
def wedgies(Z, R, N, n, wedge, var, flags):
    """Eq. 4-1 bottom up: e_T = max(e_T0, e_T1) + |z(m) − (z(a) + z(b))/2| (0 at the
    finest triangles), and McNally's variance (eq. 4-2, kept as the max down the tree
    as his split-only ROAM does); ∞ for a triangle whose samples mix data and no-data.
    ``Z``: R × N samples, flat (a square's N × N, or a root grid's extent, roots of side
    2^n). ``flags`` (2RN, uint8) is scratch: bit 1 some sample valid, bit 2 some not."""
    for d in range(2 * n - 1, -1, -1):
        h = 1 << (n - d // 2 - 1)
        for pass_ in range(2 if d % 2 == 1 else 1):
            if d % 2 == 0:
                i_start, j_start = h, h
            elif pass_ == 0:
                i_start, j_start = h, 0
            else:
                i_start, j_start = 0, h
            for mi in range(i_start, R, 2 * h):
                for mj in range(j_start, N, 2 * h):
                    pi0, pj0, pi1, pj1 = parents_nb(mi, mj, h)
                    m = mi * N + mj
                    zm = Z[m]
                    for s in range(2):
                        ci = pi0 if s == 0 else pi1
                        cj = pj0 if s == 0 else pj1
                        if ci < 0 or cj < 0 or ci >= R or cj >= N:
                            continue
                        # hypotenuse ends: m ± the perpendicular of (c − m)
                        di, dj = ci - mi, cj - mj
                        ai, aj = mi + dj, mj - di
                        bi, bj = mi - dj, mj + di
                        za, zb = Z[ai * N + aj], Z[bi * N + bj]
                        e, v, fl = 0.0, 0.0, 0
                        for k in range(2):  # children (c, a, m) and (b, c, m)
                            xi, xj = (ai, aj) if k == 0 else (bi, bj)
                            si, sj = ci + xi, cj + xj
                            if si % 2 == 0 and sj % 2 == 0:  # a grid point: not finest
                                ui, uj = si // 2, sj // 2
                                q = 2 * (ui * N + uj) + diamond_side(ui, uj, mi, mj)
                                e = max(e, np.float64(wedge[q]))
                                v = max(v, np.float64(var[q]))
                                fl |= flags[q]
                            else:
                                fl |= _bits(Z[ci * N + cj]) | _bits(Z[xi * N + xj])
                        fl |= _bits(zm)
                        q = 2 * m + s
                        flags[q] = fl
                        if fl == 3:
                            wedge[q] = np.inf
                            var[q] = np.inf
                        elif fl == 2:
                            wedge[q] = 0.0
                            var[q] = 0.0
                        else:
                            dz = abs(zm - 0.5 * (za + zb))
                            wedge[q] = e + dz  # eq. 4-1 (float32, rounded up below)
                            if np.float64(wedge[q]) < e + dz:
                                wedge[q] = np.nextafter(wedge[q], np.float32(np.inf))
                            var[q] = max(v, dz)
