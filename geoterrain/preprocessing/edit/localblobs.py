"""The δ and r blobs of an edit (:mod:`.localbounds`' codes, coded again): which
blobs the changed codes reach (:func:`blob_reach`), a stored value's code
(:func:`_codes`), the blobs decided the same before coding (``_pred_kept``), and the
rest coded a batch at a time (:func:`_level_blobs_of`). Methods of
:class:`.localbounds.Bounds`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from geoterrain.bounds.log8codes import log8_table  # noqa: F401 (_codes' doctest)
from geoterrain.bounds.ownguess import new_codes_same, own_codes, pred_payload_same
from geoterrain.bounds.tileblobs import BoundsCoding, OwnHeights, level_blobs
from geoterrain.bounds.vertexdata import shaped_zstd_level

__all__ = ["BlobCoding", "blob_reach"]


class BlobCoding:
    """The blob coding of :class:`.localbounds.Bounds` (its window's and coarse vertices'
    old and new codes)."""

    def _code_blobs(self) -> None:
        """The δ and r blobs whose bytes the changed codes can reach, and the rows' largest
        stored δ and r of the tiles whose own vertices changed (:func:`blob_reach`): only
        those tiles are decoded and coded again, each blob only where its payload reads a
        changed code of its kind."""
        g, job = self.g, self.job
        # the vertices whose δ or r code changed, [δ changed, r changed] each: the
        # window's as arrays, then the coarse vertices' (each against its stored code)
        wd, wr = self.dc != self.dc_old, self.rc != self.rc_old
        a, b = np.nonzero(wd | wr)
        ij = np.stack([a + self.oi, b + self.oj], axis=1).astype(np.int64)
        flags = np.stack([wd[a, b], wr[a, b]], axis=1)
        coarse = [(i, j, code != self._old_code(i, j, "delta"),
                   self.coarse_r[(i, j)] != self._old_code(i, j, "radius"))
                  for (i, j), code in self.coarse_d.items()]
        coarse = [c for c in coarse if c[2] or c[3]]
        if coarse:  # a vertex in both keeps its first place, its flags or-ed
            c = np.array(coarse, np.int64).reshape(-1, 4)
            ij = np.concatenate([ij, c[:, :2]])
            flags = np.concatenate([flags, c[:, 2:].astype(bool)])
            _, first, inv = np.unique(ij, axis=0, return_index=True, return_inverse=True)
            inv = inv.reshape(-1)
            merged = np.zeros((len(first), 2), bool)
            np.logical_or.at(merged, inv, flags)
            keep = np.sort(first)
            ij, flags = ij[keep], merged[inv[keep]]
        job.dirty.append(np.concatenate([ij, ij + 1], axis=1))  # one rectangle a vertex
        canvas = self.c
        need = blob_reach(g, ij[:, 0], ij[:, 1], flags[:, 0], flags[:, 1], job.derive_bounds,
                          edited=(canvas.r0, canvas.c0, canvas.r1, canvas.c1))
        # the coarse vertices' new codes, as arrays
        cv = np.array(list(self.coarse_d), np.int64).reshape(-1, 2)
        cd = np.array(list(self.coarse_d.values()), np.uint8)
        cr = np.array([self.coarse_r[k] for k in self.coarse_d], np.uint8)
        T = g.tile_samples
        exact = bool(np.isfinite(self.t8[254]) and np.isfinite(self.rt[254]))
        batches: dict = {}  # (the top, level 0, the blob kinds) → (key, row, d, r, own)
        for key in sorted(need):
            if key not in self.t.tile_info:
                continue
            kinds, row = need[key]
            L, x, y = key
            span, step = g.tile_span(L), 1 << L
            i0, j0 = y * span, x * span
            # a level-0 tile in the window: its codes are there (none decoded again)
            if L == 0 and i0 >= self.oi and i0 + span <= self.i1 and j0 >= self.oj and \
                    j0 + span <= self.j1 and self.known[i0 - self.oi, j0 - self.oj + 1]:
                sl = (slice(i0 - self.oi, i0 + span - self.oi + 1),
                      slice(j0 - self.oj, j0 + span - self.oj + 1))
                d, r = self.dc[sl].copy(), self.rc[sl].copy()
            else:  # the stored codes, the window's where it holds them (slices: its
                # samples on the tile's lattice are a step apart)
                want_d = row or "delta" in kinds
                want_r = row or "radius" in kinds
                d = _codes(self.t8, self.t.tile_delta(*key)) if want_d else \
                    np.zeros((T, T), np.uint8)
                d_old = d.copy()
                r = _codes(self.rt, self.t.tile_radius(*key)) if want_r else \
                    np.zeros((T, T), np.uint8)
                a0, a1 = -(-max(self.oi - i0, 0) // step), min(self.i1 - i0, span) // step + 1
                b0, b1 = -(-max(self.oj - j0, 0) // step), min(self.j1 - j0, span) // step + 1
                if a0 < a1 and b0 < b1:
                    w = (slice(i0 + a0 * step - self.oi, i0 + (a1 - 1) * step - self.oi + 1,
                               step),
                         slice(j0 + b0 * step - self.oj, j0 + (b1 - 1) * step - self.oj + 1,
                               step))
                    kn = self.known[w]
                    d[a0:a1, b0:b1][kn] = self.dc[w][kn]
                    r[a0:a1, b0:b1][kn] = self.rc[w][kn]
            # the coarse vertices' codes (the window holds their old ones)
            di, dj = cv[:, 0] - i0, cv[:, 1] - j0
            on = (di >= 0) & (di <= span) & (dj >= 0) & (dj <= span) & \
                (di % step == 0) & (dj % step == 0)
            d[di[on] // step, dj[on] // step] = cd[on]
            r[di[on] // step, dj[on] // step] = cr[on]
            # schema 20: δ's blob guessed from the own errors on the tile's edited heights
            h, v = canvas.tile_lattice(L, x, y)
            own = OwnHeights(np.where(v, h * canvas.factor, np.nan), v, self.stand_in)
            if 0 < L < g.top_level and "delta" in kinds and self._pred_kept(key, d_old, d, own):
                kinds = tuple(k for k in kinds if k != "delta")  # its bytes stay
                if not kinds and not row:
                    continue
            # coded with the tiles of the same level kind and blob kinds (below)
            batches.setdefault((L == g.top_level, L == 0, kinds), []).append(
                (key, row, d, r, own))
        for (top, zero, kinds), tiles in batches.items():
            blobs, dm, rm = _level_blobs_of(
                tiles, g.t, top, kinds, job.derive_bounds and zero,
                job.derive_bounds and not zero, job.ed, job.er, exact, self.t8, self.rt,
                shaped_zstd_level(g.rows, g.cols))
            for n, (key, row, *_) in enumerate(tiles):
                for kind in kinds:
                    job.put(key, kind, blobs[kind][(0, 2 * n, 0)])
                if row:
                    job.set_row(key, delta_max=float(dm[n]), radius_max=float(rm[n]))

    def _pred_kept(self, key, d_old: np.ndarray, d: np.ndarray, own: OwnHeights) -> bool:
        """Whether a δ blob below the top and above level 0 (schema 20's ``PRED`` with
        ``SLACK``, or ``CENTRES``) keeps its bytes: decided from its inputs before coding
        it (:func:`~geoterrain.bounds.ownguess.pred_payload_same`: the stored codes
        ``d_old`` and own errors of the tile's stored heights against the new ones). An
        edit's reach names such blobs where a corner of a cell changed (its centre's
        prediction may not) or the heights under them (their own errors may not)."""
        if not new_codes_same(d_old, d):  # a new vertex's code moved: so does the payload
            return False
        tl = self.t.tile(*key)
        f, e = self.c.factor, self.job.ed
        lo_old = own_codes(np.where(tl.valid, tl.heights * f, np.nan), tl.valid,
                           self.stand_in, e)[0]
        lo_new = own_codes(own.z, own.valid, self.stand_in, e)[0]
        return pred_payload_same(d_old, lo_old, d, lo_new)


def _level_blobs_of(tiles: list, t: int, top: bool, kinds: tuple, ring: bool, mids: bool,
                    ed: int, er: int, exact: bool, t8: np.ndarray, rt: np.ndarray,
                    zlevel: int) -> tuple[dict, np.ndarray, np.ndarray]:
    """:func:`~geoterrain.bounds.tileblobs.level_blobs` of several tiles of one level
    (``tiles``: (key, row, δ codes, r codes, :class:`OwnHeights`), each (T, T)) in one
    call: tile n laid at tile position (2n, 0) of one grid of codes and heights (a tile
    apart: no sample shared), keyed so (level 0 of the call: ``top`` the level's own top).
    Each blob is a function of its tile's codes and heights alone, so the bytes are one
    call a tile's (tested), for one call's work: its Python, one own-error kernel call,
    one range coder and one zstd call for them all. ``exact``: the codes are
    :meth:`~geoterrain.bounds.tileblobs.BoundsCoding.of_codes`' (each table strictly
    increasing, log8_table, where its top finite code is finite), else the table values'
    coded again."""
    T = (1 << t) + 1
    n = len(tiles)
    shape = (T, (2 * n - 1) * (T - 1) + 1)
    d, r = np.zeros(shape, np.uint8), np.zeros(shape, np.uint8)
    z, v = np.full(shape, np.nan), np.zeros(shape, bool)
    for q, (_, _, dq, rq, own) in enumerate(tiles):
        cols = slice(2 * q * (T - 1), 2 * q * (T - 1) + T)
        d[:, cols], r[:, cols], z[:, cols], v[:, cols] = dq, rq, own.z, own.valid
    coding = BoundsCoding.of_codes(d, ed, r, er) if exact else \
        BoundsCoding(t8[d], None, ed, r_codes=(_codes(rt, rt[r]), er))
    return level_blobs(coding, np.zeros((*shape, 2), np.uint8), t, 0, 0 if top else 1,
                       [(2 * q, 0) for q in range(n)], kinds, ring=ring, mids=mids,
                       own=OwnHeights(z, v, tiles[0][4].stand_in), zlevel=zlevel)


def blob_reach(g, vi: np.ndarray, vj: np.ndarray, fd: np.ndarray, fr: np.ndarray,
               derived: bool, edited: tuple[int, int, int, int] | None = None) -> dict:
    """Which stored bytes vertices (``vi``, ``vj``) whose δ code (``fd``) or r code
    (``fr``) changed can reach: ``{(L, x, y): (kinds, row)}``, the tile's δ and r blobs
    whose payload reads such a code (``kinds``) and whether its row's largest stored δ and
    r can change (``row``: the tile holds one as a vertex of its own level; every vertex
    at the top, whose blobs hold them all). A blob's payload is a function of the codes
    it reads, so a blob left out keeps its bytes; one named may keep them too (its old
    bytes are compared). What each blob reads (``derived``: the store derives level 0's
    inner bounds and r's cell centres above it, :func:`~geoterrain.bounds.tileblobs.level_blobs`'s
    ``ring`` and ``mids``):

    - level 0's ``RING`` δ and r: the new vertices of the tile's border only;
    - r's ``MIDS`` above level 0: the tile's own vertices but its cell centres;
    - every other blob (``PRED`` δ: seed 002 §2.4's parents, a cell centre's
      prediction reading the corners of its cell, a coarser level's vertices; ``CENTRES``;
      the top level's): every vertex of the tile.

    And (schema 20) every δ blob below the top reads its tile's heights (its guess from
    the own errors, :func:`geoterrain.bounds.ownguess.own_codes`), and (schema 23) the
    top tile's too (:func:`geoterrain.bounds.ownguess.top_payload_own`): ``edited``
    (rows r0 … r1 − 1, columns c0 … c1 − 1 of changed heights) reaches the δ of every
    tile whose lattice holds one of those samples.

    Examples
    --------
    >>> from geoterrain.core.grid import Grid
    >>> g = Grid(17, 17, 4, 2)  # 5 × 5 samples a tile, levels 0-2
    >>> reach = blob_reach(g, np.array([8]), np.array([4]), np.array([True]),
    ...                    np.array([False]), True)
    >>> for key, what in sorted(reach.items()):  # (8, 4): new at level 2, PRED δ below
    ...     print(key, what)
    (1, 0, 0) (('delta',), False)
    (1, 0, 1) (('delta',), False)
    (2, 0, 0) (('delta',), True)
    """
    vi, vj = np.asarray(vi, np.int64), np.asarray(vj, np.int64)
    fd, fr = np.asarray(fd, bool), np.asarray(fr, bool)
    top = g.top_level
    low = (vi | vj) & -(vi | vj)  # 2^level of each vertex (0: the corner (0, 0), none)
    # the level where each vertex is new, the top for every vertex of the top's lattice
    vk = np.minimum(np.frexp(low.astype(np.float64))[1] - 1, top)
    need: dict = {}
    # every level at once: which vertices each blob of a level reads, (3, levels, n):
    # δ, r, and the row's maxima
    Ls = np.arange(top + 1)
    span = np.array([g.tile_span(int(L)) for L in Ls], np.int64)
    nx, ny = np.array([g.tiles(int(L)) for L in Ls], np.int64).reshape(-1, 2).T
    on = vk[None] >= Ls[:, None]  # on the level's lattice
    own = vk[None] == Ls[:, None]  # the level's new vertices (every vertex of the top's tiles)
    sd, sr = on & fd, on & fr
    if derived:
        if top > 0:  # RING at level 0: the border's new vertices
            ring = own[0] & ((vi % span[0] == 0) | (vj % span[0] == 0))
            sd[0], sr[0] = ring & fd, ring & fr
        # MIDS above level 0: no cell centre (odd row and column)
        centre = (((vi[None] >> Ls[1:, None]) & 1) & ((vj[None] >> Ls[1:, None]) & 1)) \
            .astype(bool)
        sr[1:] = own[1:] & ~centre & fr
    n_, L_, v_ = np.nonzero(np.stack([sd, sr, own & (fd | fr)]))
    if len(v_):
        i, j, sp = vi[v_], vj[v_], span[L_]
        found = []
        # the tiles whose closed footprint holds the vertex (two or four on a border)
        for y in (np.minimum(i // sp, ny[L_] - 1), np.maximum((i - 1) // sp, 0)):
            for x in (np.minimum(j // sp, nx[L_] - 1), np.maximum((j - 1) // sp, 0)):
                ok = (y * sp <= i) & (i <= y * sp + sp) & (x * sp <= j) & (j <= x * sp + sp)
                found.append((L_[ok], y[ok], x[ok], n_[ok]))
        L_, y, x, n_ = (np.concatenate(a) for a in zip(*found, strict=True))
        NY, NX = int(y.max(initial=0)) + 1, int(x.max(initial=0)) + 1  # each tile once
        for q in np.unique(((L_ * NY + y) * NX + x) * 3 + n_).tolist():
            rest, n = divmod(q, 3)
            rest, tx = divmod(rest, NX)
            L, ty = divmod(rest, NY)
            need.setdefault((L, tx, ty), [False, False, False])[n] = True
    if edited is not None:  # schema 20 (23: the top's too): δ's own-error guess reads
        r0, c0, r1, c1 = (int(a) for a in edited)  # the tile's heights
        for L in range(top + 1):
            span, step, (nx, ny) = g.tile_span(L), 1 << L, g.tiles(L)
            i0, i1 = -(-r0 // step) * step, (r1 - 1) // step * step  # the level's samples
            j0, j1 = -(-c0 // step) * step, (c1 - 1) // step * step
            if i1 < i0 or j1 < j0:
                continue
            for ty in range(max(-(-(i0 - span) // span), 0), min(i1 // span, ny - 1) + 1):
                for tx in range(max(-(-(j0 - span) // span), 0), min(j1 // span, nx - 1) + 1):
                    need.setdefault((L, tx, ty), [False, False, False])[0] = True
    return {k: (tuple(kind for kind, f in zip(("delta", "radius"), v[:2], strict=True) if f),
                v[2]) for k, v in need.items()}


def _codes(table: np.ndarray, values) -> np.ndarray | int:
    """Log8 codes of stored values (each a table entry): ``np.searchsorted(table,
    values)``, the first entry ≥ each value, for a :func:`log8_table` (float64). A table
    entry is known by its float64's sign, exponent and top mantissa bits (16 entries an
    octave, 2^(1/16) apart: 6 bits tell them apart), so a look-up table on those bits
    (:func:`_entry_lut`) guesses each code; a check of every code against its two entries
    sends what it misses (a value off the table: between entries, NaN, negative) to the
    binary search: a tile's 4225 values in a fifth of its time.

    Examples
    --------
    >>> t = log8_table(-3).astype(np.float64)
    >>> v = np.array([0.0, t[1], t[7], np.nextafter(t[7], 0), t[254], 1e30, np.inf, np.nan])
    >>> _codes(t, v).tolist() == np.searchsorted(t, v).astype(np.uint8).tolist(), _codes(t, t[9])
    (True, 9)
    """
    v = np.asarray(values, np.float64)
    if v.size < 64:
        out = np.searchsorted(table, v).astype(np.uint8)
        return int(out) if out.ndim == 0 else out
    lut, below = _entry_lut(table.tobytes())
    # a key of every value (its bits' top 18, sign-extended: a negative value's indexes
    # the table's upper half from its end), its code by the look-up table
    c = lut[np.ascontiguousarray(v).view(np.int64) >> _LUT_SHIFT]
    # the first entry ≥ v: entry c is v and the one below it is below v (−inf below 0)
    ok = table[c] == v
    ok &= below[c] < v
    if not ok.all():
        miss = ~ok
        c[miss] = np.searchsorted(table, v[miss]).astype(np.uint8)
    return c


_LUT_SHIFT = 46  # a float64's bits above its 6 top mantissa bits: sign, exponent, 6 bits


@lru_cache(maxsize=16)
def _entry_lut(table_bytes: bytes) -> tuple[np.ndarray, np.ndarray]:
    """For :func:`_codes`, of a table (its float64 bytes, increasing): the code of every
    key (a float64's bits shifted right by :data:`_LUT_SHIFT`, 2^18 of them; a negative
    value's, sign-extended, counted from the end): a table entry's own code, code 0 below
    the first positive entry (0), 255 above the last (+inf, NaN, and every negative
    value's), keys between entries any code, which the check refuses; and each code's
    entry below it (−inf below code 0)."""
    table = np.frombuffer(table_bytes, np.float64)
    keys = table.view(np.int64) >> _LUT_SHIFT
    fin = np.flatnonzero(np.isfinite(table) & (table > 0))
    lut = np.full(1 << (64 - _LUT_SHIFT), 255, np.uint8)
    lut[:int(keys[fin].max()) + 1 if len(fin) else 1] = 0
    lut[keys[fin]] = fin  # (where two entries share a key, the later: the check sorts it)
    below = np.concatenate([[-np.inf], table[:-1]])
    return lut, below
