"""The padded domain and its pyramid of (2^t+1)² tiles (docs/conventions.md).

Two layouts. ``square``: the raster padded to one (2^n+1)² square, a single top tile.
``roots``: level 0 padded only to the next multiple of the tile span a side, level L
holding ``ceil((cols − 1) / 2^(t+L))`` × ``ceil((rows − 1) / 2^(t+L))`` tiles, up to a
top level of at most two root tiles (1 × 1, 2 × 1 or 1 × 2, each 2^n level-0 samples a
side). A square grid is the roots grid whose every level is a power-of-two square; a grid
whose two layouts give the same tiles is always written as ``square``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import asdict, dataclass
from functools import cached_property

import numpy as np

from geoterrain.exceptions import UsageError


def level_offsets(top: int) -> np.ndarray:
    """Where each level starts in the dense (level, y, x) table of every tile of a
    pyramid with levels 0 … ``top`` (4^(top−L) tiles at level L): tile (L, x, y) is entry
    ``offsets[L] + y·2^(top−L) + x``; ``offsets[-1]`` is the table's size.

    Examples
    --------
    >>> level_offsets(2).tolist()
    [0, 16, 20, 21]
    """
    return np.concatenate([[0], np.cumsum(4 ** np.arange(top, -1, -1))]).astype(np.int64)


LAYOUTS = ("square", "roots")
MAX_ROOTS = 2  # the top level holds at most this many tiles (Cesium's geographic 2 × 1)


class RootGridError(UsageError, ValueError):
    """A square-only computation was asked of a grid with a rectangular root grid."""


def _tiles_over(samples: int, span: int) -> int:
    """Tiles of ``span`` samples between borders that cover ``samples`` samples (≥ 1)."""
    return max(1, -(-(samples - 1) // span))


@dataclass(frozen=True)
class Grid:
    """Index arithmetic of the padded domain, levels and tiles.

    Examples
    --------
    >>> g = Grid.for_shape(868, 884, tile_size=64)
    >>> g.size, g.tile_samples, g.top_level
    (1025, 65, 4)
    >>> g.tiles_per_side(0), g.parent(0, 5, 3)
    (16, (1, 2, 1))
    >>> r = Grid.for_shape(520, 1180, tile_size=64, roots=True)
    >>> r.shape, r.tiles(0), r.roots, r.top_level, r.extent
    ((577, 1217), (19, 9), (2, 1), 4, (1025, 2049))
    """

    rows: int  # source raster rows (H)
    cols: int  # source raster columns (W)
    n: int  # square: padded size N = 2**n + 1; roots: a root tile spans 2**n samples
    t: int  # tile size T = 2**t + 1
    layout: str = "square"  # or "roots" (see the module's docstring)

    def __post_init__(self):
        if self.layout not in LAYOUTS:
            raise ValueError(f"Expected grid layout in {LAYOUTS}, got {self.layout!r}.")

    @staticmethod
    def for_shape(rows: int, cols: int, tile_size: int = 64, roots: bool = False) -> Grid:
        """The grid of a rows × cols raster: one padded square, or with ``roots`` the
        rectangular root grid (which is the square one whenever they tile alike)."""
        if tile_size < 2 or tile_size & (tile_size - 1):
            raise ValueError(f"Expected tile size to be a power of two ≥ 2, got {tile_size}.")
        n = max(1, int(np.ceil(np.log2(max(rows, cols) - 1))) if max(rows, cols) > 2 else 1)
        square = Grid(rows, cols, n, min(int(np.log2(tile_size)), n))
        if not roots:
            return square
        t = square.t
        top = 0
        while (_tiles_over(cols, 1 << (t + top)) * _tiles_over(rows, 1 << (t + top))
               > MAX_ROOTS):
            top += 1
        g = Grid(rows, cols, t + top, t, "roots")
        return square if g.same_tiles(square) else g

    def same_tiles(self, other: Grid) -> bool:
        """Whether both grids hold the same levels of the same tiles (their stores agree)."""
        return (self.rows, self.cols, self.t, self.top_level) == \
            (other.rows, other.cols, other.t, other.top_level) and \
            all(self.tiles(L) == other.tiles(L) for L in self.levels)

    @property
    def square(self) -> bool:
        return self.layout == "square"

    def _square_only(self, what: str) -> None:
        if not self.square:
            raise RootGridError(f"{what} needs a square grid; this one has "
                                f"{self.roots[0]} × {self.roots[1]} root tiles over "
                                f"{self.shape[1]} × {self.shape[0]} samples (a root grid's "
                                "are tiles(L), level_shape(L), shape and extent)")

    def tiles(self, level: int) -> tuple[int, int]:
        """(tiles across, tiles down) at level L."""
        if 0 <= level < len(self._tiles):
            return self._tiles[level]
        return self._count_tiles(level)

    @cached_property
    def _tiles(self) -> tuple[tuple[int, int], ...]:
        # every level's count, once (an edit asks about 500 times)
        return tuple(self._count_tiles(L) for L in self.levels)

    def _count_tiles(self, level: int) -> tuple[int, int]:
        if self.square:
            k = 1 << (self.top_level - level)
            return k, k
        s = self.tile_span(level)
        return _tiles_over(self.cols, s), _tiles_over(self.rows, s)

    @property
    def roots(self) -> tuple[int, int]:
        """(across, down) tiles of the top level: each its own bintree."""
        return self.tiles(self.top_level)

    def level_shape(self, level: int) -> tuple[int, int]:
        """(rows, cols) of the level-L lattice: its tiles side by side, borders shared."""
        tx, ty = self.tiles(level)
        return ty * (1 << self.t) + 1, tx * (1 << self.t) + 1

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the padded level-0 grid (every whole-grid array's shape)."""
        return self.level_shape(0)

    @property
    def extent(self) -> tuple[int, int]:
        """(rows, cols) in level-0 samples that the root tiles cover; a coarse level's
        samples beyond :attr:`shape` are padding only, held by that level alone."""
        tx, ty = self.roots
        return ty * (1 << self.n) + 1, tx * (1 << self.n) + 1

    def offsets(self) -> np.ndarray:
        """Where each level starts in the dense (level, y, x) table of every tile: tile
        (L, x, y) is entry ``offsets[L] + y·tiles(L)[0] + x``; ``offsets[-1]`` is the
        table's size (:func:`level_offsets` on a square grid)."""
        per = [self.tiles(L)[0] * self.tiles(L)[1] for L in self.levels]
        return np.concatenate([[0], np.cumsum(per)]).astype(np.int64)

    def table_index(self, keys: np.ndarray) -> np.ndarray:
        """Entries of (L, x, y) ``keys`` (K, 3) in the dense table of :meth:`offsets`.

        Examples
        --------
        >>> g = Grid.for_shape(65, 129, tile_size=16, roots=True)
        >>> g.table_index(np.array([[0, 7, 3], [2, 1, 0]])).tolist()
        [31, 41]
        """
        keys = np.asarray(keys, np.int64).reshape(-1, 3)
        L = keys[:, 0]
        across = np.array([self.tiles(k)[0] for k in self.levels], np.int64)
        return self.offsets()[L] + keys[:, 2] * across[L] + keys[:, 1]

    def vertex_tiles(self, i: np.ndarray, j: np.ndarray, L: np.ndarray
                     ) -> tuple[list[tuple[int, int, int]], np.ndarray, np.ndarray, np.ndarray,
                                np.ndarray]:
        """The tiles that hold level-0 samples (i, j) on levels ``L`` (each sample's coarsest,
        :func:`geoterrain.core.bintree.vertex_level`): the distinct tiles' keys in the
        order of :meth:`offsets`' table, each sample's index into them, its row and column
        in its tile, and whether a tile holds it (a root grid's padding past its tiles:
        none, and row and column 0). Whole arrays; one entry a distinct tile.

        Examples
        --------
        >>> g = Grid.for_shape(65, 65, tile_size=32)
        >>> keys, inv, a, b, held = g.vertex_tiles(np.array([0, 40]), np.array([0, 3]),
        ...                                        np.array([1, 0]))
        >>> keys, inv.tolist(), a.tolist(), b.tolist(), held.tolist()
        ([(0, 0, 1), (1, 0, 0)], [1, 0], [0, 8], [0, 3], [True, True])
        """
        li, lj = i >> L, j >> L
        # tiles across and down per level (a square's 2^(top − L) a side)
        across, down = (np.array([self.tiles(v)[a] for v in self.levels], np.int64) for a in (0, 1))
        ty = np.minimum(li >> self.t, down[L] - 1)
        tx = np.minimum(lj >> self.t, across[L] - 1)
        a, b = li - (ty << self.t), lj - (tx << self.t)
        # a root grid's padding past its tiles: no tile (δ = r = 0, height NaN)
        held = (a <= 1 << self.t) & (b <= 1 << self.t)
        a, b = np.where(held, a, 0), np.where(held, b, 0)
        # unique tiles without sorting: an occupancy grid over every level's tiles
        base = self.offsets()
        slot = base[L] + ty * across[L] + tx
        occ = np.zeros(int(base[-1]), bool)
        occ[slot] = True
        used = np.flatnonzero(occ)
        remap = np.cumsum(occ) - 1
        inv = remap[slot]
        keys = []
        for u in used.tolist():
            lv = int(np.searchsorted(base, u, side="right") - 1)
            r = u - int(base[lv])
            keys.append((lv, r % int(across[lv]), r // int(across[lv])))
        return keys, inv, a, b, held

    def key_of(self, index: int) -> tuple[int, int, int]:
        """The (L, x, y) at ``index`` of the dense table (:meth:`table_index`'s inverse)."""
        base = self.offsets()
        L = int(np.searchsorted(base, index, side="right") - 1)
        r = int(index) - int(base[L])
        across = self.tiles(L)[0]
        return L, r % across, r // across

    def walk_table(self) -> np.ndarray:
        """The table compiled tile walks take (``base``, :func:`geoterrain.lod.kernels.
        _coarsest_tile`): a square grid's :meth:`offsets`; a root grid's, followed by each
        level's tiles across, then down.

        Examples
        --------
        >>> Grid.for_shape(65, 129, tile_size=16, roots=True).walk_table().tolist()
        [0, 32, 40, 42, 8, 4, 2, 4, 2, 1]
        """
        if self.square:
            return self.offsets()
        return np.concatenate([self.offsets(), [self.tiles(L)[0] for L in self.levels],
                               [self.tiles(L)[1] for L in self.levels]]).astype(np.int64)

    @property
    def size(self) -> int:
        """N, samples per side of the padded domain (square grids only)."""
        self._square_only("the padded size N")
        return (1 << self.n) + 1

    @property
    def tile_samples(self) -> int:
        """T, samples per side of a tile."""
        return (1 << self.t) + 1

    @property
    def top_level(self) -> int:
        return self.n - self.t

    @property
    def levels(self) -> range:
        return range(self.top_level + 1)

    def tiles_per_side(self, level: int) -> int:
        """Tiles a side at level L (square grids only: :meth:`tiles` otherwise)."""
        self._square_only("tiles per side")
        return 1 << (self.top_level - level)

    def level_size(self, level: int) -> int:
        """Samples per side of the whole level-L grid (square grids only)."""
        self._square_only("the level size")
        return (1 << (self.n - level)) + 1

    def tile_span(self, level: int) -> int:
        """Full-resolution samples between a tile's first and last row (2^(t+L))."""
        return 1 << (self.t + level)

    def tile_rows(self, level: int, y: int) -> np.ndarray:
        """Full-resolution row indices of the samples of tile row y at level L."""
        return (y * (1 << self.t) + np.arange(self.tile_samples)) << level

    def tile_cols(self, level: int, x: int) -> np.ndarray:
        return (x * (1 << self.t) + np.arange(self.tile_samples)) << level

    def parent(self, level: int, x: int, y: int) -> tuple[int, int, int]:
        return level + 1, x // 2, y // 2

    def children(self, level: int, x: int, y: int) -> list[tuple[int, int, int]]:
        """The tile's children that the grid holds: four, or fewer on the right and
        bottom edges of a roots grid."""
        tx, ty = self.tiles(level - 1)
        return [(level - 1, cx, cy) for cy in (2 * y, 2 * y + 1) for cx in (2 * x, 2 * x + 1)
                if cx < tx and cy < ty]

    def ancestors(self, level: int, x: int, y: int) -> list[tuple[int, int, int]]:
        """The tile's ancestors from its parent up to the top tile."""
        out = []
        while level < self.top_level:
            level, x, y = self.parent(level, x, y)
            out.append((level, x, y))
        return out

    def holds(self, key: tuple[int, int, int]) -> bool:
        """Whether tile (L, x, y) is one of the grid's (the square's tiles, or a root
        grid's ``tiles(L)``: a tile past the raster's last row or column, which a
        footprint count over the extent may see holding that shared border, is not)."""
        L, x, y = key
        if not 0 <= L <= self.top_level:
            return False
        tx, ty = self.tiles(L)
        return 0 <= x < tx and 0 <= y < ty

    def held(self, blobs: dict) -> dict:
        """``blobs`` keyed by tile, keeping the grid's own tiles (:meth:`holds`; all of
        them on a square grid)."""
        return blobs if self.square else {k: b for k, b in blobs.items() if self.holds(k)}

    @property
    def whole_shape(self) -> int | tuple[int, int]:
        """The whole-grid arrays' shape as the frame and the preprocess take it: N on a
        square grid, a root grid's :attr:`extent` (rows, cols)."""
        return self.size if self.square else self.extent

    @property
    def codec_roots(self) -> tuple[int, int] | None:
        """The root tiles the height codec codes apart (None: the square's one)."""
        return None if self.square else self.roots

    @property
    def span(self) -> int | None:
        """A root's side 2^n in level-0 samples, as the bounds take it (None: the square)."""
        return None if self.square else 1 << self.n

    def pad(self, a: np.ndarray, fill, whole: bool = False) -> np.ndarray:
        """Embed a (rows, cols) array at the top-left of a :attr:`shape` array filled with
        ``fill`` (N × N on a square grid); with ``whole``, of an :attr:`extent` array (the
        whole-grid preprocess's arrays: the same N × N on a square grid)."""
        out = np.full(self.extent if whole else self.shape, fill, dtype=a.dtype)
        out[: self.rows, : self.cols] = a
        return out

    def footprint_counts(self, valid: np.ndarray) -> dict[int, np.ndarray]:
        """Per level, (tiles down, tiles across) counts of valid samples in each
        footprint: :func:`footprint_counts` keyed by level."""
        return dict(enumerate(footprint_counts(valid, self.t, self.top_level)))

    def stored_tiles(self, valid: np.ndarray) -> Iterator[tuple[int, int, int]]:
        """Every (L, x, y) whose footprint holds a valid sample, coarsest level first."""
        counts = self.footprint_counts(valid)
        for L in reversed(self.levels):
            ys, xs = np.nonzero(counts[L])
            yield from ((L, int(x), int(y)) for y, x in zip(ys, xs, strict=True))

    def to_json(self) -> dict:
        """The store's grid: a square grid as stores always wrote it (no layout)."""
        d = asdict(self)
        if self.square:
            del d["layout"]
        return d


def footprint_counts(valid: np.ndarray, t: int, top: int | None = None) -> list[np.ndarray]:
    """Valid full-resolution samples in each tile footprint, for every pyramid level.

    ``valid`` is the level-0 mask, (N, N) with N = 2**n + 1 on a square grid (levels
    0 … n − t), or a roots grid's (rows, cols) lattice with levels 0 … ``top``; tiles
    have 2**t + 1 samples a side. Entry L is the (ny, nx) int64 count of level L (tile
    span S = 2**(t + L), ``ceil((side − 1) / S)`` tiles a side); the footprint of tile
    (x, y) is the closed box ``[y S, (y + 1) S] × [x S, (x + 1) S]`` clipped to the
    mask, shared borders included. A tile is stored when its count is > 0. Computed
    from one integral image (an all-valid mask: from the boxes' areas, without it), so
    every level costs O(tiles).

    Examples
    --------
    >>> v = np.zeros((5, 5), bool); v[2, 2] = True
    >>> [c.tolist() for c in footprint_counts(v, 1)]
    [[[1, 1], [1, 1]], [[1]]]
    >>> [c.tolist() for c in footprint_counts(np.ones((3, 5), bool), 1, top=1)]
    [[[9, 9]], [[15]]]
    """
    valid = np.asarray(valid, dtype=bool)
    R, C = valid.shape
    if top is None:
        top = int(max(R, C) - 1).bit_length() - 1 - t
    full = bool(valid.all())  # every sample valid: each count is its box's area
    if not full:
        from geoterrain.core.gridcount import integral_nb  # compiled: loaded where it runs

        ii = np.zeros((R + 1, C + 1), np.int32 if valid.size < 2**31 else np.int64)
        integral_nb(valid.view(np.uint8), ii)
    out = []
    for L in range(top + 1):
        s = 1 << (t + L)
        ry, rx = (np.minimum(np.arange(_tiles_over(k, s)) * s, k) for k in (R, C))
        hy, hx = np.minimum(ry + s + 1, R), np.minimum(rx + s + 1, C)
        if full:
            c = (hy - ry).astype(np.int64)[:, None] * (hx - rx).astype(np.int64)[None, :]
        else:
            c = ii[hy][:, hx] - ii[ry][:, hx] - ii[hy][:, rx] + ii[ry][:, rx]
        out.append(c.astype(np.int64))
    return out


def level_tiles(a: np.ndarray, t: int, level: int) -> np.ndarray:
    """Every tile of pyramid level L as a read-only (ny, nx, T, T, ...) view of a
    full-resolution array ``a`` (N, N, ...) (T = 2**t + 1; trailing axes kept last).

    Level L keeps ``a[::2**L, ::2**L]``; tile (x, y) is its T × T window starting at
    sample (y 2**t, x 2**t), so neighbouring tiles share their border samples.

    Examples
    --------
    >>> a = np.arange(25).reshape(5, 5)
    >>> w = level_tiles(a, 1, 0)
    >>> w.shape, w[1, 0].tolist()
    ((2, 2, 3, 3), [[10, 11, 12], [15, 16, 17], [20, 21, 22]])
    """
    lv = a[:: 1 << level, :: 1 << level]
    T, step = (1 << t) + 1, 1 << t
    win = np.lib.stride_tricks.sliding_window_view(lv, (T, T), axis=(0, 1))[::step, ::step]
    # sliding_window_view puts the window axes last; move trailing channel axes after them
    for _ in range(a.ndim - 2):
        win = np.moveaxis(win, 2, -1)
    return win
