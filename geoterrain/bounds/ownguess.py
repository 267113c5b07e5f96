"""Bounds payloads guessed from a tile's own heights (schemas 20 and 23).

:func:`own_codes` codes a lower bound of each new vertex's δ from the tile's decoded
heights (an edge midpoint's own error, a cell centre's seed 002 §2.3 closed form over its
cell); the payloads store the codes against that guess, range-coded
(:mod:`geoterrain.bounds.gapcoder`) and opened by :func:`guess_check`:

- :func:`pred_payloads_own` / :func:`pred_codes_own`: a δ ``PRED`` payload (``PRED``
  with ``SLACK``), each code's difference from its parents' prediction in the contexts
  of its gap to the own error;
- :func:`ring_payloads_own` / :func:`ring_codes_own`: a level-0 ring δ (``RING`` with
  ``PRED``), the codes less their own errors';
- :func:`edge_own_codes`, :func:`edge_payload_own` / :func:`edge_codes_own`,
  :func:`top_edge_payload_own` / :func:`top_edge_codes_own`: schema 23's δ_edge (``DIFF``
  with ``PRED``), guessed from the tile's δ and its edge heights;
- :func:`top_steps`, :func:`top_payload_own` / :func:`top_codes_own`: schema 23's whole
  (top) tile's δ, level by level.

A wrong guess costs bytes, never exactness; the blob formats are in
:mod:`geoterrain.bounds.vertexdata`.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
from numba import njit

from geoterrain.bounds.gapcoder import GapDecoder, encode_gaps, encode_gaps_rows
from geoterrain.bounds.log8codes import (
    LOG_STEPS,
    _log8_table64,
    _new_flat,
    _pred_centres,
    _pred_index,
)


@njit(cache=True, nogil=True, inline="always")
def _code_up(table, x, e):
    # the smallest log8 code whose value is ≥ x (radii.code_up_nb's binary search, the
    # same result): a guess from log2(x), walked to the first entry ≥ x
    if not x > table[1]:  # 0 for x ≤ 0, else 1
        return 0 if not x > 0.0 else 1
    if x > table[254]:
        return 255
    c = min(max(int(LOG_STEPS * (math.log2(x) - e)) + 1, 1), 254)
    while table[c - 1] >= x:
        c -= 1
    while table[c] < x:
        c += 1
    return c


@njit(cache=True, nogil=True)
def _own_codes_nb(z, valid, stand_in, r0, c0, s, ring, table, e, out):
    # tile k's samples are z[r0[k] + s i, c0[k] + s j], copied first into ``w`` with the
    # stand-in where not valid (no mask: all valid). IEEE products, sums and abs only (no
    # fast math): a writer and any reader get the same codes bit for bit. Edge midpoints:
    # |z − the mean of the split edge's ends|; cell centres: seed 002 §2.3's h = 1 closed
    # form over the cell's 9 samples (delta._centre1: the centre off its diagonal, each
    # edge midpoint off its edge), the diagonal by the union-jack parity from the tile's
    # first cell (as _pred_index). ``ring``: the border's new vertices only
    T = out.shape[1]
    w = np.empty((T, T))
    masked = valid.shape[0] > 0
    for k in range(out.shape[0]):
        for i in range(T):
            a = r0[k] + s * i
            for j in range(T):
                if ring and 1 < i < T - 2 and 1 < j < T - 2:
                    continue
                b = c0[k] + s * j
                w[i, j] = z[a, b] if not masked or valid[a, b] else stand_in
        for i in range(T):
            for j in range(1 - (i & 1), T, 2 - (i & 1)):  # the new vertices
                if ring and 0 < i < T - 1 and 0 < j < T - 1:
                    continue
                zv = w[i, j]
                if (i & 1) and (j & 1):
                    z00 = w[i - 1, j - 1]
                    z01 = w[i - 1, j + 1]
                    z10 = w[i + 1, j - 1]
                    z11 = w[i + 1, j + 1]
                    main = ((i >> 1) + (j >> 1)) % 2 == 0
                    sc = 0.5 * (z00 + z11) if main else 0.5 * (z01 + z10)
                    m = abs(zv - sc)
                    m = max(m, abs(w[i - 1, j] - 0.5 * (z00 + z01)))
                    m = max(m, abs(w[i + 1, j] - 0.5 * (z10 + z11)))
                    m = max(m, abs(w[i, j - 1] - 0.5 * (z00 + z10)))
                    m = max(m, abs(w[i, j + 1] - 0.5 * (z01 + z11)))
                elif i & 1:  # odd row, even column: the ends above and below
                    m = abs(zv - 0.5 * (w[i - 1, j] + w[i + 1, j]))
                else:
                    m = abs(zv - 0.5 * (w[i, j - 1] + w[i, j + 1]))
                out[k, i, j] = _code_up(table, m, e) if m == m else 0


def own_codes(z: np.ndarray, valid: np.ndarray | None, stand_in: float, e: int,
              origins: np.ndarray | None = None, T: int | None = None, step: int = 1,
              ring: bool = False) -> np.ndarray:
    """The log8 codes (from ``2^e``) of a lower bound of each new vertex's δ, from the
    scene heights ``z`` (invalid samples, where ``valid`` is False, by the store's
    ``stand_in`` height, as the radii take them; ``valid`` None: all valid): an edge
    midpoint's own error, |z − the mean of its split edge's ends|, and a cell centre's
    closed form over its cell (its own error and its four edge midpoints', seed 002
    §2.3). δ is the largest error over the vertex's diamond, saturated over its
    children, so it is never below these where the samples are valid. (k, T, T) uint8 of
    the tiles whose first samples are at ``origins`` (k, 2: row, column; None: one tile,
    ``z`` itself) with samples ``step`` apart, 0 on the parent's vertices (and off the
    border with ``ring``). Schema 20's guess for δ (:func:`pred_payloads_own`, and
    :func:`ring_payloads_own`): a wrong one costs bytes, never exactness.

    Examples
    --------
    >>> z = np.zeros((3, 3)); z[1, 1] = 2.0; z[0, 1] = 1.0
    >>> from geoterrain.bounds.log8codes import log8_table
    >>> c = own_codes(z, None, 0.0, -3)[0]; t = log8_table(-3)
    >>> float(t[c[1, 1]]), float(t[c[0, 1]]), int(c[0, 0])
    (2.0, 1.0, 0)
    """
    z = np.asarray(z, np.float64)
    if origins is None:
        origins, T = np.zeros((1, 2), np.int64), z.shape[0]
    o = np.asarray(origins, np.int64).reshape(-1, 2)
    v = np.zeros((0, 0), np.uint8) if valid is None else np.asarray(valid).view(np.uint8) \
        if np.asarray(valid).dtype in (np.bool_, np.uint8) else np.asarray(valid, np.uint8)
    out = np.zeros((len(o), T, T), np.uint8)
    _own_codes_nb(z, v, float(stand_in), np.ascontiguousarray(o[:, 0]),
                  np.ascontiguousarray(o[:, 1]), int(step), bool(ring),
                  _log8_table64(int(e)), int(e), out)
    return out


def guess_check(g: np.ndarray) -> int:
    """The byte that opens a schema-20 δ payload: the low byte of the crc32 of the guess
    it was coded against (a tile's :func:`own_codes`, or its ring's, as uint8). A reader
    compares it with its own guess's, so a payload moved to another tile (its checksum
    recomputed) is refused rather than decoded against the wrong heights (a ring's
    differences, mostly 0, would decode to plausible codes there).

    Examples
    --------
    >>> guess_check(np.array([1, 2, 3])) != guess_check(np.array([2, 3, 4]))
    True
    """
    return zlib.crc32(np.ascontiguousarray(g, np.uint8).tobytes()) & 0xFF


def pred_gaps(W: np.ndarray, lo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For tiles ``W`` (k, T, T) of log8 codes and their :func:`own_codes` ``lo``:
    :func:`~geoterrain.bounds.log8codes.pred_residuals`' differences (k, n) (the parents' prediction
    minus the code, mod 256; the centres, then the other new vertices) and their gaps (k, n) (the
    prediction minus ``lo``): where the bounds hold, 0 ≤ difference ≤ gap."""
    W = np.asarray(W, np.int16)
    lo = np.asarray(lo, np.int16)
    k, T = W.shape[0], W.shape[1]
    other, n1, n2, main = _pred_index(T)
    hc = _pred_centres(W, main).reshape(k, -1)
    ext = np.concatenate([W.reshape(k, -1), np.full((k, 1), 255, np.int16)], axis=1)
    hm = np.minimum(ext[:, n1], ext[:, n2])
    r = np.concatenate([hc - W[:, 1::2, 1::2].reshape(k, -1), hm - ext[:, other]], axis=1)
    gap = np.concatenate([hc - lo[:, 1::2, 1::2].reshape(k, -1),
                          hm - lo.reshape(k, -1)[:, other]], axis=1)
    return r & 0xFF, gap


