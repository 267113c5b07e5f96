"""δ and r of an edit, over what it reaches (:mod:`.local`); the tile errors and the
blocks' δ_n: :mod:`.localerrors`.

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
from functools import lru_cache

import numpy as np
from numba import njit

from geoterrain.bounds.delta import Cell
from geoterrain.bounds.log8codes import log8_exponent, log8_table
from geoterrain.bounds.ownguess import new_codes_same, own_codes, pred_payload_same
from geoterrain.bounds.tileblobs import BoundsCoding, OwnHeights, level_blobs
from geoterrain.bounds.tilebounds import closed_blocks
from geoterrain.bounds.vertexdata import shaped_zstd_level
from geoterrain.bounds.windows import (
    block_sweep_rect,
    fine_raw_delta,
    nest_codes_rect,
    nest_codes_sparse,
)
from geoterrain.core.bintree import child_nb, main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.preprocessing.edit.localerrors import TileErrors
from geoterrain.preprocessing.edit.localerrors import WholeGrid as _Whole

__all__ = ["Bounds", "blob_reach"]

_SLACK = 1e-9  # relative slack of a tile's bound (float rounding of the planes)

# The scalar helpers called from this module's Python code run as Python (the same
# integer arithmetic; round_up32's float32 steps are IEEE operations in numpy too): a
# compiled scalar called from Python costs a load from numba's cache in each process
# (2-5 ms each, docs/lab/editing.md) for a few hundred calls of well under a microsecond.
# The kernels below keep calling the compiled ones.
_child = child_nb.py_func
_main_diagonal = main_diagonal_nb.py_func


def _round_up32(a: float) -> float:
    # what the compiled round_up32 returns to Python: its float32 as a float
    return float(round_up32.py_func(a))


class Bounds:
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

    def _status(self, a: int, b: int, s: int, new: bool = True) -> int:
        """A coarse block's status (1 all valid, 2 all invalid, 3 mixed) from its tiles'
        valid counts; 0 outside the grid."""
        if not (0 <= a < (self.R - 1) // s and 0 <= b < (self.C - 1) // s):
            return 0
        k = s // self.S
        n = self.rows0[new][0, a * k:a * k + k, b * k:b * k + k]
        return (1 if (n > 0).any() else 0) | (2 if (n < (self.S + 1) ** 2).any() else 0)

    def _coarse_raw(self, i: int, j: int, h: int, new: bool = True) -> np.float32:
        """Raw δ of a coarse vertex (as bounds._raw_delta_nb computes it)."""
        s = 2 * h
        if (i // h) % 2 == 1 and (j // h) % 2 == 1:
            a, b = (i - h) // s, (j - h) // s
            f = self._status(a, b, s, new)
            if f == 1:
                return _round_up32(self._block_max(a, b, s, (0,), new)[0])
            return np.float32(np.inf) if f == 3 else np.float32(0.0)
        if (i // h) % 2 == 1:  # hypotenuse along the rows
            a, b = (i - h) // s, j // s
            lo, hi = (a, b - 1, 2), (a, b, 1)
        else:
            a, b = i // s, (j - h) // s
            lo, hi = (a - 1, b, 4), (a, b, 3)
        flo = self._status(lo[0], lo[1], s, new)
        fhi = self._status(hi[0], hi[1], s, new)
        f = flo | fhi
        if f == 2:
            return np.float32(0.0)
        if f == 1:
            m = 0.0
            for (ba, bb, which), fs in ((lo, flo), (hi, fhi)):
                if fs:
                    m = max(m, self._block_max(ba, bb, s, (which,), new)[which])
            return _round_up32(m)
        if self._diamond_mixed(i, j, h, new):
            return np.float32(np.inf)
        raise _Whole("nodata beside a coarse vertex whose diamond may be all valid")

    def _diamond_mixed(self, i: int, j: int, h: int, new: bool) -> bool:
        """Whether tiles wholly inside the vertex's diamond hold valid and invalid
        samples (the diamond is then mixed: δ = +inf)."""
        S, T2 = self.S, (self.S + 1) ** 2
        got = 0
        nx, ny = self.g.tiles(0)
        for ty in range(max((i - h) // S, 0), min((i + h) // S, ny - 1) + 1):
            for tx in range(max((j - h) // S, 0), min((j + h) // S, nx - 1) + 1):
                corners = [(ty * S + a, tx * S + b) for a in (0, S) for b in (0, S)]
                if all(abs(p - i) + abs(q - j) <= h for p, q in corners):
                    n = self.rows0[new][0, ty, tx]
                    got |= (1 if n > 0 else 0) | (2 if n < T2 else 0)
                    if got == 3:
                        return True
        return False

    def _block_max(self, a: int, b: int, s: int, want: tuple, new: bool = True) -> np.ndarray:
        """The exact maxima (centre, left, right, top, bottom) of the all-valid block
        (a, b) of side s > tile, those in ``want`` exact: its tiles swept in decreasing
        order of their bound until no bound passes the best value found."""
        c, S = self.c, self.S
        i0, j0 = a * s, b * s
        main = _main_diagonal(a, b)
        corners = c.samples(np.array([i0, i0, i0 + s, i0 + s, i0 + s // 2]),
                            np.array([j0, j0 + s, j0, j0 + s, j0 + s // 2]), new)[0]
        z00, z01, z10, z11, zc = (float(v) for v in corners)
        cell = Cell(i0, j0, s, main, z00, z01, z10, z11)
        k = s // S
        ty, tx = np.meshgrid(np.arange(a * k, a * k + k), np.arange(b * k, b * k + k),
                             indexing="ij")
        ty, tx = ty.ravel(), tx.ravel()
        bkey = (a, b, s, new)
        got = self._bound_cache.get(bkey)
        if got is None:
            zlo = self.rows0[new][1, ty, tx]
            zhi = self.rows0[new][2, ty, tx]
            bound = _bounds(cell, zc, ty * S - i0, tx * S - j0, S, zlo, zhi)
            if k > 2:  # tighter: the union-jack surfaces of the block table
                tight = self._uj_bounds(cell, zc, a, b, s, new)
                bound = np.where(np.isneginf(bound), bound, np.minimum(bound, tight))
            # each region's tiles by decreasing bound, and which were swept
            got = self._bound_cache[bkey] = (bound, np.argsort(-bound, axis=0, kind="stable"),
                                             np.zeros(len(ty), bool), np.zeros(5))
        bound, order, swept, best = got
        pos = [0] * 5
        while True:
            # the wanted region whose next unswept tile's bound most exceeds its best
            pick, gain = -1, 0.0
            for r in want:
                while pos[r] < len(ty) and swept[order[pos[r], r]]:
                    pos[r] += 1
                if pos[r] < len(ty):
                    g = bound[order[pos[r], r], r] - best[r]
                    if g > gain:
                        pick, gain = r, g
            if pick < 0:
                return best.copy()
            q = int(order[pos[pick], pick])
            key = (a, b, s, new, int(ty[q]), int(tx[q]))
            m = self._sweeps.get(key)
            if m is None:
                z, _ = c.tile_z(int(ty[q]), int(tx[q]), new)
                a0, c0 = int(ty[q]) * S - i0, int(tx[q]) * S - j0
                m = self._sweeps[key] = np.array(block_sweep_rect(
                    z, int(ty[q]) * S, int(tx[q]) * S, cell, zc, a0, a0 + S, c0, c0 + S))
            np.maximum(best, m, out=best)
            swept[q] = True
            self.tiles_swept += 1

    def _uj_bounds(self, cell: Cell, zc: float, a: int, b: int, s: int, new: bool
                   ) -> np.ndarray:
        """(tiles, 5) bounds of |z − P| over each tile of block (a, b) from the store's
        GeoMipMapping table: at level n, z lies within the tile's δ_n (rounded up) of
        S_n, the union-jack surface through the tile's level-n samples, and S_n − P is
        linear on each of its triangles, so |z − P| ≤ max over those samples of
        |z − P| + δ_n, at n = max(t − 2, 1) (of n = t, t − 1, t − 2, the coarser two lowered
        the tiles swept by 1 in 116 an edit on the 4097² fBm for a quarter of this
        bound's time, docs/lab/editing.md). Tiles the edit changed get +inf (the table is
        the old one) when ``new``."""
        g, c, S = self.g, self.c, self.S
        i0, j0, s_, main, z00, z01, z10, z11 = cell
        h = s // 2
        k = s // S
        table = self.t.block_errors()
        out = np.full((k * k, 5), np.inf)
        for n in range(max(g.t - 2, 1), min(max(g.t - 2, 1), table.shape[2] - 1) + 1):
            step = 1 << n
            rows = np.arange(i0, i0 + s + 1, step)
            cols = np.arange(j0, j0 + s + 1, step)
            hh, vv = c.lattice(n, rows, cols, new)
            if not vv.all():
                return out
            z = hh * c.factor
            di = (rows - i0)[:, None].astype(np.float64)
            dj = (cols - j0)[None, :].astype(np.float64)
            fi = di / s
            kl = (zc - 0.5 * (z00 + z10)) / h
            kr = (zc - 0.5 * (z01 + z11)) / h
            kt = (zc - 0.5 * (z00 + z01)) / h
            kb = (zc - 0.5 * (z10 + z11)) / h
            if main:
                p1 = z00 + (z10 - z00) * fi + (z11 - z10) / s * dj
                p2 = z00 + (z11 - z01) * fi + (z01 - z00) / s * dj
                left, right = dj < di, dj > di
            else:
                p1 = z00 + (z10 - z00) * fi + (z01 - z00) / s * dj
                p2 = z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11) - (z10 - z11) / s * dj
                left, right = dj < s - di, dj > s - di
            a1, a2 = np.abs(z - p1), np.abs(z - p2)
            errs = [np.where(left, a1, np.where(right, a2, np.maximum(a1, a2))),
                    np.abs(z - (z00 + (z10 - z00) * fi + kl * dj)),
                    np.abs(z - (z01 + (z11 - z01) * fi + kr * s - kr * dj)),
                    np.abs(z - (z00 + kt * di + (z01 - z00) / s * dj)),
                    np.abs(z - (z10 + kb * (s - di) + (z11 - z10) / s * dj))]
            m = S // step
            d_n = table[a * k:a * k + k, b * k:b * k + k, n].ravel()
            for r, e in enumerate(errs):
                per = closed_blocks(e, m, np.maximum).ravel()
                bnd = per + d_n + _SLACK * (np.abs(z).max() + 1.0) * 4
                out[:, r] = np.minimum(out[:, r], bnd)
        if new:  # the edit's tiles: the table holds their old δ_n
            ty = np.repeat(np.arange(a * k, a * k + k), k)
            tx = np.tile(np.arange(b * k, b * k + k), k)
            hit = (ty * S <= c.r1 - 1) & (ty * S + S >= c.r0) & (tx * S <= c.c1 - 1) & \
                (tx * S + S >= c.c0)
            out[hit] = np.inf
        return out

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


def _bounds(cell: Cell, zc: float, a0: np.ndarray, c0: np.ndarray, S: int, zlo: np.ndarray,
            zhi: np.ndarray) -> np.ndarray:
    """(tiles, 5) upper bounds of |z − P| over each tile (rows a0 … a0 + S, columns
    c0 … c0 + S of the block) for the block's centre surface and its four quarter
    planes (−inf where a tile misses a quarter): z within [zlo, zhi], P linear, so its
    extremes lie at the tile's corners."""
    i0, j0, s, main, z00, z01, z10, z11 = cell
    h = s // 2
    fi = np.stack([a0, a0, a0 + S, a0 + S], 1) / s
    dj = np.stack([c0, c0 + S, c0, c0 + S], 1).astype(np.float64)
    di = fi * s
    kl = (zc - 0.5 * (z00 + z10)) / h
    kr = (zc - 0.5 * (z01 + z11)) / h
    kt = (zc - 0.5 * (z00 + z01)) / h
    kb = (zc - 0.5 * (z10 + z11)) / h
    if main:
        p1 = z00 + (z10 - z00) * fi + (z11 - z10) / s * dj
        p2 = z00 + (z11 - z01) * fi + (z01 - z00) / s * dj
    else:
        p1 = z00 + (z10 - z00) * fi + (z01 - z00) / s * dj
        p2 = z11 + (z01 - z11) * (1.0 - fi) + (z10 - z11) - (z10 - z11) / s * dj
    planes = [np.concatenate([p1, p2], 1),
              z00 + (z10 - z00) * fi + kl * dj,
              z01 + (z11 - z01) * fi + kr * s - kr * dj,
              z00 + kt * di + (z01 - z00) / s * dj,
              z10 + kb * (s - di) + (z11 - z10) / s * dj]
    out = np.empty((len(a0), 5))
    for k, P in enumerate(planes):
        lo, hi = P.min(axis=1), P.max(axis=1)
        b = np.maximum(zhi - lo, hi - zlo)
        out[:, k] = b + _SLACK * (np.abs(zhi) + np.abs(zlo) + np.abs(lo) + np.abs(hi)) + 1e-300
    # which quarter each tile meets (closed: diagonal samples in both)
    r0, r1 = a0, a0 + S
    q0, q1 = c0, c0 + S
    fmax = lambda lo_, hi_: np.minimum(np.clip(h, lo_, hi_), s - np.clip(h, lo_, hi_))  # noqa: E731
    gmin = lambda lo_, hi_: np.maximum(np.clip(h, lo_, hi_), s - np.clip(h, lo_, hi_))  # noqa: E731
    out[:, 1] = np.where(q0 <= fmax(r0, r1), out[:, 1], -np.inf)
    out[:, 2] = np.where(q1 >= gmin(r0, r1), out[:, 2], -np.inf)
    out[:, 3] = np.where(r0 <= fmax(q0, q1), out[:, 3], -np.inf)
    out[:, 4] = np.where(r1 >= gmin(q0, q1), out[:, 4], -np.inf)
    return out


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
