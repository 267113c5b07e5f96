"""Georeferenced mesh files for other tools: glTF/GLB, OBJ + MTL + PNG, PLY, printable STL.

Every file is written from a :class:`~geoterrain.lod.Selection` (a static or a
view-dependent LOD mesh) and says where it is on Earth:

- **glTF / GLB** (pygltflib): float32 positions relative to the scene origin (the
  raster centre), glTF's Y-up axes (x = east, y = up, z = −north), normals, an
  ``_ELEVATION`` attribute (metres), the shading texture (elevation colours ×
  hillshade, :mod:`geoterrain.rendering.textures`; or an image draped by
  :mod:`geoterrain.rendering.drape`)
  embedded in an unlit material, and the georeference (:func:`georeference`) in
  ``asset.extras.geoterrain`` and a sidecar ``<file>.json``.
- **OBJ** with an MTL and a PNG texture beside it (and the sidecar).
- **PLY** (binary): x, y, z (float64), normals, ``elevation``; the CRS and the origin
  offset in header comments. ``crs_coords=True`` writes source-CRS x, y of each
  vertex's sample (pyproj through :class:`~geoterrain.core.frame.Frame`) and z = elevation.
- **STL**: a closed, printable solid (:func:`printable_solid`): the surface, vertical
  walls along its boundary and a flat base ``base_height`` under the lowest point;
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
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from geoterrain._version import __version__
from geoterrain.core.atomicfiles import partial_path, publish
from geoterrain.core.paths import check_output
from geoterrain.exceptions import UsageError, WriteError
from geoterrain.export.meshfiles import check_output_path
from geoterrain.rendering.textures import SHADINGS, texture_image

if TYPE_CHECKING:
    from geoterrain.terrainlike import TerrainLike

EXPORT_FORMATS = (".glb", ".gltf", ".obj", ".stl", ".ply")
TEXTURE_SIZE = 4097  # samples per side of an exported texture at most (a coarser level beyond)
WALL_COLOUR = (0.62, 0.58, 0.52)  # a solid's walls and bottom: a plain warm grey


@dataclass
class MeshArrays:
    """The referenced part of a selection, ready to write.

    ``xyz`` scene frame (float64), ``faces`` (F, 3), ``ij`` grid row/column of each
    vertex's sample, ``elevation`` metres (scene Z without vertical exaggeration),
    ``normals`` area-weighted unit vertex normals (scene frame), ``surface`` (F,) bool
    (False on skirt triangles).
    """

    xyz: np.ndarray
    faces: np.ndarray
    ij: np.ndarray
    elevation: np.ndarray
    normals: np.ndarray
    surface: np.ndarray


def mesh_arrays(terrain: TerrainLike, selection, *, skirts: bool = True) -> MeshArrays:
    """The vertices the selection's triangles use, with elevation and normals.

    Examples
    --------
    >>> m = mesh_arrays(t, t.static_selection(5.0))
    >>> m.xyz.shape[0] == m.elevation.shape[0] == m.normals.shape[0]
    True
    """
    faces = selection.faces
    surface = np.ones(len(faces), bool)
    if len(faces) and "skirt" in selection.mesh.cell_data:
        surface = np.asarray(selection.mesh.cell_data["skirt"]) == 0
    if not skirts:
        faces, surface = faces[surface], surface[surface]
    pts = np.asarray(selection.mesh.points, np.float64)
    used = np.zeros(len(pts), bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    xyz = pts[used]
    ij = selection.ij[used] if len(selection.ij) else np.zeros((len(xyz), 2))
    faces = remap[faces].astype(np.int64)
    elevation = (xyz[:, 2] / (terrain.frame.z_scale or 1.0)).astype(np.float32)
    return MeshArrays(xyz, faces, ij, elevation, vertex_normals(xyz, faces), surface)


def vertex_normals(xyz: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (float32); +Z where a vertex has no area.

    Examples
    --------
    >>> n = vertex_normals(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]), np.array([[0, 1, 2]]))
    >>> n.tolist()
    [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]
    """
    p = xyz[faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # length = 2 × area
    n = np.zeros((len(xyz), 3))
    for k in range(3):
        for c in range(3):
            n[:, c] += np.bincount(faces[:, k], fn[:, c], minlength=len(xyz))
    length = np.linalg.norm(n, axis=1)
    bad = length == 0
    n[bad] = (0.0, 0.0, 1.0)
    length[bad] = 1.0
    return (n / length[:, None]).astype(np.float32)


def georeference(terrain: TerrainLike, scale: float = 1.0, offset: tuple[float, float,
                 float] = (0, 0, 0)
                 ) -> dict:
    """How a written position maps back to the source CRS (the sidecar's content).

    A file position p (its axes named by the format) is ``scene = p / scale + offset``
    in the scene frame: east, north, up metres from ``origin_crs``. For a projected
    frame, source-CRS x, y = ``origin_crs + (east, north) / unit_to_m``; for a
    geographic one (east, north) are coordinates of ``positions_crs_wkt`` (an
    azimuthal equidistant CRS centred on the origin). Heights: up / z_scale metres.

    Examples
    --------
    >>> g = georeference(t)
    >>> g["frame"], len(g["origin_crs"])
    ('projected', 2)
    """
    f = terrain.frame
    return {
        "generator": f"geoterrain {__version__}",
        "crs_name": f.crs_name,
        "crs_wkt": f.crs_wkt,
        "frame": f.kind,
        "positions_crs_wkt": f.aeqd_wkt if f.kind == "geographic" else f.crs_wkt,
        "origin_crs": [float(v) for v in f.origin_crs],
        "unit_to_m": f.unit_to_m,
        "z_scale": f.z_scale,
        "units": "metres" if scale == 1.0 else f"{scale:g} per metre",
        "scale": float(scale),
        "offset_scene": [float(v) for v in offset],
        "transform": list(f.transform),
        "grid": [terrain.grid.rows, terrain.grid.cols],
    }


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

    N = terrain.grid.size
    if 2 * (N - 1) ** 2 * EXPORT_BYTES_PER_TRIANGLE <= limit:
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
        (:func:`printable_solid`); STL always is one, and either closes a glTF, OBJ or PLY.
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
    if closed and "skirt" in selection.mesh.cell_data \
            and np.any(np.asarray(selection.mesh.cell_data["skirt"]) != 0):
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
    V = int(selection.mesh.n_points)
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


# ----------------------------------------------------------------------------- STL
@dataclass
class Solid:
    """A surface closed into a solid (:func:`solid`): ``points`` (the surface's V points,
    then the same V on the bottom plane z = 0), ``faces`` wound outwards (the surface's
    ``n_surface`` faces, the bottom's as many, then the walls), and the map back to the
    scene frame: scene = point / ``scale`` + ``offset``; ``unit`` ("mm" with a print
    size, else "m"); ``base_height`` in that unit; ``geo`` the sidecar's georeference."""

    points: np.ndarray
    faces: np.ndarray
    n_surface: int
    scale: float
    offset: tuple[float, float, float]
    unit: str
    base_height: float
    geo: dict

    def rescaled(self, f: float) -> Solid:
        """The same solid with its units × ``f`` (millimetres → metres: 1e-3)."""
        geo = dict(self.geo, scale=self.geo["scale"] * f, base_height=self.base_height * f,
                   units=f"{self.geo['scale'] * f:g} per metre")
        return Solid(self.points * f, self.faces, self.n_surface, self.scale * f, self.offset,
                     {"mm": "m"}.get(self.unit, self.unit) if f == 1e-3 else self.unit,
                     self.base_height * f, geo)

    def surface(self, m: MeshArrays) -> MeshArrays:
        """The surface's :class:`MeshArrays` in the solid's units."""
        V = len(m.xyz)
        return MeshArrays(self.points[:V], m.faces, m.ij, m.elevation, m.normals, m.surface)

    def elevation(self, terrain: TerrainLike) -> np.ndarray:
        """Each point's elevation in metres (float32): its scene height / z_scale."""
        z = self.points[:, 2] / self.scale + self.offset[2]
        return (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)

    def sides(self, terrain: TerrainLike) -> MeshArrays:
        """The bottom and walls as their own mesh: the bottom's points (normal −z), then three
        points per wall triangle (its own normal, so walls are flat-shaded)."""
        F, V = self.n_surface, len(self.points) // 2
        bottom = self.faces[F:2 * F] - V
        walls = self.faces[2 * F:]
        p = self.points[walls].reshape(-1, 3)
        wn = np.cross(p[1::3] - p[0::3], p[2::3] - p[0::3])
        wn /= np.maximum(np.linalg.norm(wn, axis=1, keepdims=True), 1e-30)
        xyz = np.concatenate([self.points[V:], p])
        normals = np.concatenate([np.tile([0.0, 0.0, -1.0], (V, 1)), np.repeat(wn, 3, 0)])
        faces = np.concatenate([bottom, V + np.arange(len(p)).reshape(-1, 3)])
        z = xyz[:, 2] / self.scale + self.offset[2]
        elev = (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)
        return MeshArrays(xyz, faces.astype(np.int64), np.zeros((len(xyz), 2)), elev,
                          normals.astype(np.float32), np.ones(len(faces), bool))

    def summary(self) -> dict:
        """Its size along x, y, z, unit and base height (for the command's summary)."""
        ext = self.points.max(0) - self.points.min(0)
        return {"size": [float(v) for v in ext], "units": self.unit,
                "base_height": float(self.base_height)}


def solid(terrain: TerrainLike, m: MeshArrays, base_height: float | None = None,
          print_size: float | None = None) -> Solid:
    """The surface closed into a :class:`Solid`: walls down every boundary edge and a flat
    base.

    ``print_size`` (mm): the longer horizontal side becomes that long, every axis
    scaled alike (the vertical exaggeration is the terrain's, ``-z``); the model
    sits on z = 0 with x, y ≥ 0. ``base_height``: the base's thickness under the
    lowest point, in output units (mm with ``print_size``, else metres); default 3 mm,
    or 2 % of the longer side. The surface must be conforming (every interior edge
    shared by two triangles, as static and ``rtin`` meshes are).

    Examples
    --------
    >>> s = solid(t, mesh_arrays(t, t.static_selection(5.0)), print_size=100.0)
    >>> s.unit, float(s.points[:, 2].min()), round(float(np.ptp(s.points[:, :2], 0).max()), 6)
    ('mm', 0.0, 100.0)
    """
    if print_size is not None and not (np.isfinite(print_size) and print_size > 0):
        raise UsageError(f"print_size must be > 0 mm, got {print_size}",
                         cli=f"--print-size must be > 0 mm, got {print_size}")
    xyz, faces = m.xyz, m.faces
    lo, hi = xyz.min(0), xyz.max(0)
    side = float(max(hi[0] - lo[0], hi[1] - lo[1])) or 1.0
    scale = 1.0 if print_size is None else float(print_size) / side
    if base_height is None:
        base_height = 3.0 if print_size is not None else 0.02 * side
    if not (np.isfinite(base_height) and base_height > 0):
        raise UsageError(f"base_height must be > 0, got {base_height}",
                         cli=f"--base-height must be > 0, got {base_height}")
    offset = (float(lo[0]), float(lo[1]), float(lo[2]) - base_height / scale)
    top = (xyz - offset) * scale
    V = len(top)
    bottom = top.copy()
    bottom[:, 2] = 0.0
    # directed edges a→b of the (counter-clockwise) surface; boundary = no b→a partner
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    fwd, rev = a * V + b, b * V + a
    fs = np.sort(fwd)  # sorting, not np.unique/np.isin: several times faster here
    if (fs[1:] == fs[:-1]).any():
        raise UsageError("the mesh is not a manifold surface; cannot close it into a solid")
    boundary = ~_contains(fs, rev)
    ea, eb = a[boundary], b[boundary]
    if not _contains(np.sort(ea), eb).all() or not _contains(np.sort(eb), ea).all():
        raise UsageError("the mesh is not conforming (T-junctions); a printable solid needs a "
                         "static or rtin mesh")
    walls = np.concatenate([np.column_stack([ea, eb + V, eb]),
                            np.column_stack([ea, ea + V, eb + V])])
    out_faces = np.concatenate([faces, faces[:, ::-1] + V, walls])
    pts = np.concatenate([top, bottom])
    # edges that are each used once forwards and once backwards: a closed 2-manifold
    fa = out_faces.ravel()
    fb = out_faces[:, [1, 2, 0]].ravel()
    P = len(pts)
    f2, r2 = np.sort(fa * P + fb), np.sort(fb * P + fa)
    if not np.array_equal(f2, r2) or (f2[1:] == f2[:-1]).any():
        raise UsageError("the mesh is not conforming (T-junctions); a printable solid needs a "
                         "static or rtin mesh")
    geo = georeference(terrain, scale, offset)
    geo["base_height"] = float(base_height)
    return Solid(pts, out_faces, len(faces), scale, offset,
                 "mm" if print_size is not None else "m", float(base_height), geo)


def printable_solid(terrain: TerrainLike, m: MeshArrays, base_height: float | None = None,
                    print_size: float | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """:func:`solid` as (points (P, 3), faces (F, 3) wound outwards, georeference dict).

    Examples
    --------
    >>> pts, faces, geo = printable_solid(t, mesh_arrays(t, t.static_selection(5.0)))
    >>> len(faces) > 0 and geo["base_height"] > 0
    True
    """
    s = solid(terrain, m, base_height, print_size)
    return s.points, s.faces, s.geo


def _contains(sorted_keys: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Whether each of ``q`` is in ``sorted_keys`` (binary search)."""
    if len(sorted_keys) == 0:
        return np.zeros(len(q), bool)
    k = np.minimum(np.searchsorted(sorted_keys, q), len(sorted_keys) - 1)
    return sorted_keys[k] == q


def stl_bytes(xyz: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary STL of triangles ``faces`` over points ``xyz`` (float32, facet normals)."""
    p = xyz[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, ln, out=np.zeros_like(n), where=ln > 0)
    rec = np.zeros(len(faces), np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]))
    rec["n"], rec["v"] = n, p
    header = f"geoterrain {__version__} printable solid".encode().ljust(80, b" ")
    return header + np.uint32(len(faces)).tobytes() + rec.tobytes()


def with_elevation(terrain: TerrainLike, mesh):
    """A shallow copy of ``mesh`` with an ``elevation`` point array (metres, made active).

    Examples
    --------
    >>> m = with_elevation(t, t.mesh(5.0))
    >>> m.active_scalars_name
    'elevation'
    """
    out = mesh.copy(deep=False)
    if out.n_points:
        z = np.asarray(out.points, np.float64)[:, 2]
        out.point_data["elevation"] = (z / (terrain.frame.z_scale or 1.0)).astype(np.float32)
        out.set_active_scalars("elevation")
    return out
