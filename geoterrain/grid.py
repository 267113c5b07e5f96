"""The padded (2^n+1)² domain and its pyramid of (2^t+1)² tiles (docs/conventions.md)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import asdict, dataclass

import numpy as np


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
        """Per level, (tiles_per_side, tiles_per_side) counts of valid samples in each footprint.

        The footprint is closed (it includes shared border samples). Computed
        from one integral image, so every level costs O(tiles).
        """
        ii = np.zeros((self.size + 1, self.size + 1), np.int64)
        ii[1:, 1:] = valid.astype(np.int64).cumsum(0).cumsum(1)
        out = {}
        for L in self.levels:
            s = self.tile_span(L)
            lo = np.arange(self.tiles_per_side(L)) * s
            hi = lo + s + 1
            out[L] = ii[hi][:, hi] - ii[lo][:, hi] - ii[hi][:, lo] + ii[lo][:, lo]
        return out

    def stored_tiles(self, valid: np.ndarray) -> Iterator[tuple[int, int, int]]:
        """Every (L, x, y) whose footprint holds a valid sample, coarsest level first."""
        counts = self.footprint_counts(valid)
        for L in reversed(self.levels):
            ys, xs = np.nonzero(counts[L])
            yield from ((L, int(x), int(y)) for y, x in zip(ys, xs, strict=True))

    def to_json(self) -> dict:
        return asdict(self)
