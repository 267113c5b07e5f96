"""Build docs/gallery.md and its pictures: one picture per feature, each made by the exact
command printed under it.

Two DEMs: srtm1_japan (Sagami Bay, SRTM 1″; the shared real DEMs beside the project, else
the bundled sample_dems/fbm_513.tif stands in) and a coarse topo-bathymetric DEM, 120 × 91
samples 1 km apart from −2500 to 1500 m, made by ``geoterrain synth``. An entry of
``ENTRIES`` is (file stem, title, caption, DEM key, command arguments after ``geoterrain``,
with ``{store}`` and ``{out}`` for the store and the picture). The notebook's picture is
``t.plot()``, as docs/quickstart.ipynb draws it.

Usage (from the project root): ``python docs/gallery/make_gallery.py``
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "gallery"
REAL = Path(os.environ.get("GEOTERRAIN_TEST_DEMS") or ROOT.parent / "shared" / "dems"
            ) / "srtm1_japan.tif"
SAMPLE = ROOT / "sample_dems" / "fbm_513.tif"
SIZE = "480x270"
TOPOBATHY = ["synth", "fbm", "--size", "120x91", "--heights", "-2500,1500", "--spacing",
             "1000", "--seed", "4"]

R = ["render", "{store}", "-o", "{out}", "--size", SIZE]
ENTRIES = [
    ("overview", "Default overview",
     "Hypsometric tints, the sea at 0 m as water, hillshade from the full-resolution normal "
     "maps; colour bar (the water as a swatch: the data has no depth), scale bar and north "
     "arrow in a column within a tenth of the width.",
     "japan", [*R, "--title", "Sagami Bay"]),
    ("flood", "Water that is water: a flood at 40 m",
     "--water-level 40: a flat, lit, semi-transparent surface at 40 m, the depth coloured "
     "under it; -z 2 keeps it flat.",
     "japan", [*R, "--water-level", "40", "--clim", "0,1200", "-z", "2"]),
    ("topobathy", "A topo-bathymetric DEM at -z 3",
     "A coarse 120 × 91 grid (1 km samples): the sea at 0 m is a body of water with sides, "
     "not a sunken basin; coasts follow the bilinear surface (colours from heights "
     "interpolated at each texel), not the samples' squares.",
     "topobathy", [*R, "-z", "3"]),
    ("topobathy_bare", "The same without the water surface",
     "--no-water: the sea floor's depth colours and relief alone (-z 3).",
     "topobathy", [*R, "-z", "3", "--no-water"]),
    ("map", "Map view",
     "--map: orthographic and north up, the whole DEM framed by a graticule in degrees and "
     "minutes (a geographic DEM), the scale bar exact everywhere.",
     "japan", [*R, "--map"]),
    ("map_topobathy", "Map view of a projected DEM",
     "--map on a UTM DEM: its grid of eastings and northings in metres.",
     "topobathy", [*R, "--map"]),
    ("print", "A print with its base",
     "export --print-size 150 -z 2 --preview: a closed solid (walls and a 3 mm base) for a "
     "slicer, drawn as it will print.",
     "japan", ["export", "{store}", "-o", "{work}/relief.stl", "--max-error", "10",
               "--print-size", "150", "-z", "2", "--preview", "{out}", "--overwrite"]),
    ("exaggeration", "Vertical exaggeration at view time",
     "-z 3 draws heights × 3 without a new preprocess; the scale bar's box says VE ×3.",
     "japan", [*R, "-z", "3", "--azimuth", "160", "--elevation", "30"]),
    ("top_down", "Top-down, north up",
     "--elevation 90 looks straight down with north at the top (a perspective view; --map "
     "is the orthographic one).",
     "japan", [*R, "--elevation", "90"]),
    ("sun_shadows", "Low sun, cast shadows and ambient occlusion",
     "--sun 250,20 lights from the west-south-west; --shadows sweeps the horizon toward the "
     "sun over the pyramid; --ambient-occlusion darkens valleys by the sky they see.",
     "japan", [*R, "--sun", "250,20", "--shadows", "--ambient-occlusion"]),
    ("multidirectional", "Multidirectional hillshade",
     "--hillshade multi: four suns 45° apart, so slopes facing every way keep relief.",
     "japan", [*R, "--hillshade", "multi"]),
    ("drape", "A draped raster",
     "--drape IMAGE: any georeferenced raster (here the DEM's own slope, written by "
     "export-raster as gdaldem's) over the colour map, blended at --drape-opacity 0.7.",
     "japan", [*R, "--drape", "{work}/slope.tif", "--drape-opacity", "0.7"]),
]


def geoterrain(*args: str) -> None:
    cmd = [sys.executable, "-m", "geoterrain.cli.main", "-q", *args]
    subprocess.run(cmd, check=True, cwd=ROOT)


def notebook_plot(store: Path, png: Path) -> None:
    """The notebook's picture: ``t.plot()`` (docs/quickstart.ipynb)."""
    import geoterrain

    with geoterrain.open(store) as t:
        t.plot(size=(480, 270), title="t.plot()").save(png)


