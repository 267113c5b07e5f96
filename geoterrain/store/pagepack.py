"""The order in which a store's blob rows are inserted, so that SQLite's leaf pages fill.

A rowid table keeps its rows in rowid order, and appending a row that does not fit the
last leaf page starts a new leaf: what is left of the old one stays empty. A blob row
keeps at most ``U − 35`` bytes of its record on the leaf (``U`` the page size) and moves
the rest to full overflow pages, so a store's leaf cells range from a few dozen bytes to
nearly a page. Appended in key order they left about 130 bytes of every 1 kB page empty
(`benchmarks/bench_size.py`, docs/lab/store-size.md): 6–10 % of a store.

:func:`pack_order` numbers the rows so that, appended in that order, consecutive rows
fill each leaf: best-fit decreasing bin packing of each row's leaf cell
(:func:`leaf_cell_size`, SQLite's record format and its local-payload rule, see
https://www.sqlite.org/fileformat2.html §1.6 and §2.1). The rows, their keys and the
primary-key index are unchanged; only where a row sits in the file moves.

Examples
--------
>>> sizes = [900, 500, 480, 100, 90]
>>> [sizes[i] for i in pack_order(sizes, 1016)]
[900, 100, 500, 480, 90]
"""

from __future__ import annotations

from bisect import bisect_left, insort

import numpy as np

LEAF_HEADER = 8  # bytes of a table b-tree leaf page's header
CELL_POINTER = 2  # bytes of a cell's entry in the page's cell pointer array


def varint_len(v: int) -> int:
    """Bytes of SQLite's big-endian varint for ``v`` ≥ 0 (1–9)."""
    n = 1
    while v >= 0x80 and n < 9:
        v >>= 7
        n += 1
    return n


def _int_body(v: int) -> tuple[int, int]:
    """(serial type, body bytes) of an integer column value (schema format 4)."""
    if v == 0:
        return 8, 0
    if v == 1:
        return 9, 0
    for st, n in ((1, 1), (2, 2), (3, 3), (4, 4), (5, 6)):
        if -(1 << (8 * n - 1)) <= v < (1 << (8 * n - 1)):
            return st, n
    return 6, 8


def record_size(values: tuple) -> int:
    """Bytes of SQLite's record of ``values`` (None, int, str, bytes), header included.
    (An INTEGER PRIMARY KEY column is stored as None: its value is the rowid.)

    >>> record_size((1, "ab", b"xyz"))  # header 4 bytes, bodies 0 + 2 + 3
    9
    >>> record_size((None, b"xyz"))
    6
    """
    types, body = [], 0
    for v in values:
        if v is None:
            st, n = 0, 0
        elif isinstance(v, bytes):
            st, n = 2 * len(v) + 12, len(v)
        elif isinstance(v, str):
            b = len(v.encode("utf-8"))
            st, n = 2 * b + 13, b
        else:
            st, n = _int_body(int(v))
        types.append(st)
        body += n
    s = sum(varint_len(t) for t in types)
    h = s + 1  # the header's own length is a varint at its start
    while s + varint_len(h) != h:
        h = s + varint_len(h)
    return h + body


def local_size(payload: int, usable: int) -> int:
    """Bytes of a table-leaf cell's payload kept on the leaf (the rest overflows)."""
    max_local = usable - 35
    if payload <= max_local:
        return payload
    min_local = (usable - 12) * 32 // 255 - 23
    k = min_local + (payload - min_local) % (usable - 4)
    return k if k <= max_local else min_local


def leaf_cell_size(values: tuple, rowid: int, usable: int) -> int:
    """Bytes a row takes on its table leaf page: the cell and its cell pointer.

    >>> leaf_cell_size((0, 1, 2, "delta", b"\\x00" * 600, 7), 1, 1024)
    620
    """
    p = record_size(values)
    local = local_size(p, usable)
    return (varint_len(p) + varint_len(rowid) + local + (4 if local < p else 0)
            + CELL_POINTER)


def _varint_lens(v: np.ndarray) -> np.ndarray:
    # varint_len of every value of v ≥ 0, on whole arrays
    return 1 + sum((v >= (1 << (7 * k))).astype(np.int64) for k in range(1, 9))


def blob_cell_sizes(lengths, crcs, rowid: int, usable: int) -> np.ndarray:
    """:func:`leaf_cell_size` of every blob row ``(None, data, crc32)`` at once, from the
    data's lengths and the CRCs (any 32-bit integer, signed or not): a store's writer
    sizes thousands of rows.

    >>> blob_cell_sizes([600], [7], 1, 1024).tolist()
    [611]
    >>> leaf_cell_size((None, bytes(600), 7), 1, 1024)
    611
    >>> blob_cell_sizes([600, 600], [-5, -2**31], 1, 1024).tolist()
    [611, 614]
    """
    n = np.asarray(lengths, np.int64)
    c = np.asarray(crcs, np.int64)
    # the crc's serial type and body (_int_body): 0 and 1 have none, then 1-4 or 6 bytes
    # (signed: the store's crcs are −2^31 … 2^31 − 1, schema 17)
    body = np.select([(c == 0) | (c == 1)] + [(-(1 << b) <= c) & (c < 1 << b)
                                              for b in (7, 15, 23, 31)], [0, 1, 2, 3, 4], 6)
    types = 2 + _varint_lens(2 * n + 12)  # serial types: NULL and the int 1 byte each
    p = types + 1 + n + body  # + the header's own length (< 128: one byte)
    max_local = usable - 35
    min_local = (usable - 12) * 32 // 255 - 23
    k = min_local + (p - min_local) % (usable - 4)
    local = np.where(p <= max_local, p, np.where(k <= max_local, k, min_local))
    return (_varint_lens(p) + varint_len(rowid) + local + np.where(local < p, 4, 0)
            + CELL_POINTER)


def pack_order(sizes, capacity: int) -> list[int]:
    """Indices of ``sizes`` in an order that fills pages of ``capacity`` bytes when the
    items are laid out one after another, each starting a new page when it does not fit
    the current one (best-fit decreasing: each item, largest first, goes to the open page
    with the least room that holds it). Deterministic; ties keep the input order."""
    order = sorted(range(len(sizes)), key=lambda i: -sizes[i])
    pages: list[list[int]] = []
    free: list[tuple[int, int]] = []  # (room left, page number), ascending
    for i in order:
        s = sizes[i]
        k = bisect_left(free, (s, -1))
        if k == len(free):
            pages.append([i])
            insort(free, (capacity - s, len(pages) - 1))
        else:
            room, p = free.pop(k)
            pages[p].append(i)
            insort(free, (room - s, p))
    return [i for p in pages for i in p]
