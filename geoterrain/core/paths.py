"""What a path names, for the messages and checks of every reader and writer.

A writer asks :func:`check_output` about each file it will write (the output, its stats
and its sidecars) before any work: only a regular file (or a folder where a folder is
asked for) is ever replaced, only with ``overwrite``, never through a symbolic link, and
never when it is one of the command's inputs. :func:`geoterrain.core.atomicfiles.publish`
asks again at the moment it moves the finished file into place. A reader asks
:func:`input_problem` why a path cannot be read, so a device, a FIFO or a symbolic-link
loop is named as such, not as a missing file.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Iterable
from pathlib import Path

from geoterrain.exceptions import UsageError, exists_error

__all__ = ["STORE_SUFFIX", "check_output", "default_store_path", "input_problem", "kind_of",
           "same_file"]

STORE_SUFFIX = ".geoterrain"  # a store's file name ends so (store.schema.is_store)

_KINDS = ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a directory"),
          (stat.S_ISLNK, "a symbolic link"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISSOCK, "a socket"))


def kind_of(mode: int) -> str:
    """What an ``st_mode`` names, in words.

    Examples
    --------
    >>> kind_of(os.stat(".").st_mode)
    'a directory'
    """
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _os_problem(exc: OSError) -> str:
    if exc.errno == errno.ENOENT:
        return "no such file"
    if exc.errno == errno.ELOOP:
        return "a symbolic link loop"
    if exc.errno == errno.ENAMETOOLONG:
        return "file name too long"
    if exc.errno == errno.ENOTDIR:
        return "a part of the path is not a directory"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    return exc.strerror or str(exc)


def _not_utf8(path: str | Path) -> bool:
    """Whether a file name holds bytes that are not UTF-8 (GDAL, SQLite and VTK take only
    UTF-8 names)."""
    try:
        os.fspath(path).encode("utf-8") if isinstance(os.fspath(path), str) else \
            os.fspath(path).decode("utf-8")
    except UnicodeError:
        return True
    return False


NOT_UTF8 = "a file name that is not UTF-8, which GDAL cannot open; rename it"


def input_problem(path: str | Path, *, folder: bool = False, utf8: bool = False
                  ) -> str | None:
    """Why ``path`` cannot be read as a file (or a ``folder``), in a few words; None if it
    can be. ``utf8``: a name that is not UTF-8 is a problem too (a raster GDAL opens).

    Examples
    --------
    >>> input_problem("/no/such/file.tif")
    'no such file'
    >>> input_problem("/dev/null")
    'a character device, not a file'
    """
    try:
        st = os.stat(path)
    except OSError as exc:
        return _os_problem(exc)
    except ValueError:  # an embedded NUL
        return "not a valid file name"
    if utf8 and _not_utf8(path):
        return NOT_UTF8
    if folder and not stat.S_ISDIR(st.st_mode):
        return f"{kind_of(st.st_mode)}, not a folder"
    if not folder and not stat.S_ISREG(st.st_mode):
        return f"{kind_of(st.st_mode)}, not a file"
    return None


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` are the same file (device and inode, links followed).

    Examples
    --------
    >>> same_file(".", "./"), same_file("/no/such", "/no/such")
    (True, False)
    """
    try:
        sa, sb = os.stat(a), os.stat(b)
    except (OSError, ValueError):
        return False
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


