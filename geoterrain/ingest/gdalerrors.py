"""GDAL's reason for a failed open or read, in the one line a user sees."""

from __future__ import annotations

import re

__all__ = ["gdal_reason"]


def gdal_reason(exc: BaseException) -> str:
    """GDAL's reason for a failed open or read, in one line: the first message in the
    exception's chain that names a file or URL (a mosaic's tile that failed), else the
    first that says more than "see previous exception".

    Examples
    --------
    >>> gdal_reason(OSError("a.tif: TIFFReadEncodedStrip() failed.\\nmore"))
    'a.tif: TIFFReadEncodedStrip() failed.'
    """
    seen = []
    x: BaseException | None = exc
    while x is not None and len(seen) < 8:
        line = str(x).strip().splitlines()[0] if str(x).strip() else ""
        if line:
            seen.append(line)
        x = x.__cause__ or x.__context__
    useful = [s for s in seen if "previous exception" not in s]
    named = [s for s in useful if _NAMES.search(s)]  # one that names the file or URL
    return (named or useful or seen or ["unreadable"])[0]


_NAMES = re.compile(r"(https?://|[\w.-]+\.\w{2,5}\b)")
