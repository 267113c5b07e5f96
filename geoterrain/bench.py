"""Benchmark harness: runtime against measured error across LOD strategies.

Every strategy (``rtin``, ``chunked``, ``bruteforce``) is run at every pixel
tolerance τ over one camera path. Each frame records the selection time, the
optional render time, the mesh size, the tiles decoded, the peak memory the
selection allocated and the *measured* screen-space error of the mesh against
the full-resolution heights (:func:`geoterrain.measure.screen_space_error`).

The result is a list of tidy rows (one per frame × strategy × τ) that
:func:`write_csv`, :func:`summarise` and :func:`plot` turn into a CSV file, a
table and a figure.

Examples
--------
>>> import geoterrain  # doctest: +SKIP
>>> from geoterrain.bench import run, summarise, format_table
>>> res = run(geoterrain.open("dem.geoterrain"), n_views=8)  # doctest: +SKIP
>>> print(format_table(summarise(res.rows)))  # doctest: +SKIP
"""

from __future__ import annotations

import csv
import hashlib
import math
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from geoterrain.exceptions import UsageError
from geoterrain.measure import screen_space_error, vertical_error
from geoterrain.view import View, load_views

STRATEGIES = ("rtin", "chunked", "bruteforce")
BRUTE_MEASURE_LIMIT = 4_000_000  # bruteforce meshes larger than this are not rasterised
TAUS = (0.5, 1.0, 2.0, 4.0, 8.0)
VIEW_KINDS = ("overview", "oblique", "grazing", "away")
SIZE = (1280, 720)
FOV = 30.0
COLUMNS = ("source", "frame", "view", "strategy", "tau", "select_ms", "render_ms", "triangles",
           "skirt_triangles", "vertices", "tiles_decoded", "peak_mem_mb", "err_max", "err_p99",
           "err_mean", "samples_in_view", "uncovered_in_view", "preprocess_s", "store_bytes")

Progress = Callable[[int], None]


@dataclass
class BenchResult:
    """Rows of one benchmark run and what it was run on."""

    rows: list[dict] = field(default_factory=list)
    peers: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    views: list[tuple[str, View]] = field(default_factory=list)
    wall_s: float = 0.0


