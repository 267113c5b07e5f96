"""Seed 004's tessellation against rtin and geomipmap: triangles and measured error.

Over ``bench_lod.flight`` (``--views`` views, 1280×720) at τ = ``--tau``, each strategy's
mesh is measured by ``measure.screen_space_error`` over every valid sample in view.

Usage: ``python benchmarks/bench_tessellation.py STORE [--views 8] [--tau 1]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import geoterrain
from geoterrain.measure import screen_space_error

sys.path.insert(0, str(Path(__file__).parent))
from bench_lod import flight  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--tau", type=float, default=1.0)
    a = ap.parse_args()
    t = geoterrain.open(a.store)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    views = flight((X, Y, Z, valid), a.views)
    print("| strategy | triangles (median) | measured ρ max / median (px) | selection median |")
    print("|---|---|---|---|")
    for strategy in ("tessellation", "rtin", "geomipmap"):
        rho, tris, ms = [], [], []
        for v, _ in views:
            s = t.select(v, a.tau, strategy, reuse=False)
            e = screen_space_error(np.asarray(s.ij).astype(np.int64), s.surface_faces(),
                                   np.asarray(s.mesh.points)[:, 2], X, Y, Zt, valid, v.eye,
                                   v.planes, v.lam)
            rho.append(e.max)
            tris.append(s.stats["triangles"])
            ms.append(s.stats["select_ms"])
        print(f"| {strategy} | {np.median(tris):.0f} | {max(rho):.2f} / {np.median(rho):.2f} "
              f"| {np.median(ms):.0f} ms |")


if __name__ == "__main__":
    main()
