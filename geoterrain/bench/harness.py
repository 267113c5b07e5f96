"""Benchmark harness: runtime against measured error across LOD strategies.

Every registered strategy (:data:`geoterrain.lod.STRATEGIES`) is run at every pixel
tolerance τ over one camera path. Each frame records the selection time, the
optional render time, the mesh size, the tiles decoded, the peak memory the
selection allocated and the *measured* screen-space error of the mesh against
the full-resolution heights (:func:`geoterrain.testing.measure.screen_space_error`).

The result is a list of tidy rows (one per frame × strategy × τ) that
:mod:`geoterrain.bench.report` turns into a CSV file, a table and a figure.
:func:`benchmark` is the whole job behind ``geoterrain bench``: preprocess a DEM
(or a synthetic one) when needed, run the flight, and compare static meshes with
the peers.

Examples
--------
>>> from geoterrain.bench.report import format_table, summarise
>>> res = run(t, n_views=4, taus=(1.0,), strategies=("rtin",))
>>> [r["view"] for r in res.rows]
['overview', 'oblique', 'grazing', 'away']
>>> all(r["err_max"] <= 1.0 + 1e-6 for r in res.rows)
True
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain import lod
from geoterrain.core.view import View, load_views
from geoterrain.exceptions import UsageError
from geoterrain.lod.registry import STRATEGIES, strategy_info
from geoterrain.store.schema import is_store
from geoterrain.testing.measure import screen_space_change, screen_space_error, vertical_error

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

BRUTE_MEASURE_LIMIT = 4_000_000  # bruteforce meshes larger than this are not rasterised
TAUS = (0.5, 1.0, 2.0, 4.0, 8.0)
VIEW_KINDS = ("overview", "oblique", "grazing", "away")
SIZE = (1280, 720)
FOV = 30.0
Progress = Callable[[int], None]


@dataclass
class BenchResult:
    """Rows of one benchmark run and what it was run on."""

    rows: list[dict] = field(default_factory=list)
    peers: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    views: list[tuple[str, View]] = field(default_factory=list)
    wall_s: float = 0.0
    label: str = ""
    preprocess_s: float | None = None
    store_bytes: int | None = None


# ----------------------------------------------------------------- cameras
def extent(X: np.ndarray, Y: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(Z)
    lo = np.array([X[ok].min(), Y[ok].min(), Z[ok].min()], np.float64)
    hi = np.array([X[ok].max(), Y[ok].max(), Z[ok].max()], np.float64)
    return lo, hi


def flight(lo: Sequence[float], hi: Sequence[float], n_views: int = 8,
           size: tuple[int, int] = SIZE, fov_y_deg: float = FOV) -> list[tuple[str, View]]:
    """A built-in camera path over the box ``lo``–``hi`` (scene frame).

    The path cycles through four kinds of view while circling the terrain:
    ``overview`` (high, steep, whole terrain), ``oblique`` (low oblique from
    the edge towards the centre), ``grazing`` (just above the highest point,
    looking at the horizon across the terrain) and ``away`` (from the edge,
    looking out of the terrain: almost everything is culled).

    Parameters
    ----------
    lo, hi : (3,) scene-frame box of the valid data.
    n_views : number of views (≥ 1).
    size, fov_y_deg : image size and vertical field of view.

    Returns
    -------
    list of (kind, View)

    Examples
    --------
    >>> v = flight((-500, -500, 0), (500, 500, 100), n_views=4)
    >>> [k for k, _ in v]
    ['overview', 'oblique', 'grazing', 'away']
    """
    if n_views < 1:
        raise UsageError(f"n_views must be ≥ 1, got {n_views}",
                         cli=f"--views must be ≥ 1, got {n_views}")
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = 0.5 * (lo + hi)
    half = max(float(np.hypot(*(hi[:2] - lo[:2]))) / 2, 1e-3)
    relief = max(float(hi[2] - lo[2]), 1e-3 * half)
    ty = math.tan(math.radians(fov_y_deg) / 2)
    views: list[tuple[str, View]] = []
    for k in range(n_views):
        kind = VIEW_KINDS[k % len(VIEW_KINDS)]
        az = math.radians(200.0 + 360.0 * k / n_views)
        d = np.array([math.sin(az), math.cos(az), 0.0])  # horizontal unit, centre → eye
        if kind == "overview":
            dist = 1.1 * half / ty
            el = math.radians(55.0)
            eye = c + dist * np.array([d[0] * math.cos(el), d[1] * math.cos(el), math.sin(el)])
            at = c.copy()
        elif kind == "oblique":
            eye = c + 0.9 * half * d
            eye[2] = hi[2] + 0.15 * half
            at = c.copy()
            at[2] = lo[2] + 0.3 * relief
        elif kind == "grazing":
            eye = c + 0.7 * half * d
            eye[2] = hi[2] + 0.02 * half
            at = c - 2.0 * half * d
            at[2] = eye[2] - 0.02 * half
        else:  # away: on the edge, looking outwards and slightly down
            eye = c + 0.8 * half * d
            eye[2] = hi[2] + 0.05 * half
            at = eye + half * d
            at[2] = eye[2] - 0.1 * half
        views.append((kind, View(tuple(eye), tuple(at), (0.0, 0.0, 1.0), fov_y_deg, size)))
    return views


def glide(lo: Sequence[float], hi: Sequence[float], n_frames: int = 60, step: float = 0.01,
          size: tuple[int, int] = SIZE, fov_y_deg: float = FOV) -> list[tuple[str, View]]:
    """A smooth flight for the popping metric: a straight low pass across the terrain.

    The eye starts over one edge, 0.15 × the half-diagonal above the highest point,
    and flies towards the far side looking ahead and down; each frame it moves by
    ``step`` × its height above the highest point (so at most ``step`` of its height
    above the terrain below it: the issue's 1 % per frame).

    Examples
    --------
    >>> v = glide((-500, -500, 0), (500, 500, 100), n_frames=3)
    >>> [k for k, _ in v], round(float(np.linalg.norm(v[1][1].eye - v[0][1].eye)), 3)
    (['glide', 'glide', 'glide'], 1.061)
    """
    if n_frames < 1:
        raise UsageError(f"n_frames must be ≥ 1, got {n_frames}")
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = 0.5 * (lo + hi)
    half = max(float(np.hypot(*(hi[:2] - lo[:2]))) / 2, 1e-3)
    d = np.array([0.6, 0.8, 0.0])  # horizontal heading
    eye = c - 0.7 * half * d
    eye[2] = hi[2] + 0.15 * half
    views = []
    for _ in range(n_frames):
        at = eye + half * d
        at[2] = lo[2]
        views.append(("glide", View(tuple(eye), tuple(at), (0.0, 0.0, 1.0), fov_y_deg, size)))
        eye = eye + step * (eye[2] - hi[2]) * d
    return views


def ground_views(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, n: int, seed: int = 0,
                 size: tuple[int, int] = (320, 180), fov_y_deg: float = 45.0
                 ) -> list[tuple[View, tuple[int, int]]]:
    """``n`` low views from just above random valid samples (rows/columns 1 … −2),
    looking across the terrain 8° down to 3° up: where nearer terrain hides farther.

    The eye stands (0.5, 3 or 20) × (std(Z)/50 + 0.1) above its sample (the sample's
    (row, column) comes with each view), and looks half the data's extent away.

    Examples
    --------
    >>> I, J = np.indices((9, 9)).astype(float)
    >>> v, (i, j) = ground_views(J, -I, np.zeros((9, 9)), 1)[0]
    >>> bool(1 <= i <= 7 and v.eye[2] > 0)
    True
    """
    ok = np.isfinite(Z)
    H, W = Z.shape
    if H < 3 or W < 3 or not ok[1:-1, 1:-1].any():
        raise UsageError("ground views need valid samples off the border")
    rng = np.random.default_rng(seed)
    ext = float(max(np.ptp(X[ok]), np.ptp(Y[ok])))
    std = float(np.nanstd(np.where(ok, Z, np.nan)))
    out = []
    while len(out) < n:
        i, j = int(rng.integers(1, H - 1)), int(rng.integers(1, W - 1))
        if not ok[i, j]:
            continue
        h = float(rng.choice([0.5, 3.0, 20.0])) * (std / 50 + 0.1)
        az, pitch = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(-8, 3))
        eye = np.array([X[i, j], Y[i, j], Z[i, j] + h])
        at = eye + 0.5 * ext * np.array([np.cos(az) * np.cos(pitch),
                                         np.sin(az) * np.cos(pitch), np.sin(pitch)])
        out.append((View(tuple(eye), tuple(at), size=size, fov_y_deg=fov_y_deg), (i, j)))
    return out


def load_path(path: str | Path, size: tuple[int, int] = SIZE,
              fov_y_deg: float = FOV, frame=None) -> list[tuple[str, View]]:
    """Views from a cameras JSON file (:func:`geoterrain.core.view.load_views`), labelled "path".

    Examples
    --------
    >>> import json, tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "cams.json")
    >>> _ = open(p, "w").write(json.dumps([{"look_from": [0, -10, 5], "look_at": [0, 0, 0]}]))
    >>> [(k, v.look_from) for k, v in load_path(p)]
    [('path', (0.0, -10.0, 5.0))]
    """
    return [("path", v) for v in load_views(path, size, fov_y_deg, frame)]


# ----------------------------------------------------------------- measuring
def _mesh_key(ij: np.ndarray, faces: np.ndarray, z: np.ndarray) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in (ij, faces, z):
        h.update(np.ascontiguousarray(a).view(np.uint8).data)
    return h.hexdigest()


def _renderer(size: tuple[int, int], terrain: TerrainLike, anti_aliasing: str,
              occlusion: bool, morph: bool | None):
    """An offscreen render scene of ``size`` for ``terrain``."""
    from geoterrain.rendering.scene import TerrainScene
    from geoterrain.rendering.window import pyvista_plotter

    return TerrainScene(pyvista_plotter(size, anti_aliasing), terrain, occlusion=occlusion,
                        morph=morph)


def _selection_peak(terrain: TerrainLike, view: View, tau: float, strategy: str,
                    switches: dict) -> int:
    """Peak bytes allocated while selecting again (tracemalloc slows Python code, so the
    timed selection runs without it; this second run finds the tiles already decoded)."""
    tracemalloc.start()
    try:
        lod.select(terrain, view, pixel_error=tau, strategy=strategy, reuse=False, **switches)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _measuring_handle(terrain: TerrainLike):
    """A second handle on ``terrain``'s store (its own cache), or ``terrain`` itself."""
    from geoterrain.terrain import Terrain

    return Terrain(terrain.path) if type(terrain) is Terrain else terrain


