"""`render --globe` and `view --globe`: stores drawn on the WGS 84 globe from the command line.

The geodetic camera option (``--camera LON,LAT,HEIGHT[,HEADING[,PITCH]]``), opening any
number of stores on one :class:`~geoterrain.globe.Globe`, the camera's framing and the
underground warning; `render` and `view` call :func:`render` and :func:`view` when given
``--globe``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from geoterrain.cli.options import Number, StageBar, _number

#: what ``--camera`` holds: (lon, lat, height, heading, pitch)
CAMERA_HELP = ("--globe: the camera LON,LAT,HEIGHT[,HEADING[,PITCH]]: degrees, metres above "
               "the WGS 84 ellipsoid, the look direction in degrees clockwise from north "
               "[default 0] and above the horizontal [default −90: straight down] "
               "(default: all the stores framed from above).")


class GeoCamera(click.ParamType):
    """``LON,LAT,HEIGHT[,HEADING[,PITCH]]``: longitude in [−180, 360], latitude in
    [−90, 90], height above the ellipsoid in [−11 000, 10^9] m, heading in [−360, 360],
    pitch in [−90, 90] degrees; as a 5-tuple (heading 0, pitch −90 when left out).

    Examples
    --------
    >>> GEO_CAMERA.convert("139.25,35.35,20e6", None, None)
    (139.25, 35.35, 20000000.0, 0.0, -90.0)
    >>> GEO_CAMERA.convert("139.25,35.35,2000,300,-10", None, None)
    (139.25, 35.35, 2000.0, 300.0, -10.0)
    """

    name = "camera"
    LIMITS = (("longitude", -180.0, 360.0), ("latitude", -90.0, 90.0),
              ("height", -11_000.0, 1e9), ("heading", -360.0, 360.0),
              ("pitch", -90.0, 90.0))

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            parts = [_number(v) for v in str(value).split(",")]
        except ValueError:
            self.fail(f"expected LON,LAT,HEIGHT[,HEADING[,PITCH]] numbers, got {value!r}",
                      param, ctx)
        if not 3 <= len(parts) <= 5:
            self.fail(f"expected 3 to 5 numbers LON,LAT,HEIGHT[,HEADING[,PITCH]], got "
                      f"{value!r}", param, ctx)
        for v, (what, lo, hi) in zip(parts, self.LIMITS, strict=False):
            if not (math.isfinite(v) and lo <= v <= hi):
                unit = "metres" if what == "height" else "degrees"
                self.fail(f"the camera's {what} must be in [{lo:g}, {hi:g}] {unit}, got {v:g}",
                          param, ctx)
        parts += [0.0, -90.0][len(parts) - 3:]
        return tuple(parts)


GEO_CAMERA = GeoCamera()

globe_flag = click.option(
    "--globe", is_flag=True,
    help="Draw the stores (any number) on the WGS 84 globe, the detail following the camera "
         "over the whole planet: whole-globe, continental and polar DEMs, and several stores "
         "at once.")
camera_option = click.option("--camera", "geo_camera", type=GEO_CAMERA,
                             metavar="LON,LAT,HEIGHT[,HEADING[,PITCH]]", help=CAMERA_HELP)


def refuse_options(ctx: click.Context, allowed: set[str], what: str) -> None:
    """A one-line usage error naming the options given on the command line that ``what``
    does not take (any parameter not in ``allowed``)."""
    from geoterrain.exceptions import UsageError

    given = [p for p in ctx.command.params
             if p.name not in allowed and isinstance(p, click.Option)
             and ctx.get_parameter_source(p.name) is click.core.ParameterSource.COMMANDLINE]
    if given:
        names = ", ".join(max(p.opts, key=len) for p in given)
        raise UsageError(f"{what} does not take {names}; drop "
                         f"{'it' if len(given) == 1 else 'them'}")


def check_stores(stores: tuple[str, ...]) -> None:
    """Every path is an existing ``.geoterrain`` store (one line otherwise)."""
    from geoterrain.core.paths import input_problem
    from geoterrain.exceptions import UsageError
    from geoterrain.store.schema import is_store

    if not stores:
        raise UsageError("give at least one store (.geoterrain) to draw on the globe")
    for s in stores:
        if (why := input_problem(s)) is not None:
            raise UsageError(f"{s}: {why}; give a .geoterrain store")
        if not is_store(Path(s)):
            raise UsageError(f"{s}: not a geoterrain store; make one first: geoterrain "
                             f"preprocess {s} -o {Path(s).with_suffix('.geoterrain').name}")


def open_globe(stores: tuple[str, ...], vertical_exaggeration: float, quiet: bool,
               sync: bool = True):
    """A :class:`~geoterrain.globe.Globe` of ``stores`` (WGS 84), its node errors measured
    behind a progress bar."""
    from geoterrain.globe import Globe

    check_stores(stores)
    bar = StageBar("globe", quiet)
    try:
        return Globe(list(stores), vertical_exaggeration=vertical_exaggeration, sync=sync,
                     progress=lambda d, n: bar("measuring nodes", d, n))
    finally:
        bar.close()


def underground(globe, lon: float, lat: float, height: float) -> float | None:
    """How far (metres) below the drawn ground a camera at ``lon``, ``lat``, ``height``
    is, or None when it is above it."""
    import numpy as np

    ground = float(globe.surface.heights(np.array([lon]), np.array([lat]),
                                         globe.max_depth)[0])
    return ground - height if math.isfinite(ground) and height < ground else None


def globe_view(globe, geo_camera, size, fov, warn=None):
    """The view of ``--camera`` (or the default framing of every store); ``warn(line)``
    is told when the camera is under the ground."""
    if geo_camera is None:
        return globe.default_view(size, fov)
    lon, lat, h, heading, pitch = geo_camera
    lon = (lon + 180.0) % 360.0 - 180.0
    below = underground(globe, lon, lat, h)
    if below is not None and warn is not None:
        warn(f"warning: the camera is {below:,.1f} m under the ground at {lon:g}, {lat:g}; "
             "raise its HEIGHT in --camera to see the surface from above")
    return globe.camera(lon, lat, h, heading, pitch, size, fov)


def render(ctx: click.Context, stores, out, geo_camera, size, fov, pixel_error,
           vertical_exaggeration, shading, palette, title, overlays: bool, stats_path,
           overwrite: bool) -> None:
    """`geoterrain render --globe`: one PNG of the stores on the globe."""
    from geoterrain.core.atomicfiles import write_atomic
    from geoterrain.core.paths import check_output, same_file
    from geoterrain.exceptions import UsageError
    from geoterrain.rendering.globescene import render_globe

    quiet = (ctx.obj or {}).get("quiet", False)
    if Path(out).suffix.lower() != ".png":
        raise UsageError(f"{out}: render --globe writes one view as .png")
    check_stores(stores)
    check_output(out, overwrite, inputs=list(stores))
    if stats_path is not None:
        check_output(stats_path, overwrite, inputs=list(stores), option="--stats")
        if same_file(stats_path, out) or Path(stats_path).absolute() == Path(out).absolute():
            raise UsageError("--stats and -o name the same file; choose another --stats path")
    g = open_globe(stores, vertical_exaggeration, quiet)
    with g:
        view = globe_view(g, geo_camera, size, fov, lambda s: click.echo(s, err=True))
        stats: dict = {}
        render_globe(g, view, out, pixel_error=pixel_error, cmap=palette, shading=shading,
                     title=title, colorbar=overlays, overwrite=overwrite, stats=stats)
    stats.update(path=str(out), size=list(size), look_from=list(view.look_from),
                 look_at=list(view.look_at), stores=[str(s) for s in stores])
    if stats_path is not None:
        write_atomic(stats_path, json.dumps(stats, indent=2, default=float), overwrite)
    if not quiet:
        click.echo(f"wrote {out}: {stats.get('triangles', 0):,} triangles on the globe "
                   f"({stats.get('nodes', 0)} nodes, τ = {pixel_error:g} px)", err=True)


def view(ctx: click.Context, stores, geo_camera, size, pixel_error, vertical_exaggeration,
         shading, palette) -> None:
    """`geoterrain view --globe`: the interactive window on the globe."""
    from geoterrain.exceptions import GeoterrainError
    from geoterrain.rendering.globeviewer import show_globe

    from .view import has_display

    quiet = (ctx.obj or {}).get("quiet", False)
    check_stores(stores)
    if not has_display():
        raise GeoterrainError(
            "no display to open a window on (DISPLAY is not set); use `geoterrain render "
            "--globe` for pictures, or run under a desktop session or Xvfb")
    g = open_globe(stores, vertical_exaggeration, quiet, sync=False)
    with g:
        home = globe_view(g, geo_camera, size, 30.0, lambda s: click.echo(s, err=True))
        show_globe(g, home, pixel_error, shading=shading, cmap=palette, size=size)



def flyover_options(f):
    """--fps, --frame-budget and --measure-every of `bench --globe`."""
    for opt in reversed([
        click.option("--flight-fps", "flight_fps", type=Number(0.5, 120.0),
                     default=10.0, show_default=True,
                     help="--globe: frames per second of flight time (the flyover lasts 24 s)."),
        click.option("--frame-budget", type=Number(1.0, 1e5), default=None,
                     metavar="MS",
                     help="--globe: the frame budget in ms that no frame may stall on "
                          "payload generation for [default: 1000 / --flight-fps]."),
        click.option("--measure-every", type=click.IntRange(0, 10_000), default=10,
                     show_default=True,
                     help="--globe with a store: measure ρ every N frames (0: never)."),
    ]):
        f = opt(f)
    return f


def bench(ctx: click.Context, source, size, taus, render_frames: bool, flight_fps: float,
          frame_budget, measure_every: int, output, overwrite: bool) -> None:
    """`geoterrain bench --globe`: seed 001's flyover, per-frame figures and the summary."""
    import numpy as np

    from geoterrain.bench.globeflight import flyover, run_flyover, summary
    from geoterrain.core.atomicfiles import write_atomic
    from geoterrain.core.paths import check_output
    from geoterrain.exceptions import UsageError
    from geoterrain.globe import Globe

    quiet = (ctx.obj or {}).get("quiet", False)
    if len(taus) != 1:
        raise UsageError("bench --globe flies at one --pixel-error, got "
                         f"{','.join(f'{t:g}' for t in taus)}")
    tau = taus[0]
    stores = (source,) if source else ()
    if stores:
        check_stores(stores)
    if output is not None:
        check_output(output, overwrite, inputs=list(stores), option="-o")
        if Path(output).suffix.lower() not in (".csv", ".json"):
            raise UsageError(f"{output}: the frames are written as .csv or .json")
    budget = float(frame_budget) if frame_budget else 1000.0 / flight_fps
    bar = StageBar("globe", quiet)
    try:
        g = Globe(list(stores), progress=lambda d, n: bar("measuring nodes", d, n))
    finally:
        bar.close()
    with g:
        measure = None
        if stores:
            st = g.stores[0]
            fl, fb = st.footprint(16)
            lon, lat = float(np.mean(fl)), float(np.mean(fb))
            # ρ is measured through a central projection onto the store's tangent plane:
            # for a regional geographic store (up to 30°)
            if measure_every and st.geographic and max(np.ptp(fl), np.ptp(fb)) < 30.0:
                from geoterrain.globe.layers import FEATHER
                from geoterrain.testing.globemeasure import measured_rho, store_truth

                truth = store_truth(st.terrain, int(FEATHER) + 1)
                if len(truth):  # a store within its feathered edge: nothing to measure
                    centre = truth.mean(0)

                    def measure(sel, view):
                        rho, n, _ = measured_rho(sel, truth, view, centre)
                        return rho if n else None
        else:  # the procedural planet: over the highest ground near the seed's start
            lon, lat = 139.25, 35.35
        views = flyover(g, lon, lat, fps=flight_fps, size=size)
        bar = StageBar("flyover", quiet)
        try:
            frames = run_flyover(g, views, tau, render=render_frames, measure=measure,
                                 measure_every=measure_every,
                                 progress=lambda d, n: bar("frame", d, n))
        finally:
            bar.close()
    s = summary(frames, budget)
    if output is not None:
        if Path(output).suffix.lower() == ".json":
            text = json.dumps(dict(summary=s, frames=frames), indent=1)
        else:
            cols = list(frames[0])
            text = "\n".join([",".join(cols)] + [",".join("" if f[c] is None else str(f[c])
                                                          for c in cols) for f in frames])
            text += "\n"
        write_atomic(output, text, overwrite)
    what = source or "the procedural planet"
    click.echo(f"# bench --globe: seed 001's flyover over {what}, {len(frames)} frames "
               f"({flight_fps:g} per second of flight), τ = {tau:g} px, {size[0]}x{size[1]}"
               f"{', rendered' if render_frames else ', not rendered'}")
    click.echo(f"frame ms: median {s['frame_ms_median']}, p90 {s['frame_ms_p90']}, p99 "
               f"{s['frame_ms_p99']}, max {s['frame_ms_max']} (min {s['frame_ms_min']})")
    click.echo(f"selection: {100 * s['selection_share_median']:.1f} % of the frame "
               f"(median), {100 * s['selection_share_total']:.1f} % of the run, "
               f"{100 * s['selection_share_max']:.1f} % at most; mesh (morph) "
               f"{100 * s['mesh_share_total']:.1f} % of the run")
    click.echo(f"render: {100 * s['render_share_total']:.1f} % of the run; the rest of "
               f"the select call (dispatch, the interpreter shared with the generating "
               f"threads) at most {s['other_ms_max']} ms")
    click.echo(f"generation on the frame: at most {s['generation_ms_max']} ms; "
               f"{s['frames_stalled_on_generation']} frames stalled over the "
               f"{budget:g} ms budget; {s['frames_over_budget']} frames over it in all")
    click.echo(f"pop: at most {s['pop_px_max']} px"
               + (f"; measured ρ at most {s['rho_px_max']} px over {s['rho_frames']} frames"
                  if s["rho_px_max"] is not None else ""))
    if output is not None and not quiet:
        click.echo(f"wrote {output}", err=True)
