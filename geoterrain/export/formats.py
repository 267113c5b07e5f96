"""Georeferenced mesh files for other tools: glTF/GLB, OBJ + MTL + PNG, PLY, printable STL.

Every file is written from a :class:`~geoterrain.lod.Selection` (a static or a
view-dependent LOD mesh) and says where it is on Earth:

- **glTF / GLB** (pygltflib): float32 positions relative to the scene origin (the
  raster centre), glTF's Y-up axes (x = east, y = up, z = −north), normals, an
  ``_ELEVATION`` attribute (metres), the shading texture (elevation colours ×
  hillshade, :mod:`geoterrain.rendering.textures`; or an image draped by
  :mod:`geoterrain.rendering.drape`)
  embedded in an unlit material, and the georeference
  (:func:`~geoterrain.export.meshdata.georeference`) in ``asset.extras.geoterrain``
  and a sidecar ``<file>.json``.
- **OBJ** with an MTL and a PNG texture beside it (and the sidecar).
- **PLY** (binary): x, y, z (float64), normals, ``elevation``; the CRS and the origin
  offset in header comments. ``crs_coords=True`` writes source-CRS x, y of each
  vertex's sample (pyproj through :class:`~geoterrain.core.frame.Frame`) and z = elevation.
- **STL**: a closed, printable solid
  (:func:`~geoterrain.export.solids.printable_solid`): the surface, vertical walls
  along its boundary and a flat base ``base_height`` under the lowest point;
  ``print_size`` scales the longer side to that many millimetres.

``base_height`` or ``print_size`` close a glTF, OBJ or PLY into the same solid: the
textured surface, and walls and a flat bottom in one plain material (glTF: a second
primitive; OBJ: a second group and material). glTF's unit is the metre, so a 150 mm
print is 0.15 m wide there; OBJ, PLY and STL are in millimetres. Textures cover the
data's rectangle only (the store's padding is cut off). Vertical exaggeration is the
terrain's: export an :func:`~geoterrain.exaggerate.exaggerated` terrain and its
selection (``geoterrain export -z N``).

Every file is written under a hidden name beside its destination and renamed into
place once complete, so a failed export leaves nothing behind.

Examples
--------
>>> import tempfile, os
>>> sel = t.static_selection(5.0)
>>> p = export_mesh(t, sel, os.path.join(tempfile.mkdtemp(), "t.glb"))
>>> p.name, p.with_name("t.glb.json").exists()
('t.glb', True)
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain._version import __version__
from geoterrain.core.atomicfiles import partial_path, publish
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.export.meshdata import MeshArrays, georeference, mesh_arrays, vertex_normals
from geoterrain.export.meshfiles import check_output_path
from geoterrain.export.solids import Solid, solid, stl_bytes
from geoterrain.rendering.textures import SHADINGS, texture_image

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

EXPORT_FORMATS = (".glb", ".gltf", ".obj", ".stl", ".ply")
TEXTURE_SIZE = 4097  # samples per side of an exported texture at most (a coarser level beyond)
WALL_COLOUR = (0.62, 0.58, 0.52)  # a solid's walls and bottom: a plain warm grey


def data_shape(terrain: TerrainLike, level: int) -> tuple[int, int]:
    """(rows, cols) of level L's samples within the DEM (the texture's size)."""
    s = 1 << level
    return -(-terrain.grid.rows // s), -(-terrain.grid.cols // s)


def _tcoords(terrain: TerrainLike, ij: np.ndarray, level: int, flip: bool) -> np.ndarray:
    """Texture coordinates of samples ``ij`` in the level-L texture cropped to the data
    (:func:`data_shape`; row 0 at the top)."""
    H, W = data_shape(terrain, level)
    s = float(1 << level)
    uv = np.empty((len(ij), 2), np.float32)
    uv[:, 0] = np.clip((ij[:, 1] / s + 0.5) / W, 0.0, 1.0)
    uv[:, 1] = np.clip((ij[:, 0] / s + 0.5) / H, 0.0, 1.0)
    if flip:
        uv[:, 1] = 1.0 - uv[:, 1]
    return uv


def _png(img: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def export_texture_level(terrain: TerrainLike, texture_size: int = TEXTURE_SIZE) -> int:
    """The finest level whose data (not its padded square) fits ``texture_size`` texels a
    side.

    Examples
    --------
    >>> export_texture_level(t, 40)
    2
    """
    for L in terrain.grid.levels:
        if max(data_shape(terrain, L)) <= texture_size:
            return L
    return terrain.grid.top_level


def _texture(terrain: TerrainLike, shading: str, cmap: str, texture_size: int,
             drape: str | Path | None = None) -> tuple[np.ndarray, int]:
    """The texture (H, W, 3) uint8 of the data's rectangle at the level it is taken from."""
    if shading not in SHADINGS or shading == "plain":
        raise UsageError(f"unknown texture shading {shading!r}; use normals or elevation")
    if texture_size < 2:
        raise UsageError(f"texture_size must be ≥ 2, got {texture_size}")
    L = export_texture_level(terrain, texture_size)
    img = texture_image(terrain, shading, cmap, L)
    if drape is not None:
        from geoterrain.rendering.drape import drape_image

        img = drape_image(terrain, drape, L, base=img)
    H, W = data_shape(terrain, L)
    return np.ascontiguousarray(img[:H, :W]), L


