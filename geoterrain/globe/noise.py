"""Seed 001's procedural planet: 12 octaves of 3-D gradient noise in float64 (§2.11, L481).

Four low-frequency octaves make the continents and ocean basins; they **modulate** the
eight high-frequency ones (mountains where the land is high, smooth sea floors), as the
seed describes in words: h = low(x) + M(low(x))·high(x), with x the unit direction
scaled by each octave's frequency, so the noise is seamless over the sphere (no poles,
no seams). Everything is float64, as the seed insists (a float32 direction at R = 6 371 km
moves the noise by half a metre).

The seed gives no lacunarity, gain or amplitude. Ours, and why:

- **low**: base frequency 1.1 (a noise cell ≈ 5 800 km: continents), lacunarity 2.07,
  gain 0.5, 2 900 m. Lacunarity not exactly 2 so that the octaves' integer lattices never
  line up (an exact 2 stacks every octave's grid-aligned artefacts on the same lines).
- **high**: base frequency 40 (≈ 160 km: mountain ranges), lacunarity 2.9, gain 0.42,
  2 400 m, eight octaves down to ≈ 95 m. Gain = lacunarity^(−H) with H ≈ 0.8, the Hurst
  exponent measured on real relief (0.7–0.9); lacunarity 2.9 spreads eight octaves from
  ranges to hillslopes without gaps in the spectrum. (The seed's "sub-metre detail" with
  eight octaves would need a lacunarity near 6, whose gaps show as stripes of one size.)
- **modulation**: M rises from 0.12 on the sea floor to 1 between low = −300 m and
  +1 500 m (a smoothstep).

:func:`error_bound` bounds how far any flat triangle through the surface is from it, from
the noise's measured constants (:data:`NOISE`), so the LOD never needs the finer samples.

Examples
--------
>>> p = Planet()
>>> d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
>>> h = p.heights(d)
>>> h.shape, bool(np.all(np.abs(h) < p.max_abs()))
((2,), True)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["Planet", "NoiseConstants", "NOISE", "error_bound", "height_range_bound"]


class NoiseConstants(NamedTuple):
    """Bounds of the gradient noise n and its derivatives (per unit of its input): |n| ≤
    ``value``, |∇n| ≤ ``slope``, |uᵀ∇²n u| ≤ ``curvature`` for unit u. Measured by
    :func:`measure_constants` (dense samples of many lattice cells, central differences)
    and rounded up by ≥ 10 %."""

    value: float
    slope: float
    curvature: float


NOISE = NoiseConstants(value=1.0, slope=3.2, curvature=15.0)


class Octaves(NamedTuple):
    """The compiled kernel's octave table: per octave its frequency, amplitude and input
    offset (``table`` (12, 5)), how many are low (``n_low``) and the modulation's
    ``lo``, ``hi`` (metres of low) and floor ``m0``; ``perm`` the permutation (512)."""

    table: np.ndarray
    n_low: int
    lo: float
    hi: float
    m0: float
    perm: np.ndarray


@njit(cache=True, inline="always")
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(cache=True, inline="always")
def _grad(h, x, y, z):
    h &= 15
    u = x if h < 8 else y
    v = y if h < 4 else (x if (h == 12 or h == 14) else z)
    return (u if (h & 1) == 0 else -u) + (v if (h & 2) == 0 else -v)


@njit(cache=True)
def noise3(x, y, z, p):
    """Perlin's improved gradient noise at (x, y, z), float64 (permutation ``p`` of 512)."""
    fx, fy, fz = np.floor(x), np.floor(y), np.floor(z)
    X, Y, Z = int(fx) & 255, int(fy) & 255, int(fz) & 255
    x -= fx
    y -= fy
    z -= fz
    u, v, w = _fade(x), _fade(y), _fade(z)
    A = p[X] + Y
    AA = p[A] + Z
    AB = p[A + 1] + Z
    B = p[X + 1] + Y
    BA = p[B] + Z
    BB = p[B + 1] + Z
    x1, y1, z1 = x - 1.0, y - 1.0, z - 1.0
    l1 = _grad(p[AA], x, y, z) + u * (_grad(p[BA], x1, y, z) - _grad(p[AA], x, y, z))
    l2 = _grad(p[AB], x, y1, z) + u * (_grad(p[BB], x1, y1, z) - _grad(p[AB], x, y1, z))
    l3 = _grad(p[AA + 1], x, y, z1) + u * (_grad(p[BA + 1], x1, y, z1)
                                           - _grad(p[AA + 1], x, y, z1))
    l4 = _grad(p[AB + 1], x, y1, z1) + u * (_grad(p[BB + 1], x1, y1, z1)
                                            - _grad(p[AB + 1], x, y1, z1))
    m1 = l1 + v * (l2 - l1)
    m2 = l3 + v * (l4 - l3)
    return m1 + w * (m2 - m1)


