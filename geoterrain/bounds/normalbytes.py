"""The byte formats of a store's normals blobs.

:func:`normals_to_bytes` / :func:`normals_from_bytes`: a tile's 8-bit octahedral normals
as two planes of 2-D differences (mod 256); :func:`ring_index`: a tile's border ring;
:func:`ring_planes` / :func:`residual_planes` / :func:`ring_from_bytes`: a derived
level's stored border rings (their codes, or schema 17's residuals from the reader's
guess). :data:`NORMAL_BITS` and :data:`NORMALS_PLANAR_DXDY` are the metadata's
``normal_bits`` and ``normals_layout``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

NORMALS_PLANAR_DXDY = 2  # metadata ``normals_layout``; absent or 1: raw interleaved bytes
NORMAL_BITS = 8  # bits per octahedral normal component the preprocess stores


def normals_to_bytes(oct8: np.ndarray) -> bytes:
    """A tile's 8-bit octahedral normals (T, T, 2) as two planes of 2-D differences
    (mod 256): neighbouring normals agree, so zstd finds ~15 % fewer bytes than in the
    raw interleaved pairs (`benchmarks/bench_size.py`; docs/lab/store-size.md).

    Examples
    --------
    >>> a = np.random.default_rng(1).integers(0, 256, (5, 5, 2)).astype(np.uint8)
    >>> bool((normals_from_bytes(normals_to_bytes(a), 5) == a).all())
    True
    """
    p = np.ascontiguousarray(np.moveaxis(np.asarray(oct8, np.uint8), -1, 0))
    d = p.copy()
    d[:, 1:, :] = p[:, 1:, :] - p[:, :-1, :]  # uint8: wraps mod 256, exactly invertible
    e = d.copy()
    e[:, :, 1:] = d[:, :, 1:] - d[:, :, :-1]
    return e.tobytes()


@lru_cache(maxsize=8)
def ring_index(T: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a T × T tile's border ring, 4T − 4 samples: the top row, the
    bottom row, then the left and the right column without their corners.

    Examples
    --------
    >>> r, c = ring_index(3)
    >>> list(zip(r.tolist(), c.tolist()))
    [(0, 0), (0, 1), (0, 2), (2, 0), (2, 1), (2, 2), (1, 0), (1, 2)]
    """
    a = np.arange(T)
    m = np.arange(1, T - 1)
    rows = np.concatenate([np.zeros(T, np.int64), np.full(T, T - 1), m, m])
    cols = np.concatenate([a, a, np.zeros(T - 2, np.int64), np.full(T - 2, T - 1)])
    rows.setflags(write=False)  # shared: cached per T
    cols.setflags(write=False)
    return rows, cols


def ring_planes(rings: np.ndarray) -> np.ndarray:
    """Rings' 8-bit codes (k, R, 2), each as two planes of first differences (mod 256):
    (k, 2R) uint8, one stored blob's bytes per row (:func:`ring_from_bytes` inverts one).

    Examples
    --------
    >>> a = np.random.default_rng(2).integers(0, 256, (3, 8, 2)).astype(np.uint8)
    >>> all((ring_from_bytes(r.tobytes()) == a[k]).all() for k, r in enumerate(ring_planes(a)))
    True
    """
    p = np.ascontiguousarray(np.asarray(rings, np.uint8).transpose(0, 2, 1))  # (k, 2, R)
    d = p.copy()
    d[:, :, 1:] = p[:, :, 1:] - p[:, :, :-1]  # uint8: wraps mod 256, exactly invertible
    return d.reshape(len(d), -1)


def ring_from_bytes(raw: bytes, residual: bool = False) -> np.ndarray:
    """One row of :func:`ring_planes` back to the ring's codes: (R, 2) uint8; with
    ``residual``, one of :func:`residual_planes` back to the ring's residuals."""
    d = np.frombuffer(raw, np.uint8).reshape(2, -1)
    if residual:
        return np.ascontiguousarray(d.T)
    return np.ascontiguousarray(np.cumsum(d, axis=1, dtype=np.uint8).T)


def residual_planes(res: np.ndarray) -> np.ndarray:
    """Rings' residuals (k, R, 2) uint8 (schema 17's ``normals_ring_residual``: each
    code's difference from the reader's guess) as two planes each, without
    :func:`ring_planes`' first differences (the residuals are mostly 0 and ±1 already:
    srtm1_japan's rings 59.8 kB so at zstd 11 against 60.4 with the differences):
    (k, 2R), one stored blob's bytes per row.

    Examples
    --------
    >>> a = np.random.default_rng(2).integers(0, 256, (3, 8, 2)).astype(np.uint8)
    >>> all((ring_from_bytes(r.tobytes(), True) == a[k]).all()
    ...     for k, r in enumerate(residual_planes(a)))
    True
    """
    r = np.asarray(res, np.uint8)
    return np.ascontiguousarray(r.transpose(0, 2, 1)).reshape(len(r), -1)


def normals_from_bytes(raw: bytes, T: int) -> np.ndarray:
    """Inverse of :func:`normals_to_bytes`: (T, T, 2) uint8."""
    e = np.frombuffer(raw, np.uint8).reshape(2, T, T)
    p = np.cumsum(np.cumsum(e, axis=2, dtype=np.uint8), axis=1, dtype=np.uint8)
    return np.ascontiguousarray(np.moveaxis(p, 0, -1))
