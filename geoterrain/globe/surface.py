"""The globe's surface: which value every lattice point of every depth takes.

A node of depth D has (n + 1)² vertices on the face lattice of level D + k (n = 2^k cells a
side). A lattice point x of depth D takes a value V(x, D): its distance from the planet's
centre along its own ray (:meth:`~geoterrain.globe.model.Model.place`).

Each layer L (the base layer, each store) has a *resolved depth* D_L: a store's is
D_s = ⌈log₂(E_face/(n·s))⌉ (:func:`~geoterrain.globe.layers.resolved_depth`; its vertices are
then no farther apart than its samples), the base layer's D_b is where its own error bound
falls to 1 mm (no deeper than the finest store's D_s). The layer's own value V_L(x, D) is

- **sampled** for D ≤ D_L: the layer's height at x, read at the store level depth D shows
  (NaN where the store has no data);
- **interpolated** beyond: on the chord of its two level-(D − 1) neighbours (the ends of the
  edge, or of the cell's short diagonal, that x halves), along x's own ray (1/t is affine
  along a flat segment seen from the centre, t = r/|p|: the harmonic mean of the
  neighbours' t): exactly where the layer's coarser surface is.

V(x, D) lays the layers' values over the base layer's, the coarsest store first, each with
its weight at x (:meth:`~geoterrain.globe.layers.StoreLayer.weight`: 1 inside, falling to 0
over its edge's outer samples, 0 where it has no data). The *measured depth* is the deepest
layer depth; the finest store (when it has no no-data) is then sampled on in its core, down
to vertices ``FINE_SPACING_M`` apart or depth ``FINE_DEPTH_LIMIT`` (:meth:`Surface.fine_points`:
a point ``fine_margin[D]`` metres inside its unblended core takes its value, any other the
chord of its coarser neighbours), so that the mesh reaches its samples near the eye.
Elsewhere beyond the measured depth nothing new appears. The *truth* the LOD bound is
stated against is the store's samples in its core (:mod:`geoterrain.globe.errors`) and V
at the measured depth's lattice elsewhere.

Every value is a function of (x, D) alone, so two nodes that share a vertex give it the
same position, bit for bit, whatever their depth: no crack between neighbours of one
depth, and (with the morph, :mod:`geoterrain.globe.cdlod`) none between depths.

Examples
--------
>>> s = Surface(Model.get("sphere"), [], BaseLayer.ellipsoid(), node_cells=8)
>>> v = s.values((0, 0, 0, 0))
>>> v.r.shape, bool(np.allclose(v.r[1:-1, 1:-1], 6371000.0))
((11, 11), True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geoterrain.exceptions import UsageError
from geoterrain.globe.layers import FACE_EDGE_M, BaseLayer, StoreLayer, resolved_depth
from geoterrain.globe.model import Model
from geoterrain.globe.nodes import node_widths
from geoterrain.globe.noise import error_bound
from geoterrain.globe.polyhedron import face_points

__all__ = ["Surface", "NodeValues", "NodeKey", "MAX_DEPTH", "BASE_TOLERANCE_M", "FINE_SPACING_M",
           "FINE_DEPTH_LIMIT"]

NodeKey = tuple[int, int, int, int]  # (face, depth, x, y)
MAX_DEPTH = 22
BASE_TOLERANCE_M = 1e-3  # the base layer is resolved where its own error bound reaches 1 mm
FINE_SPACING_M = 0.004  # the finest store is sampled, in its core, to vertices this close
FINE_DEPTH_LIMIT = 26  # … or this depth (a node key holds x, y < 2^26)


@dataclass
class NodeValues:
    """A node's lattice with a one-sample border: (n + 3)² points, float64.

    ``d`` unit ray directions, ``fn`` |p| of the flat face points, ``r`` the distance of each
    vertex from the centre, ``rT`` of the coarser surface along the same ray (the morph
    target: the level-(D − 1) value of an even point, the chord of its neighbours for an odd
    one), ``h`` the vertex's height (metres; NaN where interpolated), ``lon``, ``lat`` its
    geodetic position, ``sampled`` whether its value was sampled (else interpolated) and
    ``store`` whether a store (not the base layer) gave it."""

    key: NodeKey
    d: np.ndarray
    fn: np.ndarray
    r: np.ndarray
    rT: np.ndarray
    h: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    sampled: np.ndarray
    store: np.ndarray

    @property
    def inner(self) -> tuple[slice, slice]:
        """The node's own (n + 1)² vertices inside the border."""
        return slice(1, -1), slice(1, -1)


