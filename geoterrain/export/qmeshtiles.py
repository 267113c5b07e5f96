"""quantized-mesh-1.0 tiles cut one at a time, as a tile server asks for them.

The same tiles as :func:`geoterrain.export.qmesh.write_tileset` writes, built from the
level-0 tiles under each requested rectangle only.

Examples
--------
>>> src = QuantizedMeshTiles(t)
>>> src.exists(0, 0, 0) or src.exists(0, 1, 0)
True
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.exceptions import UsageError
from geoterrain.export.qmesh import (
    DEFAULT_TILE_MESHER,
    availability_ranges,
    build_tile,
    check_tile_mesher,
    lattice_has_triangle,
    max_zoom_for,
    select_tile,
)
from geoterrain.export.qmeshdem import GeoDem, geoid_transformer, lonlat_bounds
from geoterrain.export.qmeshformat import (
    METADATA_LEVELS,
    QMAX,
    cesium_level_error,
    lattice,
    tile_rect,
)

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike


class QuantizedMeshTiles:
    """quantized-mesh-1.0 tiles of ``terrain`` cut one at a time (a server's source).

    The same tiles as :func:`write_tileset` builds, with what a whole-set writer learns
    from all the tiles fixed beforehand instead: one height quantisation range for every
    tile (the store's recorded height range, widened by 120 m with ``geoid``) and the
    ``lattice`` at every level. The tiles a level has are the writer's: those on which
    :func:`build_tile` finds a triangle of valid samples, so none over nodata (a void, the
    sea, a nodata corner) is listed in ``layer.json`` or served (a 404, as a tile outside
    the data); levels coarser than the first with such a tile get flat tiles at the lowest
    height over the DEM's box, as the writer gives them. Which tiles hold data is found
    from the level-0 validity (stored tiles whose samples are all valid, by their count;
    the others decoded, only where the store has nodata) through each tile's lattice:
    rtin tiles by :func:`lattice_has_triangle` alone, TIN tiles with nodata in their
    lattice by building them (see :meth:`_data_tiles`).
    Building tile (z, x, y) decodes only the level-0 tiles under its rectangle
    (:class:`GeoDem`'s window), and its declared bound is :func:`build_tile`'s.
    ``mesher``: ``"rtin"`` or ``"tin"``, as :func:`write_tileset`'s.

    Examples
    --------
    >>> q = QuantizedMeshTiles(t)
    >>> q.layer("dem")["format"], q.exists(0, 0, 0), q.exists(0, 5, 0)
    ('quantized-mesh-1.0', True, False)
    >>> data, bound, triangles = q.tile(q.max_zoom, *min(q.level_tiles(q.max_zoom)))
    >>> bound > 0 and triangles > 0
    True
    """

    def __init__(self, terrain: TerrainLike, *, lattice: int = 129, max_error: float = 1.0,
                 geoid: str | None = None, max_zoom: int | None = None,
                 mesher: str = DEFAULT_TILE_MESHER):
        if lattice < 3 or (lattice - 1) & (lattice - 2) or lattice > 129:
            raise UsageError(f"lattice must be 2^k + 1 in 3..129, got {lattice}")
        if not max_error > 0:
            raise UsageError(f"max_error must be > 0, got {max_error}")
        check_tile_mesher(mesher)
        self.terrain, self.lattice, self.max_error, self.geoid = terrain, lattice, max_error, geoid
        self.mesher = mesher
        self.geo = GeoDem(terrain, geoid, heights=False)
        if geoid is not None:
            geoid_transformer(geoid)  # fail now if the grid is missing
        self.max_zoom = (max_zoom_for(self.geo.pixel_deg, lattice) if max_zoom is None
                         else int(max_zoom))
        if not 0 <= self.max_zoom <= 22:
            raise UsageError(f"max_zoom must be in 0..22, got {self.max_zoom}")
        self.extent = self.geo.extent()
        lo, hi = terrain.scene_box()
        zs = terrain.frame.z_scale or 1.0
        pad = 120.0 if geoid else 0.0  # EGM96's undulation is within −107..+86 m
        h0, h1 = math.floor(lo[2] / zs - pad), math.ceil(hi[2] / zs + pad)
        self.hrange = (float(h0), float(max(h1, h0 + 1)))
        self._levels: dict[int, frozenset[tuple[int, int]]] = {}

    # ---------------------------------------------------------------- which tiles
    def _touching(self, z: int) -> tuple[range, range]:
        w, s, e, n = self.extent
        size = 180.0 / (1 << z)
        # unwrapped: a grid past the antimeridian (170°…190°) reaches x ≥ 2^(z+1), the
        # western tiles taken round once more (x modulo 2^(z+1) names the tile)
        x0 = int((w + 180) // size)
        xs = range(x0, min(int(math.ceil((e + 180) / size)), x0 + (2 << z)))
        ys = range(max(int((s + 90) // size), 0), min(int(math.ceil((n + 90) / size)), 1 << z))
        return xs, ys

    def _jobs(self, z: int) -> list[tuple[int, int]]:
        """The tiles of level z the writer builds: those touching the DEM's box, and both
        level-0 tiles (Cesium starts from them)."""
        xs, ys = self._touching(z)
        got = {(x % (2 << z), y) for x in xs for y in ys}  # x modulo 2^(z+1) names the tile
        if z == 0:
            got |= {(0, 0), (1, 0)}
        return sorted(got, key=lambda k: (k[1], k[0]))

    @functools.cached_property
    def mask(self) -> GeoDem:
        """The level-0 validity (no heights): all valid when the store says every sample
        is; else stored tiles whose every sample is valid (``nvalid``) filled in, the
        others decoded (only tiles along a void, the sea or the padding), absent ones not."""
        t, g = self.terrain, self.terrain.grid
        H, W = g.rows, g.cols
        if t.meta.get("valid_samples") == H * W:
            return GeoDem(t, heights=False, mask=np.ones((H, W), bool))
        step, T = 1 << g.t, g.tile_samples
        v = np.zeros(g.level_shape(0), bool)
        full = [k for k in t.tile_keys(0) if t.tile_info[k]["nvalid"] == T * T]
        part = [k for k in t.tile_keys(0) if t.tile_info[k]["nvalid"] != T * T]
        for _, x, y in full:
            v[y * step:y * step + T, x * step:x * step + T] = True
        for _, x, y in part:
            w = t.tile(0, x, y).valid
            sl = (slice(y * step, y * step + T), slice(x * step, x * step + T))
            v[sl] |= w  # a sample shared with a full tile is valid in both
        return GeoDem(t, heights=False, mask=np.ascontiguousarray(v[:H, :W]))

    def _lattice_validity(self, z: int, tiles: list[tuple[int, int]]
                          ) -> tuple[np.ndarray, np.ndarray]:
        """(len(tiles), M, M) bool twice: where each tile's lattice (:func:`lattice`, the
        same lon/lat as :func:`build_tile`'s) has a bilinear height
        (:meth:`GeoDem.valid_at`), and where it lies inside the grid (valid or not)."""
        M = self.lattice
        valid = np.zeros((len(tiles), M, M), bool)
        inside = np.zeros((len(tiles), M, M), bool)
        for a in range(0, len(tiles), 64):  # 64 tiles' lattices through pyproj at a time
            chunk = tiles[a:a + 64]
            grids = [lattice(tile_rect(z, x, y), M) for x, y in chunk]
            valid[a:a + len(chunk)], inside[a:a + len(chunk)] = self.mask.valid_at(
                np.stack([g[0] for g in grids]), np.stack([g[1] for g in grids]), inside=True)
        return valid, inside

    def _data_tiles(self, z: int) -> frozenset[tuple[int, int]]:
        """The tiles of level z that :func:`build_tile` gives (the writer writes no other),
        from their lattices' validity. rtin: those holding a triangle of valid samples
        (:func:`lattice_has_triangle`: exactly the cut's). tin: those whose lattice is all
        valid (a TIN of valid samples alone); those with at least 3 valid samples and
        nodata inside the grid, built to know (the greedy TIN may join valid samples across
        a cell's other diagonal than the lattice's triangulation, or join none, even
        beside a cell of four valid samples: ``tests/export/test_qmeshtin.py``); those cut
        only by the DEM's edge, by :func:`lattice_has_triangle` as rtin (a rectangle of
        valid samples, or a projected grid's edge: the rule main used, from the
        georeference, refined; not proven for a TIN there)."""
        jobs = self._jobs(z)
        if not jobs:
            return frozenset()
        valid, inside = self._lattice_validity(z, jobs)
        tri = lattice_has_triangle(valid)
        if self.mesher == "rtin":
            return frozenset(jobs[i] for i in np.flatnonzero(tri))
        void = (inside & ~valid).any(axis=(1, 2))  # nodata inside the grid
        out = {jobs[i] for i in np.flatnonzero(tri & ~void)}
        for i in np.flatnonzero(void & (valid.sum(axis=(1, 2)) >= 3)):
            if self._build(z, *jobs[i]) is not None:
                out.add(jobs[i])
        return frozenset(out)

    def level_tiles(self, z: int) -> frozenset[tuple[int, int]]:
        """The (x, y) TMS tiles level z has: the writer's (see the class docs)."""
        if z not in self._levels:
            if not 0 <= z <= self.max_zoom:
                return frozenset()
            if z <= self.data_from - 1:
                self._levels[z] = frozenset(self._jobs(z))
            else:
                self._levels[z] = self._data_tiles(z)
        return self._levels[z]

    @functools.cached_property
    def data_from(self) -> int:
        """The first level with a tile holding data (coarser ones are flat)."""
        for z in range(self.max_zoom + 1):
            got = self._data_tiles(z)
            if got:
                self._levels[z] = got
                return z
        return self.max_zoom + 1

    def exists(self, z: int, x: int, y: int) -> bool:
        """Whether TMS tile (z, x, y) is one of the set's tiles."""
        return 0 <= z <= self.max_zoom and (x, y) in self.level_tiles(z)

    def layer(self, name: str, tiles: str = "{z}/{x}/{y}.terrain?v={version}") -> dict:
        """The set's ``layer.json`` (availability per level, the extensions served)."""
        return {
            "tilejson": "2.1.0", "name": name, "version": "1.0.0",
            "format": "quantized-mesh-1.0", "scheme": "tms", "projection": "EPSG:4326",
            "tiles": [tiles], "bounds": lonlat_bounds(*self.extent),
            "minzoom": 0, "maxzoom": self.max_zoom,
            "available": [availability_ranges(sorted(self.level_tiles(z)))
                          for z in range(self.max_zoom + 1)],
            "extensions": ["octvertexnormals", "watermask", "metadata"],
            "metadataAvailability": METADATA_LEVELS,
            "attribution": "geoterrain",
        }

    # ---------------------------------------------------------------- one tile
    def target(self, z: int) -> tuple[float, float | None]:
        """(the bound's target, the fixed vertex threshold or None) of level z."""
        if z == self.max_zoom:
            return self.max_error, self.max_error
        return cesium_level_error(z), None

    def tile(self, z: int, x: int, y: int) -> tuple[bytes, float, int]:
        """(tile bytes with the octvertexnormals and watermask extensions, not gzipped;
        declared error bound in metres; triangles) of TMS tile (z, x, y), which must
        :meth:`exists`."""
        if z < self.data_from:  # coarser than the data: the flat tile
            return self._flat(z, x, y)
        res = self._build(z, x, y)
        if res is None:
            raise UsageError(f"quantized-mesh tile {z}/{x}/{y} holds no data: the tile set "
                             "has no such tile")
        data, bound, ntri, _ = res
        return data, bound, ntri

    def _build(self, z: int, x: int, y: int):
        """:func:`build_tile`'s result for tile (z, x, y) of a data level (None: no data)."""
        target, fixed = self.target(z)
        return build_tile(self._window(z, x, y), z, x, y, self.lattice, target, self.hrange,
                          fixed_threshold=fixed, mesher=self.mesher)

    def metadata(self, z: int, x: int, y: int) -> dict:
        """The metadata extension's content: the tiles of the next
        :data:`METADATA_LEVELS` levels under this one (CesiumJS learns the set's
        availability from it when ``layer.json`` says ``metadataAvailability``)."""
        out = []
        for d in range(1, METADATA_LEVELS + 1):
            if z + d > self.max_zoom:
                break
            kids = [(cx, cy) for cx, cy in self.level_tiles(z + d)
                    if cx >> d == x and cy >> d == y]
            out.append(availability_ranges(sorted(kids)) if kids else [])
        while out and not out[-1]:
            out.pop()
        return {"available": out}

    def _window(self, z: int, x: int, y: int) -> GeoDem:
        """The DEM under tile (z, x, y) and a margin (the normals' lattice ring and the
        bilinear neighbours): only those level-0 tiles are decoded."""
        w, s, e, n = tile_rect(z, x, y)
        mx, my = (e - w) / (self.lattice - 1), (n - s) / (self.lattice - 1)
        t = np.linspace(0.0, 1.0, 33)
        lon = np.concatenate([w - mx + t * (e - w + 2 * mx), w - mx + t * (e - w + 2 * mx),
                              t * 0 + w - mx, t * 0 + e + mx])
        lat = np.concatenate([t * 0 + s - my, t * 0 + n + my,
                              s - my + t * (n - s + 2 * my), s - my + t * (n - s + 2 * my)])
        i, j = self.geo.pixel(lon, lat)
        j = self.geo.contiguous(j)  # a whole-globe grid's columns across the antimeridian
        win = ((int(np.floor(np.nanmin(i))) - 2, int(np.ceil(np.nanmax(i))) + 2),
               (int(np.floor(np.nanmin(j))) - 2, int(np.ceil(np.nanmax(j))) + 2))
        H, W = self.geo.full
        win = ((max(win[0][0], 0), min(win[0][1], H - 1)),
               win[1] if self.geo.turn else (max(win[1][0], 0), min(win[1][1], W - 1)))
        if win[0][0] > win[0][1] or win[1][0] > win[1][1]:
            return GeoDem(self.terrain, self.geoid, heights=False)
        return GeoDem(self.terrain, self.geoid, window=win)

    def _flat(self, z: int, x: int, y: int) -> tuple[bytes, float, int]:
        """Two triangles at the lowest height over the tile's rectangle; its bound needs no
        heights: every height lies in the quantisation range."""
        rect = tile_rect(z, x, y)
        lon, lat = lattice(rect, 3)
        h = np.full(lon.shape, self.hrange[0])
        valid = np.ones(lon.shape, bool)
        data, faces, _, _ = select_tile(self.geo, rect, 3, lon, lat, h, valid, np.zeros((3, 3)),
                                    0.0, self.hrange, True)
        e_h = 0.5 * (self.hrange[1] - self.hrange[0]) / QMAX
        return data, self.hrange[1] - self.hrange[0] + e_h, len(faces)
