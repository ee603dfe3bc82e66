"""Config's mesh formats, above limits and below mesh_files: what a mesh file's header declares
(its triangle count, read before the file is loaded, so one over the budget is refused at
once), the check that every number it stores is finite before trimesh sees it (trimesh drops
the faces of a NaN vertex silently), and reading it, through trimesh, into parts: OBJ objects
and groups apart, glTF's nodes with their transforms. Errors are ValueErrors naming the
element: ``line 23: vertex is inf``, ``vertex 17 is nan``, ``face 4 indexes vertex 9``."""

from __future__ import annotations

import json
import os
import re
import struct
from pathlib import Path

import numpy as np

from .limits import MAX_COORDINATE

FORMATS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".glb": "glb", ".gltf": "gltf"}
STL_HEADER, STL_RECORD = 84, 50  # binary STL: 80 bytes, a uint32 count, 50 bytes a triangle
PLY_HEADER_MAX = 65536
GLTF_TRIANGLES = 4  # a primitive's mode: 4 is triangles (the default), others points or lines


def mesh_format(path) -> str:
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix not in FORMATS:
        raise ValueError(f"unknown mesh format {suffix or '(no suffix)'!r}: use "
                         f"{', '.join(FORMATS)}")
    return FORMATS[suffix]


def declared_triangles(data: bytes, fmt: str) -> int:
    """The triangles (at least: faces, whose polygons may be more) the file says it holds, from
    its header where it has one; a ValueError for a header that contradicts the file."""
    if fmt == "stl":
        return _stl_count(data)
    if fmt == "ply":
        return _ply_faces(data)
    if fmt in ("glb", "gltf"):
        return _gltf_triangles(_gltf_json(data, fmt))
    return data.count(b"\nf ") + data.count(b"\nf\t") + data.startswith((b"f ", b"f\t"))


def _stl_binary(data: bytes) -> bool:
    return (len(data) >= STL_HEADER and len(data) == STL_HEADER + STL_RECORD
            * struct.unpack_from("<I", data, 80)[0])


def _stl_count(data: bytes) -> int:
    if _stl_binary(data):
        return struct.unpack_from("<I", data, 80)[0]
    if data.lstrip()[:5].lower() == b"solid":
        return data.count(b"endfacet")
    if len(data) < STL_HEADER:
        raise ValueError(f"{len(data)} bytes: shorter than a binary STL's {STL_HEADER}-byte "
                         "header, and not ASCII STL ('solid ...')")
    declared = struct.unpack_from("<I", data, 80)[0]
    held, rest = divmod(len(data) - STL_HEADER, STL_RECORD)
    raise ValueError(f"binary STL header declares {declared:,} triangles, the file holds "
                     f"{held:,}" + (f" and {rest} bytes more" if rest else ""))


def _ply_header(data: bytes) -> list[str]:
    end = data.find(b"end_header", 0, PLY_HEADER_MAX)
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("not a PLY file (no 'ply' ... 'end_header' header in its first "
                         f"{PLY_HEADER_MAX // 1024} KiB)")
    return data[:end].decode("ascii", "replace").splitlines()


def _ply_faces(data: bytes) -> int:
    for line in _ply_header(data):
        words = line.split()
        if words[:2] == ["element", "face"] and len(words) == 3 and words[2].isdigit():
            return int(words[2])
    raise ValueError("PLY header has no 'element face N': no triangles")


def _gltf_json(data: bytes, fmt: str) -> dict:
    try:
        if fmt == "gltf":
            return json.loads(data)
        magic, _, _, chunk_length, chunk_type = struct.unpack_from("<4sIIII", data)
        if magic != b"glTF" or chunk_type != 0x4E4F534A:  # "JSON"
            raise ValueError
        return json.loads(data[20:20 + chunk_length])
    except (ValueError, struct.error, UnicodeDecodeError):
        raise ValueError(f"not a {fmt.upper()} file (no glTF JSON)") from None


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


def check_numbers(data: bytes, fmt: str) -> None:
    """Every number a binary STL stores, named by vertex and triangle, before trimesh reads
    past them (an OBJ's are checked by line as it is read: :class:`_ObjLines`)."""
    if fmt == "stl" and _stl_binary(data):
        records = _stl_records(data)
        _finite(records["v"].reshape(-1, 3), lambda i: f"vertex {i} (triangle {i // 3})")
        _finite(records["normal"], lambda t: f"normal of triangle {t}")


