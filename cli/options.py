"""Options shared between commands, the Click types that check every value, and the
progress bar.

Every value a command takes is checked here, before any work, with one line and exit 2
(Click's usage errors are printed as one line by :mod:`geoterrain.cli.main`). A new
command or option takes a type from this list rather than ``float`` or ``int``:

=====================  ================================================================
type                   accepts
=====================  ================================================================
``Number(lo, hi)``     a finite number in [lo, hi] (``lo_open``/``hi_open``: the open
                       ends; ``nan=True`` also NaN, e.g. ``--nodata nan``)
``FINITE``             any finite number (a height, a coordinate)
``POSITIVE``           a finite number > 0 (a bound, a tolerance, a size in metres)
``NON_NEGATIVE``       a finite number ≥ 0 (``--max-error``: 0 is every vertex)
``AZIMUTH``            degrees clockwise from north, in [−360, 360]
``ELEVATION``          degrees above the horizon, in (0, 90]
``FOV``                a field of view, degrees in (0, 180)
``FRACTION``           a number in [0, 1] (an opacity)
``DISTANCE``           metres in (0, 10^9]
``EXAGGERATION``       a vertical exaggeration in [10^-6, 10^6] (the store's own range)
``PIXEL_SIZE``         metres per sample in [10^-6, 10^6] (the store's own range)
``PIXEL_ERROR``        a screen-space error in pixels, in (0, 10^4]
``NODATA``             a finite number or NaN
``Point(n)``           ``n`` finite comma-separated numbers (``X,Y,Z``; ``X,Y``)
``SIZE``               a picture ``WIDTHxHEIGHT``, 16 … 16384 per side
``Text(n)``            printable text of at most ``n`` characters (a title)
=====================  ================================================================

For example ``click.option("--azimuth", type=AZIMUTH)``. The strategy names come from the
LOD registry (:mod:`geoterrain.lod.registry`), so a new strategy appears in every command
and its ``--help`` by itself.
"""

from __future__ import annotations

import math
import sys

import click

from geoterrain.cli.compilebar import COMPILING, CompileBar  # noqa: F401  (StageBar's)
from geoterrain.core.limits import PIXEL_SIZE_RANGE, SCENE_LIMIT, Z_SCALE_RANGE
from geoterrain.lod.registry import DEFAULT, STRATEGIES, describe


def _number(text: object) -> float:
    """A float from a command line word (ValueError otherwise)."""
    if isinstance(text, bool):
        raise ValueError(text)
    if isinstance(text, int | float):
        return float(text)
    return float(str(text).strip())


class Number(click.ParamType):
    """A finite number in [lo, hi] (``lo_open``, ``hi_open``: excluded ends); ``nan``
    also takes NaN. One line naming the range otherwise.

    Examples
    --------
    >>> Number(0, 90, lo_open=True).convert("45", None, None)
    45.0
    >>> try:
    ...     Number(0, 90, lo_open=True).convert("nan", None, None)
    ... except click.BadParameter as e:
    ...     print(e)
    expected a number in (0, 90], got nan
    """

    name = "number"

    def __init__(self, lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
                 hi_open: bool = False, nan: bool = False):
        self.lo, self.hi, self.lo_open, self.hi_open, self.nan = lo, hi, lo_open, hi_open, nan

    def describe(self) -> str:
        if self.lo == -math.inf and self.hi == math.inf:
            return "a finite number"
        if self.hi == math.inf:
            return f"a finite number {'>' if self.lo_open else '≥'} {self.lo:g}"
        return (f"a number in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}"
                f"{')' if self.hi_open else ']'}")

    def convert(self, value, param, ctx):
        try:
            v = _number(value)
        except ValueError:
            self.fail(f"expected {self.describe()}, got {value!r}", param, ctx)
        if math.isnan(v) and self.nan:
            return v
        lo_ok = v > self.lo if self.lo_open else v >= self.lo
        hi_ok = v < self.hi if self.hi_open else v <= self.hi
        if not (math.isfinite(v) and lo_ok and hi_ok):
            self.fail(f"expected {self.describe()}, got {value}", param, ctx)
        return v

    def __repr__(self) -> str:
        return f"Number({self.describe()})"


