"""Benchmark of the residual pyramid codec against flat baselines.

Bits per valid sample on the real DEMs of ``../shared/dems`` (skipped when absent) and
on seeded synthetic fractal fields, at epsilon in {0 (lossless), 0.1, 0.5, 1, 2} (source
vertical units), for:

- ours: the sum of the pyramid's tile blobs (every level, masks included; t = 6);
- zstd-raw: zstd-19 of the raw source array (native dtype, lossless);
- q+delta: the same codes as ours (quantised to ~2 eps, or lossless), row delta,
  narrowest int, zstd-19;
- LERC at the same eps (lossless on the native array for eps = 0);
- SZ3 (``pysz``, ABS error bound = eps, float64 heights; eps > 0 only), the error-bounded
  compressor of the scientific-data field: one whole array, no single-tile decoding and
  no mask (voids are filled with the lowest valid height), decoded and checked within
  eps on the valid samples like ours.

Run from the project root::

    python benchmarks/bench_codec.py [--quick] [--dems-only] [--eps 0.5 1 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import zstandard

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from geoterrain.codec.pyramid import decode_tile, encode_pyramid  # noqa: E402
from geoterrain.codec.quantchoice import choose_quantizer  # noqa: E402
from geoterrain.codec.quantize import codes_to_heights, heights_to_codes  # noqa: E402

DEMS = Path(__file__).resolve().parents[2] / "shared" / "dems"
EPSILONS = [0.0, 0.1, 0.5, 1.0, 2.0]
_RAW: dict = {}


def load_dems() -> list[tuple[str, np.ndarray, np.ndarray, np.dtype, float | None, float | None]]:
    """(name, heights float64, valid, native array, scale, offset) for each present file."""
    out = []
    for name in ("srtm3_pysheds.tif", "srtm1_japan.tif", "roi_epsg3089.tif"):
        path = DEMS / name
        if not path.exists():
            continue
        import rasterio

        with rasterio.open(path) as ds:
            raw = ds.read(1)
            nodata = ds.nodata
        valid = np.ones(raw.shape, bool) if nodata is None else raw != nodata
        valid &= np.isfinite(raw)
        out.append((name, raw.astype(np.float64), valid, raw, None, None))
    for name, kind in (
        ("fuji_terrain_rgb.png", "rgb"),
        ("st_helens_terrain_rgb.png", "rgb"),
        ("terrarium.png", "terrarium"),
    ):
        path = DEMS / name
        if not path.exists():
            continue
        from PIL import Image

        rgb = np.asarray(Image.open(path).convert("RGB")).astype(np.int64)
        r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
        if kind == "rgb":
            code = r * 65536 + g * 256 + b
            h = -10000 + code * 0.1
            out.append((name, h, np.ones(h.shape, bool), code.astype(np.int32), 0.1, -10000.0))
        else:
            h = r * 256 + g + b / 256 - 32768
            code = r * 65536 + g * 256 + b
            out.append((name, h, np.ones(h.shape, bool), code.astype(np.int32), 1 / 256, -32768.0))
    return out


def fractal(size: int, seed: int, relief: float = 2000.0) -> np.ndarray:
    """Seeded spectral-synthesis fractal surface (amplitude ~ f**-1.6), float32 heights."""
    rng = np.random.default_rng(seed)
    f = np.sqrt(np.fft.fftfreq(size)[:, None] ** 2 + np.fft.rfftfreq(size)[None, :] ** 2)
    f[0, 0] = 1.0
    spec = (rng.normal(size=f.shape) + 1j * rng.normal(size=f.shape)) / f**1.6
    spec[0, 0] = 0
    z = np.fft.irfft2(spec, s=(size, size))
    z = (z - z.min()) / (z.max() - z.min()) * relief
    return z.astype(np.float32)


def pad(h: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Embed at the top-left of N x N, N = 2**n + 1 (docs/conventions.md)."""
    m = max(h.shape)
    n = max(1, int(np.ceil(np.log2(max(m - 1, 1)))))
    size = (1 << n) + 1
    z = np.zeros((size, size))
    v = np.zeros((size, size), bool)
    z[: h.shape[0], : h.shape[1]] = np.where(valid, h, 0.0)
    v[: h.shape[0], : h.shape[1]] = valid
    return z, v


def zstd19(data: bytes) -> bytes:
    return zstandard.ZstdCompressor(level=19, threads=-1).compress(data)


def narrow(a: np.ndarray) -> np.ndarray:
    lo, hi = int(a.min()), int(a.max())
    for dt in (np.int8, np.int16, np.int32):
        if np.iinfo(dt).min <= lo and hi <= np.iinfo(dt).max:
            return a.astype(dt)
    return a.astype(np.int64)


