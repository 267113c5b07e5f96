"""Static mesh files written chunk by chunk: PLY, OBJ and STL in bounded memory.

:func:`write_static_mesh` writes the static mesh of bound e (every vertex with
δ > e, :func:`geoterrain.lod.static`) without building it as one ``PolyData``:
the chunks of :func:`geoterrain.lod.stream.static_chunks` go to hidden partial
files beside the output, and the file is assembled (header, vertices, faces)
and published only once complete (``atomicfiles.publish``: an interrupted or failed
write leaves nothing behind). The files hold what :func:`geoterrain.export.meshfiles.write_mesh`
writes for the same mesh:

- **PLY** (binary little-endian): float x, y, z (scene frame), float nx, ny, nz (the
  normalised sum of the unit normals of the triangles around each vertex, as VTK
  computes them) and the faces;
- **OBJ**: ``v x y z`` lines, then ``f a b c`` (1-based);
- **STL** (binary): one facet per triangle with its unit normal.

Memory: the flags and vertex map of :mod:`geoterrain.lod.stream`, its tile pool,
one chunk, and for PLY and STL the float32 positions (12 B per vertex; PLY adds
12 B of normal sums). Formats that cannot stream (.vtp, .vtk) go through
:func:`geoterrain.export.meshfiles.write_mesh`; :func:`check_in_memory` refuses a mesh too
large for the memory available before it is built.

Examples
--------
>>> import tempfile, os, pyvista as pv
>>> p = os.path.join(tempfile.mkdtemp(), "m.ply")
>>> st = write_static_mesh(t, 5.0, p)
>>> pv.read(p).n_cells == st["triangles"] == t.static_selection(5.0).stats["triangles"]
True
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from geoterrain._version import __version__
from geoterrain.core.atomicfiles import partial_path, publish, remove_stale_partials
from geoterrain.core.memory import available_memory
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.export.meshfiles import check_mesh_path

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

STREAM_FORMATS = (".ply", ".obj", ".stl")
# resident bytes per triangle of the in-memory path (PolyData, normals, the writer's
# copies): 7.13 GB (6 958 664 kB) for 31.8 M triangles at 4097², e = 0.1 (docs/store.md)
IN_MEMORY_BYTES_PER_TRIANGLE = 224
_BLOCK = 1 << 20  # vertices per block when assembling a PLY
# the terrain's decoded-tile cache while streaming (the pool holds what the walk reads)
STREAM_CACHE_BYTES = 128 << 20


@njit(cache=True)
def _add_normals(pos, faces, acc):
    """Add each face's unit normal (float64 from the float32 positions) to its corners."""
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ux, uy, uz = (np.float64(pos[b, 0]) - pos[a, 0], np.float64(pos[b, 1]) - pos[a, 1],
                      np.float64(pos[b, 2]) - pos[a, 2])
        vx, vy, vz = (np.float64(pos[c, 0]) - pos[a, 0], np.float64(pos[c, 1]) - pos[a, 1],
                      np.float64(pos[c, 2]) - pos[a, 2])
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        if ln > 0:
            for v in (a, b, c):
                acc[v, 0] += nx / ln
                acc[v, 1] += ny / ln
                acc[v, 2] += nz / ln


class _Positions:
    """float32 positions (and for PLY normal sums) of every vertex so far, grown by doubling."""

    def __init__(self, estimate: int, normals: bool):
        self.pos = np.empty((max(estimate, 1024), 3), np.float32)
        self.acc = np.zeros_like(self.pos) if normals else None
        self.n = 0

    def add(self, xyz: np.ndarray) -> None:
        need = self.n + len(xyz)
        if need > len(self.pos):
            size = max(need, 2 * len(self.pos))
            self.pos = np.concatenate([self.pos[:self.n], np.empty((size - self.n, 3),
                                                                   np.float32)])
            if self.acc is not None:
                self.acc = np.concatenate([self.acc[:self.n], np.zeros((size - self.n, 3),
                                                                       np.float32)])
        self.pos[self.n:need] = xyz
        self.n = need


