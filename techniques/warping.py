"""Perspective reparameterization of a light's shadow map (a helper, not a technique).

Shared by ``psm``, ``lispsm`` and ``gmnpr``: the body B of points that need shadow-map
resolution (the view frustum clipped to the scene bounds and to the view-depth range of the
visible receivers, extended toward the light to its casters), the light-space warp of Wimmer et
al. 2004 (warp axis = view direction projected perpendicular to the light), the
post-perspective light of Stamminger and Drettakis 2002, the fit of the warped body to the unit
cube, the lambda formulas of Zhang et al. (equations 4, 8, 9 of "Generalized Minimum-Norm
Perspective Shadow Maps") and its analytic aliasing F (equation 2).

n and f, the view depths of the formulas, are the nearest and farthest view depth of the
visible receivers (the covered G-buffer pixels): the papers' body B is what the camera sees, and
the view frustum clipped to the scene bounds can start at the near plane and end far behind the
last visible surface. Where no receiver is visible the clipped frustum's range stands in.

A spot light is warped in its own post-projective space (its clip space, where its rays are
parallel and it is a directional light travelling along +z), as Wimmer et al.'s reference code
does; there theta, n and f are measured too.

Every map is expressed as a :class:`harness.transforms.LightFrustum`: ``view`` is a rigid light
basis whose -z is the light's travel direction (a spot light's own view), centred on the camera
(on a spot light), a local origin so the float32 GL passes keep their precision far from the
world origin, so map depth stays the linear distance along the light; ``proj`` carries the whole
warp. A texel is one world light ray in all three warps, so that linear depth orders occluders
correctly within a texel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import Callable

import numpy as np
from OpenGL import GL
from pydantic import Field

from harness import metrics
from harness.config import SquareInt
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams
from harness.transforms import (LightFrustum, any_perpendicular_up, box_corners, fit_light,
                               look_at)

from .shadowmap import LightDepthMap

# lambda is clamped here: at theta = 0 both LiSPSM's and GMNPR's lambda are infinite (the
# standard shadow map); 1e4 body depths of warp distance is indistinguishable from it.
LAMBDA_MAX = 1.0e4
# Fraction of the fitted extent left as margin on each side of the unit cube.
CUBE_MARGIN = 1.0e-3
# The aliasing statistics count surfaces with n . l above this (about 87 degrees from the light):
# a face parallel to the light has an infinite texel footprint, and the projection factor
# 1 / (n . l) of the faces counted stays below 20.
ALIAS_MIN_COS = 0.05
# alias_near: the nearest part of the visible depth range, where the papers argue for the warps.
NEAR_FRACTION = 0.2


# --- lambda and F (the paper's 2-D model: n, f view depths, phi half field of view) -----------


def lambda_minimum_norm(theta, phi, n, f):
    """Equation 4: the lambda making F(n) = F(f) (lambda_1 above phi, lambda_2 below)."""
    theta = np.asarray(theta, dtype=np.float64)
    t = math.tan(phi) / np.tan(np.maximum(theta, 1e-300))
    lam1 = (n + math.sqrt(f * n) - n * t) / (f - n + (f + n) * t)
    lam2 = (f + math.sqrt(f * n)) / (2 * f) / t - 0.5
    return np.where(theta >= phi, lam1, lam2)


def lambda_gmnpr(theta, phi, n, f):
    """Equation 8: lambda_1 for theta in [phi, pi/2], lambda_1(phi) / tan(pi theta / (4 phi))
    below, so lambda is continuous at phi and grows to infinity (the plain map) at theta = 0."""
    theta = np.asarray(theta, dtype=np.float64)
    below = math.sqrt(f * n) / (2 * f) / np.tan(np.pi * np.maximum(theta, 1e-300) / (4 * phi))
    return np.where(theta >= phi, lambda_minimum_norm(np.maximum(theta, phi), phi, n, f), below)


def n_opt(theta, n, f):
    """LiSPSM's warp-frustum near distance P_n = (n + sqrt(f n)) / sin(theta) (equation 9's
    numerator; Wimmer et al.'s n_opt), infinite at theta = 0."""
    with np.errstate(divide="ignore"):
        return (n + math.sqrt(f * n)) / np.sin(np.asarray(theta, dtype=np.float64))


def lambda_lispsm(theta, phi, n, f):
    """Equation 9: n_opt over the body depth P_f - P_n of the paper's 2-D model."""
    theta = np.maximum(np.asarray(theta, dtype=np.float64), 1e-300)
    t = math.tan(phi) / np.tan(theta)
    depth = np.where(theta >= phi, (f - n + (f + n) * t) * np.sin(theta),
                     2 * f * math.tan(phi) * np.cos(theta))
    return n_opt(theta, n, f) / depth


