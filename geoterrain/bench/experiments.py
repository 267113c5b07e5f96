"""Seed 000's experiments (the thesis's Tables 6-3 … 6-20) re-run on this renderer.

The thesis measures mean frames per second of brute force (BF), GeoMipMapping (GMM) and
GPU Terrain Rendering (GTR) over a one-minute scripted flight on four machines, varying
one parameter of its Table 6-2 defaults at a time. Here:

- **Algorithms**: BF is ``bruteforce``, GMM ``geomipmap_distance`` (the thesis's switch
  distances D_n = δ·C; its cracks are closed by stitching, the thesis's IndexUpdate), GTR
  ``gtr`` (Vistnes' blocks as the thesis built them, optimised skirts, geomorphing).
- **Defaults** (Table 6-2): τ = 8 px, 1024 × 768, 33² tiles (a store preprocessed with
  ``--tile-size 32``), frustum and horizon culling, geomorphing. Choices: the vertical
  field of view is 45° (the thesis does not give it); the near and far planes are the
  renderer's, around the terrain (the thesis's 1 and 10 000 are in its own world units);
  the horizon culling is the project's (:mod:`geoterrain.lod.occlusion`), with no pixel
  threshold of its own.
- **Terrains**: the thesis's four are not distributed; stand-ins of the same sizes,
  generated deterministically (:data:`TERRAINS`): Valley 257² (fBm), Desert 513²
  (diamond-square, smooth), Terrace 1025² (fBm cut into terraces, as L3DT's terrace
  filter does), Highland 2049² (ridged multifractal); 10 m spacing.
- **Flight** (:func:`minute_flight`): one loop around the terrain in 60 s, low over the
  highest ground, looking ahead and down; the thesis samples 60 frames from 5 s after
  the start, here ``frames`` evenly over 5 … 60 s (after one warm-up frame).
- **Frame rate**: 1000 / (selection + texture update + draw and read-back) per frame,
  its median over the flight; one anti-aliasing mode for every row of a run (named in
  the output). The draw is VTK's on Mesa's llvmpipe, a CPU renderer on the same cores as
  the selection: its cost follows the triangles drawn, which the thesis's GPUs' did not.

Experiments (``geoterrain bench --experiment NAME``): :data:`EXPERIMENTS`; the tables that
do not apply to a CPU renderer are in :data:`NOT_APPLICABLE`, with the reason.

Examples
--------
>>> sorted(EXPERIMENTS)  # doctest: +NORMALIZE_WHITESPACE
['algorithm', 'cull-mode', 'lod-error', 'resolution', 'spatial-coherence',
 'temporal-coherence', 'tile-size']
>>> [c.setting for c in configs("lod-error", ("Terrace",))][:4]
['4', '8', '16', '32']
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.bench.thesis000 import MACHINES, TABLES
from geoterrain.core.view import View
from geoterrain.exceptions import UsageError

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

FOV = 45.0  # the thesis does not give its field of view
SIZE = (1024, 768)  # Table 6-2
TAU = 8.0  # Table 6-2: LodMaxError
TILE = 33  # Table 6-2: TerrainTileSize
SPACING = 10.0  # metres between samples of the stand-in terrains
ALGORITHMS = {"BF": "bruteforce", "GMM": "geomipmap_distance", "GTR": "gtr"}


@dataclass(frozen=True)
class TerrainSpec:
    """A stand-in for one of the thesis's terrains: size, generator, seed, relief."""

    size: int
    kind: str
    seed: int
    relief: float
    terraces: int = 0
    params: tuple = ()


TERRAINS = {
    "Valley": TerrainSpec(257, "fbm", 11, 180.0),
    "Desert": TerrainSpec(513, "diamond-square", 12, 120.0, params=(("roughness", 1.4),)),
    "Terrace": TerrainSpec(1025, "fbm", 13, 600.0, terraces=12),
    "Highland": TerrainSpec(2049, "ridged", 14, 1500.0),
}


