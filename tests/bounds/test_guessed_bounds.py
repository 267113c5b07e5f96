"""Schema 17's guesses: a geographic level-0 r's cell centres stored as differences from
their guess from the heights (``CENTRES`` with ``PRED``, leafbounds.centre_guess), and
the normals' border rings as differences from the tile's own derived map
(normals.ring_guess, metadata ``normals_ring_residual``); schema 20's: a geographic r
above level 0, every new vertex as its difference from its guess from the heights
(``MIDS`` with ``PRED``, leafbounds.mids_residuals)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.bounds.leafbounds import (
    CentreHeights,
    centre_guess,
    mids_codes,
    mids_residuals,
    ring_guesses,
)
from geoterrain.bounds.log8codes import log8_table, new_mask
from geoterrain.bounds.normalbytes import ring_from_bytes, ring_index
from geoterrain.bounds.normals import derived_codes, ring_guess
from geoterrain.bounds.tileblobs import BoundsCoding, level_blobs, ring_blobs
from geoterrain.bounds.vertexdata import CENTRES, MIDS, PRED, RING, decode_bounds
from geoterrain.core import zstdsafe

pytestmark = pytest.mark.fast


def _heights(rng, shape, relief, holes):
    z = rng.normal(0, relief, shape).cumsum(0).cumsum(1) / 4 + rng.normal(0, relief / 10, shape)
    v = rng.random(shape) >= holes
    return np.where(v, z, np.nan), v


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), t=st.sampled_from([1, 2, 3, 4]),
       tiles=st.sampled_from([(1, 1), (2, 1), (2, 2)]),
       relief=st.sampled_from([0.1, 10.0, 1000.0]), holes=st.sampled_from([0.0, 0.2]),
       codes=st.sampled_from(["guess", "random"]))
def test_guessed_centres_decode_to_the_stored_codes(seed, t, tiles, relief, holes, codes):
    """A level-0 r blob of ``CENTRES`` shape written with the heights holds its centres
    as (guess − code) mod 256 and decodes to the codes exactly, whether the codes are
    near the guess (r's own: √(s² + Δz²), a small payload) or have nothing to do with it
    (random codes: a wrong guess costs bytes, never exactness)."""
    rng = np.random.default_rng(seed)
    T = (1 << t) + 1
    nx, ny = tiles
    shape = (ny * (T - 1) + 1, nx * (T - 1) + 1)
    z, v = _heights(rng, shape, relief, holes)
    stand_in = float(rng.normal(0, relief))
    boxes = np.array([[0.0, 30.0 * (T - 1), 0.0, 31.0 * (T - 1)]] * (nx * ny))
    boxes += rng.normal(0, 1, boxes.shape)
    xy = [(x, y) for y in range(ny) for x in range(nx)]
    e = -3
    c = CentreHeights(z, v.view(np.uint8), stand_in, boxes)
    rc = np.zeros(shape, np.uint8)  # edge midpoints: leaves of code 0 (CENTRES shape)
    if codes == "guess":
        g = centre_guess(c, np.array([(y << t, x << t) for x, y in xy]), T, e)
        for k, (x, y) in enumerate(xy):
            rc[(y << t) + 1:(y << t) + T:2, (x << t) + 1:(x << t) + T:2] = g[k]
        rc[1::2, 1::2] += rng.integers(0, 3, rc[1::2, 1::2].shape).astype(np.uint8)
    else:
        rc[1::2, 1::2] = rng.integers(0, 256, rc[1::2, 1::2].shape)
    rc[::2, ::2] = rng.integers(0, 256, rc[::2, ::2].shape)  # the parents': not stored
    coding = BoundsCoding(np.zeros(shape), None, 0, r_codes=(rc, e))
    blobs, _, _ = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), t, 0, 1, xy,
                              ("delta", "radius"), centres=c)
    table = log8_table(e)
    for k, (x, y) in enumerate(xy):
        blob = blobs["radius"][(0, x, y)]
        assert blob[1] & (CENTRES | PRED) == CENTRES | PRED
        win = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]

        def guess(ee, win=win, k=k):  # the reader's: the tile's own heights and box
            return centre_guess(CentreHeights(z[win], v[win].view(np.uint8), stand_in,
                                              boxes[k:k + 1]), np.zeros((1, 2)), T, ee)[0]

        parent = np.zeros((T, T), np.float32)
        got = decode_bounds(blob, (T, T), parent, (x % 2, y % 2), guess=guess)
        want = table[rc[win]]
        m = new_mask(T)
        assert np.array_equal(got[m], want[m]), (x, y)
        if codes == "guess":  # a guess from other heights decodes to other codes
            other = decode_bounds(blob, (T, T), parent, (x % 2, y % 2),
                                  guess=lambda ee, g0=guess: g0(ee) + np.uint8(1))
            assert not np.array_equal(other[m], want[m])


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 10_000), T=st.sampled_from([3, 5, 9, 17]),
       origin=st.floats(-3e7, 3e7), code=st.integers(40, 160), flat=st.booleans())
def test_the_centre_guess_is_the_same_from_the_exact_box_and_the_stored_one(
        seed, T, origin, code, flat):
    """A writer guesses from a tile's exact box, a reader from the tile table's (rounded
    outward, schema 17's catalog): the guesses must be equal bit for bit, or a reader
    would decode other codes than the writer stored. Flat tiles whose spacing is a code's
    value put the guess on a code boundary, where a box wider by a step changes it."""
    from geoterrain.bounds.log8codes import log8_table
    from geoterrain.store.catalog import TILE_COLUMNS, stored_numbers

    rng = np.random.default_rng(seed)
    s = float(log8_table(0)[code])
    z = np.zeros((T, T)) if flat else rng.uniform(0.0, 3 * s, (T, T))
    o = origin + rng.uniform(0.0, 1.0) * 2.0 ** -12
    box = np.array([o, o + s * (T - 1), -o / 3, -o / 3 + s * (T - 1)])
    nums = np.zeros((1, len(TILE_COLUMNS)))
    nums[0, 5:9] = box
    stored = stored_numbers(np.array([0]), nums)[0, 5:9]
    ok = np.ones((T, T), np.uint8)
    zero = np.zeros((1, 2), np.int64)
    exact = centre_guess(CentreHeights(z, ok, 0.0, box[None]), zero, T, 0)
    read = centre_guess(CentreHeights(z, ok, 0.0, stored[None]), zero, T, 0)
    assert np.array_equal(exact, read)
    # schema 20's guesses above level 0 take the same spacings
    res = rng.integers(0, 3, 3 * (T // 2) ** 2 + 2 * (T // 2)).astype(np.uint8)
    a = int(rng.integers(0, 64))
    assert np.array_equal(mids_codes(CentreHeights(z, ok, 0.0, box[None]), zero, T, 0, a, 0, res),
                          mids_codes(CentreHeights(z, ok, 0.0, stored[None]), zero, T, 0, a, 0,
                                     res))


def test_a_guessed_centres_blob_without_its_heights_is_refused():
    T, e = 5, 0
    z = np.zeros((T, T))
    c = CentreHeights(z, np.ones((T, T), np.uint8), 0.0, np.array([[0.0, 4.0, 0.0, 4.0]]))
    rc = np.zeros((T, T), np.uint8)
    rc[1::2, 1::2] = 9
    coding = BoundsCoding(np.zeros((T, T)), None, 0, r_codes=(rc, e))
    blob = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), 2, 0, 1, [(0, 0)],
                       ("delta", "radius"), centres=c)[0]["radius"][(0, 0, 0)]
    parent = np.zeros((T, T), np.float32)
    with pytest.raises(ValueError, match="guessed centres"):
        decode_bounds(blob, (T, T), parent)  # no guess
    with pytest.raises(ValueError, match="wrong shape"):
        decode_bounds(blob, (T, T), parent, guess=lambda ee: np.zeros((3, 3), np.uint8))
    ring_flag = bytes([blob[0], blob[1] | 4, blob[2]]) + blob[3:]  # with RING
    with pytest.raises(ValueError, match="guessed centres"):
        decode_bounds(ring_flag, (T, T), parent, guess=lambda ee: np.zeros((2, 2), np.uint8))
    with pytest.raises(ValueError, match="guessed r vertices"):  # the writer: not on a ring
        level_blobs(coding, np.zeros((0, 0, 2), np.uint8), 2, 0, 1, [(0, 0)],
                    ("delta", "radius"), ring=True, centres=c)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), T=st.sampled_from([3, 5, 9, 17]),
       holes=st.sampled_from([0.0, 0.1, 0.5]), zf=st.sampled_from([1.0, 0.3048, 3.0]),
       bend=st.sampled_from([0.0, 1e-3, 0.2]), bits=st.sampled_from([8, 16]))
def test_ring_guess_is_what_the_reader_derives_at_the_ring(seed, T, holes, zf, bend, bits):
    """The writer's ring-only kernel gives, bit for bit, the codes the reader's whole
    derived map has at the ring before it sets the stored ones (``derived_codes`` with a
    zero residual), on straight and bent (curvilinear) x, y, with holes and NaN."""
    rng = np.random.default_rng(seed)
    k = 3
    h, v = _heights(rng, (k, T, T), 20.0, holes)
    jj, ii = np.meshgrid(np.arange(T) * 30.0, np.arange(T) * -31.0)
    X = np.stack([jj + bend * ii * ii + rng.normal(0, bend, (T, T)) for _ in range(k)])
    Y = np.stack([ii + bend * jj * jj for _ in range(k)])
    ring = ring_index(T)
    zero = np.zeros((k, len(ring[0]), 2), np.uint8 if bits == 8 else np.uint16)
    full = derived_codes(h, zf, v, X, Y, zero, ring, bits, residual=True)
    got = ring_guess(h * zf, v, X, Y, ring, bits)
    assert np.array_equal(got, full[:, ring[0], ring[1]])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), T=st.sampled_from([3, 5, 9]),
       holes=st.sampled_from([0.0, 0.2]))
def test_residual_rings_decode_to_the_stored_codes(seed, T, holes):
    """A ring blob written as differences from the guess (``ring_blobs(..., guess)``)
    gives back the ring's codes through the reader's ``derived_codes(residual=True)``;
    read without the residual flag it does not (the test can fail)."""
    rng = np.random.default_rng(seed)
    h, v = _heights(rng, (1, T, T), 50.0, holes)
    jj, ii = np.meshgrid(np.arange(T) * 10.0, np.arange(T) * -10.0)
    codes = rng.integers(0, 256, (T, T, 2)).astype(np.uint8)  # any stored ring
    ring = ring_index(T)
    guess = ring_guess(h, v, jj[None], ii[None], ring)
    blob = ring_blobs(codes, (T - 1).bit_length() - 1, [(0, 0)], 0, guess)[(0, 0, 0)]
    stored = ring_from_bytes(zstdsafe.decompress(blob, 2 * len(ring[0]), exact=True), True)
    got = derived_codes(h, 1.0, v, jj[None], ii[None], stored[None], ring, residual=True)
    assert np.array_equal(got[0][ring], codes[ring])
    plain = derived_codes(h, 1.0, v, jj[None], ii[None], stored[None], ring)
    assert (guess == 0).all() or not np.array_equal(plain[0][ring], codes[ring])


def test_ring_guesses_take_each_tile_from_its_origin():
    """``ring_guesses`` cuts each tile at its origin in the level's window: two tiles
    side by side give each its own guess (not its neighbour's)."""
    from geoterrain.core.frame import Frame
    from geoterrain.core.grid import Grid

    rng = np.random.default_rng(5)
    g = Grid(9, 9, 3, 2)
    z = rng.normal(0, 5, (9, 9))
    v = np.ones((9, 9), bool)
    f = Frame.pixel(9, 9, 2.0)
    got = ring_guesses(g, f, 0, [(0, 0), (1, 0)], z, v, np.array([(0, 0), (0, 4)]))
    X, Y = f.grid_xy(9)
    ring = ring_index(5)
    for k, c0 in enumerate((0, 4)):
        w = np.s_[0:5, c0:c0 + 5]
        want = ring_guess(z[w][None], v[w][None], np.ascontiguousarray(X[w])[None],
                          np.ascontiguousarray(Y[w])[None], ring)
        assert np.array_equal(got[k], want[0])
    assert not np.array_equal(got[0], got[1])


def _mids_case(rng, t, tiles, relief, holes, codes, e=-3):
    # a level's lattice of heights and r codes for ``tiles`` (nx, ny) tiles of 2^t + 1
    T = (1 << t) + 1
    nx, ny = tiles
    shape = (ny * (T - 1) + 1, nx * (T - 1) + 1)
    z, v = _heights(rng, shape, relief, holes)
    stand_in = float(rng.normal(0, relief))
    boxes = np.array([[0.0, 30.0 * (T - 1), 0.0, 29.0 * (T - 1)]] * (nx * ny))
    boxes += rng.normal(0, 1, boxes.shape)
    xy = [(x, y) for y in range(ny) for x in range(nx)]
    c = CentreHeights(z, v.view(np.uint8), stand_in, boxes)
    rc = rng.integers(0, 256, shape).astype(np.uint8)
    if codes == "near":  # the guesses (a = 8, no offset) with small errors: r's own kind
        h = (T - 1) // 2
        for k, (x, y) in enumerate(xy):
            win = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]
            noise = rng.integers(0, 3, 3 * h * h + 2 * h).astype(np.uint8)
            g = mids_codes(c._replace(boxes=boxes[k:k + 1]), np.array([y << t, x << t]), T,
                           e, 8, 0, noise)
            rc[win] = np.where(new_mask(T), g, rc[win])
    return T, z, v, stand_in, boxes, xy, c, rc


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), t=st.sampled_from([1, 2, 3, 4]),
       tiles=st.sampled_from([(1, 1), (2, 1), (2, 2)]),
       relief=st.sampled_from([0.1, 10.0, 1000.0]), holes=st.sampled_from([0.0, 0.2]),
       codes=st.sampled_from(["near", "random"]))
