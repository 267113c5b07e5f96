"""`geoterrain render`: offscreen views, orbits and fly-throughs of a store."""

from __future__ import annotations

import json
from pathlib import Path

import click

from geoterrain.cli.globe import camera_option, globe_flag
from geoterrain.cli.options import (
    AZIMUTH,
    DISTANCE,
    FINITE,
    POSITIVE,
    Number,
    StageBar,
    Text,
    anti_aliasing_option,
    camera_options,
    colour_options,
    drape_options,
    light_and_drape,
    light_options,
    morph_option,
    occlusion_option,
    palette,
    pixel_error_option,
    strategy_option,
    vertical_exaggeration_option,
)

#: the options `render --globe` takes (the others are the flat scene's)
GLOBE_OPTIONS = {"out", "globe", "geo_camera", "fov", "size", "pixel_error",
                 "vertical_exaggeration", "shading", "cmap", "clim", "water_level",
                 "title", "no_overlays", "stats_path", "overwrite"}


@click.command("render")
@click.argument("stores", metavar="STORE...", nargs=-1, required=True,
                type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(),
              help="Output .png (one view), .gif or .mp4 (--orbit / --path), or a directory "
                   "of PNG frames.")
@globe_flag
@camera_option
@camera_options
@click.option("--azimuth", type=AZIMUTH,
              help="Camera bearing from the target, degrees clockwise from north "
                   "[default: 190; 180 with --elevation 90, so north is up].")
@click.option("--elevation", type=FINITE, default=40.0, show_default=True,
              help="Camera angle above the horizon, degrees in (0, 90]; 90 looks straight "
                   "down.")
@click.option("--distance", type=DISTANCE,
              help="Eye–target distance in metres (default: fit).")
@click.option("--map", "map_view", is_flag=True,
              help="A map: orthographic, north up, the whole DEM framed with a graticule "
                   "(geographic DEMs) or grid ticks in its CRS, the scale bar exact "
                   "everywhere.")
@pixel_error_option
@strategy_option
@occlusion_option
@morph_option
@anti_aliasing_option
@vertical_exaggeration_option
@click.option("--shading", type=click.Choice(["normals", "elevation", "plain"]),
              default="normals", show_default=True,
              help="normals: hillshade from full-resolution normal maps × elevation colours.")
@colour_options
@light_options
@drape_options
@click.option("--title", type=Text(200), help="Title drawn at the top.")
@click.option("--contours", "contour_interval", type=POSITIVE, metavar="DZ",
              help="Draw contour lines every DZ (the DEM's vertical unit) over the terrain, "
                   "every fifth one bolder (single views).")
@click.option("--no-overlays", is_flag=True,
              help="No colour bar, scale bar or north arrow.")
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False),
              help="Write the selection and frame stats as JSON.")
@click.option("--orbit", type=click.IntRange(1, 100_000),
              help="Render an orbit of N frames around the terrain.")
@click.option("--path", "cameras", type=click.Path(exists=True, dir_okay=False),
              help="Fly through the cameras of a JSON file.")
@click.option("--frames-between", type=click.IntRange(0, 1000), default=0, show_default=True,
              help="With --path: eased frames on a smooth spline between each pair of cameras.")
@click.option("--fps", type=Number(0, 1000, lo_open=True), default=10.0, show_default=True,
              help="Animation speed, frames per second in (0, 1000].")
@click.option("--strips", is_flag=True,
              help="Draw the mesh as triangle strips instead of triangle lists (the same "
                   "picture; no faster on the CPU renderer, docs/benchmarks.md).")