def _rows(fmt: str, a: np.ndarray) -> bytes:
    if len(a) == 0:
        return b""
    return (((fmt + "\n") * len(a)) % tuple(a.ravel().tolist())).encode()


def write_static_mesh(terrain: TerrainLike, max_error: float, path: str | Path, *,
                      overwrite: bool = False,
                      chunk: int | None = None,
                      progress: Callable[[int, int], None] | None = None) -> dict:
    """Stream the static mesh of bound ``max_error`` to ``path`` (.ply, .obj or .stl).

    Returns the stats of :func:`geoterrain.lod.static` (``strategy`` 'static',
    ``triangles``, ``vertices``, ``tiles_decoded``, ``select_ms`` = the whole write, …)
    with ``streamed: True``. ``progress(done, total)`` is called after each chunk
    (leaf triangles walked). ``chunk``: leaf triangles per chunk (the output does
    not depend on it).
    """
    from geoterrain.lod.stream import CHUNK, static_chunks

    out = check_mesh_path(path, overwrite)
    ext = out.suffix.lower()
    if ext not in STREAM_FORMATS:
        raise UsageError(f"{out}: {ext} cannot be streamed; use one of "
                         f"{', '.join(STREAM_FORMATS)}")
    e = _check_error(max_error)
    remove_stale_partials(out.parent if str(out.parent) else Path("."))
    tmp = partial_path(out)
    vtx, fac = tmp.with_name(tmp.name + ".vtx"), tmp.with_name(tmp.name + ".fac")
    t0, dec0 = time.perf_counter(), terrain.decoded_tiles
    nf = nv = 0
    try:
        ffh = open(fac if ext != ".stl" else tmp, "wb")  # noqa: SIM115 (closed below)
        vfh = open(vtx, "wb") if ext == ".obj" else None  # noqa: SIM115
        try:
            if ext == ".stl":
                ffh.write(f"geoterrain {__version__} static mesh".encode().ljust(80, b" "))
                ffh.write(b"\0\0\0\0")  # the facet count, written at the end
            store = None
            for c in static_chunks(terrain, e, chunk=chunk or CHUNK):
                if store is None:
                    store = _Positions(c.total // 2 + 2 * sum(terrain.grid.extent),
                                       ext == ".ply")
                if ext == ".obj":
                    vfh.write(_rows("v %.17g %.17g %.17g", c.xyz))
                    ffh.write(_rows("f %d %d %d", c.faces + 1))
                else:
                    store.add(c.xyz)
                    if ext == ".ply":
                        _add_normals(store.pos, c.faces, store.acc)
                        rec = np.empty(len(c.faces), [("n", "u1"), ("i", "<i4", 3)])
                        rec["n"], rec["i"] = 3, c.faces
                        ffh.write(rec.tobytes())
                    else:
                        ffh.write(_stl_facets(store.pos, c.faces))
                nf += len(c.faces)
                nv += len(c.xyz)
                if progress is not None:
                    progress(c.done, c.total)
        finally:
            ffh.close()
            if vfh is not None:
                vfh.close()
        if ext == ".stl":
            with open(tmp, "r+b") as fh:
                fh.seek(80)
                fh.write(np.uint32(nf).tobytes())
        else:
            with open(tmp, "wb") as fh:
                if ext == ".ply":
                    _ply_assemble(fh, store, nv, nf, fac)
                else:
                    fh.write(f"# geoterrain {__version__} static mesh (scene frame, metres), "
                             f"{nv} vertices, {nf} triangles\n".encode())
                    for part in (vtx, fac):
                        with open(part, "rb") as src:
                            shutil.copyfileobj(src, fh, 1 << 22)
        publish(tmp, out, overwrite)
    except OSError as exc:
        raise WriteError(f"{out}: cannot write the mesh ({exc.strerror or exc})") from None
    finally:
        for p in (tmp, vtx, fac):
            p.unlink(missing_ok=True)
    return {"strategy": "static", "triangles": nf, "skirt_triangles": 0, "vertices": nv,
            "tiles_visited": 0, "tiles_culled": 0,
            "tiles_decoded": int(terrain.decoded_tiles - dec0),
            "select_ms": round((time.perf_counter() - t0) * 1e3, 3), "reused": False,
            "max_error": e, "streamed": True}


