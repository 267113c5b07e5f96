"""An edit computed over what it reaches only: the rows :mod:`.whole` would write, from a
few decoded tiles instead of the whole grid (issue 52; seed 004 §5.2, L42: deforming the
terrain at no extra cost).

For the window E of changed samples:

- **heights**: the tiles whose own samples change, or whose parent's decoded codes
  (their prediction, :mod:`geoterrain.codec.predict`) change, level by level from the
  top; each is coded as the whole-grid encoder codes it, and its decoded codes are
  compared with the old ones to find the next level's;
- **δ and r** (:mod:`.localbounds`): the vertices whose diamond holds a changed sample
  (their ancestors are such vertices too, so the saturation chain up to the root is
  among them); their δ is the exact diamond maximum, swept over the decoded tiles
  where a block fits in a tile and, for larger blocks, a tile at a time, only the
  tiles whose bound (the tile's height range against the block's planes) can beat the
  largest value found; saturation and nesting in the stored codes (a code of a
  maximum is the maximum of the codes);
- **tile rows**: valid counts and boxes from the changed tiles up; tile errors from
  the GeoMipMapping blocks' δ_n (the same field over a level-0 tile; the store keeps
  them rounded up, which bounds the others' exact values, so only the blocks that can
  hold the largest one are decoded); skirt errors along the tile borders E reaches;
- **normals**: every level's central differences within one sample of E.

On a root grid (issue 45: the top level a row or column of root tiles, each its own
bintree) the same steps run over the level's tiles across and down
(:meth:`~geoterrain.core.grid.Grid.tiles`) and the roots' extent: the saturation chain
ends at each root's top (half-spans below a root's side, as the preprocess's ``span``),
and every stored root is coded again with its edges filled first and its invalid
corners from the whole top level's fill (:func:`geoterrain.codec.pyramid.encode_root`),
so a window across two roots' shared edge rewrites both roots' blobs alike.

It takes projected and pixel frames, lossless stores (and stores coded within ε
without residual bins), unpadded grids (a square, or roots their raster fills) whose
block table covers every level; anything
else, and an edit that changes a number every tile's codes depend on (δ's or r's code
scale, the nodata stand-in height, a largest δ that only a full pass can find), goes to
:mod:`.whole`, which says why (:func:`unsupported`, :func:`local_plan`). Tested against
it and against a preprocess of the edited DEM.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoterrain.bounds.edgepad import has_padding
from geoterrain.bounds.leafbounds import ring_guesses
from geoterrain.bounds.normalbytes import NORMAL_BITS
from geoterrain.bounds.normals import encode_octahedral, normal_map
from geoterrain.bounds.tileblobs import BoundsCoding, level_blobs, ring_blobs
from geoterrain.bounds.vertexdata import LOG8, RING, shaped_zstd_level
from geoterrain.codec.predict import fill_outward
from geoterrain.codec.pyramid import decode_tile_valid, encode_child, encode_root
from geoterrain.codec.quantize import valid_codes
from geoterrain.preprocessing.edit.canvas import Canvas
from geoterrain.preprocessing.edit.whole import Plan, store_predictor, store_reader
from geoterrain.store.catalog import TILE_COLUMNS
from geoterrain.store.reader import StoreReader

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["local_plan", "ring_reached", "unsupported"]


def unsupported(terrain: TerrainLike, row: int, col: int, heights: np.ndarray,
                valid: np.ndarray) -> str:
    """Why the local computation cannot take this store ("" when it can).

    Examples
    --------
    >>> unsupported(t, 0, 0, np.zeros((1, 1)), np.ones((1, 1), bool))
    ''
    """
    g, f, q, m = terrain.grid, terrain.frame, terrain.quantizer, terrain.meta
    if f.kind == "geographic":
        return "a geographic grid's δ and r hold curvilinear terms"
    if q.bins > 1:
        return "heights coded in residual bins depend on the whole pyramid"
    if has_padding(g):
        return "a padded grid's second δ (the static mesh's) is not computed by tiles yet"
    if g.top_level > g.t or g.tile_samples < 3:
        return "the block table does not cover every level"
    if "block_delta_levels" not in m or m.get("normals_derived") not in (
            None, list(range(g.top_level + 1))):
        return "a store written before the block table and derived normals"
    with store_reader(terrain) as r:
        top = _stored_root(terrain)
        blob = r.get_blob(top, "delta")
        rblob = r.get_blob(top, "radius")
    if not (blob and len(blob) > 2 and blob[1] & LOG8 and rblob and len(rblob) > 2
            and rblob[1] & LOG8):
        return "δ or r not in log8 codes (an older store)"
    return ""


def local_plan(terrain: TerrainLike, row: int, col: int, heights: np.ndarray,
               valid: np.ndarray) -> tuple[Plan | None, str]:
    """The plan of the edit putting ``heights``/``valid`` at (``row``, ``col``), computed
    over what it reaches (module docstring); (None, why) when it needs the whole grid."""
    from geoterrain.preprocessing.edit.localbounds import Bounds

    job = _Job(terrain, Canvas(terrain, row, col, heights, valid))
    job.tile_numbers()
    job.heights()
    why = Bounds(job).run()
    if why:
        return None, why
    job.normals()
    job.metadata()
    return job.plan(), ""


def ring_reached(canvas: Canvas, span: int, step: int, x: int, y: int) -> bool:
    """Whether an edited sample lies within ``step`` samples of the border ring of the
    level tile (``x``, ``y``) of ``span`` samples a side (``step`` = 2^L).

    A derived-normals store keeps a tile's ring alone (``tileblobs.ring_blobs``): the
    ring's central differences read one level sample either side of it, and the guess
    it is stored against (``ring_guesses``) the tile's samples within one of its border.
    So where every edited sample lies farther inside, the blob is the stored one and is
    not coded again (``tests/preprocessing/test_edit_normals_reach.py``).

    Examples
    --------
    >>> c = Canvas.__new__(Canvas); c.r0, c.r1, c.c0, c.c1 = 10, 20, 10, 20
    >>> ring_reached(c, 64, 2, 0, 0), ring_reached(c, 16, 1, 0, 0)
    (False, True)
    """
    inner = (canvas.r0 > y * span + step and canvas.r1 - 1 < (y + 1) * span - step
             and canvas.c0 > x * span + step and canvas.c1 - 1 < (x + 1) * span - step)
    return not inner


def _e8(blob: bytes) -> int:
    return int(np.int8(np.uint8(blob[2])))


def _stored_root(terrain: TerrainLike) -> tuple[int, int, int]:
    """The first stored top tile (a root grid's root (top, 0, 0) may hold no data; every
    root's δ and r blobs record the store's code exponents)."""
    g = terrain.grid
    nx, ny = g.roots
    keys = [(g.top_level, x, y) for y in range(ny) for x in range(nx)]
    return next((k for k in keys if k in terrain.tile_info), keys[0])


def _first_level0(terrain: TerrainLike) -> tuple[int, int, int] | None:
    """``terrain.tile_keys(0)[0]`` (None where no level-0 tile is stored), without
    sorting every stored key where tile (0, 0, 0) is stored (the smallest there is)."""
    if (0, 0, 0) in terrain.tile_info:
        return (0, 0, 0)
    keys = terrain.tile_keys(0)
    return keys[0] if keys else None


class _Job:
    """One edit's computation: the canvas, the old store's rows, and what changes."""

    def __init__(self, terrain: TerrainLike, canvas: Canvas):
        self.t = terrain
        self.c = canvas
        self.g = terrain.grid
        # the terrain's reader where it has one (store_reader)
        own = getattr(terrain, "reader", None)
        self._own = not isinstance(own, StoreReader)
        self.reader = StoreReader(terrain.path) if self._own else own
        self.puts: dict = {}
        self._put: list = []  # (key, kind, blob) put, not yet compared with the store's
        self.dirty: list = []
        self.rows: dict = {}  # new tile rows (TILE_COLUMNS order), changed tiles only
        top = _stored_root(terrain)
        dblob = self.reader.get_blob(top, "delta")
        rblob = self.reader.get_blob(top, "radius")
        self.ed, self.er = _e8(dblob), _e8(rblob)
        first = _first_level0(terrain)
        self.derive_bounds = first is not None and self.g.top_level > 0 and bool(
            (self.reader.get_blob(first, "delta") or b"\0\0")[1] & RING)
        self.derive_normals = bool(terrain.meta.get("normals_derived"))
        self.ring_residual = terrain.meta.get("normals_ring_residual") is True
        self.meta = dict(terrain.meta)

    # ------------------------------------------------------------- shared helpers
    def old_row(self, key) -> tuple | None:
        info = self.t.tile_info.get(key)
        if info is None:
            return None
        return tuple(np.nan if info[c] is None else info[c] for c in TILE_COLUMNS)

    def row(self, key) -> tuple | None:
        """A tile's row as the edit leaves it (None: not stored)."""
        return self.rows[key] if key in self.rows else self.old_row(key)

    def set_row(self, key, **cols) -> None:
        r = list(self.row(key) or (0,) + (np.nan,) * (len(TILE_COLUMNS) - 1))
        for name, v in cols.items():
            r[TILE_COLUMNS.index(name)] = v
        self.rows[key] = tuple(r)

    def put(self, key, kind: str, blob: bytes) -> None:
        """Write ``blob`` where it differs from the stored one (compared in :meth:`plan`,
        the stored blobs read in one batch)."""
        self._put.append((key, kind, blob))

    def _settle(self) -> None:
        # the blobs put that differ from the stored ones: rewritten, their tiles dirty
        olds, _ = self.reader.get_blobs([(k, kind) for k, kind, _ in self._put])
        for (key, kind, blob), old in zip(self._put, olds, strict=True):
            if old != blob:
                self.puts[(key, kind)] = blob
                self.dirty_tile(key)
        self._put = []

    def dirty_tile(self, key) -> None:
        L, x, y = key
        span = self.g.tile_span(L)
        self.dirty.append((y * span, x * span, y * span + span + 1, x * span + span + 1))

    def tiles_near(self, L: int, margin: int) -> list[tuple[int, int]]:
        """Level-L tiles (x, y) whose closed footprint grown by ``margin`` samples meets
        the edit."""
        c, span, (nx, ny) = self.c, self.g.tile_span(L), self.g.tiles(L)
        y0 = max((c.r0 - margin - 1) // span, 0)
        y1 = min((c.r1 - 1 + margin) // span, ny - 1)
        x0 = max((c.c0 - margin - 1) // span, 0)
        x1 = min((c.c1 - 1 + margin) // span, nx - 1)
        return [(x, y) for y in range(y0, y1 + 1) for x in range(x0, x1 + 1)
                if c.touches(y * span - margin, x * span - margin, (y + 1) * span + margin,
                             (x + 1) * span + margin)]

    # ------------------------------------------------------------- tile rows
    def tile_numbers(self) -> None:
        """Valid counts and boxes of the tiles whose footprint holds an edited sample
        (level 0 from its samples, coarser levels from their children: a parent's closed
        footprint is the union of its children's)."""
        g, c, f = self.g, self.c, self.t.frame
        S = c.S
        near = self.tiles_near(0, 0)
        c.fetch([(0, x, y) for x, y in near])
        for x, y in near:
            h, v = c.tile(y, x)
            n = int(v.sum())
            key = (0, x, y)
            if n == 0:
                if key in self.t.tile_info:  # cannot happen with the edit modes
                    raise AssertionError("an edit removed a tile's last valid sample")
                continue
            z = h[v] * c.factor
            ii, jj = np.nonzero(v)
            X, Y = f.xy(ii + y * S, jj + x * S)
            self.set_row(key, nvalid=n, zmin=float(z.min()), zmax=float(z.max()),
                         xmin=float(X.min()), xmax=float(X.max()), ymin=float(Y.min()),
                         ymax=float(Y.max()), error=0.0, boundary_error=0.0)
        oldv = np.zeros(c.valid.shape, bool)
        ho, vo = _window(c, new=False)
        oldv[:] = vo
        delta_v = c.valid.astype(np.int64) - oldv.astype(np.int64)
        for L in range(1, g.top_level + 1):
            span = g.tile_span(L)
            for x, y in self.tiles_near(L, 0):
                a0, a1 = max(c.r0, y * span), min(c.r1, y * span + span + 1)
                b0, b1 = max(c.c0, x * span), min(c.c1, x * span + span + 1)
                dn = int(delta_v[a0 - c.r0:a1 - c.r0, b0 - c.c0:b1 - c.c0].sum())
                old = self.row((L, x, y))
                n = (0 if old is None else int(old[0])) + dn
                if n == 0:
                    continue
                kids = [self.row((L - 1, 2 * x + dx, 2 * y + dy)) for dy in (0, 1)
                        for dx in (0, 1)]
                kids = np.array([k for k in kids if k is not None], np.float64)
                cols = {"nvalid": n}
                for name, op in (("zmin", np.min), ("zmax", np.max), ("xmin", np.min),
                                 ("xmax", np.max), ("ymin", np.min), ("ymax", np.max)):
                    cols[name] = float(op(kids[:, TILE_COLUMNS.index(name)]))
                if old is None:
                    cols.update(error=0.0, boundary_error=0.0)
                self.set_row((L, x, y), **cols)

    def stored(self, key) -> bool:
        return self.row(key) is not None

    # ------------------------------------------------------------- heights
    def heights(self) -> None:
        """The height blobs the edit reaches, top to bottom (module docstring)."""
        g, c, t = self.g, self.c, self.t
        q = t.quantizer
        te, T, top = g.t, g.tile_samples, g.top_level
        cubic = store_predictor(t) == "cubic"
        wide = q.mode == "float"
        self.codes: dict = {}  # (L, x, y) → new decoded codes
        zero = int(valid_codes(np.zeros((1, 1)), np.ones((1, 1), bool), q)[0, 0])
        roots = self._top_level(zero)
        changed: list = []  # level-0 rectangles (closed) of changed decoded codes, a level up
        for L in range(top, -1, -1):
            step, span = 1 << L, g.tile_span(L)
            nx, ny = g.tiles(L)
            # the top level: every root (a root's fill reads the whole top level)
            cands = set(roots) if L == top else set(self.tiles_near(L, 2 * step))
            for r in changed:  # tiles whose prediction reads a changed parent sample
                for x in range(max((r[1] - 2 * step - 1) // span, 0),
                               min((r[3] + 2 * step) // span, nx - 1) + 1):
                    for y in range(max((r[0] - 2 * step - 1) // span, 0),
                                   min((r[2] + 2 * step) // span, ny - 1) + 1):
                        cands.add((x, y))
            changed = []
            if L < top:  # the stored ones in one batch (their parents come with them)
                c.fetch([(L, x, y) for x, y in cands])
            for x, y in sorted(cands):
                key = (L, x, y)
                if not self.stored(key):
                    continue
                if L == top and roots[(x, y)][2] is None:
                    # a root the edit leaves as it is (_top_level): its codes are decoded
                    # only if a child coded again reads them (as any unchanged parent's)
                    continue
                old = t.tile(*key) if key in t.tile_info else None
                if L == top:
                    codes, ok, blob = roots[(x, y)]
                    dec, _ = decode_tile_valid(blob, None, (x % 2, y % 2), te, q.bins)
                else:
                    codes = old.codes.copy() if old is not None else np.zeros((T, T), np.int64)
                    ok = old.valid.copy() if old is not None else np.zeros((T, T), bool)
                    _overlay(c, L, x, y, span, codes, ok)
                    pk = (L + 1, x // 2, y // 2)
                    parent = self.codes[pk] if pk in self.codes else t.tile(*pk).codes
                    blob = encode_child(codes, ok, parent, (x % 2, y % 2), te, cubic, q.bins,
                                        wide)
                    # its decoded codes: the codes just coded where nothing is left to decode
                    dec = child_codes(blob, codes, ok, parent, (x % 2, y % 2), te, q.bins)
                self.codes[key] = dec
                self.put(key, "heights", blob)
                diff = np.ones((T, T), bool) if old is None else (dec != old.codes)
                if diff.any():
                    ii, jj = np.nonzero(diff)
                    changed.append((y * span + int(ii.min()) * step, x * span + int(jj.min())
                                    * step, y * span + int(ii.max()) * step,
                                    x * span + int(jj.max()) * step))

    def _top_level(self, zero: int) -> dict:
        """(x, y) → (codes, validity, blob) of every stored root as the edit leaves it:
        the edit's codes over the top level's samples, invalid ones at ``zero`` (the code
        of height 0, as :func:`~geoterrain.codec.quantize.valid_codes` gives them), each
        root coded as the whole grid codes it. A root of a grid of several fills its
        edges first and takes its invalid corners from the fill of the whole top level
        (:func:`geoterrain.codec.pyramid.encode_root`): a window on the edge two roots
        share gives both the same codes there. A root whose closed footprint holds no
        edited sample and whose samples are all valid keeps its blob (None here): its
        codes are the old ones, and with no invalid sample no fill reads another root's.
        Where every sample of the grid is valid, such a root is not even decoded."""
        g, c, t = self.g, self.c, self.t
        q = t.quantizer
        te, T, top = g.t, g.tile_samples, g.top_level
        cubic = store_predictor(t) == "cubic"
        W, span = 1 << te, g.tile_span(top)
        nx, ny = g.roots
        codes = np.full((ny * W + 1, nx * W + 1), zero, np.int64)
        ok = np.zeros(codes.shape, bool)
        keys = [(x, y) for y in range(ny) for x in range(nx) if self.stored((top, x, y))]
        # every sample of the grid valid, before the edit and after it: no root is filled
        # from another's samples, so a root the edit does not reach is not decoded
        full = int(t.meta["valid_samples"]) == g.rows * g.cols and bool(c.valid.all())
        for x, y in keys:
            win = (slice(y * W, y * W + T), slice(x * W, x * W + T))
            if full and (top, x, y) in t.tile_info and not self._reaches_root(x, y):
                continue  # codes[win] stays at zero, ok[win] False: nothing reads them
            if (top, x, y) in t.tile_info:
                tl = t.tile(top, x, y)
                codes[win] = np.where(tl.valid, tl.codes, zero)
                ok[win] = tl.valid
            _overlay(c, top, x, y, span, codes[win], ok[win])
        codes = np.where(ok, codes, zero)
        edges = (nx, ny) != (1, 1)
        near = None
        if edges:
            near = codes.copy()
            fill_outward(near, ok)
        out = {}
        for x, y in keys:
            win = (slice(y * W, y * W + T), slice(x * W, x * W + T))
            if (top, x, y) in t.tile_info and (full or ok[win].all()) \
                    and not self._reaches_root(x, y):
                # its closed footprint holds no edited sample and every sample of it is
                # valid (so no fill reads another root's): its codes are the old ones,
                # and so is its blob (None: not coded again, 1.7 ms a 65² root)
                out[(x, y)] = (codes[win], ok[win], None)
                continue
            cw, ow = codes[win].copy(), ok[win].copy()
            out[(x, y)] = (cw, ow, encode_root(cw, ow, te, cubic, q.bins, edges,
                                               None if near is None else near[win].copy()))
        return out

    def _reaches_root(self, x: int, y: int) -> bool:
        """Whether root (x, y)'s closed footprint holds an edited sample."""
        span = self.g.tile_span(self.g.top_level)
        return self.c.touches(y * span, x * span, y * span + span, x * span + span)

    # ------------------------------------------------------------- normals
    def normals(self) -> None:
        """Every level's normal map within one of its samples of the edit (central
        differences of the level's samples), for the tiles that hold them: one window
        of the level's samples a level, its codes cut into the tiles' blobs."""
        g, c, f = self.g, self.c, self.t.frame
        te, (R, C) = g.t, g.extent
        for L in range(g.top_level + 1):
            step, span = 1 << L, g.tile_span(L)
            # a level-L sample in the edit (its rows and columns multiples of 2^L)
            if -(-c.r0 // step) * step >= c.r1 or -(-c.c0 // step) * step >= c.c1:
                continue
            keys = [(x, y) for x, y in self.tiles_near(L, step) if self.stored((L, x, y))
                    and (not self.derive_normals or ring_reached(c, span, step, x, y))]
            if not keys:
                continue
            x0, y0 = min(x for x, _ in keys), min(y for _, y in keys)
            x1, y1 = max(x for x, _ in keys), max(y for _, y in keys)
            # the tiles' samples and one more around (the central differences' neighbours)
            lo_i, lo_j = max(y0 * span - step, 0), max(x0 * span - step, 0)
            hi_i = min((y1 + 1) * span + step, R - 1)
            hi_j = min((x1 + 1) * span + step, C - 1)
            rows = np.arange(lo_i, hi_i + 1, step)
            cols = np.arange(lo_j, hi_j + 1, step)
            h, v = c.lattice(L, rows, cols)
            X, Y = f.xy(rows[:, None], cols[None, :])  # as on a meshgrid, broadcast
            zs = np.where(v, h * c.factor, np.nan)
            n = normal_map(X, Y, zs, v)
            a, b = (y0 * span - lo_i) // step, (x0 * span - lo_j) // step
            codes = encode_octahedral(n[a:, b:], NORMAL_BITS)  # from the first tile's corner
            tiles = [(x - x0, y - y0) for x, y in keys]
            if self.derive_normals:
                guess = None
                if self.ring_residual:  # schema 17: rings as differences from the derived
                    guess = ring_guesses(g, f, L, keys, zs[a:, b:], v[a:, b:],
                                         np.array([(dy << te, dx << te) for dx, dy in tiles],
                                                  np.int64).reshape(-1, 2))
                blobs = ring_blobs(codes, te, tiles, L, guess,
                                   shaped_zstd_level(g.rows, g.cols))
            else:
                coding = BoundsCoding(np.zeros(codes.shape[:2]), np.zeros(codes.shape[:2]))
                blobs = level_blobs(coding, codes, te, 0, 1, tiles, ("normals",))[0]["normals"]
                blobs = {(L, x, y): bb for (_, x, y), bb in blobs.items()}
            for (x, y), (dx, dy) in zip(keys, tiles, strict=True):
                self.put((L, x, y), "normals", blobs[(L, dx, dy)])

    # ------------------------------------------------------------- metadata
    def metadata(self) -> None:
        """The metadata's counts and ranges after the edit (the largest δ:
        :mod:`.localbounds`)."""
        g, c = self.g, self.c
        m = self.meta
        ho, vo = _window(c, new=False)
        dn = int(c.valid.sum()) - int(vo.sum())
        valid = int(m["valid_samples"]) + dn
        m["valid_samples"] = valid
        m["nodata_fraction"] = float(1.0 - valid / (g.rows * g.cols))
        lo, hi = self.scene_range()
        m["stand_in_z"] = float(0.5 * (lo + hi))
        m["height_range"] = self.height_range(lo, hi)

    def level0(self, new: bool = True) -> np.ndarray:
        """The level-0 tiles' valid counts, smallest and largest scene heights, as
        (3, nt, nt) arrays (0, +inf, −inf for a tile not stored), before or after."""
        key = "_level0_new" if new else "_level0_old"
        if not hasattr(self, key):
            nx, ny = self.g.tiles(0)
            a = np.zeros((3, ny, nx))
            a[1], a[2] = np.inf, -np.inf
            table = self.reader.table()  # the rows tile_info holds, as arrays
            lev0 = (table.tiles & 31) == 0
            m = table.tiles[lev0] >> 5  # Morton number of (x, y): keys.tile_key
            nums = np.asarray(table.numbers, np.float64).reshape(len(table.tiles), -1)[lev0]
            cols = [TILE_COLUMNS.index(c) for c in ("nvalid", "zmin", "zmax")]
            a[:, _compact(m >> 1), _compact(m)] = nums[:, cols].T
            if new:
                for k in self.rows:
                    if k[0] == 0:
                        a[:, k[2], k[1]] = self.rows[k][:3]
            setattr(self, key, a)
        return getattr(self, key)

    def scene_range(self) -> tuple[float, float]:
        """The smallest and largest valid scene height, from the level-0 tile rows."""
        a = self.level0()
        return float(a[1].min()), float(a[2].max())

    def height_range(self, lo: float, hi: float) -> list[float]:
        """The valid heights' range in source units: decoded from the tiles that hold
        the scene range's ends."""
        a = self.level0()
        ends = [np.nonzero(a[col] == end) for col, end in ((1, lo), (2, hi))]
        # their tiles and ancestors not cached in one batch (then decoded from the cache)
        self.c.fetch([(0, int(tx), int(ty)) for e in ends for ty, tx in zip(*e, strict=True)])
        out = []
        for (ys, xs), op in zip(ends, (np.min, np.max), strict=True):
            vals = []
            for ty, tx in zip(ys, xs, strict=True):
                h, v = self.c.tile(int(ty), int(tx))
                vals.append(float(op(h[v])))
            out.append(float(op(vals)))
        return out

    # ------------------------------------------------------------- the plan
    def plan(self) -> Plan:
        self._settle()
        out = {}
        for k, r in self.rows.items():
            r = list(r)
            r[0] = int(r[0])
            out[k] = tuple(r)
        if self._own:
            self.reader.close()
        return Plan(self.puts, set(), out, self.meta, self.dirty, how="tiles",
                    all_tiles=False)


def _compact(m: np.ndarray) -> np.ndarray:
    """The even bits of Morton numbers ``m``, packed (:func:`geoterrain.store.keys.tile_key`
    interleaves x in the even bits, y in the odd ones)."""
    x = np.asarray(m, np.int64) & 0x5555555555555555
    for shift, mask in ((1, 0x3333333333333333), (2, 0x0F0F0F0F0F0F0F0F),
                        (4, 0x00FF00FF00FF00FF), (8, 0x0000FFFF0000FFFF),
                        (16, 0x00000000FFFFFFFF)):
        x = (x | (x >> shift)) & mask
    return x


def _window(c: Canvas, new: bool) -> tuple[np.ndarray, np.ndarray]:
    """The edit's window's heights and validity, before or after."""
    if new:
        return c.heights, c.valid
    z, v = c.rect(c.r0, c.c0, c.r1, c.c1, new=False)
    return z / c.factor, v.astype(bool)


def child_codes(blob: bytes, codes: np.ndarray, ok: np.ndarray, parent: np.ndarray,
                parity: tuple[int, int], te: int, bins: int) -> np.ndarray:
    """The decoded codes of a non-top tile's ``blob`` that :func:`encode_child` just
    coded from ``codes`` and ``ok`` over ``parent``: ``codes`` themselves where every
    sample is valid, the bins are 1 (lossless) and the tile's even samples are its
    parent's (nothing to decode: a decode gives them back), else the blob decoded.

    Examples
    --------
    >>> c = np.arange(25, dtype=np.int64).reshape(5, 5); ok = np.ones((5, 5), bool)
    >>> p = np.zeros((5, 5), np.int64); p[:3, :3] = c[::2, ::2]
    >>> b = encode_child(c, ok, p, (0, 0), 2, False)
    >>> child_codes(b, c, ok, p, (0, 0), 2, 1) is c
    True
    >>> bool((child_codes(b, c + 1, ok, p, (0, 0), 2, 1) == c).all())  # decoded: c + 1
    True
    """
    h = (codes.shape[0] - 1) // 2
    px, py = parity
    if bins == 1 and ok.all() and np.array_equal(
            codes[::2, ::2], parent[py * h:py * h + h + 1, px * h:px * h + h + 1]):
        return codes
    return decode_tile_valid(blob, parent, parity, te, bins)[0]


def _overlay(c: Canvas, L: int, x: int, y: int, span: int, codes: np.ndarray,
             ok: np.ndarray) -> None:
    """Put the edit's codes and validity on tile (L, x, y)'s samples (in place)."""
    step = 1 << L
    i0, j0 = y * span, x * span
    a = np.arange(-(-max(c.r0 - i0, 0) // step), min(c.r1 - 1 - i0, span) // step + 1)
    b = np.arange(-(-max(c.c0 - j0, 0) // step), min(c.c1 - 1 - j0, span) // step + 1)
    if a.size and b.size:
        rr = i0 + a * step - c.r0
        cc = j0 + b * step - c.c0
        codes[np.ix_(a, b)] = c.codes[np.ix_(rr, cc)]
        ok[np.ix_(a, b)] = c.valid[np.ix_(rr, cc)]