def _empty_cache(terrain: TerrainLike) -> None:
    """Empty the terrain's tile cache (decoded heights, bounds, normals, textures)."""
    terrain.clear_cache()


def _counters(terrain: TerrainLike) -> tuple[int, int, int, int]:
    return (int(terrain.decoded_tiles), int(getattr(terrain, "decoded_normals", 0)),
            int(getattr(terrain, "decoded_bounds", 0)), int(getattr(terrain, "bytes_read", 0)))


def run(terrain: TerrainLike, views: Sequence[tuple[str, View]] | None = None, *,
        strategies: Sequence[str] = STRATEGIES, taus: Sequence[float] = TAUS,
        n_views: int = 8, render: bool = False, source: str = "",
        preprocess_s: float | None = None, store_bytes: int | None = None,
        progress: Progress | None = None, pop: bool = True, occlusion: bool = True,
        morph: bool | None = None, anti_aliasing: str = "auto") -> BenchResult:
    """Run every strategy at every τ over ``views`` and measure each frame.

    Parameters
    ----------
    terrain : geoterrain.Terrain
    views : (kind, View) pairs; default :func:`flight` over the terrain's extent.
    strategies, taus : what to run (every combination).
    n_views : length of the default flight.
    render : also render each frame offscreen and time it.
    source, preprocess_s, store_bytes : recorded in every row.
    progress : called with the number of frames done since the last call.
    pop : measure ``pop_px``, the largest jump of the drawn surface since the previous
        frame of the same strategy and τ (:func:`geoterrain.testing.measure.screen_space_change`;
        meaningful on a smooth path such as :func:`glide`; NaN on the first frame).
    occlusion, morph : the selections' horizon culling and geomorphing
        (:func:`geoterrain.lod.select`).
    anti_aliasing : the rendered frames' (:func:`geoterrain.rendering.scene.render`).

    Returns
    -------
    BenchResult
        ``rows`` with the columns of :data:`COLUMNS`. ``select_cold_ms`` and the
        decode counts (``tiles_decoded`` heights, ``normals_decoded``, ``bounds_decoded``,
        ``bytes_read``) come from a selection with an empty tile cache;
        ``select_ms`` from the same selection again (warm); ``textures_built`` from
        the render (``render=True``); ``peak_mem_mb`` is the peak
        allocated by a second, identical selection under ``tracemalloc`` (which slows
        Python code, so it never runs during the timed one); ``err_*`` are in pixels.

    Examples
    --------
    >>> res = run(t, n_views=1, taus=(1.0,))
    >>> sorted({r["strategy"] for r in res.rows}) == sorted(STRATEGIES)
    True
    """
    once = {s: strategy_info(s).tau_independent for s in strategies}
    for tau in taus:
        if not (math.isfinite(tau) and tau > 0):
            raise UsageError(f"every τ must be a finite number > 0, got {tau}")
    t_start = time.perf_counter()
    # the error measure reads every level-0 height: through a second handle, so the
    # timed terrain's cache is not filled with them before the frames
    X, Y, Z = _measuring_handle(terrain).scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    if views is None:
        views = flight(*extent(X, Y, Z), n_views=n_views)
    res = BenchResult(views=list(views))
    scene = None
    aa = ""  # the pictures' anti-aliasing (edges, msaa, fxaa or none) when they are drawn
    switches = {"occlusion": occlusion, "morph": morph}
    if render:
        scene = _renderer(views[0][1].size, terrain, anti_aliasing, occlusion, morph)
        aa = str(getattr(scene.plotter, "_geoterrain_aa", ""))
    cache: dict[str, tuple] = {}
    previous: dict[tuple, tuple] = {}  # (strategy, τ) → last frame's surface, for pop_px
    try:
        for fi, (kind, view) in enumerate(views):
            for strategy in strategies:
                for ti, tau in enumerate(taus):
                    if once[strategy] and ti > 0:  # τ-independent: select once
                        res.rows.append({**res.rows[-1], "tau": float(tau)})
                        if progress:
                            progress(1)
                        continue
                    # cold: an empty tile cache; warm: the same selection again (both real
                    # selections, never a reuse of the last one)
                    _empty_cache(terrain)
                    c0 = _counters(terrain)
                    cold = lod.select(terrain, view, pixel_error=float(tau), strategy=strategy,
                                      reuse=False, **switches)
                    c1 = _counters(terrain)
                    sel = lod.select(terrain, view, pixel_error=float(tau), strategy=strategy,
                                     reuse=False, **switches)
                    peak = _selection_peak(terrain, view, float(tau), strategy, switches)
                    render_ms, textures_built, frame_aa = float("nan"), 0, aa
                    if scene is not None:
                        _, rs = scene.frame(view, float(tau), strategy)  # reuses the selection
                        render_ms = float(rs["update_ms"] + rs["render_ms"])
                        textures_built = int(rs.get("textures_built", 0))
                        frame_aa = str(rs.get("anti_aliasing", aa))  # auto: the one taken
                    pts = np.asarray(sel.mesh.points, np.float64)
                    faces = sel.surface_faces()
                    ij = sel.ij
                    vz = pts[:, 2] if len(pts) else np.zeros(0)
                    key = _mesh_key(ij, faces, vz)
                    if strategy == "bruteforce" and len(faces) > BRUTE_MEASURE_LIMIT:
                        # every full-resolution triangle: error 0 by construction
                        # (tests/lod/test_lod.py measures it); rasterising it costs GBs
                        cache = {key: (0.0, 0.0, 0.0, -1, -1)}
                    elif key not in cache:  # a τ-independent mesh is measured once
                        e = screen_space_error(ij, faces, vz, X, Y, Zt, valid, view.eye,
                                               view.planes, view.lam)
                        cache = {key: (e.max, e.p99, e.mean, e.n_samples, e.n_uncovered)}
                    emax, ep99, emean, ns, nu = cache[key]
                    pop_px = float("nan")
                    if pop and len(faces) <= BRUTE_MEASURE_LIMIT:
                        before = previous.get((strategy, float(tau)))
                        if before is not None:
                            pop_px = screen_space_change(before[0], (ij, faces, vz), X, Y, Zt,
                                                         valid, view.eye, view.planes,
                                                         view.lam, before[1]).max
                        previous[(strategy, float(tau))] = ((ij, faces, vz), view.planes)
                    st = sel.stats
                    res.rows.append({
                        "source": source, "frame": fi, "view": kind, "strategy": strategy,
                        "tau": float(tau), "select_ms": float(st["select_ms"]),
                        "render_ms": render_ms, "anti_aliasing": frame_aa,
                        "triangles": int(st["triangles"]),
                        "skirt_triangles": int(st.get("skirt_triangles", 0)),
                        "vertices": int(st["vertices"]),
                        "select_cold_ms": float(cold.stats["select_ms"]),
                        "tiles_decoded": c1[0] - c0[0], "normals_decoded": c1[1] - c0[1],
                        "bounds_decoded": c1[2] - c0[2], "bytes_read": c1[3] - c0[3],
                        "textures_built": textures_built,
                        "peak_mem_mb": round(peak / 2**20, 3), "err_max": emax,
                        "err_p99": ep99, "err_mean": emean, "pop_px": pop_px,
                        "samples_in_view": ns,
                        "uncovered_in_view": nu,
                        "preprocess_s": preprocess_s if preprocess_s is not None else "",
                        "store_bytes": store_bytes if store_bytes is not None else "",
                    })
                    if progress:
                        progress(1)
    finally:
        if scene is not None:
            scene.plotter.close()
    res.wall_s = time.perf_counter() - t_start
    return res


