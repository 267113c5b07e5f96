"""Edit a store in place (issue 52): new heights over a window of the DEM, and every
stored bound kept what a preprocess of the edited DEM gives.

Seed 004 deforms its terrain at run time "at no extra cost" (§5.2, L42): only what the
edit reaches changes. Here that is, for a window of changed samples:

- the height blobs of the level-0 tiles under it and of their ancestors, whose decoded
  codes change (residual coding predicts level L from the decoded level L + 1), and of
  any finer tile those predictions reach;
- δ and r of the vertices whose diamond holds a changed sample, up the saturation
  chain to the root (seed 002 §2.4: δ saturated, spheres nested);
- the tile rows (error, skirt error, box, stored δ and r maxima) and the GeoMipMapping
  blocks' δ_n;
- the normals within their central differences' one-sample halo, at every level;
- the metadata (height range, nodata count, largest δ, δ_edge list) and an edit log.

The rows are written in one SQLite transaction (:class:`geoterrain.store.editor.StoreEditor`):
a killed edit leaves the old store, which the next open restores. How the new rows are
computed: :mod:`.local` (a few tiles' worth of work) where it applies, else :mod:`.whole`
(the preprocess's stages over the whole grid); both give the rows a preprocess of the
edited DEM gives (tested), with the store's quantizer and predictor.

Examples
--------
>>> import numpy as np, shutil, tempfile, os, geoterrain
>>> p = os.path.join(tempfile.mkdtemp(), "c.geoterrain"); _ = shutil.copy(t.path, p)
>>> res = edit_terrain(geoterrain.open(p), Patch(2, 3, np.full((4, 4), 2500.0)), "max")
>>> res.changed, res.how in ("tiles", "whole grid")
(16, True)
"""

from __future__ import annotations

import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain.core.threads import serial_kernels
from geoterrain.preprocessing.edit.patch import (
    MODES,
    RESAMPLING,
    Patch,
    combine,
    fit_to_quantizer,
    read_patch,
)
from geoterrain.preprocessing.edit.whole import whole_plan
from geoterrain.store.editor import StoreEditor
from geoterrain.store.reader import StoreReader

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["MODES", "RESAMPLING", "EditResult", "Patch", "edit_terrain", "read_patch",
           "window_heights"]

EDIT_LOG = 32  # the edits the store's metadata keeps (the count goes on)
MAX_DIRTY = 64  # dirty rectangles an edit records; beyond, their bounding box


@dataclass
class EditResult:
    """What an edit did.

    ``window``: (row, col, rows, cols) of the samples whose height or validity changed
    (None: nothing changed, and nothing was written); ``changed``: how many;
    ``rounded``: the largest rounding of a patch height to a lossless store's grid;
    ``how``: ``"tiles"`` (only what the edit reaches was computed) or ``"whole grid"``
    (the preprocess's stages over the whole grid; ``why`` says why); ``rows``,
    ``bytes``: the store rows and bytes written; ``seconds``: the time taken;
    ``dirty``: level-0 sample rectangles (r0, c0, r1, c1) outside which nothing decoded
    changed."""

    path: Path
    mode: str
    source: str
    window: tuple[int, int, int, int] | None
    changed: int
    rounded: float = 0.0
    how: str = "nothing changed"
    why: str = ""
    rows: int = 0
    bytes: int = 0
    seconds: float = 0.0
    dirty: list = field(default_factory=list)
    write_seconds: float = 0.0  # of ``seconds``: the transaction (its syncs included)

    def summary(self) -> str:
        """One line for the command line."""
        if self.window is None:
            return f"{self.path}: the patch changes no sample; nothing written"
        r, c, h, w = self.window
        line = (f"{self.path}: {self.mode} changed {self.changed} samples in rows {r} … "
                f"{r + h - 1}, columns {c} … {c + w - 1}; rewrote {self.rows} rows, "
                f"{self.bytes / 1e3:.1f} kB ({self.how}{': ' + self.why if self.why else ''})"
                f" in {self.seconds:.2f} s")
        if self.rounded:
            line += f"; heights rounded by up to {self.rounded:.3g}"
        return line


