"""Pictures: the offscreen scene, view-dependent textures and their shading,
colours, drapes, overlays, anti-aliasing, cameras, animations, the interactive viewer and
the notebook.
"""

__all__ = ["animation", "antialias", "atlaskernels", "cameras", "colours", "drape", "edgeaa",
           "gifstream", "notebook", "overlays", "scene", "shading", "textures", "tileshade",
           "tiletextures", "viewer", "viewer_style"]
