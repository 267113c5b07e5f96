"""The render window and its picture: offscreen plotters, reading a frame back, the PNG.

What every picture of the project goes through, the flat scene's
(:mod:`geoterrain.rendering.scene`), the globe's, the previews of exports and the
benchmarks' harness: :func:`offscreen_plotter` (VTK alone, what ``render`` draws with) or
:func:`pyvista_plotter` (PyVista's, for the viewer, notebooks and widgets), both
headless on EGL where there is no display; :func:`draw` renders and reads the frame back
without VTK's end-of-frame pass; :func:`write_png` publishes it atomically.

Examples
--------
>>> p = offscreen_plotter((64, 48), anti_aliasing="none")
>>> draw(p).shape
(48, 64, 3)
>>> p.close()
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from geoterrain.core.atomicfiles import partial_path, publish, remove_stale_partials
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.rendering.antialias import ANTI_ALIASING, depth_buffer, fxaa

__all__ = ["aa_mode", "draw", "offscreen_plotter", "prefer_egl", "pyvista_plotter",
           "writable_target", "write_png"]


def prefer_egl() -> None:
    """Use the EGL (headless) OpenGL window when there is no display, before VTK makes one.

    Also tells PyVista that plotting is allowed: its X-server probe (``xset -q``, then a
    throw-away render window, about 0.1 s of a cold render) only decides whether to warn
    that no display exists, and an offscreen EGL window needs none.
    """
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
            and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        os.environ.setdefault("ALLOW_PLOTTING", "true")


def pyvista_plotter(size: tuple[int, int], anti_aliasing: bool | str = "auto"):
    """An offscreen plotter (EGL when there is no display).

    ``anti_aliasing``: ``"auto"`` (the default: each frame of the scene's
    ``TerrainScene.frame`` takes ``"edges"`` where its silhouettes are sparse, else
    ``"msaa"``), ``"msaa"`` (or True; the renderer's multisampling), ``"edges"`` (drawn
    without it; ``TerrainScene.frame`` blends the mesh's silhouette edges by their
    coverage, :mod:`geoterrain.rendering.edgeaa`), ``"fxaa"``
    (a CPU pass over each read-back picture along its depth edges,
    :mod:`geoterrain.rendering.antialias`: 3–5 ms where a software renderer's MSAA costs 30–60 ms
    at 1280×720), ``"none"`` (or False).
    """
    mode = aa_mode(anti_aliasing)
    prefer_egl()
    import pyvista as pv

    p = pv.Plotter(off_screen=True, window_size=list(size))
    p._geoterrain_samples = int(p.render_window.GetMultiSamples())  # what "msaa" draws with
    if mode not in ("msaa", "auto"):
        p.disable_anti_aliasing()
    p._geoterrain_aa = mode
    return p


def offscreen_plotter(size: tuple[int, int], anti_aliasing: bool | str = "auto"):
    """:func:`pyvista_plotter`'s window on VTK alone (:class:`~geoterrain.rendering.offscreen.
    OffscreenPlotter`): the same pictures, without importing PyVista's plotting modules.
    What :func:`render`, :func:`render_array`, orbits and fly-throughs draw with."""
    mode = aa_mode(anti_aliasing)
    prefer_egl()
    from geoterrain.rendering.offscreen import OffscreenPlotter

    p = OffscreenPlotter(size)
    p._geoterrain_samples = int(p.render_window.GetMultiSamples())
    if mode not in ("msaa", "auto"):
        p.disable_anti_aliasing()
    p._geoterrain_aa = mode
    return p


def aa_mode(anti_aliasing: bool | str) -> str:
    mode = {True: "msaa", False: "none"}.get(anti_aliasing, anti_aliasing)
    if mode not in ANTI_ALIASING:
        raise UsageError(f"unknown anti-aliasing {anti_aliasing!r}; use "
                         f"{', '.join(ANTI_ALIASING)}")
    return mode


def draw(plotter) -> np.ndarray:
    """Render the plotter's scene and read the picture back (H, W, 3) uint8, without
    VTK's end-of-frame pass.

    A plain ``Render()`` ends with ``Frame()``: the multisampled picture resolved by a
    gamma-correcting full-screen shader into the display framebuffer, then blitted
    again. On a software renderer (llvmpipe) a 1280×720 MSAA render costs about 65 ms
    whatever it draws (a small sphere as much as a 49 k-triangle view of the 4097²
    flight of ``benchmarks/bench_render.py``). Here the buffers are not swapped, so
    ``Frame()`` does not run, and the colours are read from the render framebuffer,
    resolved by the driver's plain average of the samples: that view's render and
    read-back took 52.4 ms instead of 66.7. Only anti-aliased edge pixels differ
    (58.9 dB against the swapped picture, 1.8 % of the pixels). The front buffer is not
    written (black, or an older swapped picture): read pictures with this function (or
    :meth:`geoterrain.rendering.scene.TerrainScene.frame`), not ``plotter.screenshot``. The
    depth buffer is the render framebuffer's, as with swapping. With the plotter's
    ``fxaa`` anti-aliasing the picture is then filtered on the CPU along its depth edges.
    """
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

    plotter._on_first_render_request()  # pyvista's own first-render setup, once
    rw = plotter.render_window
    swap = rw.GetSwapBuffers()
    rw.SwapBuffersOff()
    try:
        plotter.render()
        w, h = rw.GetSize()
        arr = vtkUnsignedCharArray()
        rw.GetPixelData(0, 0, w - 1, h - 1, 0, arr, 0)  # the back (render) buffer
    finally:
        rw.SetSwapBuffers(swap)
    img = np.ascontiguousarray(vtk_to_numpy(arr).reshape(h, w, 3)[::-1])
    if getattr(plotter, "_geoterrain_aa", "msaa") == "fxaa":
        img = fxaa(img, depth_buffer(plotter))
    return img


def writable_target(path: Path, overwrite: bool, folder: bool = False,
                     option: str = "-o") -> None:
    """:func:`geoterrain.core.paths.check_output`: a missing parent folder, anything but a
    regular file (a folder of frames with ``folder``), or an existing one without
    ``overwrite`` is refused."""
    check_output(path, overwrite, folder=folder, option=option)


#: zlib's level for rendered PNGs: 1 is 3.4× faster than Pillow's default 6 on rendered
#: terrain and within 1 % of its size (1280×720 with its overlays, CPU medians of 7 at
#: load 11: 41.5 ms and 890 kB at 1, 60.1 ms and 882 kB at 3, 140.6 ms and 894 kB at 6)
PNG_LEVEL = 1


def write_png(path: str | Path, img: np.ndarray, overwrite: bool = True) -> None:
    """Write a PNG to a hidden partial file, then publish it (never a half-written PNG)."""
    from PIL import Image

    path = Path(path)
    writable_target(path, overwrite)
    remove_stale_partials(path.parent)
    tmp = partial_path(path)
    try:
        # Pillow itself, the format named: imageio's writer (the same bytes) first
        # loads every one of Pillow's image plugins to look the extension up, about
        # 0.1 s of a cold render
        Image.fromarray(np.ascontiguousarray(img, np.uint8)).save(tmp, format="PNG",
                                                                  compress_level=PNG_LEVEL)
        publish(tmp, path, overwrite)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise WriteError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