class _Files:
    """Several files written under hidden names, renamed into place together at the end."""

    def __init__(self, overwrite: bool):
        self.overwrite = overwrite
        self.items: list[tuple[Path, Path]] = []

    def path(self, out: Path) -> Path:
        check_output(out, self.overwrite)
        tmp = partial_path(out)
        tmp = tmp.with_name(tmp.name + out.suffix)
        self.items.append((tmp, out))
        return tmp

    def write(self, out: Path, data: bytes | str) -> None:
        tmp = self.path(out)
        (tmp.write_text if isinstance(data, str) else tmp.write_bytes)(data)

    def commit(self) -> None:
        for tmp, out in self.items:
            publish(tmp, out, self.overwrite)

    def discard(self) -> None:
        for tmp, _ in self.items:
            tmp.unlink(missing_ok=True)


def export_paths(out: str | Path) -> list[Path]:
    """Every file an export to ``out`` writes: ``out``, then its sidecars (the
    georeference ``OUT.json``; an OBJ's material ``.mtl`` and texture ``.png``).

    Examples
    --------
    >>> [p.name for p in export_paths("dem.obj")]
    ['dem.obj', 'dem.obj.json', 'dem.mtl', 'dem.png']
    """
    out = Path(out)
    ext = out.suffix.lower()
    side = [] if ext == ".ply" else [out.with_name(out.name + ".json")]
    if ext == ".obj":
        side += [out.with_suffix(".mtl"), out.with_suffix(".png")]
    return [out, *side]


# peak resident bytes per triangle of a static mesh exported in memory (the selection, its
# arrays, normals, the texture's coordinates and the file's bytes): 9.81 GB for 31.8 M
# triangles at 4097², e = 0.1, as .glb (issue 49)
EXPORT_BYTES_PER_TRIANGLE = 320


