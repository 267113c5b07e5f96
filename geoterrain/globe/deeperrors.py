"""The levels beyond the measured depth of the globe's error tables, where the finest store
is sampled on in its core (:meth:`geoterrain.globe.surface.Surface.fine_points`): their
errors measured per region, their moves bounded from the samples' gradient, and the view
ranges that use them. :class:`DeeperLevels` holds these methods of
:class:`geoterrain.globe.errors.ErrorTable`, which mixes it in.

- **Measured per region** (:meth:`DeeperLevels.deep_errors`): per measured-depth node and
  deeper depth, the largest gap of the deeper triangles to the store samples in it, each
  rebuilt from its three vertices when a view first needs it, then kept; a frame of the
  flight has them measured off it, on a thread of its own, and bounds them meanwhile.
- **Bounded** (:meth:`DeeperLevels.fine_errors`): a triangle whose vertices lie on the
  bilinear surface f misses f by at most G·R_c (G the spread of ∇f over its cells, R_c its
  circumradius); a vertex's morph onto its coarser neighbours' chord by G·|AB|/2.
- **Ranges** (:meth:`DeeperLevels._deep_ranges`): each depth's table over the nodes that
  depth can be drawn under, iterated while the ranges shrink (each such iterate is sound).
"""

from __future__ import annotations

import math

import numpy as np

from geoterrain.globe.nodes import encode
from geoterrain.globe.polyhedron import face_coordinates, face_points
from geoterrain.globe.ranges import SAFE, ranges_from


