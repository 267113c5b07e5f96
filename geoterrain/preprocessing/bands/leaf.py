"""A geographic grid's level-0 δ as a reader derives it, a tile row at a time (issue 45;
the whole-grid twin is :func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`).

Each level-0 tile's slack and raised δ (:func:`geoterrain.bounds.leafbounds.tile_slack`)
read only the tile's own samples, its saturated δ and its raw metric terms: the per-level
arrays of one tile row hold them. The raised values replace the tiles' new vertices off
their border rings (rows inside the tile row, so no tile row reads another's), and δ is
saturated again (seed 002 §2.4, L46) by the caller.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoterrain.bounds.leafbounds import _inner, tile_slack
from geoterrain.preprocessing.bands.delta import copy_levels, grid_shape, level_lattice
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["band_leaf_slack", "follow_slack"]

Rows = Callable[[int, int], tuple[np.ndarray, np.ndarray]]


def band_leaf_slack(sa: ScratchArrays, N: int | tuple[int, int], t: int, rows: Rows,
                    pre: str = "", terms: str = "", empty_from: int | None = None
                    ) -> dict[tuple[int, int, int], float] | None:
    """:func:`~geoterrain.bounds.leafbounds.geographic_leaf_delta` on per-level arrays: the
    per-tile slack {(0, x, y): s}, level 0's ``{pre}C0``, ``{pre}R0``, ``{pre}K0`` raised
    (not yet saturated again), or None with δ untouched.

    ``rows(i0, i1)`` → (scene heights, valid) of grid rows i0 … i1 − 1; ``terms``: the
    prefix of the raw metric terms ``{terms}dm{x}0``, ``{terms}b{x}0``. ``N``: the grid's
    side, or a root grid's extent (R, C): its level-0 tiles down and across.
    ``empty_from``: a row from which on ``rows`` holds no valid sample (a root grid's
    padding below the raster); the tile rows from there on are not read (each of their
    tiles is one without a valid sample: no slack, δ as it was).

    Examples
    --------
    >>> from geoterrain.preprocessing.bands.delta import band_vertex_errors, rows_of
    >>> z = np.random.default_rng(0).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> d = band_vertex_errors(rows_of(z, v), 9, band=2)
    >>> for k, nb in ((0, 4), (1, 2), (2, 1)):
    ...     for x, sh in zip("CRK", ((nb, nb), (nb, nb + 1), (nb + 1, nb))):
    ...         d.arrays.create(f"dm{x}{k}", sh, np.float64)
    ...         d.arrays.create(f"b{x}{k}", sh, np.uint8)
    >>> sorted(band_leaf_slack(d.arrays, 9, 2, rows_of(z, v)))
    [(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1)]
    """
    R, C = grid_shape(N)
    T1 = 1 << t
    T = T1 + 1
    down, across = (R - 1) >> t, (C - 1) >> t
    copy_levels(sa, 1, pre, "slack")  # raised here, and kept only if every tile can be
    out: dict[tuple[int, int, int], float] = {}
    for y in range(down):
        p0 = y * T1
        if empty_from is not None and p0 >= empty_from:
            break  # tile_slack's True for every tile below: nothing raised, none listed
        # level 0's values only (not the top: n is not read)
        w = level_lattice(sa, pre, 0, 1, p0, p0 + T, C, False, np.float32)
        dm = level_lattice(sa, f"{terms}dm", 0, 1, p0, p0 + T, C, False, np.float64)
        bulge = level_lattice(sa, f"{terms}b", 0, 1, p0, p0 + T, C, False, np.uint8) != 0
        z, v = rows(p0, p0 + T)
        z = np.asarray(z, np.float64)
        v = np.asarray(v, bool)
        raised = w.copy()
        for x in range(across):
            c = np.s_[:, x * T1:x * T1 + T]
            got = tile_slack(w[c], z[c], v[c], dm[c], bulge[c], (p0, x * T1))
            if got is None:
                return None
            if got is True:
                continue
            s, d = got
            inner = _inner(T)  # new vertices off the ring
            raised[c][inner] = d[inner]
            out[(0, x, y)] = s
        for p in range(p0 + 1, p0 + T1):  # the tile row's inner lattice rows
            if p % 2:
                sa.write("slackC0", (p - 1) // 2, raised[p - p0:p - p0 + 1, 1::2])
                sa.write("slackR0", (p - 1) // 2, raised[p - p0:p - p0 + 1, 0::2])
            else:
                sa.write("slackK0", p // 2, raised[p - p0:p - p0 + 1, 1::2])
    copy_levels(sa, 1, "slack", pre)
    return out


def follow_slack(se: ScratchArrays, sa: ScratchArrays, n: int, before: str = "db",
                 budget: int = 16 << 20) -> None:
    """δ_edge (``se``'s per-level arrays) where it equals δ before level 0's slack
    (``sa``'s ``{before}{x}{k}``) takes δ after it (``sa``'s ``{x}{k}``), as
    ``levelblobs.tile_blobs`` does before saturating δ_edge again.

    Examples
    --------
    >>> a, e = ScratchArrays(), ScratchArrays()
    >>> for s, pre, v in ((a, "", 2.0), (a, "db", 1.0), (e, "", 1.0)):
    ...     for x, sh in zip("CRK", ((1, 1), (1, 2), (2, 1))):
    ...         s.create(f"{pre}{x}0", sh, np.float32); s.write(f"{pre}{x}0", 0, np.full(sh, v))
    >>> follow_slack(e, a, 1); float(e.read("C0", 0, 1)[0, 0])
    2.0
    """
    for k in range(n):
        for x in "CRK":
            nr, nc = se.shape(f"{x}{k}")
            step = max(1, budget // (12 * (nc + 1)))
            for a0 in range(0, nr, step):
                d_edge = np.array(se.read(f"{x}{k}", a0, a0 + step))
                same = d_edge == sa.read(f"{before}{x}{k}", a0, a0 + step)
                d_edge[same] = sa.read(f"{x}{k}", a0, a0 + step)[same]
                se.write(f"{x}{k}", a0, d_edge)
