"""Geometric anti-aliasing: the drawn mesh's silhouette edges blended by their coverage.

A picture drawn without multisampling has hard steps only where the surface ends in
front of something farther: along the mesh's silhouette edges (between a face turned
towards the eye and one turned away) and its border. The texture inside is filtered
already. Persson's geometric post-process anti-aliasing (GPAA, 2011) takes those
edges from the geometry itself: each pixel an edge crosses is blended with its
neighbour across the edge, weighted by the share of the pixel on the surface's side
of the exact edge line. Persson takes that share as the pixel's extent along the
edge's minor axis at the column's centre, which is the area only where the line runs
through two opposite sides of the pixel; here it is the exact area, for each of the
(at most three) pixels the line crosses in a column, near the pixels' corners too.
Where the depth buffer shows that the surface at the pixel is not the edge's (a nearer
hill hides it), the pixel is left as drawn.

A face's side is its upward normal's (a height field's outside is up; the RTIN mesh's
winding is not consistent), and a silhouette edge is listed once per face beside it:
at an open border of the data a face turned away from the eye can be the one seen, and
the depth buffer says which.

On a software renderer (llvmpipe) the draw without MSAA costs about half the draw
with it. Against a 16× supersampled picture of the same mesh and texture, the pass
(measured with the centre's extent) is 1.4 dB closer than 4× MSAA on average where the
silhouettes are sparse (four of the six shared DEMs, 12 views: closer on 8, at most
1.9 dB further on the others), and 6–8.5 dB further where thousands of steep thin
facets put many edges in one pixel (the Terrain-RGB and Terrarium tiles), where
coverage needs samples (docs/lab/anti-aliasing.md); the exact area adds 0.03-0.15 dB
against a 4 × 4 supersampled fBm (two views).
The default anti-aliasing (``"auto"``) therefore takes this pass for a frame
whose silhouettes are sparse (:func:`sparse`) and the renderer's MSAA for the others;
``"edges"`` always takes it.

Examples
--------
>>> import numpy as np
>>> pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
>>> faces = np.array([[0, 1, 2], [1, 3, 2]])
>>> e = silhouette_edges(pts, faces, np.eye(4), (8, 8), eye=(0.5, 0.5, 10.0))
>>> len(e.a)  # the square's four border edges
4
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

# distinct silhouette edges on screen per 1 000 pixels of the picture, at most, for the
# pass to stand in for MSAA: 0.9-20.6 on srtm1_japan, srtm3, St Helens and roi (3 views
# each at 640x360) and 0.3-15.9 over the 4097² fBm flight at 1280x720, where it is as
# close to a supersampled picture as MSAA or closer; 60-87 on the Fuji and Terrarium
# tiles, where it is 6-8.5 dB further (docs/lab/anti-aliasing.md)
SPARSE_EDGES_PER_KPX = 30.0
# a mesh with more faces is drawn with MSAA under "auto" without looking for its edges
# (a full-resolution mesh): the edge lists take about 48 bytes a face (100 MB at 2 M
# faces; an rtin frame at 1280x720 has 30-150 k)
SPARSE_MAX_FACES = 2_000_000


@dataclass
class Silhouettes:
    """Screen x, y (pixels, y down) and window depth of every vertex, and the
    silhouette edges: vertices ``a``, ``b``, the third vertex ``c`` of the face on the
    visible side, and ``tol``, how far (window depth) the surface may lie from the
    edge's depth within a pixel of it."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    tol: np.ndarray
    size: tuple[int, int] = (1, 1)
    # on_screen() as the compiled pass counted it while listing the edges (-1: not known)
    n_on_screen: int = -1

    def on_screen(self) -> int:
        """How many distinct edges reach into the picture (their boxes meet it; a
        silhouette edge is listed once per face beside it)."""
        if self.n_on_screen >= 0:
            return self.n_on_screen
        W, H = self.size
        xa, xb, ya, yb = self.x[self.a], self.x[self.b], self.y[self.a], self.y[self.b]
        on = ((np.minimum(xa, xb) < W) & (np.maximum(xa, xb) > 0)
              & (np.minimum(ya, yb) < H) & (np.maximum(ya, yb) > 0))
        lo, hi = np.minimum(self.a, self.b)[on], np.maximum(self.a, self.b)[on]
        return len(np.unique(lo * (int(hi.max(initial=0)) + 1) + hi))


def sparse(edges: Silhouettes) -> bool:
    """Whether the silhouettes are sparse enough for :func:`edge_antialias` to stand in
    for MSAA: at most :data:`SPARSE_EDGES_PER_KPX` edges on screen per 1 000 pixels.

    Examples
    --------
    >>> pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> sparse(silhouette_edges(pts, np.array([[0, 1, 2], [1, 3, 2]]), np.eye(4), (64, 64),
    ...                         eye=(0.5, 0.5, 10.0)))
    True
    """
    W, H = edges.size
    return edges.on_screen() <= SPARSE_EDGES_PER_KPX * W * H / 1000.0


