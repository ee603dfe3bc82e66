"""Config's mesh formats, above limits and mesh_obj, below mesh_files: what a mesh file's header
declares (its triangle count, read before the file is loaded and without reading more of it
than the header, or for an OBJ a cheap count of its faces' triangles, so one over the budget
is refused at once), the check that every coordinate a binary STL stores is finite before
trimesh sees it (trimesh drops the faces of a NaN vertex silently; facet normals are never
read: the harness computes its own), and reading the file, through trimesh or our own readers,
into parts: OBJ objects and groups apart, glTF's nodes with their transforms, with what was
skipped counted. Errors are ValueErrors naming the element: ``line 23: vertex is inf``,
``vertex 17 is nan``, ``face 4 indexes vertex 9``."""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from .mesh_obj import FileCutout, finite, obj_triangles, read_obj

# every format trimesh reads that carries triangles (trimesh.exchange.load.mesh_formats()
# less xyz, a point cloud); COLLADA (.dae) through pycollada, a dependency
FORMATS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".glb": "glb", ".gltf": "gltf",
           ".off": "off", ".dae": "dae"}
# COLLADA's primitives, whose count attribute counts polygons (strips and fans: at least one
# triangle each)
COLLADA_PRIMITIVES = {"triangles", "polylist", "polygons", "tristrips", "trifans"}
STL_HEADER, STL_RECORD = 84, 50  # binary STL: 80 bytes, a uint32 count, 50 bytes a triangle
HEADER_MAX = 65536  # a PLY's or OFF's header is read from the file's first 64 KiB
GLTF_TRIANGLES = 4  # a primitive's mode: 4 is triangles (the default), others points or lines
NO_TRIANGLES = "geometries without triangles (points or lines)"


def mesh_format(path) -> str:
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix not in FORMATS:
        raise ValueError(f"unknown mesh format {suffix or '(no suffix)'!r}: use "
                         f"{', '.join(FORMATS)}")
    return FORMATS[suffix]


def declared_triangles(path, fmt: str, stop_after: int | None = None) -> int:
    """The triangles the file says it holds, from its header (a PLY's or OFF's faces: at
    least, as their polygons may be more), or for an OBJ from a cheap count of its faces
    (polygons fanned, stopping once past ``stop_after``); read in bounded memory, whatever the
    file's size. A ValueError for a header that contradicts the file."""
    if fmt == "obj":
        return obj_triangles(path, stop_after)
    if fmt == "dae":
        return _collada_triangles(path)
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        head = f.read(HEADER_MAX)
        if fmt == "stl":
            return _stl_count(head, size, f)
        if fmt == "ply":
            return _ply_faces(head)
        if fmt == "off":
            return _off_faces(head)
        if fmt == "glb":
            return _gltf_triangles(_glb_json(head, f))
        return _gltf_triangles(gltf_json(head + f.read()))


def _stl_binary(data: bytes, size: int | None = None) -> bool:
    """Whether the file (whose first bytes are ``data``, and ``size`` bytes in all) is a binary
    STL whose header's count matches its size."""
    size = len(data) if size is None else size
    return (len(data) >= STL_HEADER and size == STL_HEADER + STL_RECORD
            * struct.unpack_from("<I", data, 80)[0])


def _stl_count(head: bytes, size: int, rest) -> int:
    if _stl_binary(head, size):
        return struct.unpack_from("<I", head, 80)[0]
    if head.lstrip()[:5].lower() == b"solid":
        count, carry, block = 0, b"", head
        while block:  # in blocks: a word may straddle two
            data = carry + block
            count += data.count(b"endfacet")
            carry = data[-7:]
            block = rest.read(HEADER_MAX)
        return count
    if size < STL_HEADER:
        raise ValueError(f"{size} bytes: shorter than a binary STL's {STL_HEADER}-byte "
                         "header, and not ASCII STL ('solid ...')")
    declared = struct.unpack_from("<I", head, 80)[0]
    held, remainder = divmod(size - STL_HEADER, STL_RECORD)
    raise ValueError(f"binary STL header declares {declared:,} triangles, the file holds "
                     f"{held:,}" + (f" and {remainder} bytes more" if remainder else ""))