def test_guessed_mids_decode_to_the_stored_codes(seed, t, tiles, relief, holes, codes):
    """An r blob above level 0 written with the level's heights (schema 20) holds every
    new vertex as (guess − code) mod 256, the edge midpoints' guesses from the heights,
    the centres' from the nesting over their decoded midpoints, and decodes to the codes
    exactly through the reader's guess from the tile's own heights and box, whether the
    codes are near the guesses (a payload of small numbers) or random (a wrong guess
    costs bytes, never exactness); a guess from other heights decodes to other codes."""
    rng = np.random.default_rng(seed)
    T, z, v, stand_in, boxes, xy, c, rc = _mids_case(rng, t, tiles, relief, holes, codes)
    e = -3
    coding = BoundsCoding(np.zeros(z.shape), None, 0, r_codes=(rc, e))
    blobs, _, _ = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), t, 0, 1, xy,
                              ("delta", "radius"), heights=c)
    table = log8_table(e)
    m = new_mask(T)
    for k, (x, y) in enumerate(xy):
        blob = blobs["radius"][(0, x, y)]
        assert blob[1] & (MIDS | PRED) == MIDS | PRED and not blob[1] & CENTRES
        win = np.s_[y << t:(y << t) + T, x << t:(x << t) + T]

        def guess(ee, a, off, res, win=win, k=k, zz=z):  # the reader's: the tile's own
            return mids_codes(CentreHeights(zz[win], v[win].view(np.uint8), stand_in,
                                            boxes[k:k + 1]), np.zeros(2), T, ee, a, off, res)

        parent = np.zeros((T, T), np.float32)
        got = decode_bounds(blob, (T, T), parent, (x % 2, y % 2), guess=guess)
        assert np.array_equal(got[m], table[rc[win]][m]), (x, y)
        if codes == "near":  # other heights: other guesses, other codes
            other = decode_bounds(blob, (T, T), parent, (x % 2, y % 2),
                                  guess=lambda ee, a, off, res, g0=guess: g0(
                                      ee, a, off + 1, res))
            assert not np.array_equal(other[m], table[rc[win]][m])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), t=st.sampled_from([1, 2, 3]),
       relief=st.sampled_from([1.0, 100.0]))
