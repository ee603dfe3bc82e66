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
  the alpha and screen buffers normalised by rectangles wherever a silhouette volume could be
  entered twice by a ray.

Either way a volume's count is the sum of the per-triangle volumes of its light-facing
triangles (the casters): the side quads between two light-facing triangles cancel. The casters
give the volume's cross-section with the camera's near plane (:func:`near_clip_polygons`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace

import numpy as np

from harness.scene.motion import moved
from harness.scene import Light, MeshPart

# Below this a triangle is taken as zero-area (twice its area over the squared extent of its
# mesh) or as edge-on to the light (the cosine between its normal and the direction to the
# light): both relative, so the same triangle is judged the same anywhere in the scene.
DEGENERATE = 1e-12


@dataclass(frozen=True)
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
    casters: np.ndarray  # (C, 3, 3) float64 light-facing triangles, counter-clockwise seen from it
    caster_volume: np.ndarray  # (C,) the volume each caster belongs to


def clean_parts(parts: list[MeshPart]) -> list[CleanMesh]:
    """:func:`clean` of each part. The last scene's are kept: every sv run of a scene cleans
    the same parts, which took 0.6 s a run on castle (closedness and convexity by trimesh)."""
    digest = hashlib.blake2b(digest_size=16)
    for part in parts:
        for array in (part.vertices, part.faces):
            digest.update(str((array.dtype, array.shape)).encode())
            digest.update(np.ascontiguousarray(array).tobytes())
    key = digest.digest()
    if _last_cleaned.get("key") != key:
        _last_cleaned.update(key=key, meshes=[clean(part) for part in parts])
    return list(_last_cleaned["meshes"])


_last_cleaned: dict = {}  # "key": digest of the parts' arrays, "meshes": their CleanMesh list


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
        import trimesh  # here: the registry imports this module for shadowbench list too

        mesh = trimesh.Trimesh(unique, faces, process=False)
        closed = bool(mesh.is_watertight and mesh.is_winding_consistent)
        if closed and mesh.volume < 0:
            faces = faces[:, ::-1]
            mesh = trimesh.Trimesh(unique, faces, process=False)
        convex = closed and bool(mesh.is_convex)
    faces = np.ascontiguousarray(faces)
    for array in (unique, faces):  # shared by the runs of a scene (clean_parts)
        array.flags.writeable = False
    return CleanMesh(unique, faces, closed, convex, notes)


def placed(meshes: list[CleanMesh], poses: np.ndarray) -> list[CleanMesh]:
    """``meshes`` where ``poses`` (``Frame.part_poses``) put them, their vertices rounded to
    float32 as the scene's moved parts' are, so that each gives the triangles :func:`clean`
    gives for its moved part; a mesh whose pose is the identity is kept."""
    return [mesh if np.array_equal(pose, np.eye(4)) else replace(
        mesh, vertices=moved(mesh.vertices, pose).astype(np.float64))
        for mesh, pose in zip(meshes, poses)]


def light_facing(tri: np.ndarray, light: Light) -> np.ndarray:
    """Cosine between each triangle's normal and the direction to the light: > 0 faces it."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    to_light = (-light.direction[None, :] if light.type == "directional"
                else light.position[None, :] - tri[:, 0])
    lengths = np.linalg.norm(n, axis=1) * np.linalg.norm(to_light, axis=1)
    return np.einsum("ij,ij->i", n, to_light) / np.maximum(lengths, 1e-300)


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


def directed_edges(mesh: CleanMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed mesh's directed edges a -> b, three per face in face order (edge k of face i
    is row 3 i + k), and the row of each one's twin b -> a."""
    f, n = mesh.faces, len(mesh.vertices)
    a = f.reshape(-1)
    b = f[:, [1, 2, 0]].reshape(-1)
    keys = a * n + b
    order = np.argsort(keys)
    return a, b, order[np.searchsorted(keys, b * n + a, sorter=order)]  # closed: all have one


def toward_light(mesh: CleanMesh, light: Light) -> np.ndarray:
    """The triangles not edge-on to the light, each turned toward it keeping its first
    vertex in place (T, 3, 3): the casters of per-triangle volumes."""
    tri = mesh.vertices[mesh.faces]
    facing = light_facing(tri, light)
    keep = np.abs(facing) > DEGENERATE
    tri = tri[keep]
    away = facing[keep] < 0
    tri[away] = tri[away][:, [0, 2, 1]]
    return tri


def one_volume(mesh: CleanMesh, grouping: str, nested_counts: bool) -> bool:
    """Whether a mesh is drawn as one silhouette volume (see :func:`build`)."""
    return mesh.closed and grouping != "polygon" and (
        grouping == "silhouette" or nested_counts or mesh.convex)


def part_notes(mesh: CleanMesh, light: Light, *, single: bool, nested_counts: bool,
               volumes: int) -> list[str]:
    """What a part's volumes warn about (``volumes``: its number of per-triangle volumes)."""
    notes = list(mesh.notes)
    if (mesh.closed and light.type != "directional"
            and abs(winding_number(mesh, light.position)) > 0.5):
        notes.append("the light is inside this closed mesh: all outside it is shadowed")
    if single and not (nested_counts or mesh.convex):
        notes.append("non-convex mesh drawn as one volume: a ray may enter it twice "
                     "and saturate the alpha/screen state machine")
    if not single and not mesh.closed:
        notes.append(f"not closed (open or non-manifold edges): {volumes} per-triangle volumes")
    return notes


def silhouette_volume(mesh: CleanMesh, light: Light, *, caps: bool):
    """One volume for a closed mesh: (triangles (T, 3, 4), number of silhouette edges, its
    light-facing triangles)."""
    v, f = mesh.vertices, mesh.faces
    lit = light_facing(v[f], light) > 0
    a, b, twin = directed_edges(mesh)
    edge_lit = np.repeat(lit, 3)
    silhouette = edge_lit & ~edge_lit[twin]
    parts = [_sides(v[a[silhouette]], v[b[silhouette]], light)]
    if caps:
        parts.append(_finite(v[f[lit]]))
        if light.type != "directional":
            parts.append(_at_infinity(v[f[~lit]], light))
    return np.concatenate(parts), int(silhouette.sum()), v[f[lit]]


def polygon_volumes(mesh: CleanMesh, light: Light, *, caps: bool):
    """One volume per triangle not edge-on to the light: (triangles, volume index of each,
    number of volumes, the triangles turned toward the light)."""
    tri = toward_light(mesh, light)
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
    return np.concatenate(pieces), np.concatenate(owners), count, tri


def build(parts: list[MeshPart], light: Light, *, caps: bool, nested_counts: bool,
          grouping: str, meshes: list[CleanMesh] | None = None) -> VolumeSet:
    """All volumes of a scene (``meshes``: the parts already :func:`clean`, which depends on
    the geometry alone, so a moving light reuses it).

    ``nested_counts``: the counter holds several entries per ray (the stencil's integer, or
    the max normalisation's 1, 1/2, 1/4 ...), so any closed mesh may be one silhouette volume;
    otherwise (the alpha/screen state machine normalised by rectangles, which tells 0 from
    "at least 1" only) only convex ones may, unless ``grouping`` is ``silhouette``, which
    forces it (to show the saturation error). ``grouping`` ``polygon`` makes every triangle its
    own volume.
    """
    triangles, owners, casters, caster_volume, warnings = [], [], [], [], []
    volumes = edges = 0
    for part, mesh in zip(parts, meshes or map(clean, parts)):
        if not len(mesh.faces):
            warnings.append(f"{part.name}: no non-degenerate triangles; casts no shadow")
            continue
        single = one_volume(mesh, grouping, nested_counts)
        if single:
            tri, n_edges, lit = silhouette_volume(mesh, light, caps=caps)
            triangles.append(tri)
            owners.append(np.full(len(tri), volumes))
            casters.append(lit)
            caster_volume.append(np.full(len(lit), volumes))
            volumes += 1
            edges += n_edges
            count = 1
        else:
            tri, owner, count, lit = polygon_volumes(mesh, light, caps=caps)
            triangles.append(tri)
            owners.append(owner + volumes)
            casters.append(lit)
            caster_volume.append(np.arange(count) + volumes)
            volumes += count
        notes = part_notes(mesh, light, single=single, nested_counts=nested_counts,
                           volumes=count)
        if notes:
            warnings.append(f"{part.name}: " + "; ".join(notes))
    tri = np.concatenate(triangles) if triangles else np.zeros((0, 3, 4))
    owner = np.concatenate(owners) if owners else np.zeros(0, np.int64)
    lit = np.concatenate(casters) if casters else np.zeros((0, 3, 3))
    lit_owner = np.concatenate(caster_volume) if caster_volume else np.zeros(0, np.int64)
    return VolumeSet(tri.astype(np.float32), owner, volumes, edges, warnings, lit, lit_owner)


def camera_facing(triangles: np.ndarray, view_proj: np.ndarray) -> np.ndarray:
    """True where a triangle faces the camera (counter-clockwise on screen, GL's default).

    The sign of det[x y w] of the clip-space vertices is the triangle's orientation as seen
    from the eye, valid for w <= 0 vertices too, so no clipping is needed to decide it."""
    clip = triangles.astype(np.float64) @ view_proj.T
    return np.linalg.det(clip[:, :, [0, 1, 3]]) > 0


def draw_order(volume_of: np.ndarray, increments: np.ndarray) -> np.ndarray:
    """The order that draws triangles volume by volume, the faces that increment the count
    first: what the alpha/screen state machine needs (Roettger et al. section 4.2). Stencil
    ignores it."""
    return np.lexsort((~increments, volume_of))


def _volume_planes(casters: np.ndarray, light: Light) -> np.ndarray:
    """The four planes (a, b, c, d) bounding each caster's volume, positive inside: behind the
    caster (away from the light) and within the three sides through its edges. (C, 4, 4)."""
    a, b, c = casters[:, 0], casters[:, 1], casters[:, 2]
    normal = np.cross(b - a, c - a)  # toward the light
    planes = [np.concatenate([-normal, np.einsum("ij,ij->i", normal, a)[:, None]], axis=1)]
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):
        along = (np.broadcast_to(light.direction, p.shape) if light.type == "directional"
                 else p - light.position)
        m = np.cross(q - p, along)
        m *= np.sign(np.einsum("ij,ij->i", m, r - p))[:, None]
        planes.append(np.concatenate([m, -np.einsum("ij,ij->i", m, p)[:, None]], axis=1))
    return np.stack(planes, axis=1)


