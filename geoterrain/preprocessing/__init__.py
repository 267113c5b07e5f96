"""The preprocess: DEM → padded pyramid → bounds, normals, codec → store, on the
whole grid or streamed in row bands (``bands/``), on a scheduler.
"""

__all__ = ["bands", "levelblobs", "passes", "pipeline", "schedulers", "scratch", "storewrite",
           "streaming", "surface"]
