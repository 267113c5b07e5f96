"""The tile errors, skirt errors and GeoMipMapping blocks' δ_n of an edit, over what it
reaches (:mod:`.local`, after :mod:`.localbounds`'s δ and r): the blocks the edit
reaches get their level fields again; a tile's error is the largest of its blocks'
(the others' stored values, rounded up, bound theirs, so only the blocks that can hold
the largest are computed) and its children's.

A tile's error and skirt error are maxima over its blocks (seed 000 §2.4's field pooled
over a footprint, or over its border lines), and the blocks the edit does not reach keep
their values: where the old maximum was held by such a block (the tile's old stored
value beats the reached blocks' old values), it is the unreached blocks' maximum, and
the new one is the larger of it and the reached blocks' new values, with no other block
read. Otherwise (the old maximum may have been in the reached blocks and dropped) the
blocks that can hold the largest are computed as above.
"""

from __future__ import annotations

import numpy as np

from geoterrain.bounds.tilebounds import pack_block_errors
from geoterrain.bounds.windows import level_field_rect
from geoterrain.store.catalog import TILE_COLUMNS

__all__ = ["TileErrors", "WholeGrid"]

_E, _B = TILE_COLUMNS.index("error"), TILE_COLUMNS.index("boundary_error")


class WholeGrid(Exception):
    """The edit needs the whole grid (the message says why)."""


