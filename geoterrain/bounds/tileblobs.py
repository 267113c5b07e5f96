"""Every stored tile's δ, r and normal-map blobs, built level by level on whole arrays.

The per-vertex bounds are coded once at full resolution (the codes are elementwise:
:func:`geoterrain.bounds.log8codes.log8_codes` for δ; for r nested log8 codes,
:func:`radius_codes`, or rounded-up float16), then one
compiled pass per pyramid level gathers each stored tile's payload (only the vertices
new at the level, as :func:`geoterrain.bounds.vertexdata.pack_bounds_v2` stores them; the
normals as planar 2-D differences, :func:`geoterrain.bounds.normalbytes.normals_to_bytes`) and
the per-tile maxima of the stored δ and r. zstd then compresses every payload of the
level in one call on every core. The blobs are byte-identical to packing each tile
with the per-tile functions (tested).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import grid_order
from geoterrain.bounds.leafbounds import CentreHeights, centre_guess, mids_residuals
from geoterrain.bounds.log8codes import (
    LOG_STEPS,
    log8_exponent,
    log8_table,
    mids_index,
    new_mask,
    pred_residuals,
    ring_new_index,
)
from geoterrain.bounds.normalbytes import residual_planes, ring_index, ring_planes
from geoterrain.bounds.normals import RingCodes
from geoterrain.bounds.ownguess import (
    edge_own_codes,
    edge_payload_own,
    own_codes,
    pred_payloads_own,
    ring_payloads_own,
    top_edge_payload_own,
    top_payload_own,
)
from geoterrain.bounds.radii import (
    _proxy_positions,
    _radii_nb,
    _walk_up,
    code_lut_nb,
    prefix_codes,
    valid_range,
)
from geoterrain.bounds.vertexdata import (
    CENTRES,
    DIFF,
    LOG8,
    MIDS,
    NEW_ONLY,
    PRED,
    RING,
    SHAPED_ZSTD_LEVEL,
    SLACK,
    VERSION_2,
    scale_exponent,
    shape_codes,
)
from geoterrain.core.rounding import round_up
from geoterrain.core.threads import cores_for, parallel_kernel
from geoterrain.core.zstdsafe import compress_many

__all__ = ["BoundsCoding", "OwnHeights", "level_blobs", "compress_rows", "radius_codes"]

# δ, r and normals: zstd level 19 saves 3 % at many times the time (docs/lab/store-size.md)
_ZSTD_LEVEL = 3
# zstd level of the δ and r blobs of a whole tile (the top level's: one a store) and of
# the δ_edge DIFF blobs (the tiles along the data's edge, O(perimeter)): 11 % fewer bytes
# than level 3 (srtm1_japan's δ_edge 6 501 → 5 551 B, 19: 5 519), about 0.4 ms CPU a
# tile more (19: 0.75 ms; docs/lab/store-size.md). Any zstd decoder reads every level.
EDGE_ZSTD_LEVEL = 15


class CodedBounds(NamedTuple):
    """A :class:`BoundsCoding`'s codes as :func:`_level_payloads` reads them: δ's log8
    codes ``dc`` and their table ``t8``; r as float16 bit patterns ``r16`` (times ``up``:
    the stored value) or, when ``rc`` is not empty, as log8 codes ``rc`` with table
    ``rt``."""

    dc: np.ndarray
    r16: np.ndarray
    t8: np.ndarray
    up: float
    rc: np.ndarray
    rt: np.ndarray


class LevelPayloads(NamedTuple):
    """What :func:`_level_payloads` writes, a row per tile: the δ codes ``pd``, the r
    bytes ``pr``, the normal planes ``pn``, and the maxima ``dmax``, ``rmax`` of the
    stored δ and r."""

    pd: np.ndarray
    pr: np.ndarray
    pn: np.ndarray
    dmax: np.ndarray
    rmax: np.ndarray


class OwnHeights(NamedTuple):
    """The scene heights δ's blobs are guessed from (schema 20,
    :func:`geoterrain.bounds.ownguess.own_codes`), indexed as the codes of a
    :class:`BoundsCoding` are: ``z`` (float64), ``valid`` (None: all valid, the stand-in
    already in place) and the store's ``stand_in`` height for invalid samples."""

    z: np.ndarray
    valid: np.ndarray | None
    stand_in: float


class EdgeGuess(NamedTuple):
    """Where the data ends for a δ_edge guessed from the heights (schema 23,
    :func:`geoterrain.bounds.ownguess.edge_own_codes`): the indices of
    :class:`OwnHeights` below ``rows`` and ``cols`` hold data; ``pred``: the level is
    above 0 (its payloads predicted from the parents')."""

    rows: int
    cols: int
    pred: bool