def check_export_memory(terrain: TerrainLike, max_error: float, limit: int) -> int:
    """Refuse (one line, before any work) a static export whose estimated peak memory
    passes ``limit`` bytes: its triangles counted without building the mesh
    (:func:`geoterrain.export.meshstream.estimated_triangles`, only when the finest mesh
    could pass it), times :data:`EXPORT_BYTES_PER_TRIANGLE`. Returns the estimate in
    bytes (0 when the finest mesh fits).

    Examples
    --------
    >>> check_export_memory(t, 1.0, 1 << 30)
    0
    """
    from geoterrain.export.meshstream import estimated_triangles

    R, C = terrain.grid.extent  # N × N, or a root grid's extent
    if 2 * (R - 1) * (C - 1) * EXPORT_BYTES_PER_TRIANGLE <= limit:
        return 0
    F = estimated_triangles(terrain, max_error)
    need = F * EXPORT_BYTES_PER_TRIANGLE
    if need > limit:
        msg = (f"the static mesh has about {F:,} triangles, about {need / 1e9:.1f} GB to "
               f"export, more than the {limit / 1e9:.1f} GB memory limit")
        raise UsageError(f"{msg}; raise max_error or the memory limit",
                         cli=f"{msg}; raise --max-error or --memory-limit (a mesh without "
                             "texture streams: `geoterrain mesh -o out.ply`)")
    return need


def check_export_path(path: str | Path, overwrite: bool = False, inputs=()) -> Path:
    """:func:`geoterrain.export.meshfiles.check_output_path` for :data:`EXPORT_FORMATS`, and
    the same rules for every sidecar (:func:`export_paths`), before any work.

    Examples
    --------
    >>> check_export_path("out.glb").suffix
    '.glb'
    """
    out = check_output_path(path, EXPORT_FORMATS, overwrite, "export", inputs)
    for side in export_paths(out)[1:]:
        check_output(side, overwrite, inputs=inputs)
    return out


