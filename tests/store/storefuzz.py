"""A mutation fuzzer over stores: every case must end in a clean error or identical output.

Mutations: flipped bytes, swapped blobs (with and without their checksums),
deleted and duplicated rows, blob keys pointing nowhere or keyed out of range, junk
and zstd bombs in the catalog's tile table (checksum recomputed),
metadata edited to bad values (checksum recomputed, as a deliberate editor would),
planted views, triggers, tables and indexes, and zstd bombs (checksum recomputed).
Cases run in a forked worker under a memory limit (RLIMIT_AS) and a per-case timeout
(SIGALRM).
"""

from __future__ import annotations

import json
import os
import random
import resource
import shutil
import signal
import sqlite3
import struct
import zlib
from pathlib import Path

import numpy as np
from storesql import (
    all_tiles,
    blob_keys,
    delete_blob,
    delete_tile,
    put_tile,
    read_blob,
    read_meta,
    read_table,
    tile_row,
    update_blob,
    write_meta,
    write_table,
)

from geoterrain.store.catalog import TILES_ID, TileTable, catalog_crc, pack_tiles
from geoterrain.store.keys import blob_key

MEM_LIMIT_EXTRA = 1 << 30  # address space beyond the worker's own at the start
CASE_TIMEOUT_S = 10


class _Timeout(Exception):
    pass


def zstd_bomb(declared: int, blocks: int = 64, magic: bool = True) -> bytes:
    """A zstd frame declaring ``declared`` bytes (0: no size) made of 128 KiB RLE blocks;
    without its magic number when not ``magic``, as a store holds its frames."""
    if declared:
        head = struct.pack("<IB", 0xFD2FB528, 0xE0) + struct.pack("<Q", declared)
    else:
        head = struct.pack("<IBB", 0xFD2FB528, 0x00, 0x58)  # no size, 8 MiB window
    size = 128 * 1024
    body = b""
    for k in range(blocks):
        hdr = (size << 3) | (1 << 1) | (1 if k == blocks - 1 else 0)
        body += struct.pack("<I", hdr)[:3] + b"\0"
    return head + body if magic else head[4:] + body


def _blob_crc(key, kind, data):
    return zlib.crc32(data, zlib.crc32(struct.pack("<3q", *key) + kind.encode()))


def _meta_rewrite(con, edit):
    meta = read_meta(con)
    edit(meta)
    write_meta(con, meta)


_BAD_META = [
    ("grid", "n", 16), ("grid", "n", 40), ("grid", "t", 0), ("grid", "t", 99),
    ("grid", "rows", -5), ("grid", "cols", 10**9), ("grid", "rows", "65"),
    ("frame", "z_scale", 0), ("frame", "z_scale", -1), ("frame", "z_scale", 10.0),
    ("frame", "kind", "weird"), ("frame", "transform", [1, 0, 0, 0]),
    ("frame", "unit_to_m", float("nan")), ("frame", "rows", 3),
    ("quantizer", "step", 10.0), ("quantizer", "step", 0), ("quantizer", "mode", "zip"),
    ("quantizer", "offset", 1e3), ("quantizer", "float_bits", 7), ("quantizer", "mode", "decimal"),
    ("quantizer", "bins", 2), ("quantizer", "bins", 0), ("quantizer", "bins", 2**40),
    ("quantizer", "bins", "7"), ("quantizer", "bins", 7),
    (None, "normal_bits", 12), (None, "valid_samples", 0), (None, "valid_samples", 10**12),
    (None, "height_range", [5, 1]), (None, "height_range", "x"),
    (None, "nodata_fraction", 2.0), (None, "tile_counts", {}), (None, "schema_version", 1),
    (None, "tile_counts", {"0": 10**9}), (None, "complete", 1),
    (None, "grid", None), (None, "frame", []), (None, "quantizer", "int"),
    (None, "delta_edge", "x"), (None, "delta_edge", [[0, 0]]),
    (None, "delta_edge", [[0, 0, 0, -1.0]]), (None, "delta_edge", [[99, 0, 0, 1.0]]),
    (None, "block_delta_levels", 0), (None, "block_delta_levels", 99),
    (None, "block_delta_levels", "x"), (None, "block_delta_levels", 2**40),
    (None, "normals_derived", [1]), (None, "normals_derived", "x"),
    (None, "normals_derived", [0, 0]),
]


