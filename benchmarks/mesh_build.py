"""Scene build from a 10^6-triangle mesh file, cold (the file read, checked and its parts built)
and from the cache (harness.config.mesh_files), per format (issue 23: at most 10 s cold and
1 s cached), and the refusal of an OBJ over the budget (issue 34: 300,000 hexagons, 1.2 M
triangles once fanned, refused in under 2 s and 200 MB, with nothing cached).

    .venv/bin/python benchmarks/mesh_build.py [--triangles 1000000] [--formats obj,ply,stl,glb]
                                              [--hexagons 300000]

The mesh is a height field on a grid (one open part); each format's file is written once into
a temporary folder, and the cache is a temporary folder too, so cold means cold. Each build is
``load_scenes`` (the scene check, which loads the parts) plus ``build_scene``, in a fresh
process memory for the mesh (the in-process memo cleared), as ``shadowbench run`` does it.
The refusal runs in a process of its own (``load_scenes`` on the hexagon file, as ``shadowbench
run`` checks a scene), which prints its seconds, its peak resident memory (``ru_maxrss``) and
that peak less its resident memory before the check (what the check itself added: the
imports of numpy, pydantic and trimesh are most of the rest).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
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


def hexagon_obj(path: Path, count: int) -> None:
    """``count`` hexagons in a row, each one ``f`` line of 6 vertices (4 triangles fanned)."""
    angles = np.arange(6) * np.pi / 3
    centres = np.arange(count)[:, None] * 3.0
    x = (centres + np.cos(angles)).ravel()
    y = np.broadcast_to(np.sin(angles), (count, 6)).ravel()
    with open(path, "w") as f:
        np.savetxt(f, np.c_[x, y, np.zeros_like(x)], fmt="v %.3f %.3f %.1f")
        np.savetxt(f, np.arange(6 * count).reshape(count, 6) + 1, fmt="f %d %d %d %d %d %d")


def refusal_child(scene_path: str) -> None:
    """The check of one scene over the budget, measured in this process; one JSON line."""
    from harness import config

    before = _resident_mb()
    started = time.perf_counter()
    try:
        config.load_scenes(scene_path)
        message = "accepted"
    except config.ConfigError as e:
        message = str(e)
    seconds = time.perf_counter() - started
    peak = _status_mb("VmHWM")  # not ru_maxrss, which keeps the forking parent's peak
    print(json.dumps({"seconds": seconds, "peak_mb": peak, "added_mb": peak - before,
                      "message": message}))


def _status_mb(field: str) -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(field + ":")) / 1024


def _resident_mb() -> float:
    return _status_mb("VmRSS")


def refusal(folder: Path, hexagons: int) -> None:
    hexagon_obj(folder / "hexagons.obj", hexagons)
    path = scene_file(folder, "hexagons.obj")
    size = (folder / "hexagons.obj").stat().st_size / 1e6
    cache = folder / "refusal-cache"
    out = subprocess.run([sys.executable, __file__, "--refusal-child", str(path)], check=True,
                         capture_output=True, text=True,
                         env={**os.environ, "SHADOWBENCH_CACHE": str(cache)})
    result = json.loads(out.stdout.splitlines()[-1])
    cached = list(cache.rglob("*")) if cache.exists() else []
    print(f"{hexagons:,} hexagons ({size:.1f} MB): refused in {result['seconds']:.2f} s, peak "
          f"{result['peak_mb']:.0f} MB ({result['added_mb']:.0f} MB added by the check), "
          f"{len(cached)} cache files")
    print(f"  {result['message']}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--triangles", type=int, default=1_000_000)
    p.add_argument("--formats", default="obj,ply,stl,glb")
    p.add_argument("--hexagons", type=int, default=300_000)
    p.add_argument("--refusal-child", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.refusal_child:
        return refusal_child(args.refusal_child)
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
        if args.hexagons:
            refusal(folder, args.hexagons)


if __name__ == "__main__":
    main()
