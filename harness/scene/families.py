"""Scene families that scale: procedural geometry of a declared triangle count, built the same
way every time (seeded), for the scale experiment (experiments/scale.yaml).

Each family lands at most at its target and within ``TOLERANCE`` below it. Geometry is made
of grids (:func:`_grid`) mapped into place with NumPy; Python loops run per element or per
object copy (a building, a tree, a sphere), never per triangle. Everything stands on the
ground square of side ``GROUND`` centred at the origin, at every size, so one camera and light
serve all sizes of a family.

- tessellation: a box caster over a plane receiver, both refined. The shapes, and so the
  shadow, are the same at every size; only the triangle count grows (geometry cost alone).
- instancing: closed icospheres on a grid over a plane: more casters, more shadow edges.
- architecture: buildings of open, thin, non-manifold parts: single-sided walls, low-pitched
  single-sided roofs (grazing to the light) with eaves past the walls, a ridge fin sharing the
  ridge with both roof planes (three faces on an edge), open columns, stairs, an arch and a
  fence of picket cards.
- foliage: trees of many thin open cards (leaves) around a trunk: shadow-volume fill explodes.
- cards: foliage as engines draw it: trees whose leaves are alpha-tested cards (a leaf
  texture cuts each quad out, harness/scene/alpha.py) along branches; trunks and branches
  opaque.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .. import config as cfg
from .alpha import QUAD_UV, AlphaMask, pattern_texture

TOLERANCE = 0.05
GROUND = 20.0  # side of the ground square every family stands on
Mesh = tuple[np.ndarray, np.ndarray]  # vertices (V, 3) float64, faces (F, 3) int32


def _grid(nu: int, nv: int, place: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Mesh:
    """An nu x nv grid of quads (2 nu nv triangles) over (u, v) in [0, 1]^2, its vertices
    ``place(u, v)`` (arrays of shape (nv + 1, nu + 1) -> (..., 3)). Counter-clockwise in
    (u, v): the front faces the side ``du x dv`` points to."""
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1))
    vertices = np.asarray(place(u, v), np.float64).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv))
    a = (j * (nu + 1) + i).ravel()
    b, c, d = a + 1, a + nu + 2, a + nu + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return vertices, faces.astype(np.int32)


def _merge(meshes: list[Mesh]) -> Mesh:
    """One mesh of several, their vertices kept apart (shared positions stay separate)."""
    offsets = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
    return (np.concatenate([v for v, _ in meshes]),
            np.concatenate([f + o for (_, f), o in zip(meshes, offsets)]).astype(np.int32))


def _quad(origin, du, dv, nu: int = 1, nv: int = 1) -> Mesh:
    """A parallelogram ``origin + u du + v dv`` as an nu x nv grid."""
    o, du, dv = (np.asarray(x, np.float64) for x in (origin, du, dv))
    return _grid(nu, nv, lambda u, v: o + u[..., None] * du + v[..., None] * dv)


def _ground(nu: int = 1, nv: int = 1) -> Mesh:
    h = GROUND / 2
    return _quad((-h, -h, 0), (GROUND, 0, 0), (0, GROUND, 0), nu, nv)


def _tube(centre, radius: float, height: float, sections: int) -> Mesh:
    """An open cylinder (no caps) about +z, outward faces: 2 * sections triangles."""
    c = np.asarray(centre, np.float64)

    def place(u, v):
        angle = 2 * np.pi * u
        return c + np.stack([radius * np.cos(angle), radius * np.sin(angle), height * v], -1)

    return _grid(sections, 1, place)


def _icosphere(subdivisions: int) -> Mesh:
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    return np.asarray(sphere.vertices, np.float64), np.asarray(sphere.faces, np.int32)


# --- tessellation -----------------------------------------------------------------------------

def _box(m: int, half) -> Mesh:
    """A closed box of half extents ``half``, each face an m x m grid (12 m^2 triangles), its
    vertices shared along the box's edges (the same linspace values on every face)."""
    axes = np.eye(3)
    faces_of_box = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            a, b = (axis + 1) % 3, (axis + 2) % 3  # a x b = +axis
            if sign < 0:
                a, b = b, a  # keep the front (du x dv) outward

            def place(u, v, axis=axis, sign=sign, a=a, b=b):
                return (sign * half[axis] * axes[axis] + ((2 * u - 1) * half[a])[..., None]
                        * axes[a] + ((2 * v - 1) * half[b])[..., None] * axes[b])

            faces_of_box.append(_grid(m, m, place))
    vertices, faces = _merge(faces_of_box)
    unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
    return unique, inverse.reshape(-1)[faces].astype(np.int32)


