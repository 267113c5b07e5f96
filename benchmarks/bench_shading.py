"""Cast shadows and ambient occlusion: agreement with a ray march, and their cost.

1. The shadow sweep (``shading.shadow_mask``) against the per-sample ray march of
   ``reference.shadow_reference`` at supersampling 1, 2 and 3, on crops of srtm1_japan
   (when ``../shared/dems`` is present) and on synthetic 129² DEMs, over six suns.
2. Time per texture-tile window (193², a 65² tile and its margin): shadow fraction and
   the sky-view factor, median of ``--runs``.
3. A cold render of a store without and with ``--shadows --ambient-occlusion``, in the
   same process (fresh scenes; texture tiles are cached per light).

Usage: ``python benchmarks/bench_shading.py [--store STORE] [--runs 5]``
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from geoterrain.ingest.synth import generate
from geoterrain.rendering.shading import Light, shadow_fraction, shadow_mask, sky_view_core
from geoterrain.testing.reference import shadow_reference

DEMS = Path(__file__).resolve().parents[1].parent / "shared" / "dems"
SUNS = [(315, 45), (200, 20), (135, 35), (250, 25), (45, 30), (100, 60)]


def crops() -> dict[str, np.ndarray]:
    out = {}
    japan = DEMS / "srtm1_japan.tif"
    if japan.exists():
        import rasterio

        with rasterio.open(japan) as src:
            z = src.read(1).astype(np.float64)
        out["srtm1_japan [0:160, 0:160]"] = z[0:160, 0:160]
        out["srtm1_japan [100:260, 500:660]"] = z[100:260, 500:660]
    for name in ("fbm", "ridged"):
        z = generate(name, 129, seed=3)
        out[f"{name} 129², 600 m relief"] = (z - z.min()) * (600.0 / (z.max() - z.min()))
        out[f"{name} 129², 2000 m relief"] = (z - z.min()) * (2000.0 / (z.max() - z.min()))
    return out


def agreement() -> None:
    print("\n### Shadow sweep against the ray march (30 m samples; min / mean over 6 suns)\n")
    print("| DEM | 1× | 2× | 3× (default) |")
    print("|---|---|---|---|")
    for name, z in crops().items():
        v = np.isfinite(z)
        refs = [shadow_reference(z, v, 30.0, a, e) for a, e in SUNS]
        cells = []
        for k in (1, 2, 3):
            r = [float((shadow_mask(z, v, 30.0, a, e, k) == ref)[v].mean())
                 for (a, e), ref in zip(SUNS, refs, strict=True)]
            cells.append(f"{100 * min(r):.2f} / {100 * statistics.mean(r):.2f} %")
        print(f"| {name} | " + " | ".join(cells) + " |")


def timing(runs: int) -> None:
    z = generate("fbm", 193, seed=3)
    v = np.ones(z.shape, bool)
    shadow_fraction(z, v, 30.0, 200, 20)
    sky_view_core(z, v, 30.0, 64)

    def med(fn):
        ts = []
        for _ in range(runs):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return 1e3 * statistics.median(ts)

    print("\n### Cost per texture tile (a 193² window around a 65² tile)\n")
    print(f"- shadow fraction (3× sweep): {med(lambda: shadow_fraction(z, v, 30.0, 200, 20)):.1f}"
          " ms")
    print(f"- sky-view factor (8 directions × 16 samples, 65² core): "
          f"{med(lambda: sky_view_core(z, v, 30.0, 64)):.1f} ms")


def render_cost(store: str) -> None:
    import geoterrain
    from geoterrain.rendering.scene import default_view, render_array

    with geoterrain.open(store) as t:  # compile every kernel first (a small render)
        render_array(t, default_view(t, (160, 90), 190, 40),
                     light=Light(shadows=True, ambient_occlusion=True))
    print(f"\n### A cold render of {Path(store).name}, 960×540, rtin τ = 1 (fresh terrain, "
          "kernels compiled)\n")
    print("| light | render ms | textures built |")
    print("|---|---|---|")
    for name, light in (("default", None), ("--shadows --ambient-occlusion",
                                            Light(shadows=True, ambient_occlusion=True))):
        t = geoterrain.open(store)  # a fresh terrain: nothing cached
        v = default_view(t, (960, 540), 190, 40)
        t0 = time.perf_counter()
        _, st = render_array(t, v, light=light)
        print(f"| {name} | {1e3 * (time.perf_counter() - t0):.0f} | "
              f"{st.get('textures_built', '–')} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", help="a store to render (optional)")
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    agreement()
    timing(a.runs)
    if a.store:
        render_cost(a.store)


if __name__ == "__main__":
    main()