# The near rectangle in normalised device coordinates, counter-clockwise, a little larger than
# the viewport so that rounding never leaves its border pixels out.
NEAR_RECTANGLE = 1.001 * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def _clip(polygon: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: a convex polygon (N, 2) cut by half-planes A x + B y + C >= 0."""
    for line in lines:
        if len(polygon) == 0:
            break
        side = polygon @ line[:2] + line[2]
        following = np.roll(polygon, -1, axis=0)
        side_following = np.roll(side, -1)
        kept = []
        for point, nxt, s, s_next in zip(polygon, following, side, side_following):
            if s >= 0:
                kept.append(point)
            if (s >= 0) != (s_next >= 0):
                kept.append(point + (nxt - point) * (s / (s - s_next)))
        polygon = np.array(kept).reshape(-1, 2)
    return polygon


def light_casters(meshes: list[CleanMesh], single: list[bool],
                  light: Light) -> tuple[np.ndarray, np.ndarray]:
    """The casters of every volume, (C, 3, 3) float64 counter-clockwise seen from the light,
    and the volume of each (C,), volumes numbered as :func:`build` numbers them: what
    :func:`near_clip_polygons` clips, without building the volumes."""
    casters, owners, volumes = [np.zeros((0, 3, 3))], [np.zeros(0, np.int64)], 0
    for mesh, one in zip(meshes, single):
        if not len(mesh.faces):
            continue
        if one:
            tri = mesh.vertices[mesh.faces]
            casters.append(tri[light_facing(tri, light) > 0])
            owners.append(np.full(len(casters[-1]), volumes))
            volumes += 1
        else:
            casters.append(toward_light(mesh, light))
            owners.append(volumes + np.arange(len(casters[-1])))
            volumes += len(casters[-1])
    return np.concatenate(casters), np.concatenate(owners)


def near_clip_polygons(casters: np.ndarray, caster_volume: np.ndarray, light: Light,
                       view_proj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each volume clipped at the camera's near plane (Roettger et al. section 3.2): where the
    near plane lies inside a volume, the clip polygon, as counter-clockwise triangles of
    normalised device x, y (K, 3, 2) with the volume of each (K,).

    Done per caster (its volume is convex, the intersection of four half-spaces) in double
    precision: on the near plane (z_ndc = -1) a plane p . X >= 0 is the line
    (p . inverse(view_proj)) . (x, y, -1, 1) >= 0. A non-convex volume's clip polygon is the
    union of its casters' pieces, with the nesting its count has."""
    if not len(casters):
        return np.zeros((0, 3, 2)), np.zeros(0, np.int64)
    planes = _volume_planes(casters, light) @ np.linalg.inv(view_proj)
    lines = np.stack([planes[..., 0], planes[..., 1], planes[..., 3] - planes[..., 2]], axis=-1)
    corner_sides = lines[..., :2] @ NEAR_RECTANGLE.T + lines[..., 2:]  # (C, 4 lines, 4 corners)
    reaches = ~(corner_sides < 0).all(axis=2).any(axis=1)
    triangles, owners = [], []
    for caster in np.flatnonzero(reaches):
        polygon = _clip(NEAR_RECTANGLE, lines[caster])
        for k in range(1, len(polygon) - 1):
            triangles.append(polygon[[0, k, k + 1]])
            owners.append(caster_volume[caster])
    if not triangles:
        return np.zeros((0, 3, 2)), np.zeros(0, np.int64)
    return np.array(triangles), np.array(owners)
