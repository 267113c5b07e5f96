"""`geoterrain query`: heights (and slopes) at points, or the area and volume of a polygon."""

from __future__ import annotations

import click

from geoterrain.cli.options import NON_NEGATIVE, points_crs_options


@click.command("query")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("--at", "at", multiple=True, metavar="X,Y",
              help="A point (repeat for more), in the DEM's CRS or --crs / --lonlat.")
@click.option("--points", metavar="FILE",
              help="Points from a CSV (columns x,y or lon,lat) or a GeoJSON of points "
                   "(lon/lat, as GeoJSON is, unless --crs says otherwise).")
@points_crs_options
@click.option("--level", type=click.IntRange(0), default=0, show_default=True,
              help="Pyramid level: read heights from level L (fewer tiles) with their "
                   "guaranteed bound.")
@click.option("--slope", is_flag=True,
              help="Also the slope and aspect (degrees, as gdaldem reports them).")
@click.option("--polygon", metavar="WKT|GEOJSON|FILE",
              help="Instead of points: the planimetric and surface area and the cut/fill "
                   "volume of this polygon.")
@click.option("--base", default="0", show_default=True, metavar="H|fit|X,Y,Z;X,Y,Z;X,Y,Z",
              help="The volume's base: a height (the DEM's unit), 'fit' (the plane through "
                   "the ground along the polygon's outline) or three points of a plane.")
@click.option("--max-error", type=NON_NEGATIVE, metavar="E",
              help="Areas and volumes: read each part at the coarsest level within E (the "
                   "DEM's unit) and state the answer's bound.")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Write the answers as CSV (points) or JSON (polygon).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, at, points, crs, lonlat, level, slope, polygon, base, max_error,
            output, as_json, overwrite):
    """Ask STORE for the height at points, or the areas and volume of a polygon.

    Heights are bilinear on the DEM's own samples (what a bilinear read of the source
    gives), in its vertical unit; --level L reads a coarser level and states the bound.
    Nodata gives an empty answer. A point outside the data is an error.

    \b
    Examples:
      geoterrain query dem.geoterrain --at 139.25,35.35 --lonlat --slope
      geoterrain query dem.geoterrain --points wells.csv -o heights.csv
      geoterrain query dem.geoterrain --polygon "POLYGON ((...))" --base fit
      geoterrain query dem.geoterrain --polygon pit.geojson --base 120 --max-error 1
    """
    import json
    import math

    import numpy as np

    import geoterrain
    from geoterrain.cli.options import parse_xy, points_crs, read_points
    from geoterrain.exceptions import UsageError

    pcrs = points_crs(crs, lonlat)
    if polygon is not None and (at or points):
        raise UsageError("give either points (--at, --points) or --polygon, not both")
    if polygon is None and not at and not points:
        raise UsageError("nothing to ask: give --at X,Y, --points FILE or --polygon")
    quiet = ctx.obj["quiet"]
    with geoterrain.open(store) as t:
        if polygon is not None:
            _polygon(t, polygon, base, max_error, pcrs, output, as_json, overwrite, quiet)
            return
        xy = [parse_xy(a, "--at") for a in at]
        if points:
            pts, _, from_geojson = read_points(points)
            pcrs = pcrs or ("lonlat" if from_geojson else None)
            xy = np.concatenate([np.asarray(xy).reshape(-1, 2), pts])
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        from geoterrain.analysis import height_at, normal_at
        from geoterrain.analysis.points import inside, outside_error, to_source, turn_coords

        src = to_source(t.frame, xy, pcrs)
        out = ~inside(t.grid, *turn_coords(t.frame, src))
        if out.any():
            raise outside_error(t.frame, t.grid, xy, pcrs, out)
        h = height_at(t, xy, level, crs=pcrs)
        nrm = normal_at(t, xy, crs=pcrs) if slope else None
    from geoterrain.analysis.points import vertical_unit

    unit = vertical_unit(t)
    rows = []
    for k in range(len(xy)):
        r = {"x": float(xy[k, 0]), "y": float(xy[k, 1]),
             f"height_{unit}": None if math.isnan(h.height[k]) else float(h.height[k]),
             f"bound_{unit}": None if math.isnan(h.bound[k]) else float(h.bound[k]),
             "level": int(h.level[k])}
        if nrm is not None:
            r["slope_deg"] = None if math.isnan(nrm.slope[k]) else float(nrm.slope[k])
            r["aspect_deg"] = None if math.isnan(nrm.aspect[k]) else float(nrm.aspect[k])
        rows.append(r)
    if output:
        _write_csv(output, rows, overwrite)
    if as_json:
        click.echo(json.dumps(rows, indent=1))
    elif not output:
        cols = list(rows[0])
        click.echo("  ".join(f"{c:>14}" for c in cols))
        for r in rows:
            click.echo("  ".join(f"{_fmt(r[c]):>14}" for c in cols))
    if not quiet:
        s = h.stats
        click.echo(f"{len(rows)} points: {s['tiles_decoded']} tiles decoded, "
                   f"{s['bytes_read']} bytes read, {s['seconds'] * 1e3:.1f} ms"
                   + (f"; wrote {output}" if output else ""), err=True)