def _ply_assemble(fh, store: _Positions | None, nv: int, nf: int, fac: Path) -> None:
    head = ["ply", "format binary_little_endian 1.0",
            f"comment generator geoterrain {__version__} (static mesh, scene frame)",
            f"element vertex {nv}", *(f"property float {a}" for a in ("x", "y", "z", "nx", "ny",
                                                                       "nz")),
            f"element face {nf}", "property list uchar int vertex_indices", "end_header"]
    fh.write(("\n".join(head) + "\n").encode())
    for k in range(0, nv, _BLOCK):
        e = min(k + _BLOCK, nv)
        n = store.acc[k:e].astype(np.float64)
        ln = np.linalg.norm(n, axis=1)
        bad = ln == 0
        n[bad], ln[bad] = (0.0, 0.0, 1.0), 1.0
        rec = np.empty((len(n), 6), "<f4")
        rec[:, :3] = store.pos[k:e]
        rec[:, 3:] = n / ln[:, None]
        fh.write(rec.tobytes())
    with open(fac, "rb") as src:
        shutil.copyfileobj(src, fh, 1 << 22)


def _stl_facets(pos: np.ndarray, faces: np.ndarray) -> bytes:
    p = pos[faces].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
    rec = np.zeros(len(faces), np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    rec["n"], rec["v"] = n, p
    return rec.tobytes()


def _check_error(max_error) -> float:
    try:
        e = float(max_error)
    except (TypeError, ValueError):
        raise UsageError(f"max_error must be a number, got {max_error!r}") from None
    if not (e >= 0 and not math.isnan(e)):
        raise UsageError(f"max_error must be ≥ 0, got {max_error}")
    return e


def estimated_triangles(terrain: TerrainLike, max_error: float) -> int:
    """Triangles of the static mesh of bound ``max_error``, counted without building it
    (the flags and one walk of :mod:`geoterrain.lod.stream`; no heights are read).

    Examples
    --------
    >>> estimated_triangles(t, 5.0) >= t.static_selection(5.0).stats["triangles"]
    True
    """
    from geoterrain.lod.pool import TilePool
    from geoterrain.lod.stream import POOL_BYTES, _count_leaves, static_flags

    act = static_flags(terrain, _check_error(max_error), TilePool(terrain, POOL_BYTES))
    return int(_count_leaves(act.active, act.mixed))


def check_in_memory(terrain: TerrainLike, max_error: float, path: str | Path,
                    available: int | None = None) -> None:
    """Refuse (a :class:`UsageError` naming the streaming formats) a static mesh to a
    format that cannot stream when building it in memory would not fit.

    Cheap for small grids: the count (:func:`estimated_triangles`) is only made when
    the finest possible mesh (2 (N − 1)² triangles) could exceed the memory available.

    Examples
    --------
    >>> check_in_memory(t, 5.0, "m.vtp")  # small: nothing to refuse
    """
    avail = available_memory() if available is None else available
    R, C = terrain.grid.extent  # N × N, or a root grid's extent
    if 2 * (R - 1) * (C - 1) * IN_MEMORY_BYTES_PER_TRIANGLE <= avail:
        return
    F = estimated_triangles(terrain, max_error)
    need = F * IN_MEMORY_BYTES_PER_TRIANGLE
    if need > avail:
        ext = Path(path).suffix.lower()
        raise UsageError(
            f"the static mesh has about {F:,} triangles, about {need / 1e9:.1f} GB to build in "
            f"memory for {ext}, more than the {avail / 1e9:.1f} GB available; write "
            f"{', '.join(STREAM_FORMATS)} (streamed to disk) or raise max_error",
            cli=f"the static mesh has about {F:,} triangles, about {need / 1e9:.1f} GB to "
                f"build in memory for {ext}, more than the {avail / 1e9:.1f} GB available; "
                f"use -o with {', '.join(STREAM_FORMATS)} (streamed to disk) or raise "
                "--max-error")
