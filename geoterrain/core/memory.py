"""Memory: how much is available (to check a job's need before it allocates), and
zeroed arrays that stay sparse in memory."""

from __future__ import annotations

import gc
import mmap
import os
import sys
import threading
import weakref
from collections.abc import Iterator
from contextlib import contextmanager

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


def release_free_heap() -> bool:
    """Hand the C heap's free pages back to the system now (glibc's ``malloc_trim(0)``):
    memory freed by a finished stage that glibc would keep (free chunks below a live one,
    and in the arenas of numba's and GDAL's threads) stops counting as resident. True when
    pages were returned; False where the C library has no such call (not glibc).

    Examples
    --------
    >>> a = [np.ones(1 << 15) for _ in range(64)]; del a[:-1]
    >>> release_free_heap() in (True, False)
    True
    """
    fn = _malloc_trim()
    return bool(fn(0)) if fn is not None else False


_TRIM: list = []


def _malloc_trim():
    if not _TRIM:
        fn = None
        try:
            import ctypes

            fn = ctypes.CDLL(None).malloc_trim
            fn.argtypes, fn.restype = [ctypes.c_size_t], ctypes.c_int
        except (OSError, AttributeError):
            fn = None
        _TRIM.append(fn)
    return _TRIM[0]


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


_PAGES_LOCK = threading.Lock()
_SMALL_PAGES = [0, True]  # callers inside small_pages(); numpy's setting before the first


@contextmanager
def small_pages() -> Iterator[None]:
    """numpy's new arrays on 4 KiB pages while inside (every thread; nestable; restored
    when the last caller leaves). numpy asks Linux for transparent huge pages on every
    large allocation, and on this project's 2-core VM a fresh huge page often cost far
    more than the 512 small ones it replaces (likely the hypervisor backing it on first
    touch): a
    whole-grid 4097² preprocess, which allocates and frees a few GB of whole-grid arrays,
    spent 3.9 s of system CPU time with huge pages and 1.0–1.3 s without
    (docs/lab/preprocess.md). numpy's own switch, ``NUMPY_MADVISE_HUGEPAGE``, when the
    environment sets it, wins (nothing is changed). Results never depend on it.

    Examples
    --------
    >>> with small_pages():
    ...     int(np.zeros(1 << 22).sum())
    0
    """
    core = getattr(np, "_core", None) or getattr(np, "core", None)  # numpy 2, numpy 1
    set_hp = getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)
    if set_hp is None or "NUMPY_MADVISE_HUGEPAGE" in os.environ:
        yield
        return
    with _PAGES_LOCK:
        if _SMALL_PAGES[0] == 0:
            _SMALL_PAGES[1] = set_hp(False)
        _SMALL_PAGES[0] += 1
    try:
        yield
    finally:
        with _PAGES_LOCK:
            _SMALL_PAGES[0] -= 1
            if _SMALL_PAGES[0] == 0:
                set_hp(_SMALL_PAGES[1])


_GC_LOCK = threading.Lock()
_GC_PAUSED = [0, False]  # callers inside collector_paused(); the collector's state before


@contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused while inside (nestable; re-enabled when
    the last caller leaves, if it was enabled before the first). A whole-grid preprocess
    makes few objects but imports and loads many (numba's kernels, rasterio): in a fresh
    process its allocations set off three full collections over them, about 0.2 s of
    CPU with the GIL held (docs/lab/preprocess.md); reference counting frees its arrays
    as before, and cycles made meanwhile are collected once it is done. Results never
    depend on it.

    Examples
    --------
    >>> with collector_paused():
    ...     inside = gc.isenabled()
    >>> inside, gc.isenabled()
    (False, True)
    """
    with _GC_LOCK:
        if _GC_PAUSED[0] == 0:
            _GC_PAUSED[1] = gc.isenabled()
            gc.disable()
        _GC_PAUSED[0] += 1
    try:
        yield
    finally:
        with _GC_LOCK:
            _GC_PAUSED[0] -= 1
            if _GC_PAUSED[0] == 0 and _GC_PAUSED[1]:
                gc.enable()


class ZeroPool:
    """Zeroed arrays on 4 KiB pages (:func:`sparse_zeros`'s) that are reused once nothing
    references the array handed out: a per-frame buffer (a view's texture atlas, a few
    MB) then costs a memset, not a page fault per 4 KiB on first touch (1.4 ms of a
    1234 × 1072 atlas's 1.6 ms fill). An array handed out keeps its mapping busy for as
    long as it, or any view of it (a VTK array sharing it included), is alive.

    Examples
    --------
    >>> pool = ZeroPool()
    >>> a = pool.zeros((2, 3))
    >>> a[0, 0] = 5
    >>> b = pool.zeros((2, 3))  # ``a`` is alive: another mapping
    >>> int(b.sum()), len(pool)
    (0, 2)
    >>> del a
    >>> int(pool.zeros((3, 2)).sum()), len(pool)  # ``a``'s mapping, zeroed again
    (0, 2)
    """

    def __init__(self, keep: int = 3, largest: int = 64 << 20):
        self.keep = keep  # mappings kept for reuse
        self.largest = largest  # bytes: a larger array is a fresh sparse_zeros, not kept
        self._maps: list[tuple[mmap.mmap, weakref.ref | None]] = []
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._maps)

    def zeros(self, shape: tuple[int, ...], dtype=np.uint8) -> np.ndarray:
        """A zeroed array of ``shape`` and ``dtype``."""
        dt = np.dtype(dtype)
        count = int(np.prod(shape, dtype=np.int64))
        n = max(1, count * dt.itemsize)
        if n > self.largest or not hasattr(mmap, "MAP_ANONYMOUS"):
            return sparse_zeros(shape, dt)
        with self._lock:
            free = [k for k, (mm, ref) in enumerate(self._maps)
                    if (ref is None or ref() is None) and len(mm) >= n]
            if free:
                k = min(free, key=lambda k: len(self._maps[k][0]))  # the smallest fitting
                mm = self._maps[k][0]
                flat = np.frombuffer(mm, np.uint8, count=n)
                flat.fill(0)
            else:
                mm = mmap.mmap(-1, n, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
                if hasattr(mmap, "MADV_NOHUGEPAGE"):
                    mm.madvise(mmap.MADV_NOHUGEPAGE)
                flat = np.frombuffer(mm, np.uint8, count=n)
                idle = [k for k, (_, ref) in enumerate(self._maps) if ref is None or ref() is None]
                if len(self._maps) >= self.keep and idle:  # drop an idle one for it
                    del self._maps[min(idle, key=lambda k: len(self._maps[k][0]))]
                k = len(self._maps)
                self._maps.append((mm, None))
            self._maps[k] = (mm, weakref.ref(flat))  # busy while flat (any view) lives
        return flat.view(dt)[:count].reshape(shape)