@njit(cache=True, nogil=True)
def _project(pts, m, W, H, x, y, z, ok):  # pragma: no cover - compiled
    for i in range(len(pts)):
        p0, p1, p2 = pts[i, 0], pts[i, 1], pts[i, 2]
        cw = m[3, 0] * p0 + m[3, 1] * p1 + m[3, 2] * p2 + m[3, 3]
        ok[i] = cw > 1e-12
        if not ok[i]:
            x[i] = y[i] = z[i] = 0.0
            continue
        x[i] = (1.0 + (m[0, 0] * p0 + m[0, 1] * p1 + m[0, 2] * p2 + m[0, 3]) / cw) * 0.5 * W
        y[i] = (1.0 - (m[1, 0] * p0 + m[1, 1] * p1 + m[1, 2] * p2 + m[1, 3]) / cw) * 0.5 * H
        z[i] = (1.0 + (m[2, 0] * p0 + m[2, 1] * p1 + m[2, 2] * p2 + m[2, 3]) / cw) * 0.5


@njit(cache=True, nogil=True)
def _silhouettes(faces, pts, eye, x, y, z, ok, n_pts, W, H):  # pragma: no cover - compiled
    F = len(faces)
    # a face is turned towards the eye when its upward normal is (a height field's
    # outside is up; the faces' winding is not relied on)
    toward = np.empty(F, np.bool_)
    for f in range(F):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ux, uy, uz = pts[b, 0] - pts[a, 0], pts[b, 1] - pts[a, 1], pts[b, 2] - pts[a, 2]
        vx, vy, vz = pts[c, 0] - pts[a, 0], pts[c, 1] - pts[a, 1], pts[c, 2] - pts[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        if nz < 0.0:
            nx, ny, nz = -nx, -ny, -nz
        d = (nx * (eye[0] - pts[a, 0]) + ny * (eye[1] - pts[a, 1])
             + nz * (eye[2] - pts[a, 2]))
        toward[f] = d > 0.0 and ok[a] and ok[b] and ok[c]
    # each undirected edge's faces: the half-edges bucketed by their smaller vertex (a
    # counting sort, in face order), so an edge's faces are found among the few
    # half-edges of its smaller vertex: the first face seen, and the last other one
    # (none: a border edge)
    start = np.zeros(n_pts + 1, np.int32)
    for f in range(F):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        start[min(a, b) + 1] += 1
        start[min(b, c) + 1] += 1
        start[min(c, a) + 1] += 1
    for v in range(n_pts):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    hi = np.empty(3 * F, np.int32)  # the other vertex (n_pts < 2^31: int32 faces)
    half = np.empty(3 * F, np.int64)  # face * 3 + edge
    for f in range(F):
        for k in range(3):
            u, v = faces[f, k], faces[f, (k + 1) % 3]
            lo = min(u, v)
            p = fill[lo]
            fill[lo] = p + 1
            hi[p] = max(u, v)
            half[p] = f * 3 + k
    # each silhouette edge once per face beside it (the face on the visible side is
    # the one the depth buffer shows there: at an open border a face turned away can
    # be the visible one), each border edge once, listed as the edge is matched (one
    # pass: an edge's listing at most both its sides, 3F in all)
    ea = np.empty(3 * F, np.int64)
    eb = np.empty(3 * F, np.int64)
    ec = np.empty(3 * F, np.int64)
    tol = np.empty(3 * F)
    n = 0
    seen = 0  # distinct edges listed whose boxes meet the picture (Silhouettes.on_screen)
    for v in range(n_pts):
        s0, s1 = start[v], start[v + 1]
        done = np.uint64(0)  # the bucket's half-edges met already (its first 64)
        for i in range(s0, s1):
            w = hi[i]
            if i - s0 < 64:
                if (done >> np.uint64(i - s0)) & np.uint64(1):
                    continue  # listed at its first half-edge
            else:
                dup = False
                for j in range(s0, i):
                    if hi[j] == w:
                        dup = True
                        break
                if dup:
                    continue
            first, second = half[i], np.int64(-1)
            for j in range(i + 1, s1):
                if hi[j] == w:
                    second = half[j]
                    if j - s0 < 64:
                        done |= np.uint64(1) << np.uint64(j - s0)
            if second != -1 and toward[first // 3] == toward[second // 3]:
                continue
            n0 = n
            for side in (first, second):
                if side == -1:
                    continue
                f, k = side // 3, side % 3
                a, b, c = faces[f, k], faces[f, (k + 1) % 3], faces[f, (k + 2) % 3]
                if not (ok[a] and ok[b] and ok[c]):
                    continue
                # the face's depth gradient across the screen: how far its depth moves
                # within a pixel and a half of the edge
                x1, y1, z1 = x[b] - x[a], y[b] - y[a], z[b] - z[a]
                x2, y2, z2 = x[c] - x[a], y[c] - y[a], z[c] - z[a]
                den = x1 * y2 - x2 * y1
                if abs(den) < 1e-12:
                    continue
                gx = (z1 * y2 - z2 * y1) / den
                gy = (x1 * z2 - x2 * z1) / den
                ea[n], eb[n], ec[n] = a, b, c
                tol[n] = 1.5 * math.sqrt(gx * gx + gy * gy) + 1e-6
                n += 1
            if n > n0:
                xa, xb, ya, yb = x[ea[n0]], x[eb[n0]], y[ea[n0]], y[eb[n0]]
                if (min(xa, xb) < W and max(xa, xb) > 0 and min(ya, yb) < H
                        and max(ya, yb) > 0):
                    seen += 1
    return ea[:n].copy(), eb[:n].copy(), ec[:n].copy(), tol[:n].copy(), seen


def silhouette_edges(points: np.ndarray, faces: np.ndarray, projection: np.ndarray,
                     size: tuple[int, int], eye) -> Silhouettes:
    """The silhouette and border edges of a height-field mesh seen from ``eye`` through
    ``projection`` (4×4: scene to clip coordinates, as VTK's camera gives it) in a
    picture of ``size`` (W, H) pixels: the edges between a face turned towards the eye
    and one turned away, and the border edges of faces turned towards it. A face's side
    is its upward normal's. Faces with a vertex behind the eye are left out.

    Examples
    --------
    >>> pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    >>> e = silhouette_edges(pts, np.array([[0, 1, 2], [1, 3, 2]]), np.eye(4), (8, 8),
    ...                      eye=(0.5, 0.5, 10.0))
    >>> sorted(zip(e.a.tolist(), e.b.tolist(), strict=True))
    [(0, 1), (1, 3), (2, 0), (3, 2)]
    """
    pts = np.ascontiguousarray(points, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    m = np.ascontiguousarray(projection, np.float64)
    eye = np.ascontiguousarray(eye, np.float64)
    W, H = (int(v) for v in size)
    n = len(pts)
    # the compiled passes index without bounds checks: refuse what would read outside
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise ValueError("points must be finite (n, 3)")
    if faces.ndim != 2 or faces.shape[1] != 3 or (
            len(faces) and (faces.min() < 0 or faces.max() >= n)):
        raise ValueError("faces must be (F, 3) indices into the points")
    if m.shape != (4, 4) or eye.shape != (3,) or W < 1 or H < 1:
        raise ValueError("projection must be 4x4, eye 3 numbers, size positive")
    x, y, z = np.empty(n), np.empty(n), np.empty(n)
    ok = np.empty(n, np.bool_)
    _project(pts, m, float(W), float(H), x, y, z, ok)
    a, b, c, tol, seen = _silhouettes(faces, pts, eye, x, y, z, ok, max(n, 1), float(W),
                                      float(H))
    return Silhouettes(x, y, z, a, b, c, tol, (W, H), int(seen))


@njit(cache=True, nogil=True)
def _blend(img, D, x, y, z, ea, eb, ec, tol, out):  # pragma: no cover - compiled
    H, W = D.shape
    for k in range(len(ea)):
        x0, y0, z0 = x[ea[k]], y[ea[k]], z[ea[k]]
        x1, y1, z1 = x[eb[k]], y[eb[k]], z[eb[k]]
        xc, yc = x[ec[k]], y[ec[k]]
        # step along the edge's major axis; u is the coordinate along it, v across
        major_x = abs(x1 - x0) >= abs(y1 - y0)
        if major_x:
            u0, v0, u1, v1, uc, vc, n_u, n_v = x0, y0, x1, y1, xc, yc, W, H
        else:
            u0, v0, u1, v1, uc, vc, n_u, n_v = y0, x0, y1, x1, yc, xc, H, W
        if u1 < u0:
            u0, v0, z0, u1, v1, z1 = u1, v1, z1, u0, v0, z0
        du, dv = u1 - u0, v1 - v0
        if not du > 0.0:
            continue
        # the visible face lies on the side of larger v when its third vertex does
        side_hi = du * (vc - v0) - dv * (uc - u0) > 0.0
        s0 = max(0, int(math.ceil(u0 - 0.5)))
        s1 = min(n_u - 1, int(math.floor(u1 - 0.5)))
        slope = dv / du  # |slope| <= 1: across a column the line moves at most a pixel
        for s in range(s0, s1 + 1):
            t = (s + 0.5 - u0) / du
            lv = v0 + t * dv
            lz = z0 + t * (z1 - z0)
            # the line enters and leaves the column at va, vb; the pixels it crosses there
            # (at most two rows, three with the one it meets at the centre's either side)
            va, vb = lv - 0.5 * slope, lv + 0.5 * slope
            q0 = int(math.floor(min(va, vb)))
            q1 = int(math.floor(max(va, vb) - 1e-12))
            for q in range(q0, q1 + 1):
                if q < 1 or q >= n_v - 1:
                    continue
                # the pixel's exact share on the face's side: the column's share of
                # the pixel between the line and its far side, clamped per u (Persson's
                # GPAA takes the extent at the centre only, exact only where the line
                # runs through two opposite sides)
                if side_hi:
                    cov = _clamped_mean(q + 1.0 - va, q + 1.0 - vb)
                else:
                    cov = _clamped_mean(va - q, vb - q)
                if cov <= 0.0 or cov >= 1.0:
                    continue
                if (q + 0.5 > lv) if side_hi else (q + 0.5 < lv):
                    # drawn as the face (its centre on the face's side): blend in the
                    # pixel across the edge
                    pf, pb = q, (q - 1 if side_hi else q + 1)
                else:  # drawn as what lies behind: blend in the face's pixel
                    pb, pf = q, (q + 1 if side_hi else q - 1)
                if major_x:
                    zf, zb = D[pf, s], D[pb, s]
                else:
                    zf, zb = D[s, pf], D[s, pb]
                # the face must be what is drawn on its side, and nothing nearer on the
                # other
                if abs(zf - lz) > tol[k] or zb < lz - tol[k]:
                    continue
                for ch in range(3):
                    if major_x:
                        f, b = img[pf, s, ch], img[pb, s, ch]
                    else:
                        f, b = img[s, pf, ch], img[s, pb, ch]
                    val = np.uint8(min(255.0, max(0.0, cov * f + (1.0 - cov) * b + 0.5)))
                    if major_x:
                        out[q, s, ch] = val
                    else:
                        out[s, q, ch] = val


@njit(cache=True, nogil=True)
def _clamped_mean(g0, g1):  # pragma: no cover - compiled
    """The mean over u in [0, 1] of clamp(g(u), 0, 1) for g linear from g0 to g1: the
    share of a pixel on one side of a line through its column."""
    if abs(g1 - g0) < 1e-9:
        return min(1.0, max(0.0, 0.5 * (g0 + g1)))
    return (_ramp_integral(g1) - _ramp_integral(g0)) / (g1 - g0)


@njit(cache=True, nogil=True)
def _ramp_integral(g):  # pragma: no cover - compiled
    """The integral of clamp(x, 0, 1) from -inf to g."""
    if g <= 0.0:
        return 0.0
    if g <= 1.0:
        return 0.5 * g * g
    return g - 0.5


def edge_antialias(img: np.ndarray, depth: np.ndarray, edges: Silhouettes) -> np.ndarray:
    """``img`` (H, W, 3) uint8 with each pixel a silhouette edge crosses blended by the
    edge's coverage, where ``depth`` (H, W, window depth, row 0 at the top) shows the
    edge's surface in front; a new array.

    Examples
    --------
    >>> img = np.zeros((8, 8, 3), np.uint8); img[:, :4] = 255  # a face on the left
    >>> depth = np.ones((8, 8), np.float32); depth[:, :4] = 0.5
    >>> pts = np.array([[-1.0, -1, 0], [-0.1, -1, 0], [-1, 1, 0], [-0.1, 1, 0]])
    >>> e = silhouette_edges(pts, np.array([[0, 1, 2], [1, 3, 2]]), np.eye(4), (8, 8),
    ...                      eye=(0.0, 0.0, 10.0))
    >>> out = edge_antialias(img, depth, e)
    >>> out[4, 3].tolist()  # the edge at x = 3.6: 0.6 of this pixel on the face's side
    [153, 153, 153]
    """
    W, H = edges.size
    if img.shape != (H, W, 3) or img.dtype != np.uint8 or np.shape(depth) != (H, W):
        raise ValueError(f"the picture must be ({H}, {W}, 3) uint8 and its depth ({H}, {W}), "
                         "the size the edges were found for")
    out = img.copy()
    _blend(img, np.ascontiguousarray(depth, np.float32), edges.x, edges.y, edges.z,
           edges.a, edges.b, edges.c, edges.tol, out)
    return out