def test_the_mids_guess_reads_no_tile_corner(seed, t, relief):
    """The guesses never read a tile's four corner samples: a streamed writer's lattice
    holds no height for the grid's coarsest vertices (the root tiles' corners, tile
    corners at every level), so the same tile with other corner heights gives the same
    payload; another height anywhere else gives another one (the test can fail)."""
    rng = np.random.default_rng(seed)
    T, z, v, stand_in, boxes, xy, c, rc = _mids_case(rng, t, (1, 1), relief, 0.0, "near")
    o = np.zeros((1, 2), np.int64)
    want = mids_residuals(c, o, T, -3, rc[None])
    z2 = z.copy()
    z2[::T - 1, ::T - 1] += rng.normal(0, 10 * relief, (2, 2)) + 50 * relief
    got = mids_residuals(c._replace(z=z2), o, T, -3, rc[None])
    assert all(np.array_equal(a, b) for a, b in zip(want, got, strict=True))
    z3 = z.copy()
    z3[0, 1] += 100 * relief  # an edge midpoint's height: its guess moves
    moved = mids_residuals(c._replace(z=z3), o, T, -3, rc[None])
    assert not np.array_equal(moved[0], want[0])


def test_a_guessed_mids_blob_without_its_heights_or_parent_is_refused():
    """A ``MIDS`` ``PRED`` blob without a guess, without its parent, beside ``CENTRES``
    or ``RING``, cut before its two header bytes, or with a guess of the wrong shape is
    a ValueError (``Terrain``: a one-line StoreCorruptError); the writer takes heights
    for r below the top only, not on a ring."""
    rng = np.random.default_rng(1)
    T, z, v, stand_in, boxes, xy, c, rc = _mids_case(rng, 2, (1, 1), 10.0, 0.0, "near")
    coding = BoundsCoding(np.zeros(z.shape), None, 0, r_codes=(rc, -3))
    blob = level_blobs(coding, np.zeros((0, 0, 2), np.uint8), 2, 0, 1, xy,
                       ("delta", "radius"), heights=c)[0]["radius"][(0, 0, 0)]
    parent = np.zeros((T, T), np.float32)

    def guess(ee, a, off, res):
        return mids_codes(c, np.zeros(2), T, ee, a, off, res)

    decode_bounds(blob, (T, T), parent, guess=guess)  # as written: read
    for bad, kw in ((blob, {"parent": parent}), (blob, {"guess": guess}),
                    (bytes([blob[0], blob[1] | CENTRES]) + blob[2:], {"parent": parent,
                                                                      "guess": guess}),
                    (bytes([blob[0], blob[1] | RING]) + blob[2:], {"parent": parent,
                                                                   "guess": guess}),
                    (blob[:4], {"parent": parent, "guess": guess})):
        with pytest.raises(ValueError, match="guessed"):
            decode_bounds(bad, (T, T), **kw)
    with pytest.raises(ValueError, match="wrong shape"):
        decode_bounds(blob, (T, T), parent, guess=lambda *a: np.zeros((3, 3), np.uint8))
    for kw in ({"ring": True}, {}):  # on a ring; at the top (not new vertices only)
        with pytest.raises(ValueError, match="guessed r vertices"):
            level_blobs(coding, np.zeros((0, 0, 2), np.uint8), 2, 0, 1 if kw else 0, xy,
                        ("delta", "radius"), heights=c, **kw)
