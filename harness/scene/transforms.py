"""Camera and light matrices (column-vector convention: clip = proj @ view @ world)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import config as cfg
from . import BuiltScene


def _pyrender():
    """pyrender, for its cameras' projection matrices, imported where one is made: it imports
    trimesh and pyglet, 0.6 s of the start of every command (shadowbench list included)."""
    import pyrender

    return pyrender


def look_at(eye, target, up) -> np.ndarray:
    """World-to-view matrix of a camera at ``eye`` looking at ``target`` (view -z forward)."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = right, true_up, -forward
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def any_perpendicular_up(direction) -> np.ndarray:
    """An up vector not parallel to ``direction`` (z unless the direction is nearly vertical)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    return np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.99 else np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class CameraMatrices:
    view: np.ndarray
    proj: np.ndarray
    position: np.ndarray

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view


def camera_matrices(camera: cfg.Camera, width: int, height: int) -> CameraMatrices:
    proj = _pyrender().PerspectiveCamera(
        yfov=math.radians(camera.yfov), znear=camera.near, zfar=camera.far,
        aspectRatio=width / height,
    ).get_projection_matrix(width, height)
    return CameraMatrices(look_at(camera.position, camera.target, camera.up), proj,
                          np.asarray(camera.position, dtype=np.float64))


@dataclass(frozen=True)
class LightFrustum:
    """A light's map projection. Map depth is light view-space distance (-z), in scene units."""

    view: np.ndarray
    proj: np.ndarray
    is_ortho: bool
    near: float
    far: float

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view


def box_corners(bounds: np.ndarray) -> np.ndarray:
    """The 8 corners of an axis-aligned box given as [min, max] rows."""
    return np.array([[bounds[i, 0], bounds[j, 1], bounds[k, 2]]
                     for i in (0, 1) for j in (0, 1) for k in (0, 1)])


def _to_view(view: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ view[:3, :3].T + view[:3, 3]


def fit_light(scene: BuiltScene, res: int, margin: float = 0.01) -> LightFrustum:
    """Directional: orthographic fitted to the scene bounds. Spot: perspective over its cone.
    A point light has no one frustum (:func:`cube_faces`)."""
    light, bounds = scene.light, scene.bounds
    if light.type == "point":
        raise ValueError("a point light shines every way: its map is six cube_faces, not one "
                         "frustum")
    corners = box_corners(bounds)
    if light.type == "directional":
        center = bounds.mean(axis=0)
        radius = max(np.linalg.norm(bounds[1] - bounds[0]) / 2, 1e-6)
        up = any_perpendicular_up(light.direction)
        view = look_at(center - light.direction * 2 * radius, center, up)
        local = _to_view(view, corners)
        lo, hi = local.min(axis=0), local.max(axis=0)
        half = (hi - lo) / 2 * (1 + margin) + 1e-6
        # move the eye so the box is centred: pyrender's orthographic camera is symmetric
        shift = (lo + hi) / 2
        eye = center - light.direction * 2 * radius + view[0, :3] * shift[0] + view[1, :3] * shift[1]
        view = look_at(eye, eye + light.direction, up)
        depth = -_to_view(view, corners)[:, 2]
        near, far = depth.min() - half[2] * 0.01 - 1e-3, depth.max() + half[2] * 0.01 + 1e-3
        near = max(near, 1e-4)
        proj = _pyrender().OrthographicCamera(xmag=half[0], ymag=half[1], znear=near,
                                           zfar=far).get_projection_matrix()
        return LightFrustum(view, proj, True, near, far)
    up = any_perpendicular_up(light.direction)
    view = look_at(light.position, light.position + light.direction, up)
    depth = -_to_view(view, corners)[:, 2]
    far = max(depth.max() * 1.01, 1e-3)
    near = max(depth.min() * 0.99, far * 1e-4)
    yfov = math.radians(light.fov_deg)
    proj = _pyrender().PerspectiveCamera(yfov=yfov, znear=near, zfar=far,
                                      aspectRatio=1.0).get_projection_matrix(res, res)
    return LightFrustum(view, proj, False, near, far)


# A point light's cube faces, in the order of the layer a shader picks for the direction d from
# the light: 2 x (axis of d's largest |component|) + (1 where that component is negative).
CUBE_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                     dtype=np.float64)
# near = far x this: a 24-bit depth buffer still orders what each face draws
CUBE_NEAR_RATIO = 1e-4


def cube_faces(scene: BuiltScene, res: int, half_tan: float = 1.0) -> list[LightFrustum]:
    """A point light's six perspective faces along ``CUBE_AXES``. ``half_tan`` 1 gives each
    face its 90 degrees exactly; more widens every face alike, so its map also holds a band of
    its neighbours' directions (for samples that reach past the face's own edge)."""
    position = scene.light.position
    far = max(float(np.linalg.norm(box_corners(scene.bounds) - position, axis=1).max()) * 1.01,
              1e-3)
    near = far * CUBE_NEAR_RATIO
    proj = _pyrender().PerspectiveCamera(yfov=2 * math.atan(half_tan), znear=near, zfar=far,
                                      aspectRatio=1.0).get_projection_matrix(res, res)
    return [LightFrustum(look_at(position, position + axis, any_perpendicular_up(axis)), proj,
                         False, near, far) for axis in CUBE_AXES]
