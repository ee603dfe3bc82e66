"""Camera, light and object paths of a moving scene: frame t of ``motion`` as a still scene.

The camera orbits its target about its up axis, the light turns about the up axis through the
centre of the scene's bounds (a directional light's direction; a spot light's position and
target together, so its aim distance and cone stay the same; a point light's position), the
camera moves toward its target by a fraction of its distance, and each moving object (all its
array copies) spins about its own centre, orbits a centre point and translates, rigidly
(:func:`object_poses`). Each path is at t / (frames - 1) of its total at frame t. A path whose
amount at frame t is zero leaves its values exactly as written, so frame 0 is the scene without
motion, bit for bit (and shares its reference cache entry).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .. import config as cfg


def progress(frames: int, t: int) -> float:
    """How far along the paths frame ``t`` of ``frames`` is, 0 at the first, 1 at the last."""
    if not 0 <= t < frames:
        raise IndexError(f"frame {t} of a {frames}-frame sequence")
    return t / (frames - 1) if frames > 1 else 0.0


def rotation(axis, degrees: float) -> np.ndarray:
    """3x3 rotation by ``degrees`` about ``axis`` (right-handed, Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    a = math.radians(degrees)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * cross + (1 - math.cos(a)) * cross @ cross


def _turned(point, centre, turn: np.ndarray) -> tuple[float, float, float]:
    p = np.asarray(point, dtype=np.float64) - centre
    return tuple(float(x) for x in turn @ p + centre)


def camera_at(camera: cfg.Camera, motion: cfg.Motion, t: int) -> cfg.Camera:
    """The camera of frame ``t``: orbited about its up axis through its target, then moved
    toward the target by ``camera_dolly`` times the fraction of the path."""
    s = progress(motion.frames, t)
    target = np.asarray(camera.target, dtype=np.float64)
    position = camera.position
    if motion.camera_orbit * s:
        position = _turned(position, target, rotation(camera.up, motion.camera_orbit * s))
    if motion.camera_dolly * s:
        offset = np.asarray(position, dtype=np.float64) - target
        position = tuple(float(x) for x in target + offset * (1 - motion.camera_dolly * s))
    return camera.model_copy(update={"position": position})


def light_at(light, motion: cfg.Motion, up, centre, t: int):
    """The light of frame ``t`` (a config light): turned by ``light_orbit`` times the fraction
    of the path about ``up`` through ``centre``."""
    degrees = motion.light_orbit * progress(motion.frames, t)
    if not degrees:
        return light
    turn = rotation(up, degrees)
    if isinstance(light, cfg.DirectionalLight):
        return light.model_copy(update={"direction": _turned(light.direction, 0.0, turn)})
    if isinstance(light, cfg.PointLight):
        return light.model_copy(update={"position": _turned(light.position, centre, turn)})
    return light.model_copy(update={"position": _turned(light.position, centre, turn),
                                    "target": _turned(light.target, centre, turn)})


def scene_at(scene: cfg.Scene, centre, t: int) -> cfg.Scene:
    """Frame ``t`` of a moving scene as a still scene (no ``motion``); ``centre`` is the centre
    of its bounds, where the light's orbit axis passes."""
    motion = scene.motion
    return scene.model_copy(update={
        "camera": camera_at(scene.camera, motion, t),
        "light": light_at(scene.light, motion, scene.camera.up, np.asarray(centre, float), t),
        "motion": None})


def _turn_about(axis, degrees: float, centre) -> np.ndarray:
    """4x4 rotation by ``degrees`` about ``axis`` through ``centre``."""
    pose = np.eye(4)
    pose[:3, :3] = rotation(axis, degrees)
    pose[:3, 3] = np.asarray(centre, dtype=np.float64) - pose[:3, :3] @ centre
    return pose


def object_poses(scene: cfg.Scene, parts, centre, t: int) -> np.ndarray | None:
    """Each part's rigid transform at frame ``t`` from the scene as written, (P, 4, 4) float64:
    its object's spin about the centre of the object's bounds (all its copies), then its orbit
    about ``orbit_axis`` through ``centre`` (the object motion's, else ``centre``, the
    scene's), then its translation. ``parts`` are the scene's as written (``MeshPart``). None
    where nothing moves at ``t`` (frame 0 always), so that frame keeps the geometry bit for
    bit."""
    s = progress(scene.motion.frames, t)
    owner = np.array([part.object_index for part in parts])
    poses = np.tile(np.eye(4), (len(parts), 1, 1))
    for path in scene.motion.objects:
        mine = owner == scene.object_index(path.object)
        pose = np.eye(4)
        if path.spin * s:
            vertices = np.concatenate([p.vertices for p, m in zip(parts, mine) if m])
            own = (vertices.min(axis=0).astype(np.float64) + vertices.max(axis=0)) / 2
            pose = _turn_about(path.spin_axis or scene.camera.up, path.spin * s, own) @ pose
        if path.orbit * s:
            pose = _turn_about(path.orbit_axis or scene.camera.up, path.orbit * s,
                               np.asarray(path.centre or centre, dtype=np.float64)) @ pose
        pose[:3, 3] += np.asarray(path.translate, dtype=np.float64) * s
        poses[mine] = pose
    return None if np.array_equal(poses, np.broadcast_to(np.eye(4), poses.shape)) else poses


def moved(vertices: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``vertices`` (N, 3) moved by the rigid ``pose`` in float64, stored float32: where a
    moving part's vertices are (:func:`posed`), for whatever follows that part."""
    return (vertices.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]).astype(np.float32)


def posed(parts, poses: np.ndarray) -> list:
    """``parts`` with their vertices :func:`moved` by ``poses``; a part whose pose is the
    identity keeps its arrays."""
    return [part if np.array_equal(pose, np.eye(4)) else replace(part, vertices=moved(
        part.vertices, pose)) for part, pose in zip(parts, poses)]