@dataclass(frozen=True)
class Config:
    """One row of one of the thesis's tables: what is run and on what."""

    table: str
    group: str  # the table's group column: a terrain, or an algorithm on Terrace
    setting: str  # the table's varied parameter, as the thesis writes it
    algorithm: str  # BF, GMM or GTR
    terrain: str
    strategy: str
    tile: int = TILE
    tau: float = TAU
    size: tuple[int, int] = SIZE
    cull: str = "horizon"  # none, frustum, horizon (Table 6-2's CullMode)
    morph: bool = True
    skirts: str = "optimised"
    reference: str = ""  # the setting the table's ratios are taken against

    def thesis(self) -> tuple | None:
        """The thesis's four figures for this row (N1, N2, D1, X1), or None."""
        for g, s, v in TABLES[self.table]["rows"]:
            if g == self.group and s == self.setting:
                return v
        return None


@dataclass(frozen=True)
class Experiment:
    """A ``--experiment``: the thesis's tables it re-runs and its rows."""

    name: str
    tables: tuple[str, ...]
    summary: str
    rows: Callable[[Sequence[str]], list[Config]] = field(repr=False, compare=False)


def _by_terrain(table, algorithm, settings, terrains, ref, **kw) -> list[Config]:
    out = []
    for t in terrains:
        for s, extra in settings:
            out.append(Config(table, t, s, algorithm, t, ALGORITHMS[algorithm], reference=ref,
                              **{**kw, **extra}))
    return out


def _tile_size(terrains):
    s = [(str(n), {"tile": n}) for n in (17, 33, 65, 129)]
    return [c for tab, a in (("6-3", "BF"), ("6-4", "GMM"), ("6-5", "GTR"))
            for c in _by_terrain(tab, a, s, terrains, "33")]


def _cull_mode(terrains):
    s = [("none", {"cull": "none"}), ("Frustum", {"cull": "frustum"}),
         ("FrustumHorizon", {"cull": "horizon"})]
    return [c for tab, a in (("6-6", "BF"), ("6-7", "GMM"), ("6-8", "GTR"))
            for c in _by_terrain(tab, a, s, terrains, "FrustumHorizon")]


def _on_terrace(table, algorithms, settings, ref, terrains):
    t = "Terrace" if "Terrace" in terrains or not terrains else terrains[0]
    return [Config(table, a, s, a, t, ALGORITHMS[a], reference=ref, **extra)
            for a in algorithms for s, extra in settings]


def _lod_error(terrains):
    return _on_terrace("6-13", ("GMM", "GTR"),
                       [(str(v), {"tau": float(v)}) for v in (4, 8, 16, 32)], "8", terrains)


def _spatial(terrains):
    # GMM: only IndexUpdate (our stitching) is built; skirts and none are not
    gmm = _by_terrain("6-14", "GMM", [("IndexUpdate", {})], terrains, "IndexUpdate")
    gtr = _by_terrain("6-15", "GTR", [("none", {"skirts": "none"}), ("Skirts", {"skirts": "all"}),
                                      ("SkirtsOptimized", {"skirts": "optimised"})],
                      terrains, "SkirtsOptimized")
    return gmm + gtr


def _temporal(terrains):
    rows = _on_terrace("6-16", ("GMM", "GTR"), [("none", {"morph": False}),
                                                 ("Geomorphing", {"morph": True})],
                       "Geomorphing", terrains)
    # the thesis's GMM morphs with its distance rule; ours morphs only the bounded
    # geomipmap (trilinear geomipmapping within τ): that one is run for this table
    return [replace(c, strategy="geomipmap") if c.algorithm == "GMM" else c for c in rows]


def _resolution(terrains):
    s = [(f"{w}x{h}", {"size": (w, h)}) for w, h in ((640, 480), (800, 600), (1024, 768),
                                                     (1280, 768))]
    return _on_terrace("6-19", ("BF", "GMM", "GTR"), s, "1024x768", terrains)


def _algorithm(terrains):
    return [Config("6-20", t, a, a, t, ALGORITHMS[a], reference="BF")
            for t in terrains for a in ("BF", "GMM", "GTR")]


EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("tile-size", ("6-3", "6-4", "6-5"),
               "BF, GMM, GTR against the tile size (17, 33, 65, 129 vertices a side)",
               _tile_size),
    Experiment("cull-mode", ("6-6", "6-7", "6-8"),
               "BF, GMM, GTR with no culling, frustum culling, frustum and horizon culling",
               _cull_mode),
    Experiment("lod-error", ("6-13",), "GMM and GTR on Terrace against τ = 4, 8, 16, 32 px",
               _lod_error),
    Experiment("spatial-coherence", ("6-14", "6-15"),
               "crack treatments: GTR with no skirts, skirts, optimised skirts; GMM's "
               "stitching (IndexUpdate)", _spatial),
    Experiment("temporal-coherence", ("6-16",),
               "GMM and GTR on Terrace with and without geomorphing", _temporal),
    Experiment("resolution", ("6-19",),
               "BF, GMM, GTR on Terrace at 640×480, 800×600, 1024×768, 1280×768", _resolution),
    Experiment("algorithm", ("6-20",), "BF, GMM, GTR on the four terrains", _algorithm),
)}

NOT_APPLICABLE = {
    "6-9 … 6-11 (HeightProcessing)":
        "multi-stream heights against vertex-texture fetch in the vertex shader: VTK draws "
        "our meshes with its own shaders, which take positions only; there is no second "
        "path to time",
    "6-12 (HorizonMaxError)":
        "the thesis's horizon planes are refined to a pixel threshold; the project's "
        "horizon culling is exact-conservative over azimuth bins and has no such threshold",
    "6-14 (GMM with skirts or none)":
        "geomipmap closes its cracks by stitching (the thesis's IndexUpdate) only",
    "6-17 (Primitive)":
        "indexed lists against strips: VTK's OpenGL back end turns strips into triangle "
        "lists before the draw, so both reach the rasteriser as the same triangles",
    "6-18 (PrimitiveBlockSize)":
        "vertex-cache row widths: llvmpipe draws on the CPU without a GPU's post-transform "
        "vertex cache of 8–24 entries",
}


def configs(name: str, terrains: Sequence[str] = tuple(TERRAINS)) -> list[Config]:
    """The rows of experiment ``name`` on ``terrains``.

    Examples
    --------
    >>> len(configs("algorithm")), configs("algorithm", ("Valley",))[0].strategy
    (12, 'bruteforce')
    """
    if name not in EXPERIMENTS:
        raise UsageError(f"unknown experiment {name!r}; use one of "
                         f"{', '.join(EXPERIMENTS)} (or 'list')")
    for t in terrains:
        if t not in TERRAINS:
            raise UsageError(f"unknown terrain {t!r}; use any of {', '.join(TERRAINS)}")
    return EXPERIMENTS[name].rows(tuple(terrains))


# ------------------------------------------------------------------ terrains, flight
def terrain_dem(name: str, folder: Path, scale: int = 1) -> Path:
    """The stand-in DEM of terrain ``name`` as a GeoTIFF in ``folder`` (made once);
    ``scale`` > 1 shrinks it ((size − 1)/scale + 1 samples a side: tests).

    Examples
    --------
    >>> import tempfile
    >>> p = terrain_dem("Valley", Path(tempfile.mkdtemp()), scale=8)
    >>> import rasterio; rasterio.open(p).shape
    (33, 33)
    """
    from geoterrain.ingest.synth import generate, write_geotiff

    spec = TERRAINS[name]
    n = (spec.size - 1) // scale + 1
    path = Path(folder) / f"{name.lower()}_{n}.tif"
    if path.exists():
        return path
    z = generate(spec.kind, n, seed=spec.seed, relief=spec.relief, **dict(spec.params))
    if spec.terraces:  # L3DT-like terraces: flat steps joined by steep risers
        step = spec.relief / spec.terraces
        k = np.floor(z / step)
        frac = z / step - k
        z = (k + np.clip((frac - 0.8) / 0.2, 0.0, 1.0)) * step
    Path(folder).mkdir(parents=True, exist_ok=True)
    return write_geotiff(path, z.astype(np.float32), spacing=SPACING)


def terrain_store(name: str, tile: int, folder: Path, scale: int = 1) -> Path:
    """The store of terrain ``name`` with tiles of ``tile`` vertices a side (made once)."""
    from geoterrain.preprocessing.pipeline import preprocess

    dem = terrain_dem(name, folder, scale)
    store = Path(folder) / f"{dem.stem}_t{tile}.geoterrain"
    if not store.exists():
        preprocess(dem, store, tile_size=tile - 1, overwrite=True)
    return store


