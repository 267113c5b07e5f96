"""Horizon culling from the stored tile bounds, before any decoding (seed 000 §2.6).

Seed 000 culls with Fiedler's horizon: front to back, a block whose top lies under the
horizon that nearer terrain draws is hidden; "test with the max, add with the min"
keeps it conservative. Two choices differ from the thesis's screen-column buffer of
least-squares planes: the horizon is kept per azimuth bin (2048 over the turn) as the
steepest blocked elevation, so it holds for any camera pitch and roll; and it is built
from the level-0 tiles' lowest heights (tile-table columns: nothing decoded), refined to
16 × 16 blocks over the 32 nearest tiles in view (which the view draws at full
resolution anyway). Every stored tile's box (a strategy may grow it, e.g. by its error
spheres) is tested against it.

Why it is conservative (never hides a point the full-resolution surface shows):

- The drawn surface over a level-0 tile whose samples are all valid is continuous and
  lies at or above the tile's ``zmin``.
- The eye is above the surface: every level-0 footprint within the near-plane distance
  of the eye is all valid and below the eye by more than that distance. A ray therefore
  starts above the surface and, until the near plane, cannot meet it.
- A ray at azimuth φ that passes under a valid tile's ``zmin`` at horizontal distance d,
  having run over valid footprints only from the eye to there, crossed the surface at
  distance ≤ d. So a point farther than d on that ray is hidden. Occluders therefore
  count in an azimuth bin only out to the nearest footprint that is not all valid
  (``reach``), and only for occludees wholly farther than the occluder.
- A bin is blocked for rays with tan(elevation) < (zmin − z_eye)/d at every d of the
  occluder's footprint (the farthest d when zmin ≥ z_eye, the nearest otherwise); an
  occluder counts only in bins its footprint spans completely.
- An occludee's rays rise at most (ztop − z_eye)/d over its box (nearest d when
  ztop ≥ z_eye, the farthest otherwise): a lower point of the box is reached along
  the same azimuth by a lower ray. It is hidden when that bound is under the
  horizon in every bin its box touches.

Why it holds for the drawn surface too (rtin, ``lift`` and ``sink`` of
:func:`hidden_rows`). The picture shows a simplified surface: a sample is drawn by the
triangle of the first inactive vertex m above it, up to δ_m off. Each sample s the
picture could show wrongly is covered by one of three cases for m: inactive by LP eq. 2
(s moves at most τ pixels: nothing to hide), culled by the frustum (its drawn point is
outside the picture), or in a tile culled here. In the last case s is drawn inside m's
box raised by δ_m (``lift``: the tile's largest δ), and every ray to that box passes
under an occluder's ``zmin`` lowered by ``sink`` × its farthest distance D (ray to a
lower point: a lower ray). Over an occluder, the drawn surface at a point p is at least
the true height less that much: if p's vertex is inactive by LP, δ ≤ τ(d − r)/λ and
d − r ≤ |p − eye| ≤ D (``sink`` = τ/λ); if it is culled by the frustum, its true and
drawn points lie outside a plane that the ray's point under them, in the frustum, is
inside: that plane's inward normal points down, and the drawn point lies above the ray;
if its tile is culled, p's true point is hidden behind nearer occluders, and the ray,
under it on the same azimuth, is too. The drawn surface is continuous over valid
footprints and (as any picture needs) under the eye, so the ray crosses it: the drawn
point of s is hidden in the picture, as its true point is in the true surface.
(Measured before these two terms, no such sample moved more than τ: the spheres' growth
already held them; the terms make the argument hold, docs/lab/occlusion.md.)

What it costs is kept small: an occluder whose best possible horizon, (zmin − z_eye) over
its centre's distance, is above every farther occludee's top is skipped without any
trigonometry; corners are ordered by pseudo-angle, so a footprint's span takes two
atan2; and before any tile is decoded for its blocks, a first pass lets each near tile
stand in for its blocks at its highest sample (an upper bound of their horizon). When
that pass hides nothing, nothing is decoded; otherwise only what it hides is tested
again with the blocks. Bins a rounding error could move (``horizon.EPS``) count
against culling. The compiled kernel is :mod:`geoterrain.lod.horizon`; this module
chooses the footprints and the boxes it is asked about.

On a geographic source the footprints are curved: corners are mapped by
:meth:`Frame.xy` and each footprint is shrunk (as occluder) or grown (as a hole) by the
largest measured deviation of a tile edge from its chord.

Examples
--------
>>> hidden = hidden_rows(t, View((0, -800, 60), (0, 800, 0)))
>>> hidden.dtype, hidden.shape == (len(t.tile_keys()),)
(dtype('bool'), True)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.view import View
from geoterrain.lod.horizon import (
    BINS,
    FootprintSet,
    _horizon_cull,
    _near_footprints,
)
from geoterrain.lod.tiles import tile_index

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["BINS", "eye_above_surface", "hidden_rows", "occluder_rows"]

NEAR_TILES = 32  # level-0 tiles nearest the eye that also occlude block by block
BLOCKS = 16  # blocks per side of such a tile


class _Footprints:
    """Level-0 tile footprints (corner x, y), with a ring of empty ones around the grid,
    whether each is all valid, its zmin/zmax, and the curved-edge margin."""

    def __init__(self, terrain: TerrainLike):
        g, f = terrain.grid, terrain.frame
        S, T = 1 << g.t, g.tile_samples
        nx, ny = g.tiles(0)  # a square's n × n, or a root grid's
        # positions −1 … n (a ring of "no data" footprints around the grid)
        ty, tx = np.meshgrid(np.arange(-1, ny + 1), np.arange(-1, nx + 1), indexing="ij")
        ty, tx = ty.ravel(), tx.ravel()
        ci = np.stack([ty, ty, ty + 1, ty + 1], 1) * S  # corners (rows)
        cj = np.stack([tx, tx + 1, tx + 1, tx], 1) * S  # corners (columns): a closed loop
        x, y = f.xy(ci.astype(np.float64), cj.astype(np.float64))
        self.corners = np.stack([x, y], 2)  # (P, 4, 2)
        ix = tile_index(terrain)
        L0 = np.flatnonzero(ix.keys[:, 0] == 0)
        p0 = (ix.keys[L0, 2] + 1) * (nx + 2) + (ix.keys[L0, 1] + 1)
        self.position = np.full(len(ix.keys), -1, np.int64)  # index row → footprint
        self.position[L0] = p0
        z0, z1 = ix.zrange[L0, 0], ix.zrange[L0, 1]
        ok = (ix.nvalid[L0] == T * T) & np.isfinite(z0)
        good = np.zeros(len(ty), bool)
        zmin, zmax = np.zeros(len(ty)), np.zeros(len(ty))
        good[p0[ok]] = True
        # decoded heights may sit 1e-9 relative under the recorded zmin
        zmin[p0[ok]] = z0[ok] - 1e-7 * np.maximum(1.0, np.abs(z0[ok]))
        zmax[p0[ok]] = z1[ok] + 1e-7 * np.maximum(1.0, np.abs(z1[ok]))
        self.good, self.zmin, self.zmax = good, zmin, zmax
        self.state = good.astype(np.int8)  # 1 an occluder, 0 a hole
        self.level0 = L0[ix.nvalid[L0] > 0]
        inner = (ty >= 0) & (ty < ny) & (tx >= 0) & (tx < nx)
        edges = np.hypot(*np.moveaxis(np.roll(self.corners, -1, 1) - self.corners, 2, 0))
        self.cell = 0.9 * float(edges[inner].min()) / S  # ≤ any cell's side, metres
        self.centres = _centres(self.corners)
        self.margin = 0.0
        self.blocks: dict = {}
        if f.kind == "geographic":  # largest deviation of a tile edge from its chord
            u = np.linspace(0.0, 1.0, 9)[1:-1]
            dev = 0.0
            for a in range(4):
                b = (a + 1) % 4
                ii = ci[:, a, None] + (ci[:, b] - ci[:, a])[:, None] * u
                jj = cj[:, a, None] + (cj[:, b] - cj[:, a])[:, None] * u
                ex, ey = f.xy(ii, jj)
                px = x[:, a, None] + (x[:, b] - x[:, a])[:, None] * u
                py = y[:, a, None] + (y[:, b] - y[:, a])[:, None] * u
                dev = max(dev, float(np.nanmax(np.hypot(ex - px, ey - py))))
            self.margin = 2.0 * dev + 1e-6 * float(np.nanmax(np.abs(self.corners)))


def _footprints(terrain: TerrainLike) -> _Footprints:
    return terrain.derived(__name__, lambda: _Footprints(terrain))



def _near_tiles(terrain: TerrainLike, index, view: View, tiles: int = NEAR_TILES,
                zmin: np.ndarray | None = None):
    """The level-0 tiles nearest the eye in the frustum that the tile bounds alone do not
    show hidden, and the eye's own: those :func:`_near_blocks` refines. ``zmin``: the
    footprints' heights to occlude with (their lowest samples unless given).

    Returns them (index rows) and their footprints (numbers in :class:`_Footprints`)."""
    fp = _footprints(terrain)
    zmin = fp.zmin if zmin is None else zmin
    rows = fp.level0
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    if not len(rows):
        return none
    lo, hi = index.lo[rows], index.hi[rows]
    e = view.eye
    under = ((lo[:, 0] <= e[0]) & (e[0] <= hi[:, 0]) & (lo[:, 1] <= e[1])
             & (e[1] <= hi[:, 1]))  # the eye's own tiles (by their boxes), with nodata:
    under &= ~fp.good[fp.position[rows]]  # finer, so that their holes do not block all
    d = view.box_distance(lo, hi)
    pick = np.arange(len(rows))
    if len(pick) > 8 * tiles:  # the frustum test for the nearest few only
        pick = np.argpartition(d, 8 * tiles)[:8 * tiles]
    pick = pick[view.box_visibility(lo[pick], hi[pick]) != 0]
    pick = pick[np.argsort(d[pick], kind="stable")]
    # not those the tile bounds already show hidden: a culled tile is never decoded
    hid = np.zeros(len(pick), bool)
    if len(pick):  # only footprints nearer than the farthest of these can occlude them
        c = fp.centres
        near = np.hypot(c[:, 0] - e[0], c[:, 1] - e[1]) - c[:, 2] - fp.margin
        keep = np.flatnonzero(near < d[pick].max())
        sec0, secw = _sector(view)
        _horizon_cull(float(e[0]), float(e[1]), float(e[2]),
                      FootprintSet(fp.corners[keep], fp.centres[keep], fp.state[keep],
                                 zmin[keep], fp.margin), sec0, secw, lo[pick], hi[pick], hid)
    pick = np.union1d(pick[~hid][:tiles], np.flatnonzero(under))
    rows = rows[pick]
    return rows, fp.position[rows]


def _near_blocks(terrain: TerrainLike, index, rows: np.ndarray):
    """Finer footprints for the level-0 tiles ``rows`` (:func:`_near_tiles`): each tile's
    b × b-cell blocks, with their lowest sample (state 1) or, if one of their samples is
    nodata, as holes (state 0). These tiles are the ones a view draws at full
    resolution, so decoding them here usually costs the selection nothing more. (One of
    them may still turn out hidden behind a nearer one: it is culled, though it was
    read.)

    Returns the blocks' corners, centres, states and lowest samples."""
    fp = _footprints(terrain)
    S = 1 << terrain.grid.t
    b = max(1, S // BLOCKS)
    keys = [(int(index.keys[r, 1]), int(index.keys[r, 2]), b) for r in rows]
    new = [k for k in dict.fromkeys(keys) if k not in fp.blocks]
    if new:
        _blocks(terrain, new, b, fp.blocks)
    got = [fp.blocks[k] for k in keys]
    return tuple(np.concatenate([g[i] for g in got]) for i in range(4))


def _blocks(terrain: TerrainLike, keys: list, b: int, into: dict) -> None:
    """Corners, centres, states and lowest samples of the blocks of the level-0 tiles
    ``keys`` ((x, y, b) each), all tiles at once, stored per tile in ``into``."""
    S = 1 << terrain.grid.t
    nb, n = S // b, len(keys)
    tiles = [terrain.tile(0, x, y) for x, y, _ in keys]
    valid = np.stack([t.valid for t in tiles])
    z = np.where(valid, terrain.frame.z(np.nan_to_num(np.stack([t.heights for t in tiles]))),
                 np.inf)
    # lowest sample of each block, borders included: the block's own b × b samples,
    # then its last row and column (the next block's first) — inf marks nodata
    bad = np.where(valid, 0.0, np.inf)

    def closed_min(a):  # (n, T, T) → (n, nb, nb)
        rows = np.minimum(a[:, :S].reshape(n, nb, b, -1).min(2), a[:, b::b])  # (n, nb, T)
        return np.minimum(rows[:, :, :S].reshape(n, nb, nb, b).min(3), rows[:, :, b::b])

    lows = closed_min(z)
    ok = closed_min(bad) == 0.0  # no nodata sample in the block
    lows = np.where(ok, lows, 0.0).reshape(n, -1)
    lows = lows - 1e-7 * np.maximum(1.0, np.abs(lows))
    ok = ok.reshape(n, -1).astype(np.int8)
    # the blocks' corners (rows, columns of the grid; a closed loop), then x, y
    k = np.arange(0, S, b)
    xs = np.array([x for x, _, _ in keys])[:, None, None]
    ys = np.array([y for _, y, _ in keys])[:, None, None]
    bi = np.broadcast_to(ys * S + k[None, :, None], (n, nb, nb)).reshape(-1)
    bj = np.broadcast_to(xs * S + k[None, None, :], (n, nb, nb)).reshape(-1)
    ci = np.stack([bi, bi, bi + b, bi + b], 1).astype(np.float64)
    cj = np.stack([bj, bj + b, bj + b, bj], 1).astype(np.float64)
    corners = np.stack(terrain.frame.xy(ci, cj), 2).reshape(n, nb * nb, 4, 2)
    cens = _centres(corners.reshape(-1, 4, 2)).reshape(n, nb * nb, 3)
    for m, key in enumerate(keys):
        into[key] = (corners[m], cens[m], ok[m], lows[m])


def _centres(corners: np.ndarray) -> np.ndarray:
    """Per footprint: its corners' mean x, y and the largest corner distance from it."""
    c = corners.mean(axis=1)
    r = np.sqrt(((corners - c[:, None, :]) ** 2).sum(-1)).max(axis=1)
    return np.concatenate([c, r[:, None] * (1 + 1e-9)], 1)


def _far_distance(corners: np.ndarray, zlo: np.ndarray, zhi: np.ndarray, eye: np.ndarray,
                  margin: float) -> np.ndarray:
    """Per footprint (corners (P, K, 2), heights between ``zlo`` and ``zhi``): an upper
    bound of the distance from the eye to any of its points (the farthest corner, grown
    by the curved-edge ``margin``, and the farther of its heights)."""
    far = np.hypot(corners[..., 0] - eye[0], corners[..., 1] - eye[1]).max(axis=1) + margin
    up = np.maximum(np.abs(zlo - eye[2]), np.abs(zhi - eye[2]))
    return np.hypot(far, up)


def _sector(view: View) -> tuple[float, float]:
    """The azimuths of the frustum's rays: (start, width); width 4π when they include
    straight down or up, or span π or more."""
    return view.memo("azimuths", lambda: _sector_of(view))


def _sector_of(view: View) -> tuple[float, float]:
    r, u, f = view.basis()
    ty = math.tan(math.radians(view.fov_y_deg) / 2)
    tx = ty * view.size[0] / view.size[1]
    rays = np.array([f + sx * tx * r + sy * ty * u for sx in (-1, 1) for sy in (-1, 1)])
    hor = np.hypot(rays[:, 0], rays[:, 1])
    if hor.min() <= 1e-6 * np.linalg.norm(rays, axis=1).max():
        return 0.0, 4 * math.pi
    az = np.arctan2(rays[:, 1], rays[:, 0])
    # the cone holds neither vertical, so its azimuths form one arc under π wide... or not:
    ref = math.atan2(f[1], f[0]) if math.hypot(f[0], f[1]) > 0 else float(az[0])
    rel = (az - ref + math.pi) % (2 * math.pi) - math.pi
    lo_, hi_ = float(rel.min()), float(rel.max())
    if hi_ - lo_ >= math.pi - 1e-3:
        return 0.0, 4 * math.pi
    pad = 1e-6
    return ref + lo_ - pad, hi_ - lo_ + 2 * pad


def _near_distance(view: View) -> float:
    """The near plane's distance along the frustum's corner rays (0 without one)."""
    ty = math.tan(math.radians(view.fov_y_deg) / 2)
    tx = ty * view.size[0] / view.size[1]
    return (view.near or 0.0) * math.sqrt(1 + tx * tx + ty * ty)


def eye_above_surface(terrain: TerrainLike, view: View) -> bool:
    """Whether no ray from the eye meets the surface before the near plane: the
    footprints within that distance are all valid and below the eye by more than it.

    The tile bounds answer first; when they cannot (a hill in the eye's tile rises
    above the eye), the full-resolution samples around the eye are read.
    """
    fp = _footprints(terrain)
    e = view.eye
    r_near = _near_distance(view)
    near = _near_footprints(float(e[0]), float(e[1]), fp.corners, fp.centres,
                            r_near + fp.margin)
    if not near.any():
        return False
    top = float(e[2]) - r_near
    if fp.good[near].all() and (fp.zmax[near] < top).all():
        return True
    # the samples of the cells within reach of the eye
    f, g = terrain.frame, terrain.grid
    cx, cy = f.scene_to_crs(np.array([e[0]]), np.array([e[1]]))
    a, b, c, d, ee, ff = f.transform
    det = a * ee - b * d
    if det == 0:
        return False
    jj = (ee * (cx[0] - c) - b * (cy[0] - ff)) / det - 0.5  # inverse geotransform,
    ii = (a * (cy[0] - ff) - d * (cx[0] - c)) / det - 0.5   # pixel centres
    rc = (r_near + fp.margin) / max(fp.cell, 1e-300)  # the reach, in cells (an upper bound)
    if rc > 64 or not np.isfinite(ii + jj):
        return False
    i0, i1 = int(math.floor(ii - rc)), max(int(math.ceil(ii + rc)), int(math.floor(ii)) + 1)
    j0, j1 = int(math.floor(jj - rc)), max(int(math.ceil(jj + rc)), int(math.floor(jj)) + 1)
    (R, C), S = g.shape, 1 << g.t  # level 0's lattice: N × N, or a root grid's
    if i0 < 0 or j0 < 0 or i1 > R - 1 or j1 > C - 1:
        return False
    z = np.empty((i1 - i0 + 1, j1 - j0 + 1))
    for ty in range(i0 // S, min((i1 - 1) // S, R // S - 1) + 1):
        for tx in range(j0 // S, min((j1 - 1) // S, C // S - 1) + 1):
            if (0, tx, ty) not in terrain.tile_info:
                return False
            tile = terrain.tile(0, tx, ty)
            r0, c0 = max(i0 - ty * S, 0), max(j0 - tx * S, 0)
            r1, c1 = min(i1 - ty * S, S), min(j1 - tx * S, S)
            if not tile.valid[r0:r1 + 1, c0:c1 + 1].all():
                return False
            z[ty * S + r0 - i0:ty * S + r1 - i0 + 1, tx * S + c0 - j0:tx * S + c1 - j0 + 1] = \
                f.z(tile.heights[r0:r1 + 1, c0:c1 + 1])
    return _surface_max_near(z, i0, j0, ii, jj, rc) < top


def _surface_max_near(z: np.ndarray, i0: int, j0: int, ii: float, jj: float, rc: float) -> float:
    """An upper bound of the drawn surface (union-jack triangles over the samples ``z``,
    whose first is sample (i0, j0)) within ``rc`` cells of the point (ii, jj): per
    triangle, its plane at the point plus its slope times ``rc``."""
    a, b = np.meshgrid(np.arange(z.shape[0] - 1), np.arange(z.shape[1] - 1), indexing="ij")
    z00, z01, z10, z11 = z[a, b], z[a, b + 1], z[a + 1, b], z[a + 1, b + 1]
    di, dj = ii - (i0 + a), jj - (j0 + b)  # the point from each cell's first corner
    main = ((i0 + a) % 2 == 1) == ((j0 + b) % 2 == 1)  # diagonal 00–11, else 01–10
    # planes z = c + gi·di + gj·dj of the cell's two triangles
    gi1, gj1, c1 = np.where(main, z11 - z01, z10 - z00), z01 - z00, z00
    gi2 = np.where(main, z10 - z00, z11 - z01)
    gj2 = np.where(main, z11 - z10, z11 - z10)
    c2 = np.where(main, z00, z01 + z10 - z11)
    # (anti-diagonal second triangle: z = z11 + (1−dj)(z10−z11) + (1−di)(z01−z11))
    best = -math.inf
    for gi, gj, c in ((gi1, gj1, c1), (gi2, gj2, c2)):
        best = max(best, float(np.max(c + gi * di + gj * dj + np.hypot(gi, gj) * rc)))
    return best


def occluder_rows(terrain: TerrainLike, view: View) -> np.ndarray:
    """The level-0 tiles (index rows) that culling for ``view`` read to occlude with
    (empty before :func:`hidden_rows` ran for it, or when it culled nothing)."""
    return view.memos.get(("occluders", id(terrain)), np.zeros(0, np.int64))


def hidden_rows(terrain: TerrainLike, view: View, grow: np.ndarray | None = None,
                rows: np.ndarray | None = None, *, enabled: bool = True,
                lift: np.ndarray | None = None, sink: float = 0.0) -> np.ndarray:
    """Which rows of the tile index are hidden from ``view`` by nearer terrain.

    ``grow`` (per row, scene units) widens each tile's box first, e.g. by the radius of
    the error spheres a strategy refines with. For a strategy that draws a simplified
    surface, ``lift`` (per row) raises each box's top further, by how far the drawn
    surface may lie above the true one over a tile left unrefined because it is hidden
    (rtin: the tile's largest finite δ), and ``sink`` lowers every occluder by how far
    the drawn surface may lie under the true one, per unit of distance from the eye
    (rtin: τ over its λ; see the module docstring). ``rows`` (index rows) limits the test to
    the rows a strategy may read, such as those its walk reaches: the others come back
    False (not hidden), and the work follows the rows asked for, not the store's size
    (the occluders are still every level-0 footprint in view). All False when culling
    is switched off (``enabled=False``: a selection's ``occlusion=False``) or the eye is
    not safely above the terrain (see the module docstring).

    Examples
    --------
    >>> h = hidden_rows(t, View((0, -800, 400), (0, 0, 0)))
    >>> h.shape == (len(tile_index(t).keys),)
    True
    """
    index = tile_index(terrain)
    out = np.zeros(len(index.keys), bool)
    if not enabled or not len(out) or index.outside(view):
        return out  # (nothing in view: nothing to read either)
    key = ("hidden", id(terrain), None if grow is None else id(grow),
           None if rows is None else np.asarray(rows, np.int64).tobytes(),
           None if lift is None else id(lift), float(sink))
    got = view.memos.get(key)
    if got is not None:
        return got
    fp = _footprints(terrain)
    rows = np.arange(len(out)) if rows is None else np.unique(np.asarray(rows, np.int64))
    lo, hi = index.lo[rows], index.hi[rows]
    if grow is not None:
        g = np.asarray(grow, np.float64)[rows, None]
        g = np.where(np.isfinite(g), g, np.inf)
        lo, hi = lo - g, hi + g
    if lift is not None:  # the drawn surface over a hidden tile: up to its δ higher
        u = np.asarray(lift, np.float64)[rows]
        hi = hi.copy()
        hi[:, 2] += np.where(np.isfinite(u), u, np.inf)
    if eye_above_surface(terrain, view):
        e = view.eye
        ex, ey, ez = float(e[0]), float(e[1]), float(e[2])
        sec0, secw = _sector(view)
        zmin = fp.zmin
        if sink > 0:  # the drawn occluders: up to sink × their distance lower
            zmin = zmin - sink * _far_distance(fp.corners, fp.zmin, fp.zmax, e, fp.margin)
        occluders, replaced = _near_tiles(terrain, index, view, zmin=zmin)
        state = fp.state.copy()
        corners, cen = fp.corners, fp.centres
        if len(occluders) and fp.good[replaced].all():
            # first with each near tile standing in for its blocks at its highest
            # sample (an upper bound of their horizon): nothing decoded when that hides
            # nothing, and only what it hides is tested again
            state[replaced] = 2
            zup = zmin.copy()
            zup[replaced] = fp.zmax[replaced]
            upper = np.zeros(len(rows), bool)
            if _horizon_cull(ex, ey, ez, FootprintSet(corners, cen, state, zup, fp.margin),
                             sec0, secw, lo, hi, upper) == 0:
                rows, lo, hi = rows[upper], lo[upper], hi[upper]
                occluders = occluders[:0] if not len(rows) else occluders
        if len(rows) and len(occluders):
            bc, bcen, bs, bz = _near_blocks(terrain, index, occluders)
            if sink > 0:  # (a block's highest sample is at most its tile's)
                top = np.repeat(fp.zmax[replaced], len(bz) // len(replaced))
                bz = bz - sink * _far_distance(bc, bz, top, e, fp.margin)
            state[replaced] = -1
            corners = np.concatenate([corners, bc])
            cen = np.concatenate([cen, bcen])
            state = np.concatenate([state, bs])
            zmin = np.concatenate([zmin, bz])
        view.memos[("occluders", id(terrain))] = occluders
        if len(rows):
            got = np.zeros(len(rows), bool)
            _horizon_cull(ex, ey, ez, FootprintSet(corners, cen, state, zmin, fp.margin), sec0,
                          secw, lo, hi, got)
            out[rows] = got
    view.memos[key] = out
    return out
