"""Residual compression of the height pyramid (geometry-clipmap style).

Seed 000, section 2.9 (Losasso & Hoppe): finer data come from coarser data plus a
residual, ``R_l = T_l - U(T_{l-1})``, and the runtime rebuilds ``T~_l = U(T~_{l-1}) + R~_l``.
Here the pyramid is the vertex-aligned one of ``docs/conventions.md`` (level L keeps
``[::2**L, ::2**L]``, tiles of ``T = 2**t + 1`` samples sharing borders) and the coding
is *closed loop* on integer codes, so errors never accumulate down the pyramid:

1. every height becomes an int64 code ``q`` (:class:`geoterrain.codec.quantize.Quantizer`);
2. the top tile ``(Lmax, 0, 0)`` is coded coarse to fine inside itself: its 4 corners,
   then each level of its own grid from the next coarser one, as below;
3. every finer tile stores only the samples that are new at its level (those not on the
   parent level's grid), as residuals ``q - pred``; ``pred`` is U(.) of
   :mod:`geoterrain.codec.predict` (linear floor-means or 4-point cubic) on the PARENT tile's
   decoded codes. Samples of the parent level are copied. With residual bins W > 1 (a
   lossy quantizer, :attr:`~geoterrain.codec.quantize.Quantizer.bins`) the residual is
   rounded to a multiple of W (SZ3's linear quantisation): the decoded code is
   ``pred + W · round((q - pred) / W)`` and the multiple is what is coded; the top
   tile's own grids use :func:`top_bins`. The decoded codes then depend on the pyramid
   (:func:`decoded_codes` computes them coarse to fine, as the encoder does).

Invalid samples are not coded: their decoded code is their prediction, so they cost
nothing. In the top tile, whose invalid samples every finer tile is predicted from,
they are filled outward from the valid ones after each level of its own grid
(:func:`geoterrain.codec.predict.fill_outward`: linear extrapolations next to the data, then
the mean of the nearer ring; an invalid corner, which is coded, holds that fill of the
source's codes): a DEM padded to 2**n + 1 samples otherwise paid for
its padding's interpolated predictions in every tile along the edge of its data (St
Helens at ε = 2 m: 1 149 bytes, 651 of them below the top tile, against 624 and 269
with the fill).
The residuals are coded by :mod:`geoterrain.codec.entropy` (an adaptive binary range coder
with contexts), afresh in every tile.

Blob format (version 3), one blob per stored tile::

    byte 0   version (3; version 2, of store schemas 5 to 7, predicted a cell centre
             along its column only, and is refused)
    byte 1   flags: bit 0 = top tile; bits 1-2 = mask kind (0 all valid, 1 all
             invalid, 2 mask stored); bit 3 = cubic predictor; bit 4 = wide; bit 5
             = filled (a top tile with a stored mask: its invalid samples filled
             outward after each of its levels; always set now, absent in older
             stores, whose invalid samples keep their predictions); bit 6 = edges
             (with bit 5, a root of a grid of several root tiles: each level's edges
             filled along themselves first, so two roots decode the same codes on the
             edge they share: :func:`geoterrain.codec.predict.fill_edges_first`)
    byte 2   t (tile size T = 2**t + 1)
    rest     the range-coded stream of :mod:`geoterrain.codec.entropy`: the (T, T) valid mask
             when stored, then the zigzag residuals: for the top tile the 4 corners
             (deltas, raster order) and then its levels of stride 2**(t-1) … 1; for the
             other tiles, with h = 2**(t-1), class A (even rows, odd columns, (h+1, h)),
             class B (odd rows, even columns, (h, h+1)), class C (odd rows, odd columns,
             (h, h)), each in raster order, invalid samples skipped.
    wide     (a non-top tile of a lossless float store, whose residuals are float bit
             patterns of 10-30 bits: the range coder's ~7 % saving there costs 3 times
             zstd's time, docs/lab/height-codec.md) byte 3 = w, the residuals' byte width
             (0, 1, 2, 4, 8); then one zstd frame of [np.packbits(mask) when stored] +
             the 3h² + 2h zigzag residuals (0 at invalid samples) as w-byte
             little-endian values, byte-shuffled (all byte 0s, then all byte 1s, ...).

Arithmetic is int64 modulo 2**64.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit, prange

from geoterrain.codec import entropy
from geoterrain.codec.entropy import (
    MASK_ALL_INVALID,
    MASK_ALL_VALID,
    MASK_STORED,
    _level_zigzag,
)
from geoterrain.codec.predict import (
    cubic_child,
    fill_edges_first,
    fill_level,
    fill_outward,
    linear_child,
    predict,
)
from geoterrain.codec.quantize import Quantizer, codes_to_heights, roundtrip, valid_codes
from geoterrain.core.grid import footprint_counts, level_tiles
from geoterrain.core.threads import cores_for, parallel_kernel
from geoterrain.core.zstdsafe import compress_many, decompress

__all__ = [
    "BLOB_VERSION",
    "blob_predictor",
    "encode_child",
    "encode_pyramid",
    "encode_root",
    "decode_tile",
    "decode_tile_valid",
    "tile_valid",
    "decoded_codes",
    "decoded_heights",
    "encode_decoded",
    "pyramid_shape",
    "roots_shape",
]

BLOB_VERSION = 3  # 2: cell centres predicted along their column only (schemas 5-7)
_HEADER = 3


def _top_fill(top: np.ndarray, valid: np.ndarray, te: int, cubic: bool, W: int = 1,
              edges: bool = False, near: np.ndarray | None = None) -> None:
    """:func:`_fill_top` on contiguous copies of ``top`` and ``valid`` (often strided
    views of the whole grid), the result written back to ``top``: the compiled fill then
    runs on the whole grid's layout, one compilation for both."""
    work = np.array(top)
    _fill_top(work, np.ascontiguousarray(valid), te, cubic, W, edges, near)
    top[...] = work