FINITE = Number()
POSITIVE = Number(0, lo_open=True)
NON_NEGATIVE = Number(0)
AZIMUTH = Number(-360, 360)
ELEVATION = Number(0, 90, lo_open=True)
FOV = Number(0, 180, lo_open=True, hi_open=True)
FRACTION = Number(0, 1)
DISTANCE = Number(0, 10 * SCENE_LIMIT, lo_open=True)
EXAGGERATION = Number(*Z_SCALE_RANGE)
PIXEL_SIZE = Number(*PIXEL_SIZE_RANGE)
PIXEL_ERROR = Number(0, 1e4, lo_open=True)
NODATA = Number(nan=True)


class Point(click.ParamType):
    """``n`` finite comma-separated numbers (``X,Y,Z`` with ``n`` = 3), as a tuple.

    Examples
    --------
    >>> Point(3).convert("1,2.5,-3", None, None)
    (1.0, 2.5, -3.0)
    """

    name = "point"

    def __init__(self, n: int = 3, names: str = "X,Y,Z"):
        self.n, self.names = n, names

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            parts = tuple(_number(v) for v in str(value).split(","))
        except ValueError:
            self.fail(f"expected {self.names} numbers, got {value!r}", param, ctx)
        if len(parts) != self.n or not all(math.isfinite(v) and abs(v) < 1e15 for v in parts):
            self.fail(f"expected {self.n} finite numbers {self.names}, got {value!r}", param,
                      ctx)
        return parts


class PictureSize(click.ParamType):
    """``WIDTHxHEIGHT`` in pixels, 16 … 16384 per side, as (width, height).

    Examples
    --------
    >>> SIZE.convert("640x360", None, None)
    (640, 360)
    """

    name = "size"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            w, h = (int(v) for v in str(value).lower().split("x"))
        except ValueError:
            self.fail(f"expected WIDTHxHEIGHT such as 1280x720, got {value!r}", param, ctx)
        if w < 16 or h < 16 or w > 16384 or h > 16384:
            self.fail(f"size {w}x{h} out of range (16..16384 per side)", param, ctx)
        return w, h


SIZE = PictureSize()


class Text(click.ParamType):
    """Printable text of at most ``n`` characters (no control characters).

    Examples
    --------
    >>> Text(10).convert("Fuji", None, None)
    'Fuji'
    """

    name = "text"

    def __init__(self, n: int = 200):
        self.n = n

    def convert(self, value, param, ctx):
        s = str(value)
        if len(s) > self.n or not s.isprintable():
            self.fail(f"expected printable text of at most {self.n} characters", param, ctx)
        return s


def parse_triple(ctx, param, value):
    """Parse ``X,Y,Z`` into a tuple of three finite floats (:class:`Point`)."""
    return None if value is None else Point(3).convert(value, param, ctx)


def parse_size(ctx, param, value):
    """Parse ``WxH`` into (width, height) (:data:`SIZE`)."""
    return None if value is None else SIZE.convert(value, param, ctx)


def parse_bytes(ctx, param, value):
    """Parse a memory size: ``1.5G``, ``800M``, ``2GB``, ``512MiB`` or bytes."""
    if value is None:
        return None
    import re

    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?b)?\s*", value.lower())
    if not m:
        raise click.BadParameter(f"expected a size such as 1.5G or 800M, got {value!r}")
    n = float(m.group(1)) * 1024 ** " kmgt".index(m.group(2) or " ")
    if n < 64 * 2**20:
        raise click.BadParameter(f"{value} is below the 64M the job needs at least")
    return int(n)


class StageBar:
    """A progress bar over named stages, on stderr; silent with -q."""

    def __init__(self, label: str, quiet: bool):
        self.quiet = quiet
        self.label = label
        self.bar = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        if CompileBar.active is not None:  # the first run's bar is shown
            if CompileBar.active.compiling():
                return
            CompileBar.active.finish()  # the command's own work goes on: its bar from now
        if self.bar is None:
            self.bar = click.progressbar(length=total, label=self.label, file=sys.stderr,
                                         show_eta=False, item_show_func=lambda s: s)
            self.bar.__enter__()
        self.bar.update(done - self.bar.pos, stage)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


def _strategy_help(prefix: str) -> str:
    return prefix + " " + "; ".join(describe().splitlines()) + "."


