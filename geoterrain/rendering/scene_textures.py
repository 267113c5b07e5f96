"""The scene's textures: the whole-terrain texture (``textures="global"``) and its
texture coordinates, or the per-view atlas of a selection
(:mod:`geoterrain.rendering.tiletextures`, seed 000 §2.5), and the VTK image that shows
one. A mixin of :class:`geoterrain.rendering.scene.TerrainScene`, whose state it reads."""

from __future__ import annotations

import numpy as np

from geoterrain.core.view import View
from geoterrain.rendering.textures import texture_image
from geoterrain.rendering.tiletextures import build_view_texture

__all__ = ["SceneTextures"]


class SceneTextures:
    """The scene's textures (a mixin of TerrainScene)."""

    def retexture_all(self) -> None:
        """After the store was edited: the whole-terrain texture (``textures="global"``)
        is made again; per-view textures come from the tiles' shading, which the
        terrain's refresh dropped where the edit reached."""
        self._vtex = None  # its texels may show the data before the edit
        if self.textures == "global" and self.shading != "plain":
            self.texture = tex = self._global_texture()
            if self.actor is not None:
                self.actor.SetTexture(tex)

    def _global_texture(self):
        """The whole-terrain texture (``textures="global"``), interpolated and mipmapped."""
        img = texture_image(self.terrain, self.shading, self.cmap, self.level)
        if self._raw:
            from geoterrain.rendering import offscreen

            # pyvista.Texture's image: its last row first (v = 0 at the bottom)
            return offscreen.texture(_image_data(np.ascontiguousarray(img[::-1])),
                                     mipmap=True)
        import pyvista as pv

        tex = pv.Texture(img)
        tex.interpolate = True
        tex.mipmap = True
        tex.repeat = False
        return tex

    def _tcoords(self, ij: np.ndarray) -> np.ndarray:
        R, C = self.terrain.grid.level_shape(self.level)  # the texture_image's shape
        s = float(1 << self.level)
        tc = np.empty((len(ij), 2), np.float32)
        tc[:, 0] = (ij[:, 1] / s + 0.5) / C
        tc[:, 1] = 1.0 - (ij[:, 0] / s + 0.5) / R
        return tc

    def view_texture(self, selection, view: View, max_builds: int | None = None):
        """The per-view atlas of ``selection`` (:mod:`geoterrain.rendering.tiletextures`), or None.

        Thread-safe to call off the UI thread (it touches no VTK object); pass the
        result to :meth:`update`. ``max_builds``: at most this many tiles shaded anew,
        the rest magnified from cached ancestors
        (:func:`~geoterrain.rendering.tiletextures.build_view_texture`). Where the atlas
        shown holds the same tiles at the same places, its image is kept, and
        :meth:`update` uploads no texture.
        """
        if self.shading == "plain" or self.textures != "view":
            return None
        return build_view_texture(self.terrain, selection, view, self.shader,
                                  max_builds=max_builds, previous=self._vtex)


def _image_data(img: np.ndarray):
    """A vtkImageData sharing (not copying) a C-contiguous (H, W, 3) uint8 ``img``, its
    row 0 at v = 0 (as :class:`geoterrain.rendering.tiletextures.ViewTexture` maps it); ``img``
    must stay unchanged while it is shown."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData

    h, w = img.shape[:2]
    out = vtkImageData()
    out.SetDimensions(w, h, 1)
    arr = numpy_to_vtk(np.ascontiguousarray(img).reshape(-1, 3), deep=False)
    arr.SetName("atlas")
    out.GetPointData().SetScalars(arr)
    return out
