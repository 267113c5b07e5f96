"""Node errors, measured once where stores lie and bounded analytically elsewhere, and the
per-depth tables the planetary CDLOD derives its ranges from.

**What a node's error bounds.** e(N) bounds the radial distance (along the rays from the
planet's centre) between N's drawn surface (flat triangles, unmorphed) and the truth. Where
a store shows unblended, the truth is **the store's own samples**, placed as the data say
(geodetic lon, lat and height → ECEF): what the project's independent measure compares
the mesh with. Elsewhere (over the base layer, in a store's feathered edge) it is the
composite surface at every point of the deepest lattice (:mod:`geoterrain.globe.surface`).

The deepest lattice does not pass through the samples: its vertices are the store's
bilinear interpolant read at face-lattice points, and between them its flat triangles cut
the corners of the samples' relief. On srtm1_japan (25 × 31 m samples, 16-cell nodes) the
deepest nodes missed samples by up to 13.0 m with 31.7 m vertices and 7.7 m with 15.9 m
ones, which an error stated against the lattice counted as 0 (the ρ of 1.06 px at τ = 1).
The error against the samples falls with the vertex spacing, never to 0: ρ ≤ τ holds
from λ·e_leaf/τ from the eye on (:func:`geoterrain.globe.layers.resolved_depth`).

**Measured, over stores.** For each node whose cone meets a store's footprint, down to the
depth where nothing new can appear (the store's resolved depth D_s, or the base layer's
D_b at a seam with it), this module generates the node's values once, when the globe is
made (seed 001's proposed pipeline, L537: bottom-up over the data, here from the stored
pyramid), and sets, deepest first,

    e(N) = max( g(N), max over children c not wholly unblended of ( (1 + s_c)·M_c + e(c) ) )

where g(N) is N's largest radial gap to the store samples on its rays, measured at every
one of them (in the face's plane, where a flat triangle's w = |p|/r is affine), M_c is
c's largest radial move onto N's surface (the morph's |rT − r|, measured at every vertex
of c) and s_c a relative slack. Why the chain holds: N's and c's surfaces are flat on c's
triangles, where w is affine along the rays, so their radial gap is largest at c's
vertices up to the factor (r_max/r_min)²·max|p|/min|p| = 1 + s_c; and
|N − truth| ≤ |N − c| + |c − truth|. A child that shows one store unblended at every
vertex has the samples for its truth, which g(N) measures directly, so it adds nothing to
the chain. A child that holds no sampled point (beyond every truth depth) reproduces its
parent exactly: M = e = 0. The store's own error (its coarse levels against its full
resolution) is in e(N) exactly, not as a bound.

**Measured per region, beyond the measured depth** (where the finest store is sampled on
in its core: :mod:`geoterrain.globe.surface`; the methods in
:mod:`geoterrain.globe.deeperrors`): per measured-depth node and deeper depth,
the largest gap of the deeper triangles to the samples in it, each rebuilt from its three
vertices when a view first needs it (:meth:`ErrorTable.deep_errors`); the moves are
bounded from the spread of the samples' gradient (:meth:`ErrorTable.fine_errors`, also the
starting bound for e). A view takes each depth's table over the nodes that depth can be
drawn under, iterated to a fixed point (:meth:`ErrorTable._deep_ranges`), and its depth
stops where the error already meets the eye's distance (:meth:`ErrorTable.view_ranges`).

**Bounded, over the base layer.** Where no store lies, a node samples the procedural
planet (or the bare ellipsoid) at every vertex, and :func:`geoterrain.globe.noise.error_bound`
bounds e from the circumradius of its triangles; its move is at most its parent's error.

Examples
--------
>>> from geoterrain.globe.model import Model
>>> from geoterrain.globe.layers import BaseLayer
>>> from geoterrain.globe.surface import Surface
>>> tb = ErrorTable(Surface(Model.get("sphere"), [], BaseLayer.ellipsoid(), node_cells=8))
>>> bool(np.all(np.diff(tb.e[: tb.max_depth + 1]) < 0)), tb.regions
(True, 0)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geoterrain.globe.deeperrors import DeeperLevels
from geoterrain.globe.nodes import children, decode, encode, geometry, hull, node_widths, parent
from geoterrain.globe.noise import error_bound, height_range_bound
from geoterrain.globe.payload import Payload, payload_from_values
from geoterrain.globe.polyhedron import FACES, face_coordinates
from geoterrain.globe.ranges import MORPH_FRACTION, SAFE, morph_error, ranges_from, settle
from geoterrain.globe.surface import NodeKey, Surface

__all__ = ["ErrorTable", "NodeError", "node_widths", "ranges", "ranges_from", "morph_error",
           "MORPH_FRACTION"]



@dataclass(frozen=True)
class NodeError:
    """A measured node: its error ``e``, its move ``move`` (M), the relative ``slack`` of
    the chain, its vertices' radial range ``r_lo``, ``r_hi`` and ``sag``; ``lattice`` the
    chain's bound against the deepest lattice and ``samples`` its largest gap to the stores'
    own samples (``e`` is the larger); ``fine`` (at the measured depth, under the finest
    store): its samples' gradient spreads G_e, G_m and steepest slope (:meth:`ErrorTable.fine`)
    and the steepest slope its deeper nodes can have (:meth:`ErrorTable.tables`)."""

    e: float
    move: float
    slack: float
    r_lo: float
    r_hi: float
    sag: float
    lattice: float = 0.0
    samples: float = 0.0
    core: bool = False
    fine: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


class ErrorTable(DeeperLevels):
    """Every node's error bound and the per-depth maxima (module docstring).

    Attributes (arrays over depth 0 … ``max_depth``): ``e`` (largest error), ``move`` (largest
    M), ``slack`` (largest s), ``diag`` (largest bounding-volume diagonal, heights included:
    seed 001 L407), ``cell`` (largest cell diameter); ``regions`` the number of measured
    nodes; ``r_min``, ``r_max`` the least and greatest distance of any point from the centre.
    """

    def __init__(self, surface: Surface, progress: Callable[[int, int], None] | None = None,
                 keep: Callable[[Payload], None] | None = None):
        self.surface = s = surface
        self.max_depth = Dm = s.max_depth
        self.measured_depth = s.measured_depth
        self.nodes: dict[NodeKey, NodeError] = {}
        rho = s.model.min_curvature_radius
        planet = s.base.planet if s.base.kind == "procedural" else None
        span = self._height_span()
        self.h_lo, self.h_hi = span
        self.r_min = s.model.b + span[0]
        self.r_max = s.model.a + span[1]
        w = node_widths(Dm)  # node corner chords, unit sphere
        wc = node_widths(Dm, s.k)  # cell corner chords
        # the base layer (or a pure-chord node) everywhere: analytic
        rc = wc * self.r_max / math.sqrt(3) * 1.02  # ≥ a triangle's circumradius (or half
        # its longest edge): the long diagonal / √3 ≥ it for the RT's cells
        base_e = np.array([error_bound(planet, rc[D], rho, s.scale) if s.base_present and
                           D <= s.base_depth else 0.0 for D in range(Dm + 1)])
        self.base_e = base_e
        self.e = base_e.copy()
        self.move = np.zeros(Dm + 1)
        self.slack = np.full(Dm + 1, 1e-3)
        self.slope = self._base_slope(planet, wc)
        self.regions = 0
        self._truth = self._store_samples()
        self._grad = self._gradients()
        self._measure(progress, keep)
        Dq = self.measured_depth
        if Dm > Dq:  # beyond: the finest store's core, sampled; elsewhere chords (copies)
            self.slack[Dq + 1:] = self.slack[Dq]
        # the nodes no one measured (the base layer, or copies beyond every layer's depth):
        # their radial extent bounds heights over the node, the ellipsoid's own change across
        # it, twice the error, the move and the sag of its triangles
        self.width = w * self.r_max
        ell = (s.model.a - s.model.b) * w
        relief = np.array([height_range_bound(planet, w[D] * self.r_max, s.scale)
                           if s.base_present else 0.0 for D in range(Dm + 1)])
        relief = np.maximum(relief, self.slope * w * self.r_max)
        sag = self.r_max * (1 - np.cos(np.minimum(wc, 2.0)))
        self.other_e = base_e.copy()
        self.other_move = np.zeros(Dm + 1)
        if s.base_present:
            self.other_move[1:s.base_depth + 1] = self.e[:s.base_depth][:Dm]
        extent = ell + relief + 2 * self.other_e + self.other_move + sag
        self.other_diag = (self.width + extent) * 1.01
        if Dm > Dq:  # (the deeper nodes' own extent: :meth:`tables`, per view)
            self.slope[Dq + 1:] = max([float(self.slope[Dq])] + [ne.fine[3] for ne in
                                                                 self.nodes.values()])
        self._ell = ell
        self.cell = np.sqrt((wc * self.r_max) ** 2 + (self.slope * wc * self.r_max) ** 2) \
            * 1.01
        self._region_arrays()
        self._deep_setup()
        e_all, mv_all, _, self.diag, _ = self.tables()
        self.e[Dq + 1:] = e_all[Dq + 1:]
        self.move[Dq + 1:] = mv_all[Dq + 1:]

    # ------------------------------------------------------------------ pieces
    def _height_span(self) -> tuple[float, float]:
        """The least and greatest height (metres, exaggerated) any layer can give."""
        s = self.surface
        lo, hi = 0.0, 0.0
        for st in s.stores:
            rng = st.terrain.meta.get("height_range") or [0.0, 0.0]
            z = st.terrain.frame.z(np.asarray(rng, np.float64))
            lo, hi = min(lo, float(z.min())), max(hi, float(z.max()))
        if s.base_present and s.base.kind == "procedural":
            m = s.base.planet.max_abs()
            lo, hi = min(lo, -m), max(hi, m)
        return lo * s.scale, hi * s.scale

    def _base_slope(self, planet, wc) -> np.ndarray:
        s = self.surface
        out = np.zeros(self.max_depth + 1)
        if s.base_present and planet is not None:
            for D in range(self.max_depth + 1):
                width = wc[D] * self.r_max
                out[D] = height_range_bound(planet, width, s.scale) / max(width, 1e-9)
        return out

    def _store_samples(self) -> tuple[np.ndarray, ...] | None:
        """Every store sample the globe shows unblended (a finer store's edge or data not
        over it), placed as the data say (geodetic lon, lat, height → ECEF): its face, u, v,
        |p| of its ray's flat face point and its distance from the centre."""
        s = self.surface
        out, deep = [], []
        for k, st in enumerate(s.stores):  # finest first
            finer = s.stores[:k]
            for lon, lat, h in st.samples():
                if finer:
                    over = np.zeros(lon.shape, bool)
                    for f in finer:
                        over |= s.weight(f, lon, lat) > 0
                    lon, lat, h = lon[~over], lat[~over], h[~over]
                if not len(lon):
                    continue
                P = s.model.to_ecef(lon, lat, h * s.scale)
                r = np.linalg.norm(P, axis=-1)
                face, u, v, fn = face_coordinates(P / r[:, None])
                out.append((face, u, v, fn, r))
                if st is s.fine:  # where every deeper triangle over it samples the store
                    with np.errstate(invalid="ignore"):
                        deep.append(st.edge_samples(lon, lat) >= s.fine_border)
                else:
                    deep.append(np.zeros(len(lon), bool))
        if not out:
            self._deep_mask = None
            return None
        self._deep_mask = np.concatenate(deep)
        return tuple(np.concatenate(a) for a in zip(*out, strict=True))

    def _sample_index(self, depth: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The store samples sorted by the depth-``depth`` node holding them: (their order,
        the sorted node keys)."""
        if self._truth is None:
            return None
        face, u, v = self._truth[:3]
        m = 1 << depth
        x = np.clip(np.floor(u * m), 0, m - 1).astype(np.int64)
        y = np.clip(np.floor(v * m), 0, m - 1).astype(np.int64)
        keys = encode(face, depth, x, y)
        order = np.argsort(keys, kind="stable")
        return order, keys[order]

    def _sample_gap(self, key: int, v, index) -> float:
        """The largest radial gap between node ``key``'s drawn surface (its flat triangles,
        unmorphed) and the store samples on its rays: measured at each sample, where the
        ray's w = |p|/r is affine over the flat triangle seen from the centre."""
        if index is None:
            return 0.0
        order, skeys = index
        a, b = np.searchsorted(skeys, [key, key + 1])
        if a == b:
            return 0.0
        sel = order[a:b]
        _, u, vv, fn, r = (arr[sel] for arr in self._truth)
        _, D, x, y = decode(key)
        n = self.surface.n
        uu = (u * (1 << D) - x) * n
        wv = (vv * (1 << D) - y) * n
        j = np.clip(np.floor(uu), 0, n - 1).astype(np.int64)
        i = np.clip(np.floor(wv), 0, n - 1).astype(np.int64)
        fu, fv = uu - j, wv - i
        inn = v.inner
        w = v.fn[inn] / v.r[inn]
        lower = fu + fv <= 1.0  # the cell's triangle on the (i, j) side of its short diagonal
        wm = np.where(lower, (1 - fu - fv) * w[i, j] + fu * w[i, j + 1] + fv * w[i + 1, j],
                      (fu + fv - 1) * w[i + 1, j + 1] + (1 - fv) * w[i, j + 1]
                      + (1 - fu) * w[i + 1, j])
        gap = np.abs(fn / wm - r)
        return float(gap.max()) * SAFE

    def _core(self, v) -> bool:
        """Whether the node shows one store unblended at every vertex (its weight 1, no
        finer store's over it, data at each): there the truth is that store's samples."""
        s = self.surface
        inn = v.inner
        if self._truth is None or not v.store[inn].all():
            return False
        lon, lat = v.lon[inn], v.lat[inn]
        for st in s.stores:  # finest first
            w = s.weight(st, lon, lat)
            if (w >= 1.0).all():
                return True
            if (w > 0).any():
                return False
        return False

    def _rings(self):
        """Per store: the depth its footprint matters to, its outline as unit ray directions
        and their spacing (radians); and its feather band's inner outline with the depth that
        matters to (the deepest: layers blended there change at every depth)."""
        s = self.surface
        out = []
        for st, D in zip(s.stores, s.resolved, strict=True):
            lim = max(D, s.base_depth) if s.base_present else D
            if st.covers_globe():
                out.append((st, lim, None, 0.0, None))
                continue
            rings = []
            for inset in (0.0, st.feather):
                lon, lat = st.footprint(256, inset)
                P = s.model.to_ecef(lon, lat, np.zeros_like(lon))
                d = P / np.linalg.norm(P, axis=-1)[:, None]
                step = float(np.arccos(np.clip(np.einsum("ij,ij->i", d, np.roll(d, -1, 0)),
                                               -1, 1)).max())
                rings.append((d, step))
            out.append((st, lim, rings[0], st.feather > 0, rings[1]))
        return out

    def _meets(self, keys: np.ndarray, rings) -> np.ndarray:
        """Which nodes matter to a store at their depth (conservative): their cone meets its
        footprint (an outline point within an outline spacing of the cone, or a node corner
        or centre inside the footprint) down to the store's depth, or meets its feather band
        down to the deepest depth."""
        _, D, _, _ = decode(keys)
        g = geometry(keys)
        pts = np.concatenate([g.dirs, g.centre[:, None]], 1)  # (N, 5, 3)
        _, lon, lat = self.surface.model.surface(pts)
        out = np.zeros(len(keys), bool)

        def near(ring, ok):
            d, step = ring
            side = np.einsum("nkj,mj->nmk", g.planes[ok], d)  # ≤ 0 inside
            hit = np.zeros(len(keys), bool)
            hit[ok] = (side <= math.sin(step) + 1e-12).all(2).any(1)
            return hit

        for st, lim, outer, banded, inner in rings:
            if outer is None:
                out |= D <= lim
                continue
            meets = near(outer, np.ones(len(keys), bool)) | st.covers(lon, lat).any(1)
            out |= meets & (D <= lim)
            if banded:
                band = near(outer, meets) | near(inner, meets) | st.in_band(lon, lat).any(1)
                out |= meets & band & (D <= self.measured_depth)
        return out

    def _measure(self, progress, keep) -> None:
        """Generate every node that meets a footprint, deepest first, and set its error."""
        s = self.surface
        if not s.stores:
            return
        rings = self._rings()
        levels: list[np.ndarray] = []
        cur = encode(np.arange(FACES), 0, 0, 0)
        cur = cur[self._meets(cur, rings)]
        while len(cur):
            levels.append(cur)
            D = len(levels) - 1
            if D >= self.measured_depth:
                break
            kids = children(cur).reshape(-1)
            cur = kids[self._meets(kids, rings)]
        total = sum(len(v) for v in levels)
        done = 0
        below: dict[int, NodeError] = {}
        for D in range(len(levels) - 1, -1, -1):
            here: dict[int, NodeError] = {}
            index = self._sample_index(D)
            for key in levels[D].tolist():
                v = s.values(decode(key))
                p = payload_from_values(s, v, normals=keep is not None)
                if keep is not None:
                    keep(p)
                e = 0.0
                if D < self.measured_depth:
                    for c in children(np.array([key]))[0].tolist():
                        ce = below.get(c)
                        if ce is None and self.base_e[D + 1] > 0:
                            # a base node beside the stores: its move onto this node's
                            # surface measured, its own error the base layer's bound
                            cp = payload_from_values(s, s.values(decode(c)), normals=False)
                            ce = NodeError(float(self.base_e[D + 1]), cp.move, cp.slack,
                                           cp.r_lo, cp.r_hi, cp.sag,
                                           float(self.base_e[D + 1]))
                            self.move[D + 1] = max(self.move[D + 1], cp.move)
                            self.slack[D + 1] = max(self.slack[D + 1], cp.slack)
                        # (else beyond every truth depth: an exact copy; and where a
                        # child shows one store unblended its truth is that store's
                        # samples, which this node's own gap measures)
                        if ce is not None and not ce.core:
                            e = max(e, (1 + ce.slack) * ce.move + ce.lattice)
                gap = self._sample_gap(key, v, index)
                ne = NodeError(max(e, gap), p.move, p.slack, p.r_lo, p.r_hi, p.sag, e, gap,
                               self._core(v), (0.0, 0.0, 0.0, 0.0))
                if D == self.measured_depth:
                    ge, gm, sl = self.fine(v)
                    # a deeper node's steepest slope: its flat triangles interpolate f (≤ 1.5
                    # its slope on the RT's near-square cells), or lie on this node's (whose
                    # edges rise at most p.slope: its gradient ≤ 2.5 that)
                    steep = 1.5 * sl if ne.core else max(1.5 * sl, 2.5 * p.slope)
                    ne = NodeError(ne.e, ne.move, ne.slack, ne.r_lo, ne.r_hi, ne.sag,
                                   ne.lattice, ne.samples, ne.core, (ge, gm, sl, steep))
                e = ne.e
                here[key] = ne
                self.nodes[decode(key)] = ne
                self.e[D] = max(self.e[D], e)
                self.move[D] = max(self.move[D], p.move)
                self.slack[D] = max(self.slack[D], p.slack)
                self.slope[D] = max(self.slope[D], p.slope)
                done += 1
                if progress is not None:
                    progress(done, total)
            below = here
        self.regions = total
        if s.base_present:  # a base node's move onto its parent: at most the parent's error
            for D in range(1, min(s.base_depth, self.max_depth) + 1):
                self.move[D] = max(self.move[D], self.e[D - 1])

    def _region_arrays(self) -> None:
        """The measured nodes as arrays: keys, depth, e, move, slack, radial range of their
        volumes, their hulls' corners, their parents' index (−1 for a root) and diameter."""
        items = sorted(self.nodes.items(), key=lambda kv: kv[0][1])
        n = len(items)
        keys = np.array([encode(*k) for k, _ in items], np.int64).reshape(n)
        self.region_keys = keys
        self.region_depth = np.array([k[1] for k, _ in items], np.int64).reshape(n)
        ne = [v for _, v in items]
        self.region_e = np.array([v.e for v in ne]).reshape(n)
        self.region_move = np.array([v.move for v in ne]).reshape(n)
        self.region_slack = np.array([v.slack for v in ne]).reshape(n)
        self.region_fine = np.array([v.fine for v in ne]).reshape(n, 4)
        lo = np.array([v.r_lo - v.e - v.sag for v in ne]).reshape(n)
        hi = np.array([v.r_hi + v.e for v in ne]).reshape(n)
        self.region_lo, self.region_hi = lo, hi
        if n:
            g = geometry(keys)
            self.region_geometry = g
            self.region_corners = hull(g, lo, hi)[0]
            chord = np.maximum(np.linalg.norm(g.dirs[:, 0] - g.dirs[:, 2], axis=-1),
                               np.linalg.norm(g.dirs[:, 1] - g.dirs[:, 3], axis=-1))
            self.region_diag = (hi * chord + (hi - lo)) * 1.01
            pos = {int(k): i for i, k in enumerate(keys.tolist())}
            self.region_parent = np.array([pos.get(int(p), -1) for p in
                                           parent(keys).tolist()], np.int64)
            self.region_parent[self.region_depth == 0] = -1
        else:
            self.region_diag = np.zeros(0)
            self.region_parent = np.zeros(0, np.int64)

    def _per_depth(self, values: np.ndarray, sel: np.ndarray) -> np.ndarray:
        out = np.zeros(self.max_depth + 1)
        if sel.any():
            np.maximum.at(out, self.region_depth[sel], values[sel])
        return out

    def tables(self, sel: np.ndarray | None = None, deep: tuple[np.ndarray, ...] | None = None
               ) -> tuple[np.ndarray, ...]:
        """Per depth (e, move, slack, diag, cell) over the unmeasured nodes and the measured
        nodes ``sel`` (a mask over them; None: all). Beyond the measured depth: the bound
        from the gradient spreads over ``sel``'s deepest nodes (:meth:`fine_errors`), or, given
        ``deep`` = per depth (e, M, steepest slope) (:meth:`_deep_table`), those."""
        if sel is None:
            sel = np.ones(self.regions, bool)
        e = np.maximum(self.other_e, self._per_depth(self.region_e, sel))
        mv = np.maximum(self.other_move, self._per_depth(self.region_move, sel))
        sl = np.maximum(1e-3, self._per_depth(self.region_slack, sel))
        dg = np.maximum(self.other_diag, self._per_depth(self.region_diag, sel))
        Dq = self.measured_depth
        if self.max_depth > Dq:
            sl[Dq + 1:] = np.maximum(sl[Dq + 1:], sl[Dq])
            f = self.region_fine[sel & (self.region_depth == Dq)]
            if deep is not None or len(f):
                if deep is None:
                    ge, gm, fs, steep = f.max(0)
                    ee, em = self.fine_errors(ge, gm, fs)
                else:
                    ee, em, steep = deep
                    steep = steep[Dq + 1:]
                e = np.maximum(e, ee)
                mv = np.maximum(mv, em)
                w = self.width[Dq + 1:]
                sag = self.r_max * (1 - np.cos(np.minimum(self.width[Dq + 1:] / self.r_max,
                                                          2.0)))
                dg[Dq + 1:] = np.maximum(dg[Dq + 1:], 1.01 * (
                    np.hypot(w, steep * w) + self._ell[Dq + 1:] + sag
                    + 2 * e[Dq + 1:] + mv[Dq + 1:]))
        return e, mv, sl, dg, self.cell

    def view_ranges(self, view, lam: float, tau: float, fraction: float = MORPH_FRACTION,
                    occluder=None, frustum: bool = True, measure: int | None = None
                    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Ranges for one view: :func:`ranges` over the nodes this view could draw.

        A measured node can be drawn only if the frustum (and the horizon) leave it and its
        parent meets its depth's sphere, dist(parent) < R_{D−1}. Ranges from all measured
        nodes draw a subset of those; ranges from that subset draw another; … until a fixed
        point, or a cycle (a coarser range can grow when a finer one's table shrinks, so two
        sets can draw each other in turn: a flight's frames met one at 0.7–1.9 Mm up and
        ran 64 sets), and the ranges kept are the last whose set holds every node they draw
        (:func:`~geoterrain.globe.ranges.settle`): the constraints hold for it.
        Returns (R, m, |A|). ``measure``: the store samples one job may measure beyond the
        measured depth, off this frame, of what it asked for (None: all it needs, now;
        :meth:`~geoterrain.globe.deeperrors.DeeperLevels.deep_errors`).
        What an earlier frame's job measured is kept before the ranges are made.
        """
        self.collect_measures()
        self.measuring(measure)
        try:
            out = self._view_ranges(view, lam, tau, fraction, occluder, frustum)
            self.measure_off_frame()
            return out
        finally:
            self.measuring(None)  # a call outside a view measures all it needs

    def _view_ranges(self, view, lam, tau, fraction, occluder, frustum):
        from geoterrain.globe.nodes import OUTSIDE, frustum_state, horizon_hidden, shell_distance

        if not self.regions:
            R, m = ranges_from(self.tables(), self.max_depth, lam, tau, fraction, self.r_min)
            return R, m, 0
        vis = np.ones(self.regions, bool)
        if frustum:
            vis &= frustum_state(view.planes, self.region_corners) != OUTSIDE
        if occluder is not None:
            vis &= ~horizon_hidden(occluder, view.eye, self.region_corners)[0]
        par = self.region_parent
        has = par >= 0
        g = self.region_geometry
        pdist = np.zeros(self.regions)
        pp = par[has]
        pdist[has] = shell_distance(view.eye, type(g)(g.dirs[pp], g.planes[pp], g.centre[pp],
                                                      g.cmin[pp]),
                                    self.region_lo[pp], self.region_hi[pp])
        A = vis.copy()
        Dq = self.measured_depth
        own = np.full(self.regions, np.inf)  # the eye's distance to each deepest measured node
        last = self.region_depth == Dq
        if self.max_depth > Dq and last.any():
            gl = type(g)(g.dirs[last], g.planes[last], g.centre[last], g.cmin[last])
            own[last] = shell_distance(view.eye, gl, self.region_lo[last], self.region_hi[last])
        D = self.region_depth

        def drawn(Rm):
            return vis & (~has | (pdist < Rm[0][np.maximum(D - 1, 0)]))

        (R, m), A = settle(lambda A: self._deep_ranges(A, own, lam, tau, fraction), drawn, A)
        return R, m, int(A.sum())

    # -------------------------------------------------------------------- API
    def node(self, key: NodeKey) -> tuple[float, float]:
        """(e, M) of node ``key``: measured, or the base layer's bound at its depth."""
        ne = self.nodes.get(tuple(key))
        if ne is not None:
            return ne.e, ne.move
        D = key[1]
        if D > self.measured_depth:
            return float(self.e[D]), float(self.move[D])
        return float(self.base_e[D]), float(self.base_e[D - 1]) if D > 0 and \
            self.base_e[D] > 0 else 0.0


def ranges(tb: ErrorTable, lam: float, tau: float, fraction: float = MORPH_FRACTION
           ) -> tuple[np.ndarray, np.ndarray]:
    """View ranges R_D and morph starts m_D, D = 0 … max depth (R_max = 0: leaves are never
    refined; m_0 = ∞: roots never morph).

    A node of depth D is refined when its volume meets the sphere of radius R_D around the
    eye. Each R_{D−1} is the smallest value meeting, with f = ``fraction``:

    - R_{D−1} ≥ (λ/τ + 1)·e_{D−1} (a depth-(D − 1) node is drawn beyond R_{D−1}; the
      measure divides by the eye's distance to the truth, which can be e nearer);
    - (1 − f)(R_{D−1} − R_D) ≥ diag_D (seed 001 L407: one whole node fits each range, so
      neighbours differ by one level at most and a node's vertices never reach the coarser
      level's morph band);
    - m_D − c_D − M_D ≥ (λ/τ + 1)·ε_D, m_D = (1 − f)R_{D−1} + f·R_D (once a vertex morphs,
      its triangles are off by at most ε_D, :func:`morph_error`, and they lie beyond m_D
      less a cell c_D and the move).

    Examples
    --------
    >>> from geoterrain.globe.model import Model
    >>> from geoterrain.globe.layers import BaseLayer
    >>> from geoterrain.globe.surface import Surface
    >>> tb = ErrorTable(Surface(Model.get("sphere"), [], BaseLayer.procedural(), node_cells=16))
    >>> R, m = ranges(tb, 1000.0, 1.0)
    >>> bool(np.all(np.diff(R) < 0)), float(R[-1]), bool(np.isinf(m[0]))
    (True, 0.0, True)
    """
    return ranges_from(tb.tables(), tb.max_depth, lam, tau, fraction, tb.r_min)
