"""`geoterrain export`: a georeferenced glTF/GLB, OBJ, PLY or printable STL of a store."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import (
    NON_NEGATIVE,
    Number,
    camera_options,
    check_mesher,
    human_bytes,
    mesh_request,
    mesh_words,
    mesher_option,
    occlusion_option,
    parse_bytes,
    pixel_error_option,
    select_mesh,
    strategy_option,
    vertical_exaggeration_option,
)

LARGE = 20e6  # bytes: an export estimated larger than this is announced before it is written


@click.command("export")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="File: .glb, .gltf, .obj (+ .mtl, .png), .ply or .stl.")
@click.option("--max-error", type=NON_NEGATIVE, metavar="E",
              help="Whole-terrain mesh: largest height error in metres; default 1. A larger "
                   "E makes a smaller file.")
@mesher_option
@camera_options
@pixel_error_option
@strategy_option
@occlusion_option
@vertical_exaggeration_option
@click.option("--shading", type=click.Choice(["normals", "elevation"]), default="normals",
              show_default=True, help="glTF/OBJ texture: colours × hillshade, or colours only.")
@click.option("--cmap", default="auto", show_default=True,
              help="auto (land tints, sea in blue) or a matplotlib colour map.")
@click.option("--texture-size", type=click.IntRange(2, 16385), default=4097, show_default=True,
              help="Largest texture side; a coarser pyramid level is used beyond it.")
@click.option("--drape", type=click.Path(dir_okay=False), metavar="IMAGE",
              help="glTF/OBJ texture: a georeferenced image (orthophoto GeoTIFF, RGB or one "
                   "band, any CRS) reprojected onto the DEM instead of the shading.")
@click.option("--base-height", type=Number(0, 1e6), metavar="H",
              help="A closed solid for printing or viewing, on every format: walls and a "
                   "flat base H thick under the lowest point (mm with --print-size, else m).")
@click.option("--print-size", type=Number(0, 1e6, lo_open=True), metavar="MM",
              help="A closed solid scaled so its longer side is MM millimetres (glTF: "
                   "MM/1000 metres, as glTF's unit is the metre); base 3 mm by default.")
@click.option("--preview", type=click.Path(dir_okay=False), metavar="PNG",
              help="Also draw the model (with its walls and base, for a solid) from the "
                   "south-west into a PNG picture.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the summary as JSON (for scripts).")
@click.option("--memory-limit", callback=parse_bytes, metavar="SIZE",
              help="Memory the export may use, e.g. 2G (default: half of what is available). "
                   "A whole-terrain mesh whose estimated export passes it is refused before "
                   "any work, with the estimate.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, mesher, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, occlusion, vertical_exaggeration, shading, cmap, texture_size,
            drape, base_height, print_size, preview, as_json, memory_limit, overwrite):
    """Export STORE's mesh for other tools: the whole terrain (--max-error) or what a
    camera sees (--look-from/--look-at).

    \b
    .glb/.gltf  positions in metres from the DEM centre (Y up), normals, an
                _ELEVATION attribute, the shading texture embedded; origin and
                CRS in asset.extras.geoterrain and in OUTPUT.json
    .obj        with OUTPUT.mtl and OUTPUT.png (the texture) and OUTPUT.json
    .ply        CRS and offset in header comments, an elevation property;
                --crs-coords for float64 source-CRS coordinates
    .stl        a closed, printable solid: walls and a base (--base-height),
                --print-size MM scales it for a printer

    --base-height or --print-size closes a .glb, .gltf, .obj or .ply into the same
    solid (its walls and bottom in a plain colour). -z N exaggerates the heights, as
    in `geoterrain render`. Textures cover the DEM's data only. An export estimated
    above 20 MB is announced with its size before it is written.

    The camera options are those of `geoterrain mesh`. --crs-coords means
    "in source-CRS coordinates" for both --look-from/--look-at and, with .ply,
    the vertices written.

    \b
    Examples:
      geoterrain export dem.geoterrain -o dem.glb --max-error 2
      geoterrain export dem.geoterrain -o dem.ply --max-error 1 --crs-coords
      geoterrain export dem.geoterrain -o dem.stl --max-error 5 --print-size 150 -z 3
      geoterrain export dem.geoterrain -o model.glb --max-error 5 --print-size 150 -z 2 \\
          --preview model.png
      geoterrain export dem.geoterrain -o dem.glb --max-error 2 --drape ortho.tif
      geoterrain export dem.geoterrain -o v.glb --look-from 0,-5000,2000 --look-at 0,0,0
    """
    import geoterrain
    from geoterrain.core.memory import available_memory
    from geoterrain.exaggerate import exaggerated
    from geoterrain.exceptions import UsageError
    from geoterrain.export.formats import (
        check_export_memory,
        check_export_path,
        data_shape,
        estimate_bytes,
        export_mesh,
        export_texture_level,
    )

    out = check_export_path(output, overwrite, inputs=[store, drape])  # and its sidecars
    ext = out.suffix.lower()
    if preview is not None:
        from pathlib import Path

        from geoterrain.export.meshfiles import check_output_path

        check_output_path(preview, (".png",), overwrite, "preview", [store, drape])
        if Path(preview).resolve() == out.with_suffix(".png").resolve() and ext == ".obj":
            raise UsageError(f"--preview {preview} is the OBJ's own texture; choose another "
                             "name")
    if crs_coords and look_from is None and look_at is None and ext != ".ply":
        raise UsageError("--crs-coords applies to --look-from/--look-at or to .ply output")
    max_error = mesh_request(max_error, look_from, look_at)
    check_mesher(mesher, max_error)
    quiet = ctx.obj["quiet"]
    closed = ext == ".stl" or base_height is not None or print_size is not None
    with geoterrain.open(store) as base:
        from geoterrain.core.frame import check_flat

        check_flat(base.frame, str(store))
        t = exaggerated(base, vertical_exaggeration)
        if max_error is not None:  # bounded: refused before the mesh is built
            check_export_memory(t, max_error, memory_limit or available_memory() // 2)
        sel = select_mesh(t, max_error, look_from, look_at, crs_coords, fov, size, pixel_error,
                          strategy, occlusion, mesher)
        texels = 0
        if ext in (".glb", ".gltf", ".obj"):
            h, w = data_shape(t, export_texture_level(t, texture_size))
            texels = h * w
        guess = estimate_bytes(sel, ext, texels=texels, closed=closed)
        if guess > LARGE and not quiet and not as_json:
            hint = (" (a larger --max-error makes it smaller)" if max_error is not None
                    else " (a larger --pixel-error makes it smaller)")
            click.echo(f"writing about {human_bytes(guess)}: {sel.stats['triangles']:,} "
                       f"triangles{hint}", err=True)
        info: dict = {}
        export_mesh(t, sel, out, overwrite=overwrite, shading=shading, cmap=cmap,
                    texture_size=texture_size, drape=drape, base_height=base_height,
                    print_size=print_size, stats=info,
                    crs_coords=crs_coords and ext == ".ply")
        if preview is not None:
            from geoterrain.export.preview import write_preview

            write_preview(t, sel, preview, overwrite=overwrite, base_height=base_height,
                          print_size=print_size, shading=shading, cmap=cmap,
                          texture_size=texture_size, drape=drape)
            info["preview"] = str(preview)
    summary = {**sel.stats, **info, "output": str(out),
               "vertical_exaggeration": float(vertical_exaggeration)}
    if as_json:
        click.echo(json.dumps(summary, default=float))
    elif not quiet:
        click.echo(export_words(summary))


def export_words(s: dict) -> str:
    """The human summary of an export's ``s`` (its stats, the files, the solid)."""
    from pathlib import Path

    more = [Path(f).name for f in s["files"][1:]]
    lines = [f"wrote {s['output']}" + (f" and {', '.join(more)}" if more else "")
             + f" ({human_bytes(s['bytes'])}{' in all' if more else ''})",
             "  " + mesh_words(s)]
    if s.get("texture"):
        lines.append(f"  texture {s['texture'][0]} × {s['texture'][1]} texels "
                     f"(pyramid level {s['texture_level']})")
    if s.get("solid"):
        x, y, z = s["solid"]["size"]
        u = s["solid"]["units"]
        lines.append(f"  solid {x:.4g} × {y:.4g} × {z:.4g} {u} (x × y × height), base "
                     f"{s['solid']['base_height']:.4g} {u}")
    if s.get("preview"):
        lines.append(f"  preview {s['preview']}")
    if s.get("vertical_exaggeration", 1.0) != 1.0:
        lines.append(f"  heights × {s['vertical_exaggeration']:g} (vertical exaggeration)")
    return "\n".join(lines)
