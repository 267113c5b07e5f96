"""Build docs/gallery.md and its pictures: one picture per rendering feature, each made
by the exact `geoterrain` command printed under it.

The DEM is srtm1_japan (Sagami Bay, SRTM 1″) when the shared real DEMs are present
beside the project, else the bundled sample_dems/fbm_513.tif. A feature is one entry of
``ENTRIES``: (file stem, title, caption, command arguments after the store).

Usage (from the project root): ``python docs/gallery/make_gallery.py``
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "gallery"
REAL = ROOT.parent / "shared" / "dems" / "srtm1_japan.tif"
SAMPLE = ROOT / "sample_dems" / "fbm_513.tif"
SIZE = "480x270"

# (stem, title, caption, arguments after STORE; {drape} is the slope map made below)
ENTRIES = [
    ("overview", "Default overview",
     "Hypsometric tints (water in blue where the data reaches the sea), hillshade from the "
     "full-resolution normal maps, colour bar, scale bar and north arrow on opaque boxes.",
     ["--title", "Overview"]),
    ("exaggeration", "Vertical exaggeration at view time",
     "-z 3 draws heights × 3 without a new preprocess; the scale bar's box says VE ×3.",
     ["-z", "3", "--azimuth", "160", "--elevation", "30"]),
    ("top_down", "Top-down, north up",
     "--elevation 90 looks straight down with north at the top; the arrow is tested "
     "against the rendered picture.",
     ["--elevation", "90"]),
    ("sun_shadows", "Low sun, cast shadows and ambient occlusion",
     "--sun 250,20 lights from the west-south-west; --shadows sweeps the horizon toward the "
     "sun over the pyramid; --ambient-occlusion darkens valleys by the sky they see.",
     ["--sun", "250,20", "--shadows", "--ambient-occlusion"]),
    ("multidirectional", "Multidirectional hillshade",
     "--hillshade multi: four suns 45° apart, so slopes facing every way keep relief.",
     ["--hillshade", "multi"]),
    ("drape", "A draped raster",
     "--drape IMAGE: any georeferenced raster (here the DEM's own slope map, written by "
     "export-raster) over the colour map, blended at --drape-opacity 0.7.",
     ["--drape", "{drape}", "--drape-opacity", "0.7"]),
    ("water", "Water level and colour limits",
     "--water-level colours everything at or below a height as water; --clim fixes the "
     "colour range.",
     ["--water-level", "{water}", "--clim", "{clim}"]),
]


def geoterrain(*args: str) -> None:
    cmd = [sys.executable, "-m", "geoterrain.cli.main", "-q", *args]
    subprocess.run(cmd, check=True, cwd=ROOT)


def main() -> None:
    dem = REAL if REAL.exists() else SAMPLE
    work = ROOT / "out" / "gallery"
    work.mkdir(parents=True, exist_ok=True)
    store = work / (dem.stem + ".geoterrain")
    geoterrain("preprocess", str(dem), "-o", str(store), "--overwrite")
    drape = work / "slope.tif"
    geoterrain("export-raster", str(store), "--what", "slope", "-o", str(drape), "--overwrite")
    water, clim = ("40", "0,1200") if dem == REAL else ("120", "0,1000")
    lines = ["# Gallery", "",
             f"Made by `python docs/gallery/make_gallery.py` from `{dem.name}`"
             f"{' (shared real DEMs)' if dem == REAL else ' (bundled sample)'}; the store is "
             f"`geoterrain preprocess {dem.name} -o {store.name}`. Each picture is "
             f"{SIZE.replace('x', '×')} px, rtin at τ = 1 px.", ""]
    for stem, title, caption, args in ENTRIES:
        args = [a.format(drape=drape.name, water=water, clim=clim) for a in args]
        png = OUT / f"{stem}.png"
        run = [str(store), "-o", str(png), "--size", SIZE, "--overwrite",
               *[str(work / a) if a == drape.name else a for a in args]]
        geoterrain("render", *run)
        shown = " ".join(shlex.quote(a) for a in
                         ["geoterrain", "render", store.name, "-o", png.name, "--size", SIZE,
                          *args])
        lines += [f"## {title}", "", f"![{title}](gallery/{png.name})", "", caption, "",
                  f"```\n{shown}\n```", ""]
    (ROOT / "docs" / "gallery.md").write_text("\n".join(lines))
    print(f"wrote docs/gallery.md and {len(ENTRIES)} pictures in docs/gallery/")


if __name__ == "__main__":
    main()