def _receiver_cells(triangles: int) -> tuple[int, int]:
    """nu, nv with 2 nu nv at most ``triangles`` and close below it."""
    nu = max(1, math.isqrt(max(triangles // 2, 1)))
    return nu, max(1, triangles // (2 * nu))


def tessellation(triangles: int, rng: np.random.Generator) -> list[tuple[str, Mesh]]:
    m = max(1, math.isqrt(triangles // 24))
    vertices, faces = _box(m, np.array([1.0, 1.0, 1.0]))
    caster = (vertices + [0.0, 0.0, 2.5], faces)
    receiver = _ground(*_receiver_cells(triangles - len(faces)))
    return [("receiver", receiver), ("caster", caster)]


# --- instancing -------------------------------------------------------------------------------

def _layout(count: int, rng: np.random.Generator, margin: float = 1.0):
    """``count`` cell centres on a near-square grid over the ground (minus ``margin``), jittered
    by up to a tenth of a cell, and the cell size."""
    columns = math.ceil(math.sqrt(count))
    cell = (GROUND - 2 * margin) / columns
    index = np.arange(count)
    centres = np.stack([index % columns, index // columns], 1) * cell - (GROUND / 2 - margin
                                                                          - cell / 2)
    return centres + rng.uniform(-0.1, 0.1, (count, 2)) * cell, cell


def instancing(triangles: int, rng: np.random.Generator) -> list[tuple[str, Mesh]]:
    vertices, faces = _icosphere(1 if triangles < 10_000 else 2)
    copies = (triangles - 2) // len(faces)
    centres, cell = _layout(copies, rng)
    radii = rng.uniform(0.25, 0.4, copies) * cell
    heights = radii + rng.uniform(0.3, 1.0, copies) * cell
    parts = [("ground", _ground(*_receiver_cells(triangles - copies * len(faces))))]
    for k in range(copies):
        parts.append((f"sphere{k}", (vertices * radii[k] + [*centres[k], heights[k]], faces)))
    return parts


# --- architecture -----------------------------------------------------------------------------

STEPS, ARCH_SEGMENTS, COLUMN_SECTIONS = 5, 10, 12


def _building_fixed() -> int:
    """Triangles of a building besides its walls, roofs, ridge fin and pickets: four columns,
    the stairs, the arch (face and intrados), the fence rail and the gable ends."""
    return 4 * 2 * COLUMN_SECTIONS + 4 * STEPS + 2 * 2 * ARCH_SEGMENTS + 2 + 2


def _building_triangles(detail: int, pickets: int) -> int:
    return 4 * 2 * detail ** 2 + 2 * 2 * detail * 2 * detail + 2 * detail + _building_fixed() \
        + 2 * pickets


def _building(detail: int, pickets: int, size: float, rng: np.random.Generator) -> Mesh:
    """One building in a cell of side ``size`` at the origin, of ``_building_triangles``."""
    w, d = size * rng.uniform(0.3, 0.4, 2)  # half width and depth of the walls
    h = size * rng.uniform(0.25, 0.45)  # wall height
    pitch = math.radians(rng.uniform(8, 18))  # low: grazing to the light
    eave = 0.12 * size
    rise = (d + eave) * math.tan(pitch)
    n = detail
    parts = [  # single-sided walls, each a separate sheet (open, corners not shared)
        _quad((-w, -d, 0), (2 * w, 0, 0), (0, 0, h), n, n),
        _quad((w, d, 0), (-2 * w, 0, 0), (0, 0, h), n, n),
        _quad((w, -d, 0), (0, 2 * d, 0), (0, 0, h), n, n),
        _quad((-w, d, 0), (0, -2 * d, 0), (0, 0, h), n, n),
        # two roof planes past the walls (eaves) meeting at the ridge, and a fin on the ridge:
        # the ridge edges have three faces (non-manifold)
        _quad((-w - eave, -d - eave, h), (2 * (w + eave), 0, 0), (0, d + eave, rise), 2 * n, n),
        _quad((w + eave, d + eave, h), (-2 * (w + eave), 0, 0), (0, -d - eave, rise), 2 * n, n),
        _quad((-w - eave, 0, h + rise), (2 * (w + eave), 0, 0), (0, 0, 0.1 * size), n, 1),
    ]
    gable = [[-w, -d, h], [-w, d, h], [-w, 0, h + rise * d / (d + eave)]]
    parts.append((np.array(gable + [[w, d, h], [w, -d, h], [gable[2][0] + 2 * w, 0, gable[2][2]]]),
                   np.array([[0, 2, 1], [3, 5, 4]], np.int32)))
    column_r = 0.03 * size
    for cx in (-w * 0.7, -w * 0.25, w * 0.25, w * 0.7):  # a portico in front of the south wall
        parts.append(_tube((cx, -d - eave * 0.8, 0), column_r, h, COLUMN_SECTIONS))
    step_run, step_rise = eave / STEPS * 2, h / 3 / STEPS
    for k in range(STEPS):  # stairs up the east wall: riser and tread, open underneath
        x0, z0 = w + 2 * eave - k * step_run, k * step_rise
        parts.append(_quad((x0, -d * 0.5, z0), (0, d * 0.4, 0), (0, 0, step_rise)))
        parts.append(_quad((x0, -d * 0.5, z0 + step_rise), (-step_run, 0, 0), (0, d * 0.4, 0)))
    outer, inner = 0.25 * size, 0.18 * size  # an arch in front of the west wall

    def arch_face(u, v):
        angle, radius = np.pi * u, inner + (outer - inner) * v
        return np.stack([np.full_like(u, -w - eave), radius * np.cos(angle),
                         h * 0.2 + radius * np.sin(angle)], -1)

    def intrados(u, v):
        angle = np.pi * u
        return np.stack([-w - eave - 0.05 * size * v, inner * np.cos(angle),
                         h * 0.2 + inner * np.sin(angle)], -1)

    parts += [_grid(ARCH_SEGMENTS, 1, arch_face), _grid(ARCH_SEGMENTS, 1, intrados)]
    fence_y, fence_h = -size * 0.47, 0.12 * size
    parts.append(_quad((-size * 0.45, fence_y, fence_h * 0.6), (size * 0.9, 0, 0),
                       (0, 0, fence_h * 0.15)))
    if pickets:  # picket cards along the rail, each two triangles
        x = np.linspace(-size * 0.45, size * 0.45, pickets)
        width = 0.4 * size * 0.9 / pickets
        corners = np.array([[-width, 0, 0], [width, 0, 0], [width, 0, fence_h],
                            [-width, 0, fence_h]])
        vertices = (corners[None] + np.stack([x, np.full_like(x, fence_y), 0 * x], 1)[:, None])
        quad = np.array([[0, 1, 2], [0, 2, 3]])
        faces = (quad[None] + 4 * np.arange(pickets)[:, None, None]).reshape(-1, 3)
        parts.append((vertices.reshape(-1, 3), faces.astype(np.int32)))
    return _merge(parts)


def architecture(triangles: int, rng: np.random.Generator) -> list[tuple[str, Mesh]]:
    buildings = max(1, round(math.sqrt(triangles) / 6))
    each = (triangles - 2) // buildings
    # walls and roofs take about 60% of a building, the fence's pickets the rest
    detail = max(1, math.isqrt(max(int(0.6 * (each - _building_fixed()) / 16), 1)))
    while detail > 1 and _building_triangles(detail, 0) > each:
        detail -= 1
    pickets = (each - _building_triangles(detail, 0)) // 2
    centres, cell = _layout(buildings, rng, margin=0.5)
    parts = []
    for k in range(buildings):
        vertices, faces = _building(detail, pickets, cell, rng)
        turn = rng.integers(4) * np.pi / 2  # a quarter turn, so walls face every way
        c, s = math.cos(turn), math.sin(turn)
        vertices = vertices @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
        parts.append((f"building{k}", (vertices + [*centres[k], 0], faces)))
    used = sum(len(f) for _, (_, f) in parts)
    return [("ground", _ground(*_receiver_cells(triangles - used)))] + parts


# --- foliage ----------------------------------------------------------------------------------

TRUNK_SECTIONS = 6


def _quads(centre: np.ndarray, axis_u: np.ndarray, length: float, width: float,
           rng: np.random.Generator) -> Mesh:
    """Cards (two triangles each) centred at ``centre`` (N, 3), ``length`` along ``axis_u``
    (N, 3, normalised here) and ``width`` across, turned at random about it; each card's four
    corners in alpha.QUAD_UV's order."""
    axis_u = axis_u / np.linalg.norm(axis_u, axis=1, keepdims=True)
    axis_v = np.cross(axis_u, rng.normal(size=axis_u.shape))
    axis_v /= np.linalg.norm(axis_v, axis=1, keepdims=True)
    u, v = axis_u * length / 2, axis_v * width / 2
    corners = np.stack([centre - u - v, centre + u - v, centre + u + v, centre - u + v], 1)
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    faces = (quad[None] + 4 * np.arange(len(centre))[:, None, None]).reshape(-1, 3)
    return corners.reshape(-1, 3), faces.astype(np.int32)


def foliage(triangles: int, rng: np.random.Generator) -> list[tuple[str, Mesh]]:
    trees = max(1, round(math.sqrt(triangles) / 4))
    cards = ((triangles - 2) // trees - 2 * TRUNK_SECTIONS) // 2
    centres, cell = _layout(trees, rng, margin=0.5)
    crown = 0.4 * cell
    # the same leaf area per tree at every size: smaller cards as there are more
    length = crown * 1.6 / math.sqrt(max(cards, 1)) * 2
    parts = []
    for k in range(trees):
        trunk_h = crown * rng.uniform(1.2, 1.8)
        trunk = _tube((*centres[k], 0), 0.08 * crown, trunk_h + crown, TRUNK_SECTIONS)
        # card centres in the crown's ball, axes random: a thin quad (length x length / 4)
        centre = rng.normal(size=(cards, 3))
        centre *= (crown * rng.uniform(0, 1, cards) ** (1 / 3)
                   / np.linalg.norm(centre, axis=1))[:, None]
        centre += [*centres[k], trunk_h + crown]
        leaves = _quads(centre, rng.normal(size=(cards, 3)), length, length / 4, rng)
        parts.append((f"tree{k}", _merge([trunk, leaves])))
    used = sum(len(f) for _, (_, f) in parts)
    return [("ground", _ground(*_receiver_cells(triangles - used)))] + parts


# --- cards -------------------------------------------------------------------------------------

BRANCHES, BRANCH_SECTIONS = 6, 4
LEAF = ("leaf", 64, 0.5)  # the cards' cut-out: pattern, texels, cutoff


def _segment(start, end, radius: float, sections: int) -> Mesh:
    """An open tube from ``start`` to ``end``: 2 * sections triangles."""
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    axis = end - start
    side = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 * np.linalg.norm(axis)
                    else [1.0, 0.0, 0.0])
    side *= radius / np.linalg.norm(side)
    other = np.cross(axis, side) * (radius / np.linalg.norm(np.cross(axis, side)))

    def place(u, v):
        angle = 2 * np.pi * u[..., None]
        return start + np.cos(angle) * side + np.sin(angle) * other + v[..., None] * axis

    return _grid(sections, 1, place)


def _cards_triangles_per_tree(cards: int) -> int:
    return 2 * TRUNK_SECTIONS + BRANCHES * 2 * BRANCH_SECTIONS + 2 * cards


def cards(triangles: int, rng: np.random.Generator) -> list[tuple[str, Mesh]]:
    """Trees as ``foliage``'s, their leaves cut out of cards by LEAF, the cards spread along
    BRANCHES branches from the trunk's top: per tree a part ``tree{k}`` (trunk and branches,
    opaque) and a part ``cards{k}`` (the cards, each quad's corners in QUAD_UV's order)."""
    # half foliage's trees in each direction: a tree's trunk and branches (60 triangles) take
    # a quarter of the family at 10^3, under 2 % at 10^5
    trees = max(1, round(math.sqrt(triangles) / 8))
    per_tree = (triangles - 2) // trees
    count = (per_tree - _cards_triangles_per_tree(0)) // 2
    centres, cell = _layout(trees, rng, margin=0.5)
    crown = 0.4 * cell
    # the same leaf area per tree at every size; a card is length x length / 2, and the leaf
    # covers about 57 % of it
    length = crown * 2.4 / math.sqrt(max(count, 1))
    parts = []
    for k in range(trees):
        trunk_h = crown * rng.uniform(1.2, 1.8)
        top = np.array([*centres[k], trunk_h])
        wood = [_tube((*centres[k], 0), 0.08 * crown, trunk_h, TRUNK_SECTIONS)]
        heading = rng.normal(size=(BRANCHES, 3)) * [1, 1, 0.4] + [0, 0, 0.6]
        heading /= np.linalg.norm(heading, axis=1, keepdims=True)
        tips = top + heading * crown
        wood += [_segment(top, tip, 0.03 * crown, BRANCH_SECTIONS) for tip in tips]
        # cards along the branches, beyond their first quarter, turned at random about them
        branch = rng.integers(BRANCHES, size=count)
        along = rng.uniform(0.25, 1.0, count)[:, None]
        centre = top + heading[branch] * crown * along + rng.normal(
            scale=0.08 * crown, size=(count, 3))
        along_branch = heading[branch] + rng.normal(scale=0.5, size=(count, 3))
        parts += [(f"tree{k}", _merge(wood)),
                  (f"cards{k}", _quads(centre, along_branch, length, length / 2, rng))]
    used = sum(len(f) for _, (_, f) in parts)
    return [("ground", _ground(*_receiver_cells(triangles - used)))] + parts


def _cards_texcoords(name: str, faces: np.ndarray) -> np.ndarray | None:
    """The corners' texture coordinates of a ``cards`` part (its quads' corners 0..3 are
    QUAD_UV's), None for the opaque ones."""
    return QUAD_UV[faces % 4] if name.startswith("cards") else None


KINDS = {"tessellation": tessellation, "instancing": instancing,
         "architecture": architecture, "foliage": foliage, "cards": cards}
TEXCOORDS = {"cards": _cards_texcoords}  # the families with cut-outs


def alpha_mask(kind: str) -> AlphaMask | None:
    """The cut-out of the family's parts that have texture coordinates (None: opaque)."""
    if kind not in TEXCOORDS:
        return None
    pattern, texels, cutoff = LEAF
    return AlphaMask(pattern_texture(pattern, texels, texels), cutoff,
                     f"the {kind} family's {pattern} pattern")


def build(family: cfg.Family
          ) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The family's parts as (name, vertices (V, 3) float32, faces (F, 3) int32, corners'
    texture coordinates (F, 3, 2) float32 of a cut-out part, else None: every part without
    them when the family's ``cutouts`` are off)."""
    rng = np.random.default_rng(family.seed)
    texcoords = TEXCOORDS.get(family.kind if family.cutouts else None, lambda name, faces: None)
    return [(name, vertices.astype(np.float32), faces, texcoords(name, faces))
            for name, (vertices, faces) in KINDS[family.kind](family.triangles, rng)]
