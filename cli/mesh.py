"""`geoterrain mesh`: export a static or view-dependent LOD mesh."""

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
    vertical_exaggeration_option,
)


@click.command("mesh")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Mesh file: .ply, .vtp, .stl, .obj or .vtk.")
@click.option("--max-error", type=float, metavar="E",
              help="Static mesh: vertical error bound e in metres (scene units); default 1.")
@camera_options
@pixel_error_option
@strategy_option
@occlusion_option
@vertical_exaggeration_option
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, occlusion, vertical_exaggeration, overwrite):
    """Write a mesh of STORE: static (--max-error) or for a view (--look-from/--look-at).

    A static mesh keeps every vertex whose error bound δ exceeds --max-error, so
    its vertical error is at most that everywhere. A view-dependent mesh has a
    projected error of at most --pixel-error pixels at every sample in view.

    \b
    Examples:
      geoterrain mesh dem.geoterrain -o dem.ply --max-error 1
      geoterrain mesh dem.geoterrain -o v.vtp --look-from 0,-5000,2000 --look-at 0,0,0
      geoterrain mesh dem.geoterrain -o relief.ply --max-error 2 -z 3
    """

    import geoterrain
    from geoterrain.export.formats import with_elevation
    from geoterrain.export.meshfiles import check_mesh_path, write_mesh
    from geoterrain.export.meshstream import STREAM_CACHE_BYTES, STREAM_FORMATS, check_in_memory

    out = check_mesh_path(output, overwrite)  # before any work
    max_error = mesh_request(max_error, look_from, look_at)
    from geoterrain.exaggerate import exaggerated

    # a static mesh to .ply/.obj/.stl streams to disk in bounded memory
    stream = max_error is not None and out.suffix.lower() in STREAM_FORMATS
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
                              pixel_error, strategy, occlusion)
            write_mesh(with_elevation(t, sel.mesh), out, overwrite=overwrite)
            stats = sel.stats
    if not ctx.obj["quiet"]:
        click.echo(json.dumps(stats))


def _stream(ctx, t, max_error, out, overwrite) -> dict:
    from geoterrain.cli.options import StageBar
    from geoterrain.export.meshstream import write_static_mesh

    bar = StageBar("mesh", ctx.obj["quiet"])
    try:
        return write_static_mesh(t, max_error, out, overwrite=overwrite,
                                 progress=lambda d, n: bar("triangles", d, n))
    finally:
        bar.close()
