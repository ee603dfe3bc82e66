"""Config's mesh files, above yaml_source: where a scene's ``shape: mesh`` file lies, loading
it, and its triangle count, which scene_schema's load_scenes adds to the scene's budget."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .limits import MAX_COORDINATE
from .yaml_source import key_error

if TYPE_CHECKING:
    from .scene_schema import MeshFile


def resolve_mesh_path(scene_path: Path, obj: MeshFile) -> Path:
    p = Path(obj.path)
    return p if p.is_absolute() else Path(scene_path).parent / p


def load_mesh(mesh_path: Path):
    """trimesh's mesh from a file; a ``ValueError`` naming what is wrong when it is not one."""
    import trimesh

    from ..interrupt import raise_if_interrupted

    try:
        mesh = trimesh.load(mesh_path, force="mesh")
    except ModuleNotFoundError:
        # trimesh's last resort for text it cannot decode as UTF-8 is an optional module
        raise ValueError("not a mesh file trimesh can read (neither its binary format nor "
                         "UTF-8 text)") from None
    except Exception as e:  # trimesh raises many kinds for a bad file
        raise ValueError(" ".join(f"{type(e).__name__}: {e}".split())[:300]) from None
    finally:
        raise_if_interrupted()  # trimesh catches BaseException in places, Ctrl-C included
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        raise ValueError("no triangles")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.abs(vertices) <= MAX_COORDINATE):
        raise ValueError(f"vertex coordinates must be finite and within +-{MAX_COORDINATE:g}")
    return mesh


def _check_mesh(path: Path, node, scene_name: str, index: int, obj: MeshFile) -> int:
    """The mesh file's triangle count; a ConfigError naming the key when it cannot be used."""
    loc = ("scenes", scene_name, "objects", index, "path")
    mesh_path = resolve_mesh_path(path, obj)
    if mesh_path.is_dir():
        raise key_error(path, node, loc, f"{mesh_path} is a folder, not a mesh file")
    if not mesh_path.is_file():
        raise key_error(path, node, loc, f"no such file: {mesh_path}")
    try:
        return len(load_mesh(mesh_path).faces)
    except ValueError as e:
        raise key_error(path, node, loc, f"cannot load mesh {mesh_path}: {e}") from None