def pred_payloads_own(W: np.ndarray, lo: np.ndarray) -> list[bytes]:
    """Schema 20's ``PRED`` δ payloads (``PRED`` with ``SLACK``) of tiles ``W`` (k, T, T)
    with their :func:`own_codes` ``lo``: :func:`pred_gaps`' differences range-coded
    (:func:`~geoterrain.bounds.gapcoder.encode_gaps`) in the contexts of their gaps. Where a gap is
    0 the code is known (a zero costs a few hundredths of a bit), where it is small the difference
    is small: srtm1_japan's level-1 δ 87.5 kB in raster order at zstd 11, 73.8 kB so
    (docs/lab/store-size.md). Exact whatever ``lo``: a wrong guess costs bytes.
    :func:`pred_codes_own` inverts it.

    Examples
    --------
    >>> W = np.random.default_rng(1).integers(0, 256, (2, 5, 5)).astype(np.uint8)
    >>> lo = np.random.default_rng(2).integers(0, 256, (2, 5, 5)).astype(np.uint8)
    >>> p = pred_payloads_own(W, lo)
    >>> all((pred_codes_own(W[k, ::2, ::2], p[k], lo[k]) == W[k]).all() for k in range(2))
    True
    """
    r, gap = pred_gaps(W, lo)
    return [bytes([guess_check(lo[n])]) + p for n, p in enumerate(encode_gaps_rows(r, gap))]