class BoundsCoding:
    """δ and r of a whole pyramid, coded once at full resolution.

    ``dc``: δ's 8-bit log codes; ``r16``: r scaled by ``2^-kr`` and rounded up to
    float16. ``d_stored`` and ``r_stored`` (computed on demand): the float32 values a
    reader decodes; the per-tile maxima in the tile rows are maxima of these, so a tile
    skipped by them skips no stored vertex.

    Examples
    --------
    >>> c = BoundsCoding(np.array([[0.0, 1.5], [2.0, np.inf]]), np.ones((2, 2)))
    >>> bool((c.d_stored >= [[0.0, 1.5], [2.0, np.inf]]).all()), c.r16.dtype.name
    (True, 'float16')
    """

    def __init__(self, delta: np.ndarray, radius: np.ndarray | None, ed: int | None = None,
                 r_codes: tuple[np.ndarray, int] | None = None) -> None:
        # ed: δ's code exponent (default: the smallest that covers its largest finite
        # value); a given one must cover it too (a larger one steps more coarsely).
        # r_codes: (codes, e) of :func:`radius_codes`: r stored as nested log8 codes,
        # and ``radius`` (float16 otherwise) is not coded (None allowed)
        self.ed = log8_exponent(delta) if ed is None else int(ed)
        self.rc = None if r_codes is None else np.ascontiguousarray(r_codes[0], np.uint8)
        self.er = None if r_codes is None else int(r_codes[1])
        if radius is None and r_codes is None:
            raise ValueError("r needs its radii or its codes")
        code_r = r_codes is None
        self.kr = scale_exponent(radius) if code_r else 0
        t8 = log8_table(self.ed)
        shape = np.shape(delta)
        self.table = t8
        self.dc = np.empty(shape, np.uint8)
        bits = np.empty(shape if code_r else (0, 0), np.uint16)
        d2 = np.asarray(delta).reshape(-1, shape[-1])
        r2 = np.asarray(radius).reshape(d2.shape) if code_r else np.empty((0, 0), np.float32)
        with cores_for(d2.size):  # small grids on one thread (geoterrain/core/threads.py)
            if not code_r and d2.dtype == np.float32:  # δ alone, as the pipeline codes it
                d2 = np.ascontiguousarray(d2)
                t64 = t8.astype(np.float64)
                _code_delta32(d2, d2.view(np.uint32), t64, prefix_codes(t64),
                              self.dc.reshape(d2.shape))
                odd = 0
            else:
                odd = _code_bounds(d2, r2, t8.astype(np.float64), self.ed, 2.0 ** -self.kr,
                                   self.dc.reshape(d2.shape), bits.reshape(r2.shape))
        self.r16 = bits.view(np.float16)
        if odd:  # NaN, negative or -0.0 radii (none in practice): numpy's exact rule
            m = ~(np.asarray(radius) > 0) & ~(np.asarray(radius) == 0) | np.signbit(radius)
            r = np.asarray(radius, np.float64)[m] * 2.0 ** -self.kr
            self.r16[m] = round_up(r, np.float16)

    @classmethod
    def of_codes(cls, dc: np.ndarray, ed: int, rc: np.ndarray, er: int) -> BoundsCoding:
        """The coding whose δ codes are ``dc`` (table ``2^ed``) and r's ``rc`` (``2^er``),
        uint8, taken as they are: what ``BoundsCoding(log8_table(ed)[dc], None, ed,
        r_codes=(rc, er))`` codes them to (each table strictly increasing, a value's code
        the first entry ≥ it), without coding the values again.

        Examples
        --------
        >>> dc = np.array([[0, 3], [254, 255]], np.uint8); rc = np.array([[1, 2], [3, 4]], np.uint8)
        >>> a = BoundsCoding.of_codes(dc, -4, rc, 2)
        >>> b = BoundsCoding(log8_table(-4)[dc].astype(np.float64), None, -4, r_codes=(rc, 2))
        >>> np.array_equal(a.dc, b.dc), np.array_equal(a.rc, b.rc), a.r16.shape == b.r16.shape
        (True, True, True)
        """
        self = cls.__new__(cls)
        self.ed, self.er, self.kr = int(ed), int(er), 0
        self.rc = np.ascontiguousarray(rc, np.uint8)
        self.table = log8_table(self.ed)
        self.dc = np.ascontiguousarray(dc, np.uint8)
        self.r16 = np.empty((0, 0), np.uint16).view(np.float16)
        return self

    def codes(self) -> CodedBounds:
        """The codes as :class:`CodedBounds`."""
        rlog = self.rc is not None
        return CodedBounds(self.dc, self.r16.view(np.uint16), self.table, 2.0 ** self.kr,
                           self.rc if rlog else np.empty((0, 0), np.uint8),
                           log8_table(self.er) if rlog else np.empty(0, np.float32))

    @property
    def d_stored(self) -> np.ndarray:
        return self.table[self.dc]

    @property
    def r_stored(self) -> np.ndarray:
        if self.rc is not None:
            return log8_table(self.er)[self.rc]
        return round_up(self.r16.astype(np.float64) * 2.0 ** self.kr, np.float32)


@njit(cache=True, nogil=True, inline="always")
def _first_ge(table, x, c):
    """The first index i with table[i] >= x (numpy's searchsorted, side="left"), walked
    from the guess ``c`` (the table is increasing and ends with +inf ≥ x)."""
    c = min(max(c, 0), table.shape[0] - 1)
    while c > 0 and table[c - 1] >= x:
        c -= 1
    while table[c] < x:
        c += 1
    return c


@njit(cache=True, nogil=True, inline="always")
def _f16_up_bits(x, bits):
    """The bit pattern of the smallest float16 ≥ x (x ≥ +0.0 or +inf; ``bits``: x's
    float64 bit pattern): float16 patterns of non-negative values increase with the
    value, so rounding the mantissa up may carry into the next binade (and past 65504
    onto +inf, 0x7C00)."""
    if x > 65504.0:
        return 0x7C00
    if x < 2.0 ** -14:  # subnormal float16: multiples of 2^-24 (exact scaling)
        return int(math.ceil(x * 2.0 ** 24))
    e = ((bits >> 52) & 0x7FF) - 1023  # x in [2^e, 2^(e+1)), e in [-14, 15]
    b = ((e + 15) << 10) | ((bits >> 42) & 0x3FF)
    if bits & ((1 << 42) - 1):
        b += 1
    return b


