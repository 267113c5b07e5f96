"""δ and r of an edit, over what it reaches (:mod:`.local`); the tile errors and the
blocks' δ_n: :mod:`.localerrors`; the coarse blocks swept a tile at a time:
:mod:`.localsweeps`; the δ and r blobs coded again: :mod:`.localblobs`.

The vertices whose closed diamond holds a changed sample are recomputed, fine levels on
a window of decoded tiles around the edit (:func:`geoterrain.bounds.windows.fine_raw_delta`),
levels whose blocks outgrow a tile a tile at a time
(:func:`geoterrain.bounds.windows.block_sweep_rect`): each tile of the block gets a bound
on |z − P| for each of the block's planes P from the tile's height range, and tiles are
swept in decreasing order of bound until no unswept bound passes the largest value
found, which is then the exact maximum. Saturation (seed 002 §2.4, L46) and the radii's
nesting (L50–52) run on the stored codes: the code of a maximum is the maximum of the
codes, so unchanged children enter with their stored codes.
"""

from __future__ import annotations

from bisect import bisect_left

import numpy as np
from numba import njit

from geoterrain.bounds.delta import Cell
from geoterrain.bounds.log8codes import log8_exponent, log8_table
from geoterrain.bounds.windows import (
    block_sweep_rect,
    fine_raw_delta,
    nest_codes_rect,
    nest_codes_sparse,
)
from geoterrain.core.bintree import child_nb
from geoterrain.preprocessing.edit.localblobs import BlobCoding, _codes, blob_reach
from geoterrain.preprocessing.edit.localerrors import TileErrors
from geoterrain.preprocessing.edit.localerrors import WholeGrid as _Whole
from geoterrain.preprocessing.edit.localsweeps import (
    BlockSweeps,
    _child,
    _main_diagonal,
    _round_up32,
)

__all__ = ["Bounds", "blob_reach"]