def main() -> None:
    dem = REAL if REAL.exists() else SAMPLE
    work = ROOT / "out" / "gallery"
    work.mkdir(parents=True, exist_ok=True)
    stores = {"japan": work / (dem.stem + ".geoterrain"),
              "topobathy": work / "topobathy.geoterrain"}
    geoterrain("preprocess", str(dem), "-o", str(stores["japan"]), "--overwrite")
    tb = work / "topobathy.tif"
    geoterrain(*TOPOBATHY, "-o", str(tb), "--overwrite")
    geoterrain("preprocess", str(tb), "-o", str(stores["topobathy"]), "--overwrite")
    geoterrain("export-raster", str(stores["japan"]), "--what", "slope", "-o",
               str(work / "slope.tif"), "--overwrite")
    made = {"japan": f"`geoterrain preprocess {dem.name} -o {stores['japan'].name}`",
            "topobathy": f"`geoterrain {' '.join(TOPOBATHY)} -o topobathy.tif` and "
                         "`geoterrain preprocess topobathy.tif`"}
    lines = ["# Gallery", "",
             f"Made by `python docs/gallery/make_gallery.py` from `{dem.name}`"
             f"{' (shared real DEMs)' if dem == REAL else ' (bundled sample)'}, its store "
             f"made by {made['japan']}, and from a synthetic topo-bathymetric DEM made by "
             f"{made['topobathy']}. Each picture is {SIZE.replace('x', '×')} px, rtin at "
             "τ = 1 px; each was looked at.", ""]
    for stem, title, caption, key, args in ENTRIES:
        png = OUT / f"{stem}.png"
        run = [a.format(store=stores[key], out=png, work=work) for a in args]
        if run[0] == "render":
            run.append("--overwrite")
        geoterrain(*run)
        shown = " ".join(shlex.quote(a.format(store=stores[key].name, out=png.name,
                                              work=".")) for a in args)
        lines += [f"## {title}", "", f"![{title}](gallery/{png.name})", "", caption, "",
                  f"```\ngeoterrain {shown}\n```", ""]
    png = OUT / "notebook_plot.png"
    notebook_plot(stores["japan"], png)
    lines += ["## The notebook's picture", "", "![t.plot()](gallery/notebook_plot.png)", "",
              "`t.plot()` in a notebook draws what `geoterrain render` does, overlays "
              "included, framed into the room they leave (docs/quickstart.ipynb).", "",
              "```\nimport geoterrain\nt = geoterrain.open('srtm1_japan.geoterrain')\n"
              "t.plot(size=(480, 270), title='t.plot()')\n```", ""]
    (ROOT / "docs" / "gallery.md").write_text("\n".join(lines))
    print(f"wrote docs/gallery.md and {len(ENTRIES) + 1} pictures in docs/gallery/")


if __name__ == "__main__":
    main()
