"""Horizon culling against the drawn surface: what rtin's picture shows, and the price.

For each view, rtin's selection at τ with horizon culling on: triangles, tiles culled
and the selection's CPU time (warm: the second of two selections). With ``--measure``,
also the picture displacement (:func:`geoterrain.testing.measure.picture_displacement`)
over every sample it counts, and over the samples the picture shows: a sample moved by
more than τ is shown when the ray-march oracle
(:func:`geoterrain.testing.reference.visible_samples`, a coarse march confirmed in
0.05-cell steps) sees its true point over the true surface or its drawn point over the
drawn surface (where the mesh leaves a sample uncovered, outside the frustum, its true
height stands in). Views: ``ground`` (:func:`geoterrain.bench.harness.ground_views`,
low views across the terrain) or bench_render.py's flights.

    PYTHONPATH=. python benchmarks/bench_occlusion_drawn.py STORE [--views 24]
        [--flight ground|low|approach] [--tau 1] [--size 1280x720] [--measure]
        [--json out.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import numpy as np

import geoterrain
from geoterrain.bench.harness import ground_views
from geoterrain.core.view import View
from geoterrain.testing.measure import (
    mesh_height_range_on_grid,
    picture_coordinates,
    picture_displacement,
)
from geoterrain.testing.reference import visible_samples

try:
    from bench_render import FLIGHTS
except ImportError:  # run as benchmarks/bench_occlusion_drawn.py from the repository root
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_render import FLIGHTS

FINE = 0.05  # cells: the oracle's confirming step


def _eye_ij(t, view: View) -> tuple[float, float]:
    """The eye's fractional (row, column) on an affine frame."""
    f = t.frame
    cx, cy = f.scene_to_crs(np.array([view.eye[0]]), np.array([view.eye[1]]))
    a, b, c, d, e, g = f.transform
    det = a * e - b * d
    return (
        float((a * (cy[0] - g) - d * (cx[0] - c)) / det - 0.5),
        float((e * (cx[0] - c) - b * (cy[0] - g)) / det - 0.5),
    )


def shown_displacement(t, truth, view: View, tau: float, sel) -> dict:
    """The largest displacement over every counted sample and over those shown, and how
    many samples moved by more than τ are shown (true point seen, drawn point seen)."""
    X, Y, Z, valid = truth
    vz = np.asarray(sel.mesh.points)[:, 2]
    faces = sel.surface_faces()
    e_all = picture_displacement(sel.ij, faces, vz, X, Y, Z, valid, view)
    out = {
        "max_px": e_all.max,
        "shown_max_px": e_all.max,
        "over_tau": 0,
        "shown_true": 0,
        "shown_drawn": 0,
    }
    if e_all.max <= tau:
        return out
    lo, hi = mesh_height_range_on_grid(sel.ij, faces, vz, Z.shape)
    drawn = valid & np.isfinite(lo)
    cam = (view.look_from, view.look_at, view.up, view.fov_y_deg, view.size)
    c0, r0, _ = picture_coordinates(X[drawn], Y[drawn], Z[drawn], *cam)
    moved = np.zeros(drawn.sum())
    for zm in (lo[drawn], hi[drawn]):
        c1, r1, _ = picture_coordinates(X[drawn], Y[drawn], zm, *cam)
        moved = np.maximum(moved, np.hypot(c1 - c0, r1 - r0))
    over = np.zeros(Z.shape, bool)
    over[drawn] = moved > tau
    # only samples the measure counts: true or drawn point inside the frustum
    inside = np.zeros(Z.shape, bool)
    for z in (Z, lo, hi):
        P = np.stack([X[drawn], Y[drawn], z[drawn]], 1)
        inside[drawn] |= ((P @ view.planes[:, :3].T + view.planes[:, 3]) >= 0).all(1)
    over &= inside
    eij, ez = _eye_ij(t, view), float(view.eye[2])
    Zt = np.where(valid, Z, 0.0)

    def seen(z):
        c = visible_samples(z, valid, eij, ez, over)
        return visible_samples(z, valid, eij, ez, c, step=FINE) if c.any() else c

    vt = seen(Zt)
    vd = seen(np.where(drawn, lo, Zt)) | seen(np.where(drawn, hi, Zt))
    shown = picture_displacement(sel.ij, faces, vz, X, Y, Z, valid & ~(over & ~(vt | vd)), view)
    out.update(
        shown_max_px=shown.max,
        over_tau=int(over.sum()),
        shown_true=int(vt.sum()),
        shown_drawn=int((vd & ~vt).sum()),
    )
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("store")
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--flight", default="ground", choices=["ground", *sorted(FLIGHTS)])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--tau", type=float, default=1.0)
    ap.add_argument("--measure", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    size = tuple(int(s) for s in a.size.split("x"))
    rows = []
    print(f"load average {os.getloadavg()[0]:.2f} before")
    with geoterrain.open(a.store) as t:
        X, Y, Z = t.scene_xyz()
        truth = (X, Y, Z, np.isfinite(Z))
        if a.flight == "ground":
            views = [
                (f"ground {k}", v)
                for k, (v, _) in enumerate(ground_views(X, Y, Z, a.views, seed=a.seed, size=size))
            ]
        else:
            views = [
                (n, v.clipped_to(*t.scene_box())) for n, v in FLIGHTS[a.flight](t, a.views, size)
            ]
        print(
            "| view | triangles | tiles culled | select CPU ms | largest px | shown px | "
            "> τ | shown (true, drawn) |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|---|")
        for name, v in views:
            t.select(v, a.tau, "rtin", occlusion=True, reuse=False)
            t0 = time.process_time()
            sel = t.select(
                dataclasses.replace(v, memos={}), a.tau, "rtin", occlusion=True, reuse=False
            )  # (a fresh view: nothing memoised)
            cpu = 1e3 * (time.process_time() - t0)
            row = {
                "view": name,
                "triangles": sel.stats["triangles"],
                "culled": sel.stats.get("tiles_hidden", 0),
                "select_cpu_ms": cpu,
            }
            if a.measure:
                row.update(shown_displacement(t, truth, v, a.tau, sel))
            rows.append(row)
            m = (
                (
                    f"{row['max_px']:.3f} | {row['shown_max_px']:.3f} | {row['over_tau']} | "
                    f"{row['shown_true']}, {row['shown_drawn']}"
                )
                if a.measure
                else "– | – | – | –"
            )
            print(
                f"| {name} | {row['triangles']} | {row['culled']} | {cpu:.1f} | {m} |", flush=True
            )
    tri = sum(r["triangles"] for r in rows)
    print(
        f"triangles {tri}, tiles culled {sum(r['culled'] for r in rows)}, select CPU median "
        f"{np.median([r['select_cpu_ms'] for r in rows]):.1f} ms"
        + (
            f", shown > τ: {sum(r['shown_true'] + r['shown_drawn'] for r in rows)}"
            if a.measure
            else ""
        )
    )
    print(f"load average {os.getloadavg()[0]:.2f} after")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return {"rows": rows}


if __name__ == "__main__":
    main()