@njit(cache=True, nogil=True, inline="always")
def _f16_value(b):
    """The value of any float16 bit pattern, as float64 (exact)."""
    e, m = (b >> 10) & 0x1F, b & 0x3FF
    if e == 31:
        v = np.inf if m == 0 else np.nan
    elif e == 0:
        v = m * 2.0 ** -24
    else:
        v = (m + 1024) * 2.0 ** (e - 25)
    return -v if b & 0x8000 else v


def radius_codes(x: np.ndarray, y: np.ndarray, z: np.ndarray, valid: np.ndarray,
                 radius: np.ndarray | None = None, span: int | None = None
                 ) -> tuple[np.ndarray, int]:
    """Nested radii as 8-bit log codes rounded up, the nesting re-established on the
    coded values: ``(codes, e)``, with table[code(v)] ≥ r(v) and ≥ |p_v − p_c| +
    table[code(c)] on every DAG edge (seed 002 §2.4, L50–52), positions as
    :func:`geoterrain.bounds.radii.vertex_radii` takes them (invalid ones by its proxies).
    ``radius`` None: the nesting alone, from leaves of radius 0 (what
    :func:`~geoterrain.bounds.radii.vertex_radii` computes, without its float32 roundings:
    the codes are ≥ its radii all the same); given (radii raised beyond the nesting, as
    :func:`geoterrain.bounds.curvature.metric_bounds` raises them), each code also covers them.

    Each vertex's rounding (< 4.4 %) passes to its parents, but damped: a child's sphere
    is a fraction of its parent's. ``e`` leaves two octaves above the largest radius for
    that growth, and doubles its headroom in the rare case a code still overflows.
    ``span``: a root grid's root side, the arrays its extent (None: the square).

    Examples
    --------
    >>> from geoterrain.bounds.radii import vertex_radii
    >>> I, J = np.indices((5, 5)).astype(float)
    >>> ok = np.ones((5, 5), bool)
    >>> r = vertex_radii(J, -I, np.zeros((5, 5)), ok)
    >>> codes, e = radius_codes(J, -I, np.zeros((5, 5)), ok, r)
    >>> v = log8_table(e)[codes]
    >>> bool((v >= r).all()), bool(v[2, 2] >= 2 ** 0.5 + v[1, 1])
    (True, True)
    """
    xp, yp, zp = _proxy_positions(x, y, z, valid)
    n = grid_order(zp.shape[0] if span is None else span + 1)
    codes = np.empty(zp.shape, np.uint8)
    if radius is None:  # the largest radius is at most the root's: the grid's diagonal
        r = np.empty((0, 0), np.float32)
        span = [np.nanmax(c) - np.nanmin(c) for c in (xp[[0, -1]][:, [0, -1]],
                                                      yp[[0, -1]][:, [0, -1]])]
        # zp's range is the valid heights' (its stand-ins lie inside it): one compiled
        # pass on both cores, not numpy's nanmax and nanmin
        lo, hi, nz = valid_range(z, valid)
        peak = float(np.hypot(*span) + (hi if nz else 0.0) - (lo if nz else 0.0))
        e = log8_exponent(np.array([peak])) + 2
    else:
        r = np.ascontiguousarray(radius, np.float32)
        e = log8_exponent(r) + 2
    e = min(e, 127)  # the blob header's int8 (a larger one would wrap to a tiny scale)
    while True:
        table = log8_table(e).astype(np.float64)
        with cores_for(codes.size):
            _radii_nb(xp, yp, zp, r, table, prefix_codes(table), codes, n)
        if not (codes == 255).any() or e >= 127:
            return codes, e
        e = min(e + 4, 127)


@parallel_kernel(cache=True, nogil=True)
def _code_delta32(delta, bits, t8, lut, dc):
    """float32 δ's log8 codes (:func:`log8_codes`: the first ``t8`` entry ≥ the value,
    NaN as +inf), rows on every core: the code of the value's 16-bit prefix
    (:func:`geoterrain.bounds.radii.prefix_codes`, ``lut``; ``bits`` is ``delta``'s bit
    patterns) walked up to the first entry ≥ the value (a step at most); the same codes
    as :func:`_code_bounds`, in a table look-up and a compare or two a sample."""
    for i in prange(delta.shape[0]):
        for j in range(delta.shape[1]):
            x = np.float64(delta[i, j])
            if x != x:  # NaN as +inf: the first +inf entry (a large e has several)
                dc[i, j] = code_lut_nb(t8, lut, np.inf)
            else:
                dc[i, j] = _walk_up(t8, np.int64(lut[bits[i, j] >> 16]), x)


@parallel_kernel(cache=True, nogil=True)
def _code_bounds(delta, radius, t8, e8, down, dc, r16):
    """One pass (rows on every core): δ's log8 codes (:func:`log8_codes`: NaN as +inf);
    r scaled by ``down`` and rounded up to float16 (bit patterns). Returns the count of
    radii that are NaN, negative or -0.0, left for numpy."""
    odd = 0
    lo8 = t8[1]
    for i in prange(delta.shape[0]):
        buf = np.empty(1, np.float64)
        ibuf = buf.view(np.int64)  # float64 bit patterns (exponent and mantissa)
        for j in range(delta.shape[1]):
            x = np.float64(delta[i, j])
            if x != x:
                x = np.inf
            if x <= lo8:
                g = 0
            elif x == np.inf:
                g = 255
            else:  # log2(x) ≈ exponent + mantissa fraction (within 0.09)
                buf[0] = x
                b = ibuf[0]
                f = ((b >> 52) & 0x7FF) - 1023 + (b & ((1 << 52) - 1)) * 2.0 ** -52
                g = int(LOG_STEPS * (f - e8)) + 1
            c = _first_ge(t8, x, g)  # the guess is off by at most two codes
            dc[i, j] = c
            if radius.shape[0] == 0:  # r coded elsewhere (radius_codes)
                continue
            r = np.float64(radius[i, j])
            if r > 0 or (r == 0 and math.copysign(1.0, r) > 0):
                buf[0] = r * down
                b = _f16_up_bits(buf[0], ibuf[0])
                r16[i, j] = b
            else:
                odd += 1
    return odd