class TileErrors:
    """The tile rows' errors and the block table of one edit (``job``:
    :class:`.local._Job`, its tile rows already updated)."""

    def __init__(self, job):
        self.job = job
        self.t, self.g, self.c = job.t, job.g, job.c
        self.R, self.C = self.g.extent  # the square's N × N, or the roots' extent
        self.S = 1 << self.g.t

    def run(self) -> None:
        """The blocks' δ_n, every tile's error and the skirt errors along the borders the
        edit reaches (:func:`geoterrain.bounds.tilebounds.tile_and_block_errors`)."""
        g, job, c, S = self.g, self.job, self.c, self.S
        table = self.t.block_errors()
        if table is None or table.shape[2] <= g.top_level:
            raise WholeGrid("the block table does not cover every level")
        new = np.array(table, np.float64)
        self._fields: dict = {}
        self._old_fields: dict = {}  # the reached blocks' fields before the edit
        self.shortcuts = self.fallbacks = 0  # tiles' errors from the old rows / by blocks
        nbx, nby = g.tiles(0)
        changed_blocks = {}
        for L in range(1, g.top_level + 1):
            sl = 1 << L
            lo_r, hi_r = max((-(-c.r0 // sl) - 1) * sl, 0), ((c.r1 - 1) // sl + 1) * sl
            lo_c, hi_c = max((-(-c.c0 // sl) - 1) * sl, 0), ((c.c1 - 1) // sl + 1) * sl
            blocks = [(ty, tx) for ty in range(max((lo_r - 1) // S, 0), min(hi_r // S, nby - 1) + 1)
                      for tx in range(max((lo_c - 1) // S, 0), min(hi_c // S, nbx - 1) + 1)
                      if ty * S <= hi_r and ty * S + S >= lo_r and tx * S <= hi_c
                      and tx * S + S >= lo_c]
            self._fields_batch(blocks, L)
            for ty, tx in blocks:
                e, mixed = self._field(ty, tx, L)[:2]
                new[ty, tx, L] = np.inf if mixed else e
            changed_blocks[L] = set(blocks)
            self._region = getattr(self, "_region", {})
            self._region[L] = (lo_r, lo_c, hi_r, hi_c)
        self._changed = changed_blocks
        job.put((g.top_level, 0, 0), "block_delta", pack_block_errors(new))
        for L in range(1, g.top_level + 1):
            span = g.tile_span(L)
            k = 1 << L  # blocks per tile side
            for x, y in job.tiles_near(L, 1 << L):
                key = (L, x, y)
                if job.row(key) is None:
                    continue
                kids = [(L - 1, 2 * x + dx, 2 * y + dy) for dy in (0, 1) for dx in (0, 1)]
                own = self._own_error(y * k, x * k, k, L, new, changed_blocks[L],
                                      self._old_own(key, kids))
                err = max([own] + [r[3] for r in map(job.row, kids) if r is not None])
                cols = {"error": float(err)}
                lo_r, lo_c, hi_r, hi_c = self._region[L]
                if any(lo_r <= line <= hi_r for line in (y * span, y * span + span)) and \
                        x * span <= hi_c and x * span + span >= lo_c or \
                        any(lo_c <= line <= hi_c for line in (x * span, x * span + span)) and \
                        y * span <= hi_r and y * span + span >= lo_r:
                    old = job.old_row(key)
                    cols["boundary_error"] = float(self._skirt(
                        x, y, L, new, changed_blocks[L], None if old is None else float(old[_B])))
                job.set_row(key, **cols)

    def _old_own(self, key: tuple, kids: list) -> float | None:
        """The tile's own error before the edit (the largest of its blocks' fields), where
        its old row tells it: its error is the larger of its own and its children's
        (:func:`~geoterrain.bounds.tilebounds.tile_rows`), so it is its own where it beats
        the children's, or is 0 (None: not known, or +inf)."""
        job = self.job
        old = job.old_row(key)
        if old is None:
            return None
        e = float(old[_E])
        k = max([0.0] + [float(r[_E]) for r in map(job.old_row, kids) if r is not None])
        return e if np.isfinite(e) and (e > k or e == 0.0) else None

    def _old_field(self, ty: int, tx: int, L: int) -> tuple:
        """:meth:`_field` before the edit (the blocks the edit reaches, level by level in
        one window)."""
        if (ty, tx, L) not in self._old_fields:
            self._fields_batch(sorted(self._changed[L]), L, new=False)
        return self._old_fields[(ty, tx, L)]

    def _fields_batch(self, blocks: list, L: int, new: bool = True) -> None:
        """:meth:`_field` of every block in ``blocks``' bounding rectangle, from one
        window (``new``: after the edit, else before it, into ``_old_fields``)."""
        if not blocks:
            return
        S, sl = self.S, 1 << L
        ys = [b[0] for b in blocks]
        xs = [b[1] for b in blocks]
        i0, j0 = max(min(ys) * S - sl, 0), max(min(xs) * S - sl, 0)
        i1 = min((max(ys) + 1) * S + sl, self.R - 1)
        j1 = min((max(xs) + 1) * S + sl, self.C - 1)
        z, v = self.c.rect(i0, j0, i1 + 1, j1 + 1, new)
        E = np.zeros(z.shape)
        mixed = np.zeros(((i1 - i0) // sl, (j1 - j0) // sl), np.bool_)
        level_field_rect(z, v, i0, j0, sl, E, mixed)
        out = self._fields if new else self._old_fields
        for ty in range(min(ys), max(ys) + 1):
            for tx in range(min(xs), max(xs) + 1):
                a, b = ty * S - i0, tx * S - j0
                Eb = E[a:a + S + 1, b:b + S + 1]
                mb = mixed[a // sl:a // sl + S // sl, b // sl:b // sl + S // sl]
                out[(ty, tx, L)] = (float(Eb.max()), bool(mb.any()), Eb, mb)

    def _field(self, ty: int, tx: int, L: int) -> tuple:
        """Block (ty, tx)'s level-L field as the edit leaves it: (max over its closed
        footprint, whether one of its cells is mixed, E on its footprint, its cells'
        mixed flags)."""
        key = (ty, tx, L)
        got = self._fields.get(key)
        if got is not None:
            return got
        S, sl = self.S, 1 << L
        i0, j0 = max(ty * S - sl, 0), max(tx * S - sl, 0)
        i1, j1 = min(ty * S + S + sl, self.R - 1), min(tx * S + S + sl, self.C - 1)
        z, v = self.c.rect(i0, j0, i1 + 1, j1 + 1)
        E = np.zeros(z.shape)
        mixed = np.zeros(((i1 - i0) // sl, (j1 - j0) // sl), np.bool_)
        level_field_rect(z, v, i0, j0, sl, E, mixed)
        a, b = ty * S - i0, tx * S - j0
        Eb = E[a:a + S + 1, b:b + S + 1]
        mb = mixed[a // sl:a // sl + S // sl, b // sl:b // sl + S // sl]
        got = self._fields[key] = (float(Eb.max()), bool(mb.any()), Eb, mb)
        return got

    def _own_error(self, by: int, bx: int, k: int, L: int, table: np.ndarray,
                   changed: set, own_old: float | None = None) -> float:
        """max over the tile's k × k blocks of their level-L field (+inf if one has a
        mixed cell): exact where the edit changed them; the others keep their values,
        whose maximum is ``own_old`` (the tile's own error before the edit, None where not
        known) if that beats the changed blocks' old values (module docstring); else
        their stored values (rounded up) bound theirs, so only those that may hold the
        maximum are computed."""
        vals = table[by:by + k, bx:bx + k, L]
        if np.isinf(vals).any():
            return np.inf
        exact = np.full(vals.shape, np.nan)
        mine = [(ty, tx) for ty, tx in changed if by <= ty < by + k and bx <= tx < bx + k]
        for ty, tx in mine:
            exact[ty - by, tx - bx] = self._field(ty, tx, L)[0]
        best = float(np.nanmax(exact)) if np.isfinite(exact).any() else 0.0
        if own_old is not None and len(mine) < k * k:
            was = max([0.0] + [self._old_field(ty, tx, L)[0] for ty, tx in mine])
            if own_old > was:  # an unreached block held it, and holds it still
                self.shortcuts += 1
                return max(best, own_old)
        self.fallbacks += 1
        order = np.argsort(-vals, axis=None)
        for q in order.tolist():
            a, b = divmod(q, k)
            if vals[a, b] <= best:
                break
            if np.isnan(exact[a, b]):
                best = max(best, self._field(by + a, bx + b, L)[0])
        return best

    def _skirt(self, x: int, y: int, L: int, table: np.ndarray, changed: set = frozenset(),
               old: float | None = None) -> float:
        """The tile's skirt error: the largest level-L field on its four border lines,
        +inf if a cell along them inside the tile is mixed. ``old``: the tile's skirt
        error before the edit (None: not known): where it is finite and beats the old
        values on the border lines of the blocks the edit reached (``changed``), it is
        the other lines' maximum, which the edit keeps (module docstring)."""
        g = self.g
        k = 1 << L
        by, bx = y * k, x * k
        nbx, nby = g.tiles(0)
        best = 0.0
        # (block inside, which line of it, the block across) per border segment
        segs = []
        for q in range(k):
            segs += [((by, bx + q), "top", (by - 1, bx + q)),
                     ((by + k - 1, bx + q), "bottom", (by + k, bx + q)),
                     ((by + q, bx), "left", (by + q, bx - 1)),
                     ((by + q, bx + k - 1), "right", (by + q, bx + k))]
        if old is not None and np.isfinite(old):
            mine = [(inside, line) for inside, line, _ in segs if inside in changed]
            if len(mine) < len(segs):
                sides = {"top": lambda a: a[0], "bottom": lambda a: a[-1],
                         "left": lambda a: a[:, 0], "right": lambda a: a[:, -1]}
                was = max([0.0] + [float(sides[line](self._old_field(*b, L)[2]).max())
                                   for b, line in mine])
                if old > was:  # an unreached line held it, and holds it still
                    self.shortcuts += 1
                    best = old
                    for b, line in mine:
                        _, _, E, mb = self._field(*b, L)
                        if sides[line](mb).any():
                            return np.inf
                        best = max(best, float(sides[line](E).max()))
                    return best
        self.fallbacks += 1
        bounds = []
        for inside, _, across in segs:
            b = table[inside[0], inside[1], L]
            if 0 <= across[0] < nby and 0 <= across[1] < nbx:
                b = min(b, table[across[0], across[1], L])
            bounds.append(b)
        for n in np.argsort(-np.array(bounds)).tolist():
            inside, line, _ = segs[n]
            mixed_possible = np.isinf(table[inside[0], inside[1], L])
            if bounds[n] <= best and not mixed_possible:
                continue
            _, _, E, mb = self._field(inside[0], inside[1], L)
            cells = {"top": mb[0], "bottom": mb[-1], "left": mb[:, 0], "right": mb[:, -1]}[line]
            if cells.any():
                return np.inf
            vals = {"top": E[0], "bottom": E[-1], "left": E[:, 0], "right": E[:, -1]}[line]
            best = max(best, float(vals.max()))
        return best
