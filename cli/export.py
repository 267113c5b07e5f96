"""`geoterrain export`: a georeferenced glTF/GLB, OBJ, PLY or printable STL of a store."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import (
    camera_options,
    mesh_request,
    occlusion_option,
    pixel_error_option,
    select_mesh,
    strategy_option,
)


@click.command("export")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="File: .glb, .gltf, .obj (+ .mtl, .png), .ply or .stl.")
@click.option("--max-error", type=float, metavar="E",
              help="Static mesh: vertical error bound in metres (scene units); default 1.")
@camera_options
@pixel_error_option
@strategy_option
@occlusion_option
@click.option("--shading", type=click.Choice(["normals", "elevation"]), default="normals",
              show_default=True, help="glTF/OBJ texture: colours × hillshade, or colours only.")
@click.option("--cmap", default="auto", show_default=True,
              help="auto (land tints, sea in blue) or a matplotlib colour map.")
@click.option("--texture-size", type=click.IntRange(2, 16385), default=4097, show_default=True,
              help="Largest texture side; a coarser pyramid level is used beyond it.")
@click.option("--drape", type=click.Path(dir_okay=False), metavar="IMAGE",
              help="glTF/OBJ texture: a georeferenced image (orthophoto GeoTIFF, RGB or one "
                   "band, any CRS) reprojected onto the DEM instead of the shading.")
@click.option("--base-height", type=float, metavar="H",
              help="STL: base thickness under the lowest point (mm with --print-size, else m).")
@click.option("--print-size", type=float, metavar="MM",
              help="STL: scale the longer side to MM millimetres.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, occlusion, shading, cmap, texture_size, drape, base_height,
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
      geoterrain export dem.geoterrain -o dem.glb --max-error 2 --drape ortho.tif
      geoterrain export dem.geoterrain -o v.glb --look-from 0,-5000,2000 --look-at 0,0,0
    """
    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.export.formats import check_export_path, export_mesh

    out = check_export_path(output, overwrite)
    if crs_coords and look_from is None and look_at is None and out.suffix.lower() != ".ply":
        raise UsageError("--crs-coords applies to --look-from/--look-at or to .ply output")
    max_error = mesh_request(max_error, look_from, look_at)
    with geoterrain.open(store) as t:
        from geoterrain.core.frame import check_flat

        check_flat(t.frame, str(store))
        sel = select_mesh(t, max_error, look_from, look_at, crs_coords, fov, size, pixel_error,
                          strategy, occlusion)
        export_mesh(t, sel, out, overwrite=overwrite, shading=shading, cmap=cmap,
                    texture_size=texture_size, drape=drape, base_height=base_height,
                    print_size=print_size,
                    crs_coords=crs_coords and out.suffix.lower() == ".ply")
    if not ctx.obj["quiet"]:
        click.echo(json.dumps({**sel.stats, "output": str(out)}))
