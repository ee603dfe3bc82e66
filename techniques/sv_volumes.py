"""Shadow-volume geometry for the ``sv`` technique (a helper, not a technique).

Volumes are triangles with homogeneous vertices: w = 1 on the caster, w = 0 for points
extruded to infinity away from the light (Everitt and Kilgard 2002). Every volume is a
closed surface with outward-facing triangles, so counting the faces crossed along a camera
ray gives its winding number: 1 inside, 0 outside.

Two kinds of volume:
- silhouette: one per closed mesh; the edges between a light-facing and a light-averted face,
  extruded; the light-facing faces are the near cap and the light-averted faces pushed to
  infinity the far cap (degenerate, so left out, for a directional light);
- polygon: one per triangle (a truncated pyramid), for meshes that are not closed, and for
  the alpha and screen buffers wherever a silhouette volume could be entered twice by a ray.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from harness.scene import Light, MeshPart

# Relative size below which a triangle is taken as zero-area or as edge-on to the light.
DEGENERATE = 1e-12


@dataclass
class CleanMesh:
    """A part with exact duplicate vertices merged and zero-area faces dropped."""

    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int64
    closed: bool
    convex: bool
    notes: list[str] = field(default_factory=list)


@dataclass
class VolumeSet:
    """Volume triangles in draw order, (T, 3, 4) float32, and what was done to build them."""

    triangles: np.ndarray
    volume_of: np.ndarray  # (T,) index of the volume each triangle belongs to
    volume_count: int
    silhouette_edges: int
    warnings: list[str]


def clean(part: MeshPart) -> CleanMesh:
    vertices = np.asarray(part.vertices, np.float64)
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[np.asarray(part.faces, np.int64)]
    notes = []
    if len(unique) < len(vertices):
        notes.append(f"{len(vertices) - len(unique)} duplicate vertices merged")
    tri = unique[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    scale = max(float(np.ptp(unique, axis=0).max()), 1e-30) if len(unique) else 1.0
    keep = area2 > DEGENERATE * scale * scale
    if not keep.all():
        notes.append(f"{int((~keep).sum())} zero-area triangles ignored")
    faces = faces[keep]
    closed = convex = False
    if len(faces):
        mesh = trimesh.Trimesh(unique, faces, process=False)
        closed = bool(mesh.is_watertight and mesh.is_winding_consistent)
        if closed and mesh.volume < 0:
            faces = faces[:, ::-1]
            mesh = trimesh.Trimesh(unique, faces, process=False)
        convex = closed and bool(mesh.is_convex)
    return CleanMesh(unique, faces, closed, convex, notes)


def _light_facing(tri: np.ndarray, light: Light) -> np.ndarray:
    """Signed (unnormalised) facing of each triangle toward the light: > 0 faces it."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    to_light = (-light.direction[None, :] if light.type == "directional"
                else light.position[None, :] - tri[:, 0])
    return np.einsum("ij,ij->i", n, to_light)


def _at_infinity(points: np.ndarray, light: Light) -> np.ndarray:
    """Points extruded away from the light to infinity: (..., 4) with w = 0."""
    away = (np.broadcast_to(light.direction, points.shape) if light.type == "directional"
            else points - light.position)
    return np.concatenate([away, np.zeros(points.shape[:-1] + (1,))], axis=-1)


def _finite(points: np.ndarray) -> np.ndarray:
    return np.concatenate([points, np.ones(points.shape[:-1] + (1,))], axis=-1)


def _sides(a: np.ndarray, b: np.ndarray, light: Light) -> np.ndarray:
    """Outward side quads of directed edges a->b (the caster's interior on their left, seen
    from the light), as triangles (E or 2E, 3, 4)."""
    a_inf, b_inf = _at_infinity(a, light), _at_infinity(b, light)
    first = np.stack([_finite(b), _finite(a), a_inf], axis=1)
    if light.type == "directional":  # a_inf == b_inf: the quad is one triangle
        return first
    second = np.stack([_finite(b), a_inf, b_inf], axis=1)
    return np.concatenate([first, second])


def winding_number(mesh: CleanMesh, point: np.ndarray) -> float:
    """Generalised winding number of a closed mesh around a point (van Oosterom-Strackee)."""
    d = mesh.vertices[mesh.faces] - point
    a, b, c = d[:, 0], d[:, 1], d[:, 2]
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    numerator = np.einsum("ij,ij->i", a, np.cross(b, c))
    denominator = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
                   + np.einsum("ij,ij->i", a, c) * lb + np.einsum("ij,ij->i", b, c) * la)
    return float(2 * np.arctan2(numerator, denominator).sum() / (4 * np.pi))