def pred_payload_same(W0: np.ndarray, lo0: np.ndarray, W1: np.ndarray, lo1: np.ndarray
                      ) -> bool:
    """Whether two tiles' schema-20 δ payloads are the same bytes, decided without coding
    them: tiles ``W0`` and ``W1`` (T, T) of log8 codes, with their :func:`own_codes`
    ``lo0`` and ``lo1``, both of the ``PRED`` shape (a new vertex off the cell centres
    not 0: else ``CENTRES``, :func:`geoterrain.bounds.vertexdata.shape_codes`), with the
    same own-error guess and the same :func:`pred_gaps` (differences and gaps):
    :func:`pred_payloads_own` is a function of those. False where unsure (another shape).

    Examples
    --------
    >>> W = np.random.default_rng(1).integers(1, 256, (5, 5)).astype(np.uint8)
    >>> lo = np.zeros((5, 5), np.uint8); V = W.copy(); V[0, 0] = 0  # a corner moved
    >>> same = lambda a, b: pred_payloads_own(a[None], lo[None]) == \\
    ...     pred_payloads_own(b[None], lo[None])
    >>> pred_payload_same(W, lo, V, lo), same(W, V)  # the prediction did not move
    (True, True)
    >>> V[1, 1] += 1  # a centre moved
    >>> pred_payload_same(W, lo, V, lo), same(W, V)
    (False, False)
    """
    W0, W1 = np.asarray(W0, np.uint8), np.asarray(W1, np.uint8)
    lo0, lo1 = np.asarray(lo0, np.uint8), np.asarray(lo1, np.uint8)
    if W0.shape != W1.shape or not new_codes_same(W0, W1) or lo0.shape != lo1.shape \
            or not np.array_equal(lo0, lo1):
        return False
    other, _, _, main = _pred_index(W0.shape[0])
    if not (W0.ravel()[other].any() and W1.ravel()[other].any()):  # CENTRES: not decided
        return False
    # with the new vertices' codes and the own errors the same, pred_gaps' differences
    # and gaps are the same where the predictions are: an edge midpoint's is read off
    # its two cell centres (new vertices), a centre's off its cell's corners (the
    # parents' lattice): those alone are compared
    return bool(np.array_equal(_pred_centres(W0[None].astype(np.int16), main),
                               _pred_centres(W1[None].astype(np.int16), main)))


