"""`geoterrain mesh`: export a static or view-dependent LOD mesh."""

from __future__ import annotations

import json
import math

import click

from geoterrain.cli.options import (
    camera_options,
    pixel_error_option,
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
@vertical_exaggeration_option
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, vertical_exaggeration, overwrite):
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
    from pathlib import Path

    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.export import MESH_FORMATS, write_mesh
    from geoterrain.formats import with_elevation

    out = Path(output)
    if out.suffix.lower() not in MESH_FORMATS:
        raise UsageError(f"{out}: unknown mesh format; use one of {', '.join(MESH_FORMATS)}")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise UsageError(f"{out.parent}: no such directory; create it first or choose another "
                         "-o path")
    if out.exists() and not overwrite:
        raise UsageError(f"{out} exists; pass --overwrite or choose another -o path")
    view_mode = look_from is not None or look_at is not None
    if view_mode and (look_from is None or look_at is None):
        raise UsageError("a view needs both --look-from and --look-at")
    if view_mode and max_error is not None:
        raise UsageError("give either --max-error (static) or a view (--look-from/--look-at)")
    if not view_mode and max_error is None:
        max_error = 1.0
    if max_error is not None and not (math.isfinite(max_error) and max_error >= 0):
        raise UsageError(f"--max-error must be a finite number ≥ 0, got {max_error}")
    from geoterrain.exaggerate import exaggerated

    with geoterrain.open(store) as base:
        t = exaggerated(base, vertical_exaggeration)
        if view_mode:
            if crs_coords:
                look_from, look_at = (t.frame.crs_point_to_scene(p) for p in (look_from, look_at))
            if look_from == look_at:
                raise UsageError("--look-from and --look-at must differ")
            sel = t.select(geoterrain.View(look_from, look_at, fov_y_deg=fov, size=size),
                           pixel_error, strategy)
        else:
            sel = t.static_selection(max_error)
        write_mesh(with_elevation(t, sel.mesh), out, overwrite=overwrite)
    if not ctx.obj["quiet"]:
        click.echo(json.dumps(sel.stats))
