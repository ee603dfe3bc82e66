"""The warps themselves: the map's orientation in the light plane, the fit of the warped body
to the unit cube, the light-space warp (LiSPSM, GMNPR) and the post-perspective one (PSM).

Every map is expressed as a :class:`harness.scene.transforms.LightFrustum`: ``view`` is a rigid light
basis whose -z is the light's travel direction (a spot light's own view), centred on the camera
(on a spot light), a local origin so the float32 GL passes keep their precision far from the
world origin, so map depth stays the linear distance along the light; ``proj`` carries the whole
warp. A texel is one world light ray in all three warps, so that linear depth orders occluders
correctly within a texel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.scene.transforms import LightFrustum, any_perpendicular_up, look_at

from .warp_body import (LightSpace, ViewSetup, homogeneous, light_space, project,
                        space_depth_range, space_theta)
from .warp_equations import LAMBDA_MAX, EyeDistance, n_opt

# Fraction of the fitted extent left as margin on each side of the unit cube.
CUBE_MARGIN = 1.0e-3


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
    r, b = project(clip, receivers), project(clip, body)
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
    local = homogeneous(space.body) @ basis.T
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
    receivers, body = project(np.linalg.inv(space.to_space), space.receivers), space.world_body
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
    r_post, b_post = project(camera, receivers), project(camera, body)
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
    fallback = setup.receivers.any_outside(clip)
    if fallback:
        theta = space_theta(space)
        clip = unwarped_clip(space, oriented_basis(space.light, warp_axis(space, theta, setup.phi)))
    return PostPerspective(frustum_from_clip(space.rigid, clip, space.origin), clip,
                           setup.theta, slide, camera, kind, fallback)
