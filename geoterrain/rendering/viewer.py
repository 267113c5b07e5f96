"""Interactive viewer: the LOD mesh follows the camera.

The update logic lives in :class:`ViewerController`, which works on any
PyVista plotter (an offscreen one in the tests): ``on_camera_changed()``
re-selects the LOD for the plotter's camera (throttled) and updates the terrain
actor in place; key handlers are plain methods.

Keys: ``m`` strategy, ``+``/``-`` coarser/finer detail (the pixel error τ ×/÷ 2),
``g`` geomorphing on/off, ``x`` wireframe, ``c`` colour (shading / LOD level / tile),
``space`` freeze the LOD, ``h`` reset the view, ``s`` save a screenshot (overlays
included), ``t`` the engine's timings on/off, ``q`` quit.

The camera moves as on a terrain (VTK's terrain interactor style): dragging turns
around the vertical and tilts, and never rolls, so the horizon stays level. The
status line sits on an opaque box and says, in plain words, the strategy, the detail
(pixels on screen), the triangles drawn and the time a frame takes, and when the view
is being updated; ``t`` adds the engine's own figures (selection and texture times,
tiles decoded). A colour bar (metres; a legend of the detail levels while the triangles
are coloured by level) and a north arrow that turns with the view stay on screen. With
``background`` the worker thread also builds the frame's textures, so the window only swaps them in;
while the camera moves frames are drawn without multisampling, and once it has rested
``REST_MS`` the view is drawn again with it (screenshots always are). Once the window
is up, the objects of the imports and the first frame are frozen out of the garbage
collector (``gc.freeze``): a full collection over them held the GIL, and so the
window, for 80 ms. ``benchmarks/bench_viewer.py`` measures all of this through the
controller.

Examples
--------
>>> import geoterrain
>>> from geoterrain.rendering.viewer import show
>>> show(geoterrain.open("dem.geoterrain"))  # doctest: +SKIP
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from geoterrain import lod
from geoterrain.core.view import View
from geoterrain.lod.registry import DEFAULT, strategy_info
from geoterrain.rendering.cameras import default_view
from geoterrain.rendering.colours import Palette
from geoterrain.rendering.drape import Drape
from geoterrain.rendering.scene import TerrainScene, store_snapshot
from geoterrain.rendering.shading import Light
from geoterrain.rendering.viewer_hud import HELP, ViewerHud, _length  # noqa: F401
from geoterrain.rendering.viewer_keys import COLOR_MODES, ViewerKeys  # noqa: F401
from geoterrain.rendering.viewer_style import mute_style_timers

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

POLL_MS = 16.0  # background mode, idle: how often the window looks for a finished frame
# background mode, a frame in flight: looked for this often (a second, repeating timer,
# made when the frame is submitted and destroyed once nothing is in flight), so a
# finished frame waits ≤ 4 ms for the window, not up to a whole idle period
BUSY_POLL_MS = 4.0
REST_MS = 250.0  # the camera still this long: drawn again with anti-aliasing
# how often the window looks whether its store was edited (geoterrain edit, Terrain.edit)
STORE_POLL_MS = 500.0
# texture tiles a camera move may shade before its picture is shown (~0.5 ms each);
# the rest are magnified from cached coarser tiles and shaded by the passes that follow
TEXTURE_BUILDS = 24


class ViewerController(ViewerHud, ViewerKeys):
    """Re-selects the LOD when the camera moves and updates the scene in place.

    Parameters
    ----------
    plotter : pyvista.Plotter (interactive or offscreen)
    terrain : Terrain
    strategy, pixel_error, shading, cmap : as in :func:`geoterrain.render.render`.
    throttle_ms : synchronous mode: minimum time between two selections; camera events
        in between are coalesced and handled by :meth:`poll` (a repeating timer).
    background : select in a worker thread so the window never waits for a selection
        (the mesh is swapped in by :meth:`poll` when ready); the interactive default.
    keys : whether the window has the key bindings (the HUD lists them); False in a web
        page or a notebook, where only the mouse reaches the plotter.

    Examples
    --------
    >>> import pyvista as pv
    >>> p = pv.Plotter(off_screen=True, window_size=(640, 360))  # doctest: +SKIP
    >>> c = ViewerController(p, t)  # doctest: +SKIP
    >>> p.camera.position = (0, -5000, 3000); c.on_camera_changed(force=True)  # doctest: +SKIP
    >>> c.stats["triangles"]  # doctest: +SKIP
    """

    def __init__(self, plotter, terrain: TerrainLike, strategy: str = DEFAULT,
                 pixel_error: float = 1.0,
                 shading: str = "normals", cmap: str | Palette = "auto",
                 throttle_ms: float = 100.0,
                 background: bool = False, light: Light | None = None,
                 drape: Drape | None = None, occlusion: bool = True,
                 morph: bool | None = None, water: bool = True, keys: bool = True):
        strategy_info(strategy)
        self.keys = bool(keys)
        self.plotter, self.terrain = plotter, terrain
        self.strategy, self.pixel_error = strategy, float(pixel_error)
        self.throttle_ms = throttle_ms
        self.scene = TerrainScene(plotter, terrain, shading, cmap, light=light, drape=drape,
                                  water=water)
        self.frozen = False
        self.wireframe = False
        self.color_mode = "shading"
        self.pending = False
        self.stats: dict = {}
        self.selections = 0
        self.frame_ms = 0.0
        self._busy = False
        self._gc_frozen = False
        # anti-aliasing (MSAA) off while the camera moves, back on once it rests; the
        # window's own setting is read at the first move (the window is up by then)
        self._msaa: int | None = None
        self._moving = False
        self._moved_t = 0.0
        self.still_ms = 0.0  # the last anti-aliased redraw at rest
        self._last_t = -1e9
        self._last_key: tuple = ()
        self._future = None
        self._executor = None
        self._store_t = time.perf_counter()  # when the store was last looked at
        self.edits_shown = 0  # store edits taken in and redrawn
        self._deferred = 0  # stand-in texture tiles in the picture shown
        self._shown_view: View | None = None  # the view the shown textures were made for
        self._closed = False
        self._iren = None  # the window's interactor, once bound (its timers)
        self._busy_timer: int | None = None  # the busy-poll timer's id while it runs
        self._hud = plotter.add_text("", position="upper_left", font_size=10, name="hud")
        tp = self._hud.GetTextProperty()  # an opaque box: readable over any terrain
        tp.SetColor(0.1, 0.1, 0.1)
        tp.SetBackgroundColor(1.0, 1.0, 1.0)
        tp.SetBackgroundOpacity(0.85)
        tp.SetFrame(True)
        tp.SetFrameColor(0.6, 0.6, 0.6)
        self.message = ""
        self.screenshots = 0
        self.telemetry = False  # key t: the engine's figures in the status line
        self._legend(cmap)
        # the selections' switches (key g toggles the morphing)
        self.occlusion, self.morph = bool(occlusion), morph
        plotter.renderer.AddObserver("StartEvent", self._clip)
        self.home = default_view(terrain, tuple(plotter.window_size))
        self._go_home()
        self.on_camera_changed(force=True)  # the first selection, synchronously
        if background:
            from concurrent.futures import ThreadPoolExecutor

            self._executor = ThreadPoolExecutor(1, thread_name_prefix="geoterrain-lod")

    # ----------------------------------------------------------------- views
    def current_view(self) -> View:
        """The :class:`View` of the plotter's camera."""
        return View.from_camera(self.plotter.camera, tuple(self.plotter.window_size))

    def _camera_key(self) -> tuple:
        c = self.plotter.camera
        return (tuple(c.position), tuple(c.focal_point), tuple(c.up), float(c.view_angle),
                tuple(self.plotter.window_size), self.strategy, self.pixel_error)

    def _view(self) -> View:
        """The camera's view, clipped to the terrain's box as :meth:`_clip` draws it."""
        cam = self.plotter.camera
        return View(tuple(cam.position), tuple(cam.focal_point), tuple(cam.up),
                    float(cam.view_angle), tuple(self.plotter.window_size)
                    ).clipped_to(*self.terrain.scene_box())

    def _clip(self, *_args) -> None:
        """Before each draw: the clipping range the selection assumed (VTK would fit it
        to the mesh drawn, and a nearer near plane could show what culling left out)."""
        v = self._view()
        self.plotter.camera.clipping_range = (v.near, v.far)
        if getattr(self, "_compass", None) is not None:
            self._compass.update(v)

    def on_camera_changed(self, *_args, force: bool = False) -> bool:
        """Re-select the LOD for the current camera (unless frozen, unchanged or throttled).

        Synchronous mode: selects and updates now; returns True when it did.
        Background mode: starts the selection in a worker thread (returns True) unless
        one is running (then it is queued); :meth:`poll` shows the result.
        """
        if self._busy or self._closed or (self.frozen and not force):
            return False
        key = self._camera_key()
        if key == self._last_key and not force:
            return False
        if self._executor is not None:
            if self._future is not None and not self._future.done():
                self.pending = True
                return False
            view, strategy, tau = self._view(), self.strategy, self.pixel_error
            self.pending = False
            self._motion()
            self._future = self._executor.submit(self._work, key, view, strategy, tau)
            self._arm()
            self._update_hud()  # the busy sign
            return True
        now = time.perf_counter()
        if not force and (now - self._last_t) * 1e3 < self.throttle_ms:
            self.pending = True
            return False
        sel = lod.select(self.terrain, self._view(), pixel_error=self.pixel_error,
                         strategy=self.strategy, occlusion=self.occlusion, morph=self.morph)
        self._apply(key, sel)
        return True

    def _work(self, key: tuple, view: View, strategy: str, tau: float):
        """Worker thread: the selection and its textures (no VTK call), read in one
        snapshot of the store (as :meth:`TerrainScene.prepare`), while the UI thread
        shows and draws the frame before."""
        with store_snapshot(self.terrain):
            sel = lod.select(self.terrain, view, pixel_error=tau, strategy=strategy,
                             occlusion=self.occlusion, morph=self.morph)
            return self._retexture(key, sel, view)

    def _retexture(self, key: tuple, sel, view: View):
        """Worker thread: the textures of ``sel``, at most ``TEXTURE_BUILDS`` tiles shaded
        anew (the rest stand in from coarser tiles until a later pass)."""
        return key, sel, self.scene.view_texture(sel, view, TEXTURE_BUILDS), view

    @property
    def refining(self) -> bool:
        """Whether the picture shown still has magnified stand-in textures."""
        return self._deferred > 0

    def _apply(self, key: tuple, sel, vtex=None, refined: bool = False) -> None:
        """Show a finished selection, or (``refined``) the same one with more of its
        textures shaded (main thread: VTK calls)."""
        self._busy = True
        try:
            t0 = time.perf_counter()
            self.ui_ms = 0.0
            self.scene.update(sel, vtex=vtex)
            self._apply_style()
            self.plotter.renderer.ResetCameraClippingRange()
            self.stats = dict(sel.stats)
            self.selections += 0 if refined else 1
            self._last_key = key
            self._last_t = time.perf_counter()
            self.frame_ms = (self._last_t - t0) * 1e3
            self.ui_ms = self.frame_ms  # main-thread time of this swap
            self._update_hud()
        finally:
            self._busy = False

    def poll(self, *_args) -> bool:
        """Timer callback: show a finished background selection, start a queued one.

        Returns True when the scene changed.
        """
        changed = False
        self.watch_store()
        if not self._gc_frozen:
            # the window is up: what the imports, VTK and the first frame made is kept
            # for good, so a full garbage collection (the GIL held, the window frozen)
            # no longer walks it (the longest UI block 81.7 → 4 ms, benchmarks/bench_viewer.py;
            # docs/lab/viewer.md)
            gc.freeze()
            self._gc_frozen = True
        f = self._future
        refine = None
        if f is not None and f.done() and f.cancelled():  # close() dropped it unstarted
            self._future = f = None
        if f is not None and f.done():
            self._future = None
            key, sel, vtex, view = f.result()
            refined = sel is self.scene.selection  # a texture pass over the shown selection
            if refined or not self.frozen or key[-2:] != self._last_key[-2:]:
                self._apply(key, sel, vtex, refined)
                self._shown_view = view
                changed = True
                before = self._deferred if refined else None
                self._deferred = 0 if vtex is None else vtex.stats.get("textures_deferred", 0)
                # another pass only while passes make progress (an LRU cache too small
                # for the view's textures, or a zero budget, would never finish)
                if self._deferred and TEXTURE_BUILDS >= 1 and \
                        (before is None or self._deferred < before):
                    refine = (key, sel, view)
            else:  # frozen: the shown selection stays, and so do its texture passes
                if self._deferred:
                    refine = (self._last_key, self.scene.selection, self._shown_view)
                self._update_hud()  # no longer busy
        if self.pending and not self.frozen:
            self.pending = False
            if self._executor is None:
                changed |= self.on_camera_changed()
            else:
                self.on_camera_changed(force=True)
        elif refine is not None and not self._closed:  # the camera is still: shade the
            self._future = self._executor.submit(self._retexture, *refine)  # next stand-ins
        self._arm()  # polled every BUSY_POLL_MS while a frame is in flight, else not
        if changed:
            t0 = time.perf_counter()
            self.plotter.render()
            self.frame_ms += (time.perf_counter() - t0) * 1e3
            self._update_hud()
        elif self._moving and self._future is None and not self.pending and \
                (time.perf_counter() - self._moved_t) * 1e3 >= REST_MS:
            self.settle()
        return changed

    def watch_store(self, force: bool = False) -> bool:
        """Every ``STORE_POLL_MS`` (or now with ``force``), while no frame is in flight:
        when the store was edited (``geoterrain edit`` in another process, or
        :meth:`~geoterrain.terrain.Terrain.edit`), take the edit in
        (:meth:`~geoterrain.terrainlike.TerrainLike.refresh`: the tiles it reached are
        decoded again) and select and draw the view anew. Returns whether it did."""
        now = time.perf_counter()
        if self._closed or self._busy or (self._future is not None and not self._future.done()):
            return False
        if not force and (now - self._store_t) * 1e3 < STORE_POLL_MS:
            return False
        self._store_t = now
        if not self.terrain.refresh():
            return False
        self.edits_shown += 1
        light = self.scene.light
        if light is not None and (light.shadows or light.ambient_occlusion):
            self.terrain.clear_cache()  # shadows and sky view reach far beyond an edit
        self.scene.retexture_all()
        self._last_key = ()
        self._refresh()
        return True

    def _arm(self) -> None:
        """While a background frame is in flight, have the window poll every
        ``BUSY_POLL_MS`` (one repeating timer); once nothing is, destroy that timer (the
        idle ``POLL_MS`` timer goes on)."""
        if self._iren is None:
            return
        busy = self._future is not None and not self._closed
        if busy and self._busy_timer is None:
            tid = self._iren.create_timer(int(BUSY_POLL_MS), repeating=True)
            self._busy_timer = tid or None  # 0: VTK made no timer
        elif not busy and self._busy_timer is not None:
            self._iren.interactor.DestroyTimer(self._busy_timer)
            self._busy_timer = None

    def _motion(self) -> None:
        """The camera moves: draw without multisampling (about half the software
        renderer's draw time at 1280×720) until it rests."""
        rw = self.plotter.render_window
        if self._executor is not None and rw is not None and not self._moving:
            if self._msaa is None:
                self._msaa = int(rw.GetMultiSamples())
            if self._msaa:
                rw.SetMultiSamples(0)
                self._moving = True
        self._moved_t = time.perf_counter()

    def settle(self) -> bool:
        """The camera rests: draw once more with the window's anti-aliasing (called by
        :meth:`poll` ``REST_MS`` after the last move, and before a screenshot).
        Returns True when it drew."""
        if not self._moving:
            return False
        self._moving = False
        self.plotter.render_window.SetMultiSamples(self._msaa)
        t0 = time.perf_counter()
        self.plotter.render()
        self.still_ms = (time.perf_counter() - t0) * 1e3
        return True

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the running background selection is shown with all its textures
        (its refinement passes included; for scripts and tests). ``timeout`` is per pass."""
        changed = False
        while self._future is not None:
            if not self._future.cancelled():
                self._future.result(timeout)
            changed |= self.poll()
        return changed

    def follow(self, interactor, on_update: Callable[[bool], None] | None = None) -> None:
        """Let the LOD follow the camera where the mouse reaches the plotter through
        ``interactor`` (a VTK interactor) but no window runs this controller's timers (a
        web page, a notebook): a throttled selection per camera change while dragging, and
        the camera's own selection once the interaction ends. ``on_update(final)`` is
        called after a selection during the drag (``final`` False) and at its end (True).

        Examples
        --------
        >>> import pyvista as pv  # doctest: +SKIP
        >>> p = pv.Plotter(off_screen=True)  # doctest: +SKIP
        >>> c = ViewerController(p, t, keys=False)  # doctest: +SKIP
        >>> c.follow(p.iren.interactor)  # doctest: +SKIP
        """
        def moved(*_args) -> None:
            if self.on_camera_changed() and on_update is not None:
                on_update(False)

        def released(*_args) -> None:
            if not self.on_camera_changed() and self.pending:  # the last move was throttled
                self.on_camera_changed(force=True)
            if on_update is not None:
                on_update(True)

        self.plotter.camera.AddObserver("ModifiedEvent", moved)
        interactor.AddObserver("EndInteractionEvent", released)

    def close(self) -> None:
        """Stop the worker thread (and the busy-poll timer)."""
        self._closed = True
        self._arm()
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)

    @property
    def busy(self) -> bool:
        """A selection is running in the worker thread."""
        return self._future is not None and not self._future.done()

    def bind(self) -> None:
        """Attach camera observers, a polling timer and the keys to the plotter."""
        p = self.plotter
        p.camera.AddObserver("ModifiedEvent", self.on_camera_changed)
        keys = {"m": self.next_strategy, "g": self.toggle_morph,
                "plus": self.tau_up, "equal": self.tau_up,
                "KP_Add": self.tau_up, "minus": self.tau_down, "KP_Subtract": self.tau_down,
                "x": self.toggle_wireframe, "c": self.next_color_mode,
                "space": self.toggle_freeze, "h": self.reset_view, "s": self.screenshot,
                "t": self.toggle_telemetry}
        for k, fn in keys.items():
            p.add_key_event(k, fn)
        if p.iren is not None:
            p.enable_terrain_style(mouse_wheel_zooms=True)  # no roll: the horizon stays level
            mute_style_timers(p.iren.interactor.GetInteractorStyle())
        if p.iren is not None and not p.off_screen:
            p.iren.add_observer("EndInteractionEvent", self.poll)
            self._iren = p.iren
            p.iren.add_observer("TimerEvent", self.poll)  # the idle timer or the busy one
            idle = POLL_MS if self._executor is not None else self.poll_ms
            p.iren.create_timer(int(idle), repeating=True)

    @property
    def poll_ms(self) -> float:
        """The polling period now: a finished background frame waits at most this long
        to be shown (``BUSY_POLL_MS`` while one is in flight, else ``POLL_MS``);
        synchronous mode polls at the throttle."""
        if self._executor is None:
            return max(self.throttle_ms, 30.0)
        return BUSY_POLL_MS if self._future is not None else POLL_MS




def show(terrain: TerrainLike, strategy: str = DEFAULT, pixel_error: float = 1.0, *,
         shading: str = "normals", cmap: str | Palette = "auto",
         size: tuple[int, int] = (1280, 720),
         title: str | None = None, throttle_ms: float = 100.0,
         light: Light | None = None, drape: Drape | None = None, occlusion: bool = True,
         morph: bool | None = None, water: bool = True) -> ViewerController:
    """Open an interactive window on the terrain; the LOD follows the camera (its
    selections cull with ``occlusion`` and geomorph with ``morph``, as
    :func:`geoterrain.lod.select`'s).

    Keys: ``m`` strategy, ``+``/``-`` coarser/finer detail, ``g`` morph, ``x`` wireframe,
    ``c`` colour by shading / LOD level / tile, ``space`` freeze the LOD, ``h`` home,
    ``s`` screenshot, ``t`` the engine's timings, ``q`` quit.

    Examples
    --------
    >>> import geoterrain
    >>> show(geoterrain.open("dem.geoterrain"), strategy="chunked")  # doctest: +SKIP
    """
    import pyvista as pv

    p = pv.Plotter(window_size=list(size), title=title or f"geoterrain — {terrain.path.name}")
    ctl = ViewerController(p, terrain, strategy, pixel_error, shading, cmap, throttle_ms,
                           background=True, light=light, drape=drape, occlusion=occlusion,
                           morph=morph, water=water)
    ctl.bind()
    try:
        p.show()
    finally:
        ctl.close()
    return ctl
