"""Terrain: lazy, cached, checksum-verified access to a store.

:class:`Terrain` implements :class:`~geoterrain.terrainlike.TerrainLike`, the one
interface every later stage reads a terrain through.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np

# The decoders (geoterrain.bounds, geoterrain.codec, core.bintree) are imported where a
# tile is read: they load numba, which opening a store and `geoterrain info` never need.
from geoterrain import extent, gathers, normalreads
from geoterrain.core.tilecache import DerivedSlot, TileCache
from geoterrain.exceptions import StoreChangedError, StoreCorruptError, StoreError, UsageError
from geoterrain.heightreads import decode_heights
from geoterrain.store.check import check_store
from geoterrain.store.reader import StoreReader
from geoterrain.store.summary import store_summary
from geoterrain.terrainlike import Tile, TileKey

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    import pyvista as pv

    from geoterrain.core.view import View
    from geoterrain.lod import Selection
    from geoterrain.preprocessing.edit import EditResult

__all__ = ["Terrain", "Tile", "TileKey", "edit", "open"]

_T = TypeVar("_T")


class Terrain:
    """A preprocessed terrain, read lazily from its store.

    Tiles are decoded on demand, with their ancestors (the codec predicts each
    level from the decoded level above), and kept in its ``tile_cache``, a
    :class:`~geoterrain.core.tilecache.TileCache` bounded in bytes (``cache_bytes``,
    :meth:`memo`). What other modules derive from the terrain once (their tables, pools,
    scratch) is kept in its :meth:`derived` slot. Both are safe to call from several
    threads.

    Examples
    --------
    >>> import tempfile, os
    >>> import geoterrain
    >>> from geoterrain.ingest.synth import generate, write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> dem = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 33, seed=1))
    >>> t = geoterrain.open(geoterrain.preprocess(dem))
    >>> X, Y, Z = t.scene_xyz()
    >>> Z.shape, t.tile(0, 0, 0).heights.shape
    ((33, 33), (33, 33))
    """

    def __init__(self, path: str | Path, cache_bytes: int = 1536 << 20):
        self.path = Path(path)
        self._bytes_before = 0  # what the readers that refresh() replaced read
        self._load()
        self.tile_cache = TileCache(cache_bytes)
        self._derived = DerivedSlot()
        self.decoded_tiles = 0  # tiles whose heights were decoded (a view counts these)
        self.decoded_normals = 0  # tiles whose normal maps were decoded
        self.decoded_bounds = 0  # δ or r arrays decoded
        self.generation = 0  # how many edits this terrain has taken in (refresh)

    def _load(self) -> None:
        """Open the store: its metadata and tile table, every field checked."""
        self.reader = StoreReader(self.path)
        self._version = self.reader.version()
        try:
            m = self.reader.metadata
            self.meta = m
            self.tile_info = self.reader.tiles()
            # an untrusted file: every field is checked before anything is sized from it
            self.grid, self.frame, self.quantizer = check_store(self.path, m, self.tile_info)
            # tiles with a second δ (padding replicated: geoterrain/bounds/edgepad.py) → the
            # largest δ_edge of their new vertices; None: the store predates it
            self.edge_max = (self.reader.edge_keys() if "delta_edge" in m
                             else None)
            if self.edge_max and not all(self.grid.holds(k) for k in self.edge_max):
                raise StoreCorruptError(f"{self.path}: the delta_edge list names a tile "
                                        "outside the grid: the file is damaged; re-run "
                                        "`geoterrain preprocess`")
        except BaseException:
            self.reader.close()
            raise
        self.open_bytes = self.reader.bytes_read  # what opening read: O(1) pages and the catalog
        edits = self.meta.get("edits")
        self._edits_seen = int(edits.get("count", 0)) if isinstance(edits, dict) else 0

    vertical_exaggeration = 1.0  # heights as stored (a view may scale them)
    stored_normals = True  # tile_normals decode normal_codes (a view may rescale them)

    # ------------------------------------------------------------------ cache
    def memo(self, key: tuple, make: Callable[[], _T]) -> _T:
        """The value cached under ``key``, made by ``make`` on a miss (once, even when
        threads ask at once): the terrain's tile cache of decoded arrays (and what other
        modules make from them, such as a tile's shading), bounded in bytes
        (``cache_bytes``; :meth:`TileCache.memo <geoterrain.core.tilecache.TileCache.memo>`).

        Examples
        --------
        >>> t.memo(("example",), lambda: np.zeros(3)).shape
        (3,)
        """
        return self.tile_cache.memo(key, make)

    def lookup(self, key: tuple):
        """The cached value of ``key``, marked as just used, or None (nothing is made).

        Examples
        --------
        >>> tile = t.tile(t.grid.top_level, 0, 0)
        >>> t.lookup(("h", t.grid.top_level, 0, 0)) is tile, t.lookup(("h", 99, 0, 0))
        (True, None)
        """
        return self.tile_cache.lookup(key)

    def peek(self, key: tuple):
        """The cached value of ``key`` (as :meth:`memo` keys it), or None; the cache's
        order is left as it is."""
        return self.tile_cache.peek(key)

    def cache_keys(self) -> list[tuple]:
        """The keys the tile cache holds, least recently used first (what a frame read:
        ``("h", level, x, y)`` heights, ``("rgb", style, level, x, y)`` shading, …).

        Examples
        --------
        >>> _ = t.tile(t.grid.top_level, 0, 0)
        >>> ("h", t.grid.top_level, 0, 0) in t.cache_keys()
        True
        """
        return self.tile_cache.keys()

    def clear_cache(self) -> None:
        """Empty the tile cache (decoded heights, bounds, normals, shading): the next
        reads decode again (a benchmark's cold start)."""
        self.tile_cache.clear()

    def derived(self, owner: str, make: Callable[[], _T]) -> _T:
        """What module ``owner`` derives from this terrain once (its tables, a tile pool,
        scratch buffers), made by ``make`` on first use and kept as long as the terrain,
        outside the byte-bounded tile cache
        (:class:`~geoterrain.core.tilecache.DerivedSlot`). The one place such data lives:
        no module keeps a cache of terrains.

        Examples
        --------
        >>> t.derived("example", dict) is t.derived("example", dict)
        True
        """
        return self._derived.get(owner, make)

    def forget(self, owner: str | None = None) -> None:
        """Drop what ``owner`` derived (every module's with None): it is derived anew on
        its next use (a test's or a benchmark's hook).

        Examples
        --------
        >>> a = t.derived("example", dict); t.forget("example")
        >>> t.derived("example", dict) is a
        False
        """
        self._derived.forget(owner)

    @property
    def stand_in_z(self) -> float:
        """The scene height that stands in for nodata samples in the nested spheres
        (:func:`geoterrain.extent.stand_in_z`)."""
        return extent.stand_in_z(self)

    def _blob(self, key: TileKey, kind: str) -> bytes:
        if key not in self.tile_info and not (kind == "delta_edge" and self.edge_max
                                              and key in self.edge_max):
            raise StoreError(f"{self.path}: tile {key} is not stored: it lies outside the "
                             "data or holds only nodata")
        b, version = self.reader.get_blob_version(key, kind)
        if version != self._version:  # an edit committed meanwhile
            raise StoreChangedError(f"{self.path} was edited while it was read; call "
                                    "refresh() (or open it again) and read again")
        if b is None:
            raise StoreCorruptError(f"{self.path}: the {kind} of tile {key} are missing; the "
                                    "file is damaged, re-run `geoterrain preprocess`")
        return b

    @property
    def bytes_read(self) -> int:
        """Every byte read from the store file since it was opened, opening included, as
        the operating system counts them (the store's pages, header and change counter:
        :mod:`geoterrain.core.osreads`; the blobs' bytes only where it does not count them).

        Examples
        --------
        >>> u = open(t.path)
        >>> u.bytes_read == u.open_bytes > 0
        True
        >>> u.close()
        """
        return self._bytes_before + self.reader.bytes_read

    # ------------------------------------------------------------------ tiles
    def tile_keys(self, level: int | None = None) -> list[TileKey]:
        """The stored tiles' keys (level, x, y), sorted; those of ``level`` only if given.

        Tiles are stored where their footprint holds valid data.

        Examples
        --------
        >>> t.tile_keys(t.grid.top_level)
        [(2, 0, 0)]
        """
        return sorted(k for k in self.tile_info if level is None or k[0] == level)

    def scene_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Scene-frame box (lo, hi), each (3,) float64, of the valid data (top tile bounds:
        :func:`geoterrain.extent.scene_box`)."""
        return extent.scene_box(self)

    def snapshot(self) -> AbstractContextManager[None]:
        """A context in which every read of the store sees the same file: one read
        transaction, the store's version checked once (an edit by another process
        waits for its end). A query that reads many tiles reads them faster inside one.

        Examples
        --------
        >>> with t.snapshot():
        ...     a, b = t.tile(0, 0, 0), t.tile(0, 1, 0)
        """
        return self.reader.snapshot()

    def tile(self, level: int, x: int, y: int) -> Tile:
        """Decode tile (level, x, y) and, as needed, its ancestors (never finer data)."""
        key = (level, x, y)
        return self.memo(("h", *key), lambda: self._decode(key))

    def tiles(self, keys: Sequence[TileKey]) -> list[Tile]:
        """:meth:`tile` of each of ``keys``: those not cached, with their ancestors not
        cached, read in one batch (:meth:`StoreReader.get_blobs`: one query, each blob's
        checksum verified) and decoded coarsest first into the tile cache.

        Examples
        --------
        >>> u = open(t.path)
        >>> a = u.tiles([(0, 1, 0), (0, 0, 0)])
        >>> [k.key for k in a], a[1] is u.tile(0, 0, 0)
        ([(0, 1, 0), (0, 0, 0)], True)
        >>> u.close()
        """
        top = self.grid.top_level
        todo: set[TileKey] = set()
        for key in keys:
            while key not in todo and self.peek(("h", *key)) is None:
                if key not in self.tile_info:
                    break  # tile() says so (one line), as it would alone
                todo.add(key)
                if key[0] >= top:
                    break
                key = (key[0] + 1, key[1] // 2, key[2] // 2)
        if len(todo) > 1:
            order = sorted(todo, key=lambda k: (-k[0], k[2], k[1]))  # parents first
            blobs, version = self.reader.get_blobs([(k, "heights") for k in order], True)
            if version != self._version:  # an edit committed meanwhile
                raise StoreChangedError(f"{self.path} was edited while it was read; call "
                                        "refresh() (or open it again) and read again")
            for k, blob in zip(order, blobs, strict=True):
                self.memo(("h", *k), lambda k=k, blob=blob: self._decode(k, blob))
        return [self.tile(*k) for k in keys]

    def _decode(self, key: TileKey, blob: bytes | None = None) -> Tile:
        return decode_heights(self, key, self._blob, blob)

    def _bounds(self, key: TileKey, kind: str) -> np.ndarray:
        from geoterrain.bounds.tilereads import decode_tile_bounds  # its decoders load numba

        self.decoded_bounds += 1
        # δ_edge: a tile without its own second δ has the same new vertices as in δ
        stored = "delta" if kind == "delta_edge" and key not in self.edge_max else kind
        return decode_tile_bounds(self, key, kind, stored, self._blob(key, stored))

    def block_errors(self) -> np.ndarray | None:
        """Every GeoMipMapping block's exact δ_n (seed 000 §2.4), None for a store written
        before the table was (:func:`geoterrain.bounds.tilereads.block_errors`)."""
        from geoterrain.bounds.tilereads import block_errors  # its decoders load numba

        return block_errors(self, self._blob)

    def tile_delta(self, level: int, x: int, y: int) -> np.ndarray:
        """Per-vertex errors δ (scene units) of the tile's samples, float32 (T, T)."""
        return self.memo(("d", level, x, y), lambda: self._bounds((level, x, y), "delta"))

    def tile_delta_edge(self, level: int, x: int, y: int) -> np.ndarray:
        """δ with the padding replicated from the data's edge (:mod:`geoterrain.bounds.edgepad`),
        float32 (T, T): the tile's second δ blob where it has one, else its δ blob (the
        same new vertices), over its parent's δ_edge."""
        if not self.edge_max:
            return self.tile_delta(level, x, y)
        return self.memo(("de", level, x, y),
                            lambda: self._bounds((level, x, y), "delta_edge"))

    def tile_radius(self, level: int, x: int, y: int) -> np.ndarray:
        """Nested bounding-sphere radii (scene units) of the tile's samples, float32 (T, T)."""
        return self.memo(("r", level, x, y), lambda: self._bounds((level, x, y), "radius"))

    def tile_xy(self, level: int, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
        """Scene X, Y (T, T) of the tile's samples (cached: geographic frames call pyproj)."""
        def make():
            g = self.grid
            rows, cols = g.tile_rows(level, y), g.tile_cols(level, x)
            if self.frame.kind != "geographic":
                # affine: the rows' column against the columns' row, broadcast to (T, T)
                # fresh arrays, each sample's arithmetic the meshgrid's (the same bits)
                return self.frame.xy(rows[:, None], cols[None, :])
            ii, jj = np.meshgrid(rows, cols, indexing="ij")
            return self.frame.xy(ii, jj)
        return self.memo(("xy", level, x, y), make)

    def tile_normals(self, level: int, x: int, y: int) -> np.ndarray:
        """Unit normals (T, T, 3) float32 of the level-L normal map at the tile's samples."""
        from geoterrain.bounds.normals import decode_octahedral

        return self.memo(("n", level, x, y), lambda: decode_octahedral(
            self.tile_normal_codes(level, x, y), self.meta["normal_bits"]))

    def tile_normal_codes(self, level: int, x: int, y: int) -> np.ndarray:
        """The octahedral codes (T, T, 2) of one tile's normals: :meth:`normal_codes`."""
        return self.normal_codes([(level, x, y)])[0]

    def normal_codes(self, keys: Sequence[TileKey]) -> np.ndarray:
        """The octahedral codes (n, T, T, 2) of tiles ``keys``' normals, as stored or derived
        on read (:func:`geoterrain.normalreads.normal_codes`; not cached, each read counted
        in ``decoded_normals``): the one door to a tile's normals.

        Examples
        --------
        >>> keys = t.tile_keys(0)[:2]
        >>> t.normal_codes(keys).shape == (2, t.grid.tile_samples, t.grid.tile_samples, 2)
        True
        """
        return normalreads.normal_codes(self, keys, self._blob)

    # ------------------------------------------------------- per-vertex data
    def vertex_level(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """The coarsest pyramid level holding samples (i, j) (:func:`gathers.vertex_level`)."""
        return gathers.vertex_level(self, i, j)

    def gather(self, i: np.ndarray, j: np.ndarray,
               kinds: Sequence[str] = ("delta", "radius", "height")) -> dict[str, np.ndarray]:
        """Per-vertex arrays at full-resolution samples (i, j), read from the coarsest tiles
        (:func:`geoterrain.gathers.gather`)."""
        return gathers.gather(self, i, j, kinds)

    def tile_stacks(self, keys: Sequence[TileKey], kinds: Sequence[str] = ("delta",)
                    ) -> dict[str, np.ndarray]:
        """(K, T, T) float64 stacks of per-sample arrays for tiles ``keys``
        (:func:`geoterrain.gathers.tile_stacks`)."""
        return gathers.tile_stacks(self, keys, kinds)

    # ------------------------------------------------------------ whole grids
    def level_heights(self, level: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Heights and valid mask of a whole level (:func:`geoterrain.gathers.level_heights`)."""
        return gathers.level_heights(self, level)

    def scene_xyz(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X, Y, Z in the scene frame, NaN where there is no data: the frame of every mesh
        geoterrain makes (:func:`geoterrain.gathers.scene_xyz`)."""
        return gathers.scene_xyz(self)

    # -------------------------------------------------------------------- LOD
    def select(self, view: View, pixel_error: float = 1.0, strategy: str = "rtin", *,
               reuse: bool = True, occlusion: bool | None = None,
               morph: bool | None = None) -> Selection:
        """The mesh for ``view`` with projected error ≤ ``pixel_error`` pixels.

        A forward to :func:`geoterrain.lod.select` (strategies, stats, reuse, horizon
        culling, geomorphing).

        Examples
        --------
        >>> from geoterrain.core.view import View
        >>> sel = t.select(View((0, -800, 400), (0, 0, 0)), pixel_error=1.0)
        >>> sel.stats["triangles"] > 0
        True
        """
        from geoterrain import lod

        return lod.select(self, view, pixel_error, strategy, reuse=reuse, occlusion=occlusion,
                          morph=morph)

    def mesh(self, max_error: float = 1.0, method: str = "rtin") -> pv.PolyData:
        """Static mesh within ``max_error`` of every valid sample: vertical error ≤ max_error.

        ``method``: ``"rtin"`` keeps every vertex with δ > ``max_error`` (the bintree cut);
        ``"tin"`` is the greedy-insertion TIN (fewer triangles; :mod:`geoterrain.lod.tin`);
        ``"tin-full"`` the same with every point collapsed that can be (fewer still, slower).
        Returns a ``pyvista.PolyData`` in the scene frame (point data ``grid_ij``).

        Examples
        --------
        >>> t.mesh(max_error=5.0).n_cells > 0
        True
        >>> t.mesh(max_error=5.0, method="tin").n_cells <= t.mesh(max_error=5.0).n_cells
        True
        """
        return self.static_selection(max_error, mesher=method).mesh

    def static_selection(self, max_error: float = 1.0, mesher: str = "rtin") -> Selection:
        """Like :meth:`mesh` but returns the :class:`~geoterrain.lod.Selection` with stats.

        A forward to :func:`geoterrain.lod.static`.
        """
        from geoterrain import lod

        return lod.static(self, max_error, mesher)

    # ----------------------------------------------------------------- edits
    def edit(self, window, heights: np.ndarray, mode: str = "replace", *,
             round_heights: bool = False) -> EditResult:
        """Change the heights of a window of the DEM, in the store, in place (issue 52).

        Only what the edit reaches is recomputed and rewritten: the tiles under the
        window and their ancestors, δ and r along the saturation chain, the tile rows and
        block errors, the normals within their halo (:mod:`geoterrain.preprocessing.edit`);
        the store then holds what a preprocess of the edited DEM gives. One transaction:
        a killed edit leaves the old store. This terrain takes the edit in at once
        (:meth:`refresh`).

        Parameters
        ----------
        window
            Where the patch goes: its top-left sample ``(row, col)`` of the DEM (rows
            southwards, columns eastwards), optionally with its ``(rows, cols)``, or a
            ``rasterio.windows.Window``.
        heights
            The patch, in the DEM's height units; NaN leaves a sample as it is.
        mode
            ``replace`` (over nodata too: fills a void), ``add``, ``min`` or ``max``
            (these leave nodata as it is).
        round_heights
            Round heights a lossless store cannot hold (say 12.3 in an integer DEM) to its
            grid instead of refusing them.

        Returns
        -------
        :class:`~geoterrain.preprocessing.edit.EditResult` (window changed, rows and bytes
        rewritten, time).

        Examples
        --------
        >>> import shutil, tempfile, os
        >>> p = os.path.join(tempfile.mkdtemp(), "c.geoterrain"); _ = shutil.copy(t.path, p)
        >>> u = open(p)
        >>> before = u.tile(0, 0, 0).heights[4, 4]
        >>> res = u.edit((3, 3), np.full((3, 3), -5.0), mode="add")
        >>> bool(u.tile(0, 0, 0).heights[4, 4] == before - 5), res.changed
        (True, 9)
        """
        from geoterrain.preprocessing.edit import Patch, edit_terrain

        if hasattr(window, "row_off"):  # a rasterio Window
            row, col = int(window.row_off), int(window.col_off)
            shape = (int(window.height), int(window.width))
        else:
            row, col = (int(v) for v in tuple(window)[:2])
            shape = tuple(int(v) for v in tuple(window)[2:4]) or None
        heights = np.asarray(heights, np.float64)
        if shape is not None and heights.shape != shape:
            raise UsageError(f"heights have shape {heights.shape}, the window {shape}")
        res = edit_terrain(self, Patch(row, col, heights), mode, round_heights=round_heights)
        self.refresh()
        return res

    def refresh(self) -> bool:
        """Take in the edits committed to the store since it was read (by :meth:`edit`,
        or another process's ``geoterrain edit``): the tile table and metadata are read
        again, the cached tiles an edit reached are dropped (the edit log says where), and
        so is what other modules derived from the terrain, unless what they keep knows
        how to take an edit in (an object with an ``edited(edits)`` method, given the edit
        log's new entries, such as the tessellation's HAM statistics,
        :class:`geoterrain.lod.tessellation.HamStats`). Returns whether anything changed;
        ``generation`` counts the changes taken in.

        Examples
        --------
        >>> t.refresh()
        False
        """
        if self.reader.version() == self._version:
            return False
        seen = self._edits_seen
        self._bytes_before += self.reader.bytes_read
        self.reader.close()
        self._load()
        edits = self.meta.get("edits") if isinstance(self.meta.get("edits"), dict) else {}
        news = [e for e in edits.get("last", []) if isinstance(e, dict) and e.get("n", 0) > seen]
        rects = None  # None: everything
        if news and len(news) == self._edits_seen - seen:
            try:
                rects = [tuple(int(v) for v in r) for e in news for r in e["dirty"]]
            except (KeyError, TypeError, ValueError):
                rects = None
        if rects is None:
            self.tile_cache.clear()
        else:
            self.tile_cache.drop_tiles(rects, self.grid)
        self._derived.edited(None if rects is None else news)
        self.generation += 1
        return True

    # ------------------------------------------------------------------ info
    def info(self) -> dict:
        """A summary: size, CRS and frame, extent, grid, levels, tiles, nodata, codec, errors
        (:func:`geoterrain.store.summary.store_summary`)."""
        return store_summary(self, self.reader.blob_bytes_by_kind_level())

    # -------------------------------------------------------------- notebooks
    def _repr_html_(self) -> str:
        """A notebook's summary: extent, CRS, size, levels, codec and a shaded thumbnail."""
        from geoterrain.rendering.notebook import repr_html  # upper layer, loaded on first display

        return repr_html(self)

    def plot(self, view: View | None = None, **kwargs):
        """Show the terrain: the picture ``geoterrain render`` makes (overlays included), as
        a PIL image; or PyVista's notebook backend with ``interactive=True``.

        Keywords: ``shading``, ``pixel_error``, ``strategy``, ``size``, ``cmap``, ``title``,
        ``overlays``, ``map``, ``vertical_exaggeration``, ``light``, ``drape``, ``water``,
        ``interactive``; see :func:`geoterrain.rendering.notebook.plot`.
        """
        from geoterrain.rendering.notebook import plot  # upper layer, loaded on first use

        return plot(self, view, **kwargs)

    def close(self) -> None:
        self.reader.close()

    def __enter__(self) -> Terrain:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open(path: str | Path, cache_bytes: int = 1536 << 20) -> Terrain:  # noqa: A001
    """Open a store (like ``rasterio.open``); decoded tiles are cached up to ``cache_bytes``.

    See :class:`Terrain`.
    """
    return Terrain(path, cache_bytes=cache_bytes)


def edit(store: str | Path, patch: str | Path, mode: str = "replace", *,
         at: tuple[int, int] | None = None, resampling: str = "bilinear",
         round_heights: bool = False, band: int | None = None) -> EditResult:
    """Edit a store in place with a patch raster (``geoterrain edit STORE --patch``).

    The patch is placed on the store's grid by its georeference (as it is when it lies on
    the grid, else resampled onto it with ``resampling``), or at ``at`` = (row, col) of
    its top-left sample; its nodata samples change nothing. Modes, rounding and what is
    rewritten: :meth:`Terrain.edit`.

    Examples
    --------
    >>> import shutil, tempfile, os
    >>> from geoterrain.ingest.synth import write_geotiff
    >>> d = tempfile.mkdtemp()
    >>> p = os.path.join(d, "c.geoterrain"); _ = shutil.copy(t.path, p)
    >>> cut = write_geotiff(os.path.join(d, "cut.tif"), np.full((5, 5), -20.0))
    >>> edit(p, cut, "add", at=(10, 12)).changed
    25
    """
    from geoterrain.preprocessing.edit import edit_terrain, read_patch

    with Terrain(store) as t:
        p = read_patch(patch, t.frame, t.grid, at=at, resampling=resampling, band=band)
        return edit_terrain(t, p, mode, round_heights=round_heights)

