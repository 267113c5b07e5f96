"""Per-tile arrays in contiguous slabs, loaded once per tile and read by compiled kernels.

A view touches ~100 candidate tiles per frame. Stacking their δ, r, heights and
positions into fresh arrays every frame cost more than the refinement itself;
here each tile's arrays are copied once into a slot of a per-terrain slab
(``D``, ``R`` float32; ``H``, ``X``, ``Y`` float64, all (slots, T, T)), and the
kernels index the slabs by slot. A flat table maps (level, x, y) to its slot.
Where the frame is affine (projected and pixel grids) x and y are not stored: the
kernels compute them from ``aff`` (:func:`~geoterrain.lod.kernels.sample_xy`).

The slabs have a byte budget: when a request needs more slots than are free,
the least recently used slots that the request does not need are reused.
A single request larger than the budget grows the slabs (correctness first).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geoterrain.lod.kernels import BLOCK, block_bounds

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

KINDS = ("delta", "radius", "height", "xy", "blocks", "delta_edge")
# per sample; "delta_edge" (the static mesh of a padded store, edgepad.py) is not
# budgeted: its pages are committed only on the few slots it is loaded into
_BYTES = {"delta": 4, "radius": 4, "height": 8, "xy": 16, "blocks": 0, "delta_edge": 0}
BUDGET_BYTES = 384 << 20

_NONE = np.zeros(0, np.int64)


class PoolSlabs(NamedTuple):
    """A pool's slabs as the compiled kernels read them (:meth:`TilePool.slabs`): the
    slot table (level ``L``'s tiles from ``base[L]``, ``top`` the top level, ``t`` log2
    of a tile's cells a side; ``slot_of`` −1: not pooled), the per-slot δ ``D``, r ``R``,
    heights ``H``, x, y ``X``, ``Y`` (empty for an affine frame, computed from ``aff``)
    and block bounds ``BK``, and ``zfac``: a height times it is a scene z (``Frame.z``)."""

    top: int
    t: int
    base: np.ndarray
    slot_of: np.ndarray
    D: np.ndarray
    R: np.ndarray
    H: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    aff: np.ndarray
    BK: np.ndarray
    zfac: float


class PooledTiles(NamedTuple):
    """Tiles as the compiled kernels walk them: per tile its pool slot, the grid row
    ``i0`` and column ``j0`` of its first sample, its sample spacing ``step`` (2^L) and
    ``level`` L; ``tx``, ``ty``, ``tps`` and ``tpd`` (its x, y and its level's tiles
    across and down: a side, on a square grid) only for the kernels that need them
    (:mod:`geoterrain.lod.leaves`), else empty."""

    slots: np.ndarray
    i0: np.ndarray
    j0: np.ndarray
    step: np.ndarray
    level: np.ndarray
    tx: np.ndarray = _NONE
    ty: np.ndarray = _NONE
    tps: np.ndarray = _NONE
    tpd: np.ndarray = _NONE


class TilePool:
    """The slabs of one terrain. Use :func:`tile_pool` to get the terrain's pool."""

    def __init__(self, terrain: TerrainLike, budget_bytes: int = BUDGET_BYTES):
        g = terrain.grid
        self.terrain = weakref.proxy(terrain)
        self.grid = g
        # N: the flags' row stride (a square's side; a root grid's extent's columns)
        self.top, self.t, self.N = g.top_level, g.t, g.extent[1]
        self.T = g.tile_samples
        # per BLOCK² block of a tile: its bounds for fill_lp (kernels.block_bounds)
        self.nb = max(1, (self.T - 1) // BLOCK)
        # slot table: level L holds 4^(top-L) tiles (a root grid: tiles(L)), row-major
        # (ty, tx), from base[L]; the kernels' table (kbase) adds a root grid's counts
        self.base = g.offsets()
        self.kbase = g.walk_table()
        self.slot_of = np.full(int(self.base[-1]), -1, np.int32)
        f = terrain.frame
        # geographic: all 0, x, y from the slabs (pyproj, cached per tile); aff[9] = 1
        # marks an affine frame. Always 10 numbers: a parallel loop may load them before
        # its branch on aff[9] (a load past an empty array's end, seen under numba's
        # bounds checks in the shape sweep)
        self.aff = np.zeros(10)
        if f.kind != "geographic":
            self.aff = np.array([*f.transform[:6], *f.origin_crs, f.unit_to_m, 1.0],
                                np.float64)
        kinds = KINDS if not self.affine else [k for k in KINDS if k != "xy"]
        per_slot = (self.T * self.T * sum(_BYTES[k] for k in kinds)
                    + self.nb ** 2 * 9 * 8)  # + each block's nine float64 bounds
        self.capacity = 0
        self.budget_slots = max(16, budget_bytes // per_slot)
        self.key_of = np.zeros((0,), np.int64)  # table index of each slot, -1 if free
        self.stamp = np.zeros((0,), np.int64)
        self.have = {k: np.zeros((0,), bool) for k in KINDS}
        self.D = np.zeros((0, self.T, self.T), np.float32)
        self.DE = np.zeros((0, self.T, self.T), np.float32)
        self.R = np.zeros((0, self.T, self.T), np.float32)
        self.H = np.zeros((0, self.T, self.T), np.float64)
        self.X = np.zeros((0, self.T, self.T), np.float64)
        self.Y = np.zeros((0, self.T, self.T), np.float64)
        self.BK = np.zeros((0, self.nb, self.nb, 9), np.float64)
        self.clock = 0
        self.stored = np.zeros(int(self.base[-1]), bool)
        if terrain.tile_info:
            self.stored[self.table_index(np.array(list(terrain.tile_info), np.int64))] = True
        # unstored tiles with a second δ (edgepad.py): served only with "delta_edge",
        # their heights NaN (the static mesh replicates the padding's)
        self.edge_only = np.zeros(int(self.base[-1]), bool)
        only = [k for k in (terrain.edge_max or {}) if k not in terrain.tile_info]
        if only:
            self.edge_only[self.table_index(np.array(only, np.int64))] = True

    @property
    def affine(self) -> bool:
        """Whether x, y are computed from ``aff`` (projected and pixel frames), not pooled."""
        return bool(self.aff[9])

    def origins(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid row and column of the first sample of the (L, x, y) tiles ``keys`` (K, 3),
        and their sample spacing 2^L."""
        L = keys[:, 0]
        return (keys[:, 2] << self.t) << L, (keys[:, 1] << self.t) << L, np.int64(1) << L

    def slabs(self, zfac: float) -> PoolSlabs:
        """The slabs as they are now (a later :meth:`slots` may grow them), heights
        scaled by ``zfac`` to scene z."""
        return PoolSlabs(self.top, self.t, self.kbase, self.slot_of, self.D, self.R, self.H,
                         self.X, self.Y, self.aff, self.BK, float(zfac))

    def table_index(self, keys: np.ndarray) -> np.ndarray:
        """Index into the slot table of (L, x, y) keys (K, 3)."""
        L = keys[:, 0]
        if not self.grid.square:
            return self.grid.table_index(keys)
        return self.base[L] + keys[:, 2] * (np.int64(1) << (self.top - L)) + keys[:, 1]

    def _grow(self, n: int) -> None:
        # The first growth reserves the whole budget: np.zeros pages are only
        # committed when a slot is written, so untouched slots cost no memory, and
        # later requests need no copy of the slabs (a copy stalled frames for 0.1 s).
        new = max(n, self.budget_slots, 16) if self.capacity == 0 else n
        extra = new - self.capacity
        if extra <= 0:
            return
        T = self.T

        def more(a, dtype):
            if self.capacity == 0:
                return np.zeros((new, T, T), dtype)
            return np.concatenate([a, np.zeros((extra, T, T), dtype)])

        self.D, self.R = more(self.D, np.float32), more(self.R, np.float32)
        self.DE = more(self.DE, np.float32)
        self.H = more(self.H, np.float64)
        self.BK = (np.zeros((new, self.nb, self.nb, 9)) if self.capacity == 0 else
                   np.concatenate([self.BK, np.zeros((extra, self.nb, self.nb, 9))]))
        if not self.affine:
            self.X, self.Y = more(self.X, np.float64), more(self.Y, np.float64)
        self.key_of = np.concatenate([self.key_of, np.full(extra, -1, np.int64)])
        self.stamp = np.concatenate([self.stamp, np.zeros(extra, np.int64)])
        for k in KINDS:
            self.have[k] = np.concatenate([self.have[k], np.zeros(extra, bool)])
        self.capacity = new

    def slots(self, idx: np.ndarray, kinds: tuple[str, ...]) -> np.ndarray:
        """Slots of the stored tiles with table indices ``idx``, their ``kinds`` loaded,
        in order (``"blocks"`` needs the other four loaded before it).

        Tiles that are not stored get slot −1 (the kernels read δ = r = 0, height NaN).
        """
        self.clock += 1
        idx = np.asarray(idx, np.int64)
        out = np.full(len(idx), -1, np.int32)
        ok = self.stored[idx]
        if "delta_edge" in kinds:
            ok = ok | self.edge_only[idx]
        sl = self.slot_of[idx]
        missing = np.unique(idx[ok & (sl < 0)])
        if len(missing):
            self._assign(missing, np.unique(idx[ok]))
            sl = self.slot_of[idx]
        out[ok] = sl[ok]
        used = np.unique(out[ok])
        self.stamp[used] = self.clock
        for kind in kinds:
            need = used[~self.have[kind][used]]
            for s in need.tolist():
                self._load(s, kind)
        return out

    def _assign(self, missing: np.ndarray, wanted: np.ndarray) -> None:
        free = np.flatnonzero(self.key_of < 0)
        if len(free) < len(missing) and self.capacity < self.budget_slots:
            self._grow(min(self.budget_slots, self.capacity + len(missing) - len(free)))
            free = np.flatnonzero(self.key_of < 0)
        if len(free) < len(missing):  # evict the least recently used, never a wanted one
            busy = np.zeros(self.capacity, bool)
            held = self.slot_of[wanted]
            busy[held[held >= 0]] = True
            cand = np.flatnonzero((self.key_of >= 0) & ~busy)
            cand = cand[np.argsort(self.stamp[cand], kind="stable")]
            drop = cand[:len(missing) - len(free)]
            self.slot_of[self.key_of[drop]] = -1
            self.key_of[drop] = -1
            for k in KINDS:
                self.have[k][drop] = False
            free = np.flatnonzero(self.key_of < 0)
        if len(free) < len(missing):
            self._grow(self.capacity + len(missing) - len(free))
            free = np.flatnonzero(self.key_of < 0)
        use = free[:len(missing)]
        self.key_of[use] = missing
        self.slot_of[missing] = use.astype(np.int32)

    def _key(self, s: int) -> tuple[int, int, int]:
        i = int(self.key_of[s])
        if not self.grid.square:
            return self.grid.key_of(i)
        L = int(np.searchsorted(self.base, i, side="right") - 1)
        r = i - int(self.base[L])
        side = 1 << (self.top - L)
        return L, r % side, r // side

    def _load(self, s: int, kind: str) -> None:
        t, key = self.terrain, self._key(s)
        if kind == "delta":
            self.D[s] = t.tile_delta(*key)
        elif kind == "delta_edge":
            self.DE[s] = t.tile_delta_edge(*key)
        elif kind == "radius":
            self.R[s] = t.tile_radius(*key)
        elif kind == "height":
            self.H[s] = (t.tile(*key).heights if key in t.tile_info else np.nan)
        elif kind == "blocks":  # after delta, radius, height and xy (see slots)
            i0, j0, step = (int(v[0]) for v in self.origins(np.array([key], np.int64)))
            block_bounds(self.D, self.R, self.H, self.X, self.Y, self.aff, s, i0, j0, step,
                         key[0] < self.top, self.BK[s])
        elif not self.affine:  # affine frames: x, y computed in the kernels
            self.X[s], self.Y[s] = t.tile_xy(*key)
        self.have[kind][s] = True


def tile_pool(terrain: TerrainLike) -> TilePool:
    """The :class:`TilePool` of ``terrain`` (made on first use, kept with the terrain)."""
    return terrain.derived(__name__, lambda: TilePool(terrain))
