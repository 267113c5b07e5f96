"""The height pyramid's tile blobs from a grid read a window at a time (issue 12's
streaming preprocess; the whole-grid twin is :func:`geoterrain.codec.pyramid.encode_pyramid`).

Seed 000 §2.9's residual pyramid is coded closed loop on integer codes, coarse to fine:
a tile's blob needs its own codes, its parent's decoded codes, and for its invalid
samples the fill of :func:`geoterrain.codec.predict.fill_level`, which reads only the parent
level inside the tile. So, with a super-tile level k:

1. a first pass reads each super-tile (the closed footprint of one level-k tile,
   2**(t + k) + 1 samples a side) and keeps its samples every 2**k (the coarse grid,
   levels k and up) and whether any of its samples is valid (which tiles are stored);
2. the coarse grid is decoded and coded as a whole pyramid;
3. a second pass reads each super-tile again, sets its level-k samples to the coarse
   grid's decoded codes, fills and codes its levels below k.

Every tile's blob is the one :func:`~geoterrain.codec.pyramid.encode_pyramid` writes, byte for
byte (``tests/test_banddelta.py``). Memory: the coarse grid (at most ``coarse_max``² codes)
and one super-tile.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoterrain.codec.predict import fill_level
from geoterrain.codec.pyramid import encode_decoded, roots_shape
from geoterrain.codec.pyramid.decoded import _decoded_codes, _predictor_bits, _predictor_crop
from geoterrain.codec.pyramid.encode import _encode_levels, _encode_top
from geoterrain.codec.pyramid.layout import _period, _root_windows
from geoterrain.codec.quantize import Quantizer, valid_codes
from geoterrain.core.grid import footprint_counts
from geoterrain.preprocessing.bands.delta import grid_shape

__all__ = ["band_encode_pyramid", "window_of"]

Window = Callable[[int, int, int, int], tuple[np.ndarray, np.ndarray]]


def window_of(z: np.ndarray, valid: np.ndarray) -> Window:
    """A ``window(i0, i1, j0, j1)`` callback over in-memory arrays (tests, small grids).

    Examples
    --------
    >>> z, v = window_of(np.zeros((5, 5)), np.ones((5, 5), bool))(0, 3, 1, 5)
    >>> z.shape
    (3, 4)
    """
    return lambda i0, i1, j0, j1: (z[i0:i1, j0:j1], valid[i0:i1, j0:j1])


def super_level(N: int | tuple[int, int], t: int, coarse_max: int = 1025,
                roots: tuple[int, int] | None = None) -> int:
    """The super-tile level k: the smallest whose coarse grid (every 2**k samples) is at
    most ``coarse_max`` a side, at most the top level (0: the whole grid at once).
    ``N``: the grid's side, or a root grid's extent (rows, cols) of ``roots`` (across,
    down).

    Examples
    --------
    >>> super_level(16385, 6), super_level(1025, 6), super_level(65537, 6, 2049)
    (4, 0, 5)
    >>> super_level((2049, 4097), 6, roots=(2, 1))
    2
    """
    NR, NC = grid_shape(N)
    n, te = roots_shape((NR, NC), t, roots)
    k = 0
    while k < n - te and ((max(NR, NC) - 1) >> k) + 1 > coarse_max:
        k += 1
    return k


def band_encode_pyramid(window: Window, N: int | tuple[int, int], t: int,
                        quantizer: Quantizer, predictor: str = "auto", coarse_max: int = 1025,
                        sink: Callable[[dict], None] | None = None,
                        decoded: Callable[[int, int, np.ndarray, np.ndarray], None]
                        | None = None, roots: tuple[int, int] | None = None,
                        ) -> dict[tuple[int, int, int], bytes]:
    """``{(L, x, y): blob}`` of every stored tile of an (N, N) grid read through
    ``window(i0, i1, j0, j1)`` → (heights, valid) of rows i0 … i1 − 1 and columns
    j0 … j1 − 1; what :func:`~geoterrain.codec.pyramid.encode_pyramid` returns for the whole grid.

    Parameters are those of :func:`~geoterrain.codec.pyramid.encode_pyramid`; ``coarse_max``
    bounds the coarse grid's side (:func:`super_level`). With ``sink``, the blobs are
    handed to ``sink(part)`` as they are made (the coarse levels, then a super-tile's
    levels at a time; a store writer's ``put_blobs``) and none is kept: the result is
    empty. With ``decoded``, ``decoded(i0, j0, codes, valid)`` gets the decoded codes of each
    stored super-tile (every sample, invalid ones included) whose first sample is
    (i0, j0): the heights the store decodes to, which residual bins make depend on the
    pyramid (:attr:`geoterrain.codec.quantize.Quantizer.bins`). ``roots`` (across, down)
    with ``N`` their extent (rows, cols): a root grid, each root a top tile of its own
    (:func:`~geoterrain.codec.pyramid.encode_pyramid`'s ``roots``; the coarse grid's top
    level fills each root's edges first, as the whole extent's does).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> z = np.round(rng.normal(0, 9, (65, 65)).cumsum(0)); v = rng.random((65, 65)) > 0.1
    >>> q = Quantizer("int")
    >>> a = band_encode_pyramid(window_of(z, v), 65, 3, q, coarse_max=9)
    >>> from geoterrain.codec.pyramid import encode_pyramid
    >>> a == encode_pyramid(z, v, 3, q)
    True
    >>> z2, v2 = z[:33], v[:33]  # 2 × 1 roots of 32 samples
    >>> b = band_encode_pyramid(window_of(z2, v2), (33, 65), 3, q, coarse_max=9, roots=(2, 1))
    >>> b == encode_pyramid(z2, v2, 3, q, roots=(2, 1))
    True
    """
    NR, NC = grid_shape(N)
    if roots is not None and tuple(roots) == (1, 1):
        roots = None
    n, te = roots_shape((NR, NC), t, roots)
    lmax = n - te
    k = super_level((NR, NC), t, coarse_max, roots)
    if k == 0:
        z, v = window(0, NR, 0, NC)
        out, d = encode_decoded(z, v, t, quantizer, predictor=predictor, roots=roots)
        if decoded is not None:
            decoded(0, 0, d, np.asarray(v, bool))
        if sink is None:
            return out
        sink(out)
        return {}
    if predictor not in ("linear", "cubic", "auto"):
        raise ValueError(f"unknown predictor {predictor!r}")
    cubic = predictor == "cubic" and te >= 2
    if predictor == "auto" and te >= 2:  # codec._resolve_predictor on its central crop
        a, crop = _predictor_crop(min(NR, NC), te)
        z, v = window(a, a + crop, a, a + crop)
        cubic = _predictor_bits(valid_codes(z, v, quantizer), v, te)
    W = 1 << (te + k)  # a super-tile's span in samples
    nsr, nsc = (NR - 1) // W, (NC - 1) // W
    step = 1 << k
    zc = np.zeros(((NR - 1) // step + 1, (NC - 1) // step + 1))
    vc = np.zeros(zc.shape, bool)
    stored = np.zeros((nsr, nsc), bool)  # level k's tiles whose footprint holds a valid sample
    for sy in range(nsr):
        for sx in range(nsc):
            z, v = window(sy * W, sy * W + W + 1, sx * W, sx * W + W + 1)
            v = np.asarray(v, bool)
            stored[sy, sx] = v.any()
            T = 1 << te
            zc[sy * T:sy * T + T + 1, sx * T:sx * T + T + 1] = z[::step, ::step]
            vc[sy * T:sy * T + T + 1, sx * T:sx * T + T + 1] = v[::step, ::step]
    z = v = None  # (the last super-tile's window: 1025² samples at 16385², t = 6)
    out: dict[tuple[int, int, int], bytes] = {}
    if not stored.any():
        return out

    def emit(part: dict) -> None:
        if sink is None:
            out.update(part)
        else:
            sink(part)

    # levels k and up: the coarse grid as a whole pyramid, its stored tiles from full res
    counts = [stored.astype(np.int64)]
    for _ in range(lmax - k):  # up to the top level (one tile, or the roots)
        c = counts[-1]
        counts.append(c[0::2, 0::2] + c[0::2, 1::2] + c[1::2, 0::2] + c[1::2, 1::2])
    bins = quantizer.bins
    dc = _decoded_codes(valid_codes(zc, vc, quantizer), vc, te, lmax - k, cubic, bins, roots)
    zc = None  # (the coarse heights: its codes are dc now)
    part: dict[tuple[int, int, int], bytes] = {}
    _encode_levels(part, dc, vc, n - k, te, lmax - k, cubic, None, counts=counts,
                   wide=quantizer.mode == "float", bins=bins)
    coarse = {(L + k, x, y): b for (L, x, y), b in part.items()}
    if roots is None:
        coarse[(lmax, 0, 0)] = _encode_top(dc, vc, te, lmax - k, cubic, bins)
    else:  # encode_decoded's roots: each a top tile, its edges filled first
        s = 1 << (lmax - k)
        vtop = vc[::s, ::s]
        for x, y, dw in _root_windows(dc[::s, ::s], roots, te):
            if counts[-1][y, x]:
                vw = vtop[y << te:((y + 1) << te) + 1, x << te:((x + 1) << te) + 1]
                coarse[(lmax, x, y)] = _encode_top(dw, vw, te, 0, cubic, bins, True)
    emit(coarse)
    # below, only the coarse grid's decoded codes are read: its mask, counts and blobs
    # go before the super-tiles' windows come (each as large as the coarse grid at 16385²)
    vc = vtop = counts = part = coarse = None
    # levels below k, one super-tile at a time, under the coarse grid's decoded codes
    T = 1 << te
    period = _period(te, cubic)
    for sy, sx in zip(*np.nonzero(stored), strict=True):
        z, v = window(sy * W, sy * W + W + 1, sx * W, sx * W + W + 1)
        v = np.ascontiguousarray(v, bool)
        d = valid_codes(z, v, quantizer)
        d[::step, ::step] = dc[sy * T:sy * T + T + 1, sx * T:sx * T + T + 1]
        for lev in range(k - 1, -1, -1):
            fill_level(d, v, 1 << lev, period, bins)
        if decoded is not None:
            decoded(int(sy) * W, int(sx) * W, d, v)
        part = {}
        _encode_levels(part, d, v, te + k, te, k, cubic, None,
                       counts=footprint_counts(v, te), wide=quantizer.mode == "float",
                       bins=bins)
        emit({(L, x + int(sx) * (1 << (k - L)), y + int(sy) * (1 << (k - L))): b
              for (L, x, y), b in part.items()})
    return out
