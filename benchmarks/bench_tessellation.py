"""Seed 004's tessellation: triangles and measured error against rtin and geomipmap, and
seed 004's figure (Fig. 5.8's triangle counts along a fly-through, with the HAM factor
histogram).

Table: over ``bench_lod.flight`` (``--views`` views, 1280×720) at τ = ``--tau``, each
strategy's mesh is measured by ``measure.screen_space_error`` over every valid sample in
view (independent of the selection code).

Figure (``--figure PNG``): along :func:`geoterrain.bench.harness.glide` (``--frames`` frames, the
eye moving ``--step`` (5 %) of its height per frame), per frame:

- the HAM-driven tessellation (``tessellation``),
- seed 004's "straight view-dependent LOD" (the same distance law with T_max = 64 for
  every patch, ``tessellation.select(..., ham=False)``),
- "T = 64 everywhere" (every patch in view at full resolution, 2·S² triangles a patch),

their measured ρ (seed 004's H14 asks < 3 px), and the histogram of the drawn patches'
factors over all frames. It also prints seed 004's H13 ordering and H15 consistency (the
coefficient of variation of the triangle count along the flight).

Usage: ``python benchmarks/bench_tessellation.py STORE [--views 8] [--tau 1]
[--figure fig.png --frames 40]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).parent))

from bench_lod import flight  # noqa: E402

import geoterrain  # noqa: E402
from geoterrain.bench.harness import extent, glide  # noqa: E402
from geoterrain.lod import tessellation  # noqa: E402
from geoterrain.testing.measure import screen_space_error  # noqa: E402


def _rho(sel_ij, faces, z, scene, v) -> float:
    X, Y, Zt, valid = scene
    return screen_space_error(np.asarray(sel_ij).astype(np.int64), faces, z, X, Y, Zt,
                              valid, v.eye, v.planes, v.lam).max


def table(t, scene, n_views: int, tau: float) -> None:
    X, Y, Zt, valid = scene
    views = flight((X, Y, np.where(valid, Zt, np.nan), valid), n_views)
    print("| strategy | triangles (median) | measured ρ max / median (px) | selection median |")
    print("|---|---|---|---|")
    for strategy in ("tessellation", "rtin", "geomipmap"):
        rho, tris, ms = [], [], []
        for v, _ in views:
            s = t.select(v, tau, strategy, reuse=False)
            rho.append(_rho(s.ij, s.surface_faces(), np.asarray(s.mesh.points)[:, 2],
                            scene, v))
            tris.append(s.stats["triangles"])
            ms.append(s.stats["select_ms"])
        print(f"| {strategy} | {np.median(tris):.0f} | {max(rho):.2f} / {np.median(rho):.2f} "
              f"| {np.median(ms):.0f} ms |")


def _surface(mesh):
    if not mesh.n_cells:
        return np.zeros((0, 2), np.int64), np.zeros((0, 3), np.int64), np.zeros(0)
    f = mesh.faces.reshape(-1, 4)[:, 1:]
    return (np.asarray(mesh.point_data["grid_ij"]), f, np.asarray(mesh.points)[:, 2])


def figure(t, scene, n_frames: int, tau: float, path: str, step: float) -> None:
    X, Y, Zt, valid = scene
    Z = np.where(valid, Zt, np.nan)
    views = [v for _, v in glide(*extent(X, Y, Z), n_frames=n_frames, step=step)]
    S = 1 << t.grid.t
    rows = {"HAM tessellation": [], "straight VD LOD": [], "T = 64 everywhere": []}
    rho = {"HAM tessellation": [], "straight VD LOD": []}
    hist = np.zeros(7, np.int64)
    for v in views:
        for name, ham in (("HAM tessellation", True), ("straight VD LOD", False)):
            # every patch in view counts, as on seed 004's GPU: no culling
            mesh, st = tessellation.select(t, v, tau, occlusion=False, ham=ham)
            ij, f, z = _surface(mesh)
            rows[name].append(len(f))
            rho[name].append(_rho(ij, f, z, scene, v) if len(f) else 0.0)
            if ham:
                hist += np.asarray(st.get("factor_counts", [0] * 7), np.int64)
                rows["T = 64 everywhere"].append(2 * S * S * int(st.get("patches", 0)))
    tri = {k: np.asarray(r, np.float64) for k, r in rows.items()}
    print(f"{n_frames} frames along the glide, τ = {tau}, patches of {S}² intervals")
    print("| curve | triangles median (min–max) | CV | measured ρ max / median |")
    print("|---|---|---|---|")
    for k, r in tri.items():
        cv = r.std() / r.mean() if r.mean() else 0.0
        rr = rho.get(k)
        rs = f"{max(rr):.2f} / {np.median(rr):.2f}" if rr else "0 (full resolution)"
        print(f"| {k} | {np.median(r):.0f} ({r.min():.0f}–{r.max():.0f}) | {cv:.3f} | {rs} |")
    a, b, c = tri.values()
    print(f"H13 ordering ours ≤ straight ≤ T=64 on {int(((a <= b) & (b <= c)).sum())} "
          f"of {len(a)} frames")
    total = hist.sum()
    print("factor histogram (share of drawn patches): " + ", ".join(
        f"{1 << i}: {100 * n / max(total, 1):.1f} %" for i, n in enumerate(hist)))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(13, 3.8))
    frames = np.arange(len(a))
    for k, r in tri.items():
        ax1.plot(frames, r, label=k)
    ax1.set_yscale("log")
    ax1.set_xlabel("frame")
    ax1.set_ylabel("triangles")
    ax1.set_title("triangles per frame (seed 004 Fig. 5.8)")
    ax1.legend(fontsize=8)
    for k, r in rho.items():
        ax2.plot(frames, r, label=k)
    ax2.axhline(3.0, color="grey", ls="--", lw=0.8, label="H14: 3 px")
    ax2.axhline(tau, color="black", ls=":", lw=0.8, label=f"τ = {tau:g}")
    ax2.set_xlabel("frame")
    ax2.set_ylabel("measured ρ max (px)")
    ax2.set_title("measured screen-space error")
    ax2.legend(fontsize=8)
    ax3.bar([str(1 << i) for i in range(7)], 100 * hist / max(total, 1))
    ax3.set_xlabel("tessellation factor T")
    ax3.set_ylabel("% of drawn patches")
    ax3.set_title("HAM factor histogram")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=8, help="views of the table's flight")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--figure", help="write seed 004's figure to this PNG (skips the table)")
    ap.add_argument("--frames", type=int, default=40, help="frames of the figure's glide")
    ap.add_argument("--step", type=float, default=0.05,
                    help="the glide's step, × the eye's height, per frame")
    a = ap.parse_args()
    t = geoterrain.open(a.store)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    scene = (X, Y, np.where(valid, Z, 0.0), valid)
    if a.figure:
        figure(t, scene, a.frames, a.tau, a.figure, a.step)
    else:
        table(t, scene, a.views, a.tau)


if __name__ == "__main__":
    main()