def _ply_faces(head: bytes) -> int:
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise ValueError("not a PLY file (no 'ply' ... 'end_header' header in its first "
                         f"{HEADER_MAX // 1024} KiB)")
    for line in head[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if words[:2] == ["element", "face"] and len(words) == 3 and words[2].isdigit():
            return int(words[2])
    raise ValueError("PLY header has no 'element face N': no triangles")


def _off_faces(head: bytes) -> int:
    """An OFF file's declared faces: ``OFF`` (or ``COFF``, ``NOFF``, ...), then, on the same
    line or the next that is not a comment, the counts of vertices, faces and edges."""
    words = b" ".join(line.split(b"#")[0] for line in head.splitlines()[:64]).split()
    if not words or not words[0].endswith(b"OFF"):
        raise ValueError("not an OFF file (its first word is not OFF)")
    if len(words) < 3 or not words[2].isdigit():
        raise ValueError("OFF header has no vertex and face counts after 'OFF'")
    return int(words[2])


def gltf_json(data: bytes) -> dict:
    try:
        return json.loads(data)
    except (ValueError, UnicodeDecodeError):
        raise ValueError("not a GLTF file (no glTF JSON)") from None


def _glb_json(head: bytes, rest) -> dict:
    try:
        magic, _, _, chunk_length, chunk_type = struct.unpack_from("<4sIIII", head)
        if magic != b"glTF" or chunk_type != 0x4E4F534A:  # "JSON"
            raise ValueError
        chunk = head[20:20 + chunk_length]
        chunk += rest.read(max(chunk_length - len(chunk), 0))
        return json.loads(chunk)
    except (ValueError, struct.error, UnicodeDecodeError):
        raise ValueError("not a GLB file (no glTF JSON)") from None


def _gltf_triangles(gltf: dict) -> int:
    """Triangles of the meshes that nodes place (each mesh once when no node does)."""
    try:
        accessors, meshes = gltf.get("accessors", []), gltf.get("meshes", [])
        per_mesh = [sum(accessors[p["indices"] if "indices" in p
                                  else p["attributes"]["POSITION"]]["count"] // 3
                        for p in mesh.get("primitives", [])
                        if p.get("mode", GLTF_TRIANGLES) == GLTF_TRIANGLES)
                    for mesh in meshes]
        placed = [node["mesh"] for node in gltf.get("nodes", []) if "mesh" in node]
        total = sum(per_mesh[i] for i in placed) if placed else sum(per_mesh)
    except (KeyError, IndexError, TypeError, AttributeError):
        raise ValueError("its glTF JSON does not describe meshes (accessors, primitives)") \
            from None
    if total == 0:
        raise ValueError("glTF with no triangles (no primitive of mode 4 with vertices)")
    return total


def _collada_triangles(path) -> int:
    """At least the triangles of the geometries a COLLADA file's nodes place (each geometry
    once when no node does): its primitives' ``count`` attributes, read by a streaming XML
    parse that keeps no element it has passed."""
    import xml.etree.ElementTree as ET

    per_geometry: dict[str | None, int] = {}
    placed: list[str] = []
    geometry = None
    try:
        for event, element in ET.iterparse(path, events=("start", "end")):
            tag = element.tag.rpartition("}")[2]
            if event == "end":
                geometry = None if tag == "geometry" else geometry
                element.clear()
            elif tag == "geometry":
                geometry = element.get("id")
                per_geometry.setdefault(geometry, 0)
            elif tag in COLLADA_PRIMITIVES and geometry in per_geometry:
                per_geometry[geometry] += int(element.get("count", "0"))
            elif tag == "instance_geometry":
                placed.append(element.get("url", "").removeprefix("#"))
    except ET.ParseError as e:
        raise ValueError(f"not a COLLADA file (XML: {e})") from None
    except ValueError:
        raise ValueError("a COLLADA primitive's count is not a whole number") from None
    total = (sum(per_geometry.get(name, 0) for name in placed) if placed
             else sum(per_geometry.values()))
    if total == 0:
        raise ValueError("COLLADA with no triangles (no placed geometry with a primitive)")
    return total


def check_numbers(data: bytes, fmt: str) -> None:
    """Every coordinate a binary STL stores, named by vertex and triangle, before trimesh
    reads past them (an OBJ's are checked by line as it is read: mesh_obj). Facet normals are
    not read, so a NaN or zero one is no error."""
    if fmt == "stl" and _stl_binary(data):
        vertices = _stl_records(data)["v"].reshape(-1, 3)
        finite(vertices, lambda i: f"vertex {i} (triangle {i // 3})")


def _stl_records(data: bytes) -> np.ndarray:
    return np.frombuffer(data, np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)),
                                         ("attribute", "<u2")]), offset=STL_HEADER)


