"""`geoterrain mesh`: export a static or view-dependent LOD mesh."""

from __future__ import annotations

import json

import click
from geoterrain.cli.options import parse_size, parse_triple

FORMATS = (".ply", ".vtp", ".stl", ".obj", ".vtk")


@click.command("mesh")
@click.argument("store", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Mesh file: .ply, .vtp, .stl, .obj or .vtk.")
@click.option("--max-error", type=float,
              help="Static mesh: vertical error bound e in metres (scene units).")
@click.option("--look-from", callback=parse_triple, help="View-dependent mesh: eye X,Y,Z.")
@click.option("--look-at", callback=parse_triple, help="View-dependent mesh: target X,Y,Z.")
@click.option("--crs-coords", is_flag=True,
              help="--look-from/--look-at are source-CRS x,y and height z in metres.")
@click.option("--fov", default=30.0, show_default=True, type=click.FloatRange(0, 180, min_open=True,
              max_open=True), help="Vertical field of view, degrees.")
@click.option("--size", default="1280x720", show_default=True, callback=parse_size,
              help="Image size WxH the pixel error refers to.")
@click.option("--pixel-error", default=1.0, show_default=True,
              type=click.FloatRange(0, min_open=True), help="Screen-space tolerance τ (pixels).")
@click.option("--strategy", type=click.Choice(["rtin", "chunked", "bruteforce"]), default="rtin",
              show_default=True, help="LOD strategy for a view-dependent mesh.")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, store, output, max_error, look_from, look_at, crs_coords, fov, size,
            pixel_error, strategy, overwrite):
    """Write a mesh of STORE: static (--max-error) or for a view (--look-from/--look-at).

    A static mesh keeps every vertex whose error bound δ exceeds --max-error, so
    its vertical error is at most that everywhere. A view-dependent mesh has a
    projected error of at most --pixel-error pixels at every sample in view.

    \b
    Examples:
      geoterrain mesh dem.geoterrain -o dem.ply --max-error 1
      geoterrain mesh dem.geoterrain -o v.vtp --look-from 0,-5000,2000 --look-at 0,0,0
    """
    from pathlib import Path

    import geoterrain
    from geoterrain.exceptions import UsageError
    from geoterrain.view import View

    out = Path(output)
    if out.suffix.lower() not in FORMATS:
        raise UsageError(f"{out}: unknown mesh format; use one of {', '.join(FORMATS)}")
    if out.exists() and not overwrite:
        raise UsageError(f"{out} exists; pass --overwrite or choose another -o path")
    view_mode = look_from is not None or look_at is not None
    if view_mode and (look_from is None or look_at is None):
        raise UsageError("a view needs both --look-from and --look-at")
    if view_mode and max_error is not None:
        raise UsageError("give either --max-error (static) or a view (--look-from/--look-at)")
    if not view_mode and max_error is None:
        max_error = 1.0
    if max_error is not None and max_error < 0:
        raise UsageError(f"--max-error must be ≥ 0, got {max_error}")
    with geoterrain.open(store) as t:
        if view_mode:
            if crs_coords:
                look_from, look_at = (t.frame.crs_point_to_scene(p) for p in (look_from, look_at))
            if look_from == look_at:
                raise UsageError("--look-from and --look-at must differ")
            sel = t.select(View(look_from, look_at, fov_y_deg=fov, size=size), pixel_error,
                           strategy)
        else:
            sel = t.static_selection(max_error)
        mesh = sel.mesh
        if out.suffix.lower() in (".stl", ".obj"):
            mesh = mesh.copy()
            mesh.clear_data()
        tmp = out.with_name(f".{out.name}.partial{out.suffix}")
        try:
            mesh.save(str(tmp))
            tmp.replace(out)
        finally:
            tmp.unlink(missing_ok=True)
    if not ctx.obj["quiet"]:
        click.echo(json.dumps({k: v for k, v in sel.stats.items()}, indent=None))

