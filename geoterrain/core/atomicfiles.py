"""Output files written whole or not at all: a hidden partial beside the destination,
published in one step, and the partials of killed processes removed by the next run.

Stores (:class:`geoterrain.store.writer.StoreWriter`), pictures, animations, meshes and stats
are all written this way, so an error or an interrupt never leaves a half-written file
under the name asked for. What may be replaced is :mod:`geoterrain.core.paths`'s rule
(a regular file, or a folder of frames; never a device, a FIFO or a link), checked
before the work by :func:`~geoterrain.core.paths.check_output` and again here.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from geoterrain.core.paths import check_replaceable
from geoterrain.exceptions import UsageError, WriteError, exists_error

_PARTIAL = re.compile(r"^\..+\.partial-(\d+)(\.[A-Za-z0-9]{1,8})?$")


def publish(tmp: str | Path, dst: str | Path, overwrite: bool) -> None:
    """Move a finished partial file (or folder) ``tmp`` to ``dst`` in one step.

    With ``overwrite`` a rename replaces ``dst``, if it is a regular file (a folder when
    ``tmp`` is one); without, the publish is a create-if-absent (a hard link, then the
    partial is unlinked), so of two racing writers exactly one wins and the other gets
    "exists". Anything else at ``dst`` (a device, a FIFO, a link) is left as it is, and
    the partial is removed.

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp()); (d / ".a.partial-1").write_text("x")
    1
    >>> publish(d / ".a.partial-1", d / "a", overwrite=False); (d / "a").read_text()
    'x'
    """
    tmp, dst = Path(tmp), Path(dst)
    folder = os.path.isdir(tmp) and not os.path.islink(tmp)
    try:
        check_replaceable(dst, folder)
    except UsageError:
        _remove(tmp)
        raise
    if overwrite:
        if folder and os.path.isdir(dst):  # a folder of frames: swap, then drop the old one
            import shutil

            old = dst.parent / f".{dst.name}.old.partial-{os.getpid()}"
            os.rename(dst, old)
            os.rename(tmp, dst)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, dst)
        return
    if folder:
        if os.path.lexists(dst):
            _remove(tmp)
            raise exists_error(dst)
        os.rename(tmp, dst)  # renaming a folder onto a non-empty folder fails
        return
    try:
        os.link(tmp, dst)
    except FileExistsError:
        os.unlink(tmp)
        raise exists_error(dst) from None
    except OSError:  # a file system without hard links
        if os.path.lexists(dst):
            os.unlink(tmp)
            raise exists_error(dst) from None
        os.replace(tmp, dst)
    else:
        os.unlink(tmp)


def _remove(tmp: Path) -> None:
    """Drop a partial file or folder."""
    import shutil

    if os.path.isdir(tmp) and not os.path.islink(tmp):
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.unlink(missing_ok=True)


def write_atomic(path: str | Path, data: str | bytes, overwrite: bool = True) -> Path:
    """Write ``data`` to a hidden partial beside ``path``, then :func:`publish` it: a failed
    or interrupted write never leaves a half-written file (JSON stats, sidecars).

    Examples
    --------
    >>> import tempfile
    >>> p = write_atomic(Path(tempfile.mkdtemp()) / "s.json", '{"a": 1}'); p.read_text()
    '{"a": 1}'
    """
    path = Path(path)
    tmp = partial_path(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
        publish(tmp, path, overwrite)
    except OSError as exc:
        raise WriteError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (a partial of a live writer is kept)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def partial_path(dst: str | Path) -> Path:
    """The hidden partial file this process writes before publishing ``dst``.

    Examples
    --------
    >>> partial_path("out/a.png").name.startswith(".a.png.partial-")
    True
    """
    dst = Path(dst)
    return dst.parent / f".{dst.name}.partial-{os.getpid()}"


def remove_stale_partials(folder: str | Path) -> list[Path]:
    """Delete ``.NAME.partial-PID`` files (or folders) left in ``folder`` by dead processes.

    A killed writer (SIGKILL cannot be caught) leaves its partial file; the next
    run in the same folder removes it. Partials of live processes are kept.

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp()); (d / ".a.geoterrain.partial-999999999").write_bytes(b"")
    0
    >>> [p.name for p in remove_stale_partials(d)]
    ['.a.geoterrain.partial-999999999']
    """
    import shutil

    gone = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return gone
    for e in entries:
        m = _PARTIAL.match(e.name)
        if not m or int(m.group(1)) == os.getpid() or pid_alive(int(m.group(1))):
            continue
        try:
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path)
            else:
                os.unlink(e.path)
            gone.append(Path(e.path))
        except OSError:
            pass
    return gone
