"""Saturation of δ's per-level arrays (seed 002 §2.4, L46) as a pull, fine to coarse, a
budget of rows at a time, in memory or in scratch files: the same maximum as
:func:`geoterrain.bounds.delta.saturate` on the whole grid."""

from __future__ import annotations

import numpy as np

from geoterrain.preprocessing.scratch import ScratchArrays


def _zero_beyond(a: np.ndarray, a_lo: int, s: int, di: int, dj: int,
                 data: tuple[int, int]) -> None:
    # edgepad.zero_beyond_data on rows a_lo … of one kind of level array: vertex
    # (a·s + di, b·s + dj) of half-span h keeps its value only if its diamond reaches the
    # data's rows × cols, i.e. a·s + di − h ≤ rows − 1 and b·s + dj − h ≤ cols − 1
    h = s // 2
    rows, cols = data
    a_idx = a_lo + np.arange(a.shape[0])
    a[a_idx * s + di - h > rows - 1] = 0
    a[:, np.arange(a.shape[1]) * s + dj - h > cols - 1] = 0


def _saturate(sa: ScratchArrays, n: int, budget: int,
              data: tuple[int, int] | None = None, pre: str = "") -> float:
    # LP §2.4 (L46) as a pull, fine to coarse and ``budget`` bytes of rows at a time: an
    # edge midpoint at h takes its four children centres at h/2 (R[a, b]: centre rows
    # 2a, 2a+1 and columns 2b−1, 2b of level h/2; K[a, b]: rows 2a−1, 2a and columns
    # 2b, 2b+1), then a centre takes its block's four edge midpoints. ``data``: first
    # zero the raw δ of the vertices whose diamond misses the data's rows × cols.
    # Returns the largest finite saturated δ (0 if none): what its log8 codes must cover.
    # ``pre``: the arrays' name prefix
    top = 0.0
    for k in range(n):
        nb, nbc = sa.shape(f"{pre}C{k}")
        step = max(1, budget // (16 * (nbc + 1) * 4))
        for a_lo in range(0, nb, step):
            a_hi = min(a_lo + step, nb)
            C = sa.read(f"{pre}C{k}", a_lo, a_hi)
            R = sa.read(f"{pre}R{k}", a_lo, a_hi)
            K = sa.read(f"{pre}K{k}", a_lo, a_hi + 1)
            if data is not None:
                s = 2 << k
                for arr, di, dj in ((C, s // 2, s // 2), (R, s // 2, 0), (K, 0, s // 2)):
                    _zero_beyond(arr, a_lo, s, di, dj, data)
            if k:
                # the finer level's centre rows 2a_lo − 1 … 2a_hi, zero outside the grid
                P = np.zeros((2 * (a_hi - a_lo) + 2, 2 * nbc + 2), np.float32)
                p0 = max(2 * a_lo - 1, 0)
                rows = sa.read(f"{pre}C{k - 1}", p0, 2 * a_hi + 1)
                P[p0 - (2 * a_lo - 1):p0 - (2 * a_lo - 1) + len(rows), 1:-1] = rows
                m = np.maximum(P[1:-1:2], P[2::2])  # rows 2a, 2a+1 of each R row
                np.maximum(R, np.maximum(m[:, 0::2], m[:, 1::2]), out=R)
                m = np.maximum(P[0::2], P[1::2])  # rows 2a−1, 2a of each K row
                np.maximum(K, np.maximum(m[:, 1:-1:2], m[:, 2::2]), out=K)
            np.maximum(C, np.maximum(np.maximum(R[:, :-1], R[:, 1:]),
                                     np.maximum(K[:-1], K[1:])), out=C)
            sa.write(f"{pre}C{k}", a_lo, C)
            sa.write(f"{pre}R{k}", a_lo, R)
            sa.write(f"{pre}K{k}", a_lo, K)
            for a in (C, R, K):
                top = max(top, float(np.max(a, where=np.isfinite(a), initial=0.0)))
    return top