def new_codes_same(W0: np.ndarray, W1: np.ndarray) -> bool:
    """Whether two (T, T) tiles' new vertices (not on the parent's lattice) hold the same
    codes: with the same own errors, :func:`pred_gaps`' gaps fix the predictions and its
    differences then the codes (mod 256), so two payloads :func:`pred_payload_same` calls
    the same have these equal (a check that needs no own errors).

    Examples
    --------
    >>> W = np.zeros((5, 5), np.uint8); V = W.copy(); V[2, 2] = 9  # a corner
    >>> new_codes_same(W, V), (V.__setitem__((1, 2), 1), new_codes_same(W, V))[1]
    (True, False)
    """
    new = _new_flat(np.shape(W0)[0])
    return bool(np.array_equal(np.ravel(W0)[new], np.ravel(W1)[new]))


def pred_codes_own(corners: np.ndarray, payload: bytes, lo: np.ndarray) -> np.ndarray:
    """A tile's (T, T) log8 codes from its parent's ``corners`` (h + 1, h + 1), its
    schema-20 ``PRED`` payload (:func:`pred_payloads_own`) and its :func:`own_codes`
    ``lo`` (T, T): the centres first (their contexts from the corners and ``lo``), then
    the other new vertices (theirs from the centres and ``lo``)."""
    h = np.shape(corners)[0] - 1
    lo = np.asarray(lo, np.int16).reshape(2 * h + 1, 2 * h + 1)
    if len(payload) < 1 or payload[0] != guess_check(lo):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = _pred_take(dec, corners, lo)
    dec.check()
    return out


def _pred_take(dec: GapDecoder, corners: np.ndarray, lo: np.ndarray) -> np.ndarray:
    # one tile's (T, T) codes from its corners (h + 1, h + 1): the next values of ``dec``
    # in pred_gaps' order (the centres, then the other new vertices), in their gaps
    corners = np.asarray(corners, np.int16)
    h = corners.shape[0] - 1
    T = 2 * h + 1
    lo = np.asarray(lo, np.int16).reshape(T, T)
    other, n1, n2, main = _pred_index(T)
    ext = np.empty(T * T + 1, np.int16)
    W = ext[:-1].reshape(1, T, T)
    W[0, ::2, ::2] = corners
    ext[-1] = 255
    hc = _pred_centres(W, main)[0].ravel()
    rc = dec.take(hc - lo[1::2, 1::2].ravel())
    W[0, 1::2, 1::2] = ((hc - rc) & 0xFF).reshape(h, h)
    hm = np.minimum(ext[n1], ext[n2])
    ext[other] = (hm - dec.take(hm - lo.ravel()[other])) & 0xFF
    return W[0].astype(np.uint8)


