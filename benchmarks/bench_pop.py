"""Popping along a smooth flight: cdlod and rtin with and without morphing, and chunked.

The flight is :func:`geoterrain.bench.harness.glide` (the eye moves 1 % of its height above the
terrain per frame). Per frame and strategy, ``pop`` is the largest jump of the drawn
surface since the previous frame, in pixels
(:func:`geoterrain.testing.measure.screen_space_change`, which rasterises both meshes and knows
nothing of the selection); ``rho`` the measured screen-space error; both use the
full-resolution heights. ``cdlod-nomorph`` is cdlod's selection with k snapped from 0 to
1 at each range (``morph=False``): the same ranges, no slide. ``rtin-morph`` is rtin with
seed 002's geomorphing (``morph=True``), ``chunked-morph`` chunked LOD morphing each chunk
to its parent, ``geomipmap-morph`` trilinear geomipmapping with continuous block levels.
Pop is counted at the samples in view in both frames, and horizon culling is off (a
hidden sample's surface may change unseen).

Run from the project root::

    PYTHONPATH=. python benchmarks/bench_pop.py STORE [--tau 1] [--frames 40]

It prints one line per strategy: max and p99 of pop over the frames, pop / τ, max ρ,
the median triangles and the median selection ms (same run, same machine).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import geoterrain  # noqa: E402
from geoterrain import lod  # noqa: E402
from geoterrain.bench.harness import extent, glide  # noqa: E402
from geoterrain.lod import cdlod  # noqa: E402
from geoterrain.testing.measure import screen_space_change, screen_space_error  # noqa: E402


def surface_of(mesh):
    f = mesh.faces.reshape(-1, 4)[:, 1:] if mesh.n_cells else np.zeros((0, 3), np.int64)
    if len(f) and "skirt" in mesh.cell_data:
        f = f[np.asarray(mesh.cell_data["skirt"]) == 0]
    ij = np.asarray(mesh.point_data["grid_ij"]) if mesh.n_points else np.zeros((0, 2))
    z = np.asarray(mesh.points)[:, 2] if mesh.n_points else np.zeros(0)
    return ij, f, z


def select(t, view, tau, name):
    t0 = time.perf_counter()
    if name == "cdlod-nomorph":
        mesh, _ = cdlod.select(t, view, tau, occlusion=False, morph=False)
    elif name.endswith("-morph"):  # rtin-morph, chunked-morph, geomipmap-morph
        mesh = lod.select(t, view, tau, name[:-len("-morph")], reuse=False, occlusion=False,
                          morph=True).mesh
    else:
        mesh = lod.select(t, view, tau, name, reuse=False, occlusion=False).mesh
    return mesh, (time.perf_counter() - t0) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--strategies",
                    default="cdlod,cdlod-nomorph,rtin,rtin-morph,chunked,chunked-morph,"
                            "geomipmap,geomipmap-morph")
    a = ap.parse_args()
    run(a)  # every sample in view counts, hidden ones too: the LOD's own popping, no culling


def run(a) -> None:
    size = tuple(int(v) for v in a.size.split("x"))
    t = geoterrain.open(a.store)
    X, Y, Z = t.scene_xyz()
    valid = np.isfinite(Z)
    Zt = np.where(valid, Z, 0.0)
    views = [v for _, v in glide(*extent(X, Y, Z), n_frames=a.frames, size=size)]
    print(f"{Path(a.store).name}: {a.frames} frames, τ = {a.tau}, {size[0]}×{size[1]}")
    print(f"{'strategy':15s} {'pop max':>8s} {'pop p99':>8s} {'pop/τ':>6s} {'ρ max':>6s} "
          f"{'tri med':>9s} {'ms med':>7s}")
    for name in a.strategies.split(","):
        pops, rhos, tris, ms, prev, prev_planes = [], [], [], [], None, None
        for v in views:
            mesh, dt = select(t, v, a.tau, name)
            s = surface_of(mesh)
            rhos.append(screen_space_error(*s, X, Y, Zt, valid, v.eye, v.planes, v.lam).max)
            if prev is not None:
                c = screen_space_change(prev, s, X, Y, Zt, valid, v.eye, v.planes, v.lam,
                                        prev_planes)
                pops.append(c.max)
            prev, prev_planes = s, v.planes
            tris.append(len(s[1]))
            ms.append(dt)
        pops = np.array(pops)
        print(f"{name:15s} {pops.max():8.3f} {np.percentile(pops, 99):8.3f} "
              f"{pops.max() / a.tau:6.3f} {max(rhos):6.3f} {int(np.median(tris)):9d} "
              f"{np.median(ms):7.1f}")


if __name__ == "__main__":
    main()
