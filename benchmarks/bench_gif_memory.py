"""Peak memory of writing an animated GIF: imageio's writer vs geoterrain.rendering.gifstream.

Each run is a fresh process that writes ``n`` synthetic 1280×720 frames (a smooth
picture with a moving band, so each frame differs) and reports its peak resident set
(``VmHWM``, :func:`geoterrain.core.memory.peak_rss`; ``ru_maxrss`` would count the parent's
peak at exec) and wall time. A writer that streams keeps a flat peak as ``n`` grows;
one that holds the frames grows by about 1280·720·3 B = 2.8 MB per frame.

Run from the project root::

    python benchmarks/bench_gif_memory.py --frames 25 100
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_RUN = """
import json, sys, time
import numpy as np
sys.path.insert(0, {root!r})
W, H, n = 1280, 720, {n}
yy, xx = np.mgrid[0:H, 0:W]
base = np.stack([xx * 200 // W, yy * 200 // H, (xx + yy) * 100 // (W + H)], -1).astype(np.uint8)
t0 = time.perf_counter()
if {writer!r} == "imageio":
    import imageio.v2 as iio2
    w = iio2.get_writer({out!r}, mode="I", duration=100.0, loop=0)
    add, close = w.append_data, w.close
else:
    from geoterrain.rendering.gifstream import GifStream
    g = GifStream({out!r}, 10.0)
    add, close = g.append, g.close
for k in range(n):
    f = base.copy()
    f[:, (k * 16) % W:(k * 16) % W + 40] = 255
    add(f)
close()
from geoterrain.core.memory import peak_rss  # VmHWM: not the parent's peak at exec
print(json.dumps({{"wall_s": time.perf_counter() - t0,
                  "max_rss_kb": peak_rss() // 1024}}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[25, 100])
    ap.add_argument("--writers", nargs="+", default=["imageio", "gifstream"])
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        for writer in a.writers:
            for n in a.frames:
                out = Path(d) / f"{writer}_{n}.gif"
                code = _RUN.format(root=str(ROOT), n=n, writer=writer, out=str(out))
                r = json.loads(subprocess.run([sys.executable, "-c", code], check=True,
                                              capture_output=True, text=True).stdout)
                print(f"{writer:9s} {n:4d} frames  peak RSS {r['max_rss_kb'] / 1e3:7.0f} MB  "
                      f"wall {r['wall_s']:5.1f} s  file {out.stat().st_size / 1e6:5.1f} MB")
                out.unlink()


if __name__ == "__main__":
    main()
