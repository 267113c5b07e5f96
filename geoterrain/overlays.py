"""Overlays drawn over a rendered picture: title, colour bar, scale bar, north arrow.

Examples
--------
>>> import numpy as np
>>> from geoterrain.cameras import default_view
>>> img = compose(np.zeros((240, 320, 3), np.uint8), default_view(t, (320, 240)), t)
>>> img.shape, img.dtype.name
((240, 320, 3), 'uint8')
"""

from __future__ import annotations

import math

import numpy as np

from geoterrain.cameras import project
from geoterrain.textures import elevation_range
from geoterrain.view import View


def _nice(x: float) -> float:
    e = 10 ** math.floor(math.log10(x))
    for m in (5, 2, 1):
        if m * e <= x:
            return m * e
    return e


def _fmt_len(m: float) -> str:
    return f"{m / 1000:g} km" if m >= 1000 else f"{m:g} m"


def compose(img: np.ndarray, view: View, terrain, *, shading: str = "normals",
            cmap: str = "gist_earth", title: str | None = None, colorbar: bool = True,
            scale_bar: bool = True, north_arrow: bool = True) -> np.ndarray:
    """Draw the title, colour bar, scale bar and north arrow over a rendered image.

    Examples
    --------
    >>> out = compose(img, view, t, title="Fuji")  # doctest: +SKIP
    """
    if not (title or (colorbar and shading != "plain") or scale_bar or north_arrow):
        return img
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    H, W = img.shape[:2]
    dpi = 100.0
    fig = Figure(figsize=(W / dpi, H / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(img, interpolation="nearest")
    ax.set_xlim(-0.5, W - 0.5)
    ax.set_ylim(H - 0.5, -0.5)
    ax.axis("off")
    fs = max(7.0, min(W, H) / 55)
    box = dict(boxstyle="round,pad=0.3", fc="white", ec="0.6", alpha=0.8)
    if title:
        ax.text(W / 2, 0.03 * H, title, ha="center", va="top", fontsize=1.4 * fs,
                weight="bold", bbox=box)
    if colorbar and shading != "plain":
        z0, z1 = elevation_range(terrain)
        cax = fig.add_axes((0.93, 0.2, 0.018, 0.6))
        norm = matplotlib.colors.Normalize(z0, z1)
        cb = fig.colorbar(matplotlib.cm.ScalarMappable(norm, matplotlib.colormaps[cmap]),
                          cax=cax)
        cb.set_label("elevation (m)", fontsize=fs)
        cb.ax.tick_params(labelsize=0.85 * fs)
        cb.ax.yaxis.set_ticks_position("left")
        cb.ax.yaxis.set_label_position("left")
    target = np.asarray(view.look_at, np.float64)
    r, _, f = view.basis()
    if scale_bar:
        # a horizontal segment through the target, across the view: metres per pixel there
        rh = np.array([r[0], r[1], 0.0])
        if np.linalg.norm(rh) > 1e-9:
            rh /= np.linalg.norm(rh)
            dist = float(np.linalg.norm(target - view.eye))
            m_per_px = max(dist / view.lam, 1e-12)
            length = _nice(0.2 * W * m_per_px)
            (a, b), _ = project(view, np.stack([target, target + length * rh]))
            px = float(np.linalg.norm(b - a))
            if np.isfinite(px) and 4 < px < W:
                x0, y0 = 0.04 * W, 0.93 * H
                ax.add_patch(matplotlib.patches.FancyBboxPatch(
                    (x0 - 8, y0 - 2.6 * fs), px + 16, 3.4 * fs,
                    boxstyle="round,pad=2", fc="white", ec="0.6", alpha=0.8))
                ax.plot([x0, x0 + px], [y0, y0], color="black", lw=3, solid_capstyle="butt")
                ax.plot([x0, x0], [y0 - 5, y0 + 5], color="black", lw=1.5)
                ax.plot([x0 + px, x0 + px], [y0 - 5, y0 + 5], color="black", lw=1.5)
                ax.text(x0 + px / 2, y0 - 6, f"{_fmt_len(length)} at view centre",
                        ha="center", va="bottom", fontsize=0.85 * fs)
    if north_arrow:
        (a, b), z = project(view, np.stack([target, target + np.array([0, 1.0, 0]) *
                                            max(1e-3, 0.05 * np.linalg.norm(target - view.eye))]))
        d = b - a
        if np.all(z > 0) and np.linalg.norm(d) > 1e-6:
            d = d / np.linalg.norm(d)
            c = np.array([0.07 * W, 0.1 * H + 2 * fs])
            L = 2.6 * fs
            ax.add_patch(matplotlib.patches.Circle(c, 1.6 * L, fc="white", ec="0.6", alpha=0.8))
            ax.annotate("", xy=c + L * d, xytext=c - L * d,
                        arrowprops=dict(arrowstyle="-|>", lw=2, color="black",
                                        mutation_scale=2 * fs))
            ax.text(*(c + 1.35 * L * d), "N", ha="center", va="center", fontsize=fs,
                    weight="bold")
    fig.canvas.draw()
    out = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    return out
