"""The streaming preprocess's stages on row bands, each the twin of a
whole-grid stage.
"""

__all__ = ["codec", "delta", "normals", "quantize", "radii", "tiles"]
