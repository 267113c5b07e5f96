"""FXAA on the CPU (geoterrain.rendering.antialias): what it changes, and that it approaches
coverage.

The reference for a jagged edge is the exact pixel coverage of a half-plane, from a
64× supersampled rasterisation in numpy (independent of the filter).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.rendering.antialias import fxaa

pytestmark = pytest.mark.fast  # the whole file is in the fast tier

LIGHT, DARK = np.array([220, 230, 240]), np.array([70, 110, 60])


def _half_plane(h: int, w: int, slope: float, icpt: float, ss: int) -> np.ndarray:
    """Share of each pixel under the line y = slope·x + icpt (ss² samples a pixel)."""
    o = (np.arange(ss) + 0.5) / ss
    ys = (np.arange(h)[:, None] + o[None, :]).ravel()
    xs = (np.arange(w)[:, None] + o[None, :]).ravel()
    below = ys[:, None] > slope * xs[None, :] + icpt  # (h·ss, w·ss)
    return below.reshape(h, ss, w, ss).mean((1, 3))


def _picture(cover: np.ndarray) -> np.ndarray:
    return (cover[..., None] * DARK + (1 - cover[..., None]) * LIGHT + 0.5).astype(np.uint8)


def _psnr(a, b) -> float:
    return float(10 * np.log10(255 ** 2 / np.mean((a.astype(float) - b.astype(float)) ** 2)))


@settings(max_examples=25, deadline=None)
@given(st.floats(0.02, 0.45), st.floats(-3.0, 3.0), st.booleans())
def test_a_jagged_edge_moves_towards_its_coverage(slope, shift, steep):
    """A one-sample-per-pixel half-plane (terrain against the sky) gains ≥ 3 dB towards
    its exact coverage, with or without the depth gate; a near-vertical edge too."""
    h, w = 48, 64
    hard = _half_plane(h, w, slope, 20 + shift, 1)
    exact = _half_plane(h, w, slope, 20 + shift, 64)
    if steep:
        hard, exact = hard.T.copy(), exact.T.copy()
    img, ref = _picture(hard), _picture(exact)
    depth = np.where(hard > 0.5, np.float32(0.5), np.float32(1.0))  # terrain / background
    base = _psnr(img, ref)
    assert _psnr(fxaa(img), ref) > base + 3.0
    assert _psnr(fxaa(img, depth), ref) > base + 3.0


def test_texture_detail_without_a_depth_edge_is_left_as_drawn():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (40, 50, 3)).astype(np.uint8)  # busy texture, one surface
    z = np.linspace(0.2, 0.4, 50, dtype=np.float32)[None, :].repeat(40, 0)  # a plane
    np.testing.assert_array_equal(fxaa(img, z), img)
    assert not np.array_equal(fxaa(img), img)  # without the gate, luma edges are filtered


@settings(max_examples=30, deadline=None)
@given(st.integers(3, 30), st.integers(3, 30), st.integers(0, 2 ** 32 - 1))
def test_each_pixel_blends_with_a_neighbour_only(h, w, seed):
    """A filtered pixel lies between itself and one 4-neighbour; the border is kept."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, 3)).astype(np.uint8)
    out = fxaa(img).astype(int)
    i = img.astype(int)
    for (y, x) in zip(*np.nonzero((out != i).any(2)), strict=True):
        assert 0 < y < h - 1 and 0 < x < w - 1
        ok = False
        for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            q = i[y + dy, x + dx]
            lo, hi = np.minimum(i[y, x], q), np.maximum(i[y, x], q)
            ok |= bool(((out[y, x] >= lo - 1) & (out[y, x] <= hi + 1)).all())
        assert ok, (y, x)


def test_a_depth_buffer_of_another_shape_is_refused():
    import pytest

    img = np.zeros((20, 30, 3), np.uint8)
    for bad in (np.zeros((20, 1), np.float32), np.zeros((19, 30), np.float32)):
        with pytest.raises(ValueError, match="depth buffer"):
            fxaa(img, bad)
    with pytest.raises(ValueError, match="picture"):
        fxaa(np.zeros((20, 30), np.uint8))
    for h, w in ((1, 1), (2, 5), (5, 2)):  # too small to have an inside: kept as drawn
        tiny = np.random.default_rng(h * w).integers(0, 256, (h, w, 3)).astype(np.uint8)
        np.testing.assert_array_equal(fxaa(tiny), tiny)