@njit(cache=True, inline="always")
def _smooth(lo, hi, t):
    s = (t - lo) / (hi - lo)
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True)
def _fbm_nb(d, oc):
    table, n_low, lo, hi, m0, perm = oc
    n = d.shape[0]
    out = np.empty(n)
    for i in range(n):
        x, y, z = d[i, 0], d[i, 1], d[i, 2]
        low = 0.0
        for k in range(n_low):
            f = table[k, 0]
            low += table[k, 1] * noise3(x * f + table[k, 2], y * f + table[k, 3],
                                        z * f + table[k, 4], perm)
        high = 0.0
        for k in range(n_low, table.shape[0]):
            f = table[k, 0]
            high += table[k, 1] * noise3(x * f + table[k, 2], y * f + table[k, 3],
                                         z * f + table[k, 4], perm)
        out[i] = low + (m0 + (1.0 - m0) * _smooth(lo, hi, low)) * high
    return out


@dataclass(frozen=True)
class Planet:
    """The 12-octave procedural planet (heights in metres over unit directions).

    The defaults are the module docstring's; ``seed`` picks the noise's permutation.
    """

    seed: int = 1
    low: tuple[float, float, float, float, int] = (1.1, 2.07, 0.5, 2900.0, 4)
    high: tuple[float, float, float, float, int] = (40.0, 2.9, 0.42, 2400.0, 8)
    modulation: tuple[float, float, float] = (-300.0, 1500.0, 0.12)
    _oct: list = field(default_factory=list, compare=False, repr=False)

    def octaves(self) -> Octaves:
        """The kernel's octave table (made once)."""
        if not self._oct:
            rng = np.random.RandomState(self.seed)
            perm = rng.permutation(256).astype(np.int64)
            rows = []
            for f0, lac, gain, amp, count in (self.low, self.high):
                for k in range(count):
                    rows.append((f0 * lac ** k, amp * gain ** k, *rng.uniform(0, 256, 3)))
            lo, hi, m0 = self.modulation
            self._oct.append(Octaves(np.array(rows), int(self.low[4]), float(lo), float(hi),
                                     float(m0), np.concatenate([perm, perm])))
        return self._oct[0]

    def heights(self, d: np.ndarray) -> np.ndarray:
        """Heights (metres, float64) at unit directions ``d`` (..., 3)."""
        d = np.asarray(d, np.float64)
        shape = d.shape[:-1]
        d = np.ascontiguousarray(d.reshape(-1, 3))
        return _fbm_nb(d, self.octaves()).reshape(shape)

    def max_abs(self) -> float:
        """A bound on |h| (metres)."""
        t = self.octaves().table
        return float(np.abs(t[:, 1]).sum() * NOISE.value)


def _terms(planet: Planet, R: float):
    """Per octave (frequency per metre along the surface, amplitude·|n|max, its first and
    second derivative bounds along a great circle of radius R)."""
    oc = planet.octaves()
    F = oc.table[:, 0] / R
    A = oc.table[:, 1] * NOISE.value
    d1 = oc.table[:, 1] * NOISE.slope * F
    # d²/ds² n(f·x(s)) = f²x'ᵀHx' + f∇n·x'', |x'| = 1/R, |x''| = 1/R²
    d2 = oc.table[:, 1] * (NOISE.curvature * F * F + NOISE.slope * F / R)
    return oc, A, d1, d2