mesher_option = click.option(
    "--mesher", type=click.Choice(["rtin", "tin", "tin-full"]), default="rtin",
    show_default=True,
    help="Whole-terrain mesh (--max-error): rtin, the bintree cut (streamed in bounded "
         "memory), or tin, a greedy Delaunay TIN (fewer triangles at the same error; the "
         "whole grid in memory); tin-full collapses every point it can after the TIN's "
         "refinement (fewer triangles still, about a quarter more time).")

strategy_option = click.option(
    "--strategy", type=click.Choice(STRATEGIES), default=DEFAULT, show_default=True,
    help=_strategy_help("LOD strategy:"))


def _parse_strategies(ctx, param, value):
    out = tuple(v.strip() for v in value.split(",") if v.strip())
    bad = [v for v in out if v not in STRATEGIES]
    if bad or not out:
        raise click.BadParameter(f"unknown strategy {', '.join(bad) or repr(value)}; "
                                 f"use {', '.join(STRATEGIES)}")
    return out


strategies_option = click.option(
    "--strategies", default=",".join(STRATEGIES), show_default=True, callback=_parse_strategies,
    help=_strategy_help("Comma-separated LOD strategies:"))


occlusion_option = click.option(
    "--occlusion/--no-occlusion", default=True, show_default=True,
    help="Skip tiles hidden behind nearer terrain before reading them (horizon culling; "
         "conservative: nothing visible is lost). --no-occlusion draws them too. The "
         "clipmap strategy draws its whole rings either way (a steady triangle count).")


anti_aliasing_option = click.option(
    "--anti-aliasing", type=click.Choice(["auto", "msaa", "edges", "fxaa", "none"]),
    default="auto", show_default=True,
    help="Smoothing of jagged edges in pictures: auto (edges for a picture whose "
         "silhouettes are sparse, else msaa), msaa (the renderer's multisampling), edges "
         "(the mesh's silhouette edges blended by their exact coverage on the CPU: about "
         "half the draw on a software renderer; as close to a supersampled picture as "
         "msaa where silhouettes are long edges, worse where steep thin facets crowd a "
         "pixel), fxaa (a pass over each picture on the CPU along its depth edges), or "
         "none.")


morph_option = click.option(
    "--morph/--no-morph", default=None,
    help="Geomorph: detail slides into place instead of popping as the camera moves "
         "(rtin: a vertex starts sliding at 3/4 of the pixel error, costing triangles; "
         "chunked: a tile slides from its parent's surface; geomipmap: each block slides "
         "between its levels; cdlod: its own ranges). Default: rtin, chunked and geomipmap "
         "off, cdlod on.")


pixel_error_option = click.option(
    "--pixel-error", type=PIXEL_ERROR, default=1.0, show_default=True,
    metavar="PX", help="Level of detail: the mesh is never more than PX pixels from the "
                       "full-resolution terrain on screen (larger: fewer triangles; at most "
                       "10000).")


def _parse_pixel_errors(ctx, param, value):
    try:
        out = tuple(float(v) for v in value.split(",") if v.strip())
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None
    if not out or any(not (math.isfinite(v) and 0 < v <= PIXEL_ERROR.hi) for v in out):
        raise click.BadParameter(f"expected numbers in (0, {PIXEL_ERROR.hi:g}], got {value!r}")
    return out


pixel_errors_option = click.option(
    "--pixel-error", "pixel_errors", default="0.5,1,2,4,8", show_default=True,
    callback=_parse_pixel_errors, metavar="PX[,PX...]",
    help="Comma-separated levels of detail: on-screen error bounds in pixels.")


def camera_options(f):
    """--look-from, --look-at, --crs-coords, --fov and --size, shared by mesh and render."""
    for opt in reversed([
        click.option("--look-from", type=Point(3), metavar="X,Y,Z",
                     help="Eye X,Y,Z (scene metres)."),
        click.option("--look-at", type=Point(3), metavar="X,Y,Z",
                     help="Target X,Y,Z (scene metres)."),
        click.option("--crs-coords", is_flag=True,
                     help="--look-from/--look-at are source-CRS x,y and height z in metres."),
        click.option("--fov", default=30.0, show_default=True, type=FOV,
                     help="Vertical field of view, degrees in (0, 180)."),
        click.option("--size", default="1280x720", show_default=True, type=SIZE,
                     help="Image WIDTHxHEIGHT (the pixel error refers to it)."),
    ]):
        f = opt(f)
    return f


