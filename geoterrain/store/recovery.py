"""What an interrupted edit or a stranger's SQLite leaves beside a store: a killed edit's
hot journal rolled back (the one write a reader makes), a running edit's lock seen, a
file in WAL mode recognised. :class:`geoterrain.store.reader.StoreReader` asks these
before it opens a store read-only.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from geoterrain.exceptions import StoreError

JOURNAL_MAGIC = bytes.fromhex("d9d505f920a163d7")  # a rollback journal's header (SQLite)


def writer_active(path: Path) -> bool:
    """Whether another process holds SQLite's RESERVED lock on the store (an edit in its
    transaction): asked of the file's POSIX locks, taking none."""
    import fcntl
    import struct

    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:  # struct flock: type, whence, start, len, pid; RESERVED_BYTE is 2^30 + 1
        lk = struct.pack("hhqqi", fcntl.F_RDLCK, os.SEEK_SET, 0x40000001, 1, 0)
        got = fcntl.fcntl(fd, fcntl.F_GETLK, lk)
        return struct.unpack("hhqqi", got)[0] != fcntl.F_UNLCK
    except OSError:
        return False
    finally:
        os.close(fd)


def wal_mode(path: Path) -> bool:
    """Whether the SQLite file ``path`` is in WAL mode (its header's read/write versions)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(20)
    except OSError:
        return False
    return len(head) == 20 and head[18] == 2 and head[19] == 2


def roll_back_interrupted_edit(path: Path) -> None:
    """An edit killed in its transaction leaves ``STORE-journal`` (the old pages) beside
    the store: SQLite rolls it back when a connection that may write reads the file, and
    a read-only one refuses the file meanwhile. This opens such a connection once and
    reads the schema, which restores the old store; no SQL of the file's runs. A journal
    of an edit still running (it holds its lock) is left alone."""
    journal = Path(str(path) + "-journal")
    try:
        with open(journal, "rb") as fh:
            if fh.read(len(JOURNAL_MAGIC)) != JOURNAL_MAGIC:
                return  # none, or not SQLite's: the reader refuses it without writing
    except OSError:
        return
    try:
        con = sqlite3.connect(path, timeout=30.0)
        try:
            con.execute("PRAGMA trusted_schema=OFF")
            con.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        finally:
            con.close()
    except sqlite3.Error:
        raise StoreError(f"{path}: an interrupted edit left {journal.name} beside it; open "
                         "the store once where it can be written (the edit is rolled back "
                         "then), and keep the journal with it until then") from None
