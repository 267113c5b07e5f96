"""Seed 000's strategies on held-out DEMs: measured ρ against τ over random views, and cracks.

For every strategy this issue added (gtr, gtr_bounded, lauritsen_nielsen, roam,
roam_split, clipmap, clipmap_bounded, clipmap_gpu, rottger) and every DEM given, 20 random
views (seeded) at τ = 1, 4, 8: the measured screen-space error ρ
(:func:`geoterrain.testing.measure.screen_space_error`, full-resolution heights, horizon
culling off so that every sample in the frustum counts), and cracks:

- a conforming strategy: grid points where the drawn surface takes two heights (a crack
  or a T-junction), and edges used by more than two triangles;
- a strategy with skirts: skirt vertices that hang above the lowest surface drawn at
  their sample (a gap the skirt does not close);
- both: valid samples in view that no triangle covers, away from no-data and from the
  frustum's border (the stress suite's rule).

Run from the project root::

    PYTHONPATH=. python benchmarks/bench_seed000_strategies.py ../shared/dems/srtm1_japan.tif \\
        ../shared/dems/srtm3_pysheds.tif [--views 20] [--strategies gtr,roam]

It prints one line per DEM × strategy × τ: the largest ρ over the views, ρ / τ, the
crack counts and the median triangles; "bounded" says what the registry promises.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geoterrain  # noqa: E402
from geoterrain.core.view import View  # noqa: E402
from geoterrain.lod import strategy_info  # noqa: E402
from geoterrain.testing.measure import mesh_height_range_on_grid, screen_space_error  # noqa: E402

NEW = ("gtr", "gtr_bounded", "lauritsen_nielsen", "roam", "roam_split", "clipmap",
       "clipmap_bounded", "clipmap_gpu", "rottger")


def random_views(X, Y, Z, n, seed=0, size=(1024, 768)):
    ok = np.isfinite(Z)
    lo = np.array([X[ok].min(), Y[ok].min(), Z[ok].min()])
    hi = np.array([X[ok].max(), Y[ok].max(), Z[ok].max()])
    c, r = 0.5 * (lo + hi), float(np.linalg.norm(hi[:2] - lo[:2]))
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(0.03, 1.2)
        d = r * rng.uniform(0.05, 1.0)
        base = c + rng.normal(0, 0.25 * r, 3) * [1, 1, 0]
        eye = base + d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                   np.sin(el)])
        eye[2] = max(eye[2], hi[2] + 0.01 * r * rng.uniform(0.1, 3))
        out.append(View(tuple(eye), tuple(base), size=size, fov_y_deg=45))
    return out


def cracks(t, sel, Z, view, tau, X, Y, valid):
    """(two-height grid points, edges used > 2 times, open skirts, uncovered samples)."""
    f = sel.surface_faces()
    if not len(f):
        return 0, 0, 0, 0
    z = np.asarray(sel.mesh.points)[:, 2]
    lo, hi = mesh_height_range_on_grid(sel.ij, f, z, Z.shape)
    spread = np.nan_to_num(hi - lo)
    two = int((spread > 1e-9 * max(1.0, float(np.nanmax(np.abs(z))))).sum())
    N = t.grid.extent[1]  # the grid's columns (a square's N)
    ij = np.asarray(sel.ij, np.int64)
    key = (ij[:, 0] * N + ij[:, 1])[f]
    e = np.sort(np.concatenate([key[:, [0, 1]], key[:, [1, 2]], key[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e[:, 0] * N * N + e[:, 1], return_counts=True)
    over = int((counts > 2).sum())
    open_skirts = 0
    skirt = np.asarray(sel.mesh.cell_data["skirt"]) == 1 if "skirt" in sel.mesh.cell_data \
        else np.zeros(len(sel.faces), bool)
    hanging = np.setdiff1d(sel.faces[skirt].ravel(), f.ravel())
    if len(hanging):
        under = lo[ij[hanging, 0], ij[hanging, 1]]
        ok = np.isfinite(under)
        open_skirts = int((z[hanging][ok] > under[ok] + 1e-9).sum())
    # valid samples in view, not next to no-data nor within τ of the frustum's border
    P = np.stack([X, Y, np.where(valid, Z, 0.0)], -1)
    dpl = P @ view.planes[:, :3].T + view.planes[:, 3]
    hole = (dpl >= 0).all(-1) & valid & ~np.isfinite(lo)
    pad = np.pad(~valid, 1, constant_values=True)
    H, W = Z.shape
    for a in range(3):
        for b in range(3):
            hole &= ~pad[a:a + H, b:b + W]
    if hole.any():
        r, u, fw = view.basis()
        q = P[hole] - view.eye
        depth = q @ fw
        w, h = view.size
        x = w / 2 + view.lam * (q @ r) / depth
        y = h / 2 - view.lam * (q @ u) / depth
        border = np.minimum(np.minimum(x, w - x), np.minimum(y, h - y))
        dist = np.linalg.norm(q, axis=1)
        zb = tau * dist / view.lam
        near_border = (border <= tau * (dist / depth) ** 2 + 1e-6) | (dpl[hole][:, 4] <= zb)
        hole_n = int((~near_border).sum())
    else:
        hole_n = 0
    return two if strategy_info(sel.stats["strategy"]).conforming else 0, over, \
        open_skirts, hole_n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dems", nargs="+")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--taus", default="1,4,8")
    ap.add_argument("--strategies", default=",".join(NEW))
    ap.add_argument("--tile-size", type=int, default=64)
    a = ap.parse_args()
    taus = [float(v) for v in a.taus.split(",")]
    print("dem  strategy  bounded  tau  rho_max  rho/tau  two-height  edges>2  open-skirts "
          "uncovered  triangles(median)")
    with tempfile.TemporaryDirectory() as tmp:
        for dem in a.dems:
            store = Path(tmp) / (Path(dem).stem + ".geoterrain")
            geoterrain.preprocess(dem, store, tile_size=a.tile_size, overwrite=True)
            t = geoterrain.open(store)
            X, Y, Z = t.scene_xyz()
            valid = np.isfinite(Z)
            Zt = np.where(valid, Z, 0.0)
            views = random_views(X, Y, Z, a.views)
            for s in a.strategies.split(","):
                for tau in taus:
                    rho, tot, tris = 0.0, np.zeros(4, int), []
                    for v in views:
                        sel = t.select(v, tau, s, reuse=False, occlusion=False)
                        f = sel.surface_faces()
                        tris.append(len(f))
                        if not len(f):
                            continue
                        e = screen_space_error(sel.ij, f, np.asarray(sel.mesh.points)[:, 2],
                                               X, Y, Zt, valid, v.eye, v.planes, v.lam)
                        rho = max(rho, e.max)
                        tot += np.array(cracks(t, sel, Z, v, tau, X, Y, valid))
                    print(f"{Path(dem).stem}  {s}  {strategy_info(s).bounded}  {tau:g}  "
                          f"{rho:.3f}  {rho / tau:.3f}  {tot[0]}  {tot[1]}  {tot[2]}  {tot[3]}  "
                          f"{int(np.median(tris))}", flush=True)
            t.close()


if __name__ == "__main__":
    main()
