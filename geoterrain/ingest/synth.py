"""Synthetic digital elevation models (fractal terrain generators).

Generators after annex A of seed 000: fBm and ridged multifractal sums of a
smooth lattice noise, diamond-square midpoint displacement and random fault
formation. Every generator is deterministic per ``seed`` (a
``numpy.random.Generator``), vectorised over the grid, and returns float32
heights in metres rescaled to ``base + [0, relief]``.

Kinds and their parameters (all optional):

``"fbm"``
    Fractional Brownian motion: ``sum_k w_k · noise(lacunarity**k · x)`` with
    ``w_k = lacunarity**(-H·k)``. ``octaves`` (float, fractional octaves
    blend the last one in; default: down to a 2-sample wavelength), ``H``
    (Hurst exponent in [0, 1], default 0.8; persistence = lacunarity**-H,
    or give ``persistence`` directly), ``lacunarity`` (default 2.0),
    ``cells`` (lattice cells across the largest side at octave 0, default 2).
``"ridged"``
    Musgrave's ridged multifractal: ``signal = (offset - |noise|)**2``
    weighted by the previous octave's ``clip(signal · gain, 0, 1)``.
    ``octaves``, ``H`` (default 1.0), ``lacunarity``, ``cells`` as for fBm,
    ``offset`` (default 1.0), ``gain`` (default 2.0).
``"diamond-square"``
    Midpoint displacement on a 2**k + 1 grid (cropped to the requested
    shape): the displacement range shrinks by ``2**-roughness`` per level;
    ``roughness`` r > 1 gives smooth terrain, r < 1 chaotic (default 1.0).
``"fault"``
    Random fault lines: each fault raises one side of a random line by a
    displacement that decays linearly from ``d0`` to ``d1`` (relative, default
    1.0 → 0.1) over ``faults`` iterations (default 400, capped at 2000).
    ``profile`` is ``"step"``, ``"sine"`` or ``"cosine"`` (with ``width``,
    the transition half-width as a fraction of the domain, default 0.02;
    "cosine" raises a ridge along the line instead of a step). Faults
    are formed on a grid of at most ``resolution`` (default 513) samples per
    side, smoothed by ``smooth`` passes of a [1, 2, 1]/4 filter (default 2) and
    interpolated up to the requested shape.

Common parameters: ``relief`` (metres between the lowest and highest sample,
default 2000.0) and ``base`` (height of the lowest sample, default 0.0).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["KINDS", "generate", "write_geotiff"]

KINDS = ("fbm", "ridged", "diamond-square", "fault")
_MAX_FAULTS = 2000


def _shape(size: int | tuple[int, int]) -> tuple[int, int]:
    if isinstance(size, (int, np.integer)):
        rows = cols = int(size)
    else:
        rows, cols = (int(s) for s in size)
    if rows < 1 or cols < 1:
        raise ValueError(f"size must be positive, got {size!r}")
    return rows, cols


def _catmull_rom_weights(t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Catmull-Rom cubic weights for the 4 lattice nodes around a fraction t in [0, 1)."""
    t2 = t * t
    t3 = t2 * t
    w0 = 0.5 * (-t3 + 2.0 * t2 - t)
    w1 = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0)
    w2 = 0.5 * (-3.0 * t3 + 4.0 * t2 + t)
    w3 = 0.5 * (t3 - t2)
    return w0, w1, w2, w3


