"""The real corpus (issue 32 item 2): every mesh file the shipped scenes take from an installed
package (``package:`` in scenes.yaml) is read by the harness's loader to trimesh's triangles,
or to a difference counted and explained: the zero-area triangles the loader drops (counted in
``MeshParts.dropped``), and nothing else."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from harness import config
from test_mesh_tolerant import canonical

ROOT = Path(__file__).resolve().parents[2]


def corpus() -> list[config.MeshFile]:
    files = {}
    for scene in config.load_scenes(ROOT / "scenes.yaml").values():
        for obj in scene.objects:
            if isinstance(obj, config.MeshFile) and obj.package:
                files[obj.label] = obj
    return list(files.values())


def test_the_corpus_has_obj_stl_and_ply_of_1e4_to_1e5_triangles():
    """The corpus as issue 32 asks for it; a scene dropped from scenes.yaml shows here."""
    sizes = {Path(obj.path).suffix: config.mesh_parts(
        config.resolve_mesh_path(ROOT / "scenes.yaml", obj)).triangles for obj in corpus()}
    assert set(sizes) == {".obj", ".ply", ".stl"}
    assert all(1e4 <= n <= 1e5 for n in sizes.values()), sizes


@pytest.mark.parametrize("obj", corpus(), ids=lambda obj: obj.label)
def test_the_loader_reads_trimeshs_triangles_less_the_zero_area_ones(obj):
    """Broken versions caught: a face read wrongly (winding, fan, index base, a part lost), a
    skipped face counted as loaded, a good triangle dropped."""
    path = config.resolve_mesh_path(ROOT / "scenes.yaml", obj)
    parts = config.mesh_parts(path)  # the file's own axes (up: z), as trimesh reads it
    mesh = trimesh.load(path, force="mesh", process=False)
    theirs = mesh.vertices[mesh.faces]
    area = np.linalg.norm(np.cross(theirs[:, 1] - theirs[:, 0], theirs[:, 2] - theirs[:, 0]),
                          axis=1)
    ours = np.concatenate([v[f] for v, f in zip(parts.vertices, parts.faces)])
    assert len(theirs) - len(ours) == parts.dropped == int((area == 0).sum())
    np.testing.assert_array_equal(canonical(ours), canonical(theirs[area > 0]))
