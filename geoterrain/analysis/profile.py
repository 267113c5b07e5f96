"""Elevation profiles along a polyline: heights every ``spacing`` metres of ground, with
the distance along the ground (geodesic on geographic grids), written as CSV or drawn.

The line runs between its vertices along the ground's geodesics on a geographic grid
(across 180° on a whole-globe grid, whose vertices may be given past ±180°),
straight in the CRS otherwise (as a GIS densifies a line in a projected layer); samples
fall every ``spacing`` ground metres along each segment and on every vertex. Heights
are :func:`~geoterrain.analysis.heights.height_at`'s (bilinear at level 0, or a coarser
level with its bound); distances are the ground lengths of the
sampled polyline: ellipsoidal geodesics (pyproj) between consecutive samples on a
geographic grid, the CRS's metres otherwise.

Examples
--------
>>> c, f = t.frame.transform[2], t.frame.transform[5]
>>> p = profile(t, [(c + 100.0, f - 100.0), (c + 600.0, f - 100.0), (c + 600.0, f - 900.0)],
...             spacing=50.0)
>>> len(p.distance), float(p.distance[-1]), p.summary["length_m"]
(27, 1300.0, 1300.0)
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from geoterrain.analysis.heights import height_at
from geoterrain.analysis.points import (
    Reads,
    as_xy,
    frame_geod,
    from_source,
    inside,
    outside_error,
    to_source,
    turn_coords,
    vertical_unit,
)
from geoterrain.exceptions import UsageError, WriteError, exists_error

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

__all__ = ["Profile", "plot_profile", "profile", "write_profile_csv"]


class Profile(NamedTuple):
    """Samples along a line: ``distance`` (ground metres from the start), ``xy`` (the
    samples in the line's CRS), ``height`` (the DEM's vertical unit, NaN over nodata),
    ``bound`` and ``level`` (as :func:`~geoterrain.analysis.heights.height_at` gives
    them), ``vertex`` (the sample index of each vertex), ``unit`` (the heights' unit),
    ``summary`` (length, lowest and highest, total ascent and descent, steepest grade)
    and ``stats`` (tiles decoded, bytes read, seconds)."""

    distance: np.ndarray
    xy: np.ndarray
    height: np.ndarray
    bound: np.ndarray
    level: np.ndarray
    vertex: np.ndarray
    unit: str
    summary: dict
    stats: dict


def _ground_lengths(terrain: TerrainLike, xy: np.ndarray) -> np.ndarray:
    """Ground metres between consecutive source-CRS points."""
    f = terrain.frame
    if f.kind == "geographic":
        geod = frame_geod(f)
        _, _, d = geod.inv(xy[:-1, 0], xy[:-1, 1], xy[1:, 0], xy[1:, 1])
        return np.asarray(d, np.float64)
    return np.hypot(*np.diff(xy, axis=0).T) * f.unit_to_m


def _along(terrain: TerrainLike, a: np.ndarray, b: np.ndarray, d: np.ndarray,
           length: float) -> np.ndarray:
    """Points ``d`` ground metres from ``a`` toward ``b`` (source CRS): on the geodesic on
    a geographic grid, on the straight line otherwise."""
    f = terrain.frame
    if f.kind == "geographic":
        geod = frame_geod(f)
        az, _, _ = geod.inv(a[0], a[1], b[0], b[1])
        x, y, _ = geod.fwd(np.full(len(d), a[0]), np.full(len(d), a[1]), np.full(len(d), az), d)
        return np.column_stack([x, y])
    return a + (d / length)[:, None] * (b - a)


def profile(terrain: TerrainLike, line: Any, spacing: float | None = None, *,
            level: int = 0, crs: Any = None) -> Profile:
    """Heights along ``line`` every ``spacing`` ground metres (and at every vertex).

    Parameters
    ----------
    terrain : an open store.
    line : the polyline's vertices, (N, 2) with N ≥ 2, in the DEM's CRS or ``crs``.
    spacing : ground metres between samples (default: the DEM's cell size).
    level : pyramid level of the heights (:func:`~geoterrain.analysis.heights.height_at`).

    Examples
    --------
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> p = profile(t, [(c + 5.0, f - 5.0), (c + 105.0, f - 5.0)])
    >>> p.distance.tolist()[:3], p.unit
    ([0.0, 10.0, 20.0], 'm')
    """
    f = terrain.frame
    with Reads(terrain) as reads:
        pts = as_xy(line)
        if len(pts) < 2:
            raise UsageError("a profile line needs at least two vertices")
        src = to_source(f, pts, crs)
        fi, fj = turn_coords(f, src)  # a whole-globe grid has no edge at 180°
        out = ~inside(terrain.grid, fi, fj)
        if out.any():
            raise outside_error(f, terrain.grid, pts, crs, out, "line vertex")
        seg = _ground_lengths(terrain, src)
        if not seg.sum() > 0:
            raise UsageError("the profile line has no length: its vertices coincide")
        if spacing is None:
            a, e = f.transform[0], f.transform[4]
            spacing = min(_ground_lengths(terrain, np.array([src[0], src[0] + [a, 0]]))[0],
                          _ground_lengths(terrain, np.array([src[0], src[0] + [0, e]]))[0])
        spacing = float(spacing)
        if not (math.isfinite(spacing) and spacing > 0):
            raise UsageError(f"spacing must be a finite number of metres > 0, got {spacing:g}",
                             cli=f"--spacing must be a finite number of metres > 0, got "
                                 f"{spacing:g}")
        # samples: every `spacing` ground metres along each segment, then its end vertex
        parts, vertex = [src[:1]], [0]
        for k in range(len(src) - 1):
            n = max(int(math.ceil(seg[k] / spacing - 1e-9)), 1) if seg[k] > 0 else 0
            if n == 0:
                vertex.append(vertex[-1])
                continue
            d = np.arange(1, n) * spacing
            parts.append(np.concatenate([_along(terrain, src[k], src[k + 1], d, seg[k]),
                                         src[k + 1:k + 2]]))
            vertex.append(vertex[-1] + n)
        xy_src = np.concatenate(parts)
        if len(xy_src) > 10_000_000:
            raise UsageError(f"{len(xy_src)} samples: give a larger spacing (more than "
                             f"{seg.sum() / 10_000_000:.3g} m)")
        dist = np.concatenate([[0.0], np.cumsum(_ground_lengths(terrain, xy_src))])
        h = height_at(terrain, xy_src, level)
    z = h.height
    dz = np.diff(z)
    ok = np.isfinite(dz)
    run = np.diff(dist)
    grade = np.where(ok & (run > 0), np.abs(dz) / np.where(run > 0, run, 1.0), np.nan)
    unit = vertical_unit(terrain)
    zm = z * f.z_to_m
    summary = {
        "length_m": float(dist[-1]), "samples": int(len(z)), "spacing_m": spacing,
        "min": float(np.nanmin(z)) if np.isfinite(z).any() else math.nan,
        "max": float(np.nanmax(z)) if np.isfinite(z).any() else math.nan,
        "ascent": float(dz[ok & (dz > 0)].sum()), "descent": float(-dz[ok & (dz < 0)].sum()),
        "max_grade_percent": float(np.nanmax(grade) * 100 * f.z_to_m)
        if np.isfinite(grade).any() else math.nan,
        "nodata_samples": int(np.isnan(zm).sum()), "unit": unit,
    }
    xy_out = from_source(f, xy_src, crs)
    return Profile(dist, xy_out, z, h.bound, h.level, np.asarray(vertex), unit, summary,
                   reads.stats(samples=len(z)))


def write_profile_csv(p: Profile, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a profile as CSV: distance_m, x, y, height, bound (the heights' unit) and
    level, one row a sample; written whole or not at all.

    Examples
    --------
    >>> import tempfile, os
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> out = write_profile_csv(profile(t, [(c + 5.0, f - 5.0), (c + 55.0, f - 5.0)]),
    ...                         os.path.join(tempfile.mkdtemp(), "p.csv"))
    >>> open(out).readline().strip()
    'distance_m,x,y,height_m,bound_m,level'
    """
    import csv
    import io

    from geoterrain.core.atomicfiles import write_atomic

    out = Path(path)
    if out.exists() and not overwrite:
        raise exists_error(out)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    u = p.unit.replace(" ", "")
    w.writerow(["distance_m", "x", "y", f"height_{u}", f"bound_{u}", "level"])
    for d, (x, y), z, b, lv in zip(p.distance.tolist(), p.xy.tolist(), p.height.tolist(),
                                   p.bound.tolist(), p.level.tolist(), strict=True):
        w.writerow([f"{d:.3f}", repr(x), repr(y), "" if math.isnan(z) else repr(z),
                    "" if math.isnan(b) else repr(b), lv])
    return write_atomic(out, buf.getvalue(), overwrite=overwrite)


def plot_profile(p: Profile, path: str | Path, *, title: str | None = None,
                 size: tuple[int, int] = (1200, 500), overwrite: bool = False) -> Path:
    """Draw a profile as a PNG, the way profile tools do: the ground as a filled
    silhouette over distance (km past 2 km), the vertices as thin vertical lines, nodata
    as gaps, the lowest and highest points marked, and the line's length, ascent and
    descent under the title; the vertical exaggeration of the drawing is stated.

    Examples
    --------
    >>> import tempfile, os
    >>> c, f = t.frame.transform[2], t.frame.transform[5]
    >>> p = profile(t, [(c + 5.0, f - 5.0), (c + 805.0, f - 905.0)])
    >>> out = plot_profile(p, os.path.join(tempfile.mkdtemp(), "p.png"))
    >>> out.stat().st_size > 10_000
    True
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    from geoterrain.core.atomicfiles import partial_path, publish

    out = Path(path)
    if out.suffix.lower() != ".png":
        raise UsageError(f"{out}: a profile plot is written as PNG: give a .png name")
    if out.exists() and not overwrite:
        raise exists_error(out)
    km = p.distance[-1] > 2000
    x = p.distance / 1000 if km else p.distance
    z = p.height
    dpi = 100
    fig = Figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    ax = fig.add_subplot()
    lo = np.nanmin(z) if np.isfinite(z).any() else 0.0
    hi = np.nanmax(z) if np.isfinite(z).any() else 1.0
    pad = 0.08 * (hi - lo or 1.0)
    base = lo - pad
    ax.fill_between(x, base, z, where=np.isfinite(z), color="#b9a27a", alpha=0.85, lw=0,
                    interpolate=False)
    ax.plot(x, z, color="#5b4424", lw=1.2)
    for v in p.vertex[1:-1]:
        ax.axvline(x[v], color="0.55", lw=0.6, ls="--")
    if np.isfinite(z).any():
        for k, mark in ((int(np.nanargmin(z)), "v"), (int(np.nanargmax(z)), "^")):
            ax.plot(x[k], z[k], mark, color="#1f3b73", ms=7)
            ax.annotate(f"{z[k]:.0f} {p.unit}", (x[k], z[k]), textcoords="offset points",
                        xytext=(0, 9 if mark == "^" else -15), ha="center", fontsize=9)
    ax.set_xlim(x[0], x[-1])
    ax.set_ylim(base, hi + 2 * pad)
    ax.set_xlabel("distance along the ground (km)" if km else "distance along the ground (m)")
    ax.set_ylabel(f"elevation ({p.unit})")
    ax.grid(True, color="0.85", lw=0.6)
    s = p.summary
    ax.set_title((title + "\n" if title else "") +
                 f"length {s['length_m'] / 1000:.2f} km · ascent {s['ascent']:.0f} {p.unit} · "
                 f"descent {s['descent']:.0f} {p.unit} · steepest {s['max_grade_percent']:.0f} %",
                 fontsize=10)
    # the drawing's vertical exaggeration: metres per pixel across over metres per pixel up
    fig.tight_layout()
    box = ax.get_window_extent()
    zunit = {"m": 1.0, "ft": 0.3048, "us-ft": 1200 / 3937}.get(p.unit, 1.0)
    across = (p.distance[-1] - p.distance[0]) / max(box.width, 1)
    up = (hi + 2 * pad - base) * zunit / max(box.height, 1)
    ax.text(0.995, 0.98, f"VE ×{across / up:.3g}" if up > 0 else "", transform=ax.transAxes,
            ha="right", va="top", fontsize=8, color="0.3")
    tmp = partial_path(out)
    try:
        fig.savefig(tmp, format="png")
        publish(tmp, out, overwrite)
    except OSError as exc:
        raise WriteError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
