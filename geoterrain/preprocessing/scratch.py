"""Row-addressed 2-D arrays in memory or in scratch files: what a streaming stage carries
from one pass to the next (issue 12: "carry only what the next level needs, in scratch
space on disk").

A file-backed array is read and written by row ranges with ``os.pread``/``os.pwrite``,
never mapped, so what it holds does not count against the process's resident memory
(a mapped file's pages would). Small grids keep the same interface in memory.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["ScratchArrays"]


class ScratchArrays:
    """Named 2-D arrays, created zeroed, read and written by rows.

    ``folder=None`` keeps them in memory; otherwise each is a file in a fresh temporary
    folder under ``folder``, removed by :meth:`close` (or at exit of a ``with`` block).

    Examples
    --------
    >>> with ScratchArrays(tempfile.gettempdir()) as s:
    ...     s.create("a", (4, 3), np.float32)
    ...     s.write("a", 1, np.ones((2, 3), np.float32))
    ...     s.read("a", 0, 4).sum(axis=1).tolist()
    [0.0, 3.0, 3.0, 0.0]
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self._mem: dict[str, np.ndarray] = {}
        self._fd: dict[str, int] = {}
        self._meta: dict[str, tuple[tuple[int, int], np.dtype]] = {}
        self._dir = (None if folder is None else
                     tempfile.TemporaryDirectory(prefix="geoterrain-", dir=folder))
        self._path = None if self._dir is None else self._dir.name

    @classmethod
    def shared(cls, path: str | Path) -> ScratchArrays:
        """Arrays in the folder ``path`` (created if needed) that other processes open
        too: an index file names each array's shape and dtype, and :meth:`close` keeps
        the files (the folder's owner removes it). Each array has one writer; a reader
        attaches once its writer is done.

        Examples
        --------
        >>> d = tempfile.mkdtemp()
        >>> a = ScratchArrays.shared(d); a.create("x", (2, 2), np.uint8)
        >>> a.write("x", 1, np.full((1, 2), 7, np.uint8)); a.close()
        >>> ScratchArrays.shared(d).read("x", 0, 2).tolist()
        [[0, 0], [7, 7]]
        """
        self = cls()
        self._path = str(path)
        os.makedirs(self._path, exist_ok=True)
        index = os.path.join(self._path, "index.json")
        if os.path.exists(index):
            with open(index) as fh:
                for name, (r, c, dt) in json.load(fh).items():
                    self._meta[name] = ((r, c), np.dtype(dt))
                    self._fd[name] = os.open(os.path.join(self._path, name), os.O_RDWR)
        return self

    def __enter__(self) -> ScratchArrays:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def on_disk(self) -> bool:
        return self._path is not None

    def create(self, name: str, shape: tuple[int, int], dtype: type) -> None:
        dt = np.dtype(dtype)
        self._meta[name] = ((int(shape[0]), int(shape[1])), dt)
        if self._path is None:
            self._mem[name] = np.zeros(shape, dt)
            return
        path = os.path.join(self._path, name)
        if name in self._fd:  # created again (bands.leaf copies level 0 back into C0, R0,
            # K0): the old descriptor goes, or it outlives close() and the folder
            os.close(self._fd.pop(name))
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o600)
        os.ftruncate(fd, shape[0] * shape[1] * dt.itemsize)  # sparse zeros
        self._fd[name] = fd
        if self._dir is None:  # shared: the index names every array (rewritten whole)
            index = {k: [*sh, d.str] for k, (sh, d) in self._meta.items()}
            tmp = os.path.join(self._path, f"index.json.{os.getpid()}")
            with open(tmp, "w") as fh:
                json.dump(index, fh)
            os.replace(tmp, os.path.join(self._path, "index.json"))

    def shape(self, name: str) -> tuple[int, int]:
        return self._meta[name][0]

    def dtype(self, name: str) -> np.dtype:
        return self._meta[name][1]

    def __contains__(self, name: str) -> bool:
        return name in self._meta

    def read(self, name: str, r0: int, r1: int, c0: int = 0, c1: int | None = None
             ) -> np.ndarray:
        """Rows ``r0 … r1 − 1`` and columns ``c0 … c1 − 1`` (default: every one; both
        clipped to the array), a copy. Some columns are read a row at a time, so a window
        of a wide array costs the window's bytes, not its rows'.

        Examples
        --------
        >>> s = ScratchArrays(tempfile.gettempdir()); s.create("c", (3, 5), np.int16)
        >>> s.write("c", 0, np.arange(15, dtype=np.int16).reshape(3, 5))
        >>> s.read("c", 1, 9, 3, 9).tolist(); s.close()
        [[8, 9], [13, 14]]
        """
        (nr, nc), dt = self._meta[name]
        r0 = max(r0, 0)
        r1 = max(min(r1, nr), r0)
        c0 = max(c0, 0)
        w = max((nc if c1 is None else min(c1, nc)) - c0, 0)
        if self._path is None:
            return self._mem[name][r0:r1, c0:c0 + w].copy()
        nbytes = (r1 - r0) * w * dt.itemsize
        buf = bytearray(nbytes)
        if w == nc:  # whole rows: one read
            got = os.preadv(self._fd[name], [buf], r0 * nc * dt.itemsize) if nbytes else 0
        else:
            row, got = w * dt.itemsize, 0
            view = memoryview(buf)
            for k in range(r1 - r0 if row else 0):
                got += os.preadv(self._fd[name], [view[k * row:(k + 1) * row]],
                                 ((r0 + k) * nc + c0) * dt.itemsize)
        if got != nbytes:
            raise OSError(f"scratch array {name}: short read ({got} of {nbytes} bytes)")
        return np.frombuffer(buf, dt).reshape(r1 - r0, w)

    def read_padded(self, name: str, r0: int, r1: int, fill: float = 0) -> np.ndarray:
        """Rows ``r0 … r1 − 1``, those outside the array filled with ``fill``."""
        (nr, nc), dt = self._meta[name]
        out = np.full((r1 - r0, nc), fill, dt)
        a, b = max(r0, 0), min(r1, nr)
        if b > a:
            out[a - r0:b - r0] = self.read(name, a, b)
        return out

    def write(self, name: str, r0: int, rows: np.ndarray, c0: int = 0) -> None:
        """Rows ``r0 …`` from ``rows`` (the dtype's), at columns ``c0 …`` (a block of
        whole rows when ``rows`` is as wide as the array, else one write a row).

        Examples
        --------
        >>> s = ScratchArrays(); s.create("b", (3, 4), np.int8)
        >>> s.write("b", 1, np.ones((2, 2), np.int8), c0=2); s.read("b", 0, 3).tolist()
        [[0, 0, 0, 0], [0, 0, 1, 1], [0, 0, 1, 1]]
        """
        (nr, nc), dt = self._meta[name]
        rows = np.ascontiguousarray(rows, dtype=dt)
        if rows.ndim != 2 or c0 < 0 or c0 + rows.shape[1] > nc or r0 < 0 \
                or r0 + rows.shape[0] > nr:
            raise ValueError(f"scratch array {name} {nr}×{nc}: cannot write "
                             f"{rows.shape} at row {r0}, column {c0}")
        if self._path is None:
            self._mem[name][r0:r0 + rows.shape[0], c0:c0 + rows.shape[1]] = rows
            return
        blocks = [rows] if rows.shape[1] == nc else rows
        step = rows.shape[0] if rows.shape[1] == nc else 1
        for k, block in enumerate(blocks):
            data = block.tobytes()
            at = ((r0 + k * step) * nc + c0) * dt.itemsize
            if os.pwrite(self._fd[name], data, at) != len(data):
                raise OSError(f"scratch array {name}: short write")

    def __del__(self) -> None:
        # an on-disk set dropped without close() (or a with block) still gives its file
        # descriptors back: a long process (a server, a test run) would run out of them
        with contextlib.suppress(Exception):
            self.close()

    def close(self) -> None:
        for fd in self._fd.values():
            os.close(fd)
        self._fd.clear()
        self._mem.clear()
        if self._dir is not None:
            self._dir.cleanup()
