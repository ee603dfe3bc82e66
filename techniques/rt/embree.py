"""``backend: embree``: rt's rays on the CPU through Mitsuba's ``ray_test``, the tracer the
reference uses (Embree in its CPU variants), on the scene the reference builds
(``harness.reference.mitsuba_scene_dict``: the same triangles, moved next to Mitsuba's origin).
The G-buffer read-back, the trace and the upload of the mask are timed passes; the scene build
is ``prepare``'s, and a moved object's rebuild is the timed ``scene_build`` pass."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness import reference

# rt_offset.glsl's rule, the same constants
OFFSET_ULPS, ORIGIN, FLOAT_SCALE = 256, 1.0 / 32.0, 1.0 / 65536.0


def offset_ray(p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``rt_offset.glsl``'s ``offset_ray`` on float32 arrays (..., 3): the same bits."""
    p, n = np.asarray(p, np.float32), np.asarray(n, np.float32)
    step = (np.float32(OFFSET_ULPS) * n).astype(np.int32)  # truncates as GLSL's int()
    moved = (p.view(np.int32) + np.where(p < 0, -step, step)).view(np.float32)
    return np.where(np.abs(p) < ORIGIN, p + np.float32(FLOAT_SCALE) * n, moved)


def shadow_rays(position, normal, directional: bool, light, camera_position):
    """Which points (float32 (N, 3), with normals) the light reaches (their visible side, the
    normal turned to the camera, faces it: ``rt_trace.comp.glsl``'s test), and the shadow rays
    from those: origins offset along that normal, unit directions toward the light, lengths."""
    light = np.asarray(light, np.float64)
    to_camera = np.asarray(camera_position, np.float64) - position
    normal = np.where((np.sum(normal * to_camera, axis=1) >= 0)[:, None], normal, -normal)
    to_light = np.broadcast_to(light, position.shape) if directional else light - position
    facing = np.sum(normal * to_light, axis=1) > 0
    position, normal = position[facing], normal[facing]
    origin = offset_ray(position, normal)
    direction = np.broadcast_to(light, origin.shape) if directional else light - origin
    length = np.linalg.norm(direction, axis=1)
    maxt = np.full(len(origin), np.inf) if directional else length
    return facing, origin, direction / np.maximum(length, 1e-30)[:, None], maxt


class EmbreeRays:
    def __init__(self, scene):
        self.mi = reference.mitsuba_module(reference.choose_variant())
        self._build(scene)

    def _build(self, scene) -> None:
        self.parts, self.shift = scene.parts, reference.mitsuba_origin(scene)
        self.scene = self.mi.load_dict(reference.mitsuba_scene_dict(scene, self.mi, samples=1))

    def follow(self, frame) -> None:
        """Where objects moved (the frame's parts are new arrays), Mitsuba's scene is built
        again from them, in the timed ``scene_build`` pass: Mitsuba has no instance pose to
        move."""
        if frame.scene.parts is not self.parts:
            with frame.measure("scene_build"):
                self._build(frame.scene)

    def trace(self, frame, mask, divisor: int, light: dict, camera_position) -> None:
        """The mask (GL rows, bottom first) from one ray per mask texel (V = 0 and no ray
        where the visible side faces away from the light)."""
        mi = self.mi
        with frame.measure("readback"):
            g = frame.gbuffer.read()
        with frame.measure("trace"):
            h, w = g.covered.shape
            rows = np.minimum(np.arange(mask.height) * divisor + divisor // 2, h - 1)
            cols = np.minimum(np.arange(mask.width) * divisor + divisor // 2, w - 1)
            pick = np.ix_(h - 1 - rows, cols)  # GL row y is the image's row h - 1 - y
            covered = g.covered[pick]
            facing, origin, direction, maxt = shadow_rays(
                g.position[pick][covered], g.normal[pick][covered], light["directional"],
                light["light"], camera_position)
            hit = np.zeros(len(origin), bool)
            if len(origin):  # Dr.Jit aborts the process on a trace of no rays
                o = (origin.astype(np.float64) - self.shift).astype(np.float32)
                ray = mi.Ray3f(mi.Point3f(*o.T), mi.Vector3f(*direction.astype(np.float32).T))
                ray.maxt = mi.Float(maxt.astype(np.float32))
                hit = np.asarray(self.scene.ray_test(ray), bool)
            lit = np.zeros(int(covered.sum()), np.float32)
            lit[facing] = np.where(hit, 0.0, 1.0)
            v = np.ones(covered.shape, np.float32)
            v[covered] = lit
        with frame.measure("upload"):
            GL.glBindTexture(GL.GL_TEXTURE_2D, mask.id)
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
            GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, 0, 0, mask.width, mask.height, GL.GL_RED,
                               GL.GL_FLOAT, np.ascontiguousarray(v))
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    def release(self) -> None:
        self.scene = None
