"""Animations of LOD terrain: orbits and fly-throughs to a GIF, an MP4 or PNG frames.

Every frame selects its own level of detail for its own camera and is drawn by the
same offscreen scene as a single picture (:class:`geoterrain.rendering.scene.TerrainScene`).
The output is written to a hidden partial and published only when every frame is
done (``geoterrain.core.atomicfiles.publish``), so an error or an interrupt leaves nothing that
looks like a result; a GIF is streamed frame by frame (:mod:`geoterrain.rendering.gifstream`),
so memory stays flat in the number of frames.

Examples
--------
>>> import geoterrain
>>> from geoterrain.rendering.animation import orbit
>>> t = geoterrain.open("dem.geoterrain")  # doctest: +SKIP
>>> stats = orbit(t, "orbit.gif", 36)  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from geoterrain.core.atomicfiles import partial_path, publish, remove_stale_partials
from geoterrain.core.view import View
from geoterrain.exaggerate import exaggerated
from geoterrain.exceptions import UsageError, exists_error
from geoterrain.lod.registry import DEFAULT, strategy_info
from geoterrain.rendering.cameras import interpolate_views, load_cameras, orbit_views
from geoterrain.rendering.colours import Palette
from geoterrain.rendering.drape import Drape
from geoterrain.rendering.overlays import compose, layout_for
from geoterrain.rendering.scene import TerrainScene
from geoterrain.rendering.shading import Light
from geoterrain.rendering.window import offscreen_plotter, writable_target, write_png

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["animate", "check_animation_output", "flythrough", "orbit"]

Progress = Callable[[int, int], None]

MAX_FRAMES = 100_000  # an animation longer than this is a mistake (about 3 h at 10 fps)
ANIMATION_SUFFIXES = (".gif", ".mp4")


def check_animation_output(out: str | Path, fps: float, overwrite: bool = True) -> None:
    """Refuse a bad animation target before any frame is rendered.

    ``out`` is a .gif, a .mp4, or a folder (no suffix) of PNG frames; ``fps``
    a finite number in (0, 1000].

    Examples
    --------
    >>> try:
    ...     check_animation_output("fly.webm", 10)
    ... except UsageError as e:
    ...     print(str(e).split(";")[0])
    fly.webm: unknown animation format '.webm'
    """
    out = Path(out)
    ext = out.suffix.lower()
    if ext and ext not in ANIMATION_SUFFIXES and not out.is_dir():
        raise UsageError(f"{out}: unknown animation format {ext!r}; use .gif, .mp4 or a folder "
                         "name without a suffix (PNG frames)")
    if not (isinstance(fps, int | float) and math.isfinite(fps) and 0 < fps <= 1000):
        raise UsageError(f"fps must be a number in (0, 1000], got {fps}",
                         cli=f"--fps must be a number in (0, 1000], got {fps}")
    folder = ext not in ANIMATION_SUFFIXES  # a folder of PNG frames
    writable_target(out, overwrite, folder=folder)
    if folder and os.path.lexists(out) and not overwrite:
        raise exists_error(out)


def _animation_writer(out: str | Path, fps: float, overwrite: bool = True):
    """(append(frame), close(), publish()) writing a .gif, .mp4 or PNG folder to a partial.

    ``close`` finishes the partial; ``publish`` then moves it into place. Until
    then nothing appears at ``out``, and an error leaves nothing behind.
    """
    out = Path(out)
    check_animation_output(out, fps, overwrite)
    ext = out.suffix.lower()
    remove_stale_partials(out.parent if str(out.parent) else Path("."))
    tmp = partial_path(out)
    if ext in ANIMATION_SUFFIXES:
        import imageio.v2 as iio2

        tmp = tmp.with_name(tmp.name + ext)  # the writer picks its format by suffix
        if ext == ".mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError:
                raise UsageError("writing .mp4 needs the imageio-ffmpeg package "
                                 "(pip install imageio-ffmpeg); or use -o frames.gif") from None
            w = iio2.get_writer(tmp, fps=fps, macro_block_size=1)
            return w.append_data, w.close, lambda: publish(tmp, out, overwrite), tmp
        from geoterrain.rendering.gifstream import (
            GifStream,  # frame by frame: memory flat in frames
        )

        g = GifStream(tmp, fps)
        return g.append, g.close, lambda: publish(tmp, out, overwrite), tmp
    tmp.mkdir()
    counter = iter(range(MAX_FRAMES))

    def append(img):
        write_png(tmp / f"frame_{next(counter):05d}.png", img)

    return append, lambda: None, lambda: publish(tmp, out, overwrite), tmp


def animate(terrain: TerrainLike, views: Sequence[View], out: str | Path, *,
            pixel_error: float = 1.0,
            strategy: str = DEFAULT, shading: str = "normals", cmap: str | Palette = "auto",
            title: str | None = None, colorbar: bool = True, scale_bar: bool = True,
            north_arrow: bool = True, fps: float = 10.0, progress: Progress | None = None,
            vertical_exaggeration: float = 1.0, overwrite: bool = True,
            light: Light | None = None, drape: Drape | None = None, occlusion: bool = True,
            morph: bool | None = None, anti_aliasing: str = "auto",
            water: bool = True) -> list[dict]:
    """Render each view (each with its own LOD selection) into a GIF, MP4 or PNG folder
    (the picture's arguments are :func:`~geoterrain.rendering.scene.render`'s).

    Returns the per-frame stats. The output is written to a hidden partial and
    moved into place only when every frame is done; ``overwrite=False`` refuses
    an existing ``out``.

    Examples
    --------
    >>> stats = animate(t, orbit_views(t, 12), "orbit.gif")  # doctest: +SKIP
    """
    strategy_info(strategy)
    if not views:
        raise UsageError("no views to render")
    if len(views) > MAX_FRAMES:
        raise UsageError(f"{len(views)} frames is more than the {MAX_FRAMES} an animation may "
                         "have; use fewer cameras or orbit frames")
    size = views[0].size
    if any(v.size != size for v in views):
        raise UsageError("every frame of an animation must have the same size")
    terrain = exaggerated(terrain, vertical_exaggeration)
    append, close, done, tmp = _animation_writer(out, fps, overwrite)
    all_stats = []
    ok = False
    try:
        scene = TerrainScene(offscreen_plotter(size, anti_aliasing), terrain, shading, cmap,
                             light=light, drape=drape, occlusion=occlusion, morph=morph,
                             water=water)
        try:
            for k, v in enumerate(views):
                img, st = scene.frame(v, pixel_error, strategy)
                st["terrain_fraction"] = round(scene.terrain_fraction(), 4)
                img = compose(img, v, terrain, shading=shading, cmap=cmap, title=title,
                              colorbar=colorbar, scale_bar=scale_bar, north_arrow=north_arrow)
                append(img)
                all_stats.append(st)
                if progress is not None:
                    progress(k + 1, len(views))
        finally:
            scene.plotter.close()
        close()
        done()
        ok = True
    finally:
        if not ok:  # an error at any frame leaves nothing that looks like a result
            try:
                close()
            except Exception:  # noqa: BLE001 - the writer of a failed run
                pass
            if tmp.is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                tmp.unlink(missing_ok=True)
    return all_stats


def orbit(terrain: TerrainLike, out: str | Path, n_frames: int = 36, *, size: tuple[int,
          int] = (1280, 720),
          azimuth: float = 190.0, elevation: float = 40.0, distance: float | None = None,
          fov_y_deg: float = 30.0, **kw) -> list[dict]:
    """A full turn around the terrain centre, ``n_frames`` frames, to a .gif/.mp4/folder.

    Every frame selects the LOD for its own camera. Keyword arguments go to
    :func:`animate` (pixel_error, strategy, shading, fps, progress, ...).

    Examples
    --------
    >>> stats = orbit(t, "orbit.gif", 24, size=(640, 360))  # doctest: +SKIP
    >>> len(stats)  # doctest: +SKIP
    24
    """
    terrain = exaggerated(terrain, kw.pop("vertical_exaggeration", 1.0))
    lay = layout_for(terrain, size, shading=kw.get("shading", "normals"),
                     cmap=kw.get("cmap", "auto"), title=kw.get("title"),
                     colorbar=kw.get("colorbar", True), scale_bar=kw.get("scale_bar", True),
                     north_arrow=kw.get("north_arrow", True))
    views = orbit_views(terrain, n_frames, size, azimuth, elevation, distance, fov_y_deg,
                        fit_rect=lay.free)
    return animate(terrain, views, out, **kw)


def flythrough(terrain: TerrainLike, cameras_json: str | Path, out: str | Path, *,
               size: tuple[int, int] = (1280, 720), fov_y_deg: float = 30.0,
               frames_between: int = 0, **kw) -> list[dict]:
    """Fly along the cameras of a JSON file (see :func:`load_cameras`).

    The cameras are keyframes: ``frames_between`` eased frames on a smooth spline
    go between each pair (:func:`interpolate_views`). Every frame selects the LOD
    for its own camera. Keyword arguments go to :func:`animate`.

    Examples
    --------
    >>> stats = flythrough(t, "cameras.json", "fly.gif", progress=print)  # doctest: +SKIP
    """
    terrain = exaggerated(terrain, kw.pop("vertical_exaggeration", 1.0))
    views = interpolate_views(load_cameras(terrain, cameras_json, size, fov_y_deg),
                              frames_between)
    return animate(terrain, views, out, **kw)
