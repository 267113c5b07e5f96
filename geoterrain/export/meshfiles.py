"""Write meshes to files: the last stage of the pipeline, for other tools to read.

Examples
--------
>>> import tempfile, os, pyvista as pv
>>> p = write_mesh(pv.Plane(), os.path.join(tempfile.mkdtemp(), "plane.ply"))
>>> p.name, pv.read(p).n_cells > 0
('plane.ply', True)
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from geoterrain.exceptions import UsageError, WriteError, exists_error

if TYPE_CHECKING:
    import pyvista as pv

MESH_FORMATS = (".ply", ".vtp", ".stl", ".obj", ".vtk")
_BARE = (".stl", ".obj")  # formats that carry no point or cell arrays


def check_output_path(path: str | Path, formats: tuple[str, ...], overwrite: bool = False,
                      what: str = "mesh") -> Path:
    """``path`` as a Path if a file of one of ``formats`` can be written there: a known
    suffix, an existing folder, and no existing file unless ``overwrite``; a
    :class:`UsageError` otherwise (checked before any work is done).

    Examples
    --------
    >>> check_output_path("out.ply", MESH_FORMATS).suffix
    '.ply'
    """
    out = Path(path)
    if out.suffix.lower() not in formats:
        raise UsageError(f"{out}: unknown {what} format; use one of {', '.join(formats)}")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"{parent}: no such directory; create it first or choose another path",
                         cli=f"{parent}: no such directory; create it first or choose another "
                             "-o path")
    if out.exists() and not overwrite:
        raise exists_error(out)
    return out


def check_mesh_path(path: str | Path, overwrite: bool = False) -> Path:
    """:func:`check_output_path` for :data:`MESH_FORMATS`.

    Examples
    --------
    >>> check_mesh_path("out.ply").suffix
    '.ply'
    """
    return check_output_path(path, MESH_FORMATS, overwrite)


def write_mesh(mesh: pv.PolyData, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``mesh`` to ``path`` (.ply, .vtp, .stl, .obj or .vtk) atomically.

    The file is written beside the destination under a hidden name and renamed
    into place only once complete, so a failed write leaves nothing behind.
    STL and OBJ get the geometry alone.
    """
    out = check_mesh_path(path, overwrite)
    if out.suffix.lower() in _BARE:
        mesh = mesh.copy()
        mesh.clear_data()
    tmp = out.with_name(f".{out.name}.partial{out.suffix}")
    try:
        mesh.save(str(tmp))
        tmp.replace(out)
    except OSError as exc:
        raise WriteError(f"{out}: cannot write the mesh ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