def export_mesh(terrain: TerrainLike, selection, path: str | Path, *, overwrite: bool = False,
                shading: str = "normals", cmap: str = "auto",
                texture_size: int = TEXTURE_SIZE, crs_coords: bool = False,
                base_height: float | None = None, print_size: float | None = None,
                drape: str | Path | None = None, stats: dict | None = None) -> Path:
    """Write ``selection`` of ``terrain`` to ``path`` (.glb, .gltf, .obj, .stl or .ply).

    Parameters
    ----------
    shading, cmap, texture_size : the texture of glTF and OBJ
        (:mod:`geoterrain.rendering.textures`), cropped to the data.
    drape : glTF and OBJ: a georeferenced image (orthophoto, map) reprojected onto the
        DEM's grid as the texture (:mod:`geoterrain.rendering.drape`) instead of the shading.
    crs_coords : PLY only: float64 source-CRS x, y and elevation z instead of scene metres.
    base_height, print_size : a closed solid with walls and a flat base
        (:func:`~geoterrain.export.solids.printable_solid`); STL always is one, and
        either closes a glTF, OBJ or PLY.
    stats : filled with what was written: ``files``, ``bytes``, ``triangles``,
        ``vertices``, ``texture`` (width, height) and ``texture_level``, and for a solid
        ``solid`` (its size along x, y, z and their unit, the base height).

    Returns the path written. See the module docstring for each format's content. The
    terrain's vertical exaggeration is the file's: pass an
    :func:`~geoterrain.exaggerate.exaggerated` terrain and its selection.

    Examples
    --------
    >>> import tempfile, os
    >>> from geoterrain.exaggerate import exaggerated
    >>> e = exaggerated(t, 3.0)
    >>> info = {}
    >>> p = export_mesh(e, e.static_selection(5.0), os.path.join(tempfile.mkdtemp(), "p.glb"),
    ...                 print_size=150.0, stats=info)
    >>> info["solid"]["units"], round(max(info["solid"]["size"][:2]), 6)
    ('m', 0.15)
    """
    out = check_export_path(path, overwrite)
    ext = out.suffix.lower()
    if crs_coords and ext != ".ply":
        raise UsageError("crs_coords applies to PLY only", cli="--crs-coords applies to .ply only")
    if drape is not None and ext not in (".glb", ".gltf", ".obj"):
        raise UsageError("drape applies to glTF and OBJ only (they carry a texture)",
                         cli="--drape applies to .glb, .gltf and .obj only")
    closed = ext == ".stl" or base_height is not None or print_size is not None
    if closed and crs_coords:
        raise UsageError("a solid (base_height, print_size) is in print units, not source-CRS "
                         "coordinates", cli="--crs-coords does not go with --base-height or "
                                            "--print-size")
    m = mesh_arrays(terrain, selection, skirts=not closed)
    if closed and "skirt" in selection.parts.cell_data \
            and np.any(np.asarray(selection.parts.cell_data["skirt"]) != 0):
        raise UsageError("a printable solid needs a conforming mesh (static or rtin); this "
                         "one has skirts over T-junctions")
    if len(m.faces) == 0:
        raise UsageError("the mesh is empty (the view sees no terrain); nothing to export")
    sol = solid(terrain, m, base_height, print_size) if closed else None
    if sol is not None and ext in (".glb", ".gltf") and print_size is not None:
        sol = sol.rescaled(1e-3)  # glTF's unit is the metre: millimetres / 1000
    files = _Files(overwrite)
    info: dict = {"texture": None, "texture_level": None}
    try:
        if ext in (".glb", ".gltf", ".obj"):
            img, L = _texture(terrain, shading, cmap, texture_size, drape)
            info.update(texture=[int(img.shape[1]), int(img.shape[0])], texture_level=L)
        if ext in (".glb", ".gltf"):
            uv = _tcoords(terrain, m.ij, L, flip=False)
            geo = georeference(terrain) if sol is None else sol.geo
            top = m if sol is None else sol.surface(m)
            data = gltf_document(top, uv, _png(img), geo, binary=ext == ".glb",
                                 sides=None if sol is None else sol.sides(terrain))
            files.write(out, data)
            files.write(out.with_name(out.name + ".json"), json.dumps(geo, indent=1))
        elif ext == ".obj":
            uv = _tcoords(terrain, m.ij, L, flip=True)
            mtl, png = out.with_suffix(".mtl"), out.with_suffix(".png")
            walls = ""
            if sol is None:
                files.write(out, obj_text(m, uv, mtl.name))
            else:
                files.write(out, obj_solid_text(sol, m, uv, mtl.name))
                walls = (f"newmtl walls\nKa 1 1 1\nKd {WALL_COLOUR[0]:g} {WALL_COLOUR[1]:g} "
                         f"{WALL_COLOUR[2]:g}\nKs 0 0 0\nillum 1\n")
            files.write(mtl, f"# geoterrain {__version__}\nnewmtl terrain\nKa 1 1 1\nKd 1 1 1\n"
                             f"Ks 0 0 0\nillum 1\nmap_Kd {png.name}\n" + walls)
            files.write(png, _png(img))
            files.write(out.with_name(out.name + ".json"), json.dumps(
                georeference(terrain) if sol is None else sol.geo, indent=1))
        elif ext == ".ply":
            files.write(out, ply_bytes(terrain, m, crs_coords, solid=sol))
        else:
            files.write(out, stl_bytes(sol.points, sol.faces))
            files.write(out.with_name(out.name + ".json"), json.dumps(sol.geo, indent=1))
        files.commit()
    except OSError as exc:
        raise WriteError(f"{out}: cannot write the export ({exc.strerror or exc})") from None
    finally:
        files.discard()
    if stats is not None:
        written = [dst for _, dst in files.items]
        stats.update(info, files=[str(f) for f in written],
                     bytes=int(sum(f.stat().st_size for f in written)),
                     triangles=int(len(m.faces) if sol is None else len(sol.faces)),
                     vertices=int(len(m.xyz) if sol is None else len(sol.points)))
        if sol is not None:
            stats["solid"] = sol.summary()
    return out