def aliasing_F(lam, theta, z, phi, n, f):
    """Equation 2: perspective aliasing F(lambda, theta, z) = psi (z + varphi)^2 / z."""
    lam, theta, z = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (lam, theta, z)))
    t = math.tan(phi) / np.tan(np.maximum(theta, 1e-300))
    a = f - n + (f + n) * t
    psi = np.where(theta >= phi, 1 / (math.tan(phi) * a * lam * (lam + 1)),
                   1 / (math.tan(phi) * 2 * f * lam * (lam + 1) / t))
    varphi = np.where(theta >= phi, a * lam + n * t - n, f * (2 * lam + 1) * t - f)
    return psi * (z + varphi) ** 2 / z


# The warp-frustum eye distance P_n of each light-space technique, in the units of the space the
# warp is made in, from theta, phi, the view depths n and f, and the body's depth along the warp
# axis: LiSPSM puts it at n_opt (Wimmer et al.'s code and OpenSceneGraph's
# LightSpacePerspectiveShadowMap do), GMNPR at lambda body depths (its lambda is for a
# normalised depth range P_f - P_n = 1).
EyeDistance = Callable[[float, float, float, float, float], float]


def lispsm_eye_distance(theta, phi, n, f, depth):
    return float(n_opt(theta, n, f))


def gmnpr_eye_distance(theta, phi, n, f, depth):
    return float(lambda_gmnpr(theta, phi, n, f)) * depth


# --- the camera and the light ---------------------------------------------------------------


@dataclass(frozen=True)
class ViewSetup:
    """What the warps need of the camera, the light and the visible receivers, in world space."""

    view: np.ndarray  # world -> camera view
    proj: np.ndarray
    eye: np.ndarray
    forward: np.ndarray  # unit view direction
    light: np.ndarray  # unit direction the light travels (a spot light's axis)
    near: float
    far: float
    bounds: np.ndarray
    visible: np.ndarray  # world positions of the visible receivers, (N, 3)
    spot: LightFrustum | None = None  # a spot light's perspective frustum; None: directional
    light_position: np.ndarray | None = None  # a spot light's position

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view

    @property
    def theta(self) -> float:
        """Angle between light and view directions folded to [0, pi/2] (the paper's symmetry)."""
        return math.acos(min(abs(float(self.forward @ self.light)), 1.0))

    @property
    def phi(self) -> float:
        """Half the frustum's angle in the plane of the view and light directions: the support
        of the image rectangle toward the light, so the body's extent along the warp axis is the
        paper's 2-D one (vertical half field of view for a light in the vertical plane)."""
        across = self.light - (self.light @ self.forward) * self.forward
        norm = np.linalg.norm(across)
        tan_x, tan_y = 1 / self.proj[0, 0], 1 / self.proj[1, 1]
        if norm < 1e-12:
            return math.atan(tan_y)
        cx, cy = (self.view[:2, :3] @ across) / norm
        return math.atan(tan_x * abs(cx) + tan_y * abs(cy))

    def view_depth(self, points: np.ndarray) -> np.ndarray:
        return -(points @ self.view[2, :3] + self.view[2, 3])

    @property
    def visible_depth_range(self) -> tuple[float, float] | None:
        """n and f: the nearest and farthest view depth of the visible receivers (None when no
        receiver is visible)."""
        if len(self.visible) == 0:
            return None
        depth = self.view_depth(self.visible)
        return float(depth.min()), float(depth.max())


def view_setup(frame) -> ViewSetup:
    """The camera, light and visible receivers (covered G-buffer pixels, inside a spot light's
    frustum) of a frame."""
    light = frame.scene.light
    cam = frame.scene.config.camera
    view = frame.camera.view
    arrays = frame.arrays
    visible = arrays.position[arrays.covered].astype(np.float64)
    spot = fit_light(frame.scene, 1) if light.type == "spot" else None
    if spot is not None:  # the receivers a spot light can reach: those in its frustum
        visible = visible[~outside_unit_cube(spot.view_proj, visible, np.ones(len(visible), bool))]
    return ViewSetup(view, frame.camera.proj, frame.camera.position, -view[2, :3],
                     np.asarray(light.direction, dtype=np.float64) / np.linalg.norm(light.direction),
                     float(cam.near), float(cam.far), frame.scene.bounds, visible, spot,
                     None if spot is None else np.asarray(light.position, dtype=np.float64))


# --- the body B -------------------------------------------------------------------------------


def _homogeneous(points: np.ndarray) -> np.ndarray:
    return np.hstack([points, np.ones((len(points), 1))])


