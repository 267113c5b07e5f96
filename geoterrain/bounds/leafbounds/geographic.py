"""A geographic grid's level-0 δ as a reader derives it: the closed forms of
:mod:`geoterrain.bounds.leafbounds.closedforms` raised by one slack per tile, which bounds
the metric term of :mod:`geoterrain.bounds.curvature` at the tile's new vertices, then
saturated again (seed 002 §2.4, L46)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from geoterrain.bounds.delta import saturate
from geoterrain.bounds.leafbounds.closedforms import _NO_RING, _leaf_delta_nb, _table, leaf_delta
from geoterrain.bounds.log8codes import new_mask, ring_new_index
from geoterrain.core.rounding import round_up

__all__ = ["geographic_leaf_delta", "tile_slack"]


def geographic_leaf_delta(delta: np.ndarray, z: np.ndarray, valid: np.ndarray, t: int,
                          dm: np.ndarray, bulge: np.ndarray, span: int | None = None
                          ) -> dict[tuple[int, int, int], float] | None:
    """Level-0 δ of a geographic grid as a reader derives it: raised in place, tile by
    tile, then saturated again; the per-tile slack, or None (``delta`` untouched) where
    the closed forms cannot bound a tile.

    On a geographic grid δ also holds the metric term δ_m of :mod:`geoterrain.bounds.curvature`
    (the error measured in the scene's curvilinear x, y), which needs pyproj's x, y of
    every sample. At level 0 that term is tiny (a sample's offset from its index-space
    place on a 1-sample triangle, about 10⁻⁴ m), so each tile stores one number instead
    of its values: the slack s, the largest amount by which δ_m exceeds the index-space
    closed form (seed 002 §2.3) at one of the tile's new vertices off the border ring. A
    reader adds s to each closed form before it rounds up and saturates
    (:func:`leaf_delta`), which gives at least max(closed form, δ_m) at every vertex, so
    at least the grid's saturated δ: still a bound. The border ring's values are stored
    as they are. Since the raised values may exceed ``delta``, the grid is saturated
    again (§2.4, L46), so every parent still bounds its children.

    ``delta``: (N, N) float32, saturated, or a root grid's (R, C) extent with roots of
    side ``span`` (:mod:`geoterrain.bounds.delta`); ``z``: scene heights; ``valid``: the
    mask; ``t``: the tile exponent; ``dm``, ``bulge``:
    :func:`~geoterrain.bounds.curvature.metric_terms`' raw terms. Returns {(0, x, y): s}
    for the tiles with a valid sample.

    Examples
    --------
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> z = np.random.default_rng(0).normal(size=(9, 9)); v = np.ones((9, 9), bool)
    >>> dm = np.zeros((9, 9)); dm[1, 1] = 5.0  # a metric term, say
    >>> d = saturate(np.maximum(vertex_errors(z, v), dm.astype(np.float32)))
    >>> s = geographic_leaf_delta(d, z, v, 2, dm, np.zeros((9, 9), bool))
    >>> 0 < s[(0, 0, 0)] <= 5.0
    True
    """
    T = (1 << t) + 1
    down, across = ((k - 1) >> t for k in delta.shape)
    raised = []
    out: dict[tuple[int, int, int], float] = {}
    for y in range(down):
        for x in range(across):
            sub = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]
            got = tile_slack(delta[sub], z[sub], valid[sub], dm[sub], bulge[sub],
                             (y << t, x << t))
            if got is None:
                return None
            if got is True:
                continue
            s, d = got
            raised.append((sub, d))
            out[(0, x, y)] = s
    inner = _inner(T)
    for sub, d in raised:
        blk = delta[sub]
        blk[inner] = d[inner]
    saturate(delta, span)
    return out


@lru_cache(maxsize=16)
def _inner(T: int) -> np.ndarray:
    # a level-0 tile's new vertices off its border ring
    rr, rc = ring_new_index(T)
    inner = new_mask(T)
    inner[rr, rc] = False  # the ring is stored as it is
    inner.flags.writeable = False
    return inner


def tile_slack(w: np.ndarray, z: np.ndarray, valid: np.ndarray, dm: np.ndarray,
               bulge: np.ndarray, origin: tuple[int, int]
               ) -> tuple[float, np.ndarray] | bool | None:
    """One level-0 tile of :func:`geographic_leaf_delta`: (its slack s, the δ a reader
    derives with it, whose inner new vertices replace ``w``'s), True for a tile without a
    valid sample, or None where the closed forms cannot bound it.

    ``w``, ``z``, ``valid``, ``dm``, ``bulge``: the tile's (T, T) saturated δ, scene
    heights, mask and raw metric terms; ``origin``: its first sample's (row, column).

    Examples
    --------
    >>> T = 5; z = np.arange(25.0).reshape(5, 5) ** 1.5; v = np.ones((5, 5), bool)
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> w = vertex_errors(z, v); dm = np.full((5, 5), 0.5)
    >>> s, d = tile_slack(w, z, v, dm, np.zeros((5, 5), bool), (0, 0))
    >>> s >= 0 and bool((d[_inner(5)] >= w[_inner(5)]).all())
    True
    """
    T = w.shape[0]
    rr, rc = ring_new_index(T)
    inner = _inner(T)
    v = np.asarray(valid, bool) & np.isfinite(z)
    if not v.any():
        return True
    if bulge[inner].any():
        return None  # a border chord that needs refining (no such case known)
    zt = np.where(v, z, 0.0)
    raw = np.zeros((T, T), np.float32)  # the closed forms, unsaturated
    _leaf_delta_nb(zt, v.view(np.uint8), bool(v.all()), origin[0], origin[1], _NO_RING,
                   _table(0), 0.0, False, False, raw)
    fin = inner & np.isfinite(raw)
    s = max(0.0, float((dm[fin] - raw[fin]).max())) if fin.any() else 0.0
    for _ in range(8):  # float32 rounding may leave a value an ulp short
        s = float(round_up(np.array([s]), np.float32)[0])
        d = leaf_delta(zt, v, origin, rr, rc, w[rr, rc], None, s)
        short = d[inner].astype(np.float64) < w[inner]
        if not short.any():
            return s, d
        if np.isinf(w[inner][short]).any():
            return None  # a +inf the closed forms do not give (no such case known)
        s += float((w[inner][short] - d[inner][short]).max()) + 2.0**-40
    return None