class Bounds(BlockSweeps, BlobCoding):
    """δ, r and tile errors of one edit (``job``: :class:`.local._Job`)."""

    def __init__(self, job):
        self.job = job
        self.t, self.g, self.c = job.t, job.g, job.c
        # the grid's vertices: the square's N × N, or a root grid's extent R × C; half-spans
        # below a root's side (the square's one root: N − 1)
        self.R, self.C = self.g.extent
        self.root = 1 << self.g.n
        self.S = 1 << self.g.t
        self.t8 = log8_table(job.ed).astype(np.float64)
        self.rt = log8_table(job.er).astype(np.float64)
        self.stand_in = float(self.t.stand_in_z)
        self.coarse_d: dict = {}  # (i, j) → new saturated δ code, coarse vertices
        self.coarse_r: dict = {}  # (i, j) → new r code
        self.raw_new: dict = {}  # (i, j) → new raw δ (float32), coarse vertices
        self._sweeps: dict = {}  # a block's tile sweeps
        self._bound_cache: dict = {}  # a block's tiles' bounds, order, swept and maxima
        self._stored_cache: dict = {}
        self._code_cache: dict = {}  # (i, j, kind) → the vertex's stored code
        self._t8_list, self._rt_list = self.t8.tolist(), self.rt.tolist()
        self.tiles_swept = 0
        self.by_window = 0  # direct coarse vertices whose raw δ code came from the window
        self.z_old = None  # the window's heights before the edit (_raw_by_window)
        # the code of the store's largest finite δ: a raw δ whose code is below it is
        # below that δ (_raw_by_window)
        self.top_code = int(np.searchsorted(self.t8, float(self.t.meta["delta_max_finite"])))
        self.rows0 = {False: job.level0(False), True: job.level0(True)}

    def run(self) -> str:
        """Everything, or why the whole grid is needed."""
        try:
            self._scales()
            self._vertices()
            self._window()
            self._fine()
            self._coarse()
            self._delta_max()
            self._code_blobs()
            TileErrors(self.job).run()
        except _Whole as exc:
            return str(exc)
        return ""

    # ------------------------------------------------------------ store-wide numbers
    def _scales(self) -> None:
        """The numbers every tile's codes depend on must stay: r's code exponent (from
        the height range) and, where there is nodata, the stand-in height."""
        job, g, m = self.job, self.g, self.t.meta
        if any(k not in self.t.tile_info for k in job.rows):
            raise _Whole("the edit fills nodata where no tile was stored")
        lo, hi = job.scene_range()
        if int(m["valid_samples"]) < g.rows * g.cols or not self.c.valid.all():
            if float(0.5 * (lo + hi)) != self.stand_in:
                raise _Whole("the edit moves the nodata stand-in height (the middle of the "
                             "height range), which every radius near nodata depends on")
        f = self.t.frame
        cx, cy = f.xy(np.array([0, 0, self.R - 1, self.R - 1]),
                      np.array([0, self.C - 1, 0, self.C - 1]))
        span = [float(np.nanmax(cx) - np.nanmin(cx)), float(np.nanmax(cy) - np.nanmin(cy))]
        er = min(log8_exponent(np.array([float(np.hypot(*span) + hi - lo)])) + 2, 127)
        if er != job.er:
            raise _Whole("the edit changes r's code scale (the height range)")

    # ------------------------------------------------------------ the vertices
    def _vertices(self) -> None:
        """Per level, the vertices an edited sample reaches: ``direct`` ones hold one in
        their closed diamond (their raw δ changes); the others hold one in a
        descendant's diamond only (saturation and nesting pull from the whole DAG below
        a vertex: the samples of its descendants' diamonds lie within 3h − 1 of a centre
        and 2h − 1 of an edge midpoint, Chebyshev, by induction over the levels)."""
        c = self.c
        R0, R1, C0, C1 = c.r0, c.r1 - 1, c.c0, c.c1 - 1
        self.levels = []
        h = 1
        while h < self.root:  # a root's corners are no vertex of the bintrees (δ 0)
            s = 2 * h
            nr, nc = (self.R - 1) // s, (self.C - 1) // s
            out, direct = [], []
            for kind in ("rows", "cols", "centre"):
                reach = 3 * h
                a = np.arange(max((R0 - reach - s) // s, 0), min((R1 + reach) // s, nr) + 1)
                b = np.arange(max((C0 - reach - s) // s, 0), min((C1 + reach) // s, nc) + 1)
                # the level's rows i (a column) and columns j (a row), their distances
                # from the edit broadcast (as on a meshgrid: the vertices in raster order)
                i = h + a * s if kind != "cols" else a * s
                j = h + b * s if kind != "rows" else b * s
                ok_i = a < nr if kind != "cols" else np.ones(len(a), bool)
                ok_j = b < nc if kind != "rows" else np.ones(len(b), bool)
                di = np.maximum(np.maximum(R0 - i, i - R1), 0)[:, None]
                dj = np.maximum(np.maximum(C0 - j, j - C1), 0)[None, :]
                cheb = np.maximum(di, dj)
                if kind == "centre":
                    near, hit = cheb <= 3 * h, cheb <= h
                else:
                    near, hit = cheb <= 2 * h, di + dj <= h
                ia, jb = np.nonzero(near & ok_i[:, None] & ok_j[None, :])
                out.append(np.stack([i[ia], j[jb], np.full(len(ia), h)], 1))
                direct.append(hit[ia, jb])
            self.levels.append((h, np.concatenate(out).astype(np.int64),
                                np.concatenate(direct)))
            h *= 2
        # fine levels: a block fits in a level-0 tile
        fine = [(v, d) for h, v, d in self.levels if 2 * h <= self.S]
        self.fine = np.concatenate([v for v, _ in fine] or [np.zeros((0, 3), np.int64)])
        self.fine_direct = np.concatenate([d for _, d in fine] or [np.zeros(0, bool)])
        self.coarse_levels = [(h, v, d) for h, v, d in self.levels if 2 * h > self.S]

    def _window(self) -> None:
        """The decoded window around the edit that holds every fine vertex's diamond,
        blocks and children (within 4h ≤ two tiles of the edit), two tiles beyond it; its
        stored δ and r codes."""
        c, t, S = self.c, self.t, self.S
        self.oi = max((c.r0 // S - 2) * S, 0)
        self.oj = max((c.c0 // S - 2) * S, 0)
        self.i1 = min(((c.r1 - 1) // S + 3) * S, self.R - 1)
        self.j1 = min(((c.c1 - 1) // S + 3) * S, self.C - 1)
        self.z, self.v = c.rect(self.oi, self.oj, self.i1 + 1, self.j1 + 1)
        shape = self.z.shape
        self.dc = np.zeros(shape, np.uint8)
        self.rc = np.zeros(shape, np.uint8)
        # where dc and rc hold the stored codes: everywhere on the tiles within 8 samples
        # of the edit; elsewhere on a coarser level's lattice only (below). A fine vertex
        # of half-span h lies within 3h of the edit (an edge midpoint within 2h), its
        # children within h of it: those on level 0's lattice within 5 samples (h = 2
        # edge midpoints' cell centres), 8 taken (tiles under 8 samples read whole)
        self.known = np.zeros(shape, bool)
        whole = self.g.top_level < 1 or S < 8
        # Farther out the reads thin out level by level: a position off level k's lattice
        # (not a multiple of 2^k) is a vertex of half-span h < 2^k, within 3h, or a child
        # of one (a centre's children within h of it, an edge midpoint's of h ≤ 2^k
        # within h/2), so within 5·2^(k−1) samples of the edit. A level-0 tile more than
        # 8·2^(k−1) samples away takes level k's lattice from its level-k ancestor (at
        # most the top; within two tiles of the edit, 2^(k+2) < 2S, so k < t − 1: the
        # h = S/2 vertices' lattice, which the coarse vertices read, stays in), whose
        # decode its finer tiles' decodes would need anyway (NEW_ONLY: a tile's even
        # samples are its parent's)
        kmax = max(min(self.g.top_level, self.g.t - 1), 1)
        coded: dict = {}  # a level-k tile's stored δ and r codes

        def codes_of(key):
            got = coded.get(key)
            if got is None:
                got = coded[key] = (_codes(self.t8, t.tile_delta(*key)),
                                    _codes(self.rt, t.tile_radius(*key)))
            return got

        plan = []  # (the tile's slice of the window, its key, the level it is read from)
        for ty in range(self.oi // S, self.i1 // S):
            dy = max(c.r0 - (ty * S + S), ty * S - (c.r1 - 1), 0)
            for tx in range(self.oj // S, self.j1 // S):
                if (0, tx, ty) not in t.tile_info:
                    raise _Whole("nodata tiles beside the edit")
                sl = (slice(ty * S - self.oi, ty * S - self.oi + S + 1),
                      slice(tx * S - self.oj, tx * S - self.oj + S + 1))
                d = max(dy, c.c0 - (tx * S + S), tx * S - (c.c1 - 1))
                k = 0
                if not (whole or d <= 8):
                    k = 1
                    while k < kmax and d > 8 << k:
                        k += 1
                plan.append((sl, (0, tx, ty), k))
        _read_ahead(t, {(k, key[1] >> k, key[2] >> k) for _, key, k in plan})
        for sl, key, k in plan:
            _, tx, ty = key
            if k == 0:
                self.dc[sl] = _codes(self.t8, t.tile_delta(*key))
                self.rc[sl] = _codes(self.rt, t.tile_radius(*key))
                self.known[sl] = True
            else:
                m, part = 1 << k, S >> k  # the level-k tile's samples over this tile: part + 1
                q = (slice((ty % m) * part, (ty % m) * part + part + 1),
                     slice((tx % m) * part, (tx % m) * part + part + 1))
                on = (slice(sl[0].start, sl[0].stop, m), slice(sl[1].start, sl[1].stop, m))
                dk, rk = codes_of((k, tx >> k, ty >> k))
                self.dc[on] = dk[q]
                self.rc[on] = rk[q]
                self.known[on] = True
        self.dc_old, self.rc_old = self.dc.copy(), self.rc.copy()
        f = t.frame
        # a row and a column broadcast (each sample's arithmetic as on a meshgrid's)
        self.X, self.Y = f.xy(np.arange(self.oi, self.i1 + 1)[:, None],
                              np.arange(self.oj, self.j1 + 1)[None, :])
        self.X, self.Y = np.ascontiguousarray(self.X), np.ascontiguousarray(self.Y)
        self.zp = np.where(self.v.astype(bool), self.z, self.stand_in)

    # ------------------------------------------------------------ fine levels
    def _fine(self) -> None:
        """Raw δ, then saturated codes and nested r codes of the fine vertices, in the
        window, level by level (edge midpoints before centres)."""
        vs = self.fine
        raw = np.zeros(len(vs), np.float32)
        fine_raw_delta(self.z, self.v, self.oi, self.oj, self.R, self.C, vs, raw)
        self.fine_raw = raw
        self._check_scale(raw)
        raw_codes = np.searchsorted(self.t8, raw.astype(np.float64)).astype(np.uint8)
        _saturate_rect(self.dc, raw_codes, vs, self.oi, self.oj, self.R, self.C)
        leaves = (vs[:, 2] == 1) & ~(((vs[:, 0] // vs[:, 2]) % 2 == 1)
                                     & ((vs[:, 1] // vs[:, 2]) % 2 == 1))
        nest_codes_rect(self.X, self.Y, self.zp, self.rc, self.rt, vs[~leaves], self.oi,
                        self.oj, self.R, self.C)
        if (self.rc == 255).any():
            raise _Whole("a radius outgrows its code scale")

    def _check_scale(self, raw) -> None:
        """A finite δ past the top finite code: the code exponent must grow."""
        raw = np.asarray(raw, np.float64)
        if (np.isfinite(raw) & (raw > self.t8[254])).any():
            raise _Whole("the edit changes δ's code scale (its largest value)")

    def _in_window(self, i: int, j: int) -> bool:
        # in the window, where it holds the vertex's code
        return self.oi <= i <= self.i1 and self.oj <= j <= self.j1 and \
            bool(self.known[i - self.oi, j - self.oj])

    def d_code(self, i: int, j: int) -> int:
        """δ's saturated code of vertex (i, j) as the edit leaves it."""
        if (i, j) in self.coarse_d:
            return self.coarse_d[(i, j)]
        if self._in_window(i, j):
            return int(self.dc[i - self.oi, j - self.oj])
        return self._old_code(i, j, "delta")

    def r_code(self, i: int, j: int) -> int:
        if (i, j) in self.coarse_r:
            return self.coarse_r[(i, j)]
        if self._in_window(i, j):
            return int(self.rc[i - self.oi, j - self.oj])
        return self._old_code(i, j, "radius")

    def _stored(self, i: int, j: int, kind: str) -> float:
        """A vertex's stored value, from a stored tile that holds it at its level."""
        key = (i, j, kind)
        if key not in self._stored_cache:
            self._stored_cache[key] = self._stored_now(i, j, kind)
        return self._stored_cache[key]

    def _old_code(self, i: int, j: int, kind: str) -> int:
        """A vertex's stored code (its stored value's: the first table entry ≥ it, as
        :func:`_codes`), once a vertex: a bisection of the table's list, not a numpy
        call per vertex."""
        key = (i, j, kind)
        got = self._code_cache.get(key)
        if got is None:
            table = self._t8_list if kind == "delta" else self._rt_list
            got = self._code_cache[key] = bisect_left(table, self._stored(i, j, kind))
        return got

    def _stored_now(self, i: int, j: int, kind: str) -> float:
        g = self.g
        h = (i | j) & -(i | j)
        k = min(h.bit_length() - 1, g.top_level)
        span = g.tile_span(k)
        nx, ny = g.tiles(k)
        cands = [(x, y) for y in sorted({min(i // span, ny - 1), max((i - 1) // span, 0)})
                 for x in sorted({min(j // span, nx - 1), max((j - 1) // span, 0)})]
        if k == g.top_level and len(cands) > 1:  # on roots' shared edge: a root the edit
            # reaches first (decoded already; both hold the vertex's one stored value)
            cands.sort(key=lambda xy: not self.c.touches(xy[1] * span, xy[0] * span,
                                                         xy[1] * span + span,
                                                         xy[0] * span + span))
        for x, y in cands:
            if (k, x, y) in self.t.tile_info and y * span <= i <= y * span + span \
                    and x * span <= j <= x * span + span:
                arr = (self.t.tile_delta if kind == "delta" else self.t.tile_radius)(k, x, y)
                return float(arr[(i - y * span) >> k, (j - x * span) >> k])
        if kind == "delta":
            return 0.0  # no stored tile holds it: its diamond holds no data
        raise _Whole("nodata tiles beside the edit's coarse vertices")

    # ------------------------------------------------------------ coarse levels
    def _coarse(self) -> None:
        """The coarse vertices' codes, edge midpoints before centres at each level: a
        direct vertex's raw δ by tiles; another's raw δ is unchanged, and its code is
        known without it unless the edit lowered the child that held its saturated
        value (then it is computed by tiles too)."""
        self.direct_coarse = set()
        for h, vs, direct in self.coarse_levels:
            centre = ((vs[:, 0] // h) % 2 == 1) & ((vs[:, 1] // h) % 2 == 1)
            # the level's edge midpoints, then its centres (whose children they are): δ,
            # then r nested on the children's codes (no δ read) in one call a part
            for part in (np.flatnonzero(~centre), np.flatnonzero(centre)):
                done = []
                for (i, j, _), d in zip(vs[part].tolist(), direct[part].tolist(),
                                        strict=True):
                    if self._coarse_one(i, j, h, d):
                        done.append((i, j))
                self._nest_all([v[0] for v in done], [v[1] for v in done], h)

    def _coarse_one(self, i: int, j: int, h: int, d: bool) -> bool:
        """Coarse vertex (i, j)'s δ code into ``coarse_d`` (``d``: its closed diamond
        holds an edited sample); False where it keeps its codes, left out: not direct,
        its height not edited and no child's codes or height changed (its raw δ, its
        children's codes and heights are then those its stored δ and r were made of),
        so that neither its codes nor those of its children the edit does not reach
        (another root's, on a root grid's shared edge) are read."""
        kids = [_child(i, j, h, k) for k in range(4)]
        kids = [(ci, cj) for ci, cj in kids if 0 <= ci < self.R and 0 <= cj < self.C]
        if not d:
            if not self.c.touches(i, j, i, j) and not any(
                    self._kid_changed(ci, cj) for ci, cj in kids):
                return False
            code = self._by_reached(i, j, kids)
            if code is not None:
                self.coarse_d[(i, j)] = code
                return True
        new_kids = max((self.d_code(ci, cj) for ci, cj in kids), default=0)
        if d:
            self.direct_coarse.add((i, j))
            raw = self._raw_by_window(i, j, h, kids, new_kids)
            if raw is None:
                raw = self._coarse_raw(i, j, h)
            self._check_scale(raw)
            self.raw_new[(i, j)] = raw
            code = max(int(np.searchsorted(self.t8, float(raw))), new_kids)
        else:
            old = self._old_code(i, j, "delta")
            old_kids = max((self._old_code(ci, cj, "delta") for ci, cj in kids), default=0)
            if old > old_kids:  # its own raw δ held it: unchanged
                code = max(old, new_kids)
            elif new_kids >= old:
                code = new_kids
            else:
                raw = self._coarse_raw(i, j, h)
                self.raw_new[(i, j)] = raw
                code = max(int(np.searchsorted(self.t8, float(raw))), new_kids)
        self.coarse_d[(i, j)] = code
        return True

    def _kid_changed(self, i: int, j: int) -> bool:
        """Whether the edit changes vertex (i, j)'s height, δ code or r code (one it does
        not reach keeps them: :meth:`_reached`)."""
        if self.c.touches(i, j, i, j):
            return True
        if (i, j) in self.coarse_d:
            return self.coarse_d[(i, j)] != self._old_code(i, j, "delta") or \
                self.coarse_r[(i, j)] != self._old_code(i, j, "radius")
        if self._in_window(i, j):
            a, b = i - self.oi, j - self.oj
            return bool(self.dc[a, b] != self.dc_old[a, b] or self.rc[a, b] != self.rc_old[a, b])
        return False

    def _raw_by_window(self, i: int, j: int, h: int, kids: list, new_kids: int
                       ) -> float | None:
        """A direct coarse vertex's raw δ, as far as its saturated code needs it, from its
        stored code and the edit's window alone, with no tile swept (None where it is
        not known so).

        Its raw δ is a maximum over its diamond's samples (its blocks' regions); where no
        block corner or centre (its planes) is edited, the samples outside the edit's
        rectangle W keep their values, whose code is at most the stored code (saturation
        takes the largest of the raw code and the children's). So the new raw code is at
        most ``ub``, the larger of the stored code and W's new values' code, and is
        ``ub`` where the stored code is the raw δ's (above the children's old codes) and
        W's old values have a lower code (the samples outside W held it). Where ``ub`` is
        at most the children's new codes, the saturated code is theirs whatever the raw
        code is. Below the code of the store's largest δ a raw value is only compared
        with that δ (:meth:`_delta_max`), and lies below it: the code's upper end is
        returned; at or above it, None (the exact value is swept)."""
        c, s, t8 = self.c, 2 * h, self._t8_list
        old = self._old_code(i, j, "delta")
        if old >= self.top_code:
            return None
        if (i // h) % 2 == 1 and (j // h) % 2 == 1:
            parts = [((i - h) // s, (j - h) // s, 0)]
        elif (i // h) % 2 == 1:  # hypotenuse along the rows
            parts = [((i - h) // s, j // s - 1, 2), ((i - h) // s, j // s, 1)]
        else:
            parts = [(i // s - 1, (j - h) // s, 4), (i // s, (j - h) // s, 3)]
        w_new = 0.0
        rects = []  # (cell, zc, rectangle, region) of W's parts
        some = False
        for a, b, r in parts:
            f, fo = self._status(a, b, s), self._status(a, b, s, False)
            if f != fo or f not in (0, 1):
                return None
            if f == 0:
                continue
            some = True
            i0, j0 = a * s, b * s
            ci = np.array([i0, i0, i0 + s, i0 + s, i0 + h])
            cj = np.array([j0, j0 + s, j0, j0 + s, j0 + h])
            if ((ci >= c.r0) & (ci < c.r1) & (cj >= c.c0) & (cj < c.c1)).any():
                return None  # an edited plane
            a0, a1 = max(c.r0, i0) - i0, min(c.r1 - 1, i0 + s) - i0
            b0, b1 = max(c.c0, j0) - j0, min(c.c1 - 1, j0 + s) - j0
            if a1 < a0 or b1 < b0:
                continue
            z00, z01, z10, z11, zc = (float(v) for v in c.samples(ci, cj)[0])
            cell = Cell(i0, j0, s, _main_diagonal(a, b), z00, z01, z10, z11)
            w_new = max(w_new, self._rect_max(cell, zc, (a0, a1, b0, b1), r, True))
            rects.append((cell, zc, (a0, a1, b0, b1), r))
        if not some:
            return None
        ub = max(old, bisect_left(t8, _round_up32(w_new)))
        if ub >= self.top_code:
            return None
        if ub <= new_kids:  # the children's codes win: any raw code up to ub will do
            self.by_window += 1
            return t8[ub]
        held = old > max((self._old_code(ci, cj, "delta") for ci, cj in kids), default=0)
        if not held:
            return None
        # W's old values, only now (the window before the edit is assembled for them)
        w_old = max([0.0] + [self._rect_max(*q, False) for q in rects])
        if bisect_left(t8, _round_up32(w_old)) < old:
            self.by_window += 1
            return t8[ub]
        return None

    def _rect_max(self, cell: Cell, zc: float, rect: tuple, r: int, new: bool) -> float:
        """Region ``r``'s largest |z − P| of block ``cell`` over the block-relative
        rectangle ``rect`` (rows a0 … a1, columns b0 … b1, inclusive) within the window,
        after the edit or before it."""
        if new:
            z = self.z
        else:
            if self.z_old is None:
                self.z_old = self.c.rect(self.oi, self.oj, self.i1 + 1, self.j1 + 1,
                                         new=False)[0]
            z = self.z_old
        return float(block_sweep_rect(z, self.oi, self.oj, cell, zc, *rect)[r])

    def _reached(self, i: int, j: int) -> bool:
        """Whether vertex (i, j) is one the edit may change (a coarse vertex computed
        already and not left out, or one in the window): any other keeps its stored
        codes."""
        return (i, j) in self.coarse_d or self._in_window(i, j)

    def _by_reached(self, i: int, j: int, kids: list) -> int | None:
        """A coarse vertex's saturated δ code where the edit does not reach its diamond
        (its raw δ unchanged), from its stored code and its reached children's codes
        alone (None where the others' are needed). Stored, the code is the largest of its
        raw code and its children's (saturation), so at least each child's old code:
        where no reached child's old code equals it and none's new code passes it, the
        raw code or an unreached child still holds it; where a reached child's new code
        reaches it, that code is the largest. Children of another root (a root grid's
        edge midpoints on the roots' shared edge) are not decoded then."""
        old = self._old_code(i, j, "delta")
        reached = [k for k in kids if self._reached(*k)]
        rn = max((self.d_code(*k) for k in reached), default=-1)
        if rn >= old:
            return rn
        ro = max((self._old_code(*k, "delta") for k in reached), default=-1)
        return old if ro < old else None

    def _nest_all(self, vi: list, vj: list, h: int) -> None:
        """The r codes of coarse vertices (``vi``, ``vj``) of half-span ``h``, nested on
        their children's codes (each row its vertex and
        its children in the grid, in ``child_nb``'s order), into ``coarse_r``."""
        # a vertex with a child the edit does not reach (a child of another root, say)
        # keeps its stored code where neither its height nor a reached child's code or
        # height changed: its code is nested on those alone (the others keep theirs),
        # and the others' codes are not read
        rest = []
        for i, j in zip(vi, vj, strict=True):
            kids = [_child(i, j, h, q) for q in range(4)]
            kids = [(ci, cj) for ci, cj in kids if 0 <= ci < self.R and 0 <= cj < self.C]
            reached = [q for q in kids if self._reached(*q)]
            if len(reached) < len(kids) and not self.c.touches(i, j, i, j) and not any(
                    self.c.touches(ci, cj, ci, cj)
                    or self.r_code(ci, cj) != self._old_code(ci, cj, "radius")
                    for ci, cj in reached):
                self.coarse_r[(i, j)] = self._old_code(i, j, "radius")
            else:
                rest.append((i, j))
        vi, vj = [v[0] for v in rest], [v[1] for v in rest]
        n = len(vi)
        if not n:
            return
        ii = np.zeros((n, 5), np.int64)
        jj = np.zeros((n, 5), np.int64)
        cc = np.zeros((n, 4), np.uint8)
        ok = np.zeros((n, 4), np.bool_)
        for k, (i, j) in enumerate(zip(vi, vj, strict=True)):
            ii[k, 0], jj[k, 0] = i, j
            m = 0
            for q in range(4):
                ci, cj = _child(i, j, h, q)
                if 0 <= ci < self.R and 0 <= cj < self.C:
                    ii[k, m + 1], jj[k, m + 1] = ci, cj
                    cc[k, m] = self.r_code(ci, cj)
                    ok[k, m] = True
                    m += 1
        used = np.concatenate([np.ones((n, 1), bool), ok], axis=1)
        X, Y = self.t.frame.xy(ii[used], jj[used])
        z, v = self.c.samples(ii[used], jj[used])
        px, py, pz = np.zeros((n, 5)), np.zeros((n, 5)), np.zeros((n, 5))
        px[used], py[used], pz[used] = X, Y, np.where(v, z, self.stand_in)
        out = np.zeros(n, np.uint8)
        nest_codes_sparse(px, py, pz, cc, ok, self.rt, out)
        if (out == 255).any():
            raise _Whole("a radius outgrows its code scale")
        for i, j, code in zip(vi, vj, out.tolist(), strict=True):
            self.coarse_r[(i, j)] = code






    # ------------------------------------------------------------ the largest δ
    def _delta_max(self) -> None:
        """The store's largest finite δ after the edit, exactly, and its code exponent,
        which must stay.

        D = max raw δ over the vertices of finite saturated δ. Only direct vertices'
        raw δ changes; another enters or leaves D's set only if its saturated δ turns
        finite or infinite (nodata filled), and then its raw δ is computed. The others'
        maximum is the old D unless a direct or leaving vertex held it (only one whose
        old code is D's can), in which case the new D is known only if the edit's
        values reach the old one."""
        job, t8 = self.job, self.t8
        d_old = float(self.t.meta["delta_max_finite"])
        top_code = int(np.searchsorted(t8, d_old))
        fi, fj = self.fine[:, 0] - self.oi, self.fine[:, 1] - self.oj
        new_fin = self.dc[fi, fj] < 255
        old_fin = self.dc_old[fi, fj] < 255
        fd = self.fine_direct
        # the new maximum among direct vertices and those whose δ turned finite
        enter = new_fin & (fd | ~old_fin)
        a_new = float(self.fine_raw[enter].max()) if enter.any() else 0.0
        held = False  # did a direct or leaving vertex hold the old maximum?
        leave = old_fin & ~new_fin & ~fd
        if (self.fine_raw[leave].astype(np.float64) == d_old).any():
            held = True
        cand = fd & old_fin & (self.dc_old[fi, fj] == top_code)
        if cand.any() and not held:
            raw_old = np.zeros(int(cand.sum()), np.float32)
            zo, vo = self.c.rect(self.oi, self.oj, self.i1 + 1, self.j1 + 1, new=False)
            fine_raw_delta(zo, vo, self.oi, self.oj, self.R, self.C, self.fine[cand], raw_old)
            held = bool((raw_old.astype(np.float64) == d_old).any())
        for h, vs, direct in self.coarse_levels:
            for (i, j, _), d in zip(vs.tolist(), direct.tolist(), strict=True):
                if (i, j) not in self.coarse_d:  # codes kept (_coarse_one): no term
                    continue
                new_code = self.coarse_d[(i, j)]
                old_code = self._old_code(i, j, "delta")
                if (new_code < 255) != (old_code < 255) and (i, j) not in self.raw_new:
                    self.raw_new[(i, j)] = self._coarse_raw(i, j, h)
                if new_code < 255 and (d or old_code == 255):
                    a_new = max(a_new, float(self.raw_new[(i, j)]))
                if old_code == top_code and not held and (d or new_code == 255):
                    raw_old = self._coarse_raw(i, j, h, new=False) if d else self.raw_new[(i, j)]
                    held = float(raw_old) == d_old
        if held and a_new < d_old:
            raise _Whole("the edit lowers the store's largest vertex error, which only a "
                         "pass over every vertex can find again")
        d_new = a_new if held else max(a_new, d_old)
        if log8_exponent(np.array([d_new])) != job.ed:
            raise _Whole("the edit changes δ's code scale (its largest value)")
        job.meta["delta_max_finite"] = d_new

    # ------------------------------------------------------------ blobs and rows







def _read_ahead(t, keys) -> None:
    """The δ and r blobs (and heights) that decoding the δ and r of tiles ``keys`` reads
    (each tile's and, up to the first one cached, its ancestors': a new-vertices blob
    reads its parent's values), read ahead in one batch where the terrain reads through
    a :class:`~geoterrain.store.reader.StoreReader` inside a snapshot (the edit's plan):
    one query instead of one a blob; the same blobs, decoded the same way."""
    ahead = getattr(getattr(t, "reader", None), "read_ahead", None)
    if ahead is None:
        return
    top, items = t.grid.top_level, []
    for kind, tag in (("delta", "d"), ("radius", "r"), ("heights", "h")):
        seen: set = set()
        for key in keys:
            while key not in seen and key in t.tile_info and t.peek((tag, *key)) is None:
                seen.add(key)
                items.append((key, kind))
                if key[0] >= top:
                    break
                key = (key[0] + 1, key[1] // 2, key[2] // 2)
    if len(items) > 1:
        ahead(items)










@njit(cache=True)
def _saturate_rect(codes, raw_codes, verts, oi, oj, R, C):
    # saturation on the codes (delta.saturate's pull from the children):
    # each listed vertex, fine to coarse, takes the largest of its raw code and its
    # children's codes
    for k in range(verts.shape[0]):
        i, j, h = verts[k, 0], verts[k, 1], verts[k, 2]
        c = raw_codes[k]
        centre = (i // h) % 2 == 1 and (j // h) % 2 == 1
        if centre or h > 1:
            for q in range(4):
                ci, cj = child_nb(i, j, h, q)
                if 0 <= ci < R and 0 <= cj < C:
                    c = max(c, codes[ci - oi, cj - oj])
        codes[i - oi, j - oj] = c
