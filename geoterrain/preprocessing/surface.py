"""The whole-grid preprocess' first stages: the DEM and its surface.

:func:`read_dem` reads and checks the DEM (:func:`validate`) and places it (frame and
padded grid); :func:`pad` pads it to the grid, :func:`quantise` chooses the quantizer and
gives the heights as a reader decodes them; :func:`vertex_bounds` computes the per-vertex
δ (Lindstrom & Pascucci's exact vertex errors, saturated) and the nested radii (seed 002
§2.4) as they are stored. :func:`geoterrain.preprocessing.pipeline.preprocess` runs them
in this order (and the whole-grid edit, :mod:`geoterrain.preprocessing.edit.whole`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geoterrain.bounds.curvature import metric_bounds, metric_terms
from geoterrain.bounds.delta import vertex_errors_fields
from geoterrain.bounds.edgepad import (
    has_padding,
)
from geoterrain.bounds.leafbounds import geographic_leaf_delta
from geoterrain.bounds.radii import numpy_range, valid_range, vertex_radii
from geoterrain.bounds.tileblobs import (
    radius_codes,
)
from geoterrain.codec.pyramid import decoded_heights, encode_decoded
from geoterrain.codec.quantchoice import choose_quantizer
from geoterrain.codec.quantize import Quantizer, codes_to_heights
from geoterrain.core.frame import Frame
from geoterrain.core.grid import Grid
from geoterrain.core.progress import StageClock
from geoterrain.exceptions import InputError
from geoterrain.ingest.raster import ABSURD_HEIGHT, Raster, read_raster
from geoterrain.preprocessing.request import Request, place


def validate(r: Raster, z_scale: float | None) -> tuple[float, float, int]:
    """Reject inputs that cannot give a correct store, with a one-line fix; else the
    valid heights' (min, max) and the count of valid samples."""
    h, w = r.shape
    if h < 2 or w < 2:
        raise InputError(f"{r.path}: grid is {h}×{w}; a DEM needs at least 2×2 samples")
    nvalid = int(np.count_nonzero(r.valid))
    if nvalid == 0:
        raise InputError(f"{r.path}: every sample is nodata; check the nodata value or the band")
    lo, hi, _ = valid_range(r.heights, r.valid)  # valid samples are finite (raster.py)
    peak = max(abs(lo), abs(hi))
    if peak > ABSURD_HEIGHT and z_scale is None:
        why = f"{r.path}: heights reach {peak:.3g}, beyond ±{ABSURD_HEIGHT:.0e}; if they are real "
        raise InputError(why + "pass z_scale (e.g. 1), else set the right nodata or unit",
                         cli=why + "pass --z-scale (e.g. 1), else set the right nodata or unit")
    return lo, hi, nvalid


@dataclass
class Dem:
    """The DEM read: its raster (heights, mask, georeference), scene frame and padded
    grid."""

    raster: Raster
    frame: Frame
    grid: Grid
    valid_samples: int


def read_dem(req: Request, *, band: int | None, encoding: str, nodata: float | None,
             tile: str | None, pixel_size: float | None, z_units: str,
             z_scale: float | None, merge: dict | None = None) -> Dem:
    """Read and check the DEM (a web-map tile placed in Web Mercator by its z/x/y;
    sources merged onto one grid, ``merge``: :func:`geoterrain.ingest.raster.read_raster`'s
    crs, resolution, resampling and priority), and its frame (pyproj) and padded grid."""
    r = read_raster(req.files if req.mosaic else req.src, band=band, encoding=encoding,
                    nodata=nodata, **(merge or {}))
    lo, hi, nvalid = validate(r, z_scale)  # one pass over the heights for both checks
    r.transform, r.crs_wkt, frame, grid = place(req, r.shape, r.transform, r.crs_wkt,
                                                tile=tile, pixel_size=pixel_size,
                                                z_units=z_units, z_scale=z_scale, label=r.path)
    frame.check_scene(grid.whole_shape, lo, hi)
    return Dem(r, frame, grid, nvalid)


@dataclass
class Surface:
    """The padded grid's samples: source ``heights`` (NaN = nodata) and ``valid``, scene
    ``X``, ``Y`` and, once quantised, the decoded scene heights ``Z`` with the quantizer
    ``q``, their range (source units) and, with residual bins, the height blobs already
    coded. ``Z`` may be ``heights`` itself (:func:`quantise`): neither is written after."""

    heights: np.ndarray
    valid: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray | None = None
    q: Quantizer | None = None
    height_range: list[float] | None = None
    height_blobs: dict | None = None
    predictor: str = "auto"  # the codec's U(.) (an edit keeps the store's)


