"""The scene's frames: a view's selection and atlas prepared (in one snapshot of the
store), drawn and read back, with the frame's stats (times, CPU, tiles decoded, bytes
read); a flight's frames, the next one prepared while one is drawn. A mixin of
:class:`geoterrain.rendering.scene.TerrainScene`, whose state it reads."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from geoterrain import lod
from geoterrain.core.memory import peak_rss as _peak_rss
from geoterrain.core.threads import serial_for, serial_kernels
from geoterrain.core.view import View
from geoterrain.lod.registry import DEFAULT
from geoterrain.rendering.antialias import depth_buffer
from geoterrain.rendering.edgeaa import edge_antialias
from geoterrain.rendering.window import draw

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Prepared", "SceneFrames", "io_counters", "peak_rss", "store_snapshot"]


class SceneFrames:
    """The scene's frames (a mixin of TerrainScene)."""

    def frame(self, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT,
              ) -> tuple[np.ndarray, dict]:
        """Select the LOD for ``view``, draw it and return the image (H, W, 3) uint8 and stats.

        The stats count what the whole frame did (selection and texture):
        ``tiles_decoded`` (heights), ``normals_decoded``, ``bounds_decoded`` (δ, r),
        ``textures_built``, ``atlas_reused`` (the atlas shown before was kept: no texel
        copied or uploaded), ``bytes_read`` and ``peak_rss_mb`` (the process's peak
        resident memory so far), besides the selection's own stats. ``bytes_read`` is every
        byte read from the store file since the scene's previous frame, as the operating
        system counts them (:attr:`geoterrain.terrain.Terrain.bytes_read`); the first frame's
        count starts where the scene was made, or where the store was opened when nothing
        was read from it since (then it includes the opening), so the frames' counts add up
        to what the process read from the store. Times: ``select_ms``,
        ``texture_ms``, ``render_ms`` (the draw and read-back) and ``frame_ms``, wall
        clock; ``cpu_ms`` and ``render_cpu_ms``, the process's CPU time over the frame
        and over the draw, the renderer's threads included (a software renderer draws
        on every core, so ``render_cpu_ms`` can exceed ``render_ms``).
        ``anti_aliasing`` is the one the picture got (under ``auto``: ``edges`` or
        ``msaa``, :meth:`_anti_aliasing`); ``render_ms`` includes finding and blending
        the edges.
        """
        p = self.prepare(view, pixel_error, strategy)
        return self.draw(p.selection, p.view, p.started, p.vtex, read=p.read)

    def prepare(self, view: View, pixel_error: float = 1.0, strategy: str = DEFAULT
                ) -> Prepared:
        """The store's half of :meth:`frame`: the selection for ``view`` and its atlas
        (:meth:`view_texture`), read in one snapshot of the store (one read transaction:
        its version checked once, not at every blob). It makes no VTK object (the
        selection's mesh is :class:`~geoterrain.lod.mesh.MeshParts`, the atlas numpy
        arrays), so it may run on a worker thread while the picture before is drawn
        (:meth:`frames`), once that picture's mesh is shown (its atlas is the one this
        atlas may keep): a VTK object made there while this thread frees one could
        deadlock the two threads (VTK's garbage collector's lock and the GIL).

        Examples
        --------
        >>> p = scene.prepare(default_view(t, (320, 240)))  # doctest: +SKIP
        >>> img, st = scene.draw(p.selection, p.view, p.started, p.vtex,  # doctest: +SKIP
        ...                      read=p.read)
        """
        t = self.terrain
        if view.near is None or view.far is None:  # the picture's own clipping planes
            view = view.clipped_to(*t.scene_box())
        c0 = io_counters(t)
        t0, p0 = time.perf_counter(), time.process_time()
        with self._kernels(), store_snapshot(t):
            sel = lod.select(t, view, pixel_error=pixel_error, strategy=strategy,
                             occlusion=self.occlusion, morph=self.morph)
            vtex = self.view_texture(sel, view)
        return Prepared(view, sel, vtex, (t0, p0, c0), io_counters(t))

    def frames(self, views: Sequence[View], pixel_error: float = 1.0,
               strategy: str = DEFAULT, overlap: bool = False
               ) -> Iterator[tuple[np.ndarray, dict]]:
        """:meth:`frame` of each of ``views`` in turn (a flight: every camera known
        beforehand), yielded as each picture is done.

        ``overlap``: view n + 1's :meth:`prepare` (selection and atlas, compiled passes
        that release the GIL, and the store's reads) runs on a worker thread while view n
        is drawn, where the renderer's own threads leave a core idle; the draw stays on
        this thread (VTK's). The pictures are :meth:`frame`'s, byte for byte (the same
        steps in the same order on the same data: view n + 1's atlas is made once view n's
        is shown, as without overlap). A picture comes out no later than without it, but
        each camera must be known one frame before its picture is drawn. Besides
        :meth:`frame`'s stats (whose ``frame_ms`` and ``cpu_ms`` then run from its
        prepare's start, on the worker, to its picture: the latency), ``interval_ms`` and
        ``interval_cpu_ms`` are the wall and process CPU time since the previous picture
        (the throughput; the first from the call).

        Examples
        --------
        >>> for img, st in scene.frames(orbit_views(t, 8)):  # doctest: +SKIP
        ...     print(st["interval_ms"])
        """
        views = list(views)
        last = (time.perf_counter(), time.process_time())

        def stamp(st: dict) -> dict:
            nonlocal last
            now = (time.perf_counter(), time.process_time())
            st["interval_ms"] = round((now[0] - last[0]) * 1e3, 3)
            st["interval_cpu_ms"] = round((now[1] - last[1]) * 1e3, 3)
            last = now
            return st

        if not overlap or len(views) < 2:
            for v in views:
                img, st = self.frame(v, pixel_error, strategy)
                yield img, stamp(st)
            return
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(1, thread_name_prefix="geoterrain-prepare") as ex:
            nxt = ex.submit(self.prepare, views[0], pixel_error, strategy)
            for k in range(len(views)):
                p = nxt.result()
                after = None
                if k + 1 < len(views):
                    def after(v=views[k + 1]):  # view n's mesh and atlas are shown
                        nonlocal nxt
                        nxt = ex.submit(self.prepare, v, pixel_error, strategy)
                img, st = self.draw(p.selection, p.view, p.started, p.vtex, read=p.read,
                                    before_render=after)
                yield img, stamp(st)

    def draw(self, sel: lod.Selection, view: View, started: tuple | None = None,
             vtex=None, *, read: dict | None = None, before_render=None
             ) -> tuple[np.ndarray, dict]:
        """Draw a selection made for ``view`` (by :meth:`frame`, or by a strategy called
        with arguments of its own, as the benchmark experiments do) and return the image
        and the stats of :meth:`frame`; ``started``: (wall clock, process clock, io
        counters) when the selection began, else the draw's own start. ``vtex``: its
        atlas, made already (:meth:`prepare`), and ``read``: the io counters at the end
        of the reads (else they are taken after the draw). ``before_render``: called once
        the mesh is shown and the camera set, before the renderer draws (:meth:`frames`
        starts the next view's :meth:`prepare` there).

        Examples
        --------
        >>> img, stats = scene.draw(sel, view)  # doctest: +SKIP
        """
        t = self.terrain
        if view.near is None or view.far is None:
            view = view.clipped_to(*t.scene_box())
        t1 = time.perf_counter()
        t0, p0, c0 = started if started is not None else (t1, time.process_time(),
                                                         io_counters(t))
        with self._kernels():
            self.update(sel, view, vtex)
            self.set_camera(view)
            self.cull_faces_turned_away(view)
            t2, p2 = time.perf_counter(), time.process_time()
            edges, aa = self._anti_aliasing()
            if before_render is not None:
                before_render()
            img = draw(self.plotter)
            if edges is not None:
                img = edge_antialias(img, depth_buffer(self.plotter), edges)
        t3, p3 = time.perf_counter(), time.process_time()
        c1 = dict(read) if read is not None else io_counters(t)
        c0["bytes_read"], self._bytes_mark = self._bytes_mark, c1["bytes_read"]
        stats = {**sel.stats, "select_tiles_decoded": sel.stats.get("tiles_decoded", 0),
                 **{k: c1[k] - c0[k] for k in c0},
                 "textures_built": int(self.texture_stats.get("textures_built", 0)),
                 "texture_tiles": int(self.texture_stats.get("texture_tiles", 0)),
                 "texture_ms": float(self.texture_stats.get("texture_ms", 0.0)),
                 "atlas_reused": bool(self.texture_stats.get("atlas_reused", False)),
                 "peak_rss_mb": round(peak_rss() / 2**20, 1),
                 "update_ms": round((t2 - t1) * 1e3, 3),
                 "render_ms": round((t3 - t2) * 1e3, 3),
                 "frame_ms": round((t3 - t0) * 1e3, 3),
                 "anti_aliasing": aa,
                 "cpu_ms": round((p3 - p0) * 1e3, 3),
                 "render_cpu_ms": round((p3 - p2) * 1e3, 3)}
        return img, stats

    def _kernels(self) -> AbstractContextManager:
        """Where a frame's compiled kernels run: on the calling thread (their serial
        twins, :func:`~geoterrain.core.threads.serial_kernels`) for a store of fewer
        than :data:`~geoterrain.core.threads.PARALLEL_MIN_SAMPLES` samples, whose whole
        frame is small work (:func:`~geoterrain.core.threads.cores_for`'s line), else as
        each call chooses. The same pixels either way; a small store's first render then
        compiles the twins only, not the threaded kernels as well.

        Examples
        --------
        >>> with scene._kernels():  # doctest: +SKIP
        ...     pass
        """
        if serial_for(self._samples):
            return serial_kernels()
        return contextlib.nullcontext()

    def terrain_fraction(self) -> float:
        """Fraction of the last image's pixels covered by terrain (its depth buffer, read
        without rendering again)."""
        if self.mesh.n_cells == 0:
            return 0.0
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

        f = vtkWindowToImageFilter()
        f.SetInput(self.plotter.render_window)
        f.ShouldRerenderOff()
        f.ReadFrontBufferOff()
        f.SetInputBufferTypeToZBuffer()
        f.Update()
        z = vtk_to_numpy(f.GetOutput().GetPointData().GetScalars())
        return float((z < 1.0).mean())


