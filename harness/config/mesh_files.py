"""Config's mesh files, above yaml_source and mesh_formats: where a scene's ``shape: mesh`` file
lies, its parts (loaded once, and cached on disk by the file's content as references are, so a
10^6-triangle file is read in seconds once and in a fraction of one after), what was skipped
in it (counted, for the manifest and each run's ``mesh_notes``), and the check that
scene_schema's load_scenes runs: the file is a regular file, its header or cheap count fits the
budget before it is read whole, and every number and index a triangle uses is usable."""

from __future__ import annotations

import base64
import hashlib
import os
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from .cache_entry import DamagedEntry, note_rebuilt, read_entry, write_entry
from .limits import MAX_COORDINATE
from .mesh_formats import (gltf_json, check_numbers, check_vertices, declared_triangles,
                           mesh_format, read_parts)
from .mesh_obj import SHORT_FACES, finite
from .mesh_packages import package_file
from .yaml_source import check_regular_file, key_error



class MeshSource(Protocol):
    """What a scene's ``shape: mesh`` object says about its file (object_schema.MeshFile has it;
    this module stays below the schema, with no import of it)."""

    path: str  # relative to the scene file (or inside the package), or absolute
    up: str  # the file's up axis
    package: str | None  # an installed top-level package or distribution the file is of