def mutate(path: Path, rng: random.Random) -> str:
    """Apply one random mutation to the store at ``path``; return its description."""
    kind = rng.choice(["flip", "flip", "swap", "swapcrc", "delete", "dup", "meta", "meta",
                       "plant", "bomb", "truncate", "blobjunk", "keyjunk", "tablejunk"])
    if kind == "flip":
        data = bytearray(path.read_bytes())
        n = rng.choice([1, 1, 4, 64])
        for _ in range(n):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(data))
        return f"flip {n} bits"
    if kind == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[: rng.randrange(len(data))])
        return "truncate"
    con = sqlite3.connect(path)
    try:
        keys = blob_keys(con)
        if kind in ("swap", "swapcrc"):
            bk = rng.choice(sorted({k[3] for k in keys}))  # delta_edge on padded stores
            same = [k for k in keys if k[3] == bk]
            if len(same) < 2:
                same = [k for k in keys if k[3] == "heights"]
            a, b = rng.sample(same, 2)
            cols = ("data", "crc32") if kind == "swapcrc" else ("data",)
            ra, rb = (read_blob(con, k, ", ".join(cols)) for k in (a, b))
            update_blob(con, a, **dict(zip(cols, rb, strict=True)))
            update_blob(con, b, **dict(zip(cols, ra, strict=True)))
            desc = f"{kind} {bk} {a[:3]}<->{b[:3]}"
        elif kind == "delete":
            table = rng.choice(["tiles", "blobs", "blob keys", "blob and key"])
            k = rng.choice(keys)
            if table == "tiles":
                delete_tile(con, k[:3])
            else:
                delete_blob(con, k, row=table != "blob keys", key=table != "blobs")
            desc = f"delete {table} {k}"
        elif kind == "dup":
            k = rng.choice(sorted(all_tiles(con)))  # a stored tile (a δ_edge's may not be)
            put_tile(con, (k[0], k[1] + 1000, k[2]), tile_row(con, k))
            desc = f"extra tile row beside {k[:3]}"
        elif kind == "meta":
            group, field, value = rng.choice(_BAD_META)

            def edit(m, group=group, field=field, value=value):
                if group is None:
                    m[field] = value
                else:
                    m[group][field] = value
            _meta_rewrite(con, edit)
            desc = f"metadata {group}.{field}={value!r}"
        elif kind == "plant":
            which = rng.choice(["view", "bview", "trigger", "index", "table"])
            if which == "view":
                con.execute("ALTER TABLE catalog RENAME TO c0")
                con.execute("CREATE VIEW catalog AS WITH RECURSIVE c(n) AS (SELECT 1 UNION ALL "
                            "SELECT n+1 FROM c) SELECT n AS id, x'00' AS data, 0 AS crc32 FROM c")
            elif which == "bview":
                con.execute("ALTER TABLE blobs RENAME TO b0")
                con.execute("CREATE VIEW blobs AS WITH RECURSIVE c(n) AS (SELECT 1 UNION ALL "
                            "SELECT n+1 FROM c) SELECT x'00' AS data, 0 AS crc32 FROM c")
            elif which == "trigger":
                con.execute("CREATE TRIGGER t AFTER INSERT ON catalog BEGIN SELECT 1; END")
            elif which == "index":
                con.execute("CREATE INDEX i ON blobs(crc32)")
            else:
                con.execute("CREATE TABLE extra(x)")
            desc = f"plant {which}"
        elif kind == "bomb":
            k = rng.choice(keys)
            bk = k[3]
            declared = rng.choice([0, 16 << 30, 1 << 40, 200 << 20])
            magic = bool(rng.choice([True, False]))
            frame = zstd_bomb(declared, rng.choice([2, 64, 512]), magic)
            old = read_blob(con, k)[0]
            prefix = {"heights": 3, "delta": 2, "radius": 2, "normals": 0, "delta_edge": 2,
                      "block_delta": 0}[bk]
            data = old[:prefix] + frame
            update_blob(con, k, data=data, crc32=_blob_crc(k[:3], bk, data))
            desc = f"zstd bomb in {k} declaring {declared} ({'with' if magic else 'no'} magic)"
        elif kind == "keyjunk":  # a blob key pointing or keyed where no row is
            k = rng.choice(keys)
            bk = blob_key(k[:3], k[3])
            how = rng.choice(["zero", "negative", "huge", "twin", "kind7", "negkey"])
            t = read_table(con)
            blobs, ids = t.blobs.copy(), t.ids.copy()
            i = int(np.flatnonzero(blobs == bk)[0])
            if how in ("kind7", "negkey"):
                blobs[i] = bk | 7 if how == "kind7" else -8
                order = np.argsort(blobs)
                blobs, ids = blobs[order], ids[order]
            else:
                ids[i] = {"zero": 0, "negative": -1, "huge": 1 << 62,
                          "twin": ids[(i + 1) % len(ids)]}[how]
            write_table(con, TileTable(t.tiles, t.numbers, blobs, ids))
            desc = f"blob key {k} {how}"
        elif kind == "tablejunk":  # the tile table's row: junk or a bomb, valid checksum
            how = rng.choice(["junk", "bomb", "raw", "short", "wrap", "huge"])
            t = read_table(con)
            if how == "wrap":  # one more tile (and its 4 blobs) whose key difference,
                #                  2^63 - 1, carries the sum past 2^63 (wraps negative)
                last = int(t.tiles[-1])
                wrapped = np.int64(last + (1 << 63) - 1 - (1 << 64))
                data = pack_tiles(TileTable(
                    np.append(t.tiles, wrapped), np.vstack([t.numbers, t.numbers[-1:]]),
                    np.append(t.blobs, t.blobs[-1] + np.arange(1, 5)),
                    np.append(t.ids, t.ids.max() + np.arange(1, 5))))
            elif how == "huge":  # far more tiles than the file could hold, compressing
                #                  well but under RATIO_CAP
                k = 400_000
                data = pack_tiles(TileTable(
                    np.arange(k, dtype=np.int64) * 32, np.zeros((k, t.numbers.shape[1])),
                    np.arange(4 * k, dtype=np.int64),
                    np.random.default_rng(rng.randrange(1 << 30)).permutation(4 * k) + 1))
            elif how == "junk":
                data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
            elif how == "bomb":  # a head claiming 2^31 tiles, then a bomb
                data = struct.pack("<BIIBBI", 1, 1 << 31, 0, 2, 0, 0) + zstd_bomb(
                    rng.choice([0, 16 << 30, 1 << 40]), rng.choice([2, 64, 512]))
            elif how == "raw":  # raw, claiming more rows than it holds
                data = struct.pack("<BIIBBI", 0, 1000, 1000, 2, 0, 0) + bytes(64)
            else:
                data = b"\x01"
            con.execute("UPDATE catalog SET data = ?, crc32 = ? WHERE id = ?",
                        (data, catalog_crc(TILES_ID, data), TILES_ID))
            desc = f"tile table {how}"
        else:  # blobjunk: random bytes with a valid bound checksum
            k = rng.choice(keys)
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
            update_blob(con, k, data=data, crc32=_blob_crc(k[:3], k[3], data))
            desc = f"junk blob {k}"
        con.commit()
    finally:
        con.close()
    return desc