def sz3_bytes(h: np.ndarray, valid: np.ndarray, eps: float) -> int | None:
    """SZ3 (ABS mode) of the heights, checked within eps on the valid samples; None when
    pysz is absent or eps = 0."""
    try:
        from pysz import sz, szConfig, szErrorBoundMode
    except ImportError:
        return None
    if eps <= 0:
        return None
    a = np.ascontiguousarray(np.where(valid, h, h[valid].min()), dtype=np.float64)
    cfg = szConfig()
    cfg.errorBoundMode = szErrorBoundMode.ABS
    cfg.absErrorBound = eps
    comp, _ = sz.compress(a, cfg)
    dec, _ = sz.decompress(comp, np.float64, a.shape)
    worst = float(np.max(np.abs(dec[valid] - h[valid])))
    assert worst <= eps, ("SZ3", eps, worst)
    return int(comp.nbytes)


def run_one(name, h, valid, native, scale, offset, eps, rows, lerc_ok):
    nvalid = int(valid.sum())
    src_dtype = native.dtype
    qz = choose_quantizer(h[valid], src_dtype, codec_error=eps or None, scale=scale, offset=offset)
    z, v = pad(h, valid)
    t0 = time.perf_counter()
    blobs = encode_pyramid(z, v, 6, qz)
    t_enc = time.perf_counter() - t0
    ours = sum(map(len, blobs.values()))
    # decode every tile top-down
    t0 = time.perf_counter()
    cache: dict = {}
    worst = 0.0
    for key in sorted(blobs, key=lambda k: -k[0]):  # parents first
        lev, x, y = key
        parent = cache.get((lev + 1, x // 2, y // 2))  # None for the top tile
        cache[key] = decode_tile(blobs[key], parent, qz, (x % 2, y % 2))
    t_dec = time.perf_counter() - t0
    span = 1 << min(6, int(np.log2(z.shape[0] - 1)))
    for (lev, x, y), codes in cache.items():
        if lev == 0:
            sl = (slice(y * span, y * span + span + 1), slice(x * span, x * span + span + 1))
            d = codes_to_heights(codes, qz)[v[sl]] - z[sl][v[sl]]
            worst = max(worst, float(np.max(np.abs(d))) if d.size else 0.0)
    assert worst <= eps, (name, eps, worst)
    # baselines
    key = (name, native.shape)
    if key not in _RAW:  # epsilon-independent
        _RAW[key] = len(zstd19(np.ascontiguousarray(native).tobytes()))
    raw = _RAW[key]
    codes = heights_to_codes(np.where(valid, h, h[valid].min()), qz)
    codes = np.where(valid, codes, 0)
    delta = np.diff(codes, axis=1, prepend=np.int64(0))
    qd = len(zstd19(narrow(delta).tobytes()))
    lerc_bytes, t_lerc = None, None
    if lerc_ok:
        import lerc

        t0 = time.perf_counter()
        if eps == 0:
            arr = np.ascontiguousarray(native)
            zerr = 0.5 if arr.dtype.kind in "iu" else 0.0
        else:
            arr, zerr = np.ascontiguousarray(h), eps
        res, nbytes, _ = lerc.encode(arr, 1, not valid.all(), valid, zerr, 1)
        t_lerc = time.perf_counter() - t0
        lerc_bytes = int(nbytes) if res == 0 else None
    best = min(b for b in (raw, qd, lerc_bytes) if b)
    sz3 = sz3_bytes(h, valid, eps)
    bps = 8.0 / nvalid
    rows.append(
        f"| {name} | {eps:g} | {qz.mode} | {ours * bps:.3f} | {raw * bps:.3f} | {qd * bps:.3f} | "
        + (f"{lerc_bytes * bps:.3f}" if lerc_bytes else "n/a")
        + f" | {ours / best:.3f} | {t_enc:.2f} | {t_dec:.2f} | "
        + (f"{t_lerc:.2f}" if t_lerc is not None else "n/a")
        + f" | {len(blobs)} | "
        + (f"{sz3 * bps:.3f} | {ours / sz3:.3f} |" if sz3 else "n/a | n/a |")
    )
    print(rows[-1], flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the 4097^2 synthetic field")
    ap.add_argument("--dems-only", action="store_true", help="skip the synthetic fields")
    ap.add_argument("--eps", type=float, nargs="+", default=EPSILONS, help="codec bounds")
    args = ap.parse_args()
    try:
        import lerc  # noqa: F401

        lerc_ok = True
    except ImportError:
        lerc_ok = False
    data = load_dems()
    sizes = [] if args.dems_only else [1025] if args.quick else [1025, 4097]
    for size in sizes:
        h = fractal(size, 42)
        data.append(
            (
                f"fractal {size}^2 (float32)",
                h.astype(np.float64),
                np.ones(h.shape, bool),
                h,
                None,
                None,
            )
        )
    header = (
        "| data | eps | mode | ours b/s | zstd-raw b/s | q+delta+zstd b/s | LERC b/s | "
        "ours/best | ours enc s | ours dec s | LERC enc s | tiles | SZ3 b/s | ours/SZ3 |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )
    print(header, flush=True)
    rows: list[str] = []
    for name, h, valid, native, scale, offset in data:
        for eps in args.eps:
            run_one(name, h, valid, native, scale, offset, eps, rows, lerc_ok)


if __name__ == "__main__":
    main()
