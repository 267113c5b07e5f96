"""What decoding every tile of the height pyramid gives, computed on the whole grid, as
the encoder computes it on its way (the coding is closed loop: each level is predicted
from the decoded codes of the coarser ones): :func:`decoded_codes`,
:func:`decoded_heights`; the top tile's outward fill of its invalid samples; and the
predictor ``"auto"`` picks (:mod:`geoterrain.codec.pyramid`).
"""

from __future__ import annotations

import numpy as np

from geoterrain.codec.predict import fill_edges_first, fill_level, fill_outward, predict
from geoterrain.codec.pyramid.layout import _period, _root_windows, roots_shape, top_bins
from geoterrain.codec.quantize import Quantizer, codes_to_heights, roundtrip, valid_codes


def _top_fill(top: np.ndarray, valid: np.ndarray, te: int, cubic: bool, W: int = 1,
              edges: bool = False, near: np.ndarray | None = None) -> None:
    """:func:`_fill_top` on contiguous copies of ``top`` and ``valid`` (often strided
    views of the whole grid), the result written back to ``top``: the compiled fill then
    runs on the whole grid's layout, one compilation for both."""
    work = np.array(top)
    _fill_top(work, np.ascontiguousarray(valid), te, cubic, W, edges, near)
    top[...] = work


def _fill_top(top: np.ndarray, valid: np.ndarray, te: int, cubic: bool, W: int = 1,
              edges: bool = False, near: np.ndarray | None = None) -> None:
    """In place on the top tile's codes, what its decoding gives (:func:`entropy._top`):
    an invalid corner holds the fill of the source's codes (the encoder is free to
    choose it: the corners are coded); then level by level of its own grid, a valid
    sample its code in residual bins ``W`` (:func:`geoterrain.codec.predict.fill_level`) and,
    once the level is decoded, every invalid sample its fill from the valid ones and
    the corners (:func:`geoterrain.codec.predict.fill_outward`), which the next level and
    the finer tiles are predicted from. A root of a grid of several (``edges``) fills
    each edge first along itself (:func:`geoterrain.codec.predict.fill_edges_first`), and
    takes its invalid corners from ``near``, the fill of the whole top level (its
    neighbours take the same: a corner is coded, so the encoder chooses it)."""
    P = _period(te, cubic)
    filled = not valid.all()
    if filled:
        c = top.shape[0] - 1  # the corners: [::c, ::c]
        if near is None:
            near = np.array(top)  # a contiguous copy
            fill_outward(near, np.ascontiguousarray(valid))
        top[::c, ::c] = np.where(valid[::c, ::c], top[::c, ::c], near[::c, ::c])
        known = valid.copy()
        known[::c, ::c] = True
    # the decoder fills a stored mask only (entropy._top), and a root of several one
    # without a valid sample too (its corners and edges are its neighbours'); a square's
    # top tile without one keeps its predictions (those and the fill are all 0 there)
    filled = filled and (edges or bool(valid.any()))
    for k in range(te - 1, -1, -1):  # its own levels: 2**te exceeds their intervals
        s = 1 << k
        fill_level(top, valid, s, P, W)
        if filled:
            level = np.array(top[::s, ::s])
            (fill_edges_first if edges else fill_outward)(
                level, np.ascontiguousarray(known[::s, ::s]))
            top[::s, ::s] = level


def _resolve_predictor(
    predictor: str, q: np.ndarray, valid: np.ndarray, te: int, lmax: int
) -> bool:
    """True for the cubic predictor. ``"auto"`` compares the zero-order entropy of the
    finest level's residuals under both predictors (on a central crop of at most
    1025 x 1025 samples) and keeps the smaller."""
    if predictor not in ("linear", "cubic", "auto"):
        raise ValueError(f"unknown predictor {predictor!r}")
    if predictor != "auto" or lmax == 0 or te < 2:
        return predictor == "cubic" and te >= 2 and lmax > 0
    a, crop = _predictor_crop(min(q.shape), te)
    return _predictor_bits(q[a : a + crop, a : a + crop], valid[a : a + crop, a : a + crop], te)