def edge_own_codes(z: np.ndarray, valid: np.ndarray | None, stand_in: float, e: int,
                   rows: int, cols: int) -> np.ndarray | None:
    """Schema 23's guess of a level-0 tile's δ_edge (T, T) log8 codes: the
    :func:`own_codes` of the tile's heights ``z`` (invalid and non-finite samples by
    ``stand_in``) with the padding replicated from the data's edge as
    :func:`geoterrain.bounds.edgepad.edge_support` does (the data: the tile's first
    ``rows`` rows and ``cols`` columns), 0 on the new vertices whose diamond misses the
    data (row > ``rows`` or column > ``cols``). None where the tile holds no data row or
    column to replicate. The writer and the reader call it on the same heights.

    Examples
    --------
    >>> z = np.zeros((5, 5)); z[:3, :3] = [[0, 1, 2], [1, 2, 3], [2, 3, 9]]
    >>> g = edge_own_codes(z, None, 0.0, -3, 3, 3)
    >>> int(g[1, 1] > 0), int(g[4, 3]), int(g[3, 4]), edge_own_codes(z, None, 0.0, -3, 0, 3)
    (1, 0, 0, None)
    """
    T = z.shape[0]
    if rows < 1 or cols < 1:
        return None
    ok = np.isfinite(z) if valid is None else np.asarray(valid, bool) & np.isfinite(z)
    Z = np.where(ok, np.asarray(z, np.float64), float(stand_in))
    if cols < T:
        Z[:rows, cols:] = Z[:rows, cols - 1:cols]
    if rows < T:
        Z[rows:] = Z[rows - 1]
    g = own_codes(Z, None, stand_in, e)[0]
    g[rows + 1:] = 0
    g[:, cols + 1:] = 0
    return g


def edge_payload_own(codes: np.ndarray, base: np.ndarray, guess: np.ndarray,
                     pred: bool = False) -> bytes | None:
    """Schema 23's δ_edge payload of a tile below the top (flags ``DIFF`` with ``PRED``):
    its new vertices' δ_edge log8 ``codes`` (T, T) where its δ codes ``base`` are +inf (255),
    range-coded (:func:`~geoterrain.bounds.gapcoder.encode_gaps`) after the :func:`guess_check` of
    their ``guess`` (:func:`edge_own_codes`): level 0's as the codes less the guess, mod 256, in one
    context; ``pred`` (above level 0, ``SLACK`` too) as :func:`pred_gaps`' differences from the
    parents' prediction in the contexts of their gaps above the guess (``codes`` then holds the
    parent's codes on the even vertices). Everywhere else δ_edge is δ, and None where it is not (the
    writer keeps the plain ``DIFF`` payload then). srtm3's 19 δ_edge blobs below the top 2.99 → 1.0
    kB (docs/lab/store-size.md). :func:`edge_codes_own` inverts it.

    Examples
    --------
    >>> b = np.full((3, 3), 255, np.uint8); b[0, 1] = 4
    >>> c = b.copy(); c[1, 1], c[2, 1] = 7, 9; c[::2, ::2] = 0  # the corners: not new
    >>> g = np.full((3, 3), 7, np.uint8); p = edge_payload_own(c, b, g)
    >>> bool((edge_codes_own(p, b, g) == c).all()), edge_payload_own(b - 1, b, g)
    (True, None)
    >>> c[::2, ::2] = 8; q = edge_payload_own(c, b, g, pred=True)
    >>> bool((edge_codes_own(q, b, g, c[::2, ::2]) == c).all())
    True
    """
    T = codes.shape[0]
    keep = _new_flat(T)
    c = np.asarray(codes, np.int64).ravel()[keep]
    b = np.asarray(base, np.int64).ravel()[keep]
    sel = b == 255
    if (c[~sel] != b[~sel]).any():
        return None
    g = np.asarray(guess, np.int64).ravel()[keep]
    head = bytes([guess_check(g[sel])])
    if not pred:
        return head + encode_gaps((c[sel] - g[sel]) & 0xFF, np.zeros(int(sel.sum()), np.int64))
    r, gap = pred_gaps(np.asarray(codes)[None], np.asarray(guess)[None])
    ps = _edge_pred_order(np.asarray(base), T)
    return head + encode_gaps(r[0][ps], gap[0][ps])


