"""δ of a grid read in row bands: memory set by the band, not the grid (issue 12).

The same exact, saturated δ as :func:`geoterrain.bounds.delta.vertex_errors` (seed 002 §2.3
with the exact diamond maximum, saturated by §2.4, L46), bit for bit, from a grid that
is never held whole: a ``rows(i0, i1)`` callback hands out rows ``i0 … i1 − 1`` (a
rasterio window, a scratch file), ``band`` rows at a time.

How the bintree splits over row bands of B = 2**b rows (docs/conventions.md):

- **Fine levels** (half-span h ≤ B/2, blocks of side 2h ≤ B) lie inside one band: each
  band sweeps its blocks with the whole-grid kernels (:func:`bounds._block_sweep`,
  ``_centre1``, ``_mid1``). Only the edge midpoints on a band's top row see the band
  above: their diamond's upper quarter maximum and block status are carried from it
  (one row of each per level), and a mixed diamond is swept over a halo of B/2 rows.
- **Coarse levels** (h ≥ B) span bands. Their corners and centres lie on rows and
  columns that are multiples of B, read once by a first pass (with each B block's
  valid/invalid status). Each band then adds its rows to every coarse block's running
  maxima (:func:`bounds._block_sweep_part`) and to each mixed diamond's running sweep
  (:func:`bounds._edge_err_part`). A maximum over rows is exact, so the split changes no
  bit.
- **Saturation** pulls each vertex's children's saturated δ level by level, fine to
  coarse, on the per-level arrays (children of an edge midpoint at h: the four centres
  at h/2 beside it; of a centre: its block's four edge midpoints), which is the same
  maximum as :func:`geoterrain.bounds.delta.saturate`.

Per-level arrays (``LevelDelta``) hold, for h = 1, 2, 4, …, with s = 2h and
nb = (N − 1)/s: ``C`` (nb, nb), the block centres (h + a·s, h + b·s); ``R`` (nb, nb + 1),
the edge midpoints (h + a·s, b·s) whose hypotenuse runs along the rows; ``K``
(nb + 1, nb), the edge midpoints (a·s, h + b·s). They are the vertices new at each
level, in the order a store writes them.

Split by job: the rows a band reads (:mod:`~geoterrain.preprocessing.bands.rows`), the
coarse levels' running sweeps (:mod:`~geoterrain.preprocessing.bands.coarselevels`) and the
per-level arrays' saturation (:mod:`~geoterrain.preprocessing.bands.saturation`); this
module drives them, sweeps the fine levels and reads the per-level arrays back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import prange

from geoterrain.bounds.delta import (
    Beside,
    _block_sweep,
    _centre1,
    edge_delta_nb,
    grid_order,
)
from geoterrain.bounds.radii import valid_range
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import parallel_kernel
from geoterrain.preprocessing.bands.coarselevels import (
    BlockMaxima,
    Sweeps,
    _coarse_edges_nb,
    _coarse_finish_nb,
    _coarse_rows_nb,
    _mixed_edges,
)
from geoterrain.preprocessing.bands.rows import (
    Rows,
    _window,
    edge_rows,
    grid_shape,
    rows_of,
)
from geoterrain.preprocessing.bands.saturation import _saturate, _zero_beyond  # noqa: F401
from geoterrain.preprocessing.scratch import ScratchArrays

__all__ = ["LevelDelta", "band_vertex_errors", "edge_rows", "level_lattice", "raise_delta",
           "rows_of"]


class BandWindow(NamedTuple):
    """A band of an (R, C) grid's rows as the band kernels read it: heights ``z``
    (invalid ones 0) and validity ``v`` of the window's rows, from grid row ``w0`` (a
    halo above the band, then its own rows ``r0`` … ``r_end``); ``B`` rows a band (also
    the step of the grid's corners read every B samples), ``R`` and ``C`` the grid's
    rows and columns (the square's N and N, or a root grid's extent)."""

    z: np.ndarray
    v: np.ndarray
    w0: int
    r0: int
    r_end: int
    B: int
    R: int
    C: int


class LevelVertices(NamedTuple):
    """One level's values (or rows of them) per kind of vertex (module docstring): the
    block centres ``C``, the edge midpoints ``R`` whose hypotenuse runs along the rows
    and ``K`` whose hypotenuse runs along the columns."""

    C: np.ndarray
    R: np.ndarray
    K: np.ndarray


@dataclass
class LevelDelta:
    """Per-level δ arrays of an (N, N) grid (or a root grid's (R, C) extent) in
    ``arrays`` (:class:`ScratchArrays`, in memory or in scratch files): ``C{k}``,
    ``R{k}``, ``K{k}`` for h = 2**k, k < n (a root's side 2**n)."""

    N: int | tuple[int, int]
    arrays: ScratchArrays
    valid_range: tuple[float, float, int] = (np.inf, -np.inf, 0)
    """(min, max, count) of the valid heights, from the first pass."""
    stand_in: float | None = None
    """The height of invalid vertices in ``Z*`` arrays (None: not kept)."""
    max_finite: float = 0.0
    """The largest finite δ (0 if none)."""
    span: int | None = None
    """A root grid's root side (None: the square's N − 1)."""

    @property
    def shape(self) -> tuple[int, int]:
        return grid_shape(self.N)

    @property
    def n(self) -> int:
        return grid_order((self.shape[0] - 1 if self.span is None else self.span) + 1)

    def level(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Level k's (C, R, K), whole."""
        return tuple(self.arrays.read(f"{x}{k}", 0, self.arrays.shape(f"{x}{k}")[0])
                     for x in "CRK")

    def grid(self) -> np.ndarray:
        """The (N, N) float32 grid of :func:`geoterrain.bounds.delta.vertex_errors` (tests,
        small grids).

        Examples
        --------
        >>> z = np.zeros((3, 3)); z[1, 1] = 2.0
        >>> d = band_vertex_errors(rows_of(z, np.ones((3, 3), bool)), 3, band=2)
        >>> float(d.grid()[1, 1])
        2.0
        """
        d = np.zeros(self.shape, np.float32)
        for k in range(self.n):
            C, R, K = self.level(k)
            h = 1 << k
            s = 2 * h
            d[h::s, h::s] = C
            d[h::s, 0::s] = R
            d[0::s, h::s] = K
        return d


@parallel_kernel(cache=True)
def _status_nb(v, r, s, nrow, nb):
    # status bits (1 valid, 2 invalid) of nrow rows of closed s-blocks, from v's row r
    out = np.zeros((nrow, nb), np.uint8)
    for a in prange(nrow):
        for b in range(nb):
            f = 0
            for i in range(r + a * s, r + a * s + s + 1):
                for j in range(b * s, b * s + s + 1):
                    f |= 1 if v[i, j] else 2
                if f == 3:
                    break
            out[a, b] = f
    return out


def _pool(st: np.ndarray) -> np.ndarray:
    # a closed 2s block's status is the OR of its four closed s blocks'
    return st[0::2, 0::2] | st[0::2, 1::2] | st[1::2, 0::2] | st[1::2, 1::2]


@parallel_kernel(cache=True)
def _fine_level_nb(band, h, st, st_prev, qb_prev, out, QB):
    """One fine level (2h ≤ B) of the ``band`` (:class:`BandWindow`): raw δ of its
    centres and edge midpoints into ``out`` (:class:`LevelVertices`; the same branches as
    bounds._raw_delta_nb), ``st`` its blocks' statuses and ``st_prev``, ``qb_prev`` the
    band above's last block row's; QB gets the block rows' lower quarter maxima (the
    next band's carry)."""
    z, vb, w0, r0, B, NR, NC = band.z, band.v, band.w0, band.r0, band.B, band.R, band.C
    last = band.r_end == NR - 1
    C = out.C  # one by one (see bounds.tileblobs._level_payloads)
    R = out.R
    K = out.K
    s = 2 * h
    nbr = (NR - 1) // s
    nb = (NC - 1) // s
    nrow = B // s
    a0 = r0 // s
    QL = np.zeros((nrow, nb))
    QR = np.zeros((nrow, nb))
    QT = np.zeros((nrow, nb))
    for ar in prange(nrow):
        a = a0 + ar
        for b in range(nb):
            f = st[ar, b]
            main = main_diagonal_nb(a, b)
            if f == 1:
                if h == 1:
                    m = _centre1(z, a * s + h - w0, b * s + h, main)
                else:
                    m, ml, mr, mt, mb = _block_sweep(z, a * s - w0, b * s, s, main)
                    QL[ar, b] = ml
                    QR[ar, b] = mr
                    QT[ar, b] = mt
                    QB[ar, b] = mb
                C[ar, b] = round_up32(m)
            elif f == 3:
                C[ar, b] = np.inf
    # edge midpoints whose hypotenuse runs along the rows: inside their block row
    for ar in prange(nrow):
        ic = h + (a0 + ar) * s
        for b in range(nb + 1):
            jc = b * s
            flo = st[ar, b - 1] if b > 0 else 0
            fhi = st[ar, b] if b < nb else 0
            qlo = QR[ar, b - 1] if flo else 0.0
            qhi = QL[ar, b] if fhi else 0.0
            R[ar, b] = edge_delta_nb(z, vb, ic, jc, h, True, NC, w0,
                                     Beside(flo, fhi, qlo, qhi), R[ar, b])
    # edge midpoints on block rows' top edges: the block above may be the band above's
    nk = nrow + (1 if last else 0)
    for ak in prange(nk):
        a = a0 + ak
        ic = a * s
        for b in range(nb):
            jc = h + b * s
            flo = 0
            qlo = 0.0
            if ak >= 1:
                flo = st[ak - 1, b]
                qlo = QB[ak - 1, b]
            elif a >= 1:
                flo = st_prev[b]
                qlo = qb_prev[b]
            fhi = st[ak, b] if a < nbr else 0
            qhi = QT[ak, b] if fhi else 0.0
            K[ak, b] = edge_delta_nb(z, vb, ic, jc, h, False, NR, w0,
                                     Beside(flo, fhi, qlo, qhi), K[ak, b])


def _keep_heights(sa: ScratchArrays, z: np.ndarray, v: np.ndarray, w0: int, r0: int,
                  r_end: int, n: int, stand_in: float) -> None:
    # the heights of every level's vertices on grid rows r0 … r_end, invalid ones by the
    # stand-in (radii._proxy_positions): ZC{k}, ZR{k}, ZK{k}, for the nested radii
    zp = np.where(v, z, stand_in)
    for k in range(n):
        h = 1 << k
        s = 2 * h
        for x, off, cols in (("C", h, slice(h, None, s)), ("R", h, slice(0, None, s)),
                             ("K", 0, slice(h, None, s))):
            a_lo = max(-(-(r0 - off) // s), 0)
            a_hi = (r_end - off) // s
            if a_hi >= a_lo:
                idx = np.arange(a_lo, a_hi + 1) * s + off - w0
                sa.write(f"Z{x}{k}", a_lo, zp[idx][:, cols])
    S = 1 << n  # the roots' corners (ZT: every S-th row and column)
    a_lo, a_hi = -(-r0 // S), r_end // S
    if "ZT" in sa and a_hi >= a_lo:
        sa.write("ZT", a_lo, zp[np.arange(a_lo, a_hi + 1) * S - w0][:, ::S])


def _fine_skip(data: tuple[int, int] | None, r0: int, B: int) -> bool:
    """Whether the band from row ``r0`` (``B`` rows) has no fine level to compute with
    ``data`` (δ_edge): a fine vertex on its rows, (i, j) of half-span h ≤ B/2 with
    i ≥ r0 (an edge midpoint on the band's first row is the lowest), has the diamond rows
    i − h … i + h, all past the data's when r0 − B/2 ≥ rows, so its raw δ is zeroed before
    saturation (:func:`_saturate`, ``data``) whatever the band computed: the arrays' zeros
    stand, and every later band skips too, so no carried row is read.

    Examples
    --------
    >>> _fine_skip((100, 9), 160, 64), _fine_skip((100, 9), 128, 64), _fine_skip(None, 128, 2)
    (True, False, False)
    """
    return data is not None and r0 - B // 2 >= data[0]


def band_vertex_errors(rows: Rows, N: int | tuple[int, int], band: int = 256,
                       scratch: ScratchArrays | None = None,
                       heights: bool = False,
                       data: tuple[int, int] | None = None,
                       span: int | None = None) -> LevelDelta:
    """Exact, saturated δ of an (N, N) grid read ``band`` rows at a time; the values of
    :func:`geoterrain.bounds.delta.vertex_errors`, bit for bit, for any band.

    Parameters
    ----------
    rows
        ``rows(i0, i1)`` → (heights, valid) of grid rows i0 … i1 − 1, shape (i1 − i0, N)
        (a root grid: (i1 − i0, C)): heights in scene units (float64, or anything that
        converts), valid bool.
    N
        Grid side, 2**n + 1; or a root grid's extent (R, C), with ``span``.
    band
        Rows per band, a power of two ≥ 2 (clipped to the root's side). Each band's window is
        1.5·band + 1 rows; the first pass reads every band once more.
    scratch
        Where the per-level arrays go (:class:`ScratchArrays`; default in memory). With
        a scratch folder, memory is the band's window and a few rows of each level.
    heights
        Also keep every level's vertex heights (``ZC{k}``, ``ZR{k}``, ``ZK{k}``,
        float64), invalid ones replaced by the middle of the valid range
        (:func:`geoterrain.bounds.radii.stand_in_z`): what
        :func:`geoterrain.preprocessing.bands.radii.band_radius_codes` nests.
    data
        ``(rows, cols)`` of the data in a padded grid: the raw δ of every vertex whose
        diamond misses them is 0 before saturation. With ``rows`` replicating the data's
        edge into the padding (:func:`edge_rows`), that is
        :func:`geoterrain.bounds.edgepad.edge_deltas` (δ_edge).
    span
        A root grid's root side 2**n (``N`` then its extent, (ry·span + 1, rx·span + 1)):
        :func:`geoterrain.bounds.delta.vertex_errors` with ``span``. None: the square.

    Examples
    --------
    >>> from geoterrain.bounds.delta import vertex_errors
    >>> rng = np.random.default_rng(1)
    >>> z = rng.normal(size=(17, 17)); v = np.ones_like(z, bool)
    >>> d = band_vertex_errors(rows_of(z, v), 17, band=4)
    >>> bool(np.array_equal(d.grid(), vertex_errors(z, v)))
    True
    >>> z = rng.normal(size=(9, 17)); v = np.ones_like(z, bool)  # 2 × 1 roots of side 8
    >>> d = band_vertex_errors(rows_of(z, v), (9, 17), band=2, span=8)
    >>> bool(np.array_equal(d.grid(), vertex_errors(z, v, span=8)))
    True
    """
    NR, NC = grid_shape(N)
    if span is None and NR != NC:
        raise ValueError(f"a {NR} × {NC} grid needs span, its roots' side")
    n = grid_order(NR if span is None else int(span) + 1)
    S = 1 << n
    if (NR - 1) % S or (NC - 1) % S:
        raise ValueError(f"a {NR} × {NC} grid is not square roots of side {S}")
    if band < 2 or band & (band - 1):
        raise ValueError(f"band must be a power of two ≥ 2, got {band}")
    B = min(band, S)
    nbands = nB = (NR - 1) // B
    nBc = (NC - 1) // B
    # first pass: every B block's status, and the grid every B samples (coarse corners)
    stB = np.zeros((nB, nBc), np.uint8)
    zd = np.zeros((nB + 1, nBc + 1))
    lo, hi, count = np.inf, -np.inf, 0
    for k in range(nbands):
        r0 = k * B
        z, v = _window(rows, r0, r0 + B + 1, NC)
        stB[k] = _status_nb(v, 0, B, 1, nBc)[0]
        zd[k] = z[0, ::B]
        if k == nbands - 1:
            zd[k + 1] = z[B, ::B]
        a, b, c = valid_range(z[:B + (k == nbands - 1)], v[:B + (k == nbands - 1)])
        lo, hi, count = min(lo, a), max(hi, b), count + c
        z = v = None  # before the next band's are read
    stand_in = (0.5 * (lo + hi) if count else 0.0) if heights else None  # radii.stand_in_z
    coarse = []  # per coarse level: (h, status, accumulators, mixed edges and sweeps)
    st = stB
    h = B
    while h < S:
        st = _pool(st)
        acc = BlockMaxima(*(np.zeros(st.shape) for _ in range(5)))
        rt, kt = _mixed_edges(st)
        sw = [Sweeps(np.zeros(len(t)), np.zeros(len(t), np.int64), np.zeros(len(t), np.int64))
              for t in (rt, kt)]
        coarse.append((h, st, acc, (rt, kt), sw))
        h *= 2
    nfine = B.bit_length() - 1  # levels h = 1 … B/2
    sa = ScratchArrays() if scratch is None else scratch
    for k in range(n):
        nr, nb = (NR - 1) >> (k + 1), (NC - 1) >> (k + 1)
        sa.create(f"C{k}", (nr, nb), np.float32)
        sa.create(f"R{k}", (nr, nb + 1), np.float32)
        sa.create(f"K{k}", (nr + 1, nb), np.float32)
        if heights:
            sa.create(f"ZC{k}", (nr, nb), np.float64)
            sa.create(f"ZR{k}", (nr, nb + 1), np.float64)
            sa.create(f"ZK{k}", (nr + 1, nb), np.float64)
    if heights:  # the roots' corners, new at no level: δ's guesses read them (schema 20)
        sa.create("ZT", (((NR - 1) >> n) + 1, ((NC - 1) >> n) + 1), np.float64)
    carry = [(np.zeros((NC - 1) // (2 << k), np.uint8), np.zeros((NC - 1) // (2 << k)))
             for k in range(nfine)]
    for k in range(nbands):
        r0 = k * B
        last = k == nbands - 1
        w0 = max(0, r0 - B // 2)
        z, v = _window(rows, w0, r0 + B + 1, NC)
        # the band's core rows (and the grid's last row, last): what the coarse levels add
        r_hi = r0 + B if last else r0 + B - 1
        band = BandWindow(z, v, w0, r0, r_hi, B, NR, NC)
        # fine levels: block statuses from the samples, pooled up the band's levels;
        # with ``data``, none in a band whose every fine vertex is zeroed (_fine_skip)
        fine = range(0) if _fine_skip(data, r0, B) else range(nfine)
        sts = [_status_nb(v, r0 - w0, 2, B // 2, (NC - 1) // 2)] if fine else []
        for _ in range(1, len(fine)):
            sts.append(_pool(sts[-1]))
        for lk in fine:
            hh = 1 << lk
            s = 2 * hh
            nb = (NC - 1) // s
            nrow = B // s
            a0 = r0 // s
            nk = nrow + (1 if last else 0)
            Cb = np.zeros((nrow, nb), np.float32)
            Rb = np.zeros((nrow, nb + 1), np.float32)
            Kb = np.zeros((nk, nb), np.float32)
            QB = np.zeros((nrow, nb))
            st_prev, qb_prev = carry[lk]
            _fine_level_nb(band, hh, sts[lk], st_prev, qb_prev, LevelVertices(Cb, Rb, Kb), QB)
            sa.write(f"C{lk}", a0, Cb)
            sa.write(f"R{lk}", a0, Rb)
            sa.write(f"K{lk}", a0, Kb)
            carry[lk] = (sts[lk][-1].copy(), QB[-1].copy())
        if stand_in is not None:
            _keep_heights(sa, z, v, w0, r0, r_hi, n, stand_in)
        for hc, stc, acc, todo, sw in coarse:
            _coarse_rows_nb(band, hc, stc, zd, acc)
            for rows_type, t, sweeps in zip((True, False), todo, sw, strict=True):
                if len(t):
                    _coarse_edges_nb(band, hc, zd, rows_type, t, sweeps)
        z = v = band = sts = None  # before the next band's are read
    for k, (_, stc, acc, (rt, kt), sw) in enumerate(coarse, start=nfine):
        nr, nb = stc.shape
        C = np.zeros((nr, nb), np.float32)
        R = np.zeros((nr, nb + 1), np.float32)
        K = np.zeros((nr + 1, nb), np.float32)
        _coarse_finish_nb(stc, acc, rt, sw[0], kt, sw[1], LevelVertices(C, R, K))
        for x, a in zip("CRK", (C, R, K), strict=True):
            sa.write(f"{x}{k}", 0, a)
    top = _saturate(sa, n, budget=max(B, 64) * NC * 16, data=data)
    return LevelDelta((NR, NC) if span is not None else NR, sa, (lo, hi, count), stand_in,
                      top, span)



def level_lattice(sa: ScratchArrays, pre: str, L: int, n: int, p0: int, p1: int, m: int,
                  top: bool, dtype, q0: int = 0, q1: int | None = None) -> np.ndarray:
    """Rows p0 … p1 − 1 and columns q0 … q1 − 1 (default: all m) of level L's lattice
    (m a side, sample (p, q) = grid sample (p 2^L, q 2^L)) of the per-level arrays
    ``{pre}C{k}``…: level L's new vertices, and at the top level every coarser one too
    (0 elsewhere; the roots' corners from ``{pre}T`` where it is kept, the heights'
    ``ZT``). Only the window's samples are read from the arrays.

    Examples
    --------
    >>> d = band_vertex_errors(rows_of(np.eye(5) * 4, np.ones((5, 5), bool)), 5, band=2)
    >>> level_lattice(d.arrays, "", 0, 2, 0, 3, 5, False, np.float32).shape
    (3, 5)
    >>> w = level_lattice(d.arrays, "", 0, 2, 0, 5, 5, True, np.float32)
    >>> bool((level_lattice(d.arrays, "", 0, 2, 1, 4, 5, True, np.float32, 2, 5)
    ...       == w[1:4, 2:5]).all())
    True
    """
    q1 = m if q1 is None else q1
    out = np.zeros((p1 - p0, q1 - q0), dtype)
    for k in range(L, n if top else L + 1):
        u = 1 << (k - L)
        for x, ro, co in (("C", u, u), ("R", u, 0), ("K", 0, u)):
            a_lo = max(-(-(p0 - ro) // (2 * u)), 0)
            a_hi = (p1 - 1 - ro) // (2 * u)
            b_lo = max(-(-(q0 - co) // (2 * u)), 0)
            b_hi = (q1 - 1 - co) // (2 * u)
            if a_hi < a_lo or b_hi < b_lo:
                continue
            rows = sa.read(f"{pre}{x}{k}", a_lo, a_hi + 1, b_lo, b_hi + 1)
            a_hi, b_hi = a_lo + rows.shape[0] - 1, b_lo + rows.shape[1] - 1
            out[ro + 2 * u * a_lo - p0:ro + 2 * u * a_hi - p0 + 1:2 * u,
                co + 2 * u * b_lo - q0:co + 2 * u * b_hi - q0 + 1:2 * u] = rows
    if top and f"{pre}T" in sa:  # the roots' corners (every 2^(n − L)-th sample)
        u = 1 << (n - L)
        a_lo, a_hi = -(-p0 // u), (p1 - 1) // u
        b_lo, b_hi = -(-q0 // u), (q1 - 1) // u
        if a_hi >= a_lo and b_hi >= b_lo:
            out[a_lo * u - p0:a_hi * u - p0 + 1:u,
                b_lo * u - q0:b_hi * u - q0 + 1:u] = sa.read(f"{pre}T", a_lo, a_hi + 1,
                                                             b_lo, b_hi + 1)
    return out


def raise_delta(sa: ScratchArrays, n: int, terms: str = "", pre: str = "",
                budget: int = 16 << 20) -> float:
    """δ made to hold in a curvilinear grid's metric x, y
    (:func:`geoterrain.bounds.curvature.metric_bounds` on per-level arrays): each saturated
    ``{pre}C{k}``… raised to the metric term ``{terms}dm{x}{k}`` (rounded up to float32),
    +inf where ``{terms}b{x}{k}`` flags a bulging border chord, then saturated again
    (seed 002 §2.4, L46). Returns the largest finite δ.

    Examples
    --------
    >>> d = band_vertex_errors(rows_of(np.zeros((5, 5)), np.ones((5, 5), bool)), 5, band=2)
    >>> for k, nb in ((0, 2), (1, 1)):
    ...     for x, sh in zip("CRK", ((nb, nb), (nb, nb + 1), (nb + 1, nb))):
    ...         d.arrays.create(f"dm{x}{k}", sh, np.float64)
    ...         d.arrays.create(f"b{x}{k}", sh, np.uint8)
    >>> d.arrays.write("dmC0", 0, np.full((2, 2), 0.1))
    >>> raise_delta(d.arrays, 2) == float(np.float32(0.1))  # rounded up, saturated
    True
    """
    from geoterrain.bounds.curvature import _round_up

    for k in range(n):
        for x in "CRK":
            nr, nc = sa.shape(f"{pre}{x}{k}")
            step = max(1, budget // (16 * (nc + 1)))
            for a0 in range(0, nr, step):
                a1 = min(a0 + step, nr)
                d = np.maximum(sa.read(f"{pre}{x}{k}", a0, a1).astype(np.float64),
                               sa.read(f"{terms}dm{x}{k}", a0, a1))
                d[sa.read(f"{terms}b{x}{k}", a0, a1) != 0] = np.inf
                sa.write(f"{pre}{x}{k}", a0, _round_up(d))
    return _saturate(sa, n, budget, pre=pre)


def copy_levels(sa: ScratchArrays, n: int, src: str, dst: str, kinds: str = "CRK",
                budget: int = 16 << 20) -> None:
    """Copy the per-level arrays ``{src}{x}{k}`` to ``{dst}{x}{k}`` (created here)."""
    for k in range(n):
        for x in kinds:
            shape = sa.shape(f"{src}{x}{k}")
            dt = sa.dtype(f"{src}{x}{k}")
            sa.create(f"{dst}{x}{k}", shape, dt)
            step = max(1, budget // (max(shape[1], 1) * dt.itemsize))
            for a0 in range(0, shape[0], step):
                sa.write(f"{dst}{x}{k}", a0, sa.read(f"{src}{x}{k}", a0, a0 + step))