# ----------------------------------------------------------------- cameras
def _extent(X: np.ndarray, Y: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
        raise UsageError(f"--views must be ≥ 1, got {n_views}")
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


def load_path(path: str | Path, size: tuple[int, int] = SIZE,
              fov_y_deg: float = FOV, frame=None) -> list[tuple[str, View]]:
    """Views from a cameras JSON file (:func:`geoterrain.view.load_views`), labelled "path".

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


def _renderer(size: tuple[int, int], terrain):
    """A render scene, or None when ``geoterrain.render`` is not available."""
    try:
        import geoterrain.rendering as r
    except ImportError:
        return None
    make = getattr(r, "_plotter", None)
    if make is None:
        import pyvista as pv

        def make(s):
            return pv.Plotter(off_screen=True, window_size=s)
    return r.TerrainScene(make(size), terrain)


def _selection_peak(terrain, view: View, tau: float, strategy: str) -> int:
    """Peak bytes allocated while selecting again (tracemalloc slows Python code, so the
    timed selection runs without it; this second run finds the tiles already decoded)."""
    terrain.selector._last = None
    tracemalloc.start()
    try:
        terrain.select(view, pixel_error=tau, strategy=strategy)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def run(terrain, views: Sequence[tuple[str, View]] | None = None, *,
        strategies: Sequence[str] = STRATEGIES, taus: Sequence[float] = TAUS,
        n_views: int = 8, render: bool = False, source: str = "",
        preprocess_s: float | None = None, store_bytes: int | None = None,
        progress: Progress | None = None) -> BenchResult:
    """Run every strategy at every τ over ``views`` and measure each frame.

    Parameters
    ----------
    terrain : geoterrain.Terrain
    views : (kind, View) pairs; default :func:`flight` over the terrain's extent.
    strategies, taus : what to run (every combination).
    n_views : length of the default flight.
    render : also render each frame offscreen (needs ``geoterrain.render``).
    source, preprocess_s, store_bytes : recorded in every row.
    progress : called with the number of frames done since the last call.

    Returns
    -------
    BenchResult
        ``rows`` with the columns of :data:`COLUMNS`. ``select_ms`` and
        ``tiles_decoded`` come from the first (timed) selection of the frame, which
        decodes what earlier frames and strategies have not; ``peak_mem_mb`` is the peak
        allocated by a second, identical selection under ``tracemalloc`` (which slows
        Python code, so it never runs during the timed one); ``err_*`` are in pixels.

    Examples
    --------
    >>> res = run(t, n_views=4, taus=(1.0,))  # doctest: +SKIP
    >>> sorted({r["strategy"] for r in res.rows})  # doctest: +SKIP
    ['bruteforce', 'chunked', 'rtin']
    """
    from geoterrain.lod import STRATEGIES as known

    for s in strategies:
        if s not in known:
            raise UsageError(f"unknown strategy {s!r}; use one of {', '.join(known)}")
    for tau in taus:
        if not (math.isfinite(tau) and tau > 0):
            raise UsageError(f"every τ must be a finite number > 0, got {tau}")
    t_start = time.perf_counter()
    X, Y, Z = terrain.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    if views is None:
        views = flight(*_extent(X, Y, Z), n_views=n_views)
    res = BenchResult(views=list(views))
    scene = None
    if render:
        scene = _renderer(views[0][1].size, terrain)
        if scene is None:
            res.notes.append("--render: geoterrain.render is not available; render_ms left empty")
    cache: dict[str, tuple] = {}
    try:
        for fi, (kind, view) in enumerate(views):
            for strategy in strategies:
                for ti, tau in enumerate(taus):
                    if strategy == "bruteforce" and ti > 0:  # τ-independent: select once
                        res.rows.append({**res.rows[-1], "tau": float(tau)})
                        if progress:
                            progress(1)
                        continue
                    terrain.selector._last = None  # time a real selection, never a reuse
                    sel = terrain.select(view, pixel_error=float(tau), strategy=strategy)
                    peak = _selection_peak(terrain, view, float(tau), strategy)
                    render_ms = float("nan")
                    if scene is not None:
                        _, rs = scene.frame(view, float(tau), strategy)  # reuses the selection
                        render_ms = float(rs["update_ms"] + rs["render_ms"])
                    pts = np.asarray(sel.mesh.points, np.float64)
                    faces = sel.surface_faces()
                    ij = sel.ij
                    vz = pts[:, 2] if len(pts) else np.zeros(0)
                    key = _mesh_key(ij, faces, vz)
                    if strategy == "bruteforce" and len(faces) > BRUTE_MEASURE_LIMIT:
                        # every full-resolution triangle: error 0 by construction
                        # (tests/test_lod.py measures it); rasterising it costs GBs
                        cache = {key: (0.0, 0.0, 0.0, -1, -1)}
                    elif key not in cache:  # bruteforce draws the same mesh at every τ
                        e = screen_space_error(ij, faces, vz, X, Y, Zt, valid, view.eye,
                                               view.planes, view.lam)
                        cache = {key: (e.max, e.p99, e.mean, e.n_samples, e.n_uncovered)}
                    emax, ep99, emean, ns, nu = cache[key]
                    st = sel.stats
                    res.rows.append({
                        "source": source, "frame": fi, "view": kind, "strategy": strategy,
                        "tau": float(tau), "select_ms": float(st["select_ms"]),
                        "render_ms": render_ms, "triangles": int(st["triangles"]),
                        "skirt_triangles": int(st.get("skirt_triangles", 0)),
                        "vertices": int(st["vertices"]),
                        "tiles_decoded": int(st.get("tiles_decoded", 0)),
                        "peak_mem_mb": round(peak / 2**20, 3), "err_max": emax,
                        "err_p99": ep99, "err_mean": emean, "samples_in_view": ns,
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
def _padded_scene_heights(terrain) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Level-0 heights in scene units on the padded (2^k+1)² grid, padding filled by
    replicating the source edge; and the source-region valid mask, rows, cols."""
    h, v = terrain.level_heights(0)
    H, W = terrain.grid.rows, terrain.grid.cols
    z = terrain.frame.z(h)
    src = z[:H, :W]
    ok = v[:H, :W]
    zp = np.pad(src, ((0, z.shape[0] - H), (0, z.shape[1] - W)), mode="edge")
    return zp, ok, H, W


def peers(terrain, errors: Sequence[float]) -> tuple[list[dict], list[str]]:
    """Static meshes of rtin, pymartini and pydelatin at the same vertical error targets.

    Each mesh is measured with :func:`geoterrain.measure.vertical_error` on the
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
        sel = terrain.static_selection(E)
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


# ----------------------------------------------------------------- outputs
def write_csv(rows: Sequence[dict], path: str | Path, columns: Sequence[str] = COLUMNS) -> Path:
    """Write tidy rows to a CSV file (one row per frame × strategy × τ).

    Examples
    --------
    >>> import tempfile, os
    >>> p = write_csv([{"frame": 0, "tau": 1.0}], os.path.join(tempfile.mkdtemp(), "b.csv"),
    ...               columns=("frame", "tau"))
    >>> open(p).read().splitlines()
    ['frame,tau', '0,1.0']
    """
    path = Path(path)
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    return path


def _p95(a: np.ndarray) -> float:
    a = a[np.isfinite(a)]
    return float(np.percentile(a, 95)) if a.size else float("nan")


def _med(a: np.ndarray) -> float:
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else float("nan")


def summarise(rows: Sequence[dict]) -> list[dict]:
    """One summary row per (strategy, τ): medians, p95 and the worst measured error.

    Examples
    --------
    >>> rows = [{"strategy": "rtin", "tau": 1.0, "select_ms": 2.0, "render_ms": float("nan"),
    ...          "triangles": 10, "tiles_decoded": 1, "peak_mem_mb": 1.0, "err_max": 0.9,
    ...          "err_p99": 0.5}]
    >>> s = summarise(rows)[0]
    >>> s["strategy"], s["select_ms_med"], s["err_max_worst"]
    ('rtin', 2.0, 0.9)
    """
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["strategy"], float(r["tau"])), []).append(r)
    out = []
    for (s, tau), g in groups.items():
        col = {k: np.array([float(r[k]) for r in g]) for k in
               ("select_ms", "render_ms", "triangles", "tiles_decoded", "peak_mem_mb",
                "err_max", "err_p99")}
        out.append({
            "strategy": s, "tau": tau, "frames": len(g),
            "select_ms_med": _med(col["select_ms"]), "select_ms_p95": _p95(col["select_ms"]),
            "render_ms_med": _med(col["render_ms"]), "render_ms_p95": _p95(col["render_ms"]),
            "triangles_med": _med(col["triangles"]), "tiles_decoded_med":
                _med(col["tiles_decoded"]), "peak_mem_mb_med": _med(col["peak_mem_mb"]),
            "err_max_worst": float(np.max(col["err_max"])),
            "err_p99_med": _med(col["err_p99"]),
        })
    order = {s: k for k, s in enumerate(STRATEGIES)}
    out.sort(key=lambda r: (order.get(r["strategy"], 99), r["tau"]))
    return out


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    v = float(v)
    if not math.isfinite(v):
        return "–"
    if v == 0:
        return "0"
    if abs(v) >= 1e5:
        return f"{v:.3g}"
    if abs(v) >= 100:
        return f"{v:.0f}"
    return f"{v:.3g}"


def format_table(summary: Sequence[dict], markdown: bool = True) -> str:
    """The summary as a (markdown) table.

    Examples
    --------
    >>> print(format_table([{"strategy": "rtin", "tau": 1.0, "frames": 3}]))
    | strategy | tau | frames |
    |---|---|---|
    | rtin | 1 | 3 |
    """
    if not summary:
        return "(no rows)"
    cols = list(summary[0].keys())
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in summary:
        lines.append("| " + " | ".join(_fmt(r[c]) for c in cols) + " |")
    return "\n".join(lines)


def plot(rows: Sequence[dict], path: str | Path, title: str = "") -> Path:
    """Write a figure: runtime against measured error, triangles against τ, a timeline.

    Examples
    --------
    >>> plot(res.rows, "bench.png")  # doctest: +SKIP
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summ = summarise(rows)
    strategies = [s for s in STRATEGIES if any(r["strategy"] == s for r in summ)]
    colors = {"rtin": "tab:blue", "chunked": "tab:orange", "bruteforce": "tab:gray"}
    fig, axes = plt.subplots(2, 2, figsize=(13, 9), layout="constrained")
    ax = axes[0, 0]
    for s in strategies:
        g = [r for r in summ if r["strategy"] == s]
        x = np.array([r["err_max_worst"] for r in g])
        y = np.array([r["select_ms_med"] for r in g])
        ax.plot(np.maximum(x, 1e-3), y, "o-", color=colors.get(s), label=s)
        flat = len({round(v, 9) for v in x}) == 1  # τ-independent (bruteforce): one label
        for r, xi, yi in zip(g, x, y, strict=True):
            if flat and r is not g[-1]:
                continue
            ax.annotate("all τ" if flat else f"τ={r['tau']:g}", (max(xi, 1e-3), yi), fontsize=7,
                        textcoords="offset points", xytext=(4, 3), color=colors.get(s))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("worst measured screen-space error over the flight (px; 0 drawn at 1e-3)")
    ax.set_ylabel("median selection time (ms)")
    ax.set_title("Runtime against measured error (lower left is better)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()

    ax = axes[0, 1]
    for s in strategies:
        g = [r for r in summ if r["strategy"] == s]
        ax.plot([r["tau"] for r in g], [max(r["triangles_med"], 1) for r in g], "o-",
                color=colors.get(s), label=s)
    taus = sorted({r["tau"] for r in summ})
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(taus)
    ax.set_xticklabels([f"{t:g}" for t in taus])
    ax.set_xlabel("pixel tolerance τ")
    ax.set_ylabel("median triangles per frame")
    ax.set_title("Mesh size against τ")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()

    ax = axes[1, 0]
    tau_mid = min(taus, key=lambda t: abs(math.log(t)))  # τ closest to 1
    for s in strategies:
        g = sorted((r for r in rows if r["strategy"] == s and float(r["tau"]) == tau_mid),
                   key=lambda r: r["frame"])
        ax.plot([r["frame"] for r in g], [max(float(r["select_ms"]), 1e-2) for r in g], "o-",
                color=colors.get(s), label=f"{s} select")
        rms = [float(r["render_ms"]) for r in g]
        if any(math.isfinite(v) for v in rms):
            ax.plot([r["frame"] for r in g], rms, "x--", color=colors.get(s),
                    label=f"{s} render")
    frames = sorted({(r["frame"], r["view"]) for r in rows})
    ax.set_xticks([f for f, _ in frames])
    ax.set_xticklabels([f"{f}\n{v}" for f, v in frames], fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel("ms")
    ax.set_title(f"Per-frame timeline at τ = {tau_mid:g}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)

    ax = axes[1, 1]
    for s in strategies:
        g = sorted((r for r in rows if r["strategy"] == s and float(r["tau"]) == tau_mid),
                   key=lambda r: r["frame"])
        ax.plot([r["frame"] for r in g], [float(r["err_max"]) for r in g], "o-",
                color=colors.get(s), label=f"{s} max")
        ax.plot([r["frame"] for r in g], [float(r["err_p99"]) for r in g], ".:",
                color=colors.get(s), label=f"{s} p99")
    ax.axhline(tau_mid, color="red", lw=1, ls="--", label=f"τ = {tau_mid:g}")
    ax.set_xticks([f for f, _ in frames])
    ax.set_xticklabels([f"{f}\n{v}" for f, v in frames], fontsize=7)
    ax.set_ylabel("measured screen-space error (px)")
    ax.set_title(f"Per-frame measured error at τ = {tau_mid:g}")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