def error_bound(planet: Planet | None, circumradius: float, curvature_radius: float,
                scale: float = 1.0) -> float:
    """A bound on the radial distance between the surface (ellipsoid + scale·h) and any
    flat triangle through three of its points whose circumradius (or half its longest
    edge, if obtuse) is at most ``circumradius`` metres.

    Linear interpolation on a triangle is off by at most ½·max|f''|·Σβᵢ|xᵢ − x|² and
    Σβᵢ|xᵢ − x|² ≤ Rc² (Taylor at x; the sum is concave, largest at the circumcentre), so:
    the planet's own curvature gives Rc²/(2ρ) (ρ: its least radius of curvature); each
    octave gives min(½·|f''|max·Rc², twice its amplitude); the modulation's product rule
    adds the cross terms, each capped likewise. ``planet=None``: the bare ellipsoid.

    Examples
    --------
    >>> e1 = error_bound(Planet(), 1000.0, 6.3e6); e2 = error_bound(Planet(), 500.0, 6.3e6)
    >>> 0 < e2 < e1
    True
    """
    rc2 = circumradius * circumradius
    err = rc2 / (2.0 * curvature_radius)
    if planet is None:
        return err
    oc, A, d1, d2 = _terms(planet, curvature_radius)
    nl = oc.n_low
    A, d1, d2 = A * scale, d1 * scale, d2 * scale
    low = np.minimum(0.5 * d2[:nl] * rc2, 2 * A[:nl]).sum()
    w = (oc.hi - oc.lo) / scale
    dM, d2M = 1.5 * (1 - oc.m0) / w, 6.0 * (1 - oc.m0) / (w * w)
    L1, L2 = d1[:nl].sum(), d2[:nl].sum()
    # (M·H)'' = M·H'' + 2M'·low'·H' + (M''·low'² + M'·low'')·H, per high octave
    hi = 0.5 * rc2 * (d2[nl:] + 2 * dM * L1 * d1[nl:] + (d2M * L1 * L1 + dM * L2) * A[nl:])
    high = np.minimum(hi, 3 * A[nl:]).sum()
    return float(err + low + high)


def height_range_bound(planet: Planet | None, width: float, scale: float = 1.0) -> float:
    """A bound on how much the heights vary over a patch ``width`` metres across.

    Examples
    --------
    >>> height_range_bound(Planet(), 10.0) < height_range_bound(Planet(), 1e5)
    True
    """
    if planet is None:
        return 0.0
    oc, A, d1, _ = _terms(planet, 6.3e6)
    A, d1 = A * scale, d1 * scale
    nl = oc.n_low
    # |M·H| varies by at most |ΔH| + |ΔM|·|H|; ΔM from the low octaves' change
    w = (oc.hi - oc.lo) / scale
    dlow = np.minimum(d1[:nl] * width, 2 * A[:nl]).sum()
    dM = min(1.5 * (1 - oc.m0) / w * dlow, 1 - oc.m0)
    dhigh = np.minimum(d1[nl:] * width, 2 * A[nl:]).sum()
    return float(dlow + dhigh + dM * A[nl:].sum())


def measure_constants(cells: int = 6, per_cell: int = 40, seed: int = 3) -> NoiseConstants:
    """Measure |n|, |∇n| and the largest directional second derivative of :func:`noise3`
    on ``cells``³ lattice cells (``per_cell`` samples a side each, central differences,
    several random rotations of the sampling grid). :data:`NOISE` rounds these up.

    Examples
    --------
    >>> c = measure_constants(1, 12)
    >>> c.value <= NOISE.value and c.slope <= NOISE.slope and c.curvature <= NOISE.curvature
    True
    """
    perm = np.random.RandomState(seed).permutation(256).astype(np.int64)
    perm = np.concatenate([perm, perm])
    return NoiseConstants(*_measure_nb(cells, per_cell, perm))


@njit(cache=True)
def _measure_nb(cells, per_cell, p):
    h = 1e-3
    vmax = gmax = cmax = 0.0
    n = cells * per_cell
    dirs = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.577350269, 0.577350269,
                     0.577350269], [0.707106781, 0.707106781, 0], [0.707106781, 0,
                     0.707106781], [0, 0.707106781, 0.707106781], [0.707106781, -0.707106781,
                     0], [0.577350269, -0.577350269, 0.577350269]])
    for a in range(n):
        for b in range(n):
            for c in range(n):
                x = (a + 0.37) / per_cell
                y = (b + 0.61) / per_cell
                z = (c + 0.13) / per_cell
                v = noise3(x, y, z, p)
                vmax = max(vmax, abs(v))
                gx = (noise3(x + h, y, z, p) - noise3(x - h, y, z, p)) / (2 * h)
                gy = (noise3(x, y + h, z, p) - noise3(x, y - h, z, p)) / (2 * h)
                gz = (noise3(x, y, z + h, p) - noise3(x, y, z - h, p)) / (2 * h)
                gmax = max(gmax, np.sqrt(gx * gx + gy * gy + gz * gz))
                for k in range(dirs.shape[0]):
                    ux, uy, uz = dirs[k, 0] * h, dirs[k, 1] * h, dirs[k, 2] * h
                    c2 = (noise3(x + ux, y + uy, z + uz, p) - 2 * v
                          + noise3(x - ux, y - uy, z - uz, p)) / (h * h)
                    cmax = max(cmax, abs(c2))
    return vmax, gmax, cmax