def estimate_bytes(selection, ext: str, *, texels: int = 0, closed: bool = False) -> int:
    """About how many bytes :func:`export_mesh` writes for ``selection`` to a file of suffix
    ``ext`` with a texture of ``texels`` texels (PNG, about 2.2 bytes a shaded texel), and
    walls and a base when ``closed``: for a hint before a large export, within about
    ±30 % on shared DEMs.

    Examples
    --------
    >>> sel = t.static_selection(5.0)
    >>> 0 < estimate_bytes(sel, ".ply") < estimate_bytes(sel, ".ply", closed=True)
    True
    """
    F = len(selection.faces)
    V = int(selection.parts.n_points)
    if closed or ext == ".stl":
        F, V = 2 * F + 2 * int(math.isqrt(max(F, 1))), 2 * V
    per_vertex, per_face = {".glb": (36, 12), ".gltf": (48, 16), ".obj": (75, 60),
                            ".ply": (40, 13), ".stl": (0, 50)}[ext.lower()]
    tex = int(2.2 * texels) if ext.lower() in (".glb", ".gltf", ".obj") else 0
    return int(per_vertex * V + per_face * F + tex)


# ---------------------------------------------------------------------------- glTF
def gltf_document(m: MeshArrays, uv: np.ndarray, png: bytes, geo: dict, binary: bool = True,
                  sides: MeshArrays | None = None) -> bytes | str:
    """A glTF 2.0 document (GLB bytes or .gltf JSON text with embedded buffers): the
    surface ``m`` textured with ``png`` (unlit), and, for a solid, its walls and bottom
    ``sides`` in a second primitive of a plain lit material."""
    import pygltflib as g

    def axes(a):  # scene (east, north, up) → glTF Y-up (x = east, y = up, z = −north)
        return np.column_stack([a[:, 0], a[:, 2], -a[:, 1]]).astype(np.float32)

    # the scene's faces are counter-clockwise from above; the axis swap keeps their winding
    parts = [(m, uv)] + ([] if sides is None else [(sides, None)])
    chunks, acc, prims = [], [], []
    for k, (part, tc) in enumerate(parts):
        pos = axes(part.xyz)
        attrs = {"POSITION": len(acc), "NORMAL": len(acc) + 1}
        chunks += [pos.tobytes(), axes(part.normals).tobytes()]
        acc += [(pos, g.VEC3, g.FLOAT), (None, g.VEC3, g.FLOAT)]
        if tc is not None:
            attrs["TEXCOORD_0"] = len(acc)
            chunks.append(tc.astype(np.float32).tobytes())
            acc.append((None, g.VEC2, g.FLOAT))
        attrs["_ELEVATION"] = len(acc)
        chunks.append(part.elevation.astype(np.float32).tobytes())
        acc.append((None, g.SCALAR, g.FLOAT))
        idx = part.faces.astype(np.uint32).ravel()
        prims.append(g.Primitive(attributes=g.Attributes(**attrs), indices=len(acc),
                                 material=k))
        chunks.append(idx.tobytes())
        acc.append((idx, g.SCALAR, g.UNSIGNED_INT))
    chunks.append(png)
    views, blob, off = [], b"", 0
    n_data = len(chunks) - 1
    accessors = []
    for k, c in enumerate(chunks):
        pad = (-len(c)) % 4
        if k < n_data:
            arr, typ, comp = acc[k]
            index = comp == g.UNSIGNED_INT
            target = g.ELEMENT_ARRAY_BUFFER if index else g.ARRAY_BUFFER
            count = len(c) // {g.VEC3: 12, g.VEC2: 8, g.SCALAR: 4}[typ]
            mm = {} if typ != g.VEC3 or arr is None else dict(min=arr.min(0).tolist(),
                                                              max=arr.max(0).tolist())
            accessors.append(g.Accessor(bufferView=k, componentType=comp, count=count,
                                        type=typ, **mm))
        else:
            target = None
        views.append(g.BufferView(buffer=0, byteOffset=off, byteLength=len(c), target=target))
        blob += c + b"\0" * pad
        off += len(c) + pad
    materials = [g.Material(
        name="terrain", doubleSided=False,
        pbrMetallicRoughness=g.PbrMetallicRoughness(
            baseColorTexture=g.TextureInfo(index=0), metallicFactor=0.0, roughnessFactor=1.0),
        extensions={"KHR_materials_unlit": {}})]
    if sides is not None:
        materials.append(g.Material(
            name="walls", doubleSided=False,
            pbrMetallicRoughness=g.PbrMetallicRoughness(
                baseColorFactor=[*WALL_COLOUR, 1.0], metallicFactor=0.0, roughnessFactor=1.0)))
    doc = g.GLTF2(
        asset=g.Asset(generator=geo["generator"], version="2.0", extras={"geoterrain": geo}),
        scene=0, scenes=[g.Scene(nodes=[0])], nodes=[g.Node(mesh=0, name="terrain")],
        meshes=[g.Mesh(primitives=prims, name="terrain")],
        materials=materials,
        extensionsUsed=["KHR_materials_unlit"],
        textures=[g.Texture(source=0, sampler=0)],
        samplers=[g.Sampler(magFilter=g.LINEAR, minFilter=g.LINEAR_MIPMAP_LINEAR,
                            wrapS=g.CLAMP_TO_EDGE, wrapT=g.CLAMP_TO_EDGE)],
        images=[g.Image(bufferView=len(chunks) - 1, mimeType="image/png", name="shading")],
        accessors=accessors, bufferViews=views, buffers=[g.Buffer(byteLength=len(blob))],
    )
    doc.set_binary_blob(blob)
    if binary:
        return b"".join(doc.save_to_bytes())
    doc.convert_buffers(g.BufferFormat.DATAURI)
    return doc.to_json()


