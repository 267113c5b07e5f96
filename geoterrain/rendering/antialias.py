"""Anti-aliasing of a rendered picture on the CPU: FXAA as a compiled post-pass.

A software OpenGL renderer (Mesa's llvmpipe, what offscreen VTK uses on a machine
without a GPU) tests depth and writes colour for every sample of a multisampled frame
(its compiled fragment code loops over the samples): 4× MSAA made a 1280×720 terrain
frame 2–4× slower to draw (12 → 51 ms at 18 k triangles, 22 → 70 ms at 42 k).
VTK's own FXAA pass costs as much there. This is Lottes's FXAA 3.11 "quality" filter
(NVIDIA, 2011) run on the read-back picture: find luma edges, estimate each edge
pixel's coverage from the length of the edge span it lies on and the sub-pixel luma
difference, and blend it with its neighbour across the edge. It runs in a few
milliseconds on the whole picture. Against a 16×-supersampled render of the same mesh
and texture it scores like 4× MSAA (docs/lab/rendering-frame.md).

Examples
--------
>>> import numpy as np
>>> img = np.zeros((8, 8, 3), np.uint8)
>>> img[np.arange(8)[:, None] > np.arange(8) // 3] = 255  # a jagged edge
>>> out = fxaa(img)
>>> out.shape, out.dtype.name
((8, 8, 3), 'uint8')
>>> bool(((out > 0) & (out < 255)).any())  # edge pixels now blend the two sides
True
>>> bool((out[0] == img[0]).all() and (out[:, 0] == img[:, 0]).all())  # border as drawn
True
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from geoterrain.core.threads import parallel_kernel

EDGE_THRESHOLD = 1.0 / 8.0  # a pixel is on an edge when its local luma range exceeds
EDGE_THRESHOLD_MIN = 1.0 / 16.0  # this share of its brightest neighbour, and this
SUBPIX = 0.75  # how much sub-pixel aliasing is removed (FXAA 3.11's default)
DEPTH_EPS = 1e-6  # depth-buffer steps below this are noise (24-bit depth: 6e-8 a step)
JUMP = 4.0  # a depth jump: one step to a neighbour > JUMP × the opposite step
_STEPS = (1.0, 1.5, 2.0, 2.0, 2.0, 2.0, 4.0, 8.0)  # the edge search (FXAA_QUALITY preset 12)


@njit(cache=True, nogil=True, inline="always")
def _luma(lu, y, x, H, W):
    """Luma of pixel (y, x), clamped to the picture."""
    return lu[min(max(y, 0), H - 1), min(max(x, 0), W - 1)]


@parallel_kernel(cache=True, nogil=True)
def _lumas(img, lu):  # pragma: no cover - compiled
    """Rec. 601 luma in [0, 1] of every pixel."""
    for y in prange(img.shape[0]):
        for x in range(img.shape[1]):
            lu[y, x] = (np.float32(0.299) * img[y, x, 0] + np.float32(0.587) * img[y, x, 1]
                        + np.float32(0.114) * img[y, x, 2]) * np.float32(1.0 / 255.0)


@njit(cache=True, nogil=True, inline="always")
def _bilinear(lu, fy, fx, H, W):
    """Luma at fractional pixel (fy, fx) (pixel centres at integers)."""
    y0, x0 = int(np.floor(fy)), int(np.floor(fx))
    ty, tx = fy - y0, fx - x0
    a = _luma(lu, y0, x0, H, W) * (1 - tx) + _luma(lu, y0, x0 + 1, H, W) * tx
    b = _luma(lu, y0 + 1, x0, H, W) * (1 - tx) + _luma(lu, y0 + 1, x0 + 1, H, W) * tx
    return a * (1 - ty) + b * ty


@parallel_kernel(cache=True, nogil=True)
def _fxaa(img, lu, z, steps, edge_t, edge_min, subpix, out):  # pragma: no cover - compiled
    H = img.shape[0]
    for y in prange(1, H - 1):  # a prange index may be unsigned: y − 1 would be a float
        _row(img, lu, z, steps, edge_t, edge_min, subpix, out, np.int64(y))


@njit(cache=True, nogil=True, inline="always")
def _geometric(z, y, x):
    """Whether pixel (y, x) lies on a geometric edge: the background on one side, or the
    depth jumping to another surface along a row or column: its step to one neighbour
    more than ``JUMP`` times its step to the opposite one. (The depth buffer is affine in
    screen space on a plane, so the two steps are equal inside a triangle and change by
    a little at a crease between two.)"""
    zc = z[y, x]
    zn, zs, zw, ze = z[y - 1, x], z[y + 1, x], z[y, x - 1], z[y, x + 1]
    far = zc >= 1.0
    if far != (zn >= 1.0) or far != (zs >= 1.0) or far != (zw >= 1.0) or far != (ze >= 1.0):
        return True
    if far:
        return False
    a, b = abs(zn - zc), abs(zs - zc)
    if max(a, b) > JUMP * min(a, b) + DEPTH_EPS:
        return True
    a, b = abs(zw - zc), abs(ze - zc)
    return max(a, b) > JUMP * min(a, b) + DEPTH_EPS


@njit(cache=True, nogil=True)
def _row(img, lu, z, steps, edge_t, edge_min, subpix, out, y):  # pragma: no cover - compiled
    H, W = img.shape[0], img.shape[1]
    gate = z.shape[0] == H
    for x in range(1, W - 1):
        if gate and not _geometric(z, y, x):
            continue  # texture detail: left as drawn (MSAA leaves it too)
        m = _luma(lu, y, x, H, W)
        n, s = _luma(lu, y - 1, x, H, W), _luma(lu, y + 1, x, H, W)
        w, e = _luma(lu, y, x - 1, H, W), _luma(lu, y, x + 1, H, W)
        hi = max(m, n, s, w, e)
        rng = hi - min(m, n, s, w, e)
        if rng < max(edge_min, hi * edge_t):
            continue  # not on an edge: the pixel as drawn
        nw, ne = _luma(lu, y - 1, x - 1, H, W), _luma(lu, y - 1, x + 1, H, W)
        sw, se = _luma(lu, y + 1, x - 1, H, W), _luma(lu, y + 1, x + 1, H, W)
        # is the edge horizontal (luma changes along y) or vertical?
        horz = (abs(nw - 2 * w + sw) + 2 * abs(n - 2 * m + s) + abs(ne - 2 * e + se))
        vert = (abs(nw - 2 * n + ne) + 2 * abs(w - 2 * m + e) + abs(sw - 2 * s + se))
        horz_span = horz >= vert
        # sub-pixel aliasing: how far the centre stands out of its 3×3 average
        avg = (2 * (n + s + w + e) + nw + ne + sw + se) / 12.0
        sa = min(1.0, abs(avg - m) / rng)
        sb = (-2.0 * sa + 3.0) * sa * sa
        sub = sb * sb * subpix
        if horz_span:
            p1, p2 = n, s  # the neighbours across the edge
        else:
            p1, p2 = w, e
        g1, g2 = p1 - m, p2 - m
        pair1 = abs(g1) >= abs(g2)
        grad = max(abs(g1), abs(g2))
        sign = -1.0 if pair1 else 1.0  # towards the steeper neighbour
        local = 0.5 * (m + (p1 if pair1 else p2))
        # walk along the edge, half a pixel towards that neighbour, both ways
        by, bx = float(y), float(x)
        if horz_span:
            by += 0.5 * sign
        else:
            bx += 0.5 * sign
        dy, dx = (0.0, 1.0) if horz_span else (1.0, 0.0)
        ny, nx, py, px = by, bx, by, bx
        end_n = end_p = 0.0
        done_n = done_p = False
        thr = grad / 4.0
        for k in range(len(steps)):
            st = steps[k]
            if not done_n:
                ny, nx = ny - dy * st, nx - dx * st
                end_n = _bilinear(lu, ny, nx, H, W) - local
                done_n = abs(end_n) >= thr
            if not done_p:
                py, px = py + dy * st, px + dx * st
                end_p = _bilinear(lu, py, px, H, W) - local
                done_p = abs(end_p) >= thr
            if done_n and done_p:
                break
        dist_n = (x - nx) if horz_span else (y - ny)
        dist_p = (px - x) if horz_span else (py - y)
        m_below = (m - local) < 0.0
        if dist_n < dist_p:
            good = (end_n < 0.0) != m_below
            d = dist_n
        else:
            good = (end_p < 0.0) != m_below
            d = dist_p
        off = 0.5 - d / (dist_n + dist_p) if good else 0.0
        f = max(off, sub)
        # blend with the neighbour across the edge by the covered share f
        qy, qx = (y + int(sign), x) if horz_span else (y, x + int(sign))
        qy, qx = min(max(qy, 0), H - 1), min(max(qx, 0), W - 1)
        for c in range(3):
            v = (1.0 - f) * img[y, x, c] + f * img[qy, qx, c]
            out[y, x, c] = np.uint8(min(255.0, v + 0.5))


def fxaa(img: np.ndarray, depth: np.ndarray | None = None, subpix: float = SUBPIX
         ) -> np.ndarray:
    """The picture ``img`` (H, W, 3) uint8, anti-aliased by FXAA 3.11 (see the module).

    ``subpix`` (0–1) sets how much sub-pixel aliasing is smoothed; 0 only blends along
    edge spans.
    """
    img = np.ascontiguousarray(img[..., :3], np.uint8)
    if img.ndim != 3:
        raise ValueError(f"fxaa takes an (H, W, 3) picture, got shape {img.shape}")
    if depth is not None and np.shape(depth) != img.shape[:2]:
        raise ValueError(f"the depth buffer {np.shape(depth)} is not the picture's "
                         f"{img.shape[:2]}")
    out = img.copy()
    z = np.zeros((0, 0), np.float32) if depth is None else np.ascontiguousarray(depth,
                                                                                np.float32)
    lu = np.empty(img.shape[:2], np.float32)
    _lumas(img, lu)
    _fxaa(img, lu, z, np.array(_STEPS), EDGE_THRESHOLD,
          EDGE_THRESHOLD_MIN, float(subpix), out)
    return out


#: the pictures' anti-aliasing modes (:func:`geoterrain.rendering.scene.render`'s
#: ``anti_aliasing``): ``auto`` (the default: ``edges`` for a frame whose silhouettes are
#: sparse, else ``msaa``), ``msaa`` (the renderer's multisampling), ``edges`` (the mesh's
#: silhouette edges blended by their coverage, :mod:`geoterrain.rendering.edgeaa`),
#: ``fxaa`` (:func:`fxaa` on each read-back picture) and ``none``
ANTI_ALIASING = ("auto", "msaa", "edges", "fxaa", "none")


def depth_buffer(plotter) -> np.ndarray:
    """The plotter's last rendered depth buffer (H, W) float32, row 0 at the top
    (1 = background): the gate :func:`fxaa` takes."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkFloatArray

    w, h = plotter.render_window.GetSize()
    arr = vtkFloatArray()
    plotter.render_window.GetZbufferData(0, 0, w - 1, h - 1, arr)
    return vtk_to_numpy(arr).reshape(h, w)[::-1]
