"""Animated GIF written frame by frame: memory does not grow with the number of frames.

imageio's GIF writer (Pillow) keeps every frame until the file is closed; a long
flight at 1280×720 holds 2.8 MB per frame. :class:`GifStream` writes each frame
as it comes: Pillow quantizes it (an adaptive 256-colour palette, as Pillow's own
animated GIFs) and LZW-encodes it as a one-frame GIF; its palette becomes the
frame's local colour table and its image data is copied into the animation
(GIF89a: a NETSCAPE2.0 loop block, then per frame a graphic control extension
with the delay, an image descriptor, the local colour table and the LZW data).

Examples
--------
>>> import tempfile, os, numpy as np, imageio.v3 as iio
>>> p = os.path.join(tempfile.mkdtemp(), "a.gif")
>>> with GifStream(p, fps=10) as g:
...     for k in range(3):
...         g.append(np.full((8, 12, 3), 80 * k, np.uint8))
>>> iio.imread(p, index=None).shape
(3, 8, 12, 3)
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np


def _frame_blocks(img: np.ndarray) -> tuple[bytes, bytes, int]:
    """(colour table, LZW data with its sub-blocks and terminator, table size bits) of
    ``img`` (H, W, 3) uint8, encoded by Pillow as a one-frame GIF."""
    from PIL import Image

    im = Image.fromarray(np.ascontiguousarray(img[..., :3], np.uint8), "RGB")
    buf = io.BytesIO()
    im.convert("P", palette=Image.Palette.ADAPTIVE).save(buf, "GIF", interlace=False)
    b = buf.getvalue()
    flags = b[10]
    pos, table, bits = 13, b"", flags & 7
    if flags & 0x80:
        n = 3 << ((flags & 7) + 1)
        table, pos = b[13:13 + n], 13 + n
    while b[pos] == 0x21:  # extensions: label, then sub-blocks up to a 0
        pos += 2
        while b[pos]:
            pos += b[pos] + 1
        pos += 1
    if b[pos] != 0x2C:
        raise ValueError("unexpected GIF block from the encoder")
    desc = b[pos + 9]
    pos += 10
    if desc & 0x80:  # a local table instead of a global one
        bits = desc & 7
        n = 3 << (bits + 1)
        table, pos = b[pos:pos + n], pos + n
    start = pos
    pos += 1  # LZW minimum code size
    while b[pos]:
        pos += b[pos] + 1
    return table, b[start:pos + 1], bits


class GifStream:
    """An animated GIF at ``path``, looping forever, ``fps`` frames per second."""

    def __init__(self, path: str | Path, fps: float):
        self.fh = open(path, "wb")  # noqa: SIM115 (closed by close())
        self.delay = max(1, round(100.0 / float(fps)))  # GIF delays are in 1/100 s
        self.size: tuple[int, int] | None = None
        self.frames = 0

    def append(self, img: np.ndarray) -> None:
        """Quantize, encode and write one (H, W, 3|4) uint8 frame."""
        img = np.asarray(img)
        h, w = img.shape[:2]
        if self.size is None:
            self.size = (w, h)
            self.fh.write(b"GIF89a" + struct.pack("<HHBBB", w, h, 0, 0, 0)
                          + b"\x21\xff\x0bNETSCAPE2.0\x03\x01\x00\x00\x00")
        elif self.size != (w, h):
            raise ValueError(f"frame {self.frames} is {w}×{h}, the first was "
                             f"{self.size[0]}×{self.size[1]}")
        table, data, bits = _frame_blocks(img)
        self.fh.write(b"\x21\xf9\x04" + struct.pack("<BHBB", 1 << 2, self.delay, 0, 0)
                      + b"\x2c" + struct.pack("<HHHHB", 0, 0, w, h, 0x80 | bits)
                      + table + data)
        self.frames += 1

    def close(self) -> None:
        """Write the trailer and close the file."""
        if not self.fh.closed:
            self.fh.write(b"\x3b")
            self.fh.close()

    def __enter__(self) -> GifStream:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
