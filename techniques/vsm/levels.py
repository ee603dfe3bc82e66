"""The levels of a virtual shadow map: where each one's virtual texels lie, and which level and
page a visible point needs (the NumPy float64 form of vsm_levels.glsl, its test oracle).

A level is a light frustum with a virtual resolution (``res`` texels per side) cut into pages
of ``page`` texels. A directional light has ``levels`` clipmap levels of ``virtual_res``
texels: the coarsest is the light frustum of the whole scene (``fit_light``), each finer one
covers half its width around the camera, its centre snapped to whole pages of its own so that
a camera move shifts its grid by whole pages (a page keeps its texels while it stays in view).
Past the coarsest come its mips, down to a single page: pixels far from the camera and
coarsening under a full pool take them. A spot light has one frustum (its cone) and mips
only, from ``virtual_res`` down to a single page.

Pages are named by global page coordinates: the page's place on the level's grid anchored in
the light's fixed frame, not on the moving window, so a cached page is found again after the
window has moved (its table slot is the global coordinate modulo the pages per side)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from harness.scene.transforms import LightFrustum, fit_light

# The most levels a map has: levels clipmap levels (at most 16) and the coarsest's mips down
# to one page (at most 16384 / 8 = 2^11): vsm_levels.glsl's MAX_LEVELS.
MAX_LEVELS = 32


@dataclass(frozen=True)
class Levels:
    """Per level k: world -> light view (K, 4, 4), the projection (K, 4, 4), texels per side
    (K,), the global page coordinate of its window's first page (K, 2) int, pages per side
    (K,), and where its pages begin in the page table (K,); ``nested``: the levels 0..nested-1
    cover only a window about the camera (a directional light's finer clipmap levels), so a
    point outside one goes to the next coarser."""

    views: np.ndarray
    projs: np.ndarray
    res: np.ndarray
    origins: np.ndarray
    pages: np.ndarray
    bases: np.ndarray
    nested: int
    page: int
    ortho: bool

    @property
    def count(self) -> int:
        return len(self.res)

    @property
    def map_grids(self) -> list[tuple[np.ndarray, float]]:
        """(world -> clip matrix, texels per side) of each level: what texels_per_pixel reads."""
        return [(proj @ view, float(res)) for view, proj, res in zip(self.views, self.projs,
                                                                    self.res)]

    @property
    def table_size(self) -> int:
        return int(self.bases[-1] + self.pages[-1] ** 2)


def sequence_bounds(sequence) -> np.ndarray:
    """The box holding a (moving) scene's geometry at every frame of its sequence: the
    coarsest level is fitted to it, so it does not follow a moving object (which would move
    every page's texels) and a technique prepared at any frame fits the same one."""
    boxes = np.array([sequence.at_frame(t).bounds for t in range(sequence.frames)])
    return np.array([boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])


def top_frustum(light, bounds: np.ndarray) -> LightFrustum:
    """The coarsest level's frustum: the light's own map frustum (sm's) over ``bounds``."""
    return fit_light(SimpleNamespace(light=light, bounds=bounds), 1)


def level_chain(top: LightFrustum, camera_position: np.ndarray, virtual_res: int, page: int,
                clipmap_levels: int) -> Levels:
    """The levels of a map whose coarsest (full-resolution) level is ``top``: for an
    orthographic ``top`` (directional light) ``clipmap_levels`` clipmap levels about the camera,
    then ``top``'s mips; for a perspective one (spot) its mips alone."""
    pages_top = virtual_res // page
    mips = int(math.log2(pages_top))  # the last mip is one page
    views, projs, res, origins = [], [], [], []
    nested = clipmap_levels - 1 if top.is_ortho else 0
    centre = (top.view @ np.append(np.asarray(camera_position, np.float64), 1.0))[:2]
    for k in range(nested):
        scale = 2.0 ** (nested - k)  # the top's half-width over this level's
        page_world = 2.0 / (top.proj[[0, 1], [0, 1]] * scale * pages_top)
        snapped = np.round(centre / page_world)
        view = top.view.copy()
        view[:2, 3] -= snapped * page_world
        proj = top.proj.copy()
        proj[0, 0] *= scale
        proj[1, 1] *= scale
        views.append(view)
        projs.append(proj)
        res.append(virtual_res)
        origins.append(snapped.astype(np.int64) - pages_top // 2)
    for m in range(mips + 1):
        views.append(top.view)
        projs.append(top.proj)
        res.append(virtual_res >> m)
        origins.append(np.zeros(2, np.int64))
    res = np.array(res, np.int64)
    pages = res // page
    bases = np.concatenate([[0], np.cumsum(pages ** 2)[:-1]])
    return Levels(np.array(views), np.array(projs), res, np.array(origins), pages, bases,
                  nested, page, top.is_ortho)


def pixel_angle(camera_proj: np.ndarray, height: int) -> float:
    """A pixel's width over its distance from the camera (2 tan(yfov / 2) / height)."""
    return 2.0 / (float(camera_proj[1, 1]) * height)


def texel_world(levels: Levels, k: int, points: np.ndarray) -> np.ndarray:
    """The world side of the square of level k's texel's area at ``points`` (N, 3): 2 w /
    (projection scale x texels), w the clip w (1 orthographic, the light depth perspective),
    the scale the geometric mean of the two axes' (a frustum fitted to the scene may give its
    texels two sides)."""
    clip = np.c_[points, np.ones(len(points))] @ (levels.projs[k] @ levels.views[k]).T
    scale = np.sqrt(levels.projs[k][0, 0] * levels.projs[k][1, 1])
    return 2.0 * clip[:, 3] / (scale * levels.res[k])


def map_texels(levels: Levels, k: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Each point's continuous texel position (N, 2) in its level k."""
    m = levels.projs[k] @ levels.views[k]  # (N, 4, 4)
    clip = np.einsum("nij,nj->ni", m, np.c_[points, np.ones(len(points))])
    return (clip[:, :2] / clip[:, 3:] * 0.5 + 0.5) * levels.res[k][:, None]


def coarsening_steps(count: int) -> list[tuple[int, float]]:
    """The (level bias, slant floor) pairs a full pool tries in turn: the slant's floors at the
    natural levels, then the whole view a level coarser at a time at the last floor."""
    return ([(0, floor) for floor in SLANT_FLOORS]
            + [(bias, SLANT_FLOORS[-1]) for bias in range(1, count)])


def light_vector(light) -> np.ndarray:
    """vsm_levels.glsl's ``light_vector``: (position, 1) for a spot light, (toward the light, 0)
    for a directional one."""
    if light.type == "directional":
        return np.append(-np.asarray(light.direction, np.float64), 0.0)
    return np.append(np.asarray(light.position, np.float64), 1.0)


# How far the receiver's slant moves a pixel's level (vsm_levels.glsl's slant_floor and
# SLANT_CEILING): at most three levels coarser (a receiver edge-on to the camera), and finer by
# the first floor whose pages fit the pool, two levels at most, then one, before the whole view
# coarsens (a sphere's terminator, almost edge-on to the light, asks ever finer pages: at 0.25
# instancing's spheres marked 492 to 547 pages, twice the default pool).
SLANT_FLOORS = (0.25, 0.5)
SLANT_CEILING = 8.0


def natural_level(levels: Levels, points: np.ndarray, normals: np.ndarray,
                  camera_position: np.ndarray, light: np.ndarray, angle: float,
                  slant_floor: float = SLANT_FLOORS[0]) -> tuple[np.ndarray, np.ndarray]:
    """The level whose texel is the largest not above the pixel's footprint, both taken on the
    receiver's plane: floor(log2(footprint / level 0's texel)), within the levels; and that
    log2 (to tell how near a point is to the next level). On the plane of normal n a pixel at
    distance d covers (d ``angle``)^2 / |n.v| and a texel of side t (t^2 / |n.l|, v and l the
    directions to the camera and to ``light``, light_vector's form), so a texel is at most a
    pixel across on the receiver where t <= d ``angle`` sqrt(|n.l| / |n.v|), that factor held
    within ``slant_floor`` .. SLANT_CEILING."""
    to_eye = camera_position - points
    to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
    to_light = np.broadcast_to(light[:3], points.shape) - light[3] * points
    to_light = to_light / np.linalg.norm(to_light, axis=1, keepdims=True)
    facing_eye = np.maximum(np.abs(np.einsum("nk,nk->n", normals, to_eye)), 1e-6)
    slant = np.clip(np.sqrt(np.abs(np.einsum("nk,nk->n", normals, to_light)) / facing_eye),
                    slant_floor, SLANT_CEILING)
    footprint = np.linalg.norm(points - camera_position, axis=1) * angle * slant
    texel = texel_world(levels, 0, points)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.log2(footprint / texel)
    # a point behind a spot light (texel <= 0) lies in no level's frustum: the coarsest
    k = np.where(texel > 0, np.clip(np.floor(np.nan_to_num(ratio)), 0, levels.count - 1),
                 levels.count - 1)
    return k.astype(np.int64), ratio


def choose_levels(levels: Levels, points: np.ndarray, normals: np.ndarray,
                  camera_position: np.ndarray, light: np.ndarray, angle: float,
                  bias: int = 0, slant_floor: float = SLANT_FLOORS[0]) -> np.ndarray:
    """vsm_levels.glsl's choice per point: the natural level (at ``slant_floor``) plus ``bias``
    (coarsening), then coarser while the point lies within a page of a nested level's window
    edge."""
    k = np.minimum(natural_level(levels, points, normals, camera_position, light, angle,
                                 slant_floor)[0] + bias, levels.count - 1)
    for _ in range(levels.nested):
        texel = map_texels(levels, k, points)
        res = levels.res[k][:, None]
        outside = ((texel < levels.page) | (texel > res - levels.page)).any(axis=1)
        k = np.where(outside & (k < levels.nested), k + 1, k)
    return k