def silhouette_volume(mesh: CleanMesh, light: Light, *, caps: bool):
    """One volume for a closed mesh: (triangles (T, 3, 4), number of silhouette edges)."""
    v, f = mesh.vertices, mesh.faces
    lit = _light_facing(v[f], light) > 0
    n = len(v)
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    keys = a * n + b
    order = np.argsort(keys)
    twin = order[np.searchsorted(keys, b * n + a, sorter=order)]  # closed: every edge has one
    edge_lit = np.repeat(lit, 3)
    silhouette = edge_lit & ~edge_lit[twin]
    parts = [_sides(v[a[silhouette]], v[b[silhouette]], light)]
    if caps:
        parts.append(_finite(v[f[lit]]))
        if light.type != "directional":
            parts.append(_at_infinity(v[f[~lit]], light))
    return np.concatenate(parts), int(silhouette.sum())


def polygon_volumes(mesh: CleanMesh, light: Light, *, caps: bool):
    """One volume per triangle not edge-on to the light: (triangles, volume index of each)."""
    tri = mesh.vertices[mesh.faces]
    facing = _light_facing(tri, light)
    scale = max(float(np.abs(tri).max()), 1e-30)
    keep = np.abs(facing) > DEGENERATE * scale ** 3
    tri = tri[keep]
    # orient every triangle toward the light, keeping the first vertex in place
    away = facing[keep] < 0
    tri[away] = tri[away][:, [0, 2, 1]]
    count = len(tri)
    pieces, owners = [], []
    for k in range(3):
        sides = _sides(tri[:, k], tri[:, (k + 1) % 3], light)
        pieces.append(sides)
        owners.append(np.tile(np.arange(count), len(sides) // max(count, 1)))
    if caps:
        pieces.append(_finite(tri))
        owners.append(np.arange(count))
        if light.type != "directional":
            pieces.append(_at_infinity(tri[:, ::-1], light))
            owners.append(np.arange(count))
    return np.concatenate(pieces), np.concatenate(owners), count


def build(parts: list[MeshPart], light: Light, *, caps: bool, one_pass_count: bool,
          grouping: str) -> VolumeSet:
    """All volumes of a scene.

    ``one_pass_count``: the buffer counts with a full integer (stencil), so any closed mesh may
    be one silhouette volume; otherwise (the alpha/screen state machine) only convex ones may,
    unless ``grouping`` is ``silhouette``, which forces it (to show the saturation error).
    ``grouping`` ``polygon`` makes every triangle its own volume.
    """
    triangles, owners, warnings = [], [], []
    volumes = edges = 0
    for part in parts:
        mesh = clean(part)
        notes = list(mesh.notes)
        if not len(mesh.faces):
            warnings.append(f"{part.name}: no non-degenerate triangles; casts no shadow")
            continue
        if (mesh.closed and light.type != "directional"
                and abs(winding_number(mesh, light.position)) > 0.5):
            notes.append("the light is inside this closed mesh: all outside it is shadowed")
        single = mesh.closed and grouping != "polygon" and (
            grouping == "silhouette" or one_pass_count or mesh.convex)
        if single:
            if not (one_pass_count or mesh.convex):
                notes.append("non-convex mesh drawn as one volume: a ray may enter it twice "
                             "and saturate the alpha/screen state machine")
            tri, n_edges = silhouette_volume(mesh, light, caps=caps)
            triangles.append(tri)
            owners.append(np.full(len(tri), volumes))
            volumes += 1
            edges += n_edges
        else:
            tri, owner, count = polygon_volumes(mesh, light, caps=caps)
            triangles.append(tri)
            owners.append(owner + volumes)
            volumes += count
            if not mesh.closed:
                notes.append(f"not closed (open or non-manifold edges): {count} per-triangle "
                             "volumes")
        if notes:
            warnings.append(f"{part.name}: " + "; ".join(notes))
    tri = np.concatenate(triangles) if triangles else np.zeros((0, 3, 4))
    owner = np.concatenate(owners) if owners else np.zeros(0, np.int64)
    return VolumeSet(tri.astype(np.float32), owner, volumes, edges, warnings)


def camera_facing(triangles: np.ndarray, view_proj: np.ndarray) -> np.ndarray:
    """True where a triangle faces the camera (counter-clockwise on screen, GL's default).

    The sign of det[x y w] of the clip-space vertices is the triangle's orientation as seen
    from the eye, valid for w <= 0 vertices too, so no clipping is needed to decide it."""
    clip = triangles.astype(np.float64) @ view_proj.T
    return np.linalg.det(clip[:, :, [0, 1, 3]]) > 0


def draw_order(volumes: VolumeSet, view_proj: np.ndarray, front_increments: bool) -> np.ndarray:
    """Triangles sorted volume by volume, the faces that increment the count first: the order
    the alpha/screen state machine needs (Roettger et al. section 4.2). Stencil ignores it."""
    increments = camera_facing(volumes.triangles, view_proj) == front_increments
    order = np.lexsort((~increments, volumes.volume_of))
    return volumes.triangles[order]
