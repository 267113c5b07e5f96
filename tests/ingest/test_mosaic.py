"""Mosaic input: a VRT, a list of files, a glob or a folder gives the same store as the
merged raster."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner
from rasterio.windows import Window

from geoterrain.exceptions import InputError, UsageError
from geoterrain.ingest.mosaic import build_vrt
from geoterrain.preprocessing.pipeline import preprocess
from tests.conftest import real_dem, write_tif
from tests.store.storesql import all_blobs, all_tiles, read_meta

# what may differ between two stores of the same heights: the source's name
_VOLATILE = {"source"}


def store_contents(path: Path) -> tuple:
    """Every blob and tile row, and the metadata but the source name and the timings."""
    con = sqlite3.connect(path)
    try:
        blobs = sorted(all_blobs(con).items())
        tiles = sorted(all_tiles(con).items())
        meta = {k: v for k, v in read_meta(con).items() if k not in _VOLATILE}
    finally:
        con.close()
    return blobs, tiles, meta


def split(src: Path, folder: Path, overlap: int = 0, suffix: str = ".tif",
          nodatas: tuple | None = None) -> list[Path]:
    """``src`` cut into 2×2 tiles (sharing ``overlap`` rows/columns, as SRTM tiles share one).

    ``nodatas`` gives each tile its own nodata value (the voids re-coded to it).
    """
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    with rasterio.open(src) as s:
        h2, w2 = s.height // 2, s.width // 2
        cuts = [((0, h2 + overlap), (0, w2 + overlap)), ((0, h2 + overlap), (w2, s.width)),
                ((h2, s.height), (0, w2 + overlap)), ((h2, s.height), (w2, s.width))]
        for k, ((r0, r1), (c0, c1)) in enumerate(cuts):
            win = Window(c0, r0, c1 - c0, r1 - r0)
            data = s.read(1, window=win)
            prof = s.profile | {"height": r1 - r0, "width": c1 - c0,
                                "transform": s.window_transform(win), "driver": "GTiff",
                                "tiled": False, "compress": "deflate"}
            prof.pop("blockxsize", None), prof.pop("blockysize", None)
            if nodatas is not None:
                data = np.where(data == s.nodata, nodatas[k], data).astype(data.dtype)
                prof["nodata"] = nodatas[k]
            p = folder / f"tile_{k}{suffix}"
            with rasterio.open(p, "w", **prof) as d:
                d.write(data, 1)
            out.append(p)
    return out


def _synthetic(tmp_path: Path) -> Path:
    rng = np.random.default_rng(3)
    z = (np.cumsum(rng.normal(0, 3, (70, 90)), 0) + np.cumsum(rng.normal(0, 3, (70, 90)), 1))
    z = (z + 500).astype(np.int16)
    z[5:12, 40:60] = -32768  # a void across the tile seam
    return write_tif(tmp_path / "merged.tif", z, nodata=-32768)


def _same_store_every_way(merged: Path, tiles: list[Path], tmp_path: Path, pattern: str):
    ref = store_contents(preprocess(merged, tmp_path / "merged.geoterrain"))
    vrt = tmp_path / "mosaic.vrt"
    vrt.write_text(build_vrt(tiles))
    ways = {"vrt": vrt, "list": [str(p) for p in tiles], "glob": pattern,
            "folder": str(Path(pattern).parent)}
    for name, src in ways.items():
        got = store_contents(preprocess(src, tmp_path / f"{name}.geoterrain"))
        assert got[2] == ref[2], f"{name}: metadata differs"
        assert got[1] == ref[1], f"{name}: tile bounds differ"
        assert got[0] == ref[0], f"{name}: blobs differ"


@pytest.mark.parametrize("overlap", [0, 1])
def test_mosaic_of_four_tiles_gives_the_merged_store(tmp_path, overlap):
    merged = _synthetic(tmp_path)
    tiles = split(merged, tmp_path / "tiles", overlap=overlap)
    _same_store_every_way(merged, tiles, tmp_path, str(tmp_path / "tiles" / "tile_*.tif"))


@pytest.mark.fast
def test_each_tile_keeps_its_own_nodata(tmp_path):
    merged = _synthetic(tmp_path)
    tiles = split(merged, tmp_path / "tiles", nodatas=(-32768, -9999, -32768, -9999))
    _same_store_every_way(merged, tiles, tmp_path, str(tmp_path / "tiles" / "*.tif"))


def test_real_srtm_split_in_four(tmp_path):
    dem = real_dem("srtm3_pysheds.tif")
    tiles = split(dem, tmp_path / "hgt", overlap=1)
    _same_store_every_way(dem, tiles, tmp_path, str(tmp_path / "hgt" / "*.tif"))


@pytest.mark.fast
def test_gaps_between_tiles_are_nodata(tmp_path):
    merged = _synthetic(tmp_path)
    tiles = split(merged, tmp_path / "tiles")
    from geoterrain.ingest.raster import read_raster

    full = read_raster(merged)
    three = read_raster([str(p) for p in tiles[:3]])  # the south-east tile missing
    assert three.shape == full.shape
    assert not three.valid[35:, 45:].any()
    assert (three.valid[:35] == full.valid[:35]).all()
    assert np.array_equal(three.heights[three.valid], full.heights[three.valid])


def _tile(tmp_path, name, **kw):
    z = np.arange(64, dtype=np.float32).reshape(8, 8)
    return write_tif(tmp_path / name, z, **kw)


@pytest.mark.fast
@pytest.mark.parametrize("second", [
    # a's east edge in the next UTM zone (pyproj: 500080, 5000000 in 32633 is
    # 971703, 5017546 in 32632), so the merged grid stays small
    dict(crs="EPSG:32632", origin=(971700.0, 5017550.0)),
    dict(spacing=5.0, origin=(500080.0, 5000000.0)),
    dict(origin=(500083.0, 5000000.0)),
])
def test_mismatched_tiles_are_merged_onto_one_grid(tmp_path, second):
    """Mixed CRSs, resolutions or pixel grids were refused before issue 45; they are now
    warped onto one grid (geoterrain.ingest.composite, tested in test_composite.py)."""
    a = _tile(tmp_path, "a.tif", origin=(500000.0, 5000000.0))
    b = _tile(tmp_path, "b.tif", **second)
    preprocess([a, b], tmp_path / "o.geoterrain")
    assert (tmp_path / "o.geoterrain").exists()


@pytest.mark.fast
def test_a_merge_of_an_ungeoreferenced_tile_is_refused_in_one_line(tmp_path):
    a = _tile(tmp_path, "a.tif", origin=(500000.0, 5000000.0))
    b = _tile(tmp_path, "b.tif", spacing=5.0, origin=(500080.0, 5000000.0))
    Image = pytest.importorskip("PIL.Image")
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(tmp_path / "c.png")
    with pytest.raises(InputError, match="no CRS") as e:
        preprocess([a, b, str(tmp_path / "c.png")], tmp_path / "o.geoterrain")
    assert "\n" not in str(e.value)
    assert not (tmp_path / "o.geoterrain").exists()


@pytest.mark.fast
def test_mixed_band_counts_are_refused(tmp_path):
    a = _tile(tmp_path, "a.tif")
    prof = dict(driver="GTiff", height=8, width=8, count=2, dtype="float32", crs="EPSG:32633",
                transform=rasterio.transform.from_origin(500080.0, 5000000.0, 10.0, 10.0))
    with rasterio.open(tmp_path / "b.tif", "w", **prof) as d:
        d.write(np.zeros((2, 8, 8), np.float32))
    with pytest.raises(InputError, match="mixed band counts"):
        preprocess([a, tmp_path / "b.tif"], tmp_path / "o.geoterrain")


@pytest.mark.fast
def test_glob_without_match_and_mosaic_without_output(tmp_path):
    with pytest.raises(InputError, match="no file matches"):
        preprocess(str(tmp_path / "*.hgt"), tmp_path / "o.geoterrain")
    a, b = _tile(tmp_path, "a.tif"), _tile(tmp_path, "b.tif", origin=(500080.0, 5000000.0))
    with pytest.raises(UsageError, match="pass dst"):
        preprocess([a, b])


def _srtm_tile(path: Path, lat: int, lon: int) -> Path:
    """A 3″ SRTM tile (1201², 1°, sharing its edge rows with its neighbours) written by
    GDAL's own SRTMHGT driver, zipped as NASA's downloads are when ``path`` ends in .zip."""
    import zipfile

    from rasterio.shutil import copy as gdal_copy
    from rasterio.transform import from_origin

    n, s = 1201, 1 / 1200
    yy, xx = np.mgrid[0:n, 0:n] * s
    z = (800 + 300 * np.sin((lon + xx) * 7) * np.cos((lat + 1 - yy) * 5)).astype(np.int16)
    tif, hgt = path.parent / "tmp.tif", path.parent / f"N{lat}E{lon:03d}.hgt"
    with rasterio.open(tif, "w", driver="GTiff", height=n, width=n, count=1, dtype="int16",
                       crs="EPSG:4326", transform=from_origin(lon - s / 2, lat + 1 + s / 2, s, s),
                       nodata=-32768) as d:
        d.write(z, 1)
    gdal_copy(tif, hgt, driver="SRTMHGT")
    tif.unlink()
    if path.suffix == ".zip":
        with zipfile.ZipFile(path, "w") as zf:
            zf.write(hgt, hgt.name)
        hgt.unlink()
    return path


@pytest.mark.slow  # 16 s of CPU: two 1201² tiles (the folder's listing: folder_files' doctest)
def test_a_folder_of_srtm_tiles_as_downloaded_is_one_store_beside_it(tmp_path, monkeypatch):
    """A folder of SRTM tiles (one still zipped, one not, GDAL's .aux.xml beside them) is
    read as their mosaic, into FOLDER.geoterrain beside it, every sample kept."""
    from geoterrain.cli.main import cli

    srtm = tmp_path / "srtm"
    srtm.mkdir()
    _srtm_tile(srtm / "N35E138.SRTMGL3.hgt.zip", 35, 138)
    _srtm_tile(srtm / "N35E139.hgt", 35, 139)
    (srtm / "N35E139.hgt.aux.xml").write_text("<PAMDataset/>")
    (srtm / "notes.txt").write_text("downloaded from earthdata")
    (srtm / "old").mkdir()
    run = CliRunner().invoke
    r = run(cli, ["-q", "preprocess", str(srtm)])
    assert r.exit_code == 0, r.output
    made = tmp_path / "srtm.geoterrain"
    assert made.is_file() and not (srtm / "srtm.geoterrain").exists()
    import geoterrain
    from geoterrain.analysis import height_at

    with geoterrain.open(made) as t:  # two tiles sharing one column: 2401 × 1201
        assert (t.grid.rows, t.grid.cols) == (1201, 2401)
        # every sample of both tiles, the zipped one too, read back exactly (lossless)
        for name in ("/vsizip/" + str(srtm / "N35E138.SRTMGL3.hgt.zip") + "/N35E138.hgt",
                     str(srtm / "N35E139.hgt")):
            with rasterio.open(name) as src:
                z = src.read(1).astype(np.float64)
                rows, cols = np.mgrid[0:1201:40, 0:1201:40]
                x, y = rasterio.transform.xy(src.transform, rows.ravel(), cols.ravel())
            got = height_at(t, np.column_stack([x, y])).height
            np.testing.assert_allclose(got, z[rows.ravel(), cols.ravel()], rtol=0, atol=1e-6)
    # the current folder has no name to write beside: -o is asked for, in one line
    monkeypatch.chdir(srtm)
    r = run(cli, ["preprocess", "."])
    assert r.exit_code == 2 and "-o STORE" in r.stderr and len(r.stderr.splitlines()) == 1


@pytest.mark.fast
def test_a_folder_without_rasters_is_one_line(tmp_path):
    from geoterrain.cli.main import cli

    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "readme.txt").write_text("no DEM here")
    r = CliRunner().invoke(cli, ["preprocess", str(tmp_path / "empty")])
    assert r.exit_code == 1 and "no raster file" in r.stderr and ".hgt.zip" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.output
    assert not list(tmp_path.glob("*.geoterrain"))


@pytest.mark.fast
def test_cli_takes_several_files_and_a_glob(tmp_path):
    from geoterrain.cli.main import cli

    merged = _synthetic(tmp_path)
    tiles = split(merged, tmp_path / "tiles")
    run = CliRunner().invoke
    r = run(cli, ["preprocess", *map(str, tiles), "-o", str(tmp_path / "l.geoterrain")])
    assert r.exit_code == 0, r.output
    r = run(cli, ["preprocess", str(tmp_path / "tiles" / "*.tif"), "-o",
                  str(tmp_path / "g.geoterrain")])
    assert r.exit_code == 0, r.output
    assert store_contents(tmp_path / "l.geoterrain") == store_contents(tmp_path / "g.geoterrain")
    r = run(cli, ["preprocess", *map(str, tiles)])
    assert r.exit_code == 2 and "-o STORE" in r.output
    b = tmp_path / "b.tif"
    b.write_bytes(b"not a raster")
    r = run(cli, ["preprocess", str(tiles[0]), str(b), "-o", str(tmp_path / "x.geoterrain")])
    assert r.exit_code == 1 and "b.tif" in r.output and "Traceback" not in r.output


@pytest.mark.fast
def test_a_recursive_glob_reads_tiles_in_subfolders_and_a_nested_folder_says_so(tmp_path):
    """Tiles one per subfolder (as some downloads unpack): ``**`` finds them all, the same
    store as the list; the folder itself (not recursive) names a glob that would."""
    from geoterrain.cli.main import cli

    merged = _synthetic(tmp_path)
    tiles = split(merged, tmp_path / "flat")
    nested = []
    for k, t in enumerate(tiles):
        (tmp_path / "dl" / f"part{k}" / "DEM").mkdir(parents=True)
        nested.append(t.rename(tmp_path / "dl" / f"part{k}" / "DEM" / t.name))
    run = CliRunner().invoke
    r = run(cli, ["-q", "preprocess", *map(str, nested), "-o", str(tmp_path / "l.geoterrain")])
    assert r.exit_code == 0, r.output
    r = run(cli, ["-q", "preprocess", str(tmp_path / "dl" / "**" / "*.tif"), "-o",
                  str(tmp_path / "g.geoterrain")])
    assert r.exit_code == 0, r.output
    assert store_contents(tmp_path / "l.geoterrain") == store_contents(tmp_path / "g.geoterrain")
    r = run(cli, ["preprocess", str(tmp_path / "dl"), "-o", str(tmp_path / "f.geoterrain")])
    assert r.exit_code == 1 and "subfolders hold 4" in r.stderr
    assert f"'{tmp_path / 'dl' / '**' / '*.tif'}'" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.output
    assert not (tmp_path / "f.geoterrain").exists()
