"""`geoterrain mesh`: export a static or view-dependent LOD mesh."""

from __future__ import annotations

import json

import click

from geoterrain.cli.options import (
    NON_NEGATIVE,
    camera_options,
    check_mesher,
    mesh_request,
    mesher_option,
    occlusion_option,
    pixel_error_option,
    select_mesh,
    strategy_option,
    vertical_exaggeration_option,
)


@click.command("mesh")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Mesh file: .ply, .vtp, .stl, .obj or .vtk.")
@click.option("--max-error", type=NON_NEGATIVE, metavar="E",
              help="Whole-terrain mesh: largest height error in metres; default 1.")
@camera_options
@mesher_option
@pixel_error_option
@strategy_option
@occlusion_option
@vertical_exaggeration_option
@click.option("--json", "as_json", is_flag=True,
              help="Print the summary as JSON (for scripts).")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, mesher, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, occlusion, vertical_exaggeration, as_json, overwrite):
    """Write a mesh of STORE: the whole terrain (--max-error) or what a camera sees
    (--look-from/--look-at).

    The whole-terrain mesh is within --max-error metres of the DEM's height
    everywhere. A camera's mesh is detailed near the camera and coarse far away,
    never more than --pixel-error pixels from the full-resolution terrain on screen.
    The summary says what was written; --json prints it for scripts.

    \b
    Examples:
      geoterrain mesh dem.geoterrain -o dem.ply --max-error 1
      geoterrain mesh dem.geoterrain -o tin.ply --max-error 1 --mesher tin
      geoterrain mesh dem.geoterrain -o v.vtp --look-from 0,-5000,2000 --look-at 0,0,0
      geoterrain mesh dem.geoterrain -o relief.ply --max-error 2 -z 3
    """

    import geoterrain
    from geoterrain.export.meshdata import with_elevation
    from geoterrain.export.meshfiles import check_mesh_path, write_mesh
    from geoterrain.export.meshstream import STREAM_CACHE_BYTES, STREAM_FORMATS, check_in_memory

    out = check_mesh_path(output, overwrite, inputs=[store])  # before any work
    max_error = mesh_request(max_error, look_from, look_at)
    check_mesher(mesher, max_error)
    from geoterrain.exaggerate import exaggerated

    # rtin's static mesh to .ply/.obj/.stl streams to disk in bounded memory (the TIN's
    # refinement is global: it is made in memory)
    stream = (max_error is not None and out.suffix.lower() in STREAM_FORMATS
              and mesher == "rtin")
    with geoterrain.open(store, **({"cache_bytes": STREAM_CACHE_BYTES} if stream else {})
                         ) as base:
        from geoterrain.core.frame import check_flat

        check_flat(base.frame, str(store))
        t = exaggerated(base, vertical_exaggeration)
        if stream:
            stats = _stream(ctx, t, max_error, out, overwrite)
        else:
            if max_error is not None:
                check_in_memory(t, max_error, out)
            sel = select_mesh(t, max_error, look_from, look_at, crs_coords, fov, size,
                              pixel_error, strategy, occlusion, mesher)
            write_mesh(with_elevation(t, sel.mesh), out, overwrite=overwrite)
            stats = sel.stats
    if as_json:
        click.echo(json.dumps({**stats, "output": str(out)}, default=float))
    elif not ctx.obj["quiet"]:
        from geoterrain.cli.options import human_bytes, mesh_words

        click.echo(f"wrote {out} ({human_bytes(out.stat().st_size)})\n  {mesh_words(stats)}")


def _stream(ctx, t, max_error, out, overwrite) -> dict:
    from geoterrain.cli.options import StageBar
    from geoterrain.export.meshstream import write_static_mesh

    bar = StageBar("mesh", ctx.obj["quiet"])
    try:
        return write_static_mesh(t, max_error, out, overwrite=overwrite,
                                 progress=lambda d, n: bar("triangles", d, n))
    finally:
        bar.close()
