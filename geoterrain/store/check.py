"""Validation of an opened store's metadata and tile table (the store is untrusted input).

Checksums catch accidents; they do not stop a file edited on purpose (anyone can
recompute a CRC). So every value the reader uses is checked for its type, range
and finiteness, and for consistency with the others and with the tile table,
before anything is sized from it. See docs/store.md, "Threat model".
"""

from __future__ import annotations

import math
from operator import itemgetter
from pathlib import Path

import numpy as np

from geoterrain.codec.quantizer import MAX_BINS, Quantizer
from geoterrain.core.frame import SCENE_LIMIT, UNIT_TO_M_RANGE, Z_SCALE_RANGE, Z_UNITS, Frame
from geoterrain.core.grid import MAX_ROOTS, Grid
from geoterrain.core.memory import available_memory
from geoterrain.exceptions import StoreError
from geoterrain.store.schema import LATTICE_SCHEMA_VERSION, schema_version

__all__ = ["check_store", "available_memory"]

MAX_N = 24  # 2**24 + 1 samples per side: far beyond any DEM a machine can hold
_FRAME_KINDS = ("projected", "geographic", "pixel")
_BYTES_PER_SAMPLE = 8  # the dense per-sample flags and vertex ids a mesh selection keeps


class _Bad(Exception):
    pass


def _int(v, lo: int, hi: int, what: str) -> int:
    if type(v) is not int or not lo <= v <= hi:
        raise _Bad(f"{what} must be an integer in [{lo}, {hi}]")
    return v


def _num(v, what: str, lo: float = -math.inf, hi: float = math.inf, *, positive=False,
         finite=True) -> float:
    if type(v) not in (int, float) or math.isnan(v) or (finite and math.isinf(v)):
        raise _Bad(f"{what} must be a {'finite ' if finite else ''}number")
    if positive and not v > 0 or not lo <= v <= hi:
        raise _Bad(f"{what} is out of range")
    return float(v)


def _keys(d, allowed: set[str], required: set[str], what: str) -> dict:
    if not isinstance(d, dict) or not required <= set(d) or not set(d) <= allowed:
        raise _Bad(f"{what} has other fields than expected")
    return d


def _grid(m: dict) -> Grid:
    """The metadata's grid: a square one (stores always wrote it so) or, with
    ``layout: "roots"``, a rectangular root grid; either the one its shape gives."""
    d = _keys(m.get("grid"), {"rows", "cols", "n", "t", "layout"}, {"rows", "cols", "n", "t"},
              "grid")
    n = _int(d["n"], 1, MAX_N, "grid.n")
    t = _int(d["t"], 1, min(n, 15), "grid.t")
    if d.get("layout", "square") not in ("square", "roots") or d.get("layout") == "square":
        raise _Bad("grid.layout must be \"roots\" or absent")
    roots = "layout" in d
    side = ((1 << n) + 1) * (MAX_ROOTS if roots else 1)
    rows = _int(d["rows"], 2, side, "grid.rows")
    cols = _int(d["cols"], 2, side, "grid.cols")
    g = Grid(rows, cols, n, t, d.get("layout", "square"))
    if Grid.for_shape(rows, cols, 1 << t, roots=roots) != g:
        raise _Bad("grid.n does not fit grid.rows and grid.cols")
    version = schema_version(d, m.get("frame"))
    if "schema_version" in m and m["schema_version"] != version:
        what = "a frame with a lattice" if version == LATTICE_SCHEMA_VERSION else \
            f"a {'root' if roots else 'square'} grid"
        raise _Bad(f"{what} is written in schema version {version}, not "
                   f"{m['schema_version']}")
    return g