def _interp_axis(
    lattice: np.ndarray,
    pos: np.ndarray,
    axis: int,
    out: np.ndarray | None = None,
    scale: float = 1.0,
    add: bool = False,
) -> np.ndarray:
    """Cubic interpolation of ``lattice`` at fractional node positions ``pos`` along ``axis``.

    Node k of the lattice sits at position k - 1 (one node of margin on each side).
    The result times ``scale`` is written to (or, with ``add``, added to) ``out``.
    Work proceeds in blocks of rows so that temporaries stay small and cache-resident.
    """
    base = np.floor(pos)
    t = (pos - base).astype(np.float32)
    idx = base.astype(np.int64)  # taps are lattice nodes idx .. idx + 3
    w = [wk * np.float32(scale) for wk in _catmull_rom_weights(t)]
    shape = (pos.size, lattice.shape[1]) if axis == 0 else (lattice.shape[0], pos.size)
    if out is None:
        out = np.zeros(shape, np.float32) if add else np.empty(shape, np.float32)
    block = max(1, (1 << 16) // max(shape[1], 1))
    tmp = np.empty((block, shape[1]), np.float32)
    for r0 in range(0, shape[0], block):
        r1 = min(r0 + block, shape[0])
        acc = tmp[: r1 - r0]
        for k in range(4):
            if axis == 0:
                taps = lattice[idx[r0:r1] + k]
                wk = w[k][r0:r1, None]
            else:
                taps = np.take(lattice[r0:r1], idx + k, axis=1)
                wk = w[k][None, :]
            if k == 0:
                np.multiply(taps, wk, out=acc)
            else:
                taps *= wk
                acc += taps
        if add:
            out[r0:r1] += acc
        else:
            out[r0:r1] = acc
    return out


def _noise(
    rows: int,
    cols: int,
    cells: float,
    rng: np.random.Generator,
    out: np.ndarray | None = None,
    scale: float = 1.0,
    add: bool = False,
) -> np.ndarray:
    """Smooth lattice (value) noise in about [-1, 1]: ``cells`` lattice cells across max side.

    Uniform random values on a lattice, interpolated with separable Catmull-Rom
    cubics at a random sub-cell offset (so octaves do not share lattice points).
    ``scale``, ``out`` and ``add`` are as in :func:`_interp_axis`.
    """
    step = cells / max(rows, cols)  # lattice units per sample
    oy, ox = rng.random(2)
    py = oy + np.arange(rows) * step
    px = ox + np.arange(cols) * step
    gh = int(math.floor(py[-1])) + 4
    gw = int(math.floor(px[-1])) + 4
    lattice = rng.random((gh, gw), dtype=np.float32) * 2.0 - 1.0
    tmp = _interp_axis(lattice, px, axis=1)  # (gh, cols): at most about half the output
    return _interp_axis(tmp, py, axis=0, out=out, scale=scale, add=add)  # (rows, cols)


def _octaves(rows: int, cols: int, cells: float, lacunarity: float, octaves: Any) -> float:
    if octaves is not None:
        return float(octaves)
    # Finest octave: a lattice cell spans about 2 samples.
    return max(1.0, math.floor(math.log(max(rows, cols) / (2.0 * cells), lacunarity)) + 1.0)


def _fbm(rows: int, cols: int, rng: np.random.Generator, p: dict[str, Any]) -> np.ndarray:
    lac = float(p.pop("lacunarity", 2.0))
    cells = float(p.pop("cells", 2.0))
    H = float(p.pop("H", 0.8))
    persistence = float(p.pop("persistence", lac**-H))
    octs = _octaves(rows, cols, cells, lac, p.pop("octaves", None))
    out = np.zeros((rows, cols), np.float32)
    amp, freq = 1.0, cells
    for k in range(int(math.ceil(octs))):
        weight = min(1.0, octs - k)  # fractional last octave (remainder term)
        _noise(rows, cols, freq, rng, out=out, scale=amp * weight, add=True)
        amp *= persistence
        freq *= lac
    return out


def _ridged(rows: int, cols: int, rng: np.random.Generator, p: dict[str, Any]) -> np.ndarray:
    lac = float(p.pop("lacunarity", 2.0))
    cells = float(p.pop("cells", 2.0))
    H = float(p.pop("H", 1.0))
    offset = np.float32(p.pop("offset", 1.0))
    gain = np.float32(p.pop("gain", 2.0))
    octs = _octaves(rows, cols, cells, lac, p.pop("octaves", None))
    freq = cells

    def ridge(buf: np.ndarray) -> np.ndarray:  # (offset - |n|)**2, in place
        np.abs(buf, out=buf)
        np.subtract(offset, buf, out=buf)
        return np.multiply(buf, buf, out=buf)

    signal = ridge(_noise(rows, cols, freq, rng))
    out = signal.copy()
    weight = np.empty_like(signal)
    for k in range(1, int(math.ceil(octs))):
        np.multiply(signal, gain, out=weight)
        np.clip(weight, 0.0, 1.0, out=weight)
        freq *= lac
        ridge(_noise(rows, cols, freq, rng, out=signal))
        signal *= weight
        frac = min(1.0, octs - k)  # fractional last octave (remainder term)
        np.multiply(signal, np.float32(lac ** (-H * k) * frac), out=weight)  # scratch
        out += weight
    return out


def _diamond_square(
    rows: int, cols: int, rng: np.random.Generator, p: dict[str, Any]
) -> np.ndarray:
    r = float(p.pop("roughness", 1.0))
    n = max(1, math.ceil(math.log2(max(rows, cols, 2) - 1)))
    N = 2**n + 1
    G = np.zeros((N, N), np.float32)
    G[:: N - 1, :: N - 1] = rng.random((2, 2), dtype=np.float32) * 2.0 - 1.0
    d = 1.0
    s = N - 1
    while s > 1:
        h = s // 2
        m = (N - 1) // s
        # Diamond step (Eq A-4): cell centres = mean of the four corners + rand(-d/2, d/2).
        C = G[0:N - 1:s, 0:N - 1:s] + G[s::s, 0:N - 1:s] + G[0:N - 1:s, s::s] + G[s::s, s::s]
        C *= 0.25
        C += (rng.random((m, m), dtype=np.float32) - 0.5) * np.float32(d)
        G[h::s, h::s] = C
        cnt = np.full(m + 1, 4.0, np.float32)
        cnt[0] = cnt[-1] = 3.0
        # Square step, edge midpoints on corner rows: left + right corners, centres above/below.
        A = G[0::s, 0:N - 1:s] + G[0::s, s::s]
        A[1:] += C
        A[:-1] += C
        A /= cnt[:, None]
        A += (rng.random(A.shape, dtype=np.float32) - 0.5) * np.float32(d)
        G[0::s, h::s] = A
        # ... and on corner columns: corners above + below, centres left/right.
        B = G[0:N - 1:s, 0::s] + G[s::s, 0::s]
        B[:, 1:] += C
        B[:, :-1] += C
        B /= cnt[None, :]
        B += (rng.random(B.shape, dtype=np.float32) - 0.5) * np.float32(d)
        G[h::s, 0::s] = B
        d *= 2.0**-r
        s = h
    return G[:rows, :cols]


def _fault(rows: int, cols: int, rng: np.random.Generator, p: dict[str, Any]) -> np.ndarray:
    faults = int(min(max(int(p.pop("faults", 400)), 1), _MAX_FAULTS))
    d0 = float(p.pop("d0", 1.0))
    d1 = float(p.pop("d1", 0.1))
    profile = str(p.pop("profile", "step"))
    width = float(p.pop("width", 0.02))
    res = int(p.pop("resolution", 513))
    smooth = int(p.pop("smooth", 2))
    if profile not in ("step", "sine", "cosine"):
        raise ValueError(f"profile must be 'step', 'sine' or 'cosine', got {profile!r}")
    scale = min(1.0, (res - 1) / max(max(rows, cols) - 1, 1))
    fr = max(2, int(round((rows - 1) * scale)) + 1) if rows > 1 else 1
    fc = max(2, int(round((cols - 1) * scale)) + 1) if cols > 1 else 1
    # Unit-square coordinates of the working grid (largest side spans [0, 1]).
    span = max(fr, fc) - 1 or 1
    y = (np.arange(fr, dtype=np.float32) / span)[:, None]
    x = (np.arange(fc, dtype=np.float32) / span)[None, :]
    Hf = np.zeros((fr, fc), np.float32)
    theta = rng.random(faults) * 2.0 * np.pi
    px = rng.random(faults) * (fc - 1) / span
    py = rng.random(faults) * (fr - 1) / span
    nx, ny = np.cos(theta).astype(np.float32), np.sin(theta).astype(np.float32)
    c = -(nx * px + ny * py).astype(np.float32)
    alpha = np.arange(faults) / max(faults - 1, 1)
    disp = (d0 + alpha * (d1 - d0)).astype(np.float32)  # Eq A-3
    for k in range(faults):  # one vectorised pass over the grid per fault
        dist = ny[k] * y + nx[k] * x + c[k]  # signed distance to the fault line
        if profile == "step":
            Hf += np.where(dist > 0, disp[k], -disp[k])
        else:
            u = np.clip(dist / np.float32(width), -1.0, 1.0) * np.float32(np.pi / 2)
            shape = np.sin(u) if profile == "sine" else np.cos(u)
            Hf += disp[k] * shape
    for _ in range(smooth):  # FIR low-pass (erosion) filter, separable [1, 2, 1] / 4
        for ax in (0, 1):
            if Hf.shape[ax] < 3:
                continue
            P = np.pad(Hf, [(1, 1) if a == ax else (0, 0) for a in range(2)], mode="edge")
            lo = P[:-2] if ax == 0 else P[:, :-2]
            hi = P[2:] if ax == 0 else P[:, 2:]
            Hf = 0.5 * Hf + 0.25 * (lo + hi)
    if (fr, fc) == (rows, cols):
        return Hf
    # Cubic upsampling with a replicated one-node margin.
    L = np.pad(Hf, 1, mode="edge")
    L = np.pad(L, ((0, 2), (0, 2)), mode="edge")
    py_ = np.arange(rows) * ((fr - 1) / max(rows - 1, 1)) if fr > 1 else np.zeros(rows)
    px_ = np.arange(cols) * ((fc - 1) / max(cols - 1, 1)) if fc > 1 else np.zeros(cols)
    return _interp_axis(_interp_axis(L, px_, axis=1), py_, axis=0)


_GENERATORS = {
    "fbm": _fbm,
    "ridged": _ridged,
    "diamond-square": _diamond_square,
    "fault": _fault,
}


def generate(
    kind: str, size: int | tuple[int, int], seed: int = 0, **params: Any
) -> np.ndarray:
    """Generate a synthetic DEM.

    Parameters
    ----------
    kind : ``"fbm"``, ``"ridged"``, ``"diamond-square"`` or ``"fault"``.
    size : side of a square grid, or ``(rows, cols)``.
    seed : seed of the ``numpy.random.Generator``; equal seeds give equal DEMs.
    **params : per-kind parameters (see the module docstring) plus ``relief``
        (metres between lowest and highest sample, default 2000.0) and ``base``
        (lowest height, default 0.0).

    Returns
    -------
    numpy.ndarray
        float32 heights in metres, shape ``(rows, cols)``, in ``base + [0, relief]``.

    Examples
    --------
    >>> h = generate("fbm", (65, 129), seed=1, relief=1500.0)
    >>> h.shape, h.dtype, float(h.min()), round(float(h.max()))
    ((65, 129), dtype('float32'), 0.0, 1500)
    >>> bool((generate("ridged", 33, seed=3) == generate("ridged", 33, seed=3)).all())
    True
    """
    if kind not in _GENERATORS:
        raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
    rows, cols = _shape(size)
    p = dict(params)
    relief = float(p.pop("relief", 2000.0))
    base = float(p.pop("base", 0.0))
    rng = np.random.default_rng(seed)
    h = _GENERATORS[kind](rows, cols, rng, p)
    if p:
        raise TypeError(f"unknown parameter(s) for {kind!r}: {', '.join(sorted(p))}")
    h = np.asarray(h, dtype=np.float32)
    lo, hi = float(h.min()), float(h.max())
    h -= np.float32(lo)
    if hi > lo:
        h *= np.float32(relief / (hi - lo))
        np.clip(h, 0.0, relief, out=h)  # float32 rounding may overshoot by an ulp
    if base:
        h += np.float32(base)
    return h


def write_geotiff(
    path: str | Path,
    heights: np.ndarray,
    crs: str = "EPSG:32633",
    origin: tuple[float, float] = (500000.0, 5000000.0),
    spacing: float | tuple[float, float] = 10.0,
    nodata: float | None = None,
) -> Path:
    """Write heights as a north-up, tiled, deflate-compressed float32 GeoTIFF.

    Parameters
    ----------
    path : destination file.
    heights : (rows, cols) heights; row 0 is the northern edge.
    crs : any CRS rasterio understands (default UTM 33N).
    origin : (x, y) of the top-left corner of the top-left pixel.
    spacing : pixel size, or ``(dx, dy)`` (both positive; y decreases southwards).
    nodata : value to record as nodata (NaN is allowed), or None.

    Returns
    -------
    pathlib.Path
        The written file.

    Examples
    --------
    >>> import tempfile, os, rasterio
    >>> d = tempfile.mkdtemp()
    >>> p = write_geotiff(os.path.join(d, "dem.tif"), generate("fbm", 17, seed=0))
    >>> with rasterio.open(p) as src:
    ...     print(src.shape, src.crs.to_epsg(), src.transform.c, src.transform.a)
    (17, 17) 32633 500000.0 10.0
    """
    import rasterio
    from affine import Affine

    path = Path(path)
    data = np.asarray(heights, dtype=np.float32)
    if data.ndim != 2:
        raise ValueError(f"heights must be 2-D, got shape {data.shape}")
    dx, dy = (spacing, spacing) if np.isscalar(spacing) else spacing
    transform = Affine(float(dx), 0.0, float(origin[0]), 0.0, -float(dy), float(origin[1]))
    profile = {
        "driver": "GTiff",
        "height": data.shape[0],
        "width": data.shape[1],
        "count": 1,
        "dtype": "float32",
        "crs": crs,
        "transform": transform,
        "tiled": True,
        "blockxsize": 256,
        "blockysize": 256,
        "compress": "deflate",
        "predictor": 3,
    }
    if nodata is not None:
        profile["nodata"] = float(nodata)
    from geoterrain.core.atomicfiles import partial_path, publish

    tmp = partial_path(path)
    tmp = tmp.with_name(tmp.name + ".tif")
    try:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(data, 1)
        publish(tmp, path, overwrite=True)  # replaces a regular file only (core/paths.py)
    finally:
        tmp.unlink(missing_ok=True)
    return path