# ----------------------------------------------------------------------------- OBJ
def _rows(fmt: str, a: np.ndarray) -> str:
    """Format the rows of ``a`` with ``fmt`` (one % per column), newline-terminated."""
    if len(a) == 0:
        return ""
    return ((fmt + "\n") * len(a)) % tuple(a.ravel().tolist())  # one C-level format call


def obj_text(m: MeshArrays, uv: np.ndarray, mtl_name: str) -> str:
    """Wavefront OBJ: positions (scene metres, Z up), texture coordinates, normals, faces."""
    f = m.faces + 1
    head = (f"# geoterrain {__version__}: scene frame, metres east/north/up from the origin "
            "in the .json sidecar\n"
            f"mtllib {mtl_name}\no terrain\n")
    return (head + _rows("v %.4f %.4f %.4f", m.xyz) + _rows("vt %.7f %.7f", uv)
            + _rows("vn %.5f %.5f %.5f", m.normals) + "usemtl terrain\ns 1\n"
            + _rows("f %d/%d/%d %d/%d/%d %d/%d/%d", np.repeat(f, 3, axis=1)))


def obj_solid_text(sol: Solid, m: MeshArrays, uv: np.ndarray, mtl_name: str) -> str:
    """Wavefront OBJ of a :class:`Solid`: its points (print units, Z up), the surface
    textured (material ``terrain``), the bottom and walls flat-shaded in material
    ``walls``; every face refers to the shared points, so the solid is closed."""
    V, F = len(m.xyz), sol.n_surface
    walls = sol.faces[2 * F:]
    p = sol.points[walls]
    wn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    wn /= np.maximum(np.linalg.norm(wn, axis=1, keepdims=True), 1e-30)
    normals = np.concatenate([m.normals, [[0.0, 0.0, -1.0]], wn])
    fs = sol.faces + 1
    nb = V + 1  # the bottom's normal
    bottom = np.column_stack([fs[F:2 * F, 0], np.full(F, nb), fs[F:2 * F, 1],
                              np.full(F, nb), fs[F:2 * F, 2], np.full(F, nb)])
    wk = np.arange(len(walls)) + V + 2
    side = np.column_stack([fs[2 * F:, 0], wk, fs[2 * F:, 1], wk, fs[2 * F:, 2], wk])
    head = (f"# geoterrain {__version__}: a printable solid in {sol.unit}; the scale and "
            "offset to the scene frame are in the .json sidecar\n"
            f"mtllib {mtl_name}\no terrain\n")
    return (head + _rows("v %.5f %.5f %.5f", sol.points) + _rows("vt %.7f %.7f", uv)
            + _rows("vn %.5f %.5f %.5f", normals) + "usemtl terrain\ns 1\n"
            + _rows("f %d/%d/%d %d/%d/%d %d/%d/%d", np.repeat(fs[:F], 3, axis=1))
            + "usemtl walls\ns off\n" + _rows("f %d//%d %d//%d %d//%d", bottom)
            + _rows("f %d//%d %d//%d %d//%d", side))