def outcome(path: Path, view) -> tuple[str, object]:
    """("error", message) for a GeoterrainError, else ("output", digest of the results)."""
    import geoterrain
    from geoterrain.exceptions import GeoterrainError

    try:
        with geoterrain.open(path) as t:
            m = t.mesh(max_error=0.5)
            sel = t.select(view, pixel_error=2.0)
            gmm = t.select(view, pixel_error=2.0, strategy="geomipmap")  # the block table
            lv0 = [k for k in sorted(t.tile_info) if k[0] == 0][:4]
            # level 0's normals, δ and r: derived from a ring, or stored
            nrm = [t.tile_normal_codes(*k).tobytes() + t.tile_delta(*k).tobytes()
                   + t.tile_radius(*k).tobytes() for k in lv0]
            info = t.info()
            for k in ("path", "size_bytes", "bytes_by_kind", "height_bytes_per_level",
                      "height_bits_per_valid_sample", "modified"):  # the file, not content
                info.pop(k)
            d = (np.asarray(m.points).tobytes(), np.asarray(m.faces).tobytes(),
                 np.asarray(sel.mesh.points).tobytes(), np.asarray(gmm.mesh.faces).tobytes(),
                 b"".join(nrm), json.dumps(info, sort_keys=True, default=str))
            return "output", hash(d)
    except GeoterrainError as exc:
        msg = str(exc)
        return "error", msg


