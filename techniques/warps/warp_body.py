"""What the warps are fitted to: the camera, the light and the visible receivers of a frame,
the body B of points that need map resolution, and the space where the light is directional.

B is the view frustum clipped to the scene bounds and to the view-depth range of the visible
receivers, extended toward the light to its casters.

n and f, the view depths of the formulas, are the nearest and farthest view depth of the
visible receivers (the covered G-buffer pixels): the papers' body B is what the camera sees, and
the view frustum clipped to the scene bounds can start at the near plane and end far behind the
last visible surface. Where no receiver is visible the clipped frustum's range stands in.

The receivers are an object of three questions (:class:`Receivers`): their view-depth range,
their depth range along a direction in the spot light's clip space, and whether any falls
outside a map. The warps ask the GPU (``warp_receivers``: one reduction over the G-buffer per
question, a few floats read back); :class:`ReceiverPoints` answers from points, the CPU copy of
the G-buffer (:func:`receiver_points`, the tests' oracle) or any point set.

A spot light is warped in its own post-projective space (its clip space, where its rays are
parallel and it is a directional light travelling along +z), as Wimmer et al.'s reference code
does; there theta, n and f are measured too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from itertools import combinations
from typing import Callable, Protocol

import numpy as np

from harness.scene.transforms import LightFrustum, any_perpendicular_up, box_corners, fit_light, look_at

from .warp_diagnostics import outside_unit_cube


# --- the visible receivers -------------------------------------------------------------------


class Receivers(Protocol):
    """The visible receivers: covered G-buffer pixels (inside a spot light's frustum)."""

    def depth_range(self, view: np.ndarray) -> tuple[float, float] | None:
        """The nearest and farthest view depth under ``view`` (world -> camera view); None
        when no receiver is visible."""

    def range_along(self, clip: np.ndarray, eye: np.ndarray,
                    forward: np.ndarray) -> tuple[float, float] | None:
        """The smallest and largest (project(clip, p) - eye) . forward; None when none."""

    def any_outside(self, clip: np.ndarray) -> bool:
        """Whether any receiver falls outside ``clip``'s unit cube (or behind it)."""


@dataclass(frozen=True)
class ReceiverPoints:
    """Receivers given as world points (N, 3), float64."""

    points: np.ndarray

    def depth_range(self, view):
        if len(self.points) == 0:
            return None
        depth = -(self.points @ view[2, :3] + view[2, 3])
        return float(depth.min()), float(depth.max())

    def range_along(self, clip, eye, forward):
        if len(self.points) == 0:
            return None
        depth = (project(clip, self.points) - eye) @ forward
        return float(depth.min()), float(depth.max())

    def any_outside(self, clip):
        return bool(outside_unit_cube(clip, self.points, np.ones(len(self.points), bool)).any())


def receiver_points(frame, spot: LightFrustum | None) -> ReceiverPoints:
    """The visible receivers from the CPU copy of the frame's G-buffer (``frame.arrays``):
    the oracle the GPU reduction is tested against."""
    arrays = frame.arrays
    visible = arrays.position[arrays.covered].astype(np.float64)
    if spot is not None:  # the receivers a spot light can reach: those in its frustum
        visible = visible[~outside_unit_cube(spot.view_proj, visible, np.ones(len(visible), bool))]
    return ReceiverPoints(visible)


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
    receivers: Receivers  # the visible receivers
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

    @cached_property
    def visible_depth_range(self) -> tuple[float, float] | None:
        """n and f: the nearest and farthest view depth of the visible receivers (None when no
        receiver is visible)."""
        return self.receivers.depth_range(self.view)


def view_setup(frame, find_receivers: Callable[..., Receivers]) -> ViewSetup:
    """The camera, light and visible receivers of a frame: ``find_receivers(frame, spot)``
    gives the covered G-buffer pixels inside ``spot``, the spot light's frustum (None for a
    directional light)."""
    light = frame.scene.light
    cam = frame.scene.config.camera
    view = frame.camera.view
    spot = fit_light(frame.scene, 1) if light.type == "spot" else None
    return ViewSetup(view, frame.camera.proj, frame.camera.position, -view[2, :3],
                     np.asarray(light.direction, dtype=np.float64) / np.linalg.norm(light.direction),
                     float(cam.near), float(cam.far), frame.scene.bounds,
                     find_receivers(frame, spot), spot,
                     None if spot is None else np.asarray(light.position, dtype=np.float64))


# --- the body B -------------------------------------------------------------------------------


def homogeneous(points: np.ndarray) -> np.ndarray:
    return np.hstack([points, np.ones((len(points), 1))])


def project(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    c = homogeneous(points) @ matrix.T
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
    with np.errstate(divide="ignore", invalid="ignore"):  # the singular triples: det 0
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
                  else project(np.linalg.inv(setup.spot.view_proj), box_corners(_CLIP_CUBE)))
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
                          setup.view[1, :3],
                          look_at(np.zeros(3), setup.light, any_perpendicular_up(setup.light)),
                          setup.eye)
    clip = setup.spot.view_proj
    light = np.array([0.0, 0.0, 1.0])
    receivers_here = project(clip, receivers)
    body = caster_body(receivers_here, -light, _CLIP_CUBE)
    world_body = project(np.linalg.inv(clip), body)
    eye = forward = up = None
    if float(clip[3] @ np.append(setup.eye, 1.0)) > 1e-9 * float(np.abs(clip[3]).max()):
        eye = project(clip, setup.eye[None])[0]
        forward = _direction_at(clip, setup.eye, setup.forward)
        up = _direction_at(clip, setup.eye, setup.view[1, :3])
    rigid = setup.spot.view.copy()
    rigid[:3, 3] = 0.0
    return LightSpace(clip, light, receivers_here, body, world_body, eye, forward, up, rigid,
                      setup.light_position)


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
        along = setup.receivers.range_along(space.to_space, space.eye, space.forward)
        depth = (np.array(along) if along else (space.receivers - space.eye) @ space.forward)
        near = max(float(depth.min()), 1e-9 * float(np.abs(depth).max()))
    return near, max(float(depth.max()), near * (1 + 1e-6))