def _edge_pred_order(base: np.ndarray, T: int) -> np.ndarray:
    # pred_gaps' order (the centres, then the other new vertices) of the new vertices
    # where δ's codes ``base`` are +inf
    other = _pred_index(T)[0]
    return np.concatenate([base[1::2, 1::2].ravel() == 255, base.ravel()[other] == 255])


def edge_codes_own(payload: bytes, base: np.ndarray, guess: np.ndarray,
                   corners: np.ndarray | None = None) -> np.ndarray:
    """A tile's δ_edge codes (T, T; its new vertices', and ``corners`` on the even ones)
    from its :func:`edge_payload_own` payload, its δ codes ``base`` and its ``guess``
    (:func:`edge_own_codes`); ``corners`` (h + 1, h + 1): the parent's codes, for a
    ``pred`` payload. ValueError for a payload coded against other heights or bytes the
    encoder would not have written."""
    T = base.shape[0]
    keep = _new_flat(T)
    sel = np.asarray(base).ravel()[keep] == 255
    if len(payload) < 1 or payload[0] != guess_check(np.asarray(guess).ravel()[keep][sel]):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = _edge_take(dec, base, guess, corners)
    dec.check()
    return out


def _edge_take(dec: GapDecoder, base: np.ndarray, guess: np.ndarray,
               corners: np.ndarray | None) -> np.ndarray:
    # one tile's δ_edge codes (T, T): δ's codes ``base`` where they are finite, the next
    # values of ``dec`` where they are +inf (edge_payload_own's order and contexts)
    T = base.shape[0]
    keep = _new_flat(T)
    b = np.asarray(base, np.int64).ravel()[keep]
    g = np.asarray(guess, np.int64)
    sel = b == 255
    out = np.zeros(T * T, np.int16)
    out[keep] = b
    if corners is None:
        out[keep[sel]] = (g.ravel()[keep][sel] + dec.take(np.zeros(int(sel.sum()), np.int64))
                          ) & 0xFF
    else:  # the centres from the corners, then the other new vertices (pred_gaps)
        other, n1, n2, main = _pred_index(T)
        ext = np.empty(T * T + 1, np.int16)
        ext[:-1] = out
        ext[-1] = 255
        W = ext[:-1].reshape(1, T, T)
        W[0, ::2, ::2] = corners
        cs = np.asarray(base)[1::2, 1::2] == 255
        hc = _pred_centres(W, main)[0]
        rc = dec.take((hc - g[1::2, 1::2])[cs])
        W[0, 1::2, 1::2][cs] = (hc[cs] - rc) & 0xFF
        os_ = np.asarray(base).ravel()[other] == 255
        hm = np.minimum(ext[n1], ext[n2])[os_]
        ext[other[os_]] = (hm - dec.take(hm - g.ravel()[other[os_]])) & 0xFF
        out = ext[:-1]
    return out.astype(np.uint8).reshape(T, T)


