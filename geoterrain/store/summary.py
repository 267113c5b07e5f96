"""``geoterrain info``'s summary of a store: its extent, units, grid, tiles per level,
codec, bytes per component and kind, errors and edit log, in one dict
(:meth:`geoterrain.terrain.Terrain.info`; the CLI prints it, :mod:`geoterrain.store.size`
adds the bytes against a GeoTIFF).
"""

from __future__ import annotations

import os
from datetime import UTC, datetime
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.codec.quantizer import describe_codec

if TYPE_CHECKING:
    from geoterrain.core.frame import Frame
    from geoterrain.terrainlike import TerrainLike

__all__ = ["edits_summary", "extent_deg", "store_summary", "unit_name"]


def store_summary(t: TerrainLike, sizes: dict[tuple[str, int], int]) -> dict:
    """``geoterrain info``'s summary of a store (:meth:`geoterrain.terrain.Terrain.info`):
    size, CRS and frame, extent, grid, levels, tiles, nodata, codec, errors; ``sizes`` its
    blob bytes per (kind, level)
    (:meth:`geoterrain.store.reader.StoreReader.blob_bytes_by_kind_level`).

    Examples
    --------
    >>> s = store_summary(t, t.reader.blob_bytes_by_kind_level())
    >>> s["grid"], s["levels"], s == {**t.info(), "modified": s["modified"]}
    ([129, 129], 3, True)
    """
    m, g, f = t.meta, t.grid, t.frame
    H, W = g.rows, g.cols
    # the extent over the whole boundary, not 4 corners (a geographic grid's edges bow)
    k = np.linspace(0.0, 1.0, 129)
    ei = np.concatenate([0 * k, 0 * k + H - 1, k * (H - 1), k * (H - 1)]).round()
    ej = np.concatenate([k * (W - 1), k * (W - 1), 0 * k, 0 * k + W - 1]).round()
    cx, cy = f.xy(ei.astype(np.int64), ej.astype(np.int64))
    per_level: dict[int, int] = {}
    for (L, _, _) in t.tile_info:
        per_level[L] = per_level.get(L, 0) + 1
    sizes = sizes
    hbytes = {L: sizes.get(("heights", L), 0) for L in g.levels}
    errs = [r["error"] for r in t.tile_info.values()
            if r["error"] is not None and np.isfinite(r["error"])]
    return {
        "path": str(t.path),
        "size_bytes": os.path.getsize(t.path),
        "source": m["source"],
        "source_dtype": m["source_dtype"],
        "encoding": m["encoding"],
        "crs": f.crs_name,
        "frame": f.kind,
        "horizontal_unit_to_m": f.unit_to_m,
        "vertical_unit_to_m": f.z_to_m,
        "horizontal_unit": unit_name(f.unit_to_m) if f.kind == "projected" else
        ("degrees" if f.kind == "geographic" else "pixels"),
        "vertical_unit": unit_name(f.z_to_m),
        "z_scale": f.z_scale,
        "origin_crs": list(f.origin_crs),
        "extent_m": {"x": [float(cx.min()), float(cx.max())],
                     "y": [float(cy.min()), float(cy.max())]},
        **(extent_deg(f) if f.kind == "geographic" else {}),
        "grid": [H, W],
        "padded": list(g.shape),
        "tile_samples": g.tile_samples,
        "levels": g.top_level + 1,
        "tiles_per_level": {str(k): per_level[k] for k in sorted(per_level)},
        "nodata_fraction": m["nodata_fraction"],
        "height_range": m["height_range"],
        "codec": describe_codec(t.quantizer),
        "codec_error": t.quantizer.codec_error,
        "height_bytes_per_level": {str(k): v for k, v in hbytes.items()},
        "height_bits_per_valid_sample": 8 * sum(hbytes.values()) / max(1, m["valid_samples"]),
        "bytes_by_kind": {k: sum(v for (kk, _), v in sizes.items() if kk == k)
                          for k in sorted({k for k, _ in sizes})},
        "tile_error_range": [min(errs, default=0.0), max(errs, default=0.0)],
        "vertex_error_max": m["delta_max_finite"],
        # the file's own clock (the store holds none: two runs write the same bytes)
        "modified": datetime.fromtimestamp(os.stat(t.path).st_mtime, UTC)
        .isoformat(timespec="seconds"),
        "edits": edits_summary(m.get("edits")),
    }


def edits_summary(log: object) -> dict | None:
    """The metadata's edit log in a line's worth: how many edits, and the last one's
    mode, source and window (None: never edited)."""
    if not isinstance(log, dict) or not log.get("last"):
        return None
    e = log["last"][-1]
    try:
        r, c, h, w = (int(v) for v in e["window"])
        when = f"{e['time']} " if "time" in e else ""  # stores edited before it was dropped
        last = (f"{when}{e['mode']} of {e['source']}, rows {r} … {r + h - 1}, "
                f"columns {c} … {c + w - 1}")
    except (KeyError, TypeError, ValueError):
        last = "?"
    return {"count": int(log.get("count", 0)), "last": last}


def unit_name(factor: float) -> str:
    """'m', 'ft' or 'us-ft' for a metres-per-unit factor, else 'units of N m'."""
    from geoterrain.ingest.units import unit_of_factor

    u = unit_of_factor(factor)
    return u if u is not None else f"units of {factor:.6g} m"


def extent_deg(f: Frame) -> dict:
    """A geographic frame's box in degrees (its pixels' outer edges, from the geotransform)
    and why the flat scene cannot show it (:meth:`Frame.flat_problem`; None when it can)."""
    a, _, c, _, e, ff = f.transform[:6]
    lon, lat = sorted((c, c + a * f.cols)), sorted((ff, ff + e * f.rows))
    return {"extent_deg": {"lon": [float(v) for v in lon], "lat": [float(v) for v in lat]},
            "flat_problem": f.flat_problem()}