def _check_cmap(ctx, param, value):
    from geoterrain.exceptions import UsageError
    from geoterrain.rendering.colours import check_cmap

    try:
        check_cmap(value)
    except UsageError as exc:
        raise click.BadParameter(str(exc)) from None
    return value


def parse_min_max(ctx, param, value):
    """Click callback: ``MIN,MAX`` in metres → (min, max), finite and increasing."""
    if value is None:
        return None
    try:
        lo, hi = (float(v) for v in value.split(","))
    except ValueError:
        raise click.BadParameter(f"expected MIN,MAX in metres, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise click.BadParameter(f"expected finite MIN < MAX, got {value!r}")
    return lo, hi


def colour_options(f):
    """--cmap, --clim, --water-level and --water/--no-water, shared by render and view."""
    for opt in reversed([
        click.option("--cmap", default="auto", show_default=True, callback=_check_cmap,
                     help="auto (land tints; water in blue at or below 0 m when the data "
                          "reaches the sea) or any matplotlib colormap name."),
        click.option("--clim", callback=parse_min_max, metavar="MIN,MAX",
                     help="Heights (m) the colour map spans (default: the data's range)."),
        click.option("--water-level", type=FINITE, metavar="H",
                     help="Water up to H metres: a flood or a lake at that level."),
        click.option("--water/--no-water", "water", default=True, show_default=True,
                     help="Draw the water (--water-level, or the sea at 0 m of the auto "
                          "colours) as a flat, lit, semi-transparent surface with the depth "
                          "coloured below it; --no-water only colours the ground under it."),
    ]):
        f = opt(f)
    return f


def palette(cmap, clim, water_level):
    """The :class:`geoterrain.rendering.colours.Palette` of the colour options."""
    from geoterrain.rendering.colours import Palette

    return Palette(cmap, clim, water_level)


def _parse_sun(ctx, param, value):
    if value is None:
        return None
    from geoterrain.exceptions import UsageError
    from geoterrain.rendering.shading import parse_sun

    try:
        az, el = parse_sun(value)
    except UsageError as exc:
        raise click.BadParameter(str(exc.cli or exc)) from None
    if not (0 <= az <= 360 and 0 < el <= 90):  # a sun on the horizon lights nothing
        raise click.BadParameter(f"expected AZ in [0, 360] and EL in (0, 90] degrees, got "
                                 f"{value!r}")
    return az, el


def light_options(f):
    """--sun, --hillshade, --shadows and --ambient-occlusion, shared by render and view."""
    for opt in reversed([
        click.option("--sun", callback=_parse_sun, metavar="AZ,EL",
                     help="Sun azimuth (degrees clockwise from north) and elevation above "
                          "the horizon [default: 315,45: the cartographic north-west sun]."),
        click.option("--hillshade", type=click.Choice(["single", "multi"]), default="single",
                     show_default=True,
                     help="multi: four suns 45° apart around --sun, so slopes facing every "
                          "way show relief."),
        click.option("--shadows/--no-shadows", default=False, show_default=True,
                     help="Cast shadows from the terrain toward the sun."),
        click.option("--ambient-occlusion/--no-ambient-occlusion", "ambient_occlusion",
                     default=False, show_default=True,
                     help="Darken valleys by the sky they see (sky-view factor)."),
    ]):
        f = opt(f)
    return f


def drape_options(f):
    """--drape and --drape-opacity, shared by render and view."""
    for opt in reversed([
        click.option("--drape", "drape_path", type=click.Path(exists=True, dir_okay=False),
                     metavar="IMAGE",
                     help="A georeferenced image (an orthophoto, land cover; any CRS, "
                          "reprojected) drawn over the colour map; its nodata shows the map."),
        click.option("--drape-opacity", type=FRACTION, default=1.0,
                     show_default=True, metavar="A",
                     help="1: the drape in place of the colour map; below 1: blended."),
    ]):
        f = opt(f)
    return f


def light_and_drape(shading, sun, hillshade, shadows, ambient_occlusion, drape_path,
                    drape_opacity):
    """The :class:`geoterrain.rendering.shading.Light` (None: the default light) and the
    :class:`geoterrain.rendering.drape.Drape` (None without --drape) of the light and drape
    options, checked against --shading."""
    from geoterrain.exceptions import UsageError
    from geoterrain.rendering.drape import Drape
    from geoterrain.rendering.shading import SUN_AZIMUTH, SUN_ELEVATION, Light

    az, el = sun if sun is not None else (SUN_AZIMUTH, SUN_ELEVATION)
    lit = Light(az, el, hillshade == "multi", bool(shadows), bool(ambient_occlusion))
    lit = None if lit.is_default else lit
    if lit is not None and shading != "normals":
        raise UsageError("--sun, --hillshade multi, --shadows and --ambient-occlusion light "
                         "the hillshade: use them with --shading normals")
    dr = None if drape_path is None else Drape(str(drape_path), float(drape_opacity))
    if dr is not None and shading == "plain":
        raise UsageError("--drape colours the texture: use it with --shading normals or "
                         "elevation")
    return lit, dr


vertical_exaggeration_option = click.option(
    "-z", "--vertical-exaggeration", "vertical_exaggeration", type=EXAGGERATION, default=1.0,
    show_default=True, metavar="N",
    help="Draw heights × N (view time; the store's --z-scale is kept). The LOD error bound "
         "holds for the exaggerated surface; pictures say VE ×N.")


def check_mesher(mesher: str, max_error) -> None:
    """--mesher tin / tin-full is a whole-terrain mesher: refused with a view (one line, exit 2)."""
    from geoterrain.exceptions import UsageError

    if mesher != "rtin" and max_error is None:
        raise UsageError(f"--mesher {mesher} makes a whole-terrain mesh (--max-error), "
                         "not a view's")


def mesh_request(max_error, look_from, look_at) -> float | None:
    """Check a static (--max-error) or view (--look-from/--look-at) request, as `mesh` and
    `export` take it; the static bound e (default 1), or None for a view."""
    from geoterrain.exceptions import UsageError

    view_mode = look_from is not None or look_at is not None
    if view_mode and (look_from is None or look_at is None):
        raise UsageError("a view needs both --look-from and --look-at")
    if view_mode and max_error is not None:
        raise UsageError("give either --max-error (static) or a view (--look-from/--look-at)")
    if view_mode:
        return None
    e = 1.0 if max_error is None else max_error
    if not (math.isfinite(e) and e >= 0):
        raise UsageError(f"--max-error must be a finite number ≥ 0, got {e}")
    return e


def select_mesh(t, max_error, look_from, look_at, crs_coords, fov, size, pixel_error, strategy,
                occlusion: bool = True, mesher: str = "rtin"):
    """The static selection of bound ``max_error`` (by ``mesher``), or the view's
    (source-CRS camera points with ``crs_coords``; horizon culling with ``occlusion``),
    after :func:`mesh_request`."""
    import geoterrain
    from geoterrain.exceptions import UsageError

    if max_error is not None:
        return t.static_selection(max_error, mesher=mesher)
    if crs_coords:
        look_from, look_at = (t.frame.crs_point_to_scene(p) for p in (look_from, look_at))
    if look_from == look_at:
        raise UsageError("--look-from and --look-at must differ")
    return t.select(geoterrain.View(look_from, look_at, fov_y_deg=fov, size=size), pixel_error,
                    strategy, occlusion=occlusion)


def human_bytes(n: float) -> str:
    """``n`` bytes in a reader's unit: 512 B, 12.3 kB, 31.9 MB, 1.20 GB."""
    for unit, f in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= f:
            return f"{n / f:.3g} {unit}" if n < 100 * f else f"{n / f:.0f} {unit}"
    return f"{int(n)} B"


def mesh_words(s: dict) -> str:
    """A mesh's stats in words: triangles, vertices, and what bounds its error."""
    what = (f"whole terrain, height error ≤ {s['max_error']:g} m" if "max_error" in s
            else f"view from the camera, {s.get('strategy', 'rtin')} within "
                 f"{s.get('pixel_error', 1.0):g} px on screen")
    return f"{s['triangles']:,} triangles, {s['vertices']:,} vertices ({what})"


# ------------------------------------------------------------------ the analysis commands


def points_crs_options(f):
    """--crs and --lonlat: the CRS the command's coordinates are given in."""
    for opt in reversed([
        click.option("--crs", "crs", metavar="CRS",
                     help="CRS of the given coordinates (an EPSG code such as EPSG:4326, a "
                          "PROJ string or WKT) [default: the DEM's own]."),
        click.option("--lonlat", is_flag=True,
                     help="The coordinates are longitude, latitude in degrees (WGS 84)."),
    ]):
        f = opt(f)
    return f


def points_crs(crs, lonlat):
    """The ``crs=`` argument of the analysis functions from --crs / --lonlat."""
    from geoterrain.exceptions import UsageError

    if crs and lonlat:
        raise UsageError("give either --crs or --lonlat, not both")
    return "lonlat" if lonlat else (crs or None)


def parse_xy(value: str, flag: str) -> tuple[float, float]:
    """``X,Y`` → two floats (a one-line UsageError naming ``flag`` otherwise)."""
    from geoterrain.exceptions import UsageError

    try:
        x, y = (float(v) for v in value.split(","))
    except ValueError:
        raise UsageError(f"{flag} expects X,Y (two numbers), got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise UsageError(f"{flag} expects finite numbers, got {value!r}")
    return x, y


def read_geometry(value: str, flag: str):
    """A geometry given as WKT, GeoJSON (text, or a .geojson/.json/.wkt file): a shapely
    geometry, and whether it came from GeoJSON (whose coordinates are lon/lat, RFC 7946,
    unless it names a CRS)."""
    import json
    from pathlib import Path

    import shapely
    from shapely.geometry import shape

    from geoterrain.exceptions import UsageError

    text = value
    p = Path(value)
    if len(value) < 4096 and p.suffix.lower() in (".geojson", ".json", ".wkt", ".txt"):
        if not p.is_file():
            raise UsageError(f"{flag}: {value} is not a file")
        text = p.read_text()
    text = text.strip()
    try:
        if text.startswith("{"):
            obj = json.loads(text)
            if obj.get("type") == "FeatureCollection":
                feats = obj.get("features") or []
                if len(feats) != 1:
                    raise UsageError(f"{flag}: the GeoJSON holds {len(feats)} features; give "
                                     "one")
                obj = feats[0]
            geom = shape(obj.get("geometry", obj) if obj.get("type") == "Feature" else obj)
            return geom, True
        return shapely.from_wkt(text), False
    except (ValueError, TypeError, KeyError, AttributeError,
            shapely.errors.ShapelyError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UsageError(f"{flag}: cannot read {value[:60]!r} as WKT or GeoJSON ({first})"
                         ) from None


def read_points(path: str):
    """Points from a CSV (columns x, y — or lon, lat — by name, else the first two) or a
    GeoJSON of Points: an (N, 2) array, their names (or None), and whether they came from
    GeoJSON (lon/lat)."""
    import csv
    import json
    from pathlib import Path

    import numpy as np

    from geoterrain.exceptions import InputError, UsageError

    p = Path(path)
    if not p.is_file():
        raise UsageError(f"--points: {path} is not a file")
    if p.suffix.lower() in (".geojson", ".json"):
        try:
            obj = json.loads(p.read_text())
            feats = obj["features"] if obj.get("type") == "FeatureCollection" else [obj]
            xy = [f["geometry"]["coordinates"][:2] for f in feats
                  if f.get("geometry", {}).get("type") == "Point"]
        except (ValueError, KeyError, TypeError, AttributeError):
            raise InputError(f"{path}: not a GeoJSON of points") from None
        if not xy:
            raise InputError(f"{path}: no Point features")
        return np.asarray(xy, np.float64), None, True
    rows = list(csv.reader(p.read_text().splitlines()))
    if not rows:
        raise InputError(f"{path}: empty")
    head = [h.strip().lower() for h in rows[0]]
    named = [("x", "y"), ("lon", "lat"), ("longitude", "latitude"), ("easting", "northing")]
    cols = next(((head.index(a), head.index(b)) for a, b in named
                 if a in head and b in head), None)
    body = rows[1:] if cols is not None or not _numeric(rows[0][:2]) else rows
    cols = cols or (0, 1)
    try:
        xy = np.array([[float(r[cols[0]]), float(r[cols[1]])] for r in body if r],
                      np.float64)
    except (ValueError, IndexError):
        raise InputError(f"{path}: expected columns x,y (or lon,lat) of numbers") from None
    if xy.size == 0:
        raise InputError(f"{path}: no points")
    return xy, None, False


def _numeric(cells) -> bool:
    try:
        [float(c) for c in cells]
    except ValueError:
        return False
    return len(cells) == 2
