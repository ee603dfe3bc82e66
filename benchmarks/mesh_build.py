"""Scene build from a 10^6-triangle mesh file, cold (the file read, checked and its parts built)
and from the cache (harness.config.mesh_files), per format (issue 23: at most 10 s cold and
1 s cached).

    .venv/bin/python benchmarks/mesh_build.py [--triangles 1000000] [--formats obj,ply,stl,glb]

The mesh is a height field on a grid (one open part); each format's file is written once into
a temporary folder, and the cache is a temporary folder too, so cold means cold. Each build is
``load_scenes`` (the scene check, which loads the parts) plus ``build_scene``, in a fresh
process memory for the mesh (the in-process memo cleared), as ``shadowbench run`` does it.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml


def grid_mesh(triangles: int):
    import trimesh

    n = math.isqrt(triangles // 2)
    x, y = np.meshgrid(np.linspace(-4, 4, n + 1), np.linspace(-4, 4, n + 1))
    vertices = np.c_[x.ravel(), y.ravel(), 0.2 * np.sin(3 * x.ravel()) * np.cos(2 * y.ravel())]
    corner = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    faces = np.r_[np.c_[corner, corner + 1, corner + n + 2], np.c_[corner, corner + n + 2,
                                                                   corner + n + 1]]
    return trimesh.Trimesh(vertices, faces, process=False)


def scene_file(folder: Path, mesh: str) -> Path:
    path = folder / f"scenes_{mesh}.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"big": {
        "resolution": [64, 64],
        "camera": {"position": [0, -9, 6], "target": [0, 0, 0]},
        "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
        "objects": [{"shape": "mesh", "path": mesh}]}}}))
    return path


def build_seconds(path: Path) -> tuple[float, int]:
    from harness import config
    from harness.config import mesh_files
    from harness.scene import build_scene

    mesh_files._loaded.clear()
    started = time.perf_counter()
    scene = config.load_scenes(path)["big"]
    built = build_scene("big", scene, path)
    return time.perf_counter() - started, len(built.triangles)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--triangles", type=int, default=1_000_000)
    p.add_argument("--formats", default="obj,ply,stl,glb")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        os.environ["SHADOWBENCH_CACHE"] = str(folder / "cache")
        mesh = grid_mesh(args.triangles)
        print(f"{len(mesh.faces):,} triangles")
        print(f"{'format':6s} {'MB':>6s} {'cold s':>7s} {'cached s':>9s}")
        for fmt in args.formats.split(","):
            mesh.export(folder / f"big.{fmt}")
            path = scene_file(folder, f"big.{fmt}")
            cold, triangles = build_seconds(path)
            cached, again = build_seconds(path)
            assert triangles == again == len(mesh.faces), (triangles, again)
            size = (folder / f"big.{fmt}").stat().st_size / 1e6
            print(f"{fmt:6s} {size:6.1f} {cold:7.2f} {cached:9.2f}")


if __name__ == "__main__":
    main()
