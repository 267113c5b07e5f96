"""The padded (2^n+1)² domain and its pyramid of (2^t+1)² tiles (docs/conventions.md)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import asdict, dataclass

import numpy as np


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
    """

    rows: int  # source raster rows (H)
    cols: int  # source raster columns (W)
    n: int  # padded size N = 2**n + 1
    t: int  # tile size T = 2**t + 1

    @staticmethod
    def for_shape(rows: int, cols: int, tile_size: int = 64) -> Grid:
        if tile_size < 2 or tile_size & (tile_size - 1):
            raise ValueError(f"Expected tile size to be a power of two ≥ 2, got {tile_size}.")
        n = max(1, int(np.ceil(np.log2(max(rows, cols) - 1))) if max(rows, cols) > 2 else 1)
        return Grid(rows, cols, n, min(int(np.log2(tile_size)), n))

    @property
    def size(self) -> int:
        """N, samples per side of the padded domain."""
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
        return 1 << (self.top_level - level)

    def level_size(self, level: int) -> int:
        """Samples per side of the whole level-L grid."""
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

    def ancestors(self, level: int, x: int, y: int) -> list[tuple[int, int, int]]:
        """The tile's ancestors from its parent up to the top tile."""
        out = []
        while level < self.top_level:
            level, x, y = self.parent(level, x, y)
            out.append((level, x, y))
        return out

    def pad(self, a: np.ndarray, fill) -> np.ndarray:
        """Embed a (rows, cols) array at the top-left of an N × N array filled with ``fill``."""
        out = np.full((self.size, self.size), fill, dtype=a.dtype)
        out[: self.rows, : self.cols] = a
        return out

    def footprint_counts(self, valid: np.ndarray) -> dict[int, np.ndarray]:
        """Per level, (tiles_per_side, tiles_per_side) counts of valid samples in each
        footprint: :func:`footprint_counts` keyed by level."""
        return dict(enumerate(footprint_counts(valid, self.t)))

    def stored_tiles(self, valid: np.ndarray) -> Iterator[tuple[int, int, int]]:
        """Every (L, x, y) whose footprint holds a valid sample, coarsest level first."""
        counts = self.footprint_counts(valid)
        for L in reversed(self.levels):
            ys, xs = np.nonzero(counts[L])
            yield from ((L, int(x), int(y)) for y, x in zip(ys, xs, strict=True))

    def to_json(self) -> dict:
        return asdict(self)


def footprint_counts(valid: np.ndarray, t: int) -> list[np.ndarray]:
    """Valid full-resolution samples in each tile footprint, for every pyramid level.

    ``valid`` is the (N, N) mask, N = 2**n + 1, and tiles have 2**t + 1 samples a side.
    Entry L is the (ny, nx) int64 count of level L (tile span S = 2**(t + L)); the
    footprint of tile (x, y) is the closed box ``[y S, (y + 1) S] × [x S, (x + 1) S]``,
    shared borders included. A tile is stored when its count is > 0. Computed from one
    integral image, so every level costs O(tiles).

    Examples
    --------
    >>> v = np.zeros((5, 5), bool); v[2, 2] = True
    >>> [c.tolist() for c in footprint_counts(v, 1)]
    [[[1, 1], [1, 1]], [[1]]]
    """
    valid = np.asarray(valid, dtype=bool)
    N = valid.shape[0]
    n = int(N - 1).bit_length() - 1
    from geoterrain.core.gridcount import integral_nb  # compiled: loaded where it runs

    ii = np.zeros((N + 1, N + 1), np.int32 if valid.size < 2**31 else np.int64)
    integral_nb(valid.view(np.uint8), ii)
    out = []
    for L in range(n - t + 1):
        s = 1 << (t + L)
        lo = np.arange((N - 1) // s) * s
        hi = lo + s + 1
        c = ii[hi][:, hi] - ii[lo][:, hi] - ii[hi][:, lo] + ii[lo][:, lo]
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