MESH_CACHE_VERSION = 4  # bump when what is cached (or how it is built) changes; 4: texcoords
# y-up assets (most of them) turned so that their +y is the scene's +z
UP_ROTATION = {"z": np.eye(3), "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])}


def cache_root() -> Path:
    """Where built references and meshes are kept: $SHADOWBENCH_CACHE, else ~/.cache."""
    return Path(os.environ.get("SHADOWBENCH_CACHE") or Path.home() / ".cache" / "shadowbench")


@dataclass(frozen=True)
class MeshParts:
    """A mesh file's parts as the scene uses them: z up, exact duplicate vertices merged,
    zero-area triangles dropped (``dropped`` counts them), each part closed or not (every
    edge shared by exactly two faces, in opposite directions); ``skipped``: what the file holds
    that defines no triangle, by kind (mesh_obj.SHORT_FACES, an OBJ keyword, ...), counted."""

    names: tuple[str, ...]
    vertices: tuple[np.ndarray, ...]  # (V, 3) float64 each
    faces: tuple[np.ndarray, ...]  # (F, 3) int32 each
    closed: tuple[bool, ...]
    dropped: int
    skipped: tuple[tuple[str, int], ...] = ()
    # per part, its corners' texture coordinates (F, 3, 2) float32 (glTF's convention,
    # harness/scene/alpha.py), or None where the file gives a corner none
    texcoords: tuple[np.ndarray | None, ...] = ()
    # the file's own cut-outs (an OBJ's map_d, a glTF's alphaMode MASK): (texture (H, W)
    # uint8, cutoff, where from) each, and per part the index of its own or -1
    cutouts: tuple[tuple[np.ndarray, float, str], ...] = ()
    part_cutouts: tuple[int, ...] = ()

    @property
    def triangles(self) -> int:
        return sum(len(f) for f in self.faces)

    def summary(self) -> str:
        open_parts = self.closed.count(False)
        return (f"{self.triangles:,} triangles in {len(self.names)} parts ({open_parts} open)"
                + (f", {self.dropped:,} degenerate dropped" if self.dropped else ""))

    def notes(self) -> str:
        """One line saying what was skipped ('' when nothing was): ``skipped 201 faces with
        fewer than 3 vertices, 3 l, 12 vt statements``."""
        return skipped_note(dict(self.skipped))


def skipped_note(skipped: dict[str, int]) -> str:
    kinds = [f"{n:,} {what}" for what, n in skipped.items() if what == SHORT_FACES]
    kinds += [f"{n:,} {what}" for what, n in skipped.items() if " " in what and
              what != SHORT_FACES]
    statements = [f"{n:,} {what}" for what, n in skipped.items() if " " not in what]
    if statements:
        kinds.append(", ".join(statements) + " statements")
    return "skipped " + ", ".join(kinds) if kinds else ""


def resolve_mesh_path(scene_path: Path, obj: MeshSource) -> Path:
    """The file: relative to the scene file's folder, or a file of the installed package or
    distribution ``obj.package`` (:func:`.mesh_packages.package_file`: a ValueError when
    neither is installed, a FileNotFoundError when it has no such file)."""
    p = Path(obj.path)
    if obj.package is not None:
        return package_file(obj.package, obj.path)
    return p if p.is_absolute() else Path(scene_path).parent / p


_loaded: dict[str, MeshParts] = {}  # by cache key: the scene check and the build share one


def mesh_parts(mesh_path: Path, up: str = "z", data: bytes | None = None) -> MeshParts:
    """The file's parts, from this process's memory, the disk cache or the file; a ValueError
    naming what is wrong when it cannot be used."""
    data = Path(mesh_path).read_bytes() if data is None else data
    key = hashlib.sha256(data + f"|{up}|{MESH_CACHE_VERSION}".encode()).hexdigest()[:24]
    if key not in _loaded:
        path = cache_root() / "mesh" / f"{key}.npz"
        try:
            parts, damaged = _read_cache(path), None
        except DamagedEntry as e:
            parts, damaged = None, str(e)
        if parts is None:
            parts = _build(mesh_path, data, up)  # a refused mesh raises: nothing is written
            _write_cache(path, parts)
            if damaged:
                note_rebuilt(path, damaged)
        _loaded[key] = parts
    return _loaded[key]


def _build(mesh_path: Path, data: bytes, up: str) -> MeshParts:
    from ..machine.interrupt import raise_if_interrupted

    fmt = mesh_format(mesh_path)
    declared_triangles(mesh_path, fmt)  # a lying header is named before trimesh misreads it
    check_numbers(data, fmt)
    if fmt == "gltf":  # a GLB's buffer is its binary chunk
        _check_data_uris(gltf_json(data))
    try:
        found, skipped = read_parts(mesh_path, fmt)
    except ValueError:
        raise  # ours, naming the line or element
    except ModuleNotFoundError:
        # trimesh's last resort for text it cannot decode as UTF-8 is an optional module
        raise ValueError("not a mesh file trimesh can read (neither its binary format nor "
                         "UTF-8 text)") from None
    except Exception as e:  # trimesh raises many kinds for a bad file
        if not str(e).strip():  # a bare assert inside trimesh says nothing of the file
            raise ValueError(f"not a {fmt.upper()} file trimesh can read (it stopped at a "
                             "check of its own without saying which)") from None
        raise ValueError(" ".join(f"{type(e).__name__}: {e}".split())[:300]) from None
    finally:
        raise_if_interrupted()  # trimesh catches BaseException in places, Ctrl-C included
    if not found:
        note = skipped_note(skipped)
        raise ValueError("no triangle left" + (f" ({note})" if note else ""))
    names, vertices, faces, closed, texcoords, dropped, total = [], [], [], [], [], 0, 0
    cutouts, part_cutouts = {}, []
    for name, v, f, uv, cutout in found:
        where = f"part {name!r}: " if len(found) > 1 else ""
        if fmt != "obj":  # an OBJ's numbers were checked by line
            check_vertices(v, where)
            if uv is not None:
                finite(uv.reshape(-1, 2), lambda i: f"{where}face {i // 3}'s texture coordinate")
        bad = np.flatnonzero((f < 0) | (f >= len(v)))
        if len(bad):
            face, corner = divmod(int(bad[0]), 3)
            raise ValueError(f"{where}face {face} indexes vertex {f[face, corner]}, and there "
                             f"are {len(v)} vertices")
        v, f = _merge_duplicates(v @ UP_ROTATION[up].T + 0.0, f)  # + 0: no -0.0 apart from 0
        good = _nonzero_area(v, f)
        total += len(f)
        dropped += int(len(f) - good.sum())
        if good.any():
            f = f[good].astype(np.int32)
            texcoords.append(None if uv is None else uv[good].astype(np.float32))
            if cutout is not None and uv is None:
                raise ValueError(f"{where}{cutout[2]} cuts it out, and it has no texture "
                                 "coordinates")
            if cutout is not None:
                cutouts.setdefault(id(cutout), (len(cutouts), cutout))
            part_cutouts.append(cutouts[id(cutout)][0] if cutout is not None else -1)
            names.append(name)
            vertices.append(v)
            faces.append(f)
            closed.append(_closed(f))
    if not faces:
        raise ValueError(f"all {total:,} triangles are degenerate (zero area)")
    return MeshParts(tuple(names), tuple(vertices), tuple(faces), tuple(closed), dropped,
                     tuple(skipped.items()), tuple(texcoords),
                     tuple(cutout for _, cutout in cutouts.values()), tuple(part_cutouts))


def _check_data_uris(gltf: dict) -> None:
    """Each glTF buffer written inline (a ``data:`` URI) holds at least its ``byteLength``
    bytes (trimesh's own check is an assert with no message)."""
    buffers = gltf.get("buffers", [])
    for i, buffer in enumerate(buffers if isinstance(buffers, list) else ()):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if not isinstance(uri, str) or not uri.startswith("data:"):
            continue
        header, _, payload = uri.partition(",")
        try:
            held = len(base64.b64decode(payload, validate=True) if header.endswith(";base64")
                       else urllib.parse.unquote_to_bytes(payload))
        except ValueError:  # binascii.Error is one
            raise ValueError(f"buffers.{i}: its data URI is not valid base64") from None
        length = buffer.get("byteLength")
        if isinstance(length, int) and held < length:
            raise ValueError(f"buffers.{i}: its data URI holds {held:,} bytes, fewer than its "
                             f"byteLength of {length:,}")


def _merge_duplicates(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact duplicate vertices become one (STL repeats each vertex in every triangle), kept
    in order of first appearance, and the unreferenced ones dropped."""
    used, faces = np.unique(faces, return_inverse=True)
    vertices = vertices[used]
    rows = np.ascontiguousarray(vertices).view(np.dtype((np.void, 24))).ravel()
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return vertices[first[order]], rank[inverse.ravel()][faces.reshape(-1, 3)]


def _nonzero_area(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    tri = vertices[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return area2 > 0


def _closed(faces: np.ndarray) -> bool:
    """Every directed edge once, and its reverse present: a closed, consistently wound
    surface (what sv's silhouette volumes need)."""
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).astype(np.int64)
    n = int(faces.max()) + 1
    keys = np.sort(edges[:, 0] * n + edges[:, 1])
    if (np.diff(keys) == 0).any():
        return False
    reverse = edges[:, 1] * n + edges[:, 0]
    at = np.minimum(np.searchsorted(keys, reverse), len(keys) - 1)
    return bool((keys[at] == reverse).all())


MESH_ENTRY = {"names": ("U", 1), "closed": ("b", 1), "dropped": ("i", 0), "vertices": ("f", 2),
              "faces": ("i", 2), "vertex_ends": ("i", 1), "face_ends": ("i", 1),
              "skipped_kinds": ("U", 1), "skipped_counts": ("i", 1),
              "texcoords": ("f", 3), "textured": ("b", 1), "cutout_texels": ("u", 1),
              "cutout_shapes": ("i", 2), "cutout_cutoffs": ("f", 1), "cutout_names": ("U", 1),
              "part_cutouts": ("i", 1)}


def _read_cache(path: Path) -> MeshParts | None:
    """The cached parts at ``path``, verified (:mod:`.cache_entry`'s checksum, then what the
    scene relies on: finite coordinates within the limits, each part's faces indexing its own
    vertices); None when there is no entry. A DamagedEntry when any check fails."""
    z = read_entry(path, MESH_ENTRY)
    if z is None:
        return None
    vertices, faces = z["vertices"], z["faces"]
    vertex_ends, face_ends = z["vertex_ends"], z["face_ends"]
    parts = len(z["names"])
    if (vertices.shape[1:] != (3,) or faces.shape[1:] != (3,) or faces.dtype != np.int32
            or vertices.dtype != np.float64 or len(z["closed"]) != parts
            or len(vertex_ends) != parts or len(face_ends) != parts or parts == 0
            or len(z["skipped_kinds"]) != len(z["skipped_counts"])):
        raise DamagedEntry("arrays of other shapes than a mesh's parts")
    if (np.diff(vertex_ends, prepend=0) <= 0).any() or (np.diff(face_ends, prepend=0) <= 0).any() \
            or vertex_ends[-1] != len(vertices) or face_ends[-1] != len(faces) or z["dropped"] < 0:
        raise DamagedEntry("part bounds out of order")
    if not (np.abs(vertices) <= MAX_COORDINATE).all():  # NaN fails it too
        raise DamagedEntry("vertices not finite or beyond the coordinate limit")
    split_vertices = np.split(vertices, vertex_ends[:-1])
    split_faces = np.split(faces, face_ends[:-1])
    for v, f in zip(split_vertices, split_faces):
        if f.min() < 0 or f.max() >= len(v):
            raise DamagedEntry("faces index past their part's vertices")
    skipped = tuple((str(k), int(n)) for k, n in zip(z["skipped_kinds"], z["skipped_counts"]))
    textured, uv = z["textured"], z["texcoords"]
    if (len(textured) != parts or uv.shape[1:] != (3, 2) or uv.dtype != np.float32
            or len(uv) != sum(len(f) for f, t in zip(split_faces, textured) if t)
            or not np.isfinite(uv).all()):
        raise DamagedEntry("texture coordinates not one finite (3, 2) per textured face")
    uv_ends = np.cumsum([len(f) if t else 0 for f, t in zip(split_faces, textured)])
    texcoords = tuple(u if t else None for u, t in zip(np.split(uv, uv_ends[:-1]), textured))
    shapes, texels, cutoffs = z["cutout_shapes"], z["cutout_texels"], z["cutout_cutoffs"]
    part_cutouts = z["part_cutouts"]
    if (shapes.shape[1:] != (2,) or len(cutoffs) != len(shapes)
            or len(z["cutout_names"]) != len(shapes) or (shapes < 1).any()
            or shapes.prod(axis=1).sum() != len(texels) or len(part_cutouts) != parts
            or (part_cutouts < -1).any() or (part_cutouts >= len(shapes)).any()
            or not ((cutoffs >= 0) & (cutoffs <= 1)).all()
            or any(not textured[p] for p in np.flatnonzero(part_cutouts >= 0))):
        raise DamagedEntry("cut-outs not of their parts and texels")
    ends = np.cumsum(shapes.prod(axis=1))
    cutouts = tuple((t.reshape(shape), float(c), str(n)) for t, shape, c, n in zip(
        np.split(texels, ends[:-1]), shapes, cutoffs, z["cutout_names"]))
    return MeshParts(tuple(str(n) for n in z["names"]), tuple(split_vertices),
                     tuple(split_faces), tuple(bool(c) for c in z["closed"]), int(z["dropped"]),
                     skipped, texcoords, cutouts, tuple(int(i) for i in part_cutouts))


def _write_cache(path: Path, parts: MeshParts) -> None:
    """Written whole and renamed (:func:`.cache_entry.write_entry`), so a reader never sees half
    of it; a cache that cannot be written (full disk, read-only) only costs the next load its
    time."""
    try:
        write_entry(path, {"names": np.array(parts.names), "closed": np.array(parts.closed),
                           "dropped": np.int64(parts.dropped),
                           "vertices": np.concatenate(parts.vertices),
                           "faces": np.concatenate(parts.faces),
                           "vertex_ends": np.cumsum([len(v) for v in parts.vertices]),
                           "face_ends": np.cumsum([len(f) for f in parts.faces]),
                           "skipped_kinds": np.array([k for k, _ in parts.skipped], dtype=str),
                           "skipped_counts": np.array([n for _, n in parts.skipped],
                                                      dtype=np.int64),
                           "textured": np.array([t is not None for t in parts.texcoords]),
                           "texcoords": np.concatenate(
                               [np.zeros((0, 3, 2), np.float32)]
                               + [t for t in parts.texcoords if t is not None]),
                           "cutout_texels": np.concatenate(
                               [np.zeros(0, np.uint8)] + [t.ravel() for t, _, _ in
                                                          parts.cutouts]),
                           "cutout_shapes": np.array([t.shape for t, _, _ in parts.cutouts],
                                                     np.int64).reshape(-1, 2),
                           "cutout_cutoffs": np.array([c for _, c, _ in parts.cutouts],
                                                      np.float64),
                           "cutout_names": np.array([n for _, _, n in parts.cutouts],
                                                    dtype=str),
                           "part_cutouts": np.array(parts.part_cutouts, np.int64)})
    except OSError:
        pass


def check_mesh(path: Path, node, scene_name: str, index: int, obj: MeshSource,
                triangle_budget: int | None = None) -> int:
    """The mesh file's triangle count; a ConfigError naming the key when it cannot be used.
    A file whose header declares more than ``triangle_budget`` is refused before loading."""
    loc = ("scenes", scene_name, "objects", index, "path")
    try:
        mesh_path = resolve_mesh_path(path, obj)
    except FileNotFoundError as e:  # the package is there, the file is not
        raise key_error(path, node, loc, str(e)) from None
    except ValueError as e:
        raise key_error(path, node, loc[:-1] + ("package",), str(e)) from None
    try:
        check_regular_file(mesh_path)
    except FileNotFoundError:
        raise key_error(path, node, loc, f"no such file: {mesh_path}") from None
    except (OSError, ValueError) as e:
        raise key_error(path, node, loc, f"{mesh_path}: {getattr(e, 'strerror', None) or e}") \
            from None
    try:
        fmt = mesh_format(mesh_path)
        declared = declared_triangles(mesh_path, fmt, stop_after=triangle_budget)
        if triangle_budget is not None and declared > triangle_budget:
            least = " at least" if fmt in ("obj", "ply", "off", "dae") else ""  # polygons fanned
            raise key_error(path, node, loc,
                            f"{mesh_path} declares{least} {declared:,} triangles, more than the "
                            f"budget of {triangle_budget:,} (an experiment may raise it with "
                            "triangle_budget:)")
        return mesh_parts(mesh_path, obj.up).triangles
    except (ValueError, OSError) as e:
        raise key_error(path, node, loc, f"cannot load mesh {mesh_path}: "
                                         f"{getattr(e, 'strerror', None) or e}") from None
