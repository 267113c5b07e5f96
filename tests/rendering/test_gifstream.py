"""Animated GIFs are written frame by frame (memory flat in the number of frames)."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from geoterrain.rendering.gifstream import GifStream

pytestmark = pytest.mark.fast  # the whole file is in the fast tier


def _frames(n, h=96, w=128):
    rng = np.random.default_rng(7)
    pal = rng.integers(0, 256, (200, 3), dtype=np.uint8)  # ≤ 256 colours: exact round trip
    return [pal[rng.integers(0, 200, (h, w))] for _ in range(n)]


def test_frames_round_trip_and_reach_the_file_as_they_come(tmp_path):
    p = tmp_path / "a.gif"
    frames = _frames(6)
    sizes = []
    with GifStream(p, fps=4) as g:
        for f in frames:
            g.append(f)
            sizes.append(p.stat().st_size)
    # the file grows with every frame: nothing is held back until close
    assert all(b - a > 0.5 * 96 * 128 for a, b in zip(sizes, sizes[1:], strict=False))
    back = iio.imread(p, index=None)
    assert back.shape == (6, 96, 128, 3)
    assert all(np.array_equal(a, b) for a, b in zip(back, frames, strict=True))
    meta = iio.immeta(p)
    assert meta["duration"] == 250 and meta["loop"] == 0


def test_a_frame_of_another_size_is_refused(tmp_path):
    with GifStream(tmp_path / "a.gif", fps=10) as g:
        g.append(_frames(1)[0])
        with pytest.raises(ValueError, match="the first was 128×96"):
            g.append(_frames(1, 10, 10)[0])