def _frame(m: dict, g: Grid) -> Frame:
    fields = {"kind", "rows", "cols", "transform", "crs_wkt", "unit_to_m", "z_to_m", "z_scale",
              "origin_crs"}  # no aeqd_wkt from schema 23 on: built on read (Frame.aeqd_wkt)
    d = _keys(m.get("frame"), fields | {"lattice"}, fields, "frame")
    if d["kind"] not in _FRAME_KINDS:
        raise _Bad("frame.kind is unknown")
    # proxy positions past level 0's lattice (Frame.xy): a geographic root grid's own
    # lattice, only where its extent passes it (the writer sets it so, nowhere else)
    if "lattice" in d and (d["kind"] != "geographic" or g.extent == g.shape
                           or not isinstance(d["lattice"], list)
                           or [type(v) for v in d["lattice"]] != [int, int]
                           or d["lattice"] != list(g.shape)):
        raise _Bad("frame.lattice is not the geographic root grid's level-0 lattice past "
                   "which it pads")
    if d["rows"] != g.rows or d["cols"] != g.cols:
        raise _Bad("frame size differs from the grid")
    tr = d["transform"]
    if not isinstance(tr, list) or len(tr) != 6:
        raise _Bad("frame.transform must be 6 numbers")
    tr = [_num(v, "frame.transform") for v in tr]
    # affine (a, b, c, d, e, f): north-up, west to east (ingest flips a south-up raster;
    # a reader would draw another one mirrored), not rotated
    if tr[1] != 0 or tr[3] != 0 or not (tr[0] > 0 and tr[4] < 0):
        raise _Bad("frame.transform must be north-up (pixel width > 0, height < 0), "
                   "not rotated")
    _num(d["unit_to_m"], "frame.unit_to_m", *UNIT_TO_M_RANGE)
    _num(d["z_scale"], "frame.z_scale", *Z_SCALE_RANGE)
    if d["z_to_m"] not in Z_UNITS.values():  # exactly one the writer knows
        raise _Bad("frame.z_to_m is not a vertical unit (m, ft, us-ft)")
    oc = d["origin_crs"]
    if not isinstance(oc, list) or len(oc) != 2:
        raise _Bad("frame.origin_crs must be 2 numbers")
    [_num(v, "frame.origin_crs") for v in oc]
    if d["crs_wkt"] is not None and (not isinstance(d["crs_wkt"], str)
                                     or len(d["crs_wkt"]) > 100_000):
        raise _Bad("frame.crs_wkt must be text")
    if (d["kind"] == "pixel") != (d["crs_wkt"] is None):
        raise _Bad("frame.kind does not match its CRS")
    if d["kind"] == "geographic":
        lat = [tr[5], tr[5] + tr[4] * g.rows]
        lon = [tr[2], tr[2] + tr[0] * g.cols]
        if max(abs(v) for v in lat) > 90 or max(abs(v) for v in lon) > 540:
            raise _Bad("frame latitudes lie beyond ±90°")
    try:
        f = Frame.from_json(d)
        if d["crs_wkt"] is not None:
            f.crs_name  # noqa: B018 - parses the WKT
    except Exception:  # noqa: BLE001 - any parse failure of a stranger's WKT
        raise _Bad("frame CRS cannot be parsed") from None
    return f


def _quantizer(m: dict) -> Quantizer:
    fields = {"mode", "step", "offset", "codec_error", "float_bits", "bins"}
    d = _keys(m.get("quantizer"), fields, {"mode"}, "quantizer")
    if d["mode"] not in ("int", "decimal", "quantized", "float"):
        raise _Bad("quantizer.mode is unknown")
    step = _num(d.get("step", 1.0), "quantizer.step", positive=True)
    _num(d.get("offset", 0.0), "quantizer.offset")
    eps = _num(d.get("codec_error", 0.0), "quantizer.codec_error", lo=0.0)
    if d.get("float_bits", 64) not in (32, 64):
        raise _Bad("quantizer.float_bits must be 32 or 64")
    bins = d.get("bins", 1)
    if type(bins) is not int or not (1 <= bins <= MAX_BINS and bins & 1):
        raise _Bad(f"quantizer.bins must be an odd integer in 1 … {MAX_BINS}")
    if d["mode"] == "quantized" and not (step <= 2 * eps and (bins - 1) * step <= 2 * eps
                                         and eps < (bins + 1) * step):
        raise _Bad("quantizer.step does not match its codec_error")
    if d["mode"] != "quantized" and eps != 0:
        raise _Bad("a lossless quantizer has codec_error 0")
    if d["mode"] == "float" and (step, d.get("offset", 0.0)) != (1.0, 0.0):
        raise _Bad("a float quantizer has step 1 and offset 0")
    try:  # the quantizer's own rules (a decimal one's step and offset)
        return Quantizer.from_json(d)
    except ValueError as exc:
        raise _Bad(str(exc)) from None