@parallel_kernel(cache=True, nogil=True)
def _level_payloads(codes, nrm, ys, xs, t, level, new_only, out):
    """Row k of ``out.pd``/``pr``/``pn`` (:class:`LevelPayloads`): tile (level, xs[k],
    ys[k])'s δ codes, r float16 planes (low bytes, then high bytes) and normal planes of
    2-D differences (mod 256); ``dmax``/``rmax``: the maxima of the stored δ and r over
    the same vertices, the values a reader decodes: ``t8[code]`` and the float16 times
    ``up`` (exact in float32: 11 bits, exponent in range); NaN propagates as numpy's max
    does. With r's log8 codes ``rc`` (``rt`` their table; empty when r is float16; all
    in ``codes``: :class:`CodedBounds`), ``pr`` holds the codes, one byte each."""
    dc, r16, t8, up, rc, rt = codes
    # the outputs bound one by one, outside the parallel loop: numba's parfors see a
    # write through an array unpacked from a tuple as dead
    pd = out.pd
    pr = out.pr
    pn = out.pn
    dmax = out.dmax
    rmax = out.rmax
    rlog = rc.shape[0] > 0
    T = (1 << t) + 1
    s = 1 << level
    step = (1 << t) * s
    nnew = pd.shape[1]
    for k in prange(ys.shape[0]):  # tiles on every core: each writes its own rows
        y0, x0 = ys[k] * step, xs[k] * step
        m = 0
        dm = np.float32(-np.inf)
        rm = np.float32(-np.inf)
        dnan = False
        rnan = False
        for i in range(T):
            yi = y0 + i * s
            for j in range(T):
                if new_only and (i & 1) == 0 and (j & 1) == 0:
                    continue
                xj = x0 + j * s
                pd[k, m] = dc[yi, xj]
                if rlog:
                    pr[k, m] = rc[yi, xj]
                    rv = rt[rc[yi, xj]]
                else:
                    b = r16[yi, xj]
                    pr[k, m] = np.uint8(b & 0xFF)
                    pr[k, nnew + m] = np.uint8(b >> 8)
                    rv = np.float32(_f16_value(b) * up)
                dv = t8[dc[yi, xj]]
                if dv != dv:
                    dnan = True
                elif dv > dm:
                    dm = dv
                if rv != rv:
                    rnan = True
                elif rv > rm:
                    rm = rv
                m += 1
        dmax[k] = np.float32(np.nan) if dnan else dm
        rmax[k] = np.float32(np.nan) if rnan else rm
        # normals: the level's own map, tile window at (ys[k] 2^t, xs[k] 2^t); none
        # when ``pn`` has no columns (the normals' blobs not asked for)
        ny0, nx0 = ys[k] * (1 << t), xs[k] * (1 << t)
        for c in range(2 if pn.shape[1] > 0 else 0):
            base = c * T * T
            for i in range(T):
                for j in range(T):
                    v = np.int32(nrm[ny0 + i, nx0 + j, c])
                    if i > 0:
                        v -= np.int32(nrm[ny0 + i - 1, nx0 + j, c])
                    if j > 0:
                        v -= np.int32(nrm[ny0 + i, nx0 + j - 1, c])
                        if i > 0:
                            v += np.int32(nrm[ny0 + i - 1, nx0 + j - 1, c])
                    pn[k, base + i * T + j] = np.uint8(v & 0xFF)


def compress_rows(rows: np.ndarray | list[np.ndarray], prefix: bytes | list[bytes] = b"",
                  level: int = _ZSTD_LEVEL) -> list[bytes]:
    """``prefix + zstd(row)`` of every row of a 2-D uint8 array (or a list of uint8 rows),
    in one call on every core (``prefix`` may be one per row); frames without their magic
    number, as :func:`geoterrain.core.zstdsafe.compress_many` writes them.

    Examples
    --------
    >>> rows = np.arange(12, dtype=np.uint8).reshape(3, 4)
    >>> from geoterrain.core.zstdsafe import decompress
    >>> [decompress(b[1:], 4) == r.tobytes() for b, r in zip(compress_rows(rows, b"v"), rows)]
    [True, True, True]
    """
    if not isinstance(rows, list):  # a list: rows of different lengths
        rows = np.ascontiguousarray(rows, np.uint8)
    heads = [prefix] * len(rows) if isinstance(prefix, bytes) else list(prefix)
    return [h + f for h, f in zip(heads, compress_many([r.tobytes() for r in rows], level),
                                  strict=True)]