class Prepared(NamedTuple):
    """What :meth:`TerrainScene.prepare` made for a picture: its ``view`` (with clipping
    planes), ``selection``, atlas ``vtex`` (None without per-view textures), ``started``
    (wall clock, process clock, io counters at its start) and ``read`` (the io counters
    at its end)."""

    view: View
    selection: lod.Selection
    vtex: object
    started: tuple
    read: dict


def store_snapshot(terrain: TerrainLike) -> AbstractContextManager:
    """``terrain``'s :meth:`~geoterrain.terrain.Terrain.snapshot` (one read transaction:
    the store's version read once, not at every blob), or nothing for a terrain without
    one.

    Examples
    --------
    >>> with store_snapshot(t):
    ...     sel = lod.select(t, default_view(t, (320, 240)))  # doctest: +SKIP
    """
    snap = getattr(terrain, "snapshot", None)
    return snap() if snap is not None else contextlib.nullcontext()


def io_counters(terrain: TerrainLike) -> dict:
    """The terrain's running counts of decoded tiles (by kind) and store bytes read."""
    return {"tiles_decoded": int(terrain.decoded_tiles),
            "normals_decoded": int(getattr(terrain, "decoded_normals", 0)),
            "bounds_decoded": int(getattr(terrain, "decoded_bounds", 0)),
            "bytes_read": int(getattr(terrain, "bytes_read", 0))}


def peak_rss() -> int:
    """Peak resident memory of this process in bytes (:func:`geoterrain.core.memory.peak_rss`)."""
    return _peak_rss()