def _view():
    from geoterrain.core.view import View

    return View((0, -90, 60), (0, 0, 0), size=(320, 240))


def _worker(store: Path, start: int, n: int, seed: int, workdir: Path, w: int) -> None:
    """Run cases start..n-1, writing one JSON line per event to fd ``w``; never returns."""
    def send(obj):
        os.write(w, (json.dumps(obj) + "\n").encode())

    try:
        view = _view()
        ref = outcome(store, view)
        base_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        send({"ref": ref[0], "base_rss_kb": base_rss})
        vm = int(open("/proc/self/statm").read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        resource.setrlimit(resource.RLIMIT_AS, (vm + MEM_LIMIT_EXTRA, resource.RLIM_INFINITY))
        case = workdir / f"case-{os.getpid()}.geoterrain"
        for i in range(start, n):
            shutil.copyfile(store, case)
            desc = mutate(case, random.Random(seed * 1_000_003 + i))
            send({"start": i, "desc": desc})
            try:
                got = outcome(case, view)
                if got[0] == "error":
                    bad = "\n" in got[1] or "Traceback" in got[1] or any(
                        not c.isprintable() for c in got[1])
                    kind = "internal" if bad else "clean_error"
                    detail = got[1]
                else:
                    kind = "identical" if got == ref else "wrong"
                    detail = ""
            except MemoryError:
                kind, detail = "oom", ""
            except Exception as exc:  # noqa: BLE001 - what the fuzzer looks for
                kind, detail = "internal", f"{type(exc).__name__}: {exc}"
            send({"done": i, "kind": kind, "desc": f"{desc}: {detail}"[:300],
                  "rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss})
        case.unlink(missing_ok=True)
    except BaseException as exc:  # noqa: BLE001 - report, never hang the parent
        send({"worker_error": f"{type(exc).__name__}: {exc}"})
    os._exit(0)


def run_cases(store: Path, n: int, seed: int, workdir: Path) -> dict:
    """Run ``n`` mutation cases in forked workers, each case under a memory limit and a
    timeout (the parent kills a worker stuck in a case and restarts from the next)."""
    import select

    res = {"clean_error": 0, "identical": 0, "wrong": [], "internal": [], "hang": [],
           "oom": [], "cases": 0, "base_rss_kb": 0, "peak_rss_kb": 0}
    # the pristine store's outcome once here: the kernels it needs are compiled (or
    # loaded) before the fork, so no worker spends its first case's timeout compiling
    # them (on a loaded machine with a cold cache that once took longer than the wait)
    outcome(store, _view())
    start = 0
    while start < n:
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(r)
            _worker(store, start, n, seed, workdir, w)
        os.close(w)
        poll = select.poll()
        poll.register(r, select.POLLIN)
        buf, current = b"", None
        while True:
            # poll, not select: select refuses descriptors ≥ 1024, which a long test
            # process may hold
            ready = poll.poll((CASE_TIMEOUT_S + 30) * 1000)
            if not ready:  # stuck: a hang (the memory limit cannot stop a CPU loop)
                os.kill(pid, signal.SIGKILL)
                break
            chunk = os.read(r, 1 << 16)
            if not chunk:
                break
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                ev = json.loads(line)
                if "worker_error" in ev:
                    res["worker_error"] = ev["worker_error"]
                elif "base_rss_kb" in ev:
                    res["base_rss_kb"] = max(res["base_rss_kb"], ev["base_rss_kb"])
                elif "start" in ev:
                    current = ev
                else:
                    current = None
                    res["cases"] += 1
                    res["peak_rss_kb"] = max(res["peak_rss_kb"], ev["rss_kb"])
                    if ev["kind"] in ("clean_error", "identical"):
                        res[ev["kind"]] += 1
                    else:
                        res[ev["kind"]].append(ev["desc"])
        os.close(r)
        os.waitpid(pid, 0)
        if "worker_error" in res:
            break
        if current is None:
            break  # finished (or died between cases)
        res["hang"].append(current["desc"])  # killed or died inside this case
        res["cases"] += 1
        start = current["start"] + 1
    return res