def pad(dem: Dem) -> Surface:
    """The DEM padded to the (2^n+1)² grid, or a root grid's extent (invalid padding),
    with scene x, y."""
    grid, r = dem.grid, dem.raster
    valid = grid.pad(r.valid, False, whole=True)
    h = r.heights
    if (h.shape == valid.shape and h.dtype == np.float64 and h.flags.c_contiguous
            and h.flags.writeable):  # no padding: the read's own array (no 134 MB copy)
        heights = h
    else:
        heights = grid.pad(h, np.nan, whole=True)
    if dem.valid_samples < valid.size:
        heights[~valid] = np.nan
    r.heights = None  # the padded array holds them now (memory: issue 12)
    X, Y = dem.frame.grid_xy(dem.grid.whole_shape)
    return Surface(heights, valid, X, Y)


def quantise(dem: Dem, s: Surface, codec_error: float | None) -> Surface:
    """The quantizer of the valid heights (NaN elsewhere, which it ignores) and the
    heights as a reader decodes them, in scene metres (``Z``)."""
    r = dem.raster
    q = choose_quantizer(s.heights, r.src_dtype, codec_error=codec_error, scale=r.scale,
                         offset=r.offset)
    factor = float(dem.frame.z_to_m * dem.frame.z_scale)  # Frame.z's
    height_blobs = None
    if q.bins > 1:  # residual bins: the heights depend on the pyramid, coded here once
        height_blobs, codes = encode_decoded(s.heights, s.valid, dem.grid.t, q,
                                             roots=dem.grid.codec_roots)
        height_blobs = dem.grid.held(height_blobs)
        Z = codes_to_heights(codes, q)
        del codes
        Z[~s.valid] = np.nan
    elif q.mode == "float" and factor == 1.0:
        # the bit-exact float quantizer decodes each valid height to itself (a float32
        # one only where every height is a float32: choose_quantizer), and pad() left
        # NaN elsewhere: the heights, shared read-only (no whole-grid copy, no pass)
        Z = s.heights
    else:
        Z = decoded_heights(s.heights, s.valid, q)  # NaN where invalid
    lo, hi = numpy_range(Z, s.valid)  # as numpy's min and max give them, as stored
    height_range = [float(lo), float(hi)]
    if factor != 1.0:  # x · 1.0 is x: no pass
        Z = dem.frame.z(Z, out=Z)  # scene metres, in place (never the shared heights)
    return Surface(s.heights, s.valid, s.X, s.Y, Z, q, height_range, height_blobs)


@dataclass
class VertexBounds:
    """Per-vertex δ (saturated) and the radii's codes, how level 0's are stored (its
    ``ring_kinds`` as border rings, a geographic δ with its per-tile ``slack``), and the
    metric terms of a geographic frame."""

    delta: np.ndarray
    r_codes: np.ndarray
    ring_kinds: tuple[str, ...]
    slack: np.ndarray | None
    terms: tuple | None
    delta_before: np.ndarray | None
    derive: bool = False  # the store derives what it can on read (derive_bounds)
    fields: dict | None = None  # the tile bounds' level fields made in δ's sweep


def vertex_bounds(dem: Dem, s: Surface, derive_bounds: bool,
                  stage: StageClock | Callable[[str], None],
                  on_fields: Callable[[dict | None], None] | None = None) -> VertexBounds:
    """δ (LP's exact vertex errors, saturated) and the nested radii (seed 002 §2.4,
    L50–52) as the 8-bit log codes they are stored as; on a geographic frame, both made
    to hold in the scene's metric x, y (:mod:`geoterrain.bounds.curvature`).
    ``on_fields``: called with the tile bounds' level fields as soon as δ is done (then
    not kept in the result)."""
    frame, grid, valid = dem.frame, dem.grid, s.valid
    # δ, and in the same sweep the tile bounds' level fields of an all-valid grid
    delta, fields = vertex_errors_fields(s.Z, valid, span=grid.span, t=grid.t)
    stage("errors")
    if on_fields is not None:
        on_fields(fields)
        fields = None
    terms = radius = None
    if frame.kind == "geographic":  # curvilinear grid: δ and r that hold in scene x/y
        radius = vertex_radii(s.X, s.Y, s.Z, valid, span=grid.span)
        terms = metric_terms(s.X, s.Y, s.Z, valid, span=grid.span)
        delta, radius = metric_bounds(delta, radius, s.X, s.Y, s.Z, valid, terms=terms,
                                      span=grid.span)
    slack = delta_before = None
    ring_kinds: tuple[str, ...] = ("delta", "radius") if derive_bounds else ()
    if derive_bounds and frame.kind == "geographic":
        # level 0's δ as a reader derives it: the closed forms + a per-tile slack for the
        # metric term (δ only: r would need pyproj's x, y of every sample)
        delta_before = delta.copy() if has_padding(grid) else None
        slack = geographic_leaf_delta(delta, s.Z, valid, grid.t, terms[0], terms[2],
                                      grid.span)
        ring_kinds = ("delta",) if slack is not None else ()
    # nested on the coded values (a projected frame needs no radii before: r = nesting)
    r_codes = radius_codes(s.X, s.Y, s.Z, valid, radius, span=grid.span)
    del radius
    stage("radii")
    return VertexBounds(delta, r_codes, ring_kinds, slack, terms, delta_before,
                        derive_bounds, fields)
