"""Rasters read over HTTP (issue 45): URLs, and text files that list them.

GDAL reads an ``http(s)://`` raster through its ``/vsicurl/`` reader: ranged requests for
the blocks a read needs (a Cloud-Optimised GeoTIFF's header, then its tiles), retried
on failure (:data:`geoterrain.ingest.raster.GDAL_READ_OPTIONS`). :class:`Url` stands
where a local :class:`~pathlib.Path` would (its name, "exists"), so a URL goes wherever a
file goes: alone, in a list, in a mosaic's VRT (as ``/vsicurl/URL``), as a merged
source. A ``.txt`` file lists sources, one URL or path a line (``#`` comments; a relative
path is taken from the list's folder): the STAC-style list of tiles a search returns.
"""

from __future__ import annotations

from pathlib import Path, PurePosixPath
from urllib.parse import urlsplit

__all__ = ["Url", "is_url", "list_file", "read_list"]

SCHEMES = ("http://", "https://")
LIST_SUFFIXES = (".txt",)


def is_url(s: object) -> bool:
    """Whether ``s`` is an HTTP(S) URL or a GDAL ``/vsicurl/`` path.

    Examples
    --------
    >>> is_url("https://example.com/dem.tif"), is_url("dem.tif")
    (True, False)
    """
    return isinstance(s, (str, Url)) and str(s).lower().startswith(SCHEMES + ("/vsicurl/",))


class Url:
    """A raster's URL where a path is expected: ``str()`` is what rasterio opens,
    ``gdal`` what a VRT names (``/vsicurl/URL``), ``name`` the last part of its path.

    Examples
    --------
    >>> u = Url("https://example.com/tiles/N35E139.tif?sig=1")
    >>> u.name, u.stem, u.gdal
    ('N35E139.tif', 'N35E139', '/vsicurl/https://example.com/tiles/N35E139.tif?sig=1')
    """

    def __init__(self, url: str) -> None:
        url = str(url)
        self.url = url[len("/vsicurl/"):] if url.startswith("/vsicurl/") else url

    def __str__(self) -> str:
        return self.url

    def __repr__(self) -> str:
        return f"Url({self.url!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Url) and other.url == self.url

    def __hash__(self) -> int:
        return hash(self.url)

    @property
    def gdal(self) -> str:
        return "/vsicurl/" + self.url

    @property
    def name(self) -> str:
        return PurePosixPath(urlsplit(self.url).path).name or self.url

    @property
    def stem(self) -> str:
        return PurePosixPath(self.name).stem

    @property
    def suffix(self) -> str:
        return PurePosixPath(self.name).suffix

    def exists(self) -> bool:  # a request says (GDAL's open names the URL if it fails)
        return True

    def is_file(self) -> bool:
        return True

    def is_dir(self) -> bool:
        return False

    def resolve(self) -> Url:
        return self


def list_file(src: object) -> bool:
    """Whether ``src`` names a local text file that lists sources."""
    return (isinstance(src, (str, Path)) and not is_url(src)
            and Path(src).suffix.lower() in LIST_SUFFIXES and Path(src).is_file())


def read_list(path: str | Path) -> list[str | Path]:
    """The sources a text file lists: URLs, and paths from the list's folder.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "tiles.txt")
    >>> _ = open(p, "w").write("# two tiles\\nhttps://h/a.tif\\nb.tif\\n")
    >>> [str(s).split("/")[-1] for s in read_list(p)]
    ['a.tif', 'b.tif']
    """
    path = Path(path)
    out: list[str | Path] = []
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        out.append(line if is_url(line) else (path.parent / line))
    return out