class DeeperLevels:
    """The deep-level methods of :class:`geoterrain.globe.errors.ErrorTable` (a mixin: it
    reads the table's surface, depths, regions and store samples)."""

    def _gradients(self):
        """The finest store's bilinear surface f, as the deepest levels sample it: per block of
        br × bc sample cells, G = the half-spread of ∇f over the block (|∇f − g| ≤ G for g the
        middle of its range: hypot of the half-ranges of ∂f/∂x and ∂f/∂y, which over a cell
        run between its two edges' differences), for the blocks a triangle of the first
        level beyond the measured one fits in (``e``) and those a coarser cell's long
        diagonal fits in (``m``: the morph's chords at that level); and each cell's steepest
        |∇f|. Metres per metre (the store's least ground steps, exaggerated heights)."""
        s = self.surface
        st = s.fine
        if st is None or self.max_depth <= self.measured_depth:
            return None
        from numpy.lib.stride_tricks import sliding_window_view as win

        sx, sy = st.ground_steps()
        H = st.full_heights() * s.scale
        dx = np.diff(H, axis=1) / sx  # (R, C − 1): ∂f/∂x along each row's cell edge
        dy = np.diff(H, axis=0) / sy  # (R − 1, C)
        Dq = self.measured_depth

        def spread(L):
            br, bc = int(L / sy) + 2, int(L / sx) + 2  # a set this wide fits br × bc cells
            br, bc = min(br, H.shape[0] - 1), min(bc, H.shape[1] - 1)
            wx, wy = win(dx, (br + 1, bc)), win(dy, (br, bc + 1))
            rx = wx.max(axis=(-2, -1)) - wx.min(axis=(-2, -1))
            ry = wy.max(axis=(-2, -1)) - wy.min(axis=(-2, -1))
            return np.hypot(rx / 2, ry / 2), (br, bc)

        ge, be = spread(s.cell_chord[Dq + 1])
        gm, bm = spread(s.cell_chord[Dq])
        ax = np.maximum(np.abs(dx[:-1]), np.abs(dx[1:]))
        ay = np.maximum(np.abs(dy[:, :-1]), np.abs(dy[:, 1:]))
        return ge, be, gm, bm, np.hypot(ax, ay)

    def fine(self, v) -> tuple[float, float, float]:
        """A measured-depth node's (G_e, G_m, steepest slope) over the finest store's blocks
        its footprint (one cell more each way) can hold a deeper triangle or chord in
        (:meth:`_gradients`); zeros where the store does not reach it."""
        if self._grad is None:
            return (0.0, 0.0, 0.0)
        st = self.surface.fine
        inn = v.inner
        lon, lat = v.lon[inn].ravel(), v.lat[inn].ravel()
        if not st.covers(lon, lat).any():
            return (0.0, 0.0, 0.0)
        ri, cj = st.grid_coords(lon, lat)
        ok = np.isfinite(ri) & np.isfinite(cj)
        if not ok.any():
            return (0.0, 0.0, 0.0)
        r0, r1 = int(np.floor(ri[ok].min())) - 1, int(np.floor(ri[ok].max())) + 1
        c0, c1 = int(np.floor(cj[ok].min())) - 1, int(np.floor(cj[ok].max())) + 1
        ge, be, gm, bm, sl = self._grad

        def top(a, b):
            i0, j0 = max(r0 - b[0] + 1, 0), max(c0 - b[1] + 1, 0)
            i1, j1 = min(r1, a.shape[0] - 1), min(c1, a.shape[1] - 1)
            return float(a[i0:i1 + 1, j0:j1 + 1].max()) if i1 >= i0 and j1 >= j0 else 0.0

        return top(ge, be), top(gm, bm), top(sl, (1, 1))

    def _deep_setup(self) -> None:
        """The store samples beyond ``fine_border`` of the finest store's edge (the truth
        of the levels beyond the measured depth), sorted by the measured-depth node holding
        them, and an empty cache of those nodes' measured deeper errors
        (:meth:`deep_errors`)."""
        Dq, Dm = self.measured_depth, self.max_depth
        self._deep_cache = np.full((self.regions, Dm + 1), np.nan)
        self._deep_samples = None
        self._deep_left = math.inf  # a frame's measuring job's samples (inf: measure now)
        self._deep_asked = np.zeros((self.regions, Dm + 1), bool)  # in the job off the frame
        self._deep_wanted: list[tuple[int, np.ndarray]] = []  # (depth, regions) this frame
        self._deep_job = None  # the measuring job running off the frame (a Future)
        self._deep_pool = None
        if Dm <= Dq or self._truth is None or self._deep_mask is None or not self.regions:
            return
        face, u, v = self._truth[:3]
        idx = np.flatnonzero(self._deep_mask)
        m = 1 << Dq
        x = np.clip(np.floor(u[idx] * m), 0, m - 1).astype(np.int64)
        y = np.clip(np.floor(v[idx] * m), 0, m - 1).astype(np.int64)
        keys = encode(face[idx], Dq, x, y)
        order = np.argsort(self.region_keys)
        sk = self.region_keys[order]
        pos = np.clip(np.searchsorted(sk, keys), 0, len(sk) - 1)
        found = sk[pos] == keys  # (all of them: every node over a store is measured)
        reg = order[pos[found]]
        o = np.argsort(reg, kind="stable")
        self._deep_samples = idx[found][o]
        reg = reg[o]
        every = np.arange(self.regions)
        self._deep_start = np.searchsorted(reg, every)
        self._deep_end = np.searchsorted(reg, every, "right")
        # how much nearer a deeper node can lie than its measured-depth ancestor's volume:
        # its vertices lie on f, within a sample's diagonal of one of the ancestor's samples
        # (which lie within e of its surface), so within slope × diagonal of its range
        diag = math.hypot(*self.surface.fine.ground_steps()) * 1.1
        self._deep_margin = self.region_e + self.region_fine[:, 2] * diag \
            + float(self.e[Dq + 1]) + self._ell[Dq]

    def deep_errors(self, regions: np.ndarray, depth: int) -> np.ndarray:
        """Measured, per measured-depth node in ``regions`` (indices into the region
        arrays), the largest radial gap between the drawn surface of its depth-``depth``
        descendants (flat triangles whose vertices sample the store's bilinear surface f:
        :meth:`~geoterrain.globe.surface.Surface.fine_points`) and the store's samples in
        it beyond ``fine_border`` (0 where it holds none): each sample's triangle at that
        depth rebuilt from its three vertices, as :meth:`_sample_gap` measures a generated
        node. Computed once per (node, depth), then kept.

        Outside a frame (:meth:`measuring` None: a converged view, or a call of its own)
        the nodes not yet measured are measured now. In a frame they are measured off it:
        the frame asks for them (:meth:`measure_off_frame` starts one job of at most a
        frame's budget of samples on a thread of its own, :meth:`collect_measures` keeps
        what it measured at the start of a later frame) and meanwhile gets, for this call
        only, the bound :meth:`fine_errors` gives from their own gradient spread: a larger
        error, so sound ranges."""
        regions = np.asarray(regions, np.int64)
        out = self._deep_cache[regions, depth]
        todo = np.unique(regions[np.isnan(out)])
        if not len(todo):
            return out
        if math.isinf(self._deep_left):
            self._deep_cache[todo, depth] = self._deep_measure(todo, depth)
            return self._deep_cache[regions, depth]
        self._deep_wanted.append((depth, todo[~self._deep_asked[todo, depth]]))
        # not measured yet: G·R_c and the curvature (fine_errors)
        c = float(self.surface.cell_chord[depth])
        ge, fs = self.region_fine[todo, 0], self.region_fine[todo, 2]
        bound = np.full(self.regions, np.nan)
        bound[todo] = 1.05 * ge * c / math.sqrt(3) + (1 + fs) * c ** 2 / self.r_min
        return np.where(np.isnan(out), bound[regions], out)

    def _deep_measure(self, todo: np.ndarray, depth: int) -> np.ndarray:
        """The kept value of :meth:`deep_errors` for regions ``todo`` at ``depth`` (reads
        only what the table was built with: safe on a thread of its own)."""
        n = self._deep_end[todo] - self._deep_start[todo]
        val = np.zeros(len(todo))
        if n.sum():
            first = np.repeat(self._deep_start[todo] - np.cumsum(n) + n, n)
            idx = self._deep_samples[first + np.arange(int(n.sum()))]
            gaps = self._deep_gaps(tuple(a[idx] for a in self._truth), depth)
            np.maximum.at(val, np.repeat(np.arange(len(todo)), n), gaps)
        return val * SAFE

    def measuring(self, samples: float | None) -> None:
        """The samples one measuring job of the next view may take beyond the measured
        depth (a frame's budget), or None: measure every one it needs at once, as a
        converged view does."""
        self._deep_left = math.inf if samples is None else float(samples)
        self._deep_wanted = []

    def collect_measures(self, wait: bool = False) -> int:
        """Keep what the measuring job off the frame measured, if it is done (``wait``: wait
        for it); returns how many (node, depth) values it kept. A frame calls this before
        its ranges, so one view's ranges see one table."""
        job = self._deep_job
        if job is None or not (wait or job.done()):
            return 0
        self._deep_job = None
        kept = 0
        for depth, todo, val in job.result():  # (its errors raise here)
            self._deep_cache[todo, depth] = val
            self._deep_asked[todo, depth] = False
            kept += len(todo)
        return kept

    def measure_off_frame(self) -> int:
        """Start measuring, on a thread of its own, what this frame asked for and found
        unmeasured (:meth:`deep_errors`), nearest depth first, up to the frame's budget of
        samples (one node at least), unless a job is still running; returns the samples
        it took."""
        wanted, self._deep_wanted = self._deep_wanted, []
        if self._deep_job is not None or not wanted or math.isinf(self._deep_left):
            return 0
        left, work = self._deep_left, []
        for depth, todo in wanted:
            todo = todo[~self._deep_asked[todo, depth]]
            if not len(todo) or left <= 0 and work:
                continue
            n = self._deep_end[todo] - self._deep_start[todo]
            take = np.cumsum(n) <= left
            take[0] |= not work  # (one node, however large)
            todo = todo[take]
            left -= float(n[take].sum())
            self._deep_asked[todo, depth] = True
            work.append((depth, todo))
        if not work:
            return 0
        if self._deep_pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._deep_pool = ThreadPoolExecutor(1, thread_name_prefix="globe-measure")
        self._deep_job = self._deep_pool.submit(
            lambda: [(d, t, self._deep_measure(t, d)) for d, t in work])
        return int(self._deep_left - left)

    def close(self) -> None:
        """Stop the measuring thread (its job's results are dropped)."""
        if self._deep_pool is not None:
            self._deep_pool.shutdown(wait=True, cancel_futures=True)
            self._deep_pool = None
        self._deep_job = None
        self._deep_asked[:] = False

    def deep_gaps(self, points: np.ndarray, depth: int) -> np.ndarray:
        """The radial gap between ECEF ``points`` (N, 3) (store samples in the finest
        store's core) and the depth-``depth`` (> the measured depth) triangle on each one's
        ray, its three vertices on the store's bilinear surface f, placed as
        :meth:`~geoterrain.globe.surface.Surface.values` places them."""
        P = np.asarray(points, np.float64).reshape(-1, 3)
        r = np.linalg.norm(P, axis=-1)
        face, u, v, fn = face_coordinates(P / r[:, None])
        return self._deep_gaps((face, u, v, fn, r), depth)

    def _deep_gaps(self, pts: tuple[np.ndarray, ...], depth: int) -> np.ndarray:
        s = self.surface
        face, u, vv, fn, r = pts
        m = float(1 << (depth + s.k))
        U, V = u * m, vv * m
        j, i = np.floor(U), np.floor(V)
        fu, fv = U - j, V - i
        lower = (fu + fv <= 1.0)[:, None]
        # the cell's triangle on the (i, j) side of its short diagonal, or the other one
        vi = np.where(lower, np.stack([i, i, i + 1], -1), np.stack([i + 1, i, i + 1], -1))
        vj = np.where(lower, np.stack([j, j + 1, j], -1), np.stack([j + 1, j + 1, j], -1))
        wt = np.where(lower, np.stack([1 - fu - fv, fu, fv], -1),
                      np.stack([fu + fv - 1, 1 - fv, 1 - fu], -1))
        F = face_points(np.broadcast_to(face[:, None], vi.shape), vj / m, vi / m)
        fv_n = np.linalg.norm(F, axis=-1)
        d = F / fv_n[..., None]

        def hf0(lo, la):
            return s.layer_heights(s.fine, lo, la, s.max_depth)

        rv = s.model.place(d, hf0, first=s.model.surface(d))[0]
        rv = s.model.settle(d, rv, hf0)
        wm = (wt * (fv_n / rv)).sum(-1)
        return np.abs(fn / wm - r)

    def fine_errors(self, ge: float, gm: float, slope: float
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Per depth beyond the measured one, (e, M) of the finest store's core, from the
        gradient spreads G_e, G_m and slope of its samples there (0 above).

        A triangle whose vertices lie on the bilinear surface f misses f at any point P of
        it (a sample among them) by |Σλᵢ(f(vᵢ) − f(P) − g·(vᵢ − P))| ≤ G·Σλᵢ|vᵢ − P| ≤ G·R_c
        (Σλᵢ|vᵢ − P|² = R_c² − |P − O|², O and R_c its circumcentre and circumradius:
        R_c ≤ the cell's long diagonal/√3 on the RT's lattice), with G the spread of ∇f
        over the cells it lies in. An odd vertex's move onto the chord of its coarser
        neighbours A, B (which carry f too: :meth:`~geoterrain.globe.surface.Surface.fine_points`)
        is |f(P) − (f(A) + f(B))/2| ≤ G·|AB|/2. Radial rather than vertical gaps, flat
        triangles rather than the curved surface, and the ground steps' spread over the
        store add at most 5 % and (1 + slope)·c²/r_min (c the cell's long diagonal)."""
        s = self.surface
        Dq, Dm = self.measured_depth, self.max_depth
        c = s.cell_chord
        ge, gm, slope = (np.broadcast_to(np.asarray(a, np.float64), (Dm + 1,))
                         for a in (ge, gm, slope))  # (per depth, or one for all)
        e = np.zeros(Dm + 1)
        mv = np.zeros(Dm + 1)
        for D in range(Dq + 1, Dm + 1):
            curv = (1 + slope[D]) * c[D] ** 2 / self.r_min
            e[D] = 1.05 * ge[D] * c[D] / math.sqrt(3) + curv
            g = gm[D] if D == Dq + 1 else ge[D]
            mv[D] = 1.05 * g * c[D - 1] / 2 + (1 + slope[D]) * c[D - 1] ** 2 / self.r_min
        return e, mv

    def _deep_table(self, A: np.ndarray, own: np.ndarray, R: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per depth D beyond the measured one, (e, M, steepest slope) over the deepest
        measured nodes in ``A`` that a depth-D node can lie under when ranges ``R`` are
        drawn: a depth-D node is drawn only if its parent meets R_{D−1}, and it lies in its
        measured ancestor's volume (up to ``_deep_margin``), so those whose distance ``own``
        less the margin is under R_{D−1}. e is measured (:meth:`deep_errors`), M and the
        slope bounded from their gradient spreads (:meth:`fine_errors`)."""
        Dq, Dm = self.measured_depth, self.max_depth
        last = A & (self.region_depth == Dq)
        near = own - self._deep_margin
        ee, ge, gm, fs, steep = (np.zeros(Dm + 1) for _ in range(5))
        for D in range(Dq + 1, Dm + 1):
            S = np.flatnonzero(last & (near < R[D - 1]))
            if not len(S):
                continue  # no node of this depth is drawn
            ee[D] = float(self.deep_errors(S, D).max())
            ge[D], gm[D], fs[D], steep[D] = self.region_fine[S].max(0)
        _, em = self.fine_errors(ge, gm, fs)
        return ee, em, steep

    def _deep_ranges(self, A, own, lam, tau, fraction):
        """Ranges over the measured nodes ``A``, beyond the measured depth from the errors
        measured under the nodes each depth can be drawn under (:meth:`_deep_table`).

        Start from the gradient bound (per depth the same over all of A: ranges R⁰); then
        R^{i+1} = ranges of the tables over the nodes within R^i. The tables only grow with
        the sets and the ranges with the tables, so while R^{i+1} ≤ R^i every node R^{i+1}
        can draw is among those its tables were taken over: each iterate that shrinks is
        sound, and the sequence stops at a fixed point (or at the last one that shrank).
        Only R_{D_s} … (the ranges that pick the sets) need shrink: a coarser range can grow
        when a finer one shrinks (the morph's budget, m_D = (1 − f)R_{D−1} + f·R_D, is
        met by the larger), and the measured nodes' own fixed point (:meth:`view_ranges`)
        answers for those. The ranges stay monotone in depth as :func:`ranges_from` makes
        any tables' ranges."""
        R, m = self._capped_ranges(self.tables(A), own, A, lam, tau, fraction)
        Dq = self.measured_depth
        if self.max_depth <= Dq or self._deep_samples is None:
            return R, m
        for _ in range(32):
            R2, m2 = self._capped_ranges(self.tables(A, self._deep_table(A, own, R)), own, A,
                                         lam, tau, fraction)
            if not np.all(R2[Dq:] <= R[Dq:]):
                break  # keep R (the sets were taken within it)
            done = np.allclose(R2, R, rtol=1e-9, atol=1e-9)
            R, m = R2, m2
            if done:
                break
        return R, m

    def _capped_ranges(self, tables, own, A, lam, tau, fraction):
        """:func:`ranges_from`, no deeper than the view needs beyond the measured depth: the
        first depth D whose e_D·(λ/τ + 1) the eye's distance d₀ to the nearest deepest
        measured node in A (every deeper node, and the truth it is measured against, lies
        in one of their volumes) already meets draws its nodes as leaves (R_D = 0)."""
        Dm, Dq = self.max_depth, self.measured_depth
        e = tables[0]
        if Dm > Dq:
            d0 = float(own[A].min()) if A.any() else np.inf
            for D in range(Dq, Dm + 1):
                if (lam / tau + 1) * e[D] * SAFE <= d0:
                    Dm = D
                    break
        R, m = ranges_from(tables, Dm, lam, tau, fraction, self.r_min)
        if Dm < self.max_depth:
            pad = self.max_depth - Dm
            R = np.concatenate([R, np.zeros(pad)])
            m = np.concatenate([m, np.full(pad, np.inf)])
        return R, m