def check_vertices(vertices: np.ndarray, name: str) -> None:
    """The vertices trimesh read (their file order): finite and representable."""
    finite(vertices, lambda i: f"{name}vertex {i}")


Parts = list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None, FileCutout | None]]


def read_parts(path, fmt: str) -> tuple[Parts, dict[str, int]]:
    """(name, vertices (V, 3) float64, faces (F, 3) int64, texture coordinates per corner
    (F, 3, 2) or None, the file's own cut-out or None) of each triangle mesh the file places,
    in its file's order, unprocessed (trimesh's processing merges and drops); and what was
    skipped, counted by kind. Texture coordinates follow glTF (v downward,
    harness/scene/alpha.py): an OBJ's and a PLY's v (``s t``, ``u v``) flipped, a glTF's
    ``TEXCOORD_0`` as written (trimesh reads it only for a primitive with a material). Cut-outs:
    an OBJ's ``map_d`` (mesh_obj), a glTF material's ``alphaMode: MASK`` (:func:`_gltf_cutout`);
    parts of one material share one."""
    import trimesh

    if fmt == "obj":
        return read_obj(Path(path).read_bytes(), Path(path).parent)
    if fmt == "stl" and _stl_binary(data := Path(path).read_bytes()):  # no need of trimesh
        vertices = _stl_records(data)["v"].reshape(-1, 3).astype(np.float64)
        return ([("stl", vertices, np.arange(len(vertices)).reshape(-1, 3), None, None)]
                if len(vertices) else []), {}
    scene = trimesh.load(path, file_type=fmt, force="scene", process=False)
    parts, other, cutouts = [], 0, {}
    for node in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[node]
        mesh = scene.geometry[geometry]
        faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
        if isinstance(mesh, trimesh.Trimesh) and len(faces):
            vertices = np.asarray(mesh.vertices, dtype=np.float64)
            if not np.allclose(transform, np.eye(4)):
                vertices = vertices @ transform[:3, :3].T + transform[:3, 3]
            material = getattr(mesh.visual, "material", None)
            if getattr(material, "alphaMode", None) == "MASK" and id(material) not in cutouts:
                cutouts[id(material)] = _gltf_cutout(material)
            parts.append((str(node), vertices, faces, _corner_uv(mesh, faces),
                          cutouts.get(id(material))))
        else:
            other += 1
    return parts, ({NO_TRIANGLES: other} if other else {})


def _corner_uv(mesh, faces: np.ndarray) -> np.ndarray | None:
    """The mesh's per-vertex texture coordinates at each face corner, v downward; None when
    it has none. trimesh keeps v upward (it flips a glTF's on load): flipped back here."""
    uv = getattr(mesh.visual, "uv", None)
    if uv is None or np.shape(uv) != (len(mesh.vertices), 2):
        return None
    uv = np.asarray(uv, np.float64)
    return np.stack([uv[:, 0], 1 - uv[:, 1]], -1)[faces]


def _gltf_cutout(material) -> FileCutout:
    """A glTF material's ``alphaMode: MASK``: alpha is its base colour texture's alpha (or
    grey) times its base colour factor's alpha, rounded to 8 bits (a 1x1 texture of the
    factor without a texture), there where alpha >= ``alphaCutoff`` (0.5 by default)."""
    from .alpha_files import MAX_TEXTURE_SIDE

    factor = np.asarray(material.baseColorFactor if material.baseColorFactor is not None
                        else [255] * 4, np.float64)[3] / 255  # trimesh keeps it as uint8
    image = material.baseColorTexture
    name = f"material {material.name or '(unnamed)'}"
    if image is None:
        texture = np.full((1, 1), 255.0)
    else:
        if max(image.size) > MAX_TEXTURE_SIDE:
            raise ValueError(f"{name}: its base colour texture is {image.size[0]}x"
                             f"{image.size[1]}, over the limit of {MAX_TEXTURE_SIDE}")
        bands = image.getbands()
        texture = np.asarray(image.getchannel("A" if "A" in bands else bands[0]), np.float64)
    cutoff = 0.5 if material.alphaCutoff is None else float(material.alphaCutoff)
    if not 0 <= cutoff <= 1:
        raise ValueError(f"{name}: alphaCutoff {cutoff} outside [0, 1]")
    return np.rint(texture * factor).astype(np.uint8), cutoff, f"{name} (alphaMode MASK)"
