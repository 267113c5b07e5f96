"""What every stage shares: the padded grid and bintree arithmetic, the scene frame
(pyproj), the View, rounding that keeps a bound a bound, memory and threads, progress,
atomic output files and bounded zstd.
"""

__all__ = ["_fork", "atomicfiles", "bintree", "frame", "grid", "limits", "memory", "paths",
           "progress", "rounding", "threads", "view", "zstdsafe"]