# ----------------------------------------------------------------- peers
def _padded_scene_heights(terrain: TerrainLike) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Level-0 heights in scene units on the padded (2^k+1)² grid, padding filled by
    replicating the source edge; and the source-region valid mask, rows, cols."""
    h, v = terrain.level_heights(0)
    H, W = terrain.grid.rows, terrain.grid.cols
    z = terrain.frame.z(h)
    src = z[:H, :W]
    ok = v[:H, :W]
    zp = np.pad(src, ((0, z.shape[0] - H), (0, z.shape[1] - W)), mode="edge")
    return zp, ok, H, W


def peers(terrain: TerrainLike, errors: Sequence[float]) -> tuple[list[dict], list[str]]:
    """Static meshes of rtin, pymartini and pydelatin at the same vertical error targets.

    Each mesh is measured with :func:`geoterrain.testing.measure.vertical_error` on the
    valid source samples, so the rows compare triangles and build time at a
    matched *measured* error. Peers that are not installed, or cannot take the
    data (nodata), are skipped with a note.

    Examples
    --------
    >>> rows, notes = peers(t, [1.0, 4.0])  # doctest: +SKIP
    >>> sorted({r["method"] for r in rows})  # doctest: +SKIP
    ['pydelatin', 'pymartini', 'rtin-static']
    """
    rows: list[dict] = []
    notes: list[str] = []
    zp, ok, H, W = _padded_scene_heights(terrain)
    Zs = np.where(ok, zp[:H, :W], 0.0)

    def add(method, target, ms, ij, faces, vz):
        e = vertical_error(ij, faces, vz, Zs, ok)
        rows.append({"method": method, "target_m": float(target), "build_ms": round(ms, 3),
                     "triangles": int(len(faces)), "vertices": int(len(ij)),
                     "err_max_m": e.max, "err_p99_m": e.p99, "uncovered": e.n_uncovered_valid})

    for E in errors:
        t0 = time.perf_counter()
        sel = lod.static(terrain, E)
        ms = (time.perf_counter() - t0) * 1e3
        pts = np.asarray(sel.mesh.points)
        add("rtin-static", E, ms, sel.ij, sel.surface_faces(), pts[:, 2] if len(pts) else [])
    has_nodata = not ok.all()
    z32 = zp.astype(np.float32)
    try:
        import pymartini
    except ImportError:
        notes.append("pymartini not installed: skipped")
    else:
        if has_nodata:
            notes.append("pymartini: the DEM has nodata, which Martini cannot skip: skipped")
        else:
            for E in errors:
                t0 = time.perf_counter()
                # Martini reads terrain[y * size + x]: x is the column j, y the row i
                tile = pymartini.Martini(zp.shape[0]).create_tile(np.ascontiguousarray(z32))
                vxy, tri = tile.get_mesh(float(E))
                ms = (time.perf_counter() - t0) * 1e3
                ij = np.asarray(vxy, np.int64).reshape(-1, 2)[:, ::-1]
                add("pymartini", E, ms, ij, np.asarray(tri, np.int64).reshape(-1, 3),
                    zp[ij[:, 0], ij[:, 1]])
    try:
        from pydelatin import Delatin
    except ImportError:
        notes.append("pydelatin not installed: skipped")
    else:
        if has_nodata:
            notes.append("pydelatin: the DEM has nodata, which Delatin cannot skip: skipped")
        else:
            src = np.ascontiguousarray(z32[:H, :W])
            for E in errors:
                t0 = time.perf_counter()
                d = Delatin(src, height=H, width=W, max_error=float(E))
                vxy, tri = d.vertices, d.triangles
                ms = (time.perf_counter() - t0) * 1e3
                vxy = np.asarray(vxy, np.float64)  # (x, y, z) with y counted from the last row
                ij = np.stack([(H - 1) - vxy[:, 1], vxy[:, 0]], 1)
                ii = np.clip(np.rint(ij).astype(np.int64), 0, [H - 1, W - 1])
                add("pydelatin", E, ms, ij, np.asarray(tri, np.int64).reshape(-1, 3),
                    zp[ii[:, 0], ii[:, 1]])
    if rows:
        notes.append("peers triangulate float32 heights; errors are measured against float64")
    return rows, notes




# ----------------------------------------------------------------- the whole job
def default_peer_errors(terrain: TerrainLike) -> tuple[float, ...]:
    """Vertical errors for :func:`peers`: 0.5, 1, 2, 4, 8 × max(codec step, 0.1 % of relief).

    Examples
    --------
    >>> len(default_peer_errors(t))
    5
    """
    step = float(getattr(terrain.quantizer, "step", 0.0) or 0.0)
    lo_h, hi_h = terrain.meta["height_range"]
    base = max(step, 1e-3 * float(hi_h - lo_h), 1e-6)
    return tuple(base * k for k in (0.5, 1, 2, 4, 8))


ProgressTotal = Callable[[int, int], None]


def benchmark(source: str | Path | None = None, *, synthetic: int | None = None, seed: int = 1,
              strategies: Sequence[str] = STRATEGIES, taus: Sequence[float] = TAUS,
              n_views: int = 8, cameras: str | Path | None = None,
              size: tuple[int, int] = SIZE, render: bool = False, peer_errors:
              Sequence[float] | bool = False, work_dir: str | Path | None = None,
              progress: ProgressTotal | None = None, occlusion: bool = True,
              morph: bool | None = None, anti_aliasing: str = "auto") -> BenchResult:
    """The whole benchmark of ``geoterrain bench``: store, flight, strategies, peers.

    Parameters
    ----------
    source : a store, or a DEM (preprocessed first into ``work_dir``, timed).
    synthetic : instead of ``source``, an N×N fBm DEM with ``seed``.
    strategies, taus, n_views, size, render, occlusion, morph, anti_aliasing : see
        :func:`run` and :func:`flight`.
    cameras : a cameras JSON (:func:`load_path`) instead of the built-in flight.
    peer_errors : vertical errors for :func:`peers`; True for
        :func:`default_peer_errors`; False for no peers.
    work_dir : where a DEM's store is written (default: a temporary directory,
        removed afterwards).
    progress : called with (frames done since the last call, total frames).

    Examples
    --------
    >>> res = benchmark(synthetic=65, strategies=("rtin",), taus=(2.0,), n_views=2)
    >>> res.label, len(res.rows), res.preprocess_s > 0
    ('synthetic fbm 65² (seed 1)', 2, True)
    """
    from geoterrain.ingest.synth import generate, write_geotiff
    from geoterrain.preprocessing.pipeline import preprocess
    from geoterrain.terrain import open as open_terrain

    if (source is None) == (synthetic is None):
        raise UsageError("give a source (a store or a DEM) or synthetic=N, not both or neither",
                         cli="give SOURCE (a store or a DEM) or --synthetic N, not both or "
                             "neither")
    if synthetic is not None and synthetic < 3:
        raise UsageError(f"synthetic needs N ≥ 3, got {synthetic}",
                         cli=f"--synthetic needs N ≥ 3, got {synthetic}")
    for s in strategies:
        strategy_info(s)
    t_wall = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="geoterrain-bench-") as tmp:
        work = Path(work_dir) if work_dir else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        if synthetic is not None:
            source = write_geotiff(Path(tmp) / f"fbm_{synthetic}.tif",
                                   generate("fbm", synthetic, seed=seed))
            label = f"synthetic fbm {synthetic}² (seed {seed})"
        else:
            label = Path(source).name
            if not Path(source).is_file():
                raise UsageError(f"{source}: no such file")
        store, preprocess_s = Path(source), None
        if not is_store(store):
            store = work / (Path(source).stem + ".geoterrain")
            t0 = time.perf_counter()
            preprocess(source, store, overwrite=True)
            preprocess_s = round(time.perf_counter() - t0, 3)
        store_bytes = os.path.getsize(store)
        with open_terrain(store) as t:
            if cameras is not None:
                views = load_path(cameras, size, frame=t.frame)
            else:
                X, Y, Z = t.scene_xyz()
                views = flight(*extent(X, Y, Z), n_views=n_views, size=size)
                del X, Y, Z
            total = len(views) * len(strategies) * len(taus)
            res = run(t, views, strategies=strategies, taus=taus, render=render, source=label,
                      preprocess_s=preprocess_s, store_bytes=store_bytes,
                      progress=(lambda n: progress(n, total)) if progress else None,
                      occlusion=occlusion, morph=morph, anti_aliasing=anti_aliasing)
            if peer_errors is not False:
                errs = default_peer_errors(t) if peer_errors is True else tuple(peer_errors)
                if any(not (math.isfinite(e) and e >= 0) for e in errs):
                    raise UsageError("peer errors must be finite and ≥ 0",
                                     cli="--peer-errors must be finite and ≥ 0")
                res.peers, notes = peers(t, errs)
                res.notes += notes
    res.label, res.preprocess_s, res.store_bytes = label, preprocess_s, store_bytes
    res.wall_s = time.perf_counter() - t_wall
    return res
