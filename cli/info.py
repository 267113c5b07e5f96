"""`geoterrain info`: what a store holds."""

from __future__ import annotations

import json

import click


@click.command("info")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print machine-readable JSON.")
@click.option("--reference/--no-reference", default=False,
              help="Also compare the size with a DEFLATE + predictor GeoTIFF of the same "
                   "heights (it decodes every full-resolution tile: seconds on a large "
                   "store; off by default, so info answers at once).")
def command(store, as_json, reference):
    """Describe STORE: size, CRS and frame, extent, grid, levels, tiles, codec and errors.

    Sizes are width × height (east-west × north-south) throughout, as gdalinfo gives
    them; --json keeps the grid as [rows, cols].

    \b
    Example:
      geoterrain info dem.geoterrain --json
    """
    import geoterrain
    from geoterrain.store.size import component_bytes, size_report

    with geoterrain.open(store) as t:
        i = t.info()
        i["size"] = size_report(t) if reference else {"components": component_bytes(t, i)}
    if as_json:
        click.echo(json.dumps(i, indent=2))
        return
    hu, vu = i["horizontal_unit"], i["vertical_unit"]
    lo, hi = i["height_range"]
    zm = i["vertical_unit_to_m"]
    in_m = f" ({lo * zm:.6g} … {hi * zm:.6g} m)" if vu != "m" else ""
    lines = [
        f"store        {i['path']} ({i['size_bytes'] / 1e6:.2f} MB, modified {i['modified']})",
        f"source       {i['source']} ({i['source_dtype']}, encoding {i['encoding']})",
        f"crs          {i['crs']}",
        f"frame        {i['frame']}; origin {i['origin_crs'][0]:.6g}, {i['origin_crs'][1]:.6g} "
        f"({hu}); heights in {vu} × {zm:g} m/{vu} × z-scale {i['z_scale']:g}",
        _extent_line(i),
        f"grid         {i['grid'][1]} × {i['grid'][0]} samples (width × height), padded to "
        f"{i['padded'][1]} × {i['padded'][0]}",
        f"tiles        {i['tile_samples']}² samples, {i['levels']} levels; stored per level "
        + ", ".join(f"L{k}:{v}" for k, v in i["tiles_per_level"].items()),
        f"heights      {lo:.6g} … {hi:.6g} {vu}{in_m}; "
        f"nodata {100 * i['nodata_fraction']:.2f} %",
        f"codec        {i['codec']} (ε in {vu}); "
        f"{i['height_bits_per_valid_sample']:.3f} bits per valid sample",
        "bytes/level  " + ", ".join(f"L{k}:{v}" for k, v in i["height_bytes_per_level"].items()),
        _size_line(i["size"]),
        f"errors       tile error {i['tile_error_range'][0]:.4g} … {i['tile_error_range'][1]:.4g}"
        f" m (scene); max vertex δ {i['vertex_error_max']:.4g} m (scene)",
    ]
    if i.get("flat_problem"):
        lines.append(f"globe        the flat scene cannot show it ({i['flat_problem']}): "
                     "draw it with render --globe or view --globe")
    if i.get("edits"):
        e = i["edits"]
        lines.append(f"edits        {e['count']} (geoterrain edit); the last: {e['last']}")
    # values come from the file: never let its control characters reach the terminal
    click.echo("\n".join("".join(c if c.isprintable() else "?" for c in ln) for ln in lines))


def _extent_line(i: dict) -> str:
    """The extent in metres on the scene's plane; a geographic store's in degrees first
    (its box, from the geotransform: a whole globe is 360° × 180°, not metres)."""
    ex = i["extent_m"]
    metres = f"{ex['x'][1] - ex['x'][0]:.1f} m × {ex['y'][1] - ex['y'][0]:.1f} m"
    if "extent_deg" not in i:
        return f"extent       {metres} (width × height, east-west × north-south)"
    (w, e), (s, n) = i["extent_deg"]["lon"], i["extent_deg"]["lat"]
    return (f"extent       {e - w:.6g}° × {n - s:.6g}° (width × height; longitude {w:.6g} … "
            f"{e:.6g}°, latitude {s:.6g} … {n:.6g}°); {metres} on the flat scene's plane")


def _size_line(s: dict) -> str:
    c = s["components"]
    total = sum(c.values())
    parts = ", ".join(f"{k} {v / 1e3:.1f} kB ({100 * v / total:.0f} %)" for k, v in c.items())
    line = f"size         {parts}"
    if "ratio" in s:
        line += (f"; {s['ratio']:.2f}× the DEFLATE+predictor GeoTIFF of the same heights "
                 f"({s['geotiff_deflate_bytes'] / 1e3:.1f} kB, {s['geotiff_dtype']})")
    else:
        line += "; --reference compares it with a DEFLATE+predictor GeoTIFF"
    return line
