"""zstd frames as a store holds them: without the magic number, still bounded (issue 51)."""

from __future__ import annotations

import sqlite3
import struct

import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st

import geoterrain
from geoterrain.core.zstdsafe import MAGIC, compress_many, compress_one, decompress, strip_magic
from geoterrain.store.catalog import META_ID, TILES_ID
from geoterrain.store.keys import unpack_blob_key


@pytest.mark.fast
@settings(max_examples=60, deadline=None)
@given(st.lists(st.binary(max_size=3000), min_size=1, max_size=6), st.sampled_from([1, 3, 9, 19]))
def test_frames_without_magic_round_trip(payloads, level):
    """Every frame written lacks the magic (4 bytes less than zstd's own), decodes to its
    payload with or without the magic, and is refused with a cap below its size."""
    frames = compress_many(payloads, level)
    for p, f in zip(payloads, frames, strict=True):
        std = zstandard.ZstdCompressor(level=level).compress(p)
        assert f == std[4:] == compress_one(p, level) and f[:4] != MAGIC
        assert decompress(f, len(p), exact=True) == p == decompress(std, len(p), exact=True)
        if p:
            with pytest.raises(ValueError):
                decompress(f, len(p) - 1)


def _noisy_heights():
    """A few kB of small int16 numbers: payloads the levels compress differently."""
    return st.tuples(st.integers(0, 2**32 - 1), st.integers(500, 6000)).map(
        lambda a: np.random.default_rng(a[0]).normal(0, 30, a[1]).astype(np.int16).tobytes())


@pytest.mark.fast
@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.lists(st.binary(max_size=2000) | _noisy_heights(), max_size=5),
                          st.sampled_from([1, 3, 6, 19]), st.sampled_from([0, 1 << 18])),
                min_size=2, max_size=5))
def test_a_reused_compressor_and_the_serial_path_write_a_fresh_ones_bytes(batches):
    """Batches at mixed levels one after another, each on this thread (under
    ``SERIAL_BYTES``) or on the worker threads: every frame is a fresh compressor's at its
    level, whatever came before it on this thread."""
    from geoterrain.core import zstdsafe

    for payloads, level, serial_bytes in batches:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(zstdsafe, "SERIAL_BYTES", serial_bytes)
            frames = compress_many(payloads, level)
        assert frames == [zstandard.ZstdCompressor(level=level).compress(p)[4:]
                          for p in payloads]
        if payloads:
            assert compress_one(payloads[0], level) == frames[0]


@pytest.mark.fast
@pytest.mark.parametrize("declared", [0, 1 << 34])
def test_a_bomb_without_magic_is_refused(declared):
    """A frame declaring 16 GiB (or nothing) made of large RLE blocks is refused without
    its magic as with it, before anything is allocated (0: capped while decoding)."""
    if declared:
        head = struct.pack("<BQ", 0xE0, declared)
    else:
        head = struct.pack("<BB", 0x00, 0x58)
    body = b"".join(struct.pack("<I", (128 * 1024) << 3 | 2 | (k == 7))[:3] + b"\0"
                    for k in range(8))
    for frame in (head + body, MAGIC + head + body):
        with pytest.raises(ValueError, match="zstd frame"):
            decompress(frame, 1000)


@pytest.mark.fast
def test_damaged_or_empty_frames_are_refused():
    f = compress_one(b"terrain" * 50)
    for bad in (b"", f[:3], bytes([f[0] | 0x08]) + f[1:], f[:-2], MAGIC, b"\x00" * 9):
        with pytest.raises(ValueError):
            decompress(bad, 350)
    with pytest.raises(AssertionError):
        strip_magic(f)  # already without it


@pytest.mark.fast
def test_a_store_holds_no_magic_number(tmp_path, fbm_tif):
    """No blob or tile-table row of a written store holds zstd's magic number where its
    frame starts (after the blob's own header); the metadata's row keeps it, so that an
    older reader finds the schema version."""
    store = geoterrain.preprocess(fbm_tif, tmp_path / "s.geoterrain")
    heads = {"heights": 4, "delta": 3, "radius": 3, "normals": 0, "delta_edge": 3,
             "block_delta": 0}
    from geoterrain.store.reader import StoreReader
    t = StoreReader(store).table()
    kinds = {int(i): unpack_blob_key(int(k))[1] for k, i in zip(t.blobs, t.ids, strict=True)}
    with sqlite3.connect(store) as con:
        rows = con.execute("SELECT id, data FROM blobs").fetchall()
        cat = con.execute("SELECT id, data FROM catalog").fetchall()
    seen = set()
    for rid, data in rows:
        kind = kinds[rid]
        seen.add(kind)
        assert MAGIC not in bytes(data[:heads[kind] + 8]), kind
    assert {"heights", "delta", "radius", "normals", "block_delta"} <= seen
    cat = dict(cat)
    assert bytes(cat[META_ID][:4]) == MAGIC and MAGIC not in bytes(cat[TILES_ID][:16])