_BOX = ("zmin", "zmax", "xmin", "xmax", "ymin", "ymax")  # finite numbers
_BOUNDS = ("error", "boundary_error", "delta_max", "radius_max")  # ≥ 0, +inf allowed


def _column(tiles: dict, k: str) -> np.ndarray:
    # one number of every tile, NaN for anything but an int or float (so it fails)
    vals = list(map(itemgetter(k), tiles.values()))
    if set(map(type, vals)) <= _NUMBERS:  # a reader's table: C loops (None → NaN)
        return np.array(vals, np.float64)
    return np.array([v if type(v) in (int, float) else np.nan for v in vals], np.float64)


_NUMBERS = {int, float, type(None)}


def _tiles(tiles: dict, g: Grid, f: Frame, m: dict) -> None:
    """Every tile inside the grid with its parent stored, a valid count its footprint
    allows, finite non-inverted boxes and non-negative bounds; the first tile (in table
    order) that fails names its first failing rule. Whole arrays: a 16385² store has
    87 381 tiles."""
    rx, ry = g.roots
    top = [(g.top_level, x, y) for y in range(ry) for x in range(rx) if (g.top_level, x, y)
           in tiles]
    if not top:
        raise _Bad("the top tile is missing")
    keys = np.array(list(tiles), np.int64).reshape(-1, 3)
    L, x, y = keys.T
    inside_levels = (0 <= L) & (L <= g.top_level)
    across, down = (np.array([g.tiles(k)[a] for k in g.levels] + [0], np.int64) for a in (0, 1))
    lv = np.where(inside_levels, L, g.top_level + 1)
    inside = (0 <= x) & (x < across[lv]) & (0 <= y) & (y < down[lv])
    # keys as one integer each (inside the grid x, y < 2^24), parents looked up by value
    code = np.where(inside, (L << 52) | (x << 26) | y, -1)
    parent = np.where(inside, ((L + 1) << 52) | ((x // 2) << 26) | (y // 2), -1)
    # parents looked up in the sorted codes (not np.isin: numpy 2's imports numpy.ma)
    srt = np.sort(code)
    at = np.minimum(np.searchsorted(srt, parent), len(srt) - 1)
    orphan = inside & (L < g.top_level) & (srt[at] != parent)
    spans = (np.int64(1) << (g.t + np.clip(L, 0, g.top_level))) + 1
    nvalid = np.array([info["nvalid"] for info in tiles.values()], np.float64)
    counts = ~((1 <= nvalid) & (nvalid <= np.minimum(spans * spans, m["valid_samples"])))
    rules = [(~inside, "lies outside the grid"), (orphan, "has no parent tile"),
             (counts, "nvalid is out of range")]
    box = {k: _column(tiles, k) for k in _BOX}
    rules += [(~(np.abs(box[k]) <= SCENE_LIMIT), f"{k} must be a finite number within "
               f"±{SCENE_LIMIT:.0e} m") for k in _BOX]
    for k in _BOUNDS:
        v = _column(tiles, k)
        rules += [(np.isnan(v), f"{k} must be a number"), (v < 0, f"{k} is out of range")]
    rules.append(((box["zmin"] > box["zmax"]) | (box["xmin"] > box["xmax"])
                  | (box["ymin"] > box["ymax"]), "box is inverted"))
    bad = np.stack([r for r, _ in rules])
    if bad.any():
        i = int(bad.any(axis=0).argmax())  # the first failing tile, its first rule
        raise _Bad(f"tile {tuple(int(v) for v in keys[i])} {rules[int(bad[:, i].argmax())][1]}")
    if not (L == 0).any():
        raise _Bad("level 0 holds no tile")
    # the top tiles' footprints are everything: their height box is the height range, in
    # scene z
    lo, hi = (float(v) for v in f.z([m["height_range"][0], m["height_range"][1]]))
    zmin, zmax = min(tiles[k]["zmin"] for k in top), max(tiles[k]["zmax"] for k in top)
    tol = 1e-6 * max(1.0, abs(lo), abs(hi))
    if abs(zmin - lo) > tol or abs(zmax - hi) > tol:
        raise _Bad("height_range, z_scale or the top tile's heights disagree")


def check_store(path: str | Path, m: dict, tiles: dict) -> tuple[Grid, Frame, Quantizer]:
    """Validate metadata ``m`` and the tile table; return the grid, frame and quantizer.

    Raises :class:`StoreError` naming the first inconsistency, or the memory a
    mesh of this grid needs when it exceeds what is available.

    Examples
    --------
    >>> g, f, q = check_store(t.path, t.meta, t.tile_info)
    >>> g == t.grid
    True
    >>> bad = dict(t.meta, quantizer=dict(t.meta["quantizer"], mode="?"))
    >>> try:
    ...     check_store("x.geoterrain", bad, t.tile_info)
    ... except StoreError as e:
    ...     print(str(e).split(":")[1])
     invalid metadata (quantizer.mode is unknown)
    """
    try:
        g = _grid(m)
        f = _frame(m, g)
        q = _quantizer(m)
        if m.get("normal_bits") not in (8, 16):
            raise _Bad("normal_bits must be 8 or 16")
        if m.get("normals_layout", 1) not in (1, 2):
            raise _Bad("normals_layout must be 1 or 2")
        # every level's rings (written now), or level 0's (stores before)
        if "normals_derived" in m and (
                m["normals_derived"] not in ([0], list(range(g.top_level + 1)))
                or m["normal_bits"] != 8 or g.tile_samples < 3):
            raise _Bad("normals_derived must be [0] or every level, with 8-bit normals and "
                       "tiles of 3 samples or more")
        if "normals_ring_residual" in m and (m["normals_ring_residual"] is not True
                                             or "normals_derived" not in m):
            raise _Bad("normals_ring_residual must be true, and only with normals_derived")
        nv = _int(m.get("valid_samples"), 1, g.rows * g.cols, "valid_samples")
        frac = _num(m.get("nodata_fraction"), "nodata_fraction", 0.0, 1.0)
        if abs(frac - (1.0 - nv / (g.rows * g.cols))) > 1e-9:
            raise _Bad("nodata_fraction does not match valid_samples")
        hr = m.get("height_range")
        if not isinstance(hr, list) or len(hr) != 2:
            raise _Bad("height_range must be 2 numbers")
        if _num(hr[0], "height_range") > _num(hr[1], "height_range"):
            raise _Bad("height_range is inverted")
        _num(m.get("delta_max_finite"), "delta_max_finite", lo=0.0)
        if "stand_in_z" in m:
            _num(m["stand_in_z"], "stand_in_z")
        if "block_delta_levels" in m:  # the block table's levels: n = 0 … min(t, top)
            _int(m["block_delta_levels"], min(g.t, g.top_level) + 1,
                 min(g.t, g.top_level) + 1, "block_delta_levels")
        for k in ("source", "source_dtype", "encoding"):
            if not isinstance(m.get(k), str):
                raise _Bad(f"{k} must be text")
        if m.get("source_nodata") is not None and type(m["source_nodata"]) not in (int, float):
            raise _Bad("source_nodata must be a number")
        _tiles(tiles, g, f, m)
    except _Bad as exc:
        raise StoreError(f"{path}: invalid metadata ({exc}): the file is damaged or not from "
                         "geoterrain; re-run `geoterrain preprocess`") from None
    (gr, gc), have = g.shape, available_memory()
    need = _BYTES_PER_SAMPLE * gr * gc
    if need > have:
        raise StoreError(f"{path}: its {gc}×{gr} grid needs about {need / 2**30:.1f} GiB "
                         f"to mesh, {have / 2**30:.1f} GiB is available; use a machine with "
                         "more memory or preprocess a smaller DEM")
    return g, f, q