def window_heights(terrain: TerrainLike, r0: int, c0: int, r1: int, c1: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Level-0 heights (source units, NaN where not valid) and validity of samples
    ``r0 … r1 − 1`` × ``c0 … c1 − 1`` (padding and unstored tiles: nodata), decoded from
    the tiles that hold them.

    Examples
    --------
    >>> h, v = window_heights(t, 0, 0, 2, 3)
    >>> h.shape, bool(v.all())
    ((2, 3), True)
    """
    g = terrain.grid
    S = 1 << g.t
    h = np.full((r1 - r0, c1 - c0), np.nan)
    v = np.zeros((r1 - r0, c1 - c0), bool)
    ntx, nty = g.tiles(0)
    # a root grid's last tile holds the data's last row or column as its far border (no
    # tile starts there): a window on it reads that tile
    tys = range(min(r0 // S, nty - 1), min((r1 - 1) // S, nty - 1) + 1)
    txs = range(min(c0 // S, ntx - 1), min((c1 - 1) // S, ntx - 1) + 1)
    batch = getattr(terrain, "tiles", None)  # one query for them all, where it reads batches
    keys = [(0, tx, ty) for ty in tys for tx in txs if (0, tx, ty) in terrain.tile_info]
    if batch is not None and len(keys) > 1:
        batch(keys)
    for ty in tys:
        for tx in txs:
            if (0, tx, ty) not in terrain.tile_info:
                continue
            tile = terrain.tile(0, tx, ty)
            a0, a1 = max(r0, ty * S), min(r1, ty * S + S + 1)
            b0, b1 = max(c0, tx * S), min(c1, tx * S + S + 1)
            h[a0 - r0:a1 - r0, b0 - c0:b1 - c0] = tile.heights[a0 - ty * S:a1 - ty * S,
                                                               b0 - tx * S:b1 - tx * S]
            v[a0 - r0:a1 - r0, b0 - c0:b1 - c0] = tile.valid[a0 - ty * S:a1 - ty * S,
                                                             b0 - tx * S:b1 - tx * S]
    return h, v


def edit_terrain(terrain: TerrainLike, patch: Patch, mode: str = "replace", *,
                 round_heights: bool = False, how: str = "auto") -> EditResult:
    """Apply ``patch`` to the store ``terrain`` reads, in place, and return what was done.

    Parameters
    ----------
    terrain
        The store's terrain (its tiles are read through it; it is not refreshed here:
        :meth:`geoterrain.terrain.Terrain.edit` does that).
    patch
        New heights over a window of the DEM (:class:`Patch`; NaN: leave the sample).
    mode
        ``replace``, ``add``, ``min`` or ``max`` (:mod:`.patch`).
    round_heights
        Round heights that a lossless store cannot hold to its grid, instead of refusing
        them (:func:`.patch.fit_to_quantizer`).
    how
        ``"auto"`` (the local computation where it applies), ``"tiles"`` (it, or a
        one-line error saying why not) or ``"whole grid"``.
    """
    from geoterrain.exceptions import UsageError

    t0 = time.perf_counter()
    if mode not in MODES:
        raise UsageError(f"unknown mode {mode!r}; use one of {', '.join(MODES)}",
                         cli=f"--mode must be one of {', '.join(MODES)}, got {mode!r}")
    if how not in ("auto", "tiles", "whole grid"):
        raise UsageError(f"unknown how {how!r}; use auto, tiles or whole grid")
    p = patch.clipped(terrain.grid)
    with serial_kernels():  # a few tiles' work: one thread (core/threads.py)
        return _edit(terrain, p, mode, round_heights, how, t0)


def _edit(terrain: TerrainLike, p: Patch, mode: str, round_heights: bool, how: str,
          t0: float) -> EditResult:
    # the store's reads in one read transaction (Terrain.snapshot: no lock, unlock and
    # change-counter check a blob), ended before the edit's own transaction writes
    snapshot = getattr(terrain, "snapshot", None)
    with snapshot() if snapshot is not None else nullcontext():
        res, plan, meta_before = _plan(terrain, p, mode, round_heights, how, t0)
    if plan is None:
        return res
    tw = time.perf_counter()
    reader = getattr(terrain, "reader", None)  # its tile table, parsed at open
    with StoreEditor(terrain.path, expect=meta_before,
                     known=reader if isinstance(reader, StoreReader) else None) as ed:
        stats = ed.apply(plan.puts, plan.deletes, plan.tiles, plan.meta, plan.all_tiles)
    res.rows, res.bytes = stats["rows"], stats["blob_bytes"] + stats["catalog_bytes"]
    res.seconds = time.perf_counter() - t0
    res.write_seconds = time.perf_counter() - tw
    return res


def _plan(terrain: TerrainLike, p: Patch, mode: str, round_heights: bool, how: str,
          t0: float) -> tuple:
    """(the result so far, the plan or None where nothing changes, the old metadata)."""
    from geoterrain.exceptions import UsageError
    from geoterrain.preprocessing.edit import local

    q = terrain.quantizer
    r0, c0 = p.row, p.col
    r1, c1 = r0 + p.heights.shape[0], c0 + p.heights.shape[1]
    old_h, old_v = window_heights(terrain, r0, c0, r1, c1)
    new_h, new_v = combine(old_h, old_v, p.heights, mode)
    new_h, rounded = fit_to_quantizer(new_h, new_v, q, round_heights=round_heights,
                                      source=p.source)
    changed = (new_v != old_v) | (new_v & (new_h != np.where(old_v, old_h, np.nan)))
    res = EditResult(terrain.path, mode, p.source, None, int(changed.sum()), rounded)
    if not changed.any():
        res.seconds = time.perf_counter() - t0
        return res, None, None
    ii, jj = np.nonzero(changed)
    a0, a1, b0, b1 = int(ii.min()), int(ii.max()) + 1, int(jj.min()), int(jj.max()) + 1
    res.window = (r0 + a0, c0 + b0, a1 - a0, b1 - b0)
    new_h, new_v = new_h[a0:a1, b0:b1], new_v[a0:a1, b0:b1]
    meta_before = dict(terrain.meta)
    why = local.unsupported(terrain, r0 + a0, c0 + b0, new_h, new_v) if how != "whole grid" \
        else "asked for"
    plan = None
    if not why:
        plan, why = local.local_plan(terrain, r0 + a0, c0 + b0, new_h, new_v)
    if plan is None:
        if how == "tiles":
            raise UsageError(f"{terrain.path}: this edit needs the whole grid ({why})")
        with serial_kernels(False):  # the whole grid: every core
            h, v = terrain.level_heights(0)
            h[r0 + a0:r0 + a1, c0 + b0:c0 + b1] = new_h
            v[r0 + a0:r0 + a1, c0 + b0:c0 + b1] = new_v
            plan = whole_plan(terrain, h, v, meta_before)
        res.why = why
    res.how = plan.how
    res.dirty = _merged(plan.dirty)
    plan.meta["edits"] = _log(meta_before.get("edits"), res)
    return res, plan, meta_before


def _merged(rects: list) -> list:
    """The rectangles ``rects`` (4-tuples, or (n, 4) integer arrays of them) without
    repeats, in ascending order, at most MAX_DIRTY of them (else their bounding box)."""
    one = [r for r in rects if not isinstance(r, np.ndarray)]
    parts = [np.array(one, np.int64).reshape(-1, 4)]
    parts += [r.astype(np.int64).reshape(-1, 4) for r in rects if isinstance(r, np.ndarray)]
    a = np.unique(np.concatenate(parts), axis=0)  # rows sorted as tuples are
    if len(a) <= MAX_DIRTY:
        return a.tolist()
    return [[int(a[:, 0].min()), int(a[:, 1].min()), int(a[:, 2].max()), int(a[:, 3].max())]]


def _log(old: dict | None, res: EditResult) -> dict:
    """The metadata's edit log with ``res`` added: a running count and the last
    :data:`EDIT_LOG` edits (how, where, and what a reader must decode again; not when: the
    same edits of the same store give the same bytes, as preprocess does)."""
    count = int(old.get("count", 0)) if isinstance(old, dict) else 0
    last = list(old.get("last", [])) if isinstance(old, dict) else []
    last.append({"n": count + 1, "mode": res.mode, "source": res.source, "window": list(res.window),
                 "samples": res.changed, "how": res.how, "dirty": res.dirty})
    return {"count": count + 1, "last": last[-EDIT_LOG:]}
