"""Camera and light paths of a moving scene: frame t of ``motion`` as a still scene.

The camera orbits its target about its up axis, the light turns about the up axis through the
centre of the scene's bounds (a directional light's direction; a spot light's position and
target together, so its aim distance and cone stay the same; a point light's position), and the
camera moves toward its target by a fraction of its distance. Each path is at t / (frames - 1)
of its total at frame t. A path whose amount at frame t is zero leaves its values exactly as
written, so frame 0 is the scene without motion, bit for bit (and shares its reference cache
entry).
"""

from __future__ import annotations

import math

import numpy as np

from . import config as cfg


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
