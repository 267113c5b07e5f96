"""The coarse levels of δ read in bands (half-span h ≥ B, blocks that span bands): each
band adds its rows to every all-valid block's running maxima and to each mixed diamond's
running sweep; once every row is in, the whole grid's branches give the raw δ (a maximum
over rows is exact: the split changes no bit). :mod:`geoterrain.preprocessing.bands.delta`
drives them."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from geoterrain.bounds.delta import (
    Cell,
    Diamond,
    _block_sweep_part,
    _edge_err_part,
    edge_status_nb,
)
from geoterrain.core.bintree import main_diagonal_nb
from geoterrain.core.rounding import round_up32
from geoterrain.core.threads import parallel_kernel

__all__ = ["BlockMaxima", "Sweeps"]


class BlockMaxima(NamedTuple):
    """A coarse level's running maxima, per block: of its centre's sweep and of its four
    quarters' (left, right, top, bottom: the edge midpoints' sides), as
    :func:`geoterrain.bounds.delta._block_sweep_part` returns them."""

    centre: np.ndarray
    left: np.ndarray
    right: np.ndarray
    top: np.ndarray
    bottom: np.ndarray


class Sweeps(NamedTuple):
    """Running sweeps of a coarse level's mixed edge midpoints, one per listed diamond:
    the largest error ``m``, the valid samples ``valid`` and all samples ``total`` seen
    (:func:`geoterrain.bounds.delta.edge_status_nb` once every row is in)."""

    m: np.ndarray
    valid: np.ndarray
    total: np.ndarray


@parallel_kernel(cache=True)
def _coarse_rows_nb(band, h, st, zd, acc):
    """Add the ``band``'s rows (:class:`BandWindow`: r_lo … r_hi, inclusive, inside the
    window from w0) to the running maxima ``acc`` (:class:`BlockMaxima`) of every
    all-valid block of the coarse level h (corners from the decimated grid ``zd``, every
    dB = B samples)."""
    z, w0, dB, r_lo, r_hi = band.z, band.w0, band.B, band.r0, band.r_end
    MC = acc.centre  # one by one (see bounds.tileblobs._level_payloads)
    QL = acc.left
    QR = acc.right
    QT = acc.top
    QB = acc.bottom
    s = 2 * h
    nbr, nb = st.shape
    k = s // dB
    for b in prange(nb):
        for a in range(max(r_lo // s - 1, 0), min(r_hi // s, nbr - 1) + 1):
            d0 = max(r_lo - a * s, 0)
            d1 = min(r_hi - a * s, s)
            if d0 > d1 or st[a, b] != 1:
                continue
            main = main_diagonal_nb(a, b)
            mc, ml, mr, mt, mb = _block_sweep_part(
                z, Cell(a * s, b * s, s, main, zd[a * k, b * k], zd[a * k, b * k + k],
                        zd[a * k + k, b * k], zd[a * k + k, b * k + k]),
                zd[a * k + k // 2, b * k + k // 2], d0, d1, w0)
            MC[a, b] = max(MC[a, b], mc)
            QL[a, b] = max(QL[a, b], ml)
            QR[a, b] = max(QR[a, b], mr)
            QT[a, b] = max(QT[a, b], mt)
            QB[a, b] = max(QB[a, b], mb)


@njit(cache=True)
def _coarse_edges_nb(band, h, zd, rows, todo, sweeps):
    """Add the ``band``'s rows (:class:`BandWindow`: r_lo … r_hi) to the running
    ``sweeps`` (:class:`Sweeps`) of the coarse level's mixed edge midpoints listed in
    ``todo`` ((a, b) rows; R-type if ``rows``, else K-type; corners from ``zd``, every
    dB = B samples)."""
    z, vb, w0, dB, r_lo, r_hi = band.z, band.v, band.w0, band.B, band.r0, band.r_end
    NR, NC = band.R, band.C
    EM, EC, ET = sweeps
    s = 2 * h
    u = h // dB  # h in decimated steps
    for t in range(todo.shape[0]):
        a = todo[t, 0]
        b = todo[t, 1]
        if rows:
            ic = h + a * s
            jc = b * s
            ii = (ic // dB)
            jj = (jc // dB)
            lo_ok = jc - h >= 0
            hi_ok = jc + h <= NC - 1
            za = zd[ii - u, jj]
            zb = zd[ii + u, jj]
            z_lo = zd[ii, jj - u] if lo_ok else 0.0
            z_hi = zd[ii, jj + u] if hi_ok else 0.0
        else:
            ic = a * s
            jc = h + b * s
            ii = (ic // dB)
            jj = (jc // dB)
            lo_ok = ic - h >= 0
            hi_ok = ic + h <= NR - 1
            za = zd[ii, jj - u]
            zb = zd[ii, jj + u]
            z_lo = zd[ii - u, jj] if lo_ok else 0.0
            z_hi = zd[ii + u, jj] if hi_ok else 0.0
        d0 = max(r_lo - ic, -h)
        d1 = min(r_hi - ic, h)
        if d0 > d1:
            continue
        m, c, n = _edge_err_part(z, vb, Diamond(ic, jc, h, rows, lo_ok, hi_ok, za, zb, z_lo,
                                                z_hi), d0, d1, w0)
        EM[t] = max(EM[t], m)
        EC[t] += c
        ET[t] += n


@njit(cache=True)
def _coarse_finish_nb(st, acc, rtodo, rsw, ktodo, ksw, out):
    # the branches of bounds._raw_delta_nb, once every row has been added: from the blocks'
    # maxima ``acc`` (BlockMaxima) and the mixed edges' sweeps (Sweeps), into ``out``
    # (LevelVertices)
    MC, QL, QR, QT, QB = acc
    C, R, K = out
    nbr, nb = st.shape
    for a in range(nbr):
        for b in range(nb):
            if st[a, b] == 1:
                C[a, b] = round_up32(MC[a, b])
            elif st[a, b] == 3:
                C[a, b] = np.inf
    for a in range(nbr):
        for b in range(nb + 1):
            flo = st[a, b - 1] if b > 0 else 0
            fhi = st[a, b] if b < nb else 0
            if flo | fhi == 1:
                m = 0.0
                if flo:
                    m = max(m, QR[a, b - 1])
                if fhi:
                    m = max(m, QL[a, b])
                R[a, b] = round_up32(m)
    for a in range(nbr + 1):
        for b in range(nb):
            flo = st[a - 1, b] if a > 0 else 0
            fhi = st[a, b] if a < nbr else 0
            if flo | fhi == 1:
                m = 0.0
                if flo:
                    m = max(m, QB[a - 1, b])
                if fhi:
                    m = max(m, QT[a, b])
                K[a, b] = round_up32(m)
    for todo, (em, ec, et), vals in ((rtodo, rsw, R), (ktodo, ksw, K)):
        for t in range(todo.shape[0]):
            m, c = edge_status_nb(em[t], ec[t], et[t])
            if c == 2:
                vals[todo[t, 0], todo[t, 1]] = np.inf
            elif c == 1:
                vals[todo[t, 0], todo[t, 1]] = round_up32(m)


def _mixed_edges(st: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # (a, b) of the R- and K-type edge midpoints whose two blocks' statuses mix (f = 3)
    nbr, nb = st.shape
    z = np.zeros((nbr, 1), np.uint8)
    fr = np.hstack([z, st]) | np.hstack([st, z])
    zk = np.zeros((1, nb), np.uint8)
    fk = np.vstack([zk, st]) | np.vstack([st, zk])
    return (np.argwhere(fr == 3).astype(np.int64), np.argwhere(fk == 3).astype(np.int64))
