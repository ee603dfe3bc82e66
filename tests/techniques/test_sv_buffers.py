"""sv's vertex buffers (techniques/sv/sv_gpu.py) built in float32 in place (issue 53): the
same numbers as the float64 corners rounded once, and no float64 copy of the whole on the way
(instancing@1e6: 1.1 GiB of float64 edge quads, concatenated, took sv's prepare 2.3 GiB
over what the process held)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import trimesh

from harness.scene import MeshPart
from techniques.sv import sv_gpu, sv_volumes


@pytest.fixture(scope="module")
def spheres():
    """Two closed meshes of 1280 and 20480 faces, scaled and moved apart."""
    out = []
    for i, subdivisions in enumerate((3, 5)):
        sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
        part = MeshPart(f"sphere{i}", (sphere.vertices * (1.3 + i) + i).astype(np.float32),
                        sphere.faces.astype(np.int32), 0.5)
        out.append(sv_volumes.clean(part))
    return out


def _planes(mesh) -> np.ndarray:
    """Each face's plane in float64: unit normal n and -n . its first corner."""
    tri = mesh.vertices[mesh.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    return np.hstack([normal, -(normal * tri[:, 0]).sum(axis=1)[:, None]])


def _edge_rows(mesh) -> np.ndarray:
    """The float64 oracle: for each undirected edge (a, b) with faces f (a -> b) and g, the
    corner of end e, other end o and far flag is [v_e, v_o, plane_f, plane_g, flag]; each edge's
    first triangle is (b, a, a far), its second (b, a far, b far), all first triangles first."""
    a, b, f, g = sv_gpu.edge_faces(mesh)
    plane, v = _planes(mesh), mesh.vertices

    def corner(end, other, far):
        return np.hstack([v[end], v[other], plane[f], plane[g], np.full((len(a), 1), far)])

    first = [corner(b, a, 0.0), corner(a, b, 0.0), corner(a, b, 1.0)]
    second = [corner(b, a, 0.0), corner(a, b, 1.0), corner(b, a, 1.0)]
    return np.vstack([np.stack(first, axis=1).reshape(-1, 15),
                      np.stack(second, axis=1).reshape(-1, 15)])


def test_edge_and_face_buffers_are_the_float64_corners_rounded_once(spheres):
    """Both meshes in one buffer, each at its range: every float the float64 oracle's, rounded
    to float32 once. Catches a corner written to the wrong slot (a far flag on a near corner,
    the twin's plane for the own face's) or a mesh written at another's range."""
    edges = [sv_gpu.edge_faces(m) for m in spheres]
    ranges = sv_gpu._ranges([6 * len(e[0]) for e in edges])
    built = sv_gpu._interleaved(spheres, ranges, 15, sv_gpu.edge_quads)
    assert built.dtype == np.float32
    assert np.array_equal(built, np.vstack([_edge_rows(m) for m in spheres]).astype(np.float32))
    faces = sv_gpu._interleaved(spheres, sv_gpu._ranges([3 * len(m.faces) for m in spheres]), 7,
                                sv_gpu.face_corners)
    expected = [np.hstack([m.vertices[m.faces].reshape(-1, 3), np.repeat(_planes(m), 3, axis=0)])
                for m in spheres]
    assert np.array_equal(faces, np.vstack(expected).astype(np.float32))


def test_the_edge_buffer_is_built_without_a_float64_copy_of_the_whole(spheres):
    """NumPy's allocations while the edge buffer of both meshes is built peak at less than
    twice the float32 buffer itself (1.4 times: the buffer and one mesh's temporaries).
    Catches the blocks made apart in float64 and concatenated (5.3 times)."""
    edges = [sv_gpu.edge_faces(m) for m in spheres]
    ranges = sv_gpu._ranges([6 * len(e[0]) for e in edges])
    tracemalloc.start()
    try:
        built = sv_gpu._interleaved(spheres, ranges, 15, sv_gpu.edge_quads)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 * built.nbytes
