"""The LOD strategies, by name: one line each.

This module is light to import (no numba, no VTK): the command line's choices,
its ``--help`` and the viewer's strategy key all read the names from here, and
a strategy's module is imported only when it first selects a mesh.

Adding a strategy means writing one module ``geoterrain/lod/NAME.py`` with a
function ``select(terrain, view, tau) -> (pyvista.PolyData, dict)`` and adding
one :class:`StrategyInfo` line to ``_ENTRIES`` below.

Examples
--------
>>> STRATEGIES  # doctest: +NORMALIZE_WHITESPACE
('rtin', 'chunked', 'bruteforce', 'geomipmap', 'geomipmap_distance', 'quadtree', 'cdlod',
 'tessellation', 'gtr', 'gtr_bounded', 'lauritsen_nielsen', 'roam', 'roam_split',
 'clipmap', 'clipmap_bounded', 'clipmap_gpu', 'rottger')
>>> strategy_info("chunked").bounded
True
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from geoterrain.exceptions import UsageError

__all__ = ["DEFAULT", "REGISTRY", "STRATEGIES", "StrategyInfo", "strategy_info", "describe"]


@dataclass(frozen=True)
class StrategyInfo:
    """One LOD strategy: its name, the module holding its ``select``, and what it promises.

    ``bounded``: the measured screen-space error ρ of its meshes is ≤ τ (tested);
    ``tau_independent``: the mesh does not depend on τ (a benchmark selects it once);
    ``conforming``: no T-junction and no edge used by more than two triangles (tested);
    ``morphs``: it geomorphs when morphing is on (``--morph``), keeping its bound;
    ``morph_default``: it morphs unless switched off (``--no-morph``);
    ``culls``: it leaves out what lies well outside the frustum (tested); False: it draws
    its whole geometry wherever the camera looks (``clipmap``: a steady count).
    Every strategy draws both grid layouts (a root grid and the square).
    ``summary`` names the method and its source (for the strategy docs); ``words`` says
    what it does in a user's words (for ``--help``).
    """

    name: str
    module: str
    summary: str
    words: str
    bounded: bool
    tau_independent: bool = False
    conforming: bool = False
    morphs: bool = False
    morph_default: bool = False
    culls: bool = True

    def load(self) -> Callable:
        """The strategy's ``select(terrain, view, tau, *, occlusion, morph) -> (mesh,
        stats)`` (imports it)."""
        return importlib.import_module(self.module).select


_ENTRIES = (
    StrategyInfo("rtin", "geoterrain.lod.rtin",
                 "Lindstrom–Pascucci vertex refinement with nested spheres (seed 002)",
                 "triangles refined where the view needs them, crack-free (the default)",
                 True, conforming=True, morphs=True),
    StrategyInfo("chunked", "geoterrain.lod.chunked",
                 "stored tile quadtree with skirts (seed 000 chunked LOD)",
                 "ready-made tiles at several resolutions, seams hidden by skirts", True,
                 morphs=True),
    StrategyInfo("bruteforce", "geoterrain.lod.bruteforce",
                 "every full-resolution tile in the frustum (the zero-error baseline)",
                 "every sample in view at full resolution (exact, slowest)", True,
                 tau_independent=True, conforming=True),
    StrategyInfo("geomipmap", "geoterrain.lod.geomipmap",
                 "GeoMipMapping: level-0 tile blocks, stitched edges (seed 000 §2.4)",
                 "blocks drawn at coarser steps by their error, edges stitched", True,
                 conforming=True, morphs=True),
    StrategyInfo("geomipmap_distance", "geoterrain.lod.geomipmap_distance",
                 "GeoMipMapping with the thesis's switch distances D_n = δ·C (unbounded)",
                 "blocks switched at fixed distances (error not guaranteed)",
                 False, conforming=True),
    StrategyInfo("quadtree", "geoterrain.lod.quadtree",
                 "restricted quadtree, Manhattan-distance LOD (seed 003; unbounded)",
                 "a quadtree refined by distance (error not guaranteed)", False,
                 conforming=True),
    StrategyInfo("cdlod", "geoterrain.lod.cdlod",
                 "CDLOD: tile quadtree, one range per level, morphed, no skirts (seed 001)",
                 "tiles by distance ranges, blended smoothly between levels", True,
                 morphs=True, morph_default=True),
    StrategyInfo("tessellation", "geoterrain.lod.tessellation",
                 "HAM-driven quad-domain tessellation, factors 1-64 (seed 004; unbounded)",
                 "tiles subdivided by how rough they are (error not guaranteed)",
                 False, conforming=True),
    StrategyInfo("gtr", "geoterrain.lod.gtr",
                 "GPU Terrain Rendering as the thesis built it: fixed-size blocks, "
                 "D_n = δ_b·C, skirts, morphed (seed 000 §2.8; unbounded)",
                 "fixed-size blocks switched by distance (error not guaranteed)", False,
                 morphs=True, morph_default=True),
    StrategyInfo("gtr_bounded", "geoterrain.lod.gtr_bounded",
                 "GPU Terrain Rendering's blocks refined by the exact tile error over the "
                 "box distance (seed 000 §2.8)",
                 "fixed-size blocks refined by their error, seams hidden by skirts",
                 True, morphs=True),
    StrategyInfo("lauritsen_nielsen", "geoterrain.lod.lauritsen_nielsen",
                 "Lauritsen & Nielsen: GeoMipMapping chunks in a chunked-LOD quadtree, "
                 "δ_b of eq. 4-23 (seed 000 §2.7)",
                 "blocks drawn at coarser steps, grouped in a quadtree by their error",
                 True, morphs=True),
    StrategyInfo("roam", "geoterrain.lod.roam",
                 "ROAM: triangle bintrees, wedgies, split and merge queues from the last "
                 "frame (seed 000 §2.2)",
                 "triangles split and merged from the last frame by their error",
                 True, conforming=True),
    StrategyInfo("roam_split", "geoterrain.lod.roam_split",
                 "McNally's split-only ROAM, variance over distance (seed 000 §2.2; "
                 "unbounded)",
                 "triangles split by roughness over distance (error not guaranteed)",
                 False, conforming=True),
    StrategyInfo("clipmap", "geoterrain.lod.clipmap",
                 "geometry clipmaps: nested viewer-centred 255² grids, toroidal updates, "
                 "transition regions, whole rings drawn for a steady triangle count, "
                 "the paper's culling with cull=True (seed 000 §2.9; unbounded)",
                 "nested grids centred on the viewer, drawn whole: a steady triangle "
                 "count (error not guaranteed)", False,
                 tau_independent=True, conforming=True, morphs=True, morph_default=True,
                 culls=False),
    StrategyInfo("clipmap_bounded", "geoterrain.lod.clipmap_bounded",
                 "geometry clipmaps whose finest level and region sizes come from the tile "
                 "errors (seed 000 §2.9)",
                 "nested grids centred on the viewer, sized by the terrain's error",
                 True, conforming=True, morphs=True,
                 morph_default=True),
    StrategyInfo("clipmap_gpu", "geoterrain.lod.clipmap_gpu",
                 "GPU-based geometry clipmaps: footprints, vertex-texture heights, emulated "
                 "on arrays, each footprint culled (seed 000 §2.10; unbounded)",
                 "nested grids built from reusable pieces, those out of view left out "
                 "(error not guaranteed)",
                 False, tau_independent=True,
                 conforming=True, morphs=True, morph_default=True),
    StrategyInfo("rottger", "geoterrain.lod.rottger",
                 "Röttger's quadtree matrix: d2 roughness propagated by K, fans, then refined "
                 "to the LP δ bound, eq. 4-7 blend (seed 000 §2.3)",
                 "a quadtree refined by roughness and distance, crack-free", True, conforming=True,
                 morphs=True),
)

REGISTRY: dict[str, StrategyInfo] = {e.name: e for e in _ENTRIES}
STRATEGIES: tuple[str, ...] = tuple(REGISTRY)
DEFAULT = "rtin"


def strategy_info(name: str) -> StrategyInfo:
    """The registered strategy ``name``; a :class:`UsageError` naming the choices otherwise.

    Examples
    --------
    >>> strategy_info("rtin").module
    'geoterrain.lod.rtin'
    """
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise UsageError(f"unknown strategy {name!r}; use one of {', '.join(STRATEGIES)}"
                         ) from None


def describe(words: bool = True) -> str:
    """One line per strategy, ``name: what it does``, for help texts (``words``: in a
    user's words; else its technical summary with its source, for the strategy docs).

    Examples
    --------
    >>> describe().splitlines()[0]
    'rtin: triangles refined where the view needs them, crack-free (the default)'
    """
    return "\n".join(f"{e.name}: {e.words if words else e.summary}" for e in _ENTRIES)