def check_output(path: str | Path, overwrite: bool, *, folder: bool = False,
                 inputs: Iterable[str | Path] = (), option: str = "-o") -> Path:
    """``path`` as a Path if a command may write it: its folder exists, and what is there
    now (if anything) is a regular file (a folder with ``folder``) that ``overwrite``
    allows to replace, reached without a symbolic link, and none of ``inputs``. Else a
    one-line :class:`UsageError` that names the fix (``option``: how the command line
    names the path).

    Examples
    --------
    >>> check_output("new.png", overwrite=False).name
    'new.png'
    >>> try:
    ...     check_output("/dev/null", overwrite=True)
    ... except UsageError as e:
    ...     print(e)
    /dev/null is a character device: geoterrain replaces only regular files; choose another path
    """
    p = Path(path)
    what = "folder" if folder else "file"
    if _not_utf8(p):  # SQLite, GDAL and VTK write only UTF-8 names
        raise UsageError(f"{_show(p)}: the name is not UTF-8; choose another path",
                         cli=f"{_show(p)}: the name is not UTF-8; choose another {option} "
                             "path")
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        st = None
    except (OSError, ValueError) as exc:
        why = _os_problem(exc) if isinstance(exc, OSError) else "not a valid file name"
        raise UsageError(f"{_show(p)}: {why}; choose another path",
                         cli=f"{_show(p)}: {why}; choose another {option} path") from None
    if st is None:
        parent = p.parent if str(p.parent) else Path(".")
        why = input_problem(parent, folder=True)
        if why is not None:
            why = "no such directory" if why == "no such file" else why
            raise UsageError(f"{_show(parent)}: {why}; create the folder first or choose "
                             "another path", cli=f"{_show(parent)}: {why}; create the folder "
                             f"first or choose another {option} path")
        return p
    mode = st.st_mode
    if stat.S_ISLNK(mode):
        raise UsageError(f"{_show(p)} is a symbolic link: geoterrain does not write through "
                         f"one; give the {what}'s own path",
                         cli=f"{_show(p)} is a symbolic link: geoterrain does not write "
                             f"through one; give the {what}'s own path to {option}")
    if folder != stat.S_ISDIR(mode) or not (stat.S_ISDIR(mode) or stat.S_ISREG(mode)):
        fix = (f"give a {what} path" if stat.S_ISDIR(mode) or stat.S_ISREG(mode)
               else "choose another path")
        only = "folders" if folder else "regular files"
        raise UsageError(f"{_show(p)} is {kind_of(mode)}: geoterrain replaces only {only}; "
                         f"{fix}", cli=f"{_show(p)} is {kind_of(mode)}: geoterrain replaces "
                         f"only {only}; {fix}" + (f" to {option}" if "path" in fix else ""))
    for src in inputs:
        if src is not None and same_file(src, p):
            raise UsageError(f"{_show(p)} is also this command's input; choose another path",
                             cli=f"{_show(p)} is also this command's input; choose another "
                                 f"{option} path")
    if not folder and not overwrite:
        raise exists_error(_show(p))
    return p


def check_replaceable(dst: Path, folder: bool = False) -> None:
    """At publish time: ``dst`` is absent, a regular file, or (``folder``) a folder (a
    device or a link put there since :func:`check_output` is never replaced)."""
    try:
        mode = os.lstat(dst).st_mode
    except FileNotFoundError:
        return
    ok = stat.S_ISDIR(mode) if folder else stat.S_ISREG(mode)
    if not ok:
        raise UsageError(f"{_show(dst)} is {kind_of(mode)}: geoterrain replaces only "
                         f"{'folders' if folder else 'regular files'}; choose another path")


def _show(p: str | Path) -> str:
    """A path for a one-line message: undecodable bytes escaped, at most 200 characters."""
    s = os.fsdecode(p) if isinstance(p, bytes) else str(p)
    s = s.encode("utf-8", "backslashreplace").decode("utf-8")
    s = "".join(c if c.isprintable() else "?" for c in s)
    return s if len(s) <= 200 else s[:96] + "…" + s[-96:]


def default_store_path(src: str | Path) -> Path:
    """The store a preprocess of ``src`` writes by default: its path with the suffix
    :data:`STORE_SUFFIX`.

    Examples
    --------
    >>> default_store_path("dem/fuji.tif").name
    'fuji.geoterrain'
    """
    return Path(src).with_suffix(STORE_SUFFIX)
