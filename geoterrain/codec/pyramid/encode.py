"""The height pyramid's encoder (:mod:`geoterrain.codec.pyramid`): every stored tile's
blob of a whole grid (:func:`encode_pyramid`, :func:`encode_decoded`: each level's tiles
coded in one compiled call on every core; the wide blobs of lossless float stores), and
one tile at a time for an edit (:func:`encode_root`, :func:`encode_child`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import prange

from geoterrain.codec import entropy
from geoterrain.codec.entropy import (
    MASK_ALL_INVALID,
    MASK_ALL_VALID,
    MASK_STORED,
    _level_zigzag,
)
from geoterrain.codec.predict import fill_level
from geoterrain.codec.pyramid.decoded import _decoded_codes, _resolve_predictor, _top_fill
from geoterrain.codec.pyramid.layout import (
    _WIDE_LEVEL,
    _header,
    _period,
    _root_windows,
    roots_shape,
    top_bins,
)
from geoterrain.codec.quantize import Quantizer, valid_codes
from geoterrain.core.grid import footprint_counts, level_tiles
from geoterrain.core.threads import cores_for, parallel_kernel
from geoterrain.core.zstdsafe import compress_many


def encode_pyramid(
    z: np.ndarray,
    valid: np.ndarray,
    t: int,
    quantizer: Quantizer,
    progress: Callable[[int, int], None] | None = None,
    predictor: str = "auto",
    roots: tuple[int, int] | None = None,
    counts: list[np.ndarray] | None = None,
) -> dict[tuple[int, int, int], bytes]:
    """Encode every stored tile of the pyramid.

    Parameters
    ----------
    z : (N, N) float64
        Heights (source units); values at invalid samples are ignored.
    valid : (N, N) bool
    t : int
        Tile exponent (T = 2**t + 1; shrinks to n when n < t).
    quantizer : Quantizer
    progress : callable, optional
        ``progress(done_levels, total_levels)`` after each level.
    predictor : {"auto", "linear", "cubic"}
        U(.) of the residuals (:mod:`geoterrain.codec.predict`): linear floor-means, or 4-point
        interpolatory weights (better on rough, high-entropy data); ``"auto"`` picks the
        one with the smaller estimated residual entropy. Recorded in every blob.
    roots : (int, int), optional
        (across, down) root tiles of a root grid (:class:`geoterrain.core.grid.Grid`):
        ``z`` is then their extent (:func:`roots_shape`), each root a top tile
        ``(Lmax, x, y)`` of its own; None or (1, 1): one square.
    counts : list of arrays, optional
        :func:`geoterrain.core.grid.footprint_counts` of ``valid`` at the tile size, when
        the caller has them (else computed here).

    Returns
    -------
    dict
        ``{(L, x, y): blob}`` for every tile whose footprint holds a valid sample.

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> sorted(encode_pyramid(z, v, 1, Quantizer("int")))
    [(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 0)]
    """
    return encode_decoded(z, valid, t, quantizer, progress, predictor, roots, counts)[0]


def encode_decoded(
    z: np.ndarray,
    valid: np.ndarray,
    t: int,
    quantizer: Quantizer,
    progress: Callable[[int, int], None] | None = None,
    predictor: str = "auto",
    roots: tuple[int, int] | None = None,
    counts: list[np.ndarray] | None = None,
) -> tuple[dict[tuple[int, int, int], bytes], np.ndarray]:
    """:func:`encode_pyramid`'s blobs and the (N, N) codes decoding them gives
    (:func:`decoded_codes`), which the encoder computes on its way (``counts`` as
    :func:`encode_pyramid`'s).

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> blobs, d = encode_decoded(z, v, 1, Quantizer("int"))
    >>> blobs == encode_pyramid(z, v, 1, Quantizer("int")), int(d[2, 3])
    (True, 13)
    """
    valid = np.asarray(valid, dtype=bool)
    z = np.asarray(z, dtype=np.float64)
    square = roots is None or tuple(roots) == (1, 1)
    if z.shape != valid.shape or z.ndim != 2 or (square and z.shape[0] != z.shape[1]):
        raise ValueError("z and valid must be the same square (N, N) shape, or the "
                         "extent of their roots")
    n, te = roots_shape(z.shape, t, None if square else roots)
    lmax = n - te
    out: dict[tuple[int, int, int], bytes] = {}
    d = valid_codes(z, valid, quantizer)  # heights_to_codes(where(valid, z, 0))
    cubic = _resolve_predictor(predictor, d, valid, te, lmax)
    d = _decoded_codes(d, valid, te, lmax, cubic, quantizer.bins, None if square else roots)
    if not valid.any():
        return out, d
    if square:
        out[(lmax, 0, 0)] = _encode_top(d, valid, te, lmax, cubic, quantizer.bins)
    else:
        if counts is None:
            counts = footprint_counts(valid, te, lmax)
        s = 1 << lmax
        for x, y, dw in _root_windows(d[::s, ::s], roots, te):
            if counts[lmax][y, x]:
                vw = valid[::s, ::s][y << te:((y + 1) << te) + 1, x << te:((x + 1) << te) + 1]
                out[(lmax, x, y)] = _encode_top(dw, vw, te, 0, cubic, quantizer.bins, True)
    with cores_for(d.size):  # small grids on one thread (geoterrain/core/threads.py)
        _encode_levels(out, d, valid, n, te, lmax, cubic, progress, counts,
                       wide=quantizer.mode == "float", bins=quantizer.bins)
    return out, d


def _mask_kind(nvalid, size: int):
    # a tile's mask kind from its count of valid samples (also element-wise on arrays)
    return np.where(nvalid == size, MASK_ALL_VALID,
                    np.where(nvalid == 0, MASK_ALL_INVALID, MASK_STORED))


def _encode_top(d, valid, te, lmax, cubic, bins=1, edges=False) -> bytes:
    # the top tile, coarse to fine inside itself (entropy.encode_top); ``edges``: a root
    # of several (its level-Lmax window as d, lmax 0)
    s = 1 << lmax
    top, vt = np.ascontiguousarray(d[::s, ::s]), np.ascontiguousarray(valid[::s, ::s])
    kind = int(_mask_kind(int(vt.sum()), vt.size))
    return _header(True, kind, te, cubic, edges=edges) + entropy.encode_top(
        top, vt, te, cubic, kind, top_bins(bins), True, edges and kind != MASK_ALL_VALID)


def _encode_levels(out, d, valid, n, te, lmax, cubic, progress, counts=None,
                   wide=False, bins=1) -> None:
    """Blobs of every non-top stored tile into ``out`` (each level's tiles coded in one
    compiled call on every core; ``wide``: the wide blobs). ``counts``: which tiles are
    stored (> 0), per level (default :func:`footprint_counts` of ``valid``)."""
    tt = (1 << te) + 1
    if progress is not None:
        progress(1, lmax + 1)
    if counts is None:
        counts = footprint_counts(valid, te)
    h = 1 << (te - 1)
    cap = 64 + tt * tt  # a level's rows: 8 bits a sample, then twice the last level's longest
    all_valid = bool(valid.all())
    for lev in range(lmax - 1, -1, -1):
        s = 1 << lev
        ys, xs = np.nonzero(counts[lev])
        if ys.size:
            nvalid = np.full(ys.size, tt * tt) if all_valid else \
                level_tiles(valid, te, lev)[ys, xs].sum(axis=(1, 2))
            kinds = _mask_kind(nvalid, tt * tt)
            if wide:
                out.update(_wide_blobs(lev, d, valid, s, h, te, ys, xs, kinds, cubic))
                continue
            streams = _encode_tiles(d, valid, s, h, cubic, ys, xs, kinds, cap, bins)
            cap = 64 + 2 * max(map(len, streams))
            heads = [_header(False, int(k), te, cubic) for k in range(3)]
            out.update(((lev, int(x), int(y)), heads[k] + b)
                       for x, y, k, b in zip(xs.tolist(), ys.tolist(), kinds.tolist(), streams,
                                             strict=True))
        if progress is not None:
            progress(lmax - lev + 1, lmax + 1)


_UINTS = {1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}


def _wide_blobs(lev, d, valid, s, h, te, ys, xs, kinds, cubic) -> dict:
    """The wide blobs of the listed tiles (the format's ``wide`` row): residuals, widths
    and byte planes in one compiled call, zstd of the level in one call on every core."""
    tt = 2 * h + 1
    n = 3 * h * h + 2 * h
    # every payload in one buffer, a slot a tile: [packbits(mask) when stored] + its w
    # byte planes; a slot holds the widest (8 bytes a residual), and only what is
    # written of it is ever touched (memory pages: an untouched one costs nothing)
    mb = (tt * tt + 7) // 8
    slot = mb + 8 * n
    buf = np.empty(ys.size * slot, np.uint8)
    ws = np.empty(ys.size, np.int64)
    _level_planes(d, s, h, _period(te, cubic), ys.astype(np.int64), xs.astype(np.int64),
                  slot, mb, buf, ws)
    stored = kinds == MASK_STORED
    base = np.arange(ys.size, dtype=np.int64) * slot + mb
    first = base - np.where(stored, mb, 0)
    last = base + ws * n
    for q in np.flatnonzero(stored).tolist():
        i0, j0 = int(ys[q]) * 2 * h * s, int(xs[q]) * 2 * h * s
        buf[first[q]:base[q]] = np.packbits(valid[i0:i0 + (tt - 1) * s + 1:s,
                                                  j0:j0 + (tt - 1) * s + 1:s])
    heads, cache = [], {}
    for k, w in zip(kinds.tolist(), ws.tolist(), strict=True):
        hd = cache.get((k, w))
        if hd is None:
            hd = cache[(k, w)] = _header(False, int(k), te, cubic, int(w))
        heads.append(hd)
    view = memoryview(buf)
    frames = compress_many([view[a:b] for a, b in zip(first.tolist(), last.tolist(),
                                                      strict=True)], _WIDE_LEVEL)
    return {(lev, int(x), int(y)): hd + f
            for x, y, hd, f in zip(xs.tolist(), ys.tolist(), heads, frames, strict=True)}


@parallel_kernel(cache=True, nogil=True)
def _level_planes(d, s, h, P, ys, xs, slot, mb, out, ws):
    """Tile q's zigzag residuals (:func:`geoterrain.codec.entropy.level_zigzag`'s, in a
    buffer of its own), their byte width ``ws[q]`` (the fewest of 0, 1, 2, 4, 8 bytes
    holding the largest) and their ``ws[q]`` little-endian byte planes (all byte 0s,
    then all byte 1s, ...) at ``out[q·slot + mb:]``; tiles on every core. One pass over
    the residuals, none held for the whole level (the wide blobs' bodies)."""
    n = 3 * h * h + 2 * h
    for q in prange(ys.size):
        zz = np.empty(n, np.uint64)
        _level_zigzag(d, s, h, P, ys[q] * 2 * h, xs[q] * 2 * h, zz)
        zm = np.uint64(0)
        for u in zz:
            zm = max(zm, u)
        w = 0
        if zm >= np.uint64(1) << np.uint64(32):
            w = 8
        elif zm >= np.uint64(1) << np.uint64(16):
            w = 4
        elif zm >= np.uint64(1) << np.uint64(8):
            w = 2
        elif zm > np.uint64(0):
            w = 1
        ws[q] = w
        a = q * slot + mb
        for b in range(w):
            sh = np.uint64(8 * b)
            o = a + b * n
            for k in range(n):
                out[o + k] = np.uint8((zz[k] >> sh) & np.uint64(0xFF))


def _encode_tiles(d, valid, s, h, cubic, ys, xs, kinds, cap, bins) -> list[bytes]:
    """The streams of the listed tiles: a row of ``cap`` bytes of a shared buffer each,
    coded on every core; a tile whose stream outgrows its row is coded again in a row 8
    times longer."""
    out: list[bytes] = [b""] * ys.size
    todo = np.arange(ys.size)
    while todo.size:
        buf = np.zeros((todo.size, cap), np.uint8)
        lens = np.empty(todo.size, np.int64)
        entropy.encode_level(d, valid, s, h, cubic, ys[todo].astype(np.int64),
                             xs[todo].astype(np.int64), kinds[todo].astype(np.int64), buf, lens,
                             bins)
        for row, q in enumerate(todo.tolist()):
            if lens[row] >= 0:
                out[q] = buf[row, :lens[row]].tobytes()
        todo = todo[lens < 0]
        cap *= 8
    return out


# ------------------------------------------------------------------- one tile at a time


def encode_root(codes: np.ndarray, valid: np.ndarray, te: int, cubic: bool, bins: int = 1,
                edges: bool = False, near: np.ndarray | None = None) -> bytes:
    """The blob of one top tile (a root), as :func:`encode_decoded` codes it, from its
    (T, T) ``codes`` as :func:`~geoterrain.codec.quantize.valid_codes` gives them (an
    invalid sample at the code of height 0) and ``valid``: the invalid samples filled
    as its decoding fills them, then the tile coded coarse to fine inside itself.
    ``edges``: a root of a grid of several, whose invalid corners come from ``near``,
    the fill (:func:`~geoterrain.codec.predict.fill_outward`) of the whole top level of
    every root, cut to this root. For an edit that codes a root again.

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> blob = encode_root(valid_codes(z, v, Quantizer("int")), v, 2, False)
    >>> blob == encode_pyramid(z, v, 2, Quantizer("int"), predictor="linear")[(0, 0, 0)]
    True
    """
    valid = np.ascontiguousarray(valid, dtype=bool)
    d = np.array(codes, np.int64)
    _top_fill(d, valid, te, cubic, top_bins(bins), edges=edges, near=near)
    return _encode_top(d, valid, te, 0, cubic, bins, edges)


def encode_child(codes: np.ndarray, valid: np.ndarray, parent: np.ndarray,
                 parity: tuple[int, int], te: int, cubic: bool, bins: int = 1,
                 wide: bool = False) -> bytes:
    """The blob of one non-top tile, as :func:`encode_decoded` codes it, from its (T, T)
    ``codes`` and ``valid`` and its parent tile's decoded codes (``parity``: (x % 2,
    y % 2), the tile's quadrant of the parent); ``wide``: a lossless float store's wide
    blob. For an edit that codes a tile again.

    Examples
    --------
    >>> z = np.arange(81.0).reshape(9, 9); v = np.ones((9, 9), bool)
    >>> blobs, d = encode_decoded(z, v, 2, Quantizer("int"), predictor="linear")
    >>> encode_child(d[4:, :5], v[4:, :5], d[::2, ::2], (0, 1), 2, False) == blobs[(0, 0, 1)]
    True
    """
    codes = np.ascontiguousarray(codes, np.int64)
    ok = np.ascontiguousarray(valid, dtype=bool)
    T = codes.shape[0]
    kind = int(_mask_kind(int(ok.sum()), T * T))
    if not wide:
        return _header(False, kind, te, cubic) + entropy.encode_tile(
            codes, ok, np.ascontiguousarray(parent, np.int64), parity, cubic, kind, bins)
    # the residuals on the parent tile's lattice (the child's quadrant filled in, its
    # invalid samples given their predictions first, as the whole grid has them)
    h = (T - 1) // 2
    px, py = parity
    d = np.zeros((2 * T - 1, 2 * T - 1), np.int64)
    vv = np.ones((2 * T - 1, 2 * T - 1), bool)
    d[py * (T - 1):py * (T - 1) + T, px * (T - 1):px * (T - 1) + T] = codes
    vv[py * (T - 1):py * (T - 1) + T, px * (T - 1):px * (T - 1) + T] = ok
    d[::2, ::2] = parent
    fill_level(d, vv, 1, _period(te, cubic), 1)
    zz = np.empty((1, 3 * h * h + 2 * h), np.uint64)
    zmax = np.empty(1, np.uint64)
    entropy.level_zigzag(d, 1, h, _period(te, cubic), np.array([py], np.int64),
                         np.array([px], np.int64), zz, zmax)
    zm = int(zmax[0]) if zz.size else 0
    w = 0 if zm == 0 else next(b for b in (1, 2, 4, 8) if zm < 1 << (8 * b))
    mask = np.packbits(ok).tobytes() if kind == MASK_STORED else b""
    body = np.ascontiguousarray(zz[0].astype(np.dtype(_UINTS[w]).newbyteorder("<"))
                                .view(np.uint8).reshape(-1, w).T).tobytes() if w else b""
    return _header(False, kind, te, cubic, w) + compress_many([mask + body], _WIDE_LEVEL)[0]
