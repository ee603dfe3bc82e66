"""A scene's edges and which of its parts are closed, and its silhouette edges seen from the
light: the per-run counts ``parts``, ``open_parts`` and ``shadow_edges`` (harness.run.score).

Vertices are merged by position within each part (never across parts), as a closed mesh made
of separate face sheets is still closed. A part is closed when every edge has exactly two
faces that traverse it in opposite directions (watertight, consistently wound). A shadow edge
is an edge whose faces some face the light and some not, or an edge of one face (the boundary
of an open part): the edges a silhouette method extrudes or rasterises.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Edges:
    """Every edge of the scene, built once per geometry."""

    face_of_half: np.ndarray  # (3F,) the face each half-edge belongs to
    edge_of_half: np.ndarray  # (3F,) the edge each half-edge lies on
    faces_per_edge: np.ndarray  # (E,)
    parts: int
    open_parts: int
    closed: np.ndarray  # (P,) bool: whether each part is closed


def edges(vertices: list[np.ndarray], faces: list[np.ndarray]) -> Edges:
    """The edges of the parts given as per-part vertex (V, 3) and face (F, 3) arrays."""
    part_of_vertex = np.repeat(np.arange(len(vertices), dtype=np.uint32),
                               [len(v) for v in vertices])
    points = np.concatenate(vertices).astype(np.float32) + np.float32(0)  # -0.0 becomes 0.0
    keyed = np.empty(len(points), dtype=[("part", "<u4"), ("xyz", "<u4", 3)])
    keyed["part"], keyed["xyz"] = part_of_vertex, points.view(np.uint32)
    _, merged = np.unique(keyed.view("V16"), return_inverse=True)
    offsets = np.cumsum([0] + [len(v) for v in vertices[:-1]])
    corner = merged.ravel()[np.concatenate([f + o for f, o in zip(faces, offsets)])]
    start, end = corner.ravel(), corner[:, [1, 2, 0]].ravel()
    low, high = np.minimum(start, end), np.maximum(start, end)
    _, edge_of_half, faces_per_edge = np.unique(low * (int(merged.max()) + 1) + high,
                                                return_inverse=True, return_counts=True)
    # a closed part's edges each have two half-edges, one each way
    forward = np.bincount(edge_of_half, weights=start < end, minlength=len(faces_per_edge))
    bad_edge = (faces_per_edge != 2) | (forward != 1)
    face_of_half = np.repeat(np.arange(len(corner)), 3)
    part_of_face = np.repeat(np.arange(len(faces)), [len(f) for f in faces])
    bad_part = np.zeros(len(faces), bool)
    bad_part[part_of_face[face_of_half[bad_edge[edge_of_half]]]] = True
    return Edges(face_of_half, edge_of_half, faces_per_edge, len(faces), int(bad_part.sum()),
                 ~bad_part)


def shadow_edges(edges: Edges, triangles: np.ndarray, light) -> int:
    """Silhouette edges of ``triangles`` (T, 3, 3) seen from ``light`` (harness.scene.Light),
    with the boundary edges of open parts."""
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    if light.type == "directional":
        to_light = -light.direction.astype(np.float32)
    else:
        to_light = light.position.astype(np.float32) - triangles.mean(axis=1)
    facing = np.einsum("ij,ij->i", normal, np.broadcast_to(to_light, normal.shape)) > 0
    facing_per_edge = np.bincount(edges.edge_of_half, weights=facing[edges.face_of_half],
                                  minlength=len(edges.faces_per_edge))
    mixed = (facing_per_edge > 0) & (facing_per_edge < edges.faces_per_edge)
    return int((mixed | (edges.faces_per_edge == 1)).sum())