def level_blobs(coding: BoundsCoding, nrm: np.ndarray, t: int, level: int, top_level: int,
                tiles: Iterable[tuple[int, int]], kinds=("delta", "radius", "normals"),
                ring: bool | tuple[str, ...] = False, base: BoundsCoding | None = None,
                slack: dict | None = None, mids: bool = False,
                centres: CentreHeights | None = None, heights: CentreHeights | None = None,
                own: OwnHeights | None = None, zlevel: int = SHAPED_ZSTD_LEVEL,
                edge: EdgeGuess | None = None
                ) -> tuple[dict, np.ndarray, np.ndarray]:
    """The δ, r and normals blobs of the stored tiles ``(x, y)`` of one level.

    ``nrm`` is the level's octahedral normal map (n, n, 2) uint8. Returns
    ``({"delta": {...}, "radius": {...}, "normals": {...}}, dmax, rmax)`` with blobs
    keyed ``(level, x, y)`` and the per-tile maxima in the order of ``tiles``; only the
    ``kinds`` asked for are compressed. ``ring`` (level 0 below the top): the δ and r
    blobs hold only the border's new vertices (flag ``RING``; a reader derives the rest,
    :mod:`geoterrain.bounds.leafbounds`); the maxima still cover every new vertex. ``base``
    (a δ_edge's δ, coded with the same table): the δ blobs hold each code's difference
    from ``base``'s mod 256 (flag ``DIFF``); the maxima are still of ``coding``'s values.
    ``ring`` may name the kinds instead (``("delta",)``: a geographic store's, whose r is
    stored whole); ``slack`` maps a tile's key to its ring δ's slack (flag ``SLACK``,
    :func:`geoterrain.bounds.leafbounds.geographic_leaf_delta`; none where it is 0).
    ``mids`` (a projected or pixel store's r above level 0, log8 codes nested from leaves
    of radius 0, ``radius_codes(..., radius=None)``): the r blobs leave out the cell
    centres (flag ``MIDS``); a reader derives them from the tile's heights
    (:func:`geoterrain.bounds.leafbounds.centre_radius`). Every other new-vertices log8 δ
    and r blob (neither ``RING``, ``DIFF``, ``MIDS`` nor ``CENTRES``) holds its codes as
    differences from its parents' codes (flag ``PRED``,
    :func:`geoterrain.bounds.log8codes.pred_residuals`). ``centres`` (level 0 of a
    geographic store: the level's heights, the stand-in height and the tiles' boxes):
    an r blob of ``CENTRES`` shape holds its centres as differences from their guess
    from the heights (flags ``CENTRES`` and ``PRED``,
    :func:`geoterrain.bounds.leafbounds.centre_guess`). ``heights`` (a geographic store's
    level above 0 and below the top: the level's heights, in the lattice the tiles are
    indexed in, and their boxes): every ``PRED`` r blob holds its new vertices as
    differences from their guesses from the heights instead (flags ``MIDS`` and ``PRED``,
    :func:`geoterrain.bounds.leafbounds.mids_residuals`; schema 20). ``own`` (schema 20:
    the level's heights, :class:`OwnHeights`): a ``RING`` δ blob holds its codes as
    differences from the codes of their own errors (flag ``PRED`` too,
    :func:`geoterrain.bounds.ownguess.ring_payloads_own`), and a ``PRED`` δ blob its
    differences in the contexts of their gaps above those (flag ``SLACK`` too,
    :func:`geoterrain.bounds.ownguess.pred_payloads_own`; both range-coded, no zstd);
    a whole tile's δ (the top level's, schema 23) its codes level by level inside the
    tile the same way (flags ``PRED`` and ``SLACK`` without ``NEW_ONLY``,
    :func:`geoterrain.bounds.ownguess.top_payload_own`).
    ``zlevel``: the zstd level of the ``CENTRES``, ``PRED`` and ``RING`` payloads
    (:func:`geoterrain.bounds.vertexdata.shaped_zstd_level` of the store's grid).
    ``edge`` (a δ_edge below the top, with ``base`` and ``own``: :class:`EdgeGuess`):
    each ``DIFF`` blob whose δ_edge equals δ wherever δ is finite holds its codes where
    δ is +inf against their guess from the tile's heights with the padding replicated
    (flag ``PRED`` too, and ``SLACK`` above level 0;
    :func:`geoterrain.bounds.ownguess.edge_own_codes`,
    :func:`~geoterrain.bounds.ownguess.edge_payload_own`; schema 23).

    Examples
    --------
    >>> c = BoundsCoding(np.ones((5, 5)), np.ones((5, 5)))
    >>> nrm = np.zeros((5, 5, 2), np.uint8)
    >>> blobs, dmax, rmax = level_blobs(c, nrm, 2, 0, 0, [(0, 0)])
    >>> sorted(blobs), float(dmax[0]), float(rmax[0])
    (['delta', 'normals', 'radius'], 1.0, 1.0)
    """
    xy = np.asarray(list(tiles), np.int64).reshape(-1, 2)
    T = (1 << t) + 1
    new_only = level < top_level
    nnew = T * T - (((T + 1) // 2) ** 2 if new_only else 0)
    k = len(xy)
    pd = np.empty((k, nnew), np.uint8)
    rlog = coding.rc is not None
    pr = np.empty((k, nnew if rlog else 2 * nnew), np.uint8)
    pn = np.empty((k, 2 * T * T if "normals" in kinds else 0), np.uint8)
    dmax = np.empty(k, np.float32)
    rmax = np.empty(k, np.float32)
    with cores_for(coding.dc.size):
        _level_payloads(coding.codes(), np.ascontiguousarray(nrm, np.uint8),
                        np.ascontiguousarray(xy[:, 1]), np.ascontiguousarray(xy[:, 0]), t,
                        level, new_only, LevelPayloads(pd, pr, pn, dmax, rmax))
    flags = NEW_ONLY if new_only else 0
    if base is not None:
        if base.ed != coding.ed or ring:
            raise ValueError("a difference δ blob needs one code table and no ring")
        s = 1 << level
        ii, jj = np.nonzero(new_mask(T) if new_only else np.ones((T, T), bool))
        rows = (xy[:, 1, None] << (t + level)) + ii[None] * s
        cols = (xy[:, 0, None] << (t + level)) + jj[None] * s
        pd = pd - base.dc[rows, cols]  # uint8: wraps mod 256, exactly invertible
        flags |= DIFF
    ring_kinds = ("delta", "radius") if ring is True else tuple(ring or ())
    flags_d, flags_r = flags, flags & ~DIFF
    if ring_kinds:
        if level != 0 or not new_only or T < 3 or base is not None:
            raise ValueError("ring bounds blobs are for level 0 below the top level")
        rr, rc = ring_new_index(T)
        pos = np.searchsorted(np.flatnonzero(new_mask(T)), rr * T + rc)
        if "delta" in ring_kinds:
            pd = pd[:, pos]
            flags_d |= RING
            if own is not None and k:  # schema 20: - the own errors' codes, range-coded
                g = own_codes(own.z, own.valid, own.stand_in, coding.ed,
                              _origins(xy, t, level), T, 1 << level, ring=True)
                pd = ring_payloads_own(pd, g[:, rr, rc])
                flags_d |= PRED
        if "radius" in ring_kinds:
            pr = pr[:, pos] if rlog else np.concatenate([pr[:, pos], pr[:, nnew + pos]], axis=1)
            flags_r |= RING
    head_d = bytes([VERSION_2, flags_d | LOG8, int(coding.ed) & 0xFF])
    head_r = bytes([VERSION_2, flags_r | (LOG8 if rlog else 0),
                    int(coding.er if rlog else coding.kr) & 0xFF])
    keys = [(level, int(x), int(y)) for x, y in xy]
    if slack:  # a tile with a slack: the flag, then the float32 after the exponent
        if not flags_d & RING:
            raise ValueError("a slack is for a ring δ blob")
        head_d = [head_d if s <= 0 else bytes([head_d[0], head_d[1] | SLACK, head_d[2]])
                  + np.float32(s).astype("<f4").tobytes()
                  for s in (float(slack.get(k, 0.0)) for k in keys)]
    if edge is not None and k:  # schema 23: a δ_edge guessed from the heights
        if base is None or own is None or T < 3:
            raise ValueError("a guessed δ_edge blob is a difference from δ")
        pd, head_d = _edge_guessed(pd, head_d, coding, base, own, xy, t, level, edge,
                                   new_only)
    # schema 6's CENTRES (vertexdata.shape_codes): a tile whose new vertices off the cell
    # centres all have code 0 (a geographic level-0 r: leaves) stores the centres only
    # (schema 14's PRED on every other such tile: codes as differences from their parents')
    if new_only and k and T >= 3 and "delta" in kinds and not flags_d & (RING | DIFF):
        W = _windows(coding.dc, xy, t, level)
        pd, head_d = _shaped(pd, head_d, W)
        if own is not None:  # schema 20: the PRED payloads in their own-error gaps' order
            pd, head_d = _own_ordered(pd, head_d, W, own, xy, t, level, int(coding.ed))
    elif not new_only and k and T >= 3 and "delta" in kinds and own is not None \
            and base is None and not flags_d & RING:
        # schema 23: a whole (top) tile's δ level by level inside it, each level's new
        # vertices in their own-error gaps (ownguess.top_payload_own; bytes: no zstd)
        W = _windows(coding.dc, xy, t, level)
        e = int(coding.ed)
        pd = [top_payload_own(W[n], lambda s, o=o: own_codes(
            own.z, own.valid, own.stand_in, e, o[None], (T - 1) // s + 1, s << level)[0])
            for n, o in enumerate(_origins(xy, t, level))]
        head_d = bytes([head_d[0], head_d[1] | PRED | SLACK, head_d[2]])
    if mids:  # schema 12's MIDS: the cell centres derived on read
        if not rlog or flags_r & RING or T < 3:
            raise ValueError("mids r blobs are log8 codes above level 0")
        keep = mids_index(T, new_only)
        pos = np.searchsorted(np.flatnonzero(new_mask(T)), keep) if new_only else keep
        pr = pr[:, pos]
        head_r = bytes([head_r[0], head_r[1] | MIDS, head_r[2]])
    elif new_only and k and T >= 3 and rlog and "radius" in kinds and not flags_r & RING:
        win = _windows(coding.rc, xy, t, level)
        pr, head_r = _shaped(pr, head_r, win)
        if centres is not None:
            pr, head_r = _guessed(pr, head_r, centres, xy, t, level, int(coding.er))
        if heights is not None:
            pr, head_r = _mids_guessed(pr, head_r, heights, xy, t, int(coding.er), win)
    elif centres is not None or heights is not None:
        raise ValueError("guessed r vertices are for r in log8 codes below the top, not a "
                         "ring")
    rows = {"delta": (pd, head_d), "radius": (pr, head_r), "normals": (pn, b"")}
    blobs = {kind: dict(zip(keys, _compress_shaped(*rows[kind], zlevel), strict=True))
             for kind in kinds}
    return blobs, dmax, rmax


def _compress_shaped(rows: np.ndarray | list[np.ndarray | bytes], heads: bytes | list[bytes],
                     zlevel: int = SHAPED_ZSTD_LEVEL) -> list[bytes]:
    # compress_rows, with the CENTRES, PRED and RING payloads at zlevel
    # (vertexdata.shaped_zstd_level; pack_bounds_v2 writes the first two at 11), a whole
    # tile's (the top's) and a DIFF one (δ_edge) at EDGE_ZSTD_LEVEL; a row of
    # bytes is a payload already coded (schema 20's range-coded δ), stored as it is
    if isinstance(heads, bytes):
        heads = [heads] * len(rows)
    if any(isinstance(r, bytes) for r in rows):
        out = [heads[n] + r if isinstance(r, bytes) else None for n, r in enumerate(rows)]
        rest = [n for n, b in enumerate(out) if b is None]
        if rest:
            for n, b in zip(rest, _compress_shaped([rows[n] for n in rest],
                                                   [heads[n] for n in rest], zlevel),
                            strict=True):
                out[n] = b
        return out
    hi = [n for n, h in enumerate(heads) if len(h) > 1 and h[1] & (CENTRES | PRED | RING)]
    top = [n for n, h in enumerate(heads) if len(h) > 1 and not h[1] & (CENTRES | PRED | RING)
           and (h[1] & DIFF or not h[1] & NEW_ONLY)]
    if not hi and not top:
        return compress_rows(rows, heads)
    lo = sorted(set(range(len(heads))) - set(hi) - set(top))
    out = [b""] * len(heads)
    for idx, level in ((hi, zlevel), (top, EDGE_ZSTD_LEVEL), (lo, _ZSTD_LEVEL)):
        if idx:
            got = compress_rows([rows[n] for n in idx], [heads[n] for n in idx], level)
            for n, b in zip(idx, got, strict=True):
                out[n] = b
    return out


def _origins(xy: np.ndarray, t: int, level: int) -> np.ndarray:
    # each tile's first sample (row, column) in the code grid
    return np.stack([xy[:, 1] << (t + level), xy[:, 0] << (t + level)], axis=1)


def _own_ordered(rows: list[np.ndarray], heads: list[bytes], W: np.ndarray, own: OwnHeights,
                 xy: np.ndarray, t: int, level: int, e: int
                 ) -> tuple[list[np.ndarray], list[bytes]]:
    # schema 20: each PRED δ payload (not CENTRES) range-coded in the contexts of its
    # vertices' gaps between the parents' prediction and their own errors' codes (bytes:
    # no zstd), flagged SLACK too
    idx = [n for n, h in enumerate(heads) if h[1] & PRED and not h[1] & CENTRES]
    if not idx:
        return rows, heads
    T = W.shape[1]
    lo = own_codes(own.z, own.valid, own.stand_in, e, _origins(xy[idx], t, level), T,
                   1 << level)
    got = pred_payloads_own(W[idx], lo)
    rows, heads = list(rows), list(heads)
    for q, n in enumerate(idx):
        rows[n] = got[q]
        heads[n] = bytes([heads[n][0], heads[n][1] | SLACK, *heads[n][2:]])
    return rows, heads


def _edge_guessed(pd: np.ndarray, head: bytes, coding: BoundsCoding, base: BoundsCoding,
                  own: OwnHeights, xy: np.ndarray, t: int, level: int, edge: EdgeGuess,
                  new_only: bool) -> tuple[list, list[bytes]]:
    # schema 23: each DIFF δ_edge payload whose codes equal δ's wherever δ is finite as
    # its codes where δ is +inf against their guess (ownguess.edge_own_codes of the
    # tile's heights, the padding replicated), range-coded (bytes: no zstd), flagged PRED
    # too (and SLACK above level 0: predicted from the parents; a whole tile, the top's,
    # level by level inside it: ownguess.top_edge_payload_own); the others as they were
    T, s = (1 << t) + 1, 1 << level
    W, D = _windows(coding.dc, xy, t, level), _windows(base.dc, xy, t, level)
    rows, heads = list(pd), []
    flags = PRED | (SLACK if edge.pred or not new_only else 0)
    e = int(coding.ed)
    for n, (r0, c0) in enumerate(_origins(xy, t, level).tolist()):
        win = np.s_[r0:r0 + (T - 1) * s + 1:s, c0:c0 + (T - 1) * s + 1:s]
        z = own.z[win]
        if z.shape != (T, T):
            raise ValueError("a tile's heights past the guessed δ_edge's")
        v = None if own.valid is None else own.valid[win]

        def guess(step: int, z=z, v=v, r0=r0, c0=c0) -> np.ndarray | None:
            sl = np.s_[::step, ::step]
            return edge_own_codes(np.ascontiguousarray(z[sl]), None if v is None else
                                  np.ascontiguousarray(v[sl]), own.stand_in, e,
                                  (edge.rows - 1 - r0) // (s * step) + 1,
                                  (edge.cols - 1 - c0) // (s * step) + 1)
        if new_only:
            g = guess(1)
            p = None if g is None else edge_payload_own(W[n], D[n], g, edge.pred)
        else:
            p = None if guess(T - 1) is None else top_edge_payload_own(W[n], D[n], guess)
        if p is not None:
            rows[n] = p
        heads.append(head if p is None else bytes([head[0], head[1] | flags, *head[2:]]))
    return rows, heads


def _windows(codes: np.ndarray, xy: np.ndarray, t: int, level: int) -> np.ndarray:
    # each tile's (T, T) codes, (k, T, T): tile (x, y) of ``level`` in the code grid
    T, s = (1 << t) + 1, 1 << level
    rows = (xy[:, 1, None] << (t + level)) + np.arange(T)[None] * s
    cols = (xy[:, 0, None] << (t + level)) + np.arange(T)[None] * s
    return codes[rows[:, :, None], cols[:, None, :]]


def _shaped(p: np.ndarray, head: bytes, windows: np.ndarray
            ) -> tuple[list[np.ndarray], list[bytes]]:
    # each tile's payload shaped (vertexdata.shape_codes: CENTRES where every new vertex
    # off the centres is 0), else predicted from its parents' codes (vertexdata.PRED,
    # from the tile's codes ``windows``), and its header with the flag
    rows, flags = shape_codes(p)
    pred = pred_residuals(windows)
    rows = [r if f else pred[n] for n, (r, f) in enumerate(zip(rows, flags, strict=True))]
    return rows, [bytes([head[0], head[1] | (int(f) or PRED), head[2]]) for f in flags]


def _guessed(rows: list[np.ndarray], heads: list[bytes], c: CentreHeights, xy: np.ndarray,
             t: int, level: int, e: int) -> tuple[list[np.ndarray], list[bytes]]:
    # schema 17: each CENTRES r payload as (guess − code) mod 256, the guess from the
    # heights (leafbounds.centre_guess), flagged PRED too
    if level != 0:
        raise ValueError("guessed centres are for level 0")
    idx = [n for n, h in enumerate(heads) if h[1] & CENTRES]
    if not idx:
        return rows, heads
    T = (1 << t) + 1
    origins = np.stack([xy[idx, 1] << t, xy[idx, 0] << t], axis=1)
    g = centre_guess(c._replace(boxes=np.asarray(c.boxes, np.float64)[idx]), origins, T, e)
    rows, heads = list(rows), list(heads)
    for q, n in enumerate(idx):
        rows[n] = g[q].ravel() - np.asarray(rows[n], np.uint8)  # uint8: mod 256
        if not rows[n].any():  # schema 23: every guess exact, no payload (was 14 B)
            rows[n] = b""
        heads[n] = bytes([heads[n][0], heads[n][1] | PRED, *heads[n][2:]])
    return rows, heads


def _mids_guessed(rows: list[np.ndarray], heads: list[bytes], c: CentreHeights,
                  xy: np.ndarray, t: int, e: int, windows: np.ndarray
                  ) -> tuple[list[np.ndarray], list[bytes]]:
    # schema 20: each PRED r payload above level 0 (a geographic store's) as every new
    # vertex's (guess − code) mod 256, the guesses from the level's heights
    # (leafbounds.mids_residuals), flagged MIDS and PRED, a and off after the exponent
    idx = [n for n, h in enumerate(heads) if h[1] & PRED]
    if not idx:
        return rows, heads
    origins = np.stack([xy[idx, 1] << t, xy[idx, 0] << t], axis=1)
    res, a, off = mids_residuals(c._replace(boxes=np.asarray(c.boxes, np.float64)[idx]),
                                 origins, (1 << t) + 1, e, windows[idx])
    rows, heads = list(rows), list(heads)
    for q, n in enumerate(idx):
        rows[n] = res[q]
        heads[n] = bytes([heads[n][0], heads[n][1] | MIDS, heads[n][2], int(a[q]),
                          int(off[q])])
    return rows, heads


def ring_blobs(nrm: np.ndarray | RingCodes, t: int, tiles: Iterable[tuple[int, int]],
               level: int = 0, guess: np.ndarray | None = None,
               zlevel: int = SHAPED_ZSTD_LEVEL) -> dict:
    """Normals blobs of level ``level`` (``nrm``: that level's codes) that hold only each
    tile's border ring (4T − 4 samples, as :func:`geoterrain.bounds.normalbytes.ring_planes`,
    zstd): a reader derives the interior from the tile's own heights
    (:meth:`geoterrain.terrain.Terrain.tile_normal_codes`), as the central differences
    there read no sample outside the tile. ``nrm`` may hold the rings' codes alone
    (:class:`geoterrain.bounds.normals.RingCodes`). ``guess`` (k, 4T − 4, 2): what a reader
    derives there (:func:`geoterrain.bounds.leafbounds.ring_guesses`); each ring is stored as
    its difference from it, mod 256, as two planes without first differences
    (:func:`geoterrain.bounds.normalbytes.residual_planes`), at zstd level ``zlevel``
    (:func:`geoterrain.bounds.vertexdata.shaped_zstd_level` of the store's grid; schema
    17's ``normals_ring_residual``).

    Examples
    --------
    >>> nrm = np.arange(5 * 5 * 2, dtype=np.uint8).reshape(5, 5, 2)
    >>> sorted(ring_blobs(nrm, 2, [(0, 0)]))
    [(0, 0, 0)]
    """
    xy = np.asarray(list(tiles), np.int64).reshape(-1, 2)
    if isinstance(nrm, RingCodes):  # the codes of the rings alone (ring_normal_codes)
        rings = nrm.rings(xy, t)
    else:
        rr, cc = ring_index((1 << t) + 1)
        rings = nrm[(xy[:, 1, None] << t) + rr[None], (xy[:, 0, None] << t) + cc[None]]
    keys = [(level, int(x), int(y)) for x, y in xy]
    if guess is not None:  # uint8: mod 256, exactly invertible; planes at zlevel
        res = np.asarray(rings, np.uint8) - np.asarray(guess, np.uint8)
        return dict(zip(keys, compress_rows(residual_planes(res), level=zlevel),
                        strict=True))
    return dict(zip(keys, compress_rows(ring_planes(rings)), strict=True))
