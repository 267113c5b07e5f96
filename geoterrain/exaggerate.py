"""Vertical exaggeration at view time: a terrain whose scene heights are N × the stored ones.

:func:`exaggerated` wraps a terrain so that every LOD strategy, camera and
texture sees the surface (x, y, N·z) without a new preprocess (the stored
``z_scale`` stays what it was). The error data scales with it, so the
selection's guarantee ρ ≤ τ holds for the exaggerated surface:

- δ (a vertical distance) becomes N·δ, exactly;
- a nested sphere of radius r becomes one of radius N·r: for N ≥ 1,
  ‖S(a) − S(b)‖ ≤ N‖a − b‖ with S(x, y, z) = (x, y, N z), so everything the
  sphere held still lies inside (for N < 1 the radius is kept: ‖S(a) − S(b)‖ ≤ ‖a − b‖);
- tile boxes, tile errors and skirt errors are vertical: × N;
- normals of the surface z' = N z are (nx, ny, nz / N), renormalised.

N = 1 returns the terrain itself, so nothing changes there bit for bit.

Examples
--------
>>> e = exaggerated(t, 3.0)
>>> lo, hi = t.scene_box(); elo, ehi = e.scene_box()
>>> bool(abs(ehi[2] - 3 * hi[2]) < 1e-9), exaggerated(t, 1.0) is t
(True, True)
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from geoterrain.core.tilecache import DerivedSlot
from geoterrain.exceptions import UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

_T = TypeVar("_T")
_VERTICAL = ("zmin", "zmax", "error", "boundary_error", "delta_max")


def check_exaggeration(n: float) -> float:
    """``n`` as a float, or a UsageError unless it is finite and > 0."""
    try:
        n = float(n)
    except (TypeError, ValueError):
        raise UsageError(f"vertical_exaggeration must be a number, got {n!r}") from None
    if not (math.isfinite(n) and n > 0):
        raise UsageError(f"vertical_exaggeration must be a finite number > 0, got {n}",
                         cli=f"--vertical-exaggeration must be a finite number > 0, got {n}")
    return n


def exaggerated(terrain: TerrainLike, n: float) -> TerrainLike:
    """``terrain`` seen with its heights × ``n`` (the same object when n = 1; one view a
    factor, kept with the terrain)."""
    n = check_exaggeration(n)
    if n == 1.0:
        return terrain
    if isinstance(terrain, Exaggerated):
        return exaggerated(terrain.base, terrain.n * n)
    per = terrain.derived(__name__, dict)
    if n not in per:
        per[n] = Exaggerated(terrain, n)
    return per[n]


class Exaggerated:
    """A read-only view of a terrain with its scene heights (and error data) × ``n``.

    It implements :class:`~geoterrain.terrainlike.TerrainLike`. Everything not
    overridden here is the base terrain's own (grid, tiles in source units, tile keys,
    x, y, the tile cache); what other modules derive from it (:meth:`derived`) is its
    own, as its error data differ.
    """

    def __init__(self, base: TerrainLike, n: float):
        self.base, self.n = base, float(n)
        self.r_scale = max(self.n, 1.0)
        self.frame = dataclasses.replace(base.frame, z_scale=base.frame.z_scale * self.n)
        self._scale_info()
        self._own: dict = {}
        self._derived = DerivedSlot()
        self.generation = 0
        self._base_generation = getattr(base, "generation", 0)

    def _scale_info(self) -> None:
        base = self.base
        self.tile_info = {}
        for k, v in base.tile_info.items():
            d = dict(v)
            for f in _VERTICAL:
                if d.get(f) is not None:
                    d[f] = d[f] * self.n
            if d.get("radius_max") is not None:
                d["radius_max"] = d["radius_max"] * self.r_scale
            self.tile_info[k] = d

    def refresh(self) -> bool:
        """Take in the base store's edits (:meth:`geoterrain.terrain.Terrain.refresh`):
        this view's scaled copies and derived data are made again."""
        self.base.refresh()
        if self.base.generation == self._base_generation:
            return False
        self._base_generation = self.base.generation
        self._scale_info()
        self._own.clear()
        self._derived.forget()
        self.generation += 1
        return True

    stored_normals = False  # tile_normals are rescaled, not the stored codes' normals

    def derived(self, owner: str, make: Callable[[], _T]) -> _T:
        """This view's own :meth:`~geoterrain.terrain.Terrain.derived` slot."""
        return self._derived.get(owner, make)

    def forget(self, owner: str | None = None) -> None:
        """Drop what ``owner`` derived from this view (every module's with None)."""
        self._derived.forget(owner)

    def __getattr__(self, name):
        return getattr(self.base, name)

    def __repr__(self) -> str:
        return f"<exaggerated ×{self.n:g} {self.base!r}>"

    @property
    def vertical_exaggeration(self) -> float:
        return self.n

    @property
    def stand_in_z(self) -> float:
        return self.base.stand_in_z * self.n

    def scene_box(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.base.scene_box()
        lo, hi = lo.copy(), hi.copy()
        lo[2], hi[2] = sorted((lo[2] * self.n, hi[2] * self.n))
        return lo, hi

    def _scaled(self, kind: str, key: tuple, make):
        k = (kind, *key)
        if k not in self._own:
            self._own[k] = make()
        return self._own[k]

    def tile_delta(self, level: int, x: int, y: int) -> np.ndarray:
        return self._scaled("d", (level, x, y), lambda: (self.base.tile_delta(level, x, y)
                                                         * np.float32(self.n)))

    def tile_delta_edge(self, level: int, x: int, y: int) -> np.ndarray:
        return self._scaled("de", (level, x, y), lambda: (
            self.base.tile_delta_edge(level, x, y) * np.float32(self.n)))

    @property
    def edge_max(self) -> dict | None:
        """The base's tiles with a second δ (edgepad.py), their maxima × n."""
        em = self.base.edge_max
        if em is None:
            return None
        return self._scaled("em", (), lambda: {k: v * self.n for k, v in em.items()})

    def block_errors(self) -> np.ndarray | None:
        """The base's GeoMipMapping δ_n table × n (None for an older store)."""
        b = self.base.block_errors()
        if b is None:
            return None
        return self._scaled("be", (), lambda: b * self.n)

    def tile_radius(self, level: int, x: int, y: int) -> np.ndarray:
        return self._scaled("r", (level, x, y), lambda: (self.base.tile_radius(level, x, y)
                                                         * np.float32(self.r_scale)))

    def tile_normals(self, level: int, x: int, y: int) -> np.ndarray:
        def make():
            nm = self.base.tile_normals(level, x, y).astype(np.float32, copy=True)
            nm[..., 2] /= self.n
            return nm / np.linalg.norm(nm, axis=-1, keepdims=True)
        return self._scaled("n", (level, x, y), make)

    def _scale_kinds(self, out: dict) -> dict:
        if "delta" in out:
            out["delta"] = out["delta"] * self.n
        if "radius" in out:
            out["radius"] = out["radius"] * self.r_scale
        return out

    def gather(self, i, j, kinds=("delta", "radius", "height")) -> dict:
        return self._scale_kinds(self.base.gather(i, j, kinds))

    def tile_stacks(self, keys, kinds=("delta",)) -> dict:
        return self._scale_kinds(self.base.tile_stacks(keys, kinds))

    def scene_xyz(self):
        X, Y, Z = self.base.scene_xyz()
        return X, Y, Z * self.n

    def select(self, view, pixel_error: float = 1.0, strategy: str = "rtin", *,
               reuse: bool = True, occlusion: bool | None = None, morph: bool | None = None):
        from geoterrain import lod

        return lod.select(self, view, pixel_error, strategy, reuse=reuse, occlusion=occlusion,
                          morph=morph)

    def static_selection(self, max_error: float = 1.0, mesher: str = "rtin"):
        from geoterrain import lod

        return lod.static(self, max_error, mesher)

    def mesh(self, max_error: float = 1.0, method: str = "rtin"):
        return self.static_selection(max_error, mesher=method).mesh