def _predictor_crop(size: int, te: int) -> tuple[int, int]:
    # the central crop of at most 1025² samples "auto" compares the predictors on
    crop = min(size, 1025)
    return ((size - crop) // 2) & ~((1 << te) - 1), crop  # tile-aligned: keeps fallbacks


def _predictor_bits(qq: np.ndarray, vv: np.ndarray, te: int) -> bool:
    # True when the cubic predictor's finest residuals have the smaller zero-order entropy
    bits = []
    for period in (None, 1 << te):
        preds = predict(qq, period)
        h = 0.0
        for sl, p in zip(_CLASSES, preds, strict=True):
            r = np.ascontiguousarray(qq[sl] - p)[vv[sl]]
            zz = ((r << 1) ^ (r >> 63)).view(np.uint64)  # zigzag
            cnt = np.bincount(np.minimum(zz, 1 << 16).astype(np.int64))
            pr = cnt[cnt > 0] / zz.size
            h += float(-(cnt[cnt > 0] * np.log2(pr)).sum())
        bits.append(h)
    return bits[1] < bits[0]


_CLASSES = (
    (slice(0, None, 2), slice(1, None, 2)),
    (slice(1, None, 2), slice(0, None, 2)),
    (slice(1, None, 2), slice(1, None, 2)),
)


def decoded_codes(
    z: np.ndarray, valid: np.ndarray, t: int, quantizer: Quantizer, predictor: str = "auto",
    roots: tuple[int, int] | None = None,
) -> np.ndarray:
    """Codes (N, N) int64 that decoding every tile gives, invalid samples included.

    Level by level on the full grid: valid samples keep their code (or its bins); an
    invalid sample of the top tile ends as its outward fill from the valid ones
    (:func:`geoterrain.codec.predict.fill_outward`), every other invalid sample its
    prediction from the coarser samples. ``predictor`` and ``roots`` as for
    :func:`encode_pyramid`.

    Examples
    --------
    >>> z = np.arange(9.0).reshape(3, 3); v = np.ones((3, 3), bool); v[1, 1] = False
    >>> int(decoded_codes(z, v, 6, Quantizer("int"))[1, 1])  # the centre: its prediction
    4
    """
    valid = np.asarray(valid, dtype=bool)
    n, te = roots_shape(valid.shape, t, roots)
    lmax = n - te
    d = valid_codes(z, valid, quantizer)  # heights_to_codes(where(valid, z, 0))
    return _decoded_codes(d, valid, te, lmax, _resolve_predictor(predictor, d, valid, te, lmax),
                          quantizer.bins, roots)


def _decoded_codes(d: np.ndarray, valid: np.ndarray, te: int, lmax: int, cubic: bool,
                   bins: int = 1, roots: tuple[int, int] | None = None):
    """In place on the codes ``d``: what tile decoding gives at invalid samples, and
    with residual ``bins`` > 1 at valid ones too (coarse to fine: each level's
    predictions read the decoded codes of the coarser ones); on a grid of several
    ``roots``, each root's top tile as its own (the edges they share agree)."""
    s = 1 << lmax
    top, vtop = d[::s, ::s], valid[::s, ::s]
    if roots is None or roots[0] * roots[1] == 1:
        _top_fill(top, vtop, te, cubic, top_bins(bins))
    else:
        near = np.array(top)  # the invalid corners: one fill of the whole top level
        fill_outward(near, np.ascontiguousarray(vtop))
        for (_, _, tw), (_, _, vw), (_, _, nw) in zip(
                _root_windows(top, roots, te), _root_windows(vtop, roots, te),
                _root_windows(near, roots, te), strict=True):
            _top_fill(tw, vw, te, cubic, top_bins(bins), edges=True, near=nw)
    for lev in range(lmax - 1, -1, -1):  # compiled: the rule of predict, in place
        fill_level(d, valid, 1 << lev, _period(te, cubic), bins)
    return d


def decoded_heights(
    z: np.ndarray,
    valid: np.ndarray,
    quantizer: Quantizer,
    t: int | None = None,
    predictor: str = "auto",
) -> np.ndarray:
    """Heights (N, N) float64 exactly as decoding every tile gives them.

    Without residual bins (``quantizer.bins`` = 1), valid samples decode to
    ``codes_to_heights(heights_to_codes(z))`` whatever the pyramid (closed-loop coding).
    Invalid samples are NaN, unless ``t`` is given: then they hold exactly the
    (meaningless) values tile decoding produces (with the same ``predictor`` as the
    encoding). With bins the decoded heights depend on the pyramid: ``t`` is then
    required.

    Examples
    --------
    >>> qz = Quantizer("quantized", 0.2, 0.0, 0.1)
    >>> decoded_heights(np.array([[0.33]]), np.array([[True]]), qz).round(6).tolist()
    [[0.4]]
    """
    valid = np.asarray(valid, dtype=bool)
    if t is not None:
        d = decoded_codes(z, valid, t, quantizer, predictor)
        return codes_to_heights(d, quantizer)
    if quantizer.bins > 1:
        raise ValueError("heights decoded through residual bins depend on the pyramid: "
                         "pass t")
    return roundtrip(z, valid, quantizer)  # the same values, in one compiled pass