def top_edge_payload_own(codes: np.ndarray, base: np.ndarray, guess_at) -> bytes | None:
    """Schema 23's whole-tile δ_edge payload (the top tile's; flags ``DIFF``, ``PRED`` and
    ``SLACK`` without ``NEW_ONLY``): the tile's (T, T) δ_edge log8 ``codes`` level by
    level inside it (:func:`top_steps`), its four corners as they are, then each level's
    new vertices where δ's codes ``base`` are +inf as :func:`edge_payload_own` with
    ``pred`` codes a tile below the top, ``guess_at(s)`` the :func:`edge_own_codes` of
    the tile's samples s apart, in one range-coded stream after the :func:`guess_check`
    of every guess there. None where δ_edge is not δ wherever δ is finite (off the
    corners). :func:`top_edge_codes_own` inverts it.

    Examples
    --------
    >>> rng = np.random.default_rng(4)
    >>> b = rng.choice(np.array([3, 255], np.uint8), (9, 9)); c = b.copy()
    >>> c[b == 255] = rng.integers(0, 256, int((b == 255).sum()))
    >>> g = {s: rng.integers(0, 256, (8 // s + 1,) * 2).astype(np.uint8) for s in (4, 2, 1)}
    >>> bool((top_edge_codes_own(top_edge_payload_own(c, b, g.get), b, g.get) == c).all())
    True
    """
    c, b = np.asarray(codes, np.uint8), np.asarray(base, np.uint8)
    T = c.shape[0]
    off = np.ones((T, T), bool)
    off[::T - 1, ::T - 1] = False
    if (c[off & (b != 255)] != b[off & (b != 255)]).any():
        return None
    rs, gs, checks = [], [], []
    for s in top_steps(T):
        g = np.asarray(guess_at(s), np.uint8)
        r, gap = pred_gaps(c[None, ::s, ::s], g[None])
        ps = _edge_pred_order(b[::s, ::s], g.shape[0])
        rs.append(r[0][ps])
        gs.append(gap[0][ps])
        checks.append(g.ravel()[_new_flat(g.shape[0])][b[::s, ::s].ravel()[
            _new_flat(g.shape[0])] == 255])
    return (bytes([guess_check(np.concatenate(checks))]) + c[::T - 1, ::T - 1].tobytes()
            + encode_gaps(np.concatenate(rs), np.concatenate(gs)))


def top_edge_codes_own(payload: bytes, base: np.ndarray, guess_at) -> np.ndarray:
    """A whole tile's (T, T) δ_edge codes from its :func:`top_edge_payload_own` payload,
    its δ codes ``base`` and its guesses ``guess_at(s)``; ValueError for a payload
    coded against other heights, or bytes the encoder would not have written."""
    b = np.asarray(base, np.uint8)
    T = b.shape[0]
    gs, checks = [], []
    for s in top_steps(T):
        g = np.asarray(guess_at(s), np.uint8)
        n = (T - 1) // s + 1
        if g.shape != (n, n):
            raise ValueError("an edge guess of the wrong shape")
        gs.append(g)
        checks.append(g.ravel()[_new_flat(n)][b[::s, ::s].ravel()[_new_flat(n)] == 255])
    if len(payload) < 5 or payload[0] != guess_check(np.concatenate(checks)):
        raise ValueError("a guessed bounds payload coded against other heights")
    W = np.frombuffer(payload[1:5], np.uint8).reshape(2, 2)
    dec = GapDecoder(payload[5:])
    for s, g in zip(top_steps(T), gs, strict=True):
        W = _edge_take(dec, b[::s, ::s], g, W)
    dec.check()
    return W


def top_steps(T: int) -> list[int]:
    """The sample steps of a whole tile's levels inside it, coarsest first:
    (T − 1) / 2, …, 2, 1 (T − 1 a power of two ≥ 2)."""
    if T < 3 or (T - 1) & (T - 2):
        raise ValueError("a tile of 2^k + 1 samples a side, k ≥ 1")
    return [1 << b for b in range((T - 1).bit_length() - 2, -1, -1)]


