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

from geoterrain.core.atomicfiles import partial_path, publish
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError

if TYPE_CHECKING:
    import pyvista as pv

MESH_FORMATS = (".ply", ".vtp", ".stl", ".obj", ".vtk")
_BARE = (".stl", ".obj")  # formats that carry no point or cell arrays


def check_output_path(path: str | Path, formats: tuple[str, ...], overwrite: bool = False,
                      what: str = "mesh", inputs=()) -> Path:
    """``path`` as a Path if a file of one of ``formats`` can be written there: a known
    suffix, and :func:`geoterrain.core.paths.check_output`'s rules (an existing folder; a
    regular file there replaced only with ``overwrite``, never one of ``inputs``); a
    :class:`UsageError` otherwise (checked before any work is done).

    Examples
    --------
    >>> check_output_path("out.ply", MESH_FORMATS).suffix
    '.ply'
    """
    out = Path(path)
    if out.suffix.lower() not in formats:
        raise UsageError(f"{out}: unknown {what} format; use one of {', '.join(formats)}")
    return check_output(out, overwrite, inputs=inputs)


def check_mesh_path(path: str | Path, overwrite: bool = False, inputs=()) -> Path:
    """:func:`check_output_path` for :data:`MESH_FORMATS`.

    Examples
    --------
    >>> check_mesh_path("out.ply").suffix
    '.ply'
    """
    return check_output_path(path, MESH_FORMATS, overwrite, inputs=inputs)


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
    tmp = partial_path(out)
    tmp = tmp.with_name(tmp.name + out.suffix)  # VTK picks the writer by suffix
    try:
        mesh.save(str(tmp))
        publish(tmp, out, overwrite)
    except OSError as exc:
        raise WriteError(f"{out}: cannot write the mesh ({exc.strerror or exc})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return out
