"""Bytes read from files, as the operating system counts them: Linux's per-thread I/O
counters.

The kernel adds every byte a ``read``/``pread`` returns to the calling thread's
``rchar`` (``/proc/thread-self/io``). SQLite runs in the calling thread, so the change
of ``rchar`` around a call into it is exactly what that call read from the file (its
pages, the header, the change counter it checks at each transaction), whatever the
page cache of SQLite held. :class:`ReadMeter` sums it over the calls made through it
(the store's reader: :class:`geoterrain.store.reader.StoreReader`). Where the
counters are not there (not Linux), :data:`EXACT` is False and a meter counts nothing;
its owner counts what it can instead.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ["EXACT", "ReadMeter", "thread_rchar"]

_T = TypeVar("_T")
_PATH = "/proc/thread-self/io"
_local = threading.local()


class _Probe:
    """This thread's open counter file (a descriptor opened in a thread reads that
    thread's counters, so each thread opens its own; closed when the thread ends)."""

    def __init__(self) -> None:
        self.fd = os.open(_PATH, os.O_RDONLY)

    def __del__(self) -> None:
        try:
            os.close(self.fd)
        except OSError:
            pass


def thread_rchar() -> tuple[int, int] | None:
    """This thread's ``rchar`` and the bytes this look itself read (the kernel counts them
    after the figure is written, so the next look includes them); None where the counters
    are not available.

    Examples
    --------
    >>> a, b = thread_rchar() or (0, 0), thread_rchar() or (0, 0)
    >>> b[0] - a[0] - a[1]  # nothing read in between
    0
    """
    p = getattr(_local, "probe", None)
    if p is None:
        try:
            p = _local.probe = _Probe()
        except OSError:
            return None
    try:
        text = os.pread(p.fd, 512, 0)
        return int(text[text.index(b"rchar:") + 6:text.index(b"\n")]), len(text)
    except (OSError, ValueError):
        return None


EXACT = thread_rchar() is not None  # whether a meter counts (Linux ≥ 3.17)


class ReadMeter:
    """Sums the bytes read by the calls made through it, as the operating system counts
    them (0 where :data:`EXACT` is False). Thread-safe: each call is measured in its own
    thread.

    Examples
    --------
    >>> import tempfile
    >>> path = tempfile.mktemp()
    >>> with open(path, "wb") as fh:
    ...     _ = fh.write(b"x" * 1000)
    >>> m = ReadMeter()
    >>> def read_some():
    ...     with open(path, "rb", buffering=0) as fh:
    ...         return len(fh.read(300))
    >>> m.call(read_some), m.bytes == (300 if EXACT else 0)
    (300, True)
    """

    def __init__(self) -> None:
        self.bytes = 0
        self.probes = 0  # what its own looks at the counters read (a process's total has them)
        self._lock = threading.Lock()

    def call(self, fn: Callable[[], _T]) -> _T:
        """``fn()``, adding what it read to :attr:`bytes`."""
        r0 = thread_rchar()
        try:
            return fn()
        finally:
            r1 = thread_rchar()
            if r0 is not None and r1 is not None:
                with self._lock:
                    self.bytes += r1[0] - r0[0] - r0[1]
                    self.probes += r0[1] + r1[1]
