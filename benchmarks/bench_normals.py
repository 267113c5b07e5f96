"""Benchmark of the normal-map stage of preprocessing on a 4097^2 synthetic field.

Times (median of ``--repeat`` runs, after a warm-up that compiles the kernels):
``normal_map`` (central and Horn kernels), ``normal_pyramid`` (7 levels, t = 6 on a
4097^2 grid), ``encode_octahedral`` at 8 bits (rounding and ``precise=True``) over every
level, and, with ``--legacy``, the per-level ``level_normals`` it replaces. Also prints
the max angular error of the octahedral encoders over 10**6 random directions.

Run from the project root::

    /work/venv/bin/python benchmarks/bench_normals.py [--repeat 5] [--legacy]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from geoterrain.bounds.normals import (  # noqa: E402
    decode_octahedral,
    encode_octahedral,
    level_normals,
    normal_map,
    normal_pyramid,
)
from geoterrain.ingest.synth import generate  # noqa: E402


def timed(label: str, f, repeat: int):
    ts, r = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = f()
        ts.append(time.perf_counter() - t0)
    runs = " ".join(f"{t:.3f}" for t in ts)
    print(f"| {label} | {statistics.median(ts):.3f} | {runs} |", flush=True)
    return r


def octahedral_errors() -> None:
    rng = np.random.default_rng(2)
    v = rng.normal(size=(1_000_000, 3))
    v = np.concatenate([v, np.eye(3), -np.eye(3)])
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    for bits in (8, 16):
        for precise in (False, True):
            d = decode_octahedral(encode_octahedral(v, bits, precise=precise), bits)
            d = d.astype(np.float64)
            ang = np.arctan2(np.linalg.norm(np.cross(d, v), axis=1), np.sum(d * v, axis=1))
            kind = "precise" if precise else "rounding"
            print(f"octahedral {bits} bits {kind}: max {np.degrees(ang.max()):.4f} deg")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--legacy", action="store_true", help="also time level_normals (slow)")
    args = ap.parse_args()
    n = 4097
    z = generate("fbm", n, seed=7).astype(np.float64)
    i, j = np.indices((n, n), dtype=np.float64)
    x, y = 10.0 * j - 20480.0, 20480.0 - 10.0 * i
    valid = np.ones((n, n), bool)
    # warm-up: compile (or load the cached) kernels
    normal_pyramid(normal_map(x[:9, :9], y[:9, :9], z[:9, :9]), None, 2)
    encode_octahedral(np.ones((2, 3)), precise=True)
    print("| step (4097^2) | median s | runs |\n|---|---|---|")
    nrm = timed("normal_map central", lambda: normal_map(x, y, z, valid), args.repeat)
    timed("normal_map horn", lambda: normal_map(x, y, z, valid, kernel="horn"), args.repeat)
    lv = timed("normal_pyramid 7 levels", lambda: normal_pyramid(nrm, valid, 7), args.repeat)
    timed("encode_octahedral 8 bits x 7 levels", lambda: [encode_octahedral(a) for a in lv], 3)
    timed(
        "encode_octahedral 8 bits precise x 7 levels",
        lambda: [encode_octahedral(a, 8, precise=True) for a in lv],
        args.repeat,
    )
    if args.legacy:
        timed("level_normals x 7 levels", lambda: [level_normals(nrm, L) for L in range(7)], 1)
    octahedral_errors()


if __name__ == "__main__":
    main()
