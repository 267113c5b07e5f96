"""The one interface a terrain is read through: :class:`TerrainLike`, and its :class:`Tile`.

Every stage after the store (LOD strategies, rendering, exports, the benchmark harness)
takes a ``TerrainLike`` and reads it only through these members; none reaches into a
terrain's private state. Two classes implement it:
:class:`geoterrain.terrain.Terrain` (a store, decoded lazily) and
:class:`geoterrain.exaggerate.Exaggerated` (a view of one with its heights × N).

What a module derives from a terrain once (its tables, pools, scratch buffers) lives in
the terrain's own slot, :meth:`TerrainLike.derived`, keyed by the module's name, and is
dropped with the terrain: no module keeps a cache of terrains.

Examples
--------
>>> isinstance(t, TerrainLike)
True
>>> t.tile(t.grid.top_level, 0, 0).heights.shape == (t.grid.tile_samples,) * 2
True
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from geoterrain.codec.quantize import Quantizer
    from geoterrain.core.frame import Frame
    from geoterrain.core.grid import Grid

__all__ = ["Tile", "TileKey", "TerrainLike"]

TileKey = tuple[int, int, int]  # (level, x, y)
T = TypeVar("T")


@dataclass
class Tile:
    """One decoded tile: level-L samples of its (T, T) window."""

    key: TileKey
    codes: np.ndarray  # (T, T) codes (int64) or raw floats, what children predict from
    heights: np.ndarray  # (T, T) float64 source units, NaN where not valid
    valid: np.ndarray  # (T, T) bool


@runtime_checkable
class TerrainLike(Protocol):
    """A preprocessed terrain as every stage after the store reads it.

    Attributes
    ----------
    path : the store's file.
    grid : the padded (2^n+1)² domain and its tiles.
    frame : grid indices → scene metres (pyproj), heights → scene z.
    quantizer : how the stored heights are coded (its ``codec_error`` bounds them).
    meta : the store's metadata, read-only.
    tile_info : per stored tile (level, x, y) its scene box, error and sphere bounds.
    edge_max : tiles with a second δ (padding replicated from the data's edge) → their
        largest δ_edge; None for a store written before it.
    stand_in_z : the scene height that stands in for nodata in the nested spheres.
    vertical_exaggeration : N of the heights drawn (1 for a store as it is).
    stored_normals : whether :meth:`normal_codes` are the surface's normals (False for a
        view whose normals are rescaled: read :meth:`tile_normals` then).
    decoded_tiles, decoded_normals, decoded_bounds, bytes_read : running counts of
        what was read from the store (a view's counts are its base's); ``bytes_read``
        counts every byte read from the store file, opening included.
    open_bytes : the bytes that opening the store read (a part of ``bytes_read``).
    generation : how many edits of the store this terrain has taken in (:meth:`refresh`).
    """

    path: Path
    grid: Grid
    frame: Frame
    quantizer: Quantizer
    meta: Mapping[str, Any]
    tile_info: Mapping[TileKey, dict]
    decoded_tiles: int
    decoded_normals: int
    decoded_bounds: int
    bytes_read: int
    open_bytes: int
    generation: int

    @property
    def edge_max(self) -> Mapping[TileKey, float] | None: ...

    @property
    def stand_in_z(self) -> float: ...

    @property
    def vertical_exaggeration(self) -> float: ...

    @property
    def stored_normals(self) -> bool: ...

    # tiles, decoded on demand
    def tile_keys(self, level: int | None = None) -> list[TileKey]: ...

    def scene_box(self) -> tuple[np.ndarray, np.ndarray]: ...

    def tile(self, level: int, x: int, y: int) -> Tile: ...

    def snapshot(self) -> AbstractContextManager[None]: ...

    def tile_delta(self, level: int, x: int, y: int) -> np.ndarray: ...

    def tile_delta_edge(self, level: int, x: int, y: int) -> np.ndarray: ...

    def tile_radius(self, level: int, x: int, y: int) -> np.ndarray: ...

    def tile_xy(self, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]: ...

    def tile_normals(self, level: int, x: int, y: int) -> np.ndarray: ...

    def normal_codes(self, keys: Sequence[TileKey]) -> np.ndarray: ...

    def block_errors(self) -> np.ndarray | None: ...

    # per-vertex data and whole grids
    def gather(self, i: np.ndarray, j: np.ndarray,
               kinds: Sequence[str] = ("delta", "radius", "height")
               ) -> dict[str, np.ndarray]: ...

    def tile_stacks(self, keys: Sequence[TileKey], kinds: Sequence[str] = ("delta",)
                    ) -> dict[str, np.ndarray]: ...

    def level_heights(self, level: int = 0) -> tuple[np.ndarray, np.ndarray]: ...

    def scene_xyz(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    # caches: the byte-bounded tile cache, and each module's derived data
    def memo(self, key: tuple, make: Callable[[], T]) -> T: ...

    def lookup(self, key: tuple) -> Any: ...

    def peek(self, key: tuple) -> Any: ...

    def cache_keys(self) -> list[tuple]: ...

    def clear_cache(self) -> None: ...

    def derived(self, owner: str, make: Callable[[], T]) -> T: ...

    def forget(self, owner: str | None = None) -> None: ...

    # edits of the store (geoterrain edit, Terrain.edit): taken in, caches dropped
    def refresh(self) -> bool: ...
