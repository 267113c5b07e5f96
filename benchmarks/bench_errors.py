"""Benchmark of the bound kernels, geoterrain.bounds.delta and geoterrain.bounds.tilebounds (a
script,
not a test).

1. Timing on a seeded 4097² spectral fBm DEM: the pure-numpy δ reference vs. the compiled
   kernel (after a warm-up compile), radii, tile errors, and pymartini
   ``Martini(4097)`` + ``create_tile`` in the same run; median of ``--runs`` runs each.
2. Tightness on the Fuji Terrain-RGB tile: triangles and MEASURED max vertical error of our
   ``static_mesh`` vs. pymartini ``get_mesh(e)`` vs. pydelatin, all measured by the same
   independent barycentric routine below.

Usage: ``python benchmarks/bench_errors.py [--size 4097] [--runs 3] [--skip-reference]``
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from geoterrain.bounds.delta import vertex_errors
from geoterrain.bounds.radii import vertex_radii
from geoterrain.bounds.tilebounds import tile_errors
from geoterrain.testing.reference import saturate, static_mesh, vertex_errors_reference

FUJI = Path("/work/shared/dems/fuji_terrain_rgb.png")


def fbm(n: int, seed: int = 0, beta: float = 2.2, relief: float = 3000.0) -> np.ndarray:
    """Seeded spectral fBm on a (2**k + 1)² grid (power spectrum ∝ |k|^-(beta+1))."""
    m = n - 1
    rng = np.random.default_rng(seed)
    kx = np.fft.fftfreq(m)[:, None]
    ky = np.fft.rfftfreq(m)[None, :]
    k = np.sqrt(kx**2 + ky**2)
    k[0, 0] = 1.0
    amp = k ** (-(beta + 1) / 2)
    amp[0, 0] = 0.0
    spec = amp * (rng.normal(size=amp.shape) + 1j * rng.normal(size=amp.shape))
    z = np.fft.irfft2(spec, s=(m, m))
    z = np.pad(z, ((0, 1), (0, 1)), mode="wrap")  # periodic: the extra row/col is a copy
    z -= z.min()
    return z * (relief / z.max())


def timed(fn, runs: int) -> tuple[float, float]:
    """Median wall and CPU seconds over ``runs`` calls."""
    wall, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def mesh_max_error(verts_ij: np.ndarray, faces: np.ndarray, z: np.ndarray,
                   valid: np.ndarray) -> tuple[float, int]:
    """Max |z − mesh| over valid samples inside the triangles (barycentric, vectorised per
    triangle bounding-box size), and the number of valid samples covered."""
    V = np.asarray(verts_ij, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    A, B, C = V[faces[:, 0]], V[faces[:, 1]], V[faces[:, 2]]
    lo = np.floor(np.minimum(np.minimum(A, B), C)).astype(np.int64)
    hi = np.ceil(np.maximum(np.maximum(A, B), C)).astype(np.int64)
    ext = (hi - lo).max(1)
    zz = np.where(valid, z, np.nan)
    covered = np.zeros(z.shape, bool)
    worst = 0.0
    for size in np.unique(ext):
        sel = np.flatnonzero(ext == size)
        oi, oj = np.indices((size + 1, size + 1))
        oi, oj = oi.ravel(), oj.ravel()
        for chunk in np.array_split(sel, max(1, len(sel) * (size + 1) ** 2 // 4_000_000)):
            a, b, c = A[chunk], B[chunk], C[chunk]
            Pi = lo[chunk, :1] + oi[None]
            Pj = lo[chunk, 1:] + oj[None]
            det = ((b[:, :1] - a[:, :1]) * (c[:, 1:] - a[:, 1:])
                   - (c[:, :1] - a[:, :1]) * (b[:, 1:] - a[:, 1:]))
            wb = ((Pi - a[:, :1]) * (c[:, 1:] - a[:, 1:])
                  - (c[:, :1] - a[:, :1]) * (Pj - a[:, 1:])) / det
            wc = ((b[:, :1] - a[:, :1]) * (Pj - a[:, 1:])
                  - (Pi - a[:, :1]) * (b[:, 1:] - a[:, 1:])) / det
            wa = 1.0 - wb - wc
            inside = ((wa >= -1e-9) & (wb >= -1e-9) & (wc >= -1e-9)
                      & (Pi >= 0) & (Pi < z.shape[0]) & (Pj >= 0) & (Pj < z.shape[1]))
            Pi_c = np.clip(Pi, 0, z.shape[0] - 1)
            Pj_c = np.clip(Pj, 0, z.shape[1] - 1)

            def h(p):
                return z[p[:, 0].astype(np.int64), p[:, 1].astype(np.int64)][:, None]

            dev = np.abs(zz[Pi_c, Pj_c] - (wa * h(a) + wb * h(b) + wc * h(c)))
            dev = np.where(inside, dev, np.nan)
            covered[Pi_c[inside], Pj_c[inside]] = True
            if np.isfinite(dev).any():
                worst = max(worst, float(np.nanmax(dev)))
    return worst, int((covered & valid).sum())


def read_fuji() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    import imageio.v3 as iio

    rgb = iio.imread(FUJI)[..., :3].astype(np.float64)
    h = -10000 + (rgb[..., 0] * 65536 + rgb[..., 1] * 256 + rgb[..., 2]) * 0.1
    H, W = h.shape
    n = int(np.ceil(np.log2(max(H, W) - 1)))
    N = 2**n + 1
    z = np.full((N, N), np.nan)
    valid = np.zeros((N, N), bool)
    z[:H, :W] = h
    valid[:H, :W] = True  # padding is invalid (conventions)
    return z, valid, h


def bench_timing(size: int, runs: int, skip_reference: bool) -> None:
    from pymartini import Martini

    z = fbm(size, seed=42)
    valid = np.ones(z.shape, bool)
    ii, jj = np.indices(z.shape).astype(np.float64)
    x, y = 30.0 * jj, -30.0 * ii
    # warm-up: compile (or load the cached) kernels, fault in memory
    s = 33
    vertex_errors(z[:s, :s].copy(), valid[:s, :s].copy())
    vertex_radii(x[:s, :s].copy(), y[:s, :s].copy(), z[:s, :s].copy(), valid[:s, :s].copy())
    tile_errors(z[:s, :s].copy(), valid[:s, :s].copy(), x[:s, :s].copy(), y[:s, :s].copy(), 4)
    vertex_errors(z, valid)
    z32 = z.astype(np.float32).ravel()

    rows = []
    if not skip_reference:
        ref = timed(lambda: saturate(vertex_errors_reference(z, valid)), runs)
        rows.append(("δ numpy reference (exact, saturated)", ref))
    d = timed(lambda: vertex_errors(z, valid), runs)
    rows.append(("δ compiled kernel (exact, saturated, float32)", d))
    r = timed(lambda: vertex_radii(x, y, z, valid), runs)
    rows.append(("radii (nested spheres, 3-D)", r))

    def both():
        vertex_errors(z, valid)
        vertex_radii(x, y, z, valid)

    dr = timed(both, runs)
    rows.append(("δ + radii", dr))
    te = timed(lambda: tile_errors(z, valid, x, y, 6), runs)
    rows.append(("tile errors (t = 6, all levels)", te))
    mt = timed(lambda: Martini(size).create_tile(z32), runs)
    rows.append(("pymartini Martini(N) + create_tile", mt))

    print(f"\n### Timing on a {size}² spectral fBm DEM (median of {runs} runs)\n")
    print("| stage | wall s | CPU s | pymartini wall / stage wall |")
    print("|---|---:|---:|---:|")
    for name, (w, c) in rows:
        print(f"| {name} | {w:.3f} | {c:.3f} | {mt[0] / w:.2f}× |")
    if not skip_reference:
        print(f"\nkernel speed-up over the numpy reference: {ref[0] / d[0]:.1f}× (wall)")
    print(f"δ + radii vs pymartini: {mt[0] / dr[0]:.2f}× faster (wall), "
          f"{mt[1] / dr[1]:.2f}× (CPU)")


def bench_tightness() -> None:
    if not FUJI.exists():
        print("\n(Fuji DEM absent: no tightness table)")
        return
    from pymartini import Martini

    z, valid, h = read_fuji()
    N = z.shape[0]
    d = vertex_errors(z, valid)
    # pymartini has no nodata: feed it the grid with the padding edge-duplicated
    zp = np.pad(h, ((0, N - h.shape[0]), (0, N - h.shape[1])), mode="edge").astype(np.float32)
    tile = Martini(N).create_tile(zp.ravel())
    try:
        from pydelatin import Delatin
    except ImportError:  # pragma: no cover
        Delatin = None
    print("\n### Tightness on the Fuji Terrain-RGB tile (512² → 513² padded, metres)\n")
    print("| e (m) | ours: triangles | ours: measured max err | pymartini: triangles "
          "| pymartini: measured max err | pydelatin: triangles | pydelatin: measured max err |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for e in (0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0):
        v, f = static_mesh(d, valid, e)
        ours = mesh_max_error(v, f, z, valid)
        mv, mf = tile.get_mesh(e)
        mart = mesh_max_error(np.asarray(mv)[:, ::-1], mf, z, valid)  # (x, y) → (i, j)
        cells = [f"{e:g}", f"{len(f)}", f"{ours[0]:.3f}", f"{len(mf)}", f"{mart[0]:.3f}"]
        if Delatin is not None:
            dl = Delatin(h.astype(np.float32), max_error=e)
            dv = np.asarray(dl.vertices)[:, :2]
            dv = np.stack([h.shape[0] - 1 - dv[:, 1], dv[:, 0]], 1)  # its y axis points up
            dtri = np.asarray(dl.triangles).astype(np.int64)
            dela = mesh_max_error(dv, dtri, z, valid)
            cells += [f"{len(dtri)}", f"{dela[0]:.3f}"]
        else:
            cells += ["–", "–"]
        print("| " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=4097)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--skip-reference", action="store_true")
    args = ap.parse_args()
    bench_timing(args.size, args.runs, args.skip_reference)
    bench_tightness()


if __name__ == "__main__":
    main()