def _fill_top(top: np.ndarray, valid: np.ndarray, te: int, cubic: bool, W: int = 1,
              edges: bool = False, near: np.ndarray | None = None) -> None:
    """In place on the top tile's codes, what its decoding gives (:func:`entropy._top`):
    an invalid corner holds the fill of the source's codes (the encoder is free to
    choose it: the corners are coded); then level by level of its own grid, a valid
    sample its code in residual bins ``W`` (:func:`geoterrain.codec.predict.fill_level`) and,
    once the level is decoded, every invalid sample its fill from the valid ones and
    the corners (:func:`geoterrain.codec.predict.fill_outward`), which the next level and
    the finer tiles are predicted from. A root of a grid of several (``edges``) fills
    each edge first along itself (:func:`geoterrain.codec.predict.fill_edges_first`), and
    takes its invalid corners from ``near``, the fill of the whole top level (its
    neighbours take the same: a corner is coded, so the encoder chooses it)."""
    P = _period(te, cubic)
    filled = not valid.all()
    if filled:
        c = top.shape[0] - 1  # the corners: [::c, ::c]
        if near is None:
            near = np.array(top)  # a contiguous copy
            fill_outward(near, np.ascontiguousarray(valid))
        top[::c, ::c] = np.where(valid[::c, ::c], top[::c, ::c], near[::c, ::c])
        known = valid.copy()
        known[::c, ::c] = True
    # the decoder fills a stored mask only (entropy._top), and a root of several one
    # without a valid sample too (its corners and edges are its neighbours'); a square's
    # top tile without one keeps its predictions (those and the fill are all 0 there)
    filled = filled and (edges or bool(valid.any()))
    for k in range(te - 1, -1, -1):  # its own levels: 2**te exceeds their intervals
        s = 1 << k
        fill_level(top, valid, s, P, W)
        if filled:
            level = np.array(top[::s, ::s])
            (fill_edges_first if edges else fill_outward)(
                level, np.ascontiguousarray(known[::s, ::s]))
            top[::s, ::s] = level


