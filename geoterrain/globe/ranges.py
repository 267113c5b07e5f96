"""Seed 001's view ranges from per-depth error tables: the planetary CDLOD's R_D and morph
starts m_D (:func:`ranges_from`), and the largest gap of a node while it morphs
(:func:`morph_error`). :mod:`geoterrain.globe.errors` makes the tables.

Examples
--------
>>> e = np.array([8.0, 4.0, 2.0, 1.0])
>>> z = np.zeros(4)
>>> R, m = ranges_from((e, z, z, np.array([0.0, 40.0, 20.0, 10.0]), z), 3, 1000.0, 1.0)
>>> bool(np.all(np.diff(R) < 0)), float(R[-1]), bool(np.isinf(m[0]))
(True, 0.0, True)
"""

from __future__ import annotations

import numpy as np

MORPH_FRACTION = 0.5  # seed 001 §3.3.2: half of each level's range morphs
SAFE = 1.0 + 1e-6  # a bound's margin for rounding


def morph_error(e: np.ndarray, move: np.ndarray, slack: np.ndarray, diag: np.ndarray,
                cell: np.ndarray, fraction: float, r_min: float) -> np.ndarray:
    """Per depth D, the largest radial gap to the truth of a depth-D node while it morphs
    (0 for D = 0, which never morphs): the smaller of two bounds.

    - e_D + (1 + s)·M_D: its vertices move at most M_D off its own surface;
    - max(e_D, e_{D−1}) + (1 + s)·Δk·M_D + (1 + s)²·M_D²/r_min: with one k at all its
      vertices the surface lies, along each ray, between the node's own (k = 0, within e_D)
      and its parent's over the same quadrant (k = 1, within e_{D−1}) up to the curvature
      of r(k) = 1/Σ(c_i/r_i(k)) (≤ M²/(2r)), so within the larger of the two; a triangle's
      own k differ by at most Δk = (1 − f)(c_D + 2M_D)/(f·diag_D) (their coarser positions
      lie within a cell and two moves, and the morph band is f(R_{D−1} − R_D) ≥
      f·diag_D/(1 − f) deep), which moves it at most (1 + s)·Δk·M_D more.
    """
    f = float(fraction)
    out = np.zeros(len(e))
    for D in range(1, len(e)):
        a = e[D] + (1 + slack[D]) * move[D]
        if 0 < f < 1 and diag[D] > 0:
            dk = min(1.0, (1 - f) * (cell[D] + 2 * move[D]) / (f * diag[D]) * 1.01)
            b = (max(e[D], e[D - 1]) + (1 + slack[D]) * dk * move[D]
                 + (1 + slack[D]) ** 2 * move[D] ** 2 / r_min)
            a = min(a, b)
        out[D] = a
    return out


def settle(ranges_of, drawn, A: np.ndarray, limit: int = 64):
    """Ranges over a set of nodes that draw no node outside it: iterate A → drawn(ranges_of(A))
    from ``A`` (a mask; ``drawn`` must return a subset of it) and return (ranges_of(A), A)
    for the last A met whose ranges draw only nodes of A (the first always does).

    The sets need not shrink to a fixed point: a coarser range can grow when a finer one's
    table shrinks (the morph budget), so two sets can draw each other in turn. The iteration
    stops at a fixed point, at a set met before (a cycle) or after ``limit`` sets; what it
    returns is sound whichever way it stopped.

    Examples
    --------
    >>> sets = [np.array([1, 1, 1], bool), np.array([1, 0, 0], bool), np.array([1, 1, 0], bool)]
    >>> out, A = settle(lambda A: int(A.sum()), lambda n: sets[{3: 1, 1: 2, 2: 1}[n]], sets[0])
    >>> out, A.tolist()
    (2, [True, True, False])
    """
    best = None
    seen = set()
    for _ in range(limit):
        out = ranges_of(A)
        B = drawn(out)
        if not (B & ~A).any():
            best = (out, A)
            if np.array_equal(B, A):
                break
        seen.add(A.tobytes())
        if B.tobytes() in seen:
            break  # a cycle: its sound member, if any, is kept
        A = B
    return best


def ranges_from(tables: tuple[np.ndarray, ...], Dm: int, lam: float, tau: float,
                fraction: float = MORPH_FRACTION, r_min: float = 6.0e6
                ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ranges` from per-depth (e, move, slack, diag, cell) tables; ``r_min`` the least
    distance of any point from the centre."""
    e, move, slack, diag, cell = tables
    f = float(fraction)
    em = morph_error(e, move, slack, diag, cell, f, r_min)
    R = np.zeros(Dm + 1)
    m = np.full(Dm + 1, np.inf)
    for D in range(Dm, 0, -1):
        prev = R[D]
        # the measure divides by the eye's distance to the truth, up to e nearer than the mesh
        need = [(lam / tau + 1) * e[D - 1] * SAFE, prev * (1 + 1e-9) + 1e-6]
        if f < 1:
            need.append(prev + diag[D] * SAFE / (1 - f))
            budget = ((lam / tau + 1) * em[D] + cell[D] + move[D]) * SAFE
            need.append((budget - f * prev) / (1 - f))
        R[D - 1] = max(need)
        m[D] = (1 - f) * R[D - 1] + f * prev
    return R, m