@click.option("--overwrite", is_flag=True, help="Replace the output if it exists.")
@click.pass_context
def command(ctx, stores, out, globe, geo_camera, look_from, look_at, crs_coords, azimuth,
            elevation, distance, map_view, size,
            fov, pixel_error, strategy, occlusion, morph, anti_aliasing, vertical_exaggeration,
            shading, cmap, clim, water_level, water,
            sun, hillshade, shadows, ambient_occlusion, drape_path, drape_opacity, title,
            contour_interval, no_overlays, stats_path, orbit, cameras, frames_between, fps,
            strips, overwrite):
    """Render STORE offscreen: each frame selects its own level of detail.

    \b
    Examples:
      geoterrain render dem.geoterrain -o view.png
      geoterrain render dem.geoterrain -o view.png --azimuth 135 --elevation 25 --title Fuji
      geoterrain render dem.geoterrain -o view.png --look-from 0,-5000,3000 --look-at 0,0,500
      geoterrain render dem.geoterrain -o view.png --crs-coords \\
          --look-from 500000,4990000,3000 --look-at 505000,5000000,800
      geoterrain render dem.geoterrain -o top.png --elevation 90
      geoterrain render dem.geoterrain -o map.png --map --title "Sagami Bay"
      geoterrain render dem.geoterrain -o relief.png -z 3
      geoterrain render dem.geoterrain -o flood.png --water-level 40 --clim 0,1200
      geoterrain render dem.geoterrain -o dusk.png --sun 250,15 --shadows --ambient-occlusion
      geoterrain render dem.geoterrain -o lines.png --contours 50
      geoterrain render dem.geoterrain -o orbit.gif --orbit 36 --size 640x360
      geoterrain render dem.geoterrain -o fly.mp4 --path cameras.json --stats fly.json
      geoterrain render --globe world.geoterrain japan.geoterrain -o earth.png
      geoterrain render --globe japan.geoterrain -o sagami.png --camera 139.1,35.12,6000,35,-12

    \b
    A cameras JSON is a list of {"look_from": [x,y,z], "look_at": [x,y,z]} (scene
    metres), or {"crs": true, "cameras": [...]} for source-CRS coordinates.

    With --globe, the STOREs (any number: a whole-globe raster, a continent, a pole, a
    regional DEM) are drawn on the WGS 84 globe, seen from --camera (default: all of
    them framed from above); a camera under the ground is warned about.
    """
    import geoterrain
    import geoterrain.rendering.animation as A
    import geoterrain.rendering.scene as R
    from geoterrain.core.paths import check_output, same_file
    from geoterrain.core.view import View
    from geoterrain.exceptions import UsageError
    from geoterrain.rendering.cameras import check_elevation

    quiet = (ctx.obj or {}).get("quiet", False)
    if globe:
        from geoterrain.cli import globe as G

        G.refuse_options(ctx, GLOBE_OPTIONS, "render --globe")
        return G.render(ctx, stores, out, geo_camera, size, fov, pixel_error,
                        vertical_exaggeration, shading, palette(cmap, clim, water_level),
                        title, not no_overlays, stats_path, overwrite)
    if geo_camera is not None:
        raise UsageError("--camera LON,LAT,HEIGHT places the camera on the globe: add "
                         "--globe (the flat scene takes --look-from/--look-at)")
    if len(stores) > 1:
        raise UsageError(f"the flat scene draws one store, got {len(stores)}; draw several "
                         "on one globe with --globe")
    store = stores[0]
    try:
        check_elevation(elevation)
    except UsageError:
        raise UsageError(f"--elevation must be in (0, 90] degrees above the horizon (90: "
                         f"straight down), got {elevation:g}; to look from below, give "
                         "--look-from and --look-at") from None
    if azimuth is None:
        azimuth = 180.0 if elevation == 90 else 190.0
    cmap = palette(cmap, clim, water_level)
    lit, dr = light_and_drape(shading, sun, hillshade, shadows, ambient_occlusion,
                              drape_path, drape_opacity)
    if frames_between and cameras is None:
        raise UsageError("--frames-between goes with --path")
    if (look_from is None) != (look_at is None):
        raise UsageError("give both --look-from and --look-at, or neither")
    if orbit is not None and cameras is not None:
        raise UsageError("give --orbit or --path, not both")
    if orbit is not None and orbit < 1:
        raise UsageError(f"--orbit needs at least 1 frame, got {orbit}")
    ext = Path(out).suffix.lower()
    animated = orbit is not None or cameras is not None
    if contour_interval is not None and animated:
        raise UsageError("--contours draws on a single view (.png), not an animation")
    if map_view:
        src = ctx.get_parameter_source
        clash = [n for n, given in (("--look-from/--look-at", look_from is not None),
                                    ("--orbit", orbit is not None),
                                    ("--path", cameras is not None),
                                    ("--distance", distance is not None),
                                    ("--elevation", src("elevation").name == "COMMANDLINE"),
                                    ("--azimuth", src("azimuth").name == "COMMANDLINE"))
                 if given]
        if clash:
            raise UsageError(f"--map frames the whole DEM from straight above, north up; "
                             f"drop {', '.join(clash)}")
    if not animated and ext != ".png":
        raise UsageError(f"{out}: a single view is written as .png (use --orbit or --path "
                         "for .gif/.mp4)")
    overlays = dict(colorbar=not no_overlays, north_arrow=not no_overlays)
    inputs = [store, drape_path, cameras]
    if animated:
        overlays["scale_bar"] = not no_overlays
        A.check_animation_output(out, fps, overwrite)  # a bad target or --fps fails now
        check_output(out, True, folder=Path(out).suffix.lower() not in A.ANIMATION_SUFFIXES,
                     inputs=inputs)  # not one of the inputs
    else:
        check_output(out, overwrite, inputs=inputs)
    if stats_path is not None:  # --stats follows the --overwrite rule too
        check_output(stats_path, overwrite, inputs=inputs, option="--stats")
        if same_file(stats_path, out) or Path(stats_path).absolute() == Path(out).absolute():
            raise UsageError("--stats and -o name the same file; choose another --stats path")
    from geoterrain.exaggerate import exaggerated

    with geoterrain.open(store) as base:
        from geoterrain.core.frame import check_flat

        check_flat(base.frame, str(store))
        t = exaggerated(base, vertical_exaggeration)
        if animated:
            bar = StageBar("rendering", quiet)
            kw = dict(pixel_error=pixel_error, strategy=strategy, shading=shading, cmap=cmap,
                      title=title, fps=fps, progress=lambda d, n: bar("frame", d, n),
                      overwrite=overwrite, light=lit, drape=dr, occlusion=occlusion,
                      morph=morph, anti_aliasing=anti_aliasing, water=water, **overlays)
            try:
                if orbit is not None:
                    frames = A.orbit(t, out, orbit, size=size, azimuth=azimuth,
                                     elevation=elevation, distance=distance, fov_y_deg=fov, **kw)
                else:
                    frames = A.flythrough(t, cameras, out, size=size, fov_y_deg=fov,
                                          frames_between=frames_between, **kw)
            finally:
                bar.close()
            if stats_path:
                from geoterrain.core.atomicfiles import write_atomic

                write_atomic(stats_path, json.dumps(frames, indent=2, default=float),
                             overwrite)
            if not quiet:
                ms = sorted(f["frame_ms"] for f in frames)
                click.echo(f"wrote {out}: {len(frames)} frames, median frame "
                           f"{ms[len(ms) // 2]:.0f} ms", err=True)
            return
        if look_from is not None:
            a, b = look_from, look_at
            if crs_coords:
                a, b = tuple(R.to_scene(t, a)), tuple(R.to_scene(t, b))
            try:
                view = View(a, b, fov_y_deg=fov, size=size)
                view.basis()
            except ValueError as exc:
                raise UsageError(f"bad camera: {exc}") from None
        elif map_view:
            from geoterrain.rendering.mapview import map_view as make_map

            view = make_map(t, size, shading=shading, cmap=cmap, title=title,
                            colorbar=not no_overlays, scale_bar=not no_overlays,
                            north_arrow=not no_overlays)
        else:
            view = R.overview(t, size, azimuth, elevation, distance, fov, shading=shading,
                              cmap=cmap, title=title, colorbar=not no_overlays,
                              scale_bar=not no_overlays, north_arrow=not no_overlays)
        lines = widths = None
        if contour_interval is not None:
            from geoterrain.analysis.contours import contours, scene_lines

            lines, widths = scene_lines(base, contours(base, contour_interval))
            lines = [p * (1.0, 1.0, vertical_exaggeration) for p in lines]
        st = R.render(t, view, out, pixel_error=pixel_error, strategy=strategy,
                      shading=shading, cmap=cmap, title=title, scale_bar=not no_overlays,
                      stats_path=stats_path, overwrite=overwrite, light=lit, drape=dr,
                      occlusion=occlusion, morph=morph, anti_aliasing=anti_aliasing,
                      strips=strips, lines=lines, line_widths=widths, water=water,
                      **overlays)
    if not quiet:
        click.echo(f"wrote {out}: {st['triangles']:,} triangles ({strategy}, τ = "
                   f"{pixel_error:g} px), select {st['select_ms']:.0f} ms, frame "
                   f"{st['frame_ms']:.0f} ms", err=True)