def _stl_records(data: bytes) -> np.ndarray:
    return np.frombuffer(data, np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)),
                                         ("attribute", "<u2")]), offset=STL_HEADER)


def check_vertices(vertices: np.ndarray, name: str) -> None:
    """The vertices trimesh read (their file order): finite and representable."""
    _finite(vertices, lambda i: f"{name}vertex {i}")


def _finite(values: np.ndarray, element) -> None:
    bad = ~(np.abs(values) <= MAX_COORDINATE).all(axis=-1)
    if bad.any():
        row = int(np.argmax(bad))
        value = values[row][~(np.abs(values[row]) <= MAX_COORDINATE)][0]
        what = (f"is {value}" if not np.isfinite(value) else
                f"has coordinate {value:g}, beyond +-{MAX_COORDINATE:g}")
        raise ValueError(f"{element(row)} {what}")


_BLANKS = np.frombuffer(b" \t\r\n", np.uint8)


class _ObjLines:
    """An OBJ file's lines, found and parsed with NumPy (trimesh's OBJ reader loops in Python
    per face: most of a minute at 10^6 triangles on a busy machine)."""

    def __init__(self, data: bytes):
        self.data = data
        self.buf = np.frombuffer(data, np.uint8)
        newlines = np.flatnonzero(self.buf == ord("\n"))
        self.starts = np.r_[0, newlines + 1]
        self.ends = np.r_[newlines + 1, len(self.buf)]  # each line's newline included

    def starting(self, keyword: bytes) -> np.ndarray:
        """Indices (from 0) of the lines that start with ``keyword`` and a blank."""
        padded = np.r_[self.buf, np.zeros(len(keyword) + 1, np.uint8)]
        mine = np.isin(padded[self.starts + len(keyword)], _BLANKS[:2])
        for k, byte in enumerate(keyword):
            mine &= padded[self.starts + k] == byte
        return np.flatnonzero(mine)

    def text(self, lines: np.ndarray, keyword: bytes) -> tuple[np.ndarray, np.ndarray]:
        """The bytes of these lines with their keyword blanked, and each byte's place in the
        file."""
        edge = np.zeros(len(self.buf) + 1, np.int8)
        np.add.at(edge, self.starts[lines], 1)
        np.add.at(edge, self.ends[lines], -1)
        chosen = np.flatnonzero(np.cumsum(edge[:-1], dtype=np.int8))
        text = self.buf.copy()
        for k in range(len(keyword)):
            text[self.starts[lines] + k] = ord(" ")
        return text[chosen], chosen

    def line_of(self, place: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.starts, place, side="right") - 1

    def vectors(self, keyword: bytes, what: str) -> tuple[np.ndarray, np.ndarray]:
        """Line numbers (from 1) and the first three numbers of the ``keyword`` lines."""
        lines = self.starting(keyword)
        if not len(lines):
            return lines, np.zeros((0, 3))
        text, _ = self.text(lines, keyword)
        try:
            values = np.loadtxt(text.tobytes().decode("utf-8", "replace").splitlines(),
                                usecols=(0, 1, 2), comments="#", ndmin=2)
        except ValueError as e:
            raise ValueError(_loadtxt_problem(str(e), lines, what)) from None
        return lines + 1, values

    def faces(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Triangles (polygons fanned) as 0-based vertex indices; each one's part, the count
        of ``o`` and ``g`` lines above it (trimesh's split_objects and split_groups); and the
        lines that start parts."""
        lines = self.starting(b"f")
        text, place = self.text(lines, b"f")
        position = np.arange(len(text))
        blank = np.isin(text, _BLANKS)
        # a face's texture and normal indices (after '/') are blanked: vertex indices are left
        after_slash = (np.maximum.accumulate(np.where(text == ord("/"), position, -1))
                       > np.maximum.accumulate(np.where(blank, position, -1)))
        text = np.where(after_slash, ord(" "), text).astype(np.uint8)
        blank = np.isin(text, _BLANKS)
        token_line = self.line_of(place[~blank & np.r_[True, blank[:-1]]])
        words = text.tobytes().split()
        try:
            index = np.array(words).astype(np.int64) if words else np.zeros(0, np.int64)
        except (ValueError, OverflowError):
            bad = next(i for i, w in enumerate(words)
                       if not re.fullmatch(rb"-?\d{1,18}", w))  # the error path only
            raise ValueError(f"line {token_line[bad] + 1}: face index "
                             f"{words[bad].decode('utf-8', 'replace')!r} is not an integer") \
                from None
        vertices = self.starting(b"v")
        before = np.searchsorted(vertices, token_line)  # vertices defined above each index
        written, index = index, np.where(index < 0, before + index, index - 1)
        bad = np.flatnonzero((index < 0) | (index >= len(vertices)))
        if len(bad):
            raise ValueError(f"line {token_line[bad[0]] + 1}: face indexes vertex "
                             f"{written[bad[0]]}, which does not exist (the file has "
                             f"{len(vertices)} vertices)")
        counts = np.bincount(np.searchsorted(lines, token_line), minlength=len(lines))
        if len(counts) and counts.min() < 3:
            short = int(np.argmin(counts))
            raise ValueError(f"line {lines[short] + 1}: a face needs 3 vertices, it has "
                             f"{counts[short]}")
        fans = counts - 2
        first = np.repeat(np.cumsum(counts) - counts, fans)
        k = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans)
        triangles = np.c_[index[first], index[first + k + 1], index[first + k + 2]]
        starts = np.union1d(self.starting(b"o"), self.starting(b"g"))
        return triangles, np.repeat(np.searchsorted(starts, lines), fans), starts

    def name(self, line: int) -> str:
        end = self.data.find(b"\n", self.starts[line])
        words = self.data[self.starts[line]:end if end >= 0 else None].decode(
            "utf-8", "replace").split(maxsplit=1)
        return words[1].strip() if len(words) > 1 else ""


def _loadtxt_problem(message: str, lines: np.ndarray, what: str) -> str:
    """loadtxt's message about a row, as the line of the OBJ file (its conversion errors count
    rows from 0, its short-row errors from 1)."""
    if (m := re.search(r"could not convert string '(.*)' to \w+ at row (\d+)", message)):
        return f"line {lines[int(m[2])] + 1}: {what} value {m[1]!r} is not a number"
    if (m := re.search(r"at row (\d+) with (\d+) columns", message)):
        return f"line {lines[int(m[1]) - 1] + 1}: a {what} needs 3 numbers, it has {m[2]}"
    return f"a {what} line is not 3 numbers ({message})"


def _read_obj(data: bytes) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """An OBJ file's parts: each ``o`` or ``g`` line starts one (faces above any: the first)."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"not a mesh file: an OBJ is text, and byte {data[e.start]:#04x} at "
                         f"offset {e.start} is not UTF-8") from None
    lines = _ObjLines(data)
    for keyword, what in ((b"vn", "normal"), (b"v", "vertex")):
        numbers, vertices = lines.vectors(keyword, what)
        _finite(vertices, lambda row: f"line {numbers[row]}: {what}")
    triangles, part, starts = lines.faces()
    order = np.argsort(part, kind="stable")
    bounds = np.searchsorted(part[order], np.arange(len(starts) + 2))
    parts = []
    for p in np.unique(part):  # per part, not per triangle
        faces = triangles[order[bounds[p]:bounds[p + 1]]]
        name = lines.name(starts[p - 1]) if p else ""
        parts.append((name or f"part{p}", vertices, faces))
    return parts


def read_parts(path, fmt: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, vertices (V, 3) float64, faces (F, 3) int64) of each triangle mesh the file
    places, in its file's order, unprocessed (trimesh's processing merges and drops)."""
    import trimesh

    if fmt == "obj":
        return _read_obj(Path(path).read_bytes())
    if fmt == "stl" and _stl_binary(data := Path(path).read_bytes()):  # no need of trimesh
        vertices = _stl_records(data)["v"].reshape(-1, 3).astype(np.float64)
        return [("stl", vertices, np.arange(len(vertices)).reshape(-1, 3))] if len(vertices) \
            else []
    scene = trimesh.load(path, file_type=fmt, force="scene", process=False)
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[node]
        mesh = scene.geometry[geometry]
        faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), dtype=np.int64)
        if isinstance(mesh, trimesh.Trimesh) and len(faces):
            vertices = np.asarray(mesh.vertices, dtype=np.float64)
            if not np.allclose(transform, np.eye(4)):
                vertices = vertices @ transform[:3, :3].T + transform[:3, 3]
            parts.append((str(node), vertices, faces))
    return parts