def top_bins(bins: int) -> int:
    """The residual bins of the top tile's own grids: the largest odd width ≤ 3/4 of the
    other tiles' ``bins``. Every finer
    sample is predicted from the top tile's, which are few: SZ3 halves its error bound
    on its coarse levels for the same reason. On the six shared DEMs at ε = 0.5, 1 and
    2 (docs/lab/height-codec.md): fewer bytes than 1/2 or 1/4 in 14 cells, as many in 4;
    against no tightening, 16–20 % fewer on the smallest pyramid (St Helens, whose top
    tile holds a sixteenth of the samples) and at most 2.8 % more elsewhere.

    Examples
    --------
    >>> [top_bins(w) for w in (1, 3, 5, 9, 15, 39)]
    [1, 1, 3, 5, 11, 29]
    """
    return max(1, ((3 * bins) // 4 - 1) | 1)


def _period(te: int, cubic: bool) -> int:
    # fill_level's P: the parent tile's intervals for the cubic predictor, 0 for linear
    return (1 << te) if cubic else 0


def pyramid_shape(n_samples: int, t: int) -> tuple[int, int]:
    """Return ``(n, t_eff)`` for an N x N grid (N = 2**n + 1) and requested tile exponent t.

    Examples
    --------
    >>> pyramid_shape(4097, 6)
    (12, 6)
    >>> pyramid_shape(5, 6)
    (2, 2)
    """
    n = int(n_samples - 1).bit_length() - 1
    if n < 1 or (1 << n) + 1 != n_samples:
        raise ValueError(f"grid size {n_samples} is not 2**n + 1 with n >= 1")
    if t < 1:
        raise ValueError("t must be >= 1")
    return n, min(t, n)


def roots_shape(shape: tuple[int, int], t: int,
                roots: tuple[int, int] | None = None) -> tuple[int, int]:
    """``(n, t_eff)`` of a grid of ``roots`` (across, down) root tiles of 2**n samples a
    side, sharing their borders: ``shape`` = (down·2**n + 1, across·2**n + 1), the roots'
    extent (:attr:`geoterrain.core.grid.Grid.extent`); None: one square
    (:func:`pyramid_shape`).

    Examples
    --------
    >>> roots_shape((1025, 2049), 6, (2, 1))
    (10, 6)
    """
    rx, ry = roots or (1, 1)
    R, C = shape
    if rx < 1 or ry < 1 or (R - 1) % ry or (C - 1) % rx or (R - 1) // ry != (C - 1) // rx:
        raise ValueError(f"a {R} × {C} grid is not {rx} × {ry} square roots sharing borders")
    return pyramid_shape((R - 1) // ry + 1, t)


def _root_windows(a: np.ndarray, roots: tuple[int, int], te: int):
    """(x, y, window) of each root in the top level ``a`` (views), row by row."""
    T = 1 << te
    for y in range(roots[1]):
        for x in range(roots[0]):
            yield x, y, a[y * T:(y + 1) * T + 1, x * T:(x + 1) * T + 1]


def _header(top: bool, mask_kind: int, t: int, cubic: bool, w: int | None = None,
            edges: bool = False) -> bytes:
    # a top tile with invalid samples always has them filled outward (_top_fill), edges
    # first for a root of several
    flags = int(top) | (mask_kind << 1) | (int(cubic) << 3)
    if top and edges and mask_kind != MASK_ALL_VALID:
        flags |= _FILLED | _EDGES
    elif top and mask_kind == MASK_STORED:
        flags |= _FILLED
    if w is None:
        return bytes((BLOB_VERSION, flags, t))
    return bytes((BLOB_VERSION, flags | _WIDE, t, w))  # a wide blob


def _resolve_predictor(
    predictor: str, q: np.ndarray, valid: np.ndarray, te: int, lmax: int
) -> bool:
    """True for the cubic predictor. ``"auto"`` compares the zero-order entropy of the
    finest level's residuals under both predictors (on a central crop of at most
    1025 x 1025 samples) and keeps the smaller."""
    if predictor not in ("linear", "cubic", "auto"):
        raise ValueError(f"unknown predictor {predictor!r}")
    if predictor != "auto" or lmax == 0 or te < 2:
        return predictor == "cubic" and te >= 2 and lmax > 0
    a, crop = _predictor_crop(min(q.shape), te)
    return _predictor_bits(q[a : a + crop, a : a + crop], valid[a : a + crop, a : a + crop], te)


def _predictor_crop(size: int, te: int) -> tuple[int, int]:
    # the central crop of at most 1025² samples "auto" compares the predictors on
    crop = min(size, 1025)
    return ((size - crop) // 2) & ~((1 << te) - 1), crop  # tile-aligned: keeps fallbacks


def _predictor_bits(qq: np.ndarray, vv: np.ndarray, te: int) -> bool:
    # True when the cubic predictor's finest residuals have the smaller zero-order entropy
    bits = []
    for period in (None, 1 << te):
        preds = predict(qq, period)
        h = 0.0
        for sl, p in zip(_CLASSES, preds, strict=True):
            r = np.ascontiguousarray(qq[sl] - p)[vv[sl]]
            zz = ((r << 1) ^ (r >> 63)).view(np.uint64)  # zigzag
            cnt = np.bincount(np.minimum(zz, 1 << 16).astype(np.int64))
            pr = cnt[cnt > 0] / zz.size
            h += float(-(cnt[cnt > 0] * np.log2(pr)).sum())
        bits.append(h)
    return bits[1] < bits[0]


_CLASSES = (
    (slice(0, None, 2), slice(1, None, 2)),
    (slice(1, None, 2), slice(0, None, 2)),
    (slice(1, None, 2), slice(1, None, 2)),
)


# --------------------------------------------------------------------------- whole grid


def decoded_codes(
    z: np.ndarray, valid: np.ndarray, t: int, quantizer: Quantizer, predictor: str = "auto",
    roots: tuple[int, int] | None = None,
) -> np.ndarray:
    """Codes (N, N) int64 that decoding every tile gives, invalid samples included.

    Level by level on the full grid: valid samples keep their code (or its bins); an
    invalid sample of the top tile ends as its outward fill from the valid ones
    (:func:`geoterrain.codec.predict.fill_outward`), every other invalid sample its
    prediction from the coarser samples. ``predictor`` and ``roots`` as for
    :func:`encode_pyramid`.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[1, 1] = False
    >>> int(decoded_codes(z, v, 6, Quantizer("int"))[1, 1])  # the centre: its prediction
    4
    """
    valid = np.asarray(valid, dtype=bool)
    n, te = roots_shape(valid.shape, t, roots)
    lmax = n - te
    d = valid_codes(z, valid, quantizer)  # heights_to_codes(where(valid, z, 0))
    return _decoded_codes(d, valid, te, lmax, _resolve_predictor(predictor, d, valid, te, lmax),
                          quantizer.bins, roots)


def _decoded_codes(d: np.ndarray, valid: np.ndarray, te: int, lmax: int, cubic: bool,
                   bins: int = 1, roots: tuple[int, int] | None = None):
    """In place on the codes ``d``: what tile decoding gives at invalid samples, and
    with residual ``bins`` > 1 at valid ones too (coarse to fine: each level's
    predictions read the decoded codes of the coarser ones); on a grid of several
    ``roots``, each root's top tile as its own (the edges they share agree)."""
    s = 1 << lmax
    top, vtop = d[::s, ::s], valid[::s, ::s]
    if roots is None or roots[0] * roots[1] == 1:
        _top_fill(top, vtop, te, cubic, top_bins(bins))
    else:
        near = np.array(top)  # the invalid corners: one fill of the whole top level
        fill_outward(near, np.ascontiguousarray(vtop))
        for (_, _, tw), (_, _, vw), (_, _, nw) in zip(
                _root_windows(top, roots, te), _root_windows(vtop, roots, te),
                _root_windows(near, roots, te), strict=True):
            _top_fill(tw, vw, te, cubic, top_bins(bins), edges=True, near=nw)
    for lev in range(lmax - 1, -1, -1):  # compiled: the rule of predict, in place
        fill_level(d, valid, 1 << lev, _period(te, cubic), bins)
    return d


def decoded_heights(
    z: np.ndarray,
    valid: np.ndarray,
    quantizer: Quantizer,
    t: int | None = None,
    predictor: str = "auto",
) -> np.ndarray:
    """Heights (N, N) float64 exactly as decoding every tile gives them.

    Without residual bins (``quantizer.bins`` = 1), valid samples decode to
    ``codes_to_heights(heights_to_codes(z))`` whatever the pyramid (closed-loop coding).
    Invalid samples are NaN, unless ``t`` is given: then they hold exactly the
    (meaningless) values tile decoding produces (with the same ``predictor`` as the
    encoding). With bins the decoded heights depend on the pyramid: ``t`` is then
    required.

    Examples
    --------
    >>> qz = Quantizer("quantized", 0.2, 0.0, 0.1)
    >>> decoded_heights(np.array([[0.33]]), np.array([[True]]), qz).round(6).tolist()
    [[0.4]]
    """
    valid = np.asarray(valid, dtype=bool)
    if t is not None:
        d = decoded_codes(z, valid, t, quantizer, predictor)
        return codes_to_heights(d, quantizer)
    if quantizer.bins > 1:
        raise ValueError("heights decoded through residual bins depend on the pyramid: "
                         "pass t")
    return roundtrip(z, valid, quantizer)  # the same values, in one compiled pass


# --------------------------------------------------------------------------- encoding


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


_WIDE, _WIDE_LEVEL = 16, 6  # the wide blobs' flag bit and zstd level
_FILLED = 32  # the top tile's flag bit: its invalid samples filled outward (_top_fill)
_EDGES = 64  # with _FILLED: a root of several, its edges filled first (fill_edges_first)
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


def blob_predictor(blob: bytes) -> str:
    """The predictor a tile blob records: ``"cubic"`` or ``"linear"`` (every blob of a
    store records the same).

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> c = valid_codes(z, v, Quantizer("int"))
    >>> blob_predictor(encode_root(c, v, 2, True)), blob_predictor(encode_root(c, v, 2, False))
    ('cubic', 'linear')
    """
    return "cubic" if _parse(blob)[3] else "linear"


# --------------------------------------------------------------------------- decoding


_NOT_A_STREAM = "tile blob's stream has bytes past its end (not one the encoder writes)"


def _parse(blob: bytes, t: int | None = None) -> tuple[bool, int, int, bool, int, np.ndarray]:
    """Header fields (top, mask kind, t, cubic, w: -1 unless wide) and the stream,
    refusing a malformed header; ``t``, when given, must match the blob's tile size.
    Any range-coded stream decodes to some codes, in bounded time; the decoders then
    refuse one with bytes past its end. A wide blob's frame must hold exactly its size."""
    if len(blob) < _HEADER or blob[0] != BLOB_VERSION:
        raise ValueError(f"not a version-{BLOB_VERSION} tile blob")
    top, kind, te = bool(blob[1] & 1), (blob[1] >> 1) & 3, blob[2]
    edges = bool(blob[1] & _EDGES)
    filled_ok = not blob[1] & _FILLED or (top and (kind == MASK_STORED or edges
                                                  and kind == MASK_ALL_INVALID))
    filled_ok = filled_ok and (not edges or bool(blob[1] & _FILLED))
    if blob[1] & ~0b1111111 or kind > MASK_STORED or not 1 <= te <= 15 or not filled_ok \
            or (t is not None and te != t):
        raise ValueError("tile blob header does not match the store's grid")
    if not blob[1] & _WIDE:
        return top, kind, te, bool(blob[1] & 8), -1, np.frombuffer(blob, np.uint8,
                                                                   offset=_HEADER)
    if top or len(blob) < _HEADER + 1 or blob[_HEADER] not in (0, 1, 2, 4, 8):
        raise ValueError("tile blob header does not match the store's grid")
    w, tt, h = blob[_HEADER], (1 << te) + 1, 1 << (te - 1)
    size = ((tt * tt + 7) // 8 if kind == MASK_STORED else 0) + w * (3 * h * h + 2 * h)
    payload = decompress(blob[_HEADER + 1:], size, exact=True)  # bounded: never a bomb
    return top, kind, te, bool(blob[1] & 8), w, np.frombuffer(payload, np.uint8)


def tile_valid(blob: bytes, t: int | None = None) -> np.ndarray:
    """The tile's (T, T) valid mask stored in its blob.

    Examples
    --------
    >>> z = np.zeros((3, 3)); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> blob = encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)]
    >>> tile_valid(blob).sum()
    np.int64(8)
    """
    _, kind, te, _, w, data = _parse(blob, t)
    if w >= 0:
        return _wide_mask(kind, te, data)
    return entropy.decode_mask(data, (1 << te) + 1, kind)


def _wide_mask(kind: int, te: int, data: np.ndarray) -> np.ndarray:
    tt = (1 << te) + 1
    if kind != MASK_STORED:
        return np.full((tt, tt), kind == MASK_ALL_VALID)
    return np.unpackbits(data[:(tt * tt + 7) // 8], count=tt * tt).reshape(tt, tt).astype(bool)


def decode_tile(
    blob: bytes,
    parent_codes: np.ndarray | None,
    quantizer: Quantizer,
    tile_xy_parity: tuple[int, int] = (0, 0),
    t: int | None = None,
) -> np.ndarray:
    """Decode one tile's (T, T) int64 codes.

    Parameters
    ----------
    blob : bytes
        The tile's blob (from :func:`encode_pyramid`).
    parent_codes : (T, T) int64 or None
        The parent tile's decoded codes (the whole tile: the cubic predictor reads one
        sample beyond the child's quadrant); None for the top tile.
    quantizer : Quantizer
        Same as for encoding (its residual bins).
    tile_xy_parity : (int, int)
        ``(x % 2, y % 2)`` of the tile: which quadrant of the parent it covers.
    t : int or None
        The store's tile exponent; a blob of another tile size is refused.

    Returns
    -------
    (T, T) int64 codes; heights via :func:`codes_to_heights`.

    Examples
    --------
    >>> z = np.arange(25.0).reshape(5, 5); v = np.ones((5, 5), bool)
    >>> blobs = encode_pyramid(z, v, 1, Quantizer("int"))
    >>> top = decode_tile(blobs[(1, 0, 0)], None, Quantizer("int"))
    >>> decode_tile(blobs[(0, 1, 0)], top, Quantizer("int"), (1, 0)).tolist()
    [[2, 3, 4], [7, 8, 9], [12, 13, 14]]
    """
    return decode_tile_valid(blob, parent_codes, tile_xy_parity, t, quantizer.bins)[0]


def decode_tile_valid(blob: bytes, parent_codes: np.ndarray | None,
                      tile_xy_parity: tuple[int, int] = (0, 0), t: int | None = None,
                      bins: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The tile's codes (:func:`decode_tile`) and valid mask (:func:`tile_valid`), its
    payload decompressed once; ``bins``: the quantizer's residual bins.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[0, 0] = False
    >>> codes, valid = decode_tile_valid(encode_pyramid(z, v, 6, Quantizer("int"))[(0, 0, 0)],
    ...                                  None)
    >>> codes[1].tolist(), int(valid.sum())
    ([3, 4, 5], 8)
    """
    top, kind, te, cubic, w, data = _parse(blob, t)
    if top:
        codes, valid, exact = entropy.decode_top(data, te, cubic, kind, top_bins(bins),
                                                 bool(blob[1] & _FILLED),
                                                 bool(blob[1] & _EDGES))
        if not exact:
            raise ValueError(_NOT_A_STREAM)
        return codes, valid
    if parent_codes is None:
        raise ValueError("a non-top tile needs its parent's decoded codes")
    tt, h = (1 << te) + 1, 1 << (te - 1)
    px, py = int(tile_xy_parity[0]) & 1, int(tile_xy_parity[1]) & 1
    parent = np.ascontiguousarray(parent_codes, np.int64)
    if parent.shape != (tt, tt):
        raise ValueError(f"parent codes must be ({tt}, {tt})")
    if w < 0:  # range-coded: the predictions are applied as the residuals are decoded
        out, valid, exact = entropy.decode_tile(data, parent, px, py, cubic, kind, bins)
        if not exact:
            raise ValueError(_NOT_A_STREAM)
        return out, valid
    # a wide blob: every residual, then the predictions (one compiled call)
    valid = _wide_mask(kind, te, data)
    off = (tt * tt + 7) // 8 if kind == MASK_STORED else 0
    out = np.empty((tt, tt), np.int64)
    _wide_child(data, off, w, 3 * h * h + 2 * h, parent, py, px, h, cubic, out)
    return out, valid


@njit(cache=True, nogil=True)
def _wide_child(data, off, w, n, parent, py, px, h, cubic, out):
    """A wide blob's child codes: its n residuals, each stored as w little-endian bytes
    in w byte planes (``data[off + b·n + k]`` the b-th byte of residual k), zig-zag
    coded, added to the parent's predictions (cubic: the parent tile's own, with its
    edge fallbacks; linear: from the quadrant the child covers)."""
    r = np.empty(n, np.int64)
    d = data[off:off + w * n]
    if w == 8:  # a residual may fill 64 bits: unsigned, shifted logically
        one = np.uint64(1)
        for k in range(n):
            v = np.uint64(0)
            for b in range(8):
                v |= np.uint64(d[b * n + k]) << np.uint64(8 * b)
            r[k] = np.int64(v >> one) ^ -np.int64(v & one)
    elif w == 0:
        r[:] = 0
    else:  # 1, 2 or 4 bytes: each plane read in order (a loop over the bytes of one
        # residual, w unknown to the compiler, took 8× as long)
        for k in range(n):
            v = np.int64(d[k])
            if w >= 2:
                v |= np.int64(d[n + k]) << 8
            if w == 4:
                v |= (np.int64(d[2 * n + k]) << 16) | (np.int64(d[3 * n + k]) << 24)
            r[k] = (v >> 1) ^ -(v & 1)
    if cubic:
        cubic_child(parent, py * h, px * h, h, r, out)
    else:
        linear_child(np.ascontiguousarray(parent[py * h:py * h + h + 1,
                                                 px * h:px * h + h + 1]), h, r, out)