def minute_flight(lo, hi, frames: int, size=SIZE, fov_y_deg: float = FOV,
                  warmup: bool = True) -> list[tuple[float, View]]:
    """The one-minute flight: a loop around the terrain's centre (radius 0.3 × its width),
    0.04 × its width above its highest point, looking ahead along the loop and 15° down;
    ``frames`` views evenly over 5 … 60 s (the thesis samples from 5 s), after a warm-up
    view at 0 s (``warmup``). Returns (seconds, view) pairs.

    Examples
    --------
    >>> v = minute_flight((0, 0, 0), (1000, 1000, 100), 3)
    >>> [round(t) for t, _ in v]
    [0, 5, 32, 60]
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c = 0.5 * (lo + hi)
    width = float(min(hi[0] - lo[0], hi[1] - lo[1]))
    R, z = 0.3 * width, float(hi[2]) + 0.04 * width
    times = ([0.0] if warmup else []) + list(np.linspace(5.0, 60.0, frames))
    out = []
    for s in times:
        a = 2 * math.pi * s / 60.0
        eye = np.array([c[0] + R * math.cos(a), c[1] + R * math.sin(a), z])
        ahead = np.array([-math.sin(a), math.cos(a), -math.tan(math.radians(15.0))])
        out.append((float(s), View(tuple(eye), tuple(eye + 100.0 * ahead), (0.0, 0.0, 1.0),
                                   fov_y_deg, tuple(size))))
    return out


class _NoCulling(View):
    """A view whose frustum culls nothing (Table 6-2's CullMode None): no planes."""

    @property
    def planes(self) -> np.ndarray:
        return np.zeros((0, 4))


# ------------------------------------------------------------------ running
def _select(terrain: TerrainLike, cfg: Config, view: View):
    """The selection of one frame for ``cfg``: the strategy's own ``select`` with the
    row's switches (a skirts choice, no culling), then the seam's elevation array."""
    from geoterrain.lod import Selection
    from geoterrain.lod.mesh import add_elevation
    from geoterrain.lod.registry import strategy_info

    fn = strategy_info(cfg.strategy).load()
    kw = {"occlusion": cfg.cull == "horizon", "morph": cfg.morph}
    if cfg.strategy == "gtr":
        kw["skirts"] = cfg.skirts
    if cfg.cull == "none":
        view = _NoCulling(view.look_from, view.look_at, view.up, view.fov_y_deg, view.size,
                          view.near, view.far)
    mesh, stats = fn(terrain, view, cfg.tau, **kw)
    add_elevation(mesh, terrain.frame.z_scale)
    return Selection(mesh, stats)


def run_config(terrain: TerrainLike, cfg: Config, frames: int, anti_aliasing: str,
               progress: Callable[[int], None] | None = None) -> dict:
    """Fly ``cfg``'s flight over ``terrain``, drawing every frame; the row's figures."""
    from geoterrain.bench.harness import _renderer, extent

    X, Y, Z = terrain.scene_xyz()
    views = minute_flight(*extent(X, Y, Z), frames, cfg.size)
    del X, Y, Z
    scene = _renderer(cfg.size, terrain, anti_aliasing, cfg.cull == "horizon", cfg.morph)
    from geoterrain.rendering.scene import io_counters

    fps, sel_ms, draw_ms, tris = [], [], [], []
    aa = anti_aliasing
    try:
        for k, (_, view) in enumerate(views):
            view = view.clipped_to(*terrain.scene_box())
            t0, p0, c0 = time.perf_counter(), time.process_time(), io_counters(terrain)
            sel = _select(terrain, cfg, view)
            t1 = time.perf_counter()
            _, rs = scene.draw(sel, view, (t0, p0, c0))
            if k == 0:
                continue  # the warm-up frame
            fps.append(1000.0 / rs["frame_ms"])
            sel_ms.append((t1 - t0) * 1e3)
            draw_ms.append(rs["update_ms"] + rs["render_ms"])
            tris.append(len(sel.surface_faces()))
            aa = rs.get("anti_aliasing", aa)
            if progress:
                progress(1)
    finally:
        scene.plotter.close()
    return {"fps": float(np.median(fps)), "select_ms": float(np.median(sel_ms)),
            "draw_ms": float(np.median(draw_ms)), "triangles": int(np.median(tris)),
            "frames": len(fps), "anti_aliasing": aa}


@dataclass
class ExperimentResult:
    """The rows of an experiment run: each :class:`Config` with its figures, the
    thesis's, and the ratios to the table's reference setting (ours and the thesis's)."""

    name: str
    rows: list[dict]
    anti_aliasing: str
    wall_s: float
    notes: list[str]


def run_experiment(name: str, *, terrains: Sequence[str] = tuple(TERRAINS), frames: int = 6,
                   anti_aliasing: str = "msaa", work_dir: str | Path | None = None,
                   scale: int = 1, progress: Callable[[int, int], None] | None = None
                   ) -> ExperimentResult:
    """Run experiment ``name`` (:data:`EXPERIMENTS`) and compare with the thesis.

    Parameters
    ----------
    terrains : which stand-ins to run on (the tables on Terrace use it, or the first).
    frames : frames timed over the minute (after one warm-up frame).
    anti_aliasing : one mode for every row (``auto`` chooses per frame, so it is refused).
    work_dir : where the stand-in DEMs and their stores are kept (default: a temporary
        folder, removed afterwards).
    scale : shrink the terrains by this factor (tests).
    progress : called with (frames done since the last call, total frames).

    Examples
    --------
    >>> res = run_experiment("algorithm", terrains=("Valley",), frames=1, scale=8)
    ... # doctest: +SKIP
    """
    import tempfile

    from geoterrain.terrain import open as open_terrain

    if anti_aliasing == "auto":
        raise UsageError("an experiment draws every strategy with one anti-aliasing mode; "
                         "auto chooses per frame: use msaa, edges, fxaa or none",
                         cli="--experiment needs one --anti-aliasing mode for every "
                             "strategy: msaa, edges, fxaa or none")
    if frames < 1:
        raise UsageError(f"frames must be ≥ 1, got {frames}", cli=f"--frames must be ≥ 1, "
                                                                    f"got {frames}")
    rows = configs(name, terrains)
    t_wall = time.perf_counter()
    total = len(rows) * frames
    with tempfile.TemporaryDirectory(prefix="geoterrain-exp-") as tmp:
        folder = Path(work_dir) if work_dir else Path(tmp)
        out = []
        for cfg in rows:
            store = terrain_store(cfg.terrain, cfg.tile, folder, scale)
            with open_terrain(store) as t:
                got = run_config(t, cfg, frames, anti_aliasing,
                                 (lambda k: progress(k, total)) if progress else None)
            out.append({"table": cfg.table, "group": cfg.group, "setting": cfg.setting,
                        "algorithm": cfg.algorithm, "strategy": cfg.strategy,
                        "terrain": cfg.terrain, **got, "thesis": cfg.thesis(),
                        "reference": cfg.reference})
    _ratios(out)
    notes = [f"{k}: not run ({v})" for k, v in NOT_APPLICABLE.items()
             if any(t in k for t in EXPERIMENTS[name].tables)]
    return ExperimentResult(name, out, anti_aliasing, time.perf_counter() - t_wall, notes)


def _ratios(rows: list[dict]) -> None:
    """Each row's frame rate over its table's reference row (same table, group and
    algorithm), ours and the thesis's per machine."""
    ref = {}
    for r in rows:
        if r["setting"] == r["reference"] or (r["table"] == "6-20" and r["algorithm"] == "BF"):
            ref[(r["table"], r["group"] if r["table"] != "6-20" else r["terrain"],
                 r["algorithm"] if r["table"] != "6-20" else "")] = r
    for r in rows:
        key = (r["table"], r["group"] if r["table"] != "6-20" else r["terrain"],
               r["algorithm"] if r["table"] != "6-20" else "")
        b = ref.get(key)
        r["ratio"] = r["fps"] / b["fps"] if b else float("nan")
        th, tb = r["thesis"], (b or {}).get("thesis")
        r["thesis_ratio"] = tuple(
            (x / y if x is not None and y else None) for x, y in zip(th, tb, strict=True)
        ) if th and tb else None


def _half_up(x: float) -> str:
    """``x`` to two places, halves rounded up (``f"{1.625:.2f}"`` gives 1.62)."""
    return f"{math.floor(x * 100 + 0.5) / 100:.2f}"


def format_result(res: ExperimentResult) -> str:
    """A plain table of an experiment's rows beside the thesis's.

    Examples
    --------
    >>> r = ExperimentResult("algorithm", [dict(table="6-20", group="Valley", setting="BF",
    ...     algorithm="BF", strategy="bruteforce", terrain="Valley", fps=10.0, select_ms=1.0,
    ...     draw_ms=99.0, triangles=5, frames=1, anti_aliasing="msaa",
    ...     thesis=(200, 294, 1310, 626), reference="BF", ratio=1.0,
    ...     thesis_ratio=(1.0, 1.0, 1.0, 1.0))], "msaa", 1.0, [])
    >>> print(format_result(r).splitlines()[2])  # doctest: +NORMALIZE_WHITESPACE
    6-20  Valley  BF  bruteforce  10  1.00  5  200 294 1310 626  1.00–1.00
    """
    head = ("table", "group", "setting", "strategy", "FPS", "× ref", "triangles",
            "thesis " + " ".join(MACHINES), "thesis × ref")
    lines = [f"# {res.name}: {len(res.rows)} rows, drawn with {res.anti_aliasing} "
             f"anti-aliasing, {res.wall_s:.0f} s wall", "  ".join(head)]
    for r in res.rows:
        th = " ".join("-" if v is None else str(v) for v in r["thesis"]) if r["thesis"] \
            else "-"
        tr = [v for v in (r["thesis_ratio"] or ()) if v is not None]
        # half up, as the docs divide (Highland's GMM on N2: 195 / 120 = 1.625 → 1.63)
        trs = f"{_half_up(min(tr))}–{_half_up(max(tr))}" if tr else "-"
        lines.append("  ".join([r["table"], r["group"], r["setting"], r["strategy"],
                                f"{r['fps']:.3g}", f"{r['ratio']:.2f}", str(r["triangles"]),
                                th, trs]))
    return "\n".join(lines)


CSV_COLUMNS = ("table", "group", "setting", "algorithm", "strategy", "terrain", "frames",
               "fps", "ratio", "select_ms", "draw_ms", "triangles", "anti_aliasing",
               *(f"thesis_{m}" for m in MACHINES), *(f"thesis_ratio_{m}" for m in MACHINES))


def write_result_csv(res: ExperimentResult, path: str | Path) -> Path:
    """The rows as a CSV file (written whole or not at all).

    Examples
    --------
    >>> import tempfile
    >>> r = ExperimentResult("algorithm", [], "msaa", 0.0, [])
    >>> write_result_csv(r, Path(tempfile.mkdtemp()) / "e.csv").read_text().split(",")[0]
    'table'
    """
    import csv
    import io

    from geoterrain.core.atomicfiles import write_atomic

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(CSV_COLUMNS), extrasaction="ignore")
    w.writeheader()
    for r in res.rows:
        flat = dict(r)
        for k, m in enumerate(MACHINES):
            flat[f"thesis_{m}"] = (r["thesis"] or (None,) * 4)[k]
            tr = r.get("thesis_ratio") or (None,) * 4
            flat[f"thesis_ratio_{m}"] = "" if tr[k] is None else round(tr[k], 4)
        w.writerow(flat)
    return write_atomic(path, buf.getvalue())


def describe() -> str:
    """The experiments and the tables left out, for ``--experiment list``.

    Examples
    --------
    >>> describe().splitlines()[0].startswith("tile-size")
    True
    """
    out = [f"{e.name} (Tables {', '.join(e.tables)}): {e.summary}" for e in EXPERIMENTS.values()]
    out += [f"not run: Table {k}: {v}" for k, v in NOT_APPLICABLE.items()]
    return "\n".join(out)
