"""Where the height codec's bits go, and what better entropy coding could save (issue 12).

For each shared DEM (``../shared/dems``, skipped when absent) and ε, the pyramid of
``bench_codec.py`` (t = 6, the preprocess predictor choice), in bits per valid sample:

- **ours**: every tile blob, as stored (headers, masks, range-coded streams);
- **top**: the top tile's blob alone (coded coarse to fine inside itself; decoded first);
- **below top, as stored**: the other blobs;
- **H0 per tile**: the order-0 entropy of each tile's zigzag residuals, summed over the
  valid samples (an ideal static coder with a free table per tile: a bound that no
  real per-tile coder reaches, tables and learning cost bits);
- **H | context**: the entropy of the residuals given their class (row, column or cell
  midpoint) and the log2 bucket of the parents' height difference along the predicted
  span (one model per level: what a context-adaptive arithmetic coder could approach);
- **SZ3**: ``pysz`` ABS at ε on the whole array, as ``bench_codec.py`` runs it.

The entropies count valid samples only (the decoder knows the mask). They show which
gaps an entropy coder alone could close and which need another quantiser (SZ3 codes
the prediction error in bins of 2ε; ours quantises the heights first, docs/lab/height-codec.md).

    python benchmarks/bench_entropy.py [--eps 0.5 1 2] [--dem NAME ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).parent))

from bench_codec import load_dems, pad, sz3_bytes  # noqa: E402

from geoterrain.codec.predict import predict  # noqa: E402
from geoterrain.codec.pyramid import encode_pyramid, pyramid_shape  # noqa: E402
from geoterrain.codec.pyramid.decoded import _decoded_codes, _resolve_predictor  # noqa: E402
from geoterrain.codec.quantchoice import choose_quantizer  # noqa: E402
from geoterrain.codec.quantize import valid_codes  # noqa: E402


def entropy_bits(x: np.ndarray) -> float:
    """Total order-0 entropy of the values ``x``, in bits."""
    if x.size == 0:
        return 0.0
    _, c = np.unique(x, return_counts=True)
    return float(-(c * np.log2(c / c.sum())).sum())


def conditional_bits(x: np.ndarray, ctx: np.ndarray) -> float:
    """Total entropy of ``x`` given ``ctx`` (one order-0 model per context), in bits."""
    order = np.argsort(ctx, kind="stable")
    xs, cs = x[order], ctx[order]
    cuts = np.flatnonzero(np.diff(cs)) + 1
    return sum(entropy_bits(part) for part in np.split(xs, cuts))


def tile_blocks(a: np.ndarray, nt: int, hh: int, rows: int, cols: int) -> np.ndarray:
    """(nt, nt, rows·cols): each tile's block of ``a`` in raster order (the tiles of one
    level overlap by a row and a column of the parent grid)."""
    out = np.empty((nt, nt, rows * cols), a.dtype)
    for ty in range(nt):
        for tx in range(nt):
            out[ty, tx] = a[ty * hh:ty * hh + rows, tx * hh:tx * hh + cols].ravel()
    return out


def level_residuals(d: np.ndarray, v: np.ndarray, n: int, te: int, lev: int, cubic: bool):
    """The zigzag residuals of every tile of level ``lev`` in the codec's order, with each
    sample's valid flag and context (class, activity bucket)."""
    hh = 1 << (te - 1)
    s, nt = 1 << lev, 1 << (n - lev - te)
    lv = d[::s, ::s]
    P = lv[::2, ::2]
    preds = predict(lv, (1 << te) if cubic else None)
    V = v[::s, ::s]
    sls = [(slice(0, None, 2), slice(1, None, 2)), (slice(1, None, 2), slice(0, None, 2)),
           (slice(1, None, 2), slice(1, None, 2))]
    res = [lv[sl] - p for sl, p in zip(sls, preds, strict=True)]
    act = [np.abs(P[:, 1:] - P[:, :-1]), np.abs(P[1:, :] - P[:-1, :]),
           np.maximum(np.abs(P[1:, 1:] - P[:-1, :-1]), np.abs(P[1:, :-1] - P[:-1, 1:]))]
    shapes = [(hh + 1, hh), (hh, hh + 1), (hh, hh)]

    def blocks(arrs):
        return np.concatenate([tile_blocks(a, nt, hh, *sh)
                               for a, sh in zip(arrs, shapes, strict=True)], 2)

    r = blocks(res)
    zz = (r << 1) ^ (r >> 63)
    valid = blocks([V[sl] for sl in sls])
    acts = blocks(act)
    cls = np.concatenate([np.full(a * b, k) for k, (a, b) in enumerate(shapes)])
    bucket = np.minimum(np.floor(np.log2(1.0 + acts)).astype(np.int64), 15)
    return zz, valid, bucket * 3 + cls[None, None, :]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--eps", type=float, nargs="+", default=[0.5, 1.0, 2.0])
    ap.add_argument("--dem", nargs="*", default=None, help="substrings of the DEM names")
    a = ap.parse_args(argv)
    print("| DEM | ε | ours | top | below top, as stored | H0 per tile | H given context "
          "| SZ3 |")
    print("|---|---|---|---|---|---|---|---|")
    for name, h, valid, native, scale, offset in load_dems():
        if a.dem and not any(w in name for w in a.dem):
            continue
        for eps in a.eps:
            qz = choose_quantizer(h[valid], native.dtype, codec_error=eps, scale=scale,
                                  offset=offset)
            z, v = pad(h, valid)
            nv = int(valid.sum())
            blobs = encode_pyramid(z, v, 6, qz)
            n, te = pyramid_shape(z.shape[0], 6)
            lmax = n - te
            d = valid_codes(z, v, qz)
            cubic = _resolve_predictor("auto", d, v, te, lmax)
            d = _decoded_codes(d, v, te, lmax, cubic)
            h0 = hc = 0.0
            for lev in range(lmax - 1, -1, -1):
                zz, ok, ctx = level_residuals(d, v, n, te, lev, cubic)
                h0 += sum(entropy_bits(zz[y, x][ok[y, x]])
                          for y in range(zz.shape[0]) for x in range(zz.shape[1]))
                hc += conditional_bits(zz[ok], ctx[ok])
            top = len(blobs[(lmax, 0, 0)]) * 8 / nv
            ours = sum(map(len, blobs.values())) * 8 / nv
            sz = sz3_bytes(h, valid, eps)
            print(f"| {name} | {eps:g} | {ours:.3f} | {top:.3f} | {ours - top:.3f} | "
                  f"{h0 / nv:.3f} | {hc / nv:.3f} | "
                  + (f"{sz * 8 / nv:.3f} |" if sz else "n/a |"), flush=True)


if __name__ == "__main__":
    main()
