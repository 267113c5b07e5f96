"""`geoterrain export`: a georeferenced glTF/GLB, OBJ, PLY or printable STL of a store."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import camera_options, pixel_error_option, strategy_option


@click.command("export")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="File: .glb, .gltf, .obj (+ .mtl, .png), .ply or .stl.")
@click.option("--max-error", type=float, metavar="E",
              help="Static mesh: vertical error bound in metres (scene units); default 1.")
@camera_options
@pixel_error_option
@strategy_option
@click.option("--shading", type=click.Choice(["normals", "elevation"]), default="normals",
              show_default=True, help="glTF/OBJ texture: colours × hillshade, or colours only.")
@click.option("--cmap", default="gist_earth", show_default=True, help="Matplotlib colour map.")
@click.option("--texture-size", type=click.IntRange(2, 16385), default=4097, show_default=True,
              help="Largest texture side; a coarser pyramid level is used beyond it.")
@click.option("--base-height", type=float, metavar="H",
              help="STL: base thickness under the lowest point (mm with --print-size, else m).")
@click.option("--print-size", type=float, metavar="MM",
              help="STL: scale the longer side to MM millimetres.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, shading, cmap, texture_size, base_height,
            print_size, overwrite):
    """Export STORE's mesh for other tools: static (--max-error) or for a view.

    \b
    .glb/.gltf  positions in metres from the DEM centre (Y up), normals, an
                _ELEVATION attribute, the shading texture embedded; origin and
                CRS in asset.extras.geoterrain and in OUTPUT.json
    .obj        with OUTPUT.mtl and OUTPUT.png (the texture) and OUTPUT.json
    .ply        CRS and offset in header comments, an elevation property;
                --crs-coords for float64 source-CRS coordinates
    .stl        a closed, printable solid: walls and a base (--base-height),
                --print-size MM scales it for a printer

    The camera options are those of `geoterrain mesh`. --crs-coords means
    "in source-CRS coordinates" for both --look-from/--look-at and, with .ply,
    the vertices written.

    \b
    Examples:
      geoterrain export dem.geoterrain -o dem.glb --max-error 2
      geoterrain export dem.geoterrain -o dem.ply --max-error 1 --crs-coords
      geoterrain export dem.geoterrain -o dem.stl --max-error 5 --print-size 150
      geoterrain export dem.geoterrain -o v.glb --look-from 0,-5000,2000 --look-at 0,0,0
    """
    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.formats import check_export_path, export_mesh

    out = check_export_path(output, overwrite)
    if crs_coords and look_from is None and look_at is None and out.suffix.lower() != ".ply":
        raise UsageError("--crs-coords applies to --look-from/--look-at or to .ply output")
    view_mode = look_from is not None or look_at is not None
    if view_mode and (look_from is None or look_at is None):
        raise UsageError("a view needs both --look-from and --look-at")
    if view_mode and max_error is not None:
        raise UsageError("give either --max-error (static) or a view (--look-from/--look-at)")
    if not view_mode and max_error is None:
        max_error = 1.0
    if max_error is not None and not max_error >= 0:
        raise UsageError(f"--max-error must be ≥ 0, got {max_error}")
    with geoterrain.open(store) as t:
        if view_mode:
            if crs_coords:
                look_from, look_at = (t.frame.crs_point_to_scene(p) for p in (look_from, look_at))
            if look_from == look_at:
                raise UsageError("--look-from and --look-at must differ")
            sel = t.select(geoterrain.View(look_from, look_at, fov_y_deg=fov, size=size),
                           pixel_error, strategy)
        else:
            sel = t.static_selection(max_error)
        export_mesh(t, sel, out, overwrite=overwrite, shading=shading, cmap=cmap,
                    texture_size=texture_size, base_height=base_height, print_size=print_size,
                    crs_coords=crs_coords and out.suffix.lower() == ".ply")
    if not ctx.obj["quiet"]:
        click.echo(json.dumps({**sel.stats, "output": str(out)}))