def _fmt(v) -> str:
    if v is None:
        return "nodata"
    if isinstance(v, float):
        return f"{v:.6f}" if abs(v) < 1e5 else f"{v:.3f}"
    return str(v)


def _write_csv(path, rows, overwrite) -> None:
    import csv
    import io
    from pathlib import Path

    from geoterrain.core.atomicfiles import write_atomic
    from geoterrain.core.paths import check_output

    check_output(Path(path), overwrite)  # core/paths.py: what -o may replace
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: "" if v is None else v for k, v in r.items()})
    write_atomic(path, buf.getvalue(), overwrite=overwrite)


def _polygon(t, polygon, base, max_error, pcrs, output, as_json, overwrite, quiet) -> None:
    import json
    from pathlib import Path

    from geoterrain.analysis import Plane, surface_area, volume
    from geoterrain.cli.options import read_geometry
    from geoterrain.core.atomicfiles import write_atomic
    from geoterrain.core.paths import check_output
    from geoterrain.exceptions import UsageError

    geom, from_geojson = read_geometry(polygon, "--polygon")
    pcrs = pcrs or ("lonlat" if from_geojson else None)
    b = base.strip()
    if b == "fit":
        basev = "fit"
    else:
        try:
            nums = [[float(v) for v in p.split(",")] for p in b.split(";")]
        except ValueError:
            raise UsageError(f"--base expects a height, 'fit' or X,Y,Z;X,Y,Z;X,Y,Z, got "
                             f"{base!r}") from None
        if len(nums) == 1 and len(nums[0]) == 1:
            basev = nums[0][0]
        elif len(nums) == 3 and all(len(p) == 3 for p in nums):
            basev = Plane.through(nums)
        else:
            raise UsageError(f"--base expects a height, 'fit' or three points X,Y,Z;X,Y,Z;"
                             f"X,Y,Z, got {base!r}")
    a = surface_area(t, geom, max_error=max_error, crs=pcrs)
    v = volume(t, geom, basev, max_error=max_error, crs=pcrs)
    res = {"area_2d_m2": a.area_2d, "area_3d_m2": a.area_3d, "nodata_area_m2": a.nodata_area,
           "area_3d_bound_m2": a.bound_3d, "cut_m3": v.cut, "fill_m3": v.fill,
           "net_m3": v.net, "volume_bound_m3": v.bound, "base_plane": list(v.base),
           "levels": {str(k): n for k, n in sorted(v.levels.items())},
           "tiles_decoded": a.stats["tiles_decoded"] + v.stats["tiles_decoded"],
           "seconds": a.stats["seconds"] + v.stats["seconds"]}
    if output:
        check_output(Path(output), overwrite)
        write_atomic(output, json.dumps(res, indent=1), overwrite=overwrite)
    if as_json:
        click.echo(json.dumps(res, indent=1))
        return
    pm = "" if max(a.bound_3d, v.bound) == 0 else " ± "
    click.echo(f"planimetric area  {a.area_2d:,.2f} m²"
               + (f"   (over nodata: {a.nodata_area:,.2f} m², not counted)"
                  if a.nodata_area else ""))
    click.echo(f"surface area      {a.area_3d:,.2f} m²" + (f"{pm}{a.bound_3d:,.2f}" if pm else ""))
    click.echo(f"cut (above base)  {v.cut:,.2f} m³" + (f"{pm}{v.bound:,.2f}" if pm else ""))
    click.echo(f"fill (below base) {v.fill:,.2f} m³" + (f"{pm}{v.bound:,.2f}" if pm else ""))
    click.echo(f"net (cut − fill)  {v.net:,.2f} m³")
    if not quiet:
        lv = ", ".join(f"level {k}: {n} tiles" for k, n in sorted(v.levels.items()))
        click.echo(f"{lv}; {res['tiles_decoded']} tiles decoded, "
                   f"{res['seconds'] * 1e3:.0f} ms" + (f"; wrote {output}" if output else ""),
                   err=True)
