"""ptsv's casters: the scene's triangles, each pair of them that makes a planar convex quad
taken as that quad. The two triangles share the quad's diagonal; the union of their two volumes
is the quad's volume (its plane and the planes through its four sides and the light), so one
volume is tested where two were, and no plane along the diagonal splits the nodes between them.
Meshes are mostly such quads as modellers and generators write them (grids, cards), so pairing
about halves the volumes, and with them the traversal's work.
"""

from __future__ import annotations

import numpy as np

NO_CORNER = 0xFFFFFFFF  # a triangle caster's fourth corner (ptsv_volume.glsl's)


def triangle_casters(faces: np.ndarray) -> np.ndarray:
    """Every face a caster of its own: (T, 4) uint32, the fourth corner ``NO_CORNER``."""
    faces = np.asarray(faces, np.uint32).reshape(-1, 3)
    return np.column_stack([faces, np.full(len(faces), NO_CORNER, np.uint32)])


def _signed_area(p, q, x, normal):
    """Twice the area of (p, q, x) along ``normal``: > 0 where x lies left of p -> q."""
    return np.einsum("ij,ij->i", np.cross(q - p, x - p), normal)


def quad_casters(vertices: np.ndarray, faces: np.ndarray, sides: np.ndarray,
                 flatness: float) -> tuple[np.ndarray, np.ndarray]:
    """The casters of the indexed mesh ``vertices`` (V, 3), ``faces`` (T, 3): (C, 4) uint32
    corner indices in the faces' winding (a triangle's fourth ``NO_CORNER``), and each
    caster's entry of ``sides`` (per face: its closed part's side, hierarchy.closed_sides).

    Two faces make a quad where the longest side of each is the other's, traversed the other
    way (the same two vertices: consistently wound), the other face's far corner lies within
    ``flatness`` (scene units) of the first face's plane, their ``sides`` are equal and the
    quad is strictly convex (each diagonal separates the other's ends; a pair folded onto
    itself is not). Every other face is a triangle caster."""
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    sides = np.asarray(sides)
    count = len(faces)
    if count == 0:
        return triangle_casters(faces), sides.astype(np.int32)
    corner = np.asarray(vertices, np.float64)[faces]  # (T, 3, 3)
    rows = np.arange(count)
    longest = np.argmax(np.stack([np.sum((corner[:, (k + 1) % 3] - corner[:, k]) ** 2, axis=1)
                                  for k in range(3)], axis=1), axis=1)
    start, end = faces[rows, longest], faces[rows, (longest + 1) % 3]
    apex = faces[rows, (longest + 2) % 3]
    span = int(faces.max()) + 1
    forward, backward = start * span + end, end * span + start
    keys, key_face, key_of, key_count = np.unique(forward, return_index=True,
                                                  return_inverse=True, return_counts=True)
    # the one face whose longest side runs end -> start (none where two or more do)
    found = np.minimum(np.searchsorted(keys, backward), len(keys) - 1)
    has_partner = (keys[found] == backward) & (key_count[found] == 1) & (key_count[key_of] == 1)
    partner = key_face[found]
    first = has_partner & (rows < partner) & (sides[partner] == sides)
    a, b, c = (corner[rows, (longest + k) % 3] for k in range(3))
    d = np.asarray(vertices, np.float64)[apex[partner]]
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    unit = normal / np.where(length > 0, length, 1.0)[:, None]
    flat = (length > 0) & (np.abs(np.einsum("ij,ij->i", unit, d - a)) <= flatness)
    convex = ((_signed_area(a, b, d, normal) < 0)
              & (_signed_area(c, d, a, normal) * _signed_area(c, d, b, normal) < 0))
    first &= flat & convex
    paired = first.copy()
    paired[partner[first]] = True
    # in the first face's winding: start, the partner's apex, end, the first face's apex
    quads = np.stack([start, apex[partner], end, apex], axis=1)[first].astype(np.uint32)
    casters = np.concatenate([quads, triangle_casters(faces[~paired])])
    return casters, np.concatenate([sides[first], sides[~paired]]).astype(np.int32)