def _chord(r: np.ndarray, fn_prev: np.ndarray, lo_prev: tuple[int, int],
           fn: np.ndarray, lo: tuple[int, int]) -> np.ndarray:
    """Values of a window of the next lattice level on the coarser surface.

    ``r``, ``fn_prev``: the coarser level's values and |p| on its window whose first row and
    column are ``lo_prev``; ``fn`` and ``lo``: the finer window. An even point keeps its
    value (bit for bit); an odd one lies on the chord of its two neighbours (the ends of the
    edge, or of the cell's short diagonal (i − 1, j + 1)–(i + 1, j − 1), it halves): w = |p|/r
    is affine along a flat segment seen from the centre, so its w is their mean.
    """
    w = fn_prev / r
    ri = np.arange(fn.shape[0])[:, None] + lo[0]
    J = np.arange(fn.shape[1])[None, :] + lo[1]
    oi, oj = ri & 1, J & 1
    # the two neighbours (in coarser-level indices); for an even point both are itself
    i1 = (ri - oi) // 2
    i2 = (ri + oi) // 2
    j1 = np.where(oi & oj, (J + 1) // 2, (J - oj) // 2)
    j2 = np.where(oi & oj, (J - 1) // 2, (J + oj) // 2)
    a = w[i1 - lo_prev[0], j1 - lo_prev[1]]
    b = w[i2 - lo_prev[0], j2 - lo_prev[1]]
    out = fn / (0.5 * (a + b))
    even = (oi == 0) & (oj == 0)
    out[even] = np.broadcast_to(r[i1 - lo_prev[0], j1 - lo_prev[1]], out.shape)[even]
    return out


class Surface:
    """The composite surface of a globe (module docstring).

    Parameters
    ----------
    model : the planet (:class:`~geoterrain.globe.model.Model`).
    stores : :class:`~geoterrain.globe.layers.StoreLayer` s; where several hold data, the one
        with the finest samples wins.
    base : the layer under them (:class:`~geoterrain.globe.layers.BaseLayer`).
    node_cells : n, cells a node side (a power of two; seed 001 uses 128).
    vertical_exaggeration : heights × N.
    """

    def __init__(self, model: Model, stores: list[StoreLayer], base: BaseLayer,
                 node_cells: int = 64, vertical_exaggeration: float = 1.0):
        if node_cells < 2 or node_cells & (node_cells - 1):
            raise UsageError(f"node_cells must be a power of two ≥ 2, got {node_cells}")
        if not (math.isfinite(vertical_exaggeration) and vertical_exaggeration > 0):
            raise UsageError(f"vertical exaggeration must be a positive number, got "
                             f"{vertical_exaggeration}")
        self.model, self.base = model, base
        self.n = int(node_cells)
        self.k = self.n.bit_length() - 1
        self.scale = float(vertical_exaggeration)
        self.stores = sorted(stores, key=lambda s: s.spacing)  # finest first
        self.resolved = [resolved_depth(s.spacing, self.n) for s in self.stores]
        self.base_present = not any(s.covers_globe() for s in self.stores)
        natural = self._base_depth()
        self.base_depth = (min(natural, max(self.resolved)) if self.stores else natural) \
            if self.base_present else -1
        self.measured_depth = max([self.base_depth] + self.resolved)
        self.max_depth = self.measured_depth
        self.fine = self._fine_store()
        self.fine_margin = np.zeros(self.max_depth + 1)
        self.fine_border = math.inf
        if self.fine is not None:
            D = self.measured_depth
            while D < FINE_DEPTH_LIMIT and self.spacing(D) > FINE_SPACING_M:
                D += 1
            self.max_depth = D
            rng = self.fine.terrain.meta.get("height_range") or [0.0, 0.0]
            top = model.a + max(0.0, float(np.max(self.fine.terrain.frame.z(
                np.asarray(rng, np.float64))))) * self.scale + 1.0
            self.cell_chord = node_widths(D, self.k) * top * 1.02  # ≥ any cell's long diagonal
            margin = np.zeros(D + 1)
            for d in range(self.measured_depth + 1, D + 1):
                margin[d] = margin[d - 1] + self.cell_chord[d - 1]
            self.fine_margin = margin
            self.fine_step = min(self.fine.ground_steps())
            self.fine_border = self.fine.feather + (
                margin[-1] + self.cell_chord[self.measured_depth + 1]) / self.fine_step

    def _fine_store(self) -> StoreLayer | None:
        """The store sampled beyond its resolved depth in its core: the finest, when it has
        no no-data (a hole would show the layer under it) and a ground step to measure by."""
        if not self.stores:
            return None
        st = self.stores[0]
        if float(st.terrain.meta.get("nodata_fraction", 1.0)) != 0.0:
            return None
        return st

    def fine_points(self, lon: np.ndarray, lat: np.ndarray, depth: int) -> np.ndarray:
        """Whether lattice points of depth ``depth`` (> the measured depth) take the finest
        store's own (bilinear, level-0) value rather than the chord of their coarser
        neighbours: those at least ``fine_margin[depth]`` metres inside its unblended core
        (weight 1), so that their coarser neighbours (≤ one coarser cell's long diagonal
        away) are such points themselves, or lie at the measured depth inside the core: the
        store's value there too."""
        lon = np.asarray(lon, np.float64)
        if self.fine is None or depth <= self.measured_depth:
            return np.zeros(lon.shape, bool)
        m = self.fine.edge_samples(lon, lat)
        need = self.fine.feather + self.fine_margin[depth] / self.fine_step
        with np.errstate(invalid="ignore"):
            return np.isfinite(m) & (m >= need)

    # ------------------------------------------------------------------ depths
    def spacing(self, depth: int) -> float:
        """Nominal vertex spacing (metres) of depth ``depth``'s nodes."""
        return FACE_EDGE_M / (self.n * 2.0 ** max(depth, 0))

    def _base_depth(self) -> int:
        """The depth at which the base layer's own error bound falls to 1 mm."""
        planet = self.base.planet if self.base.kind == "procedural" else None
        rho = self.model.min_curvature_radius
        for D in range(MAX_DEPTH + 1):
            if error_bound(planet, self.spacing(D), rho, self.scale) <= BASE_TOLERANCE_M:
                return D
        return MAX_DEPTH

    def layers(self) -> list[tuple[StoreLayer | None, int]]:
        """(layer, its resolved depth), in the order they are laid: the base layer (None;
        unless a store covers the globe), then the stores, coarsest first."""
        out: list[tuple[StoreLayer | None, int]] = []
        if self.base_present:
            out.append((None, self.base_depth))
        for st, D in sorted(zip(self.stores, self.resolved, strict=True),
                            key=lambda p: -p[0].spacing):
            out.append((st, D))
        return out

    def layer_heights(self, layer: StoreLayer | None, lon: np.ndarray, lat: np.ndarray,
                      depth: int) -> np.ndarray:
        """One layer's heights (metres, exaggerated) at depth ``depth`` (NaN: no data)."""
        lon = np.asarray(lon, np.float64)
        lat = np.asarray(lat, np.float64)
        if layer is None:
            h = self.base.heights(lon, lat, self.model.up(lon, lat))
        else:
            h = np.full(lon.shape, np.nan)
            c = layer.covers(lon, lat)
            if c.any():
                h[c] = layer.heights(lon[c], lat[c], layer.level_for(self.spacing(depth)))
        return h * self.scale

    def weight(self, layer: StoreLayer | None, lon: np.ndarray, lat: np.ndarray
               ) -> np.ndarray:
        """How much of ``layer`` the composite takes at lon, lat (1 for the base layer)."""
        if layer is None:
            return np.ones(np.shape(lon))
        w = np.zeros(np.shape(lon))
        c = layer.covers(lon, lat)
        if c.any():
            w[c] = layer.weight(np.asarray(lon)[c], np.asarray(lat)[c])
        return w

    def heights(self, lon: np.ndarray, lat: np.ndarray, depth: int = 0) -> np.ndarray:
        """Composite heights (metres, exaggerated) at depth ``depth``, the layers laid as
        :meth:`values` lays their values (for colours, queries and tests)."""
        h = None
        for layer, _ in self.layers():
            hl = self.layer_heights(layer, lon, lat, depth)
            if h is None:
                h = hl
                continue
            w = np.where(np.isfinite(hl), self.weight(layer, lon, lat), 0.0)
            h = np.where(w > 0, w * np.where(w > 0, hl, 0.0) + (1 - w) * h, h)
        return h

    def values(self, key: NodeKey) -> NodeValues:
        """The node's lattice values with a one-sample border (the module docstring's
        definition): each layer's values on windows of the lattice, from the level at which
        it is sampled (or the node's parent's level) down to the node's own, then laid over
        each other at the node's level and its parent's; the morph targets are the parent
        level's composite on its chords."""
        face, depth, x, y = key
        k, n = self.k, self.n
        fin = depth + k  # the node's own lattice level
        wins = {fin: ((y * n - 1, y * n + n + 1), (x * n - 1, x * n + n + 1))}
        grids: dict[int, tuple] = {}

        def window(lam):
            while lam not in wins:
                top = min(wins)
                (r0, r1), (c0, c1) = wins[top]
                wins[top - 1] = ((r0 // 2, -(-r1 // 2)), (c0 // 2, -(-c1 // 2)))
            return wins[lam]

        def grid(lam):
            if lam not in grids:
                (r0, r1), (c0, c1) = window(lam)
                vi = np.arange(r0, r1 + 1, dtype=np.float64) / 2.0 ** lam
                J = np.arange(c0, c1 + 1, dtype=np.float64) / 2.0 ** lam
                V, U = np.meshgrid(vi, J, indexing="ij")
                F = face_points(face, U, V)
                fn = np.linalg.norm(F, axis=-1)
                d = F / fn[..., None]
                t0, lon0, lat0 = self.model.surface(d)
                grids[lam] = (d, fn, t0, lon0, lat0)
            return grids[lam]

        levels = [fin - 1, fin] if depth > 0 else [fin]
        comp: dict[int, np.ndarray] = {}
        any_store = np.zeros(grid(fin)[1].shape, bool)
        # beyond the measured depth, where the finest store shows unblended at every point
        # of both levels, the layers under it take no part (their weight is 0)
        alone = depth > self.measured_depth and self.fine is not None and all(
            (self.weight(self.fine, grid(lv)[3], grid(lv)[4]) >= 1.0).all() for lv in levels)
        for layer, DL in self.layers():
            if alone and layer is not self.fine:
                continue
            if layer is not None and not any(layer.covers(grid(lv)[3], grid(lv)[4]).any()
                                             for lv in levels):
                continue
            start = min(max(DL, 0), max(depth - 1, 0)) + k
            if layer is self.fine and depth - 1 > DL and self.fine_points(
                    *grid(fin - 1)[3:], depth - 1).all():
                start = fin - 1  # the parent's lattice is sampled throughout: no chords
            prev = None
            for lam in range(start, fin + 1):
                d, fn, t0, lon0, lat0 = grid(lam)
                (r0, _), (c0, _) = window(lam)
                if lam - k <= DL or prev is None:  # sampled
                    delta = max(lam - k, 0)

                    def hf(lo, la, depth=delta, layer=layer):
                        return self.layer_heights(layer, lo, la, depth)

                    r = self.model.place(d, hf, first=(t0, lon0, lat0))[0]
                    if layer is self.fine and lam - k >= DL:
                        r = self.model.settle(d, r, hf)
                else:
                    r = _chord(prev[0], prev[1], prev[2], fn, (r0, c0))
                    if layer is self.fine:
                        fm = self.fine_points(lon0, lat0, lam - k)
                        if fm.any():
                            def hf0(lo, la, layer=layer):
                                return self.layer_heights(layer, lo, la, self.max_depth)

                            rs = self.model.place(d[fm], hf0, first=(t0[fm], lon0[fm],
                                                                     lat0[fm]))[0]
                            r[fm] = self.model.settle(d[fm], rs, hf0)
                prev = (r, fn, (r0, c0))
                if lam in levels:
                    if layer is None:
                        comp[lam] = r
                        continue
                    w = np.where(np.isfinite(r), self.weight(layer, lon0, lat0), 0.0)
                    base = comp.get(lam)
                    if base is None:  # no base layer: the coarsest store (covers the globe)
                        comp[lam] = np.where(w > 0, r, np.nan)
                    else:
                        comp[lam] = np.where(w > 0, w * np.where(w > 0, r, 0.0)
                                             + (1 - w) * base, base)
                    if lam == fin:
                        any_store |= w > 0
        d, fn, t0, lon0, lat0 = grid(fin)
        r = comp[fin]
        if depth > 0:
            (r0, _), (c0, _) = window(fin - 1)
            (f0, _), (g0, _) = window(fin)
            rT = _chord(comp[fin - 1], grid(fin - 1)[1], (r0, c0), fn, (f0, g0))
        else:
            rT = r.copy()
        h = (r - t0) * np.einsum("...j,...j", d, self.model.up(lon0, lat0))
        sampled = np.ones(r.shape, bool)
        return NodeValues(key, d, fn, r, rT, h, lon0, lat0, sampled, any_store)
