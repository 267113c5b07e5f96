"""Memory: how much is available (to check a job's need before it allocates), and
zeroed arrays that stay sparse in memory."""

from __future__ import annotations

import mmap
import os
import sys

import numpy as np


def _proc_kib(path: str, field: str) -> int | None:
    """The kB figure of ``field`` in a /proc file, or None (not Linux, or absent)."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(field):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


def available_memory() -> int:
    """Bytes of memory available now (``MemAvailable``; physical memory elsewhere).

    Examples
    --------
    >>> available_memory() > 0
    True
    """
    v = _proc_kib("/proc/meminfo", "MemAvailable:")
    if v is not None:
        return v * 1024
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 62


def peak_rss() -> int:
    """Peak resident memory of this process's own image in bytes.

    Linux's ``VmHWM`` (reset when a process execs), else ``ru_maxrss``. Not
    ``ru_maxrss`` on Linux: it survives ``execve``, so a process started by a large
    parent (a test runner that preprocessed a 16385² DEM) reports the parent's peak
    (7.2 GB for a render that peaked at 0.7 GB).

    Examples
    --------
    >>> peak_rss() > 0
    True
    """
    v = _proc_kib("/proc/self/status", "VmHWM:")
    if v is not None:
        return v * 1024
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r if sys.platform == "darwin" else r * 1024)


def current_rss() -> int:
    """Resident memory of this process now, in bytes (Linux's ``VmRSS``; else
    :func:`peak_rss`).

    Examples
    --------
    >>> 0 < current_rss() <= peak_rss()
    True
    """
    v = _proc_kib("/proc/self/status", "VmRSS:")
    return v * 1024 if v is not None else peak_rss()


def sparse_zeros(shape: tuple[int, ...], dtype=np.uint8) -> np.ndarray:
    """A zeroed array whose memory is committed 4 KiB page by page as it is written.

    numpy asks Linux for transparent huge pages on large allocations, so one write
    commits 2 MiB. For per-sample flags over a whole grid, written at a few thousand
    scattered samples a frame, that makes memory follow the grid's size: a 16385²
    flag array written at 5 000 coarse vertices committed 180 MB. Here the pages are
    an anonymous mapping advised against huge pages, and memory follows the writes.

    Examples
    --------
    >>> a = sparse_zeros((1000, 1000))
    >>> a[500, 500] = 7
    >>> int(a.sum()), a.dtype.name, a.shape
    (7, 'uint8', (1000, 1000))
    """
    dt = np.dtype(dtype)
    if not hasattr(mmap, "MAP_ANONYMOUS"):  # not a POSIX system: numpy's own zeros
        return np.zeros(shape, dt)
    n = max(1, int(np.prod(shape, dtype=np.int64)) * dt.itemsize)
    buf = mmap.mmap(-1, n, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    if hasattr(mmap, "MADV_NOHUGEPAGE"):
        buf.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(buf, dt, count=int(np.prod(shape, dtype=np.int64))).reshape(shape)