def _project(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    c = _homogeneous(points) @ matrix.T
    return c[:, :3] / c[:, 3:]


def _planes_of(matrix: np.ndarray) -> np.ndarray:
    """The six inward half-spaces (a . p + d >= 0, |a| = 1) of a clip matrix's frustum."""
    rows = [matrix[3] + s * matrix[i] for i in range(3) for s in (1, -1)]
    planes = np.array(rows)
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def _box_planes(bounds: np.ndarray) -> np.ndarray:
    planes = []
    for axis in range(3):
        normal = np.zeros(3)
        normal[axis] = 1
        planes.append([*normal, -bounds[0, axis]])
        planes.append([*-normal, bounds[1, axis]])
    return np.array(planes)


# a spot light's clip space: its frustum is this cube, its light travels along +z
_CLIP_CUBE = np.array([[-1.0] * 3, [1.0] * 3])


def convex_vertices(planes: np.ndarray, tolerance: float) -> np.ndarray:
    """Vertices of the convex polytope {p : a . p + d >= 0}: every three-plane intersection
    inside all the half-spaces (coincident planes of a flat box are simply singular triples)."""
    triples = np.array(list(combinations(range(len(planes)), 3)))
    a, d = planes[triples, :3], planes[triples, 3]
    det = np.linalg.det(a)
    ok = np.abs(det) > 1e-9
    points = np.linalg.solve(a[ok], -d[ok][..., None])[..., 0]
    inside = np.all(points @ planes[:, :3].T + planes[:, 3] >= -tolerance, axis=1)
    return points[inside]


def padded_bounds(bounds: np.ndarray) -> np.ndarray:
    """Scene bounds grown a little, so surfaces on the box itself stay strictly inside."""
    pad = 1e-4 * max(float(np.linalg.norm(bounds[1] - bounds[0])), 1e-6)
    return np.stack([bounds[0] - pad, bounds[1] + pad])


def receiver_body(setup: ViewSetup) -> np.ndarray:
    """Vertices of the view frustum clipped to the scene bounds, to the view-depth range of the
    visible receivers and to a spot light's frustum: every visible receiver the light can reach
    lies in their hull. An empty intersection (nothing in view) falls back to the box corners
    (to the spot light's frustum corners)."""
    box = padded_bounds(setup.bounds)
    scale = max(float(np.abs(box).max()), 1.0)
    planes = [_planes_of(setup.view_proj), _box_planes(box)]
    depth_range = setup.visible_depth_range
    if depth_range is not None:
        n, f = depth_range
        # float32 G-buffer positions: their depths are good to a few 1e-7 of the coordinates
        pad = 1e-3 * (f - n) + 1e-6 * scale
        z = setup.view[2]
        planes.append(np.array([[*-z[:3], -z[3] - n + pad], [*z[:3], z[3] + f + pad]]))
    if setup.spot is not None:
        planes.append(_planes_of(setup.spot.view_proj))
    points = convex_vertices(np.vstack(planes), 1e-7 * scale)
    if len(points) < 1:
        points = (box_corners(box) if setup.spot is None
                  else _project(np.linalg.inv(setup.spot.view_proj), box_corners(_CLIP_CUBE)))
    return points


def _exit_times(points: np.ndarray, to_light: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Per point and axis, the travel along ``to_light`` to that axis' box face (inf if none)."""
    face = np.where(to_light > 0, box[1], box[0])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = (face - points) / to_light
    return np.where(np.abs(to_light) > 1e-12, np.maximum(t, 0), np.inf)


def caster_body(receivers: np.ndarray, to_light: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Receivers plus the vertices of their sweep toward the light, clipped to the scene bounds.

    The sweep's vertices are the exit points of the receiver vertices and of the points on the
    segments between them where the exit face changes (where two per-axis exit times are equal):
    there a swept edge meets a box edge.
    """
    box = padded_bounds(bounds)
    seeds = [receivers]
    if len(receivers) > 1:
        pairs = np.array(list(combinations(range(len(receivers)), 2)))
        a, b = receivers[pairs[:, 0]], receivers[pairs[:, 1]]
        ta, tb = _exit_times(a, to_light, box), _exit_times(b, to_light, box)
        for i, j in combinations(range(3), 2):
            with np.errstate(divide="ignore", invalid="ignore"):
                u = (ta[:, j] - ta[:, i]) / ((tb[:, i] - ta[:, i]) - (tb[:, j] - ta[:, j]))
            keep = np.isfinite(u) & (u > 0) & (u < 1)
            seeds.append(a[keep] + u[keep, None] * (b[keep] - a[keep]))
    seeds = np.vstack(seeds)
    t = _exit_times(seeds, to_light, box).min(axis=1)
    t = np.where(np.isfinite(t), t, 0.0)
    return np.vstack([receivers, seeds + t[:, None] * to_light])


# --- the space the light is directional in ---------------------------------------------------


@dataclass(frozen=True)
class LightSpace:
    """The space the warps are made in, where the light travels along one direction: the world
    for a directional light, a spot light's clip space (its post-projective space) for a spot.

    The camera is mapped there (``eye`` None when it lies behind a spot light's plane, where the
    post-projective space has no viewer); ``rigid`` and ``origin`` give the map's rigid view."""

    to_space: np.ndarray  # world -> this space (homogeneous)
    light: np.ndarray  # unit travel direction of the light here
    receivers: np.ndarray  # receiver-body vertices here
    body: np.ndarray  # receivers and casters here
    world_body: np.ndarray  # the same body in world space
    eye: np.ndarray | None
    forward: np.ndarray | None  # unit view direction here
    up: np.ndarray | None  # the camera's up direction here
    visible: np.ndarray  # the visible receivers here
    rigid: np.ndarray  # world -> rigid light view, rotation only (-z: the light's travel)
    origin: np.ndarray  # world origin of the map's rigid view


def _direction_at(matrix: np.ndarray, point: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The unit image under the projective map ``matrix`` of ``direction`` at ``point``."""
    h = matrix @ np.append(point, 1.0)
    moved = (matrix[:3, :3] - np.outer(h[:3] / h[3], matrix[3, :3])) @ direction / h[3]
    return moved / np.linalg.norm(moved)


def light_space(setup: ViewSetup) -> LightSpace:
    """The receiver body, its casters, the camera and the visible receivers where the light is
    directional."""
    receivers = receiver_body(setup)
    if setup.spot is None:
        body = caster_body(receivers, -setup.light, setup.bounds)
        return LightSpace(np.eye(4), setup.light, receivers, body, body, setup.eye, setup.forward,
                          setup.view[1, :3], setup.visible,
                          look_at(np.zeros(3), setup.light, any_perpendicular_up(setup.light)),
                          setup.eye)
    clip = setup.spot.view_proj
    light = np.array([0.0, 0.0, 1.0])
    receivers_here = _project(clip, receivers)
    body = caster_body(receivers_here, -light, _CLIP_CUBE)
    world_body = _project(np.linalg.inv(clip), body)
    eye = forward = up = None
    if float(clip[3] @ np.append(setup.eye, 1.0)) > 1e-9 * float(np.abs(clip[3]).max()):
        eye = _project(clip, setup.eye[None])[0]
        forward = _direction_at(clip, setup.eye, setup.forward)
        up = _direction_at(clip, setup.eye, setup.view[1, :3])
    visible = _project(clip, setup.visible)  # all inside its frustum (view_setup)
    rigid = setup.spot.view.copy()
    rigid[:3, 3] = 0.0
    return LightSpace(clip, light, receivers_here, body, world_body, eye, forward, up, visible,
                      rigid, setup.light_position)


def space_theta(space: LightSpace) -> float:
    """The angle between the light and the view direction in the light's space (nan where the
    camera has no image there)."""
    if space.forward is None:
        return float("nan")
    return math.acos(min(abs(float(space.forward @ space.light)), 1.0))


def space_depth_range(space: LightSpace, setup: ViewSetup) -> tuple[float, float]:
    """n and f in the light's space: the view depths of the visible receivers (where none is
    visible, of the receiver body from the camera's near plane on), for a spot light measured
    in its post-projective space from the camera along its view direction there."""
    if setup.spot is None:
        visible = setup.visible_depth_range
        depth = np.array(visible) if visible else setup.view_depth(space.receivers)
        near = float(depth.min()) if visible else max(float(depth.min()), setup.near)
    else:
        points = space.visible if len(space.visible) else space.receivers
        depth = (points - space.eye) @ space.forward
        near = max(float(depth.min()), 1e-9 * float(np.abs(depth).max()))
    return near, max(float(depth.max()), near * (1 + 1e-6))


# --- the map's orientation in the light plane ------------------------------------------------


def _across(vector: np.ndarray, light: np.ndarray) -> np.ndarray:
    return vector - (vector @ light) * light


def _unit_or_none(vector: np.ndarray) -> np.ndarray | None:
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 1e-9 else None


def warp_axis(space: LightSpace, theta: float, phi: float) -> np.ndarray:
    """The map's y axis in the light plane: the warp axis, continuous in theta.

    For theta >= phi it is LiSPSM's warp axis, the view direction projected perpendicular to
    the light. That projection vanishes at theta = 0 and turns with the side the light comes
    from as theta -> 0, so alone it would flip the map's orientation there. At theta = 0 the
    body seen along the light is bounded by the image rectangle (the view frustum seen along
    the view direction), so the best-fitting rectangle is the camera's: the axis there is the
    camera's up projected on the light plane (the image's direction toward far receivers, or
    toward near ones for a light facing the viewer). Between 0 and phi the axis turns from that
    one to the warp axis by the fraction tan(pi theta / (4 phi)), the factor by which GMNPR's
    lambda_2* (equation 7) leaves the standard map, so the map, lambda and every quantity built
    on them are continuous in theta, and the warp axis holds wherever the warp is strong.
    """
    light = space.light
    toward_far = None if space.forward is None else _unit_or_none(_across(space.forward, light))
    rectangle = None
    if space.up is not None:
        side = 1.0 if float(space.forward @ light) >= 0 else -1.0
        rectangle = _unit_or_none(side * _across(space.up, light))
    if rectangle is None:
        rectangle = toward_far if toward_far is not None else _unit_or_none(
            _across(any_perpendicular_up(light), light))
    if toward_far is None or not theta < phi:
        return toward_far if toward_far is not None else rectangle
    turn = math.atan2(float(light @ np.cross(rectangle, toward_far)), float(rectangle @ toward_far))
    angle = math.tan(math.pi * theta / (4 * phi)) * turn
    return math.cos(angle) * rectangle + math.sin(angle) * np.cross(light, rectangle)


def oriented_basis(light: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Rigid rotation (no translation): -z = light travel, y = ``axis`` (perpendicular to it)."""
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = np.cross(axis, -light), axis, -light
    return m


# --- the unit-cube fit ----------------------------------------------------------------------


def cube_fit(clip: np.ndarray, receivers: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Scale and offset ``clip`` so the receivers fill [-1, 1] in map x and y and the whole body
    (casters included) [-1, 1] in depth."""
    r, b = _project(clip, receivers), _project(clip, body)
    lo = np.array([*r[:, :2].min(0), b[:, 2].min()])
    hi = np.array([*r[:, :2].max(0), b[:, 2].max()])
    half = np.maximum((hi - lo) / 2, 1e-12) * (1 + CUBE_MARGIN)
    fit = np.eye(4)
    fit[:3, :3] = np.diag(1 / half)
    fit[:3, 3] = -(hi + lo) / 2 / half
    return fit @ clip


def local_light_view(basis: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """The rigid light basis moved so that ``origin`` maps to the light-view origin."""
    view = basis.copy()
    view[:3, 3] = -basis[:3, :3] @ origin
    return view


def frustum_from_clip(light_view: np.ndarray, clip: np.ndarray,
                      origin: np.ndarray) -> LightFrustum:
    """A LightFrustum whose view is the rigid light basis translated to ``origin`` (a local
    origin near the camera, or a spot light's position) and whose proj carries the warp.

    The GL passes run in float32: with an untranslated basis, a scene far from the world origin
    (1e5 units) puts light-view coordinates of size 1e5 into proj, whose perspective rows then
    subtract translations of that size and amplify the float32 rounding into texels. Relative
    to a nearby origin, proj sees small coordinates and only the rigid view meets the large ones."""
    view = local_light_view(light_view, np.asarray(origin, dtype=np.float64))
    return LightFrustum(view, clip @ np.linalg.inv(view), False, 0.0, 0.0)


# map depth grows along the light's travel (-z of an oriented basis)
_ORTHOGRAPHIC = np.diag([1.0, 1.0, -1.0, 1.0])


def unwarped_clip(space: LightSpace, basis: np.ndarray) -> np.ndarray:
    """World -> clip of the map without a warp: orthographic along the light in its space (a
    spot light's own perspective in world), fitted to the receivers."""
    return cube_fit(_ORTHOGRAPHIC @ basis, space.receivers, space.body) @ space.to_space


# --- light-space perspective (LiSPSM, GMNPR) -----------------------------------------------


@dataclass(frozen=True)
class Warp:
    frustum: LightFrustum
    clip: np.ndarray  # world -> clip of the map
    theta: float
    phi: float
    lam: float  # eye_distance over the body's depth along the warp axis
    near: float  # view depths of the visible receivers: the n and f of the formulas
    far: float
    eye_distance: float  # P_n: the warp frustum's eye before the body, along the warp axis
    n_opt: float  # LiSPSM's n_opt at these theta, n, f (equal to eye_distance for lispsm)


def light_space_warp(setup: ViewSetup, res: int, eye_distance: EyeDistance) -> Warp:
    """Wimmer's warp: a perspective frustum P along the warp axis with its eye
    ``eye_distance(theta, phi, n, f, depth)`` before the body (``depth`` its extent along the
    warp axis), laterally at the camera; orthographic along the light after it. For a spot light
    all of it happens in the light's post-projective space; with the camera behind the spot
    light's plane there is no viewer there, and the map is not warped."""
    space = light_space(setup)
    theta, phi = space_theta(space), setup.phi
    basis = oriented_basis(space.light, warp_axis(space, theta, phi))
    local = _homogeneous(space.body) @ basis.T
    along = local[:, 1]
    depth = max(float(along.max() - along.min()), 1e-9)
    if space.eye is None:
        near = far = optimal = float("nan")
        lam, lateral = LAMBDA_MAX, float(local[:, 0].mean())
    else:
        near, far = space_depth_range(space, setup)
        optimal = float(n_opt(theta, near, far))
        lam = float(np.clip(eye_distance(theta, phi, near, far, depth) / depth, 1e-6, LAMBDA_MAX))
        lateral = float(basis[0, :3] @ space.eye)
    p_near = lam * depth
    # P's eye: the camera's lateral position, p_near before the body along the warp axis
    origin = np.array([lateral, along.min() - p_near, 0.0])
    to_p = np.eye(4)
    to_p[:3, 3] = -origin
    p_far = p_near + depth
    # rows: map x (lateral), map y (hyperbolic warp-axis depth), map depth (along the light,
    # away from it), w (distance along the warp axis)
    warp = np.array([[1, 0, 0, 0],
                     [0, (p_far + p_near) / (p_far - p_near), 0, -2 * p_far * p_near / (p_far - p_near)],
                     [0, 0, -1, 0],
                     [0, 1, 0, 0]], dtype=np.float64)
    clip = cube_fit(warp @ to_p @ basis, space.receivers, space.body) @ space.to_space
    return Warp(frustum_from_clip(space.rigid, clip, space.origin), clip, theta, phi, lam,
                near, far, p_near, optimal)


def warp_columns(warp: Warp) -> dict:
    """The result columns of a light-space warp."""
    return {"lambda": warp.lam, "n_opt": warp.n_opt, "warp_eye_distance": warp.eye_distance,
            "depth_near": warp.near, "depth_far": warp.far}


# --- post-perspective space (PSM) -----------------------------------------------------------


@dataclass(frozen=True)
class PostPerspective:
    frustum: LightFrustum
    clip: np.ndarray
    theta: float
    slide_back: float  # how far the virtual camera moved back to see every caster
    camera: np.ndarray  # world -> clip of that virtual camera
    light_kind: str  # "point", "inverted" (light behind the viewer) or "directional"
    fallback: bool  # the warp could not hold the visible receivers: the unwarped map instead


def post_perspective_warp(setup: ViewSetup, res: int) -> PostPerspective:
    """Stamminger and Drettakis: the map is made in the post-perspective space of a virtual
    camera slid back until every caster is in front of its near plane (at the real near
    distance); the light (a directional one, or a spot light's point) becomes a point there, an
    inverted point (depth order reversed, Kozlov's inverse projection) when it is behind the
    viewer, or a directional light when it lies in the camera's plane. The light frustum is
    fitted to the receivers' part of the unit cube (unit-cube clipping).

    Where that map cannot hold the visible receivers (some fall outside its unit cube, or
    behind the post-perspective light, even after the slide-back), the unwarped map, fitted to
    the same body, is used instead and ``fallback`` is set."""
    space = light_space(setup)
    receivers, body = _project(np.linalg.inv(space.to_space), space.receivers), space.world_body
    depth = setup.view_depth(body)
    slide = max(0.0, setup.near - float(depth.min()))
    near = float(depth.min()) + slide
    far = max(float(depth.max()) + slide, near * (1 + 1e-6))
    virtual_view = setup.view.copy()
    virtual_view[2, 3] -= slide  # view z of every point moves by -slide
    virtual_proj = setup.proj.copy()
    virtual_proj[2, 2] = -(far + near) / (far - near)
    virtual_proj[2, 3] = -2 * far * near / (far - near)
    camera = virtual_proj @ virtual_view
    r_post, b_post = _project(camera, receivers), _project(camera, body)
    light4 = camera @ (np.append(-setup.light, 0.0) if setup.spot is None
                       else np.append(setup.light_position, 1.0))
    centre = (r_post.min(0) + r_post.max(0)) / 2
    extent = float(np.linalg.norm(b_post.max(0) - b_post.min(0))) + 1e-12
    if abs(light4[3]) * extent < 1e-6 * np.linalg.norm(light4[:3]):
        kind = "directional"
        travel = -light4[:3] / np.linalg.norm(light4[:3])
        up = np.eye(3)[np.argmin(np.abs(travel))]
        light_view = look_at(centre - travel, centre, up)
        projection = np.diag([1.0, 1.0, -1.0, 1.0])  # depth grows away from the light
    else:
        kind = "point" if light4[3] > 0 else "inverted"
        position = light4[:3] / light4[3]
        aim = centre - position
        aim /= np.linalg.norm(aim)
        light_view = look_at(position, position + aim, np.eye(3)[np.argmin(np.abs(aim))])
        # divide by the distance d along the aim; depth -1/d grows away from a point light,
        # +1/d toward an inverted one (its occluders lie farther from the converging point)
        sign = 1.0 if kind == "point" else -1.0
        projection = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, -sign],
                               [0, 0, -1, 0]], dtype=np.float64)
    clip = cube_fit(projection @ light_view @ camera, receivers, body)
    fallback = bool(outside_unit_cube(clip, setup.visible, np.ones(len(setup.visible), bool)).any())
    if fallback:
        theta = space_theta(space)
        clip = unwarped_clip(space, oriented_basis(space.light, warp_axis(space, theta, setup.phi)))
    return PostPerspective(frustum_from_clip(space.rigid, clip, space.origin), clip,
                           setup.theta, slide, camera, kind, fallback)


# --- measurements ---------------------------------------------------------------------------


def map_coordinates(clip: np.ndarray, points: np.ndarray, res: int) -> tuple[np.ndarray, np.ndarray]:
    """Map texel coordinates (..., 2) and clip w (...) of world points (..., 3)."""
    c = np.einsum("ij,...j->...i", clip, np.concatenate([points, np.ones(points.shape[:-1] + (1,))], -1))
    with np.errstate(divide="ignore", invalid="ignore"):
        texel = (c[..., :2] / c[..., 3:] * 0.5 + 0.5) * res
    return texel, c


def outside_unit_cube(clip: np.ndarray, position: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Covered pixels whose world position falls outside the map's unit cube (or behind it)."""
    _, c = map_coordinates(clip, position, 1)
    w = c[..., 3]
    tolerance = 1e-5 * np.abs(w)
    inside = (w > 0) & np.all(np.abs(c[..., :3]) <= w[..., None] + tolerance[..., None], axis=-1)
    return covered & ~inside


def alias_map(clip: np.ndarray, res: int, position: np.ndarray, normal: np.ndarray,
              covered: np.ndarray) -> np.ndarray:
    """Per pixel, the largest screen extent of one map texel, in pixels (1 = a texel per pixel).

    From numpy finite differences of the map coordinates of the G-buffer world positions: J is
    d(texel)/d(pixel) from the right and lower neighbours, and a texel spans 1 / sigma_min(J)
    pixels. Pixels whose neighbours are not on their own plane (silhouettes, creases) get NaN.
    """
    texel, _ = map_coordinates(clip, position.astype(np.float64), res)
    h, w = covered.shape
    alias = np.full((h, w), np.nan)
    p, n = position.astype(np.float64), normal.astype(np.float64)
    centre, right, down = p[:-1, :-1], p[:-1, 1:], p[1:, :-1]
    scale = np.linalg.norm(right - centre, axis=-1) + np.linalg.norm(down - centre, axis=-1) + 1e-12
    on_plane = ((np.abs(np.einsum("...i,...i", right - centre, n[:-1, :-1])) < 1e-3 * scale)
                & (np.abs(np.einsum("...i,...i", down - centre, n[:-1, :-1])) < 1e-3 * scale))
    valid = covered[:-1, :-1] & covered[:-1, 1:] & covered[1:, :-1] & on_plane
    dx = texel[:-1, 1:] - texel[:-1, :-1]
    dy = texel[1:, :-1] - texel[:-1, :-1]
    jac = np.stack([dx, dy], axis=-1)  # (..., texel axis, pixel axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma_min = np.linalg.svd(np.where(np.isfinite(jac), jac, 0.0), compute_uv=False)[..., -1]
        alias[:-1, :-1] = np.where(valid & np.all(np.isfinite(jac), axis=(-1, -2)),
                                   1.0 / sigma_min, np.nan)
    return alias




def alias_statistics(alias: np.ndarray, normal: np.ndarray, position: np.ndarray,
                     covered: np.ndarray, light, camera_view: np.ndarray) -> dict:
    """``alias_mean`` and ``alias_max`` of an :func:`alias_map` over the covered surfaces facing
    the light (n . l > ALIAS_MIN_COS, n turned toward the camera; inside a spot light's cone),
    and ``alias_near``, its mean over those of them within the nearest NEAR_FRACTION of the
    visible view-depth range. NaN where no pixel counts."""
    camera = -camera_view[:3, :3].T @ camera_view[:3, 3]
    n = normal.astype(np.float64)
    toward_camera = np.sign((n * (camera - position)).sum(-1))
    facing = covered & ((n * light.to_light(position)).sum(-1) * toward_camera > ALIAS_MIN_COS)
    if light.type == "spot":
        facing &= light.inside_cone(position)
    depth = -(position @ camera_view[2, :3] + camera_view[2, 3])
    near = np.zeros_like(covered)
    if covered.any():
        lo, hi = depth[covered].min(), depth[covered].max()
        near = depth <= lo + NEAR_FRACTION * (hi - lo)

    def stat(reduce, mask):
        values = alias[mask]
        values = values[~np.isnan(values)]
        return float(reduce(values)) if values.size else float("nan")

    return dict(alias_mean=stat(np.mean, facing), alias_max=stat(np.max, facing),
                alias_near=stat(np.mean, facing & near))
# --- the technique shared by psm, lispsm and gmnpr ------------------------------------------

PARAMETER_TABLE = """
    ==============  ================================================  =======  ===========
    Parameter       Meaning                                           Default  Range
    ==============  ================================================  =======  ===========
    ``res``         map width and height, texels                      1024     16 .. 8192
    ``bias``        constant depth bias, scene units                  0.02     >= 0
    ``slope_bias``  times the receiver plane's depth slope x each     1.0      >= 0
                    read's distance, in the warped map's texels
                    (shadow_map.glsl)
    ``k``           PCF samples per pixel, a square grid of texels    1        1 .. 49
    ==============  ================================================  =======  ===========
    """


class WarpParams(TechniqueParams):
    res: int = Field(1024, ge=16, le=8192)
    bias: float = Field(0.02, ge=0)
    slope_bias: float = Field(1.0, ge=0)
    k: SquareInt = Field(1, le=49)


class WarpedShadowMap(Technique):
    """A light's depth map under a warp chosen by ``warp(setup, res)`` (which returns a
    :class:`Warp` or :class:`PostPerspective` and the technique's extra columns, or raises
    NotApplicable for a light the technique does not treat), looked up by
    ``warp_shading.frag.glsl``. Columns of every warp: ``theta_deg``, ``alias_mean``,
    ``alias_max``, ``alias_near`` (see :func:`alias_statistics`), ``outside_pct``."""

    Params = WarpParams

    def warp(self, setup: ViewSetup, res: int) -> tuple[Warp | PostPerspective, dict]:
        raise NotImplementedError

    def prepare(self, frame: Frame) -> None:
        self.map = LightDepthMap(frame, self.params.res)
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl", "warp_shading.frag.glsl")

    def update(self, frame: Frame) -> None:
        """The warp of the frame's camera, light and visible receivers, timed (``warp_fit``:
        an engine fits it every frame); then its aliasing and coverage diagnostics, untimed."""
        res = self.params.res
        with frame.measure("warp_fit"):
            self.transform, columns = self.warp(view_setup(frame), res)
            self.map.frustum = self.transform.frustum
        arrays = frame.arrays
        alias = alias_map(self.transform.clip, res, arrays.position, arrays.normal,
                          arrays.covered)
        reached = arrays.covered
        if frame.scene.light.type == "spot":  # outside its cone no receiver needs the map
            reached = reached & frame.scene.light.inside_cone(arrays.position)
        outside = outside_unit_cube(self.transform.clip, arrays.position, reached)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.alias_log2 = np.log2(alias)
        self.columns = dict(
            theta_deg=math.degrees(self.transform.theta),
            **alias_statistics(alias, arrays.normal, arrays.position, arrays.covered,
                               frame.scene.light, frame.camera.view),
            outside_pct=100.0 * float(np.count_nonzero(outside))
            / max(np.count_nonzero(reached), 1),
            **columns)

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        with frame.measure("shadow_map"):
            # casters nearer the light than the fitted range still occlude: depth clamp puts them
            # on the near plane instead of clipping them (past the far plane, where the clamped
            # depth equals the cleared one, lie no receivers to shadow)
            GL.glEnable(GL.GL_DEPTH_CLAMP)
            self.map.render(frame)
            GL.glDisable(GL.GL_DEPTH_CLAMP)
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            self.shading.set(**self.map.lookup_uniforms(unit, p.slope_bias, frame),
                             grid_n=math.isqrt(p.k), bias=p.bias)
            frame.draw_fullscreen(covered_only=True)  # V = 1 where no surface
        warnings = []
        if self.columns["outside_pct"] > 0:
            warnings.append(f"{self.columns['outside_pct']:.2f}% of visible receivers fall "
                            "outside the warped map")
        return frame.output(mem_bytes=self.map.mem_bytes, fetches_per_px=p.k,
                            nonfinite=self.map.nonfinite + metrics.nonfinite(self.transform.clip),
                            extra=dict(self.columns), warnings=warnings,
                            maps={"pixels_per_texel_log2": self.alias_log2})

    def release(self) -> None:
        # prepare may have stopped early (a failed compile)
        for name in ("map", "shading"):
            resource = self.__dict__.pop(name, None)
            if resource is not None:
                resource.release()