# ----------------------------------------------------------------------------- PLY
def ply_bytes(terrain: TerrainLike, m: MeshArrays, crs_coords: bool = False,
              solid: Solid | None = None) -> bytes:
    """Binary little-endian PLY with the CRS and offset in header comments.

    Scene positions by default (``comment offset`` = CRS coordinates of the origin);
    with ``crs_coords`` the x, y of each vertex are the source-CRS coordinates of its
    sample (float64) and z its elevation in metres. A ``solid`` (:class:`Solid`) is written
    whole, in its print units (its scale and offset in the comments).
    """
    f = terrain.frame
    if solid is not None:
        xyz, faces = solid.points, solid.faces
        normals, elevation = vertex_normals(xyz, faces), solid.elevation(terrain)
    elif crs_coords:
        if f.crs_wkt is None:
            raise UsageError("crs_coords needs a georeferenced DEM; this one has no CRS",
                             cli="--crs-coords needs a georeferenced DEM; this one has no CRS")
        x, y = f.crs_xy(m.ij[:, 0], m.ij[:, 1])
        xyz = np.column_stack([x, y, m.elevation.astype(np.float64)])
        faces, normals, elevation = m.faces, m.normals, m.elevation
    else:
        xyz, faces, normals, elevation = m.xyz, m.faces, m.normals, m.elevation
    vdt = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("nx", "<f4"), ("ny", "<f4"),
                    ("nz", "<f4"), ("elevation", "<f4")])
    v = np.empty(len(xyz), vdt)
    v["x"], v["y"], v["z"] = xyz.T
    v["nx"], v["ny"], v["nz"] = normals.T
    v["elevation"] = elevation
    fdt = np.dtype([("n", "u1"), ("i", "<i4", 3)])
    fc = np.empty(len(faces), fdt)
    fc["n"], fc["i"] = 3, faces
    wkt = (f.crs_wkt or "none").replace("\n", " ")
    comments = [f"generator geoterrain {__version__}", f"crs {f.crs_name}", f"crs_wkt {wkt}",
                "positions " + ("solid" if solid is not None else
                                "source_crs" if crs_coords else "scene")]
    if solid is not None:
        o = solid.offset
        comments.append(f"solid in {solid.unit}: scene = position / {solid.scale:.12g} + "
                        f"({o[0]:.10g} {o[1]:.10g} {o[2]:.10g})")
    if not crs_coords:
        ox, oy = f.origin_crs
        comments.append(f"offset {ox:.10g} {oy:.10g} 0 (source-CRS coordinates of the origin)")
        comments.append(f"frame {f.kind} unit_to_m {f.unit_to_m:.12g} z_scale {f.z_scale:g}")
    head = ["ply", "format binary_little_endian 1.0", *("comment " + c for c in comments),
            f"element vertex {len(v)}", *(f"property {t} {n}" for n, t in (
                ("x", "double"), ("y", "double"), ("z", "double"), ("nx", "float"),
                ("ny", "float"), ("nz", "float"), ("elevation", "float"))),
            f"element face {len(fc)}", "property list uchar int vertex_indices", "end_header"]
    return ("\n".join(head) + "\n").encode() + v.tobytes() + fc.tobytes()