def top_payload_own(codes: np.ndarray, lo_at) -> bytes:
    """Schema 23's whole-tile δ payload (the top tile's; flags ``PRED`` with ``SLACK``
    without ``NEW_ONLY``): the tile's (T, T) log8 ``codes`` level by level inside it, as
    :func:`pred_payloads_own` codes a tile below the top: its four corners, then, for each step s of
    :func:`top_steps`, the vertices new at s (the samples s apart, their parents 2s apart) as
    :func:`pred_gaps`' differences in their gaps above ``lo_at(s)``, the :func:`own_codes` of the
    tile's samples s apart, all range-coded in one stream
    (:func:`~geoterrain.bounds.gapcoder.encode_gaps`), after the :func:`guess_check` of every
    level's guess. srtm3's top δ 1.50 → 0.97 kB (docs/lab/store-size.md). :func:`top_codes_own`
    inverts it; any guess decodes exactly.

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> c = rng.integers(0, 256, (9, 9)).astype(np.uint8)
    >>> lo = {s: rng.integers(0, 256, (8 // s + 1,) * 2).astype(np.uint8) for s in (4, 2, 1)}
    >>> bool((top_codes_own(top_payload_own(c, lo.get), 9, lo.get) == c).all())
    True
    """
    c = np.asarray(codes, np.uint8)
    T = c.shape[0]
    los = [np.asarray(lo_at(s), np.uint8) for s in top_steps(T)]
    rs, gs = [], []
    for s, lo in zip(top_steps(T), los, strict=True):
        r, gap = pred_gaps(c[None, ::s, ::s], lo[None])
        rs.append(r[0])
        gs.append(gap[0])
    check = guess_check(np.concatenate([lo.ravel() for lo in los]))
    return (bytes([check]) + c[::T - 1, ::T - 1].tobytes()
            + encode_gaps(np.concatenate(rs), np.concatenate(gs)))


def top_codes_own(payload: bytes, T: int, lo_at) -> np.ndarray:
    """A whole tile's (T, T) log8 codes from its :func:`top_payload_own` payload and its
    guesses ``lo_at(s)`` (each step s of :func:`top_steps`: the :func:`own_codes` of the
    tile's samples s apart); ValueError for a payload coded against other heights, or
    bytes the encoder would not have written."""
    steps = top_steps(T)
    los = []
    for s in steps:
        lo = np.asarray(lo_at(s), np.uint8)
        if lo.shape != ((T - 1) // s + 1,) * 2:
            raise ValueError("an own-error guess of the wrong shape")
        los.append(lo)
    if len(payload) < 5 or payload[0] != guess_check(
            np.concatenate([lo.ravel() for lo in los])):
        raise ValueError("a guessed bounds payload coded against other heights")
    W = np.frombuffer(payload[1:5], np.uint8).reshape(2, 2)
    dec = GapDecoder(payload[5:])
    for lo in los:
        W = _pred_take(dec, W, lo)
    dec.check()
    return W


def ring_payloads_own(rings: np.ndarray, guess: np.ndarray) -> list[bytes]:
    """Schema 20's level-0 ``RING`` δ payloads (``RING`` with ``PRED``): each ring's codes
    (k, 2(T − 1)) less their :func:`own_codes` ``guess``, mod 256, range-coded in one context
    (:func:`~geoterrain.bounds.gapcoder.encode_gaps`; mostly zeros: an edge midpoint at level 0 is a
    leaf, its δ its own error but where the next tile's cell holds nodata, or a geographic store's
    curvilinear term raises it). :func:`ring_codes_own` inverts one.

    Examples
    --------
    >>> c = np.array([[5, 7, 0, 255]], np.uint8); g = np.array([[5, 6, 1, 255]], np.uint8)
    >>> ring_codes_own(ring_payloads_own(c, g)[0], g[0]).tolist()
    [5, 7, 0, 255]
    """
    g = np.asarray(guess, np.int64)
    d = (np.asarray(rings, np.int64) - g) & 0xFF
    return [bytes([guess_check(g[n])]) + p
            for n, p in enumerate(encode_gaps_rows(d, np.zeros_like(d)))]


def ring_codes_own(payload: bytes, guess: np.ndarray) -> np.ndarray:
    """A ring's codes from its :func:`ring_payloads_own` payload and its guess."""
    g = np.asarray(guess, np.int64)
    if len(payload) < 1 or payload[0] != guess_check(g):
        raise ValueError("a guessed bounds payload coded against other heights")
    dec = GapDecoder(payload[1:])
    out = ((dec.take(np.zeros(len(g), np.int64)) + g) & 0xFF).astype(np.uint8)
    dec.check()
    return out
